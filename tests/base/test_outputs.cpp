// require_outputs (atomic_file.hpp): the checks every job runs on its outputs before its work, here
// the one between outputs: two outputs of one command at one path, however spelled, are refused.
#include "rayscan/base/atomic_file.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <unistd.h>

namespace fs = std::filesystem;

TEST(RequireOutputs, TwoOutputsAtOnePathAreRefusedHoweverSpelled) {
  const fs::path dir = fs::temp_directory_path() / ("rayscan_outputs_" + std::to_string(::getpid()));
  fs::create_directories(dir / "sub");
  const fs::path a = dir / "a.tif";
  const auto refused = [](std::initializer_list<fs::path> outs) {
    const std::vector<fs::path> v(outs);
    try {
      rayscan::require_outputs(v);
    } catch (const rayscan::OutputFileError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(refused({a, a}), a.string() + ": is also the command's output '" + a.string() + "' (give each output its own path)");
  EXPECT_NE(refused({a, dir / "sub" / ".." / "a.tif"}), "");  // (a new file: resolved by its directory)
  std::ofstream(a) << "x";
  fs::create_symlink(a, dir / "link.tif");
  EXPECT_NE(refused({a, dir / "link.tif"}), "");               // a link to it
  EXPECT_EQ(refused({a, dir / "b.tif", fs::path()}), "");      // distinct outputs; empty ones skipped
  fs::remove_all(dir);
}
