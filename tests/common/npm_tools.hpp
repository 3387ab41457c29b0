// The npm test tools (tests/npm: laz-perf and copc.js, the independent LAZ and COPC readers of the
// writer tests), installed once per machine from tests/npm's lock file.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace rayscan::test {

/// node_modules holding the packages of tests/npm/package-lock.json (exact versions, integrity
/// hashes checked by `npm ci`), in a cache outside the repository ($RAYSCAN_NPM_CACHE, else
/// ~/.cache/rayscan-npm-ci): installed when absent or when its lock file is not the repository's.
/// "" when node or npm is missing or the registry cannot be reached (`why` says which; the caller
/// skips). tools/install-deps.sh installs node and npm.
inline std::filesystem::path npm_modules(std::string& why) {
  namespace fs = std::filesystem;
  const char* env = std::getenv("RAYSCAN_NPM_CACHE");
  const char* home = std::getenv("HOME");
  const fs::path cache = env ? fs::path(env) : home ? fs::path(home) / ".cache/rayscan-npm-ci" : fs::path("/tmp/rayscan-npm-ci");
  if (std::system("node --version >/dev/null 2>&1 && npm --version >/dev/null 2>&1") != 0) {
    why = "node or npm is not installed (tools/install-deps.sh installs them)";
    return {};
  }
  const fs::path src = fs::path(RAYSCAN_SOURCE_DIR) / "tests/npm";
  const auto text = [](const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(f), {});
  };
  const std::string lock = text(src / "package-lock.json");
  if (text(cache / "package-lock.json") != lock || !fs::exists(cache / "node_modules/laz-perf") ||
      !fs::exists(cache / "node_modules/copc")) {
    fs::create_directories(cache);
    fs::copy_file(src / "package.json", cache / "package.json", fs::copy_options::overwrite_existing);
    fs::copy_file(src / "package-lock.json", cache / "package-lock.json", fs::copy_options::overwrite_existing);
    const std::string cmd = "cd '" + cache.string() + "' && timeout 300 npm ci --no-audit --no-fund >/dev/null 2>&1";
    if (std::system(cmd.c_str()) != 0 || !fs::exists(cache / "node_modules/copc")) {
      fs::remove(cache / "package-lock.json");  // (the next run tries again)
      why = "npm ci could not install tests/npm's packages into " + cache.string() + " (registry unreachable?)";
      return {};
    }
  }
  return cache / "node_modules";
}

}  // namespace rayscan::test
