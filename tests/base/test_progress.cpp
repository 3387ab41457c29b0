// The progress bar's text: the default labels are a render's, other users pass their own units.
#include "rayscan/base/progress.hpp"

#include <gtest/gtest.h>

#include <fcntl.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

using namespace rayscan;

namespace {

// Runs `f` with file descriptor 2 redirected to a file and returns what was written.
template <class F>
std::string capture_stderr(F f) {
  const std::string path = (std::filesystem::temp_directory_path() /
                            ("rayscan_progress_" + std::to_string(::getpid()) + ".txt")).string();
  std::fflush(stderr);
  const int saved = ::dup(2);
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  ::dup2(fd, 2);
  ::close(fd);
  f();
  std::fflush(stderr);
  ::dup2(saved, 2);
  ::close(saved);
  std::stringstream ss;
  ss << std::ifstream(path).rdbuf();
  std::filesystem::remove(path);
  return ss.str();
}

}  // namespace

TEST(Progress, DefaultLabelsAreTheRenderers) {
  const std::string s = capture_stderr([] {
    Progress p(2, true);
    p.tile_done(1000);
    p.tile_done(1000);  // the last item always draws
  });
  EXPECT_NE(s.find("2/2 tiles 100.0%"), std::string::npos) << s;
  EXPECT_NE(s.find(" M rays/s"), std::string::npos) << s;
}

TEST(Progress, UnitsArePassedByTheCaller) {
  const std::string s = capture_stderr([] {
    Progress p(3, true, ProgressUnits{"chunks", "points/s", 1.0, 0});
    for (int i = 0; i < 3; ++i) p.tile_done(4096);
  });
  EXPECT_NE(s.find("3/3 chunks 100.0%"), std::string::npos) << s;
  EXPECT_NE(s.find(" points/s  "), std::string::npos) << s;
  EXPECT_EQ(s.find("tiles"), std::string::npos) << s;
  EXPECT_EQ(s.find("rays/s"), std::string::npos) << s;
}

TEST(Progress, DisabledDrawsNothing) {
  const std::string s = capture_stderr([] {
    Progress p(1, false, ProgressUnits{"chunks", "points/s", 1.0, 0});
    p.tile_done(1);
    p.finish();
  });
  EXPECT_EQ(s, "");
}

// Into a file (stderr is not a terminal here): plain lines, each ending in a newline, no carriage
// return, and a final line when the last item is done.
TEST(Progress, LogFileGetsPlainLines) {
  const std::string s = capture_stderr([] {
    Progress p(4, true, ProgressUnits{"chunks", "points/s", 1.0, 0});
    for (int i = 0; i < 4; ++i) p.tile_done(10);
    p.finish();
  });
  EXPECT_EQ(s.find('\r'), std::string::npos) << s;
  EXPECT_NE(s.find("progress: 4/4 chunks 100.0%"), std::string::npos) << s;
  EXPECT_NE(s.find("done in"), std::string::npos) << s;
  ASSERT_FALSE(s.empty());
  EXPECT_EQ(s.back(), '\n');
}
