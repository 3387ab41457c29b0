// Outputs under hostile conditions, through the command line: a full file system, a read-only
// directory, a read-only output file, and an output that is one of the inputs. Each case must
// exit 2 with one line naming the output, leave the old output byte-identical and no temporary
// (".<name>.tmp.<pid>") behind. The full file system is a real tmpfs mounted by the test (root
// only; skipped with a message otherwise); the read-only directory is a read-only tmpfs mount as
// root (root writes through a 0555 folder) or a 0555 folder otherwise.
#include "../common/run_command.hpp"
#include "jobs_test_util.hpp"

#include <sys/mount.h>
#include <sys/stat.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

namespace rayscan::test {
namespace {

namespace fs = std::filesystem;

const std::string kBin = RAYSCAN_BIN;

/// The names in `dir` that look like an output's temporary (".<name>.tmp.<pid>").
std::vector<std::string> temporaries(const fs::path& dir) {
  std::vector<std::string> out;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().filename().string().find(".tmp.") != std::string::npos) out.push_back(e.path().filename().string());
  return out;
}

/// One line on the output, exit 2, the line naming `name`.
void expect_one_line_error(const CommandResult& r, const std::string& name, const std::string& why) {
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  EXPECT_NE(r.out.find(name), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(why), std::string::npos) << r.out;
}

/// A tmpfs mounted at `dir` for the test's lifetime (root only).
struct Tmpfs {
  fs::path dir;
  bool mounted = false;
  Tmpfs(fs::path d, const std::string& options, unsigned long flags = 0) : dir(std::move(d)) {
    fs::create_directories(dir);
    mounted = ::geteuid() == 0 && ::mount("tmpfs", dir.c_str(), "tmpfs", flags, options.c_str()) == 0;
  }
  ~Tmpfs() {
    if (mounted) ::umount2(dir.c_str(), MNT_DETACH);
  }
};

/// Fills the file system of `dir` with a filler file until a write fails (ENOSPC).
void fill(const fs::path& dir) {
  std::FILE* f = std::fopen((dir / "filler").c_str(), "wb");
  ASSERT_NE(f, nullptr);
  std::vector<char> block(4096, 'x');
  while (std::fwrite(block.data(), 1, block.size(), f) == block.size() && std::fflush(f) == 0) {
  }
  std::fclose(f);
  // What is left is less than a block: top it up a byte at a time.
  f = std::fopen((dir / "filler2").c_str(), "wb");
  if (f != nullptr) {
    while (std::fputc('x', f) != EOF && std::fflush(f) == 0) {
    }
    std::fclose(f);
  }
}

const fs::path& cloud() {
  static const fs::path p = data_file("las/autzen_trim.las");
  return p;
}

// A render, its JPEG, a viewshed raster with its PNG preview and a translate onto a full file
// system: exit 2, one line naming the output, the old output kept, no temporary left.
TEST(OutputsCli, FullFileSystemFailsCleanlyAndKeepsTheOldOutput) {
  const Tmpfs full(temp_dir() / "full", "size=256k");
  if (!full.mounted) GTEST_SKIP() << "needs root to mount a tmpfs (full file system); skipped";
  const std::vector<std::string> outputs = {"r.png", "r.jpg", "v.tif", "t.laz"};
  for (const std::string& name : outputs) {
    std::ofstream(full.dir / name) << "OLD " << name;
    std::ofstream(full.dir / ("v.png")) << "OLD v.png";
  }
  fill(full.dir);
  const std::string render = kBin + " render " + quoted(cloud()) + " -q --spp 1 --width 300 --out ";
  for (const std::string& name : {std::string("r.png"), std::string("r.jpg")}) {
    SCOPED_TRACE(name);
    expect_one_line_error(run_command(render + quoted(full.dir / name)), name, "No space left on device");
    EXPECT_EQ(file_bytes(full.dir / name), "OLD " + name);
  }
  {
    const CommandResult r = run_command(kBin + " visibility " + quoted(cloud()) +
                                        " -q --observer 636500,849200,500 --cell 5 --raster " + quoted(full.dir / "v.tif"));
    // GDAL's failure in the project's form "<output>: <what>: <cause>", the cause the system's.
    expect_one_line_error(r, ": " + (full.dir / "v.tif").string() + ": ", std::string(": ") + std::strerror(ENOSPC) + "\n");
    EXPECT_EQ(file_bytes(full.dir / "v.tif"), "OLD v.tif");
    EXPECT_EQ(file_bytes(full.dir / "v.png"), "OLD v.png");
  }
  expect_one_line_error(run_command(kBin + " translate -q " + quoted(cloud()) + " " + quoted(full.dir / "t.laz")), "t.laz",
                        "write");
  EXPECT_EQ(file_bytes(full.dir / "t.laz"), "OLD t.laz");
  EXPECT_EQ(temporaries(full.dir), std::vector<std::string>{});
}

// Every writer of point outputs on a full file system names the output given and the cause, never
// the hidden file it was writing when the disk filled (an output's temporary, the uncompressed LAS
// of a LAZ output, COPC records, an import's temporary index): one line, exit 2, old output kept.
TEST(OutputsCli, FullFileSystemErrorsNameTheOutputNotATemporary) {
  const Tmpfs full(temp_dir() / "full_names", "size=100k");
  if (!full.mounted) GTEST_SKIP() << "needs root to mount a tmpfs (full file system); skipped";
  const std::string in = quoted(cloud());
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"x.rsi", kBin + " index -q " + in + " -o "},
      {"x.las", kBin + " translate -q " + in + " "},
      {"x.laz", kBin + " translate -q " + in + " "},
      {"x.copc.laz", kBin + " translate -q " + in + " "},
      {"v.laz", kBin + " visibility -q " + in + " --observer 636500,849200,500 --out "},
      {"x.sqlite", kBin + " db import -q " + in + " -o "},
  };
  for (const auto& [name, command] : cases) {
    SCOPED_TRACE(name);
    const fs::path out = full.dir / name;
    std::ofstream(out) << "OLD";
    const CommandResult r = run_command(command + quoted(out));
    expect_one_line_error(r, ": " + out.string() + ": ", std::strerror(ENOSPC));
    EXPECT_EQ(r.out.find(".tmp."), std::string::npos) << r.out;
    EXPECT_EQ(r.out.find("/."), std::string::npos) << r.out;  // no hidden file named
    EXPECT_EQ(file_bytes(out), "OLD");
    fs::remove(out);
    EXPECT_TRUE(fs::is_empty(full.dir));
  }
}

// Standard output on a device that refuses every write (/dev/full: ENOSPC, as a full disk under
// a redirection): every command that prints its result exits 2 with one line on standard error,
// never 0 with its output lost; the same commands exit 0 into /dev/null.
TEST(OutputsCli, StandardOutputThatCannotBeWrittenFails) {
  if (!fs::exists("/dev/full")) GTEST_SKIP() << "no /dev/full on this system; skipped";
  const fs::path dir = temp_dir() / "stdout";
  fs::create_directories(dir);
  std::ofstream(dir / "rays.csv") << "ox,oy,oz,dx,dy,dz\n636500,849200,1000,0,0,-1\n";
  const std::vector<std::string> commands = {
      kBin + " info " + quoted(cloud()),
      kBin + " info --json " + quoted(cloud()),
      kBin + " query --cloud " + quoted(cloud()) + " --rays " + quoted(dir / "rays.csv") + " --radius 1000 --threads 1 -q",
      kBin + " query --cloud " + quoted(cloud()) + " --rays " + quoted(dir / "rays.csv") + " --radius 1000 --threads 1 -q -o -",
      kBin + " render " + quoted(cloud()) + " --print-scene",
      kBin + " --version",
      kBin + " --help",
  };
  for (const std::string& cmd : commands) {
    SCOPED_TRACE(cmd);
    ASSERT_EQ(run_command(cmd + " > /dev/null", false).code, 0);
    const CommandResult r = run_command("(" + cmd + " > /dev/full)");  // (its standard error captured)
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
    EXPECT_NE(r.out.find("standard output: write failed"), std::string::npos) << r.out;
  }
  fs::remove_all(dir);
}

// An output directory this process cannot write is refused before the work (the message names
// the directory), and nothing is created.
TEST(OutputsCli, ReadOnlyDirectoryIsRefusedFirst) {
  const fs::path dir = temp_dir() / "ro";
  Tmpfs ro(dir, "size=64k", MS_RDONLY);
  if (!ro.mounted) {
    if (::geteuid() == 0) GTEST_SKIP() << "cannot mount a read-only tmpfs; skipped";
    fs::permissions(dir, fs::perms::owner_read | fs::perms::owner_exec);
  }
  const CommandResult r =
      run_command(kBin + " render " + quoted(cloud()) + " -q --spp 1 --width 64 --out " + quoted(dir / "r.png"));
  expect_one_line_error(r, "r.png", "cannot write in directory");
  const CommandResult v = run_command(kBin + " visibility " + quoted(cloud()) + " -q --observers 636500,849200 --out " +
                                      quoted(dir / "v.las"));
  expect_one_line_error(v, "v.las", "cannot write in directory");
  if (!ro.mounted) fs::permissions(dir, fs::perms::owner_all);
  EXPECT_TRUE(fs::is_empty(dir));
  // A directory whose permission bits let root in but whose file system takes no new files
  // (procfs): refused before the work too (the computation's report lines never appear).
  if (fs::exists("/proc/self")) {
    const CommandResult p =
        run_command(kBin + " visibility " + quoted(cloud()) + " --observers 636500,849200 --out /proc/v.las");
    expect_one_line_error(p, "/proc/v.las", "cannot write in directory '/proc'");
    EXPECT_EQ(p.out.find("line of sight"), std::string::npos) << p.out;
  }
}

// A replaced read-only output keeps its mode (as `cp` onto an existing file does).
TEST(OutputsCli, ReplacedOutputKeepsItsMode) {
  const fs::path dir = temp_dir() / "mode";
  fs::create_directories(dir);
  const fs::path out = dir / "t.laz";
  std::ofstream(out) << "OLD";
  ::chmod(out.c_str(), 0444);
  const CommandResult r = run_command(kBin + " translate " + quoted(cloud()) + " " + quoted(out));
  ASSERT_EQ(r.code, 0) << r.out;
  struct stat st {};
  ASSERT_EQ(::stat(out.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 07777, 0444u);
  EXPECT_NE(file_bytes(out), "OLD");
  fs::remove_all(dir);
}

// An output that is one of the inputs (same path, another spelling, a hard link) is refused
// before anything is read or written; the input stays byte-identical.
TEST(OutputsCli, OutputThatIsAnInputIsRefused) {
  const fs::path dir = temp_dir() / "same";
  fs::create_directories(dir);
  const fs::path las = dir / "q.las";
  fs::copy_file(cloud(), las, fs::copy_options::overwrite_existing);
  fs::create_hard_link(las, dir / "link.las");
  const std::string before = file_bytes(las);
  {
    std::ofstream r(dir / "rays.csv");
    r << "ox,oy,oz,dx,dy,dz\n636500,849200,1000,0,0,-1\n";
  }
  const std::string same = "is the same file as the input";
  expect_one_line_error(run_command(kBin + " query --cloud " + quoted(las) + " --rays " + quoted(dir / "rays.csv") +
                                    " --radius 1 --out " + quoted(las)),
                        "q.las", same);
  expect_one_line_error(run_command(kBin + " query --cloud " + quoted(las) + " --rays " + quoted(dir / "rays.csv") +
                                    " --radius 1 --out " + quoted(dir / "." / "link.las")),
                        "link.las", same);
  expect_one_line_error(run_command(kBin + " db import " + quoted(las) + " -o " + quoted(las)), "q.las", same);
  expect_one_line_error(run_command(kBin + " translate " + quoted(las) + " " + quoted(dir / "link.las")), "link.las", same);
  EXPECT_EQ(file_bytes(las), before);
  EXPECT_EQ(temporaries(dir), std::vector<std::string>{});
  fs::remove_all(dir);
}

// A GeoTIFF carries the cloud's CRS: a LAS whose WKT VLR GDAL cannot read and that has no GeoKeys
// to fall back on is refused before any work by each command that writes one (an ortho map, a
// visibility raster, a solar raster), one line naming the input and exit 2, where the GeoTIFF
// writer refused it after the whole run naming no file. Nothing is written, no temporary left.
TEST(OutputsCli, GeoTiffOfAnUnreadableCrsIsRefusedNamingTheInput) {
  const fs::path dir = temp_dir() / "unreadable_crs";
  fs::create_directories(dir);
  const fs::path las = dir / "bad_crs.las";
  std::ofstream(las, std::ios::binary) << las_with_unreadable_wkt(false);
  const std::string in = quoted(las), why = "the CRS is WKT that GDAL cannot read ('XROJCS[";
  const std::string commands[] = {
      "render " + in + " --ortho-map 1 --dsm " + quoted(dir / "dsm.tif") + " -o " + quoted(dir / "map.tif"),
      "visibility " + in + " --sky-rays 4 --raster " + quoted(dir / "sky.tif") + " --cell 1 --out " + quoted(dir / "sky.las"),
      "solar " + in + " --at 2026-06-21T12:00 --latitude 41 --longitude -96 --raster " + quoted(dir / "sun.tif") +
          " --cell 1",
      "solar " + in + " --at 2026-06-21T12:00 --raster " + quoted(dir / "sun.tif") + " --cell 1",
  };
  for (const std::string& c : commands) {
    SCOPED_TRACE(c);
    expect_one_line_error(run_command(kBin + " " + c), las.string() + ": " + why, "expected a CRS GDAL reads, or none");
    std::vector<std::string> left;
    for (const auto& e : fs::directory_iterator(dir)) left.push_back(e.path().filename().string());
    EXPECT_EQ(left, std::vector<std::string>{"bad_crs.las"});
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace rayscan::test
