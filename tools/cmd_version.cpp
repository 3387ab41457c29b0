// `rayscan version [--json]`: what a bug report needs: the version, the commit it was built from,
// the SIMD path the traversal takes on this CPU, the compiler and the libraries' versions.
#include "commands.hpp"

#include "rayscan/base/version.hpp"
#include "rayscan/octree/simd.hpp"

#include "git_commit.h"

#include <gdal.h>
#include <nlohmann/json.hpp>
#include <sqlite3.h>
#include <tbb/version.h>

#include <iostream>
#include <memory>
#include <string>

namespace rayscan::cli {

Runner add_version_command(CLI::App& app) {
  auto* sub = app.add_subcommand("version", "Print the version, the commit, the SIMD path and the libraries' versions");
  auto json = std::make_shared<bool>(false);
  sub->add_flag("--json", *json, "print one JSON object instead of text");
  return [json]() -> int {
    nlohmann::ordered_json j;
    j["version"] = version();
    j["git_commit"] = RAYSCAN_GIT_COMMIT;
    j["simd"] = simd_description();
#if defined(__clang__)
    j["compiler"] = std::string("clang ") + __clang_version__;
#elif defined(__GNUC__)
    j["compiler"] = std::string("gcc ") + __VERSION__;
#endif
    j["libraries"] = {{"tbb", TBB_runtime_version()},
                      {"gdal", GDALVersionInfo("RELEASE_NAME")},
                      {"sqlite", sqlite3_libversion()},
                      {"nlohmann_json", std::to_string(NLOHMANN_JSON_VERSION_MAJOR) + "." +
                                            std::to_string(NLOHMANN_JSON_VERSION_MINOR) + "." +
                                            std::to_string(NLOHMANN_JSON_VERSION_PATCH)}};
    if (*json) {
      std::cout << j.dump(2) << "\n";
      return 0;
    }
    std::cout << "rayscan " << version() << " (commit " << RAYSCAN_GIT_COMMIT << ")\n"
              << "SIMD:      " << simd_description() << "\n";
    if (j.contains("compiler")) std::cout << "compiler:  " << j["compiler"].get<std::string>() << "\n";
    std::cout << "libraries:";
    for (const auto& [name, v] : j["libraries"].items()) std::cout << " " << name << " " << v.get<std::string>();
    std::cout << "\n";
    return 0;
  };
}

}  // namespace rayscan::cli
