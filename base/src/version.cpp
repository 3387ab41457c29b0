// rayscan/base/version.hpp. RAYSCAN_VERSION is the project version, a private definition of this file.
#include "rayscan/base/version.hpp"

namespace rayscan {

const char* version() { return RAYSCAN_VERSION; }

std::string software_name() { return std::string("rayscan ") + RAYSCAN_VERSION; }

}  // namespace rayscan
