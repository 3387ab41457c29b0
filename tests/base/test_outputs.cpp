// require_outputs (atomic_file.hpp): the checks every job runs on its outputs before its work, here
// the one between outputs: two outputs of one command at one path, however spelled, are refused;
// and the errors about temporaries, which name the output they are written for; IntermediateFile.
#include "rayscan/base/atomic_file.hpp"

#include "../common/temp_dir.hpp"

#include <gtest/gtest.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <stdexcept>
#include <string>
#include <unistd.h>

namespace fs = std::filesystem;

TEST(RequireOutputs, TwoOutputsAtOnePathAreRefusedHoweverSpelled) {
  const fs::path dir = rayscan::test::process_temp_dir("rayscan_outputs");
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

// Errors about a temporary name the output the user asked for (output_of, output_error): an
// AtomicFile's temporary, an intermediate file registered for it, a file in a registered folder,
// and a chain (an import's temporary index, whose own AtomicFile writes a temporary of it).
TEST(OutputError, TemporariesAreNamedByTheirOutput) {
  const fs::path dir = rayscan::test::process_temp_dir("rayscan_output_error");
  fs::create_directories(dir / "elsewhere");
  const fs::path out = dir / "x.laz";
  const std::string enospc = std::strerror(ENOSPC);
  {
    const rayscan::AtomicFile file(out);
    EXPECT_NE(file.temp(), out);
    EXPECT_EQ(rayscan::output_of(file.temp()), out);
    EXPECT_EQ(rayscan::output_error(file.temp(), "write failed at byte 4096", ENOSPC).what(),
              out.string() + ": write failed at byte 4096: " + enospc);
  }
  const fs::path plain = dir / ".x.laz.las.tmp.1";
  EXPECT_EQ(rayscan::output_of(plain), plain);  // not registered: named as it is
  EXPECT_EQ(rayscan::output_error(plain, "write failed", 0).what(), plain.string() + ": write failed");
  rayscan::TemporaryOf kept;
  {
    rayscan::TemporaryOf named(plain, out);
    EXPECT_EQ(rayscan::output_of(plain), out);
    const rayscan::AtomicFile inner(plain);  // (write_las's own temporary of the intermediate file)
    EXPECT_EQ(rayscan::output_of(inner.temp()), out);
    EXPECT_EQ(rayscan::output_error(inner.temp(), "write failed", EFBIG).what(),
              out.string() + ": write failed: " + std::strerror(EFBIG));
    kept = std::move(named);
  }  // `named`, moved from, is gone: the registration went with the move
  EXPECT_EQ(rayscan::output_of(plain), out);
  kept = rayscan::TemporaryOf();
  EXPECT_EQ(rayscan::output_of(plain), plain);  // released with its owner
  {
    const fs::path runs = dir / ".x.rsi.runs.1";
    const rayscan::TemporaryOf named(runs, dir / "x.rsi");
    EXPECT_EQ(rayscan::output_error(runs / "run3", "write failed at byte 0", ENOSPC).what(),
              (dir / "x.rsi").string() + ": write failed at byte 0: " + enospc);
    // A temporary in another folder than its output: that folder is the full one, and said so.
    const fs::path far = dir / "elsewhere" / ".x.rsi.runs.1";
    const rayscan::TemporaryOf far_named(far, dir / "x.rsi");
    EXPECT_EQ(rayscan::output_error(far / "run0", "write failed", ENOSPC).what(),
              (dir / "x.rsi").string() + ": write failed (temporary file in '" + (dir / "elsewhere").string() +
                  "'): " + enospc);
  }
  fs::remove_all(dir);
}

// IntermediateFile, a file or (Kind::folder) a folder with its contents: registered for its output
// while it lives (errors about it, or a file in the folder, name the output) and removed however
// the scope is left; a folder it cannot create is an error naming the output, and what stands at
// its path is left alone. The oracle is the file system and the messages' own wording.
TEST(IntermediateFile, FileOrFolderIsRemovedHoweverTheScopeIsLeft) {
  const fs::path dir = rayscan::test::fresh_temp_dir("rayscan_intermediate");
  const fs::path out = dir / "x.rsi";
  const std::string enospc = std::strerror(ENOSPC);
  try {
    const rayscan::IntermediateFile file(dir / ".x.rsi.las.1", out);
    std::ofstream(file.path()) << "records";
    EXPECT_EQ(rayscan::output_error(file.path(), "write failed", ENOSPC).what(), out.string() + ": write failed: " + enospc);
    const rayscan::IntermediateFile runs(dir / ".x.rsi.runs.1", out, rayscan::RemoveOnInterrupt::Kind::folder);
    ASSERT_TRUE(fs::is_directory(runs.path()));
    fs::create_directory(runs.path() / "sub");
    std::ofstream(runs.path() / "run0") << "run";
    std::ofstream(runs.path() / "sub" / "run1") << "run";
    EXPECT_EQ(rayscan::output_error(runs.path() / "run0", "write failed", ENOSPC).what(),
              out.string() + ": write failed: " + enospc);
    EXPECT_EQ(rayscan::test::entry_names(dir), (std::set<std::string>{".x.rsi.las.1", ".x.rsi.runs.1"}));
    throw std::runtime_error("left by an exception");
  } catch (const std::runtime_error&) {
  }
  EXPECT_TRUE(rayscan::test::entry_names(dir).empty());
  EXPECT_EQ(rayscan::output_of(dir / ".x.rsi.runs.1" / "run0"), dir / ".x.rsi.runs.1" / "run0");  // released

  std::ofstream(dir / "taken") << "not ours";
  std::string error;
  try {
    const rayscan::IntermediateFile runs(dir / "taken", out, rayscan::RemoveOnInterrupt::Kind::folder);
  } catch (const rayscan::OutputFileError& e) {
    error = e.what();
  }
  EXPECT_EQ(error, out.string() + ": cannot create the temporary folder: " + std::strerror(EEXIST));
  std::ifstream taken(dir / "taken");
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(taken), {}), "not ours");
  fs::remove_all(dir);
}

// A writer's message about an intermediate file told of the file the user gave: the path at the
// start replaced, any other message kept as it is.
TEST(IntermediateFile, MessagesNameTheFileTheUserGave) {
  const fs::path temp = "/d/.x.laz.las.tmp.7", out = "/d/x.laz";
  EXPECT_EQ(rayscan::temporary_named_as(temp.string() + ": no points", temp, out), "/d/x.laz: no points");
  EXPECT_EQ(rayscan::temporary_named_as("in.las: no points in " + temp.string(), temp, out),
            "in.las: no points in " + temp.string());
}
