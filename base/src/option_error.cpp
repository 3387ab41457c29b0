// OptionError (option_error.hpp).
#include "rayscan/base/option_error.hpp"

namespace rayscan {

namespace {

std::string join(const std::vector<OptionError::Part>& parts,
                 const std::function<std::string(std::string_view)>& spell) {
  std::string s;
  for (const OptionError::Part& p : parts) {
    if (const auto* text = std::get_if<std::string>(&p)) s += *text;
    else s += spell(std::get<OptionName>(p).field);
  }
  return s;
}

}  // namespace

OptionError::OptionError(std::vector<Part> parts)
    : std::invalid_argument(join(parts, [](std::string_view f) { return std::string(f); })),
      parts_(std::make_shared<const std::vector<Part>>(std::move(parts))) {}

std::string OptionError::spelled(const std::function<std::string(std::string_view)>& spell) const {
  return join(*parts_, spell);
}

}  // namespace rayscan
