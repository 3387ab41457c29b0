// The index job (rayscan/jobs/index.hpp) on a real file; oracle: the cloud read by the io reader
// and the index file read back through its memory map.
#include "rayscan/base/atomic_file.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/jobs/index.hpp"
#include "rayscan/site/index_file.hpp"

#include <gtest/gtest.h>

#include "jobs_test_util.hpp"

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

using namespace rayscan;
using rayscan::test::data_file;
using rayscan::test::fields_of_option_error;
using rayscan::test::file_bytes;
using rayscan::test::option_fields;
using rayscan::test::temp_dir;
namespace fs = std::filesystem;

namespace {

jobs::IndexJobOptions index_options(const fs::path& out) {
  jobs::IndexJobOptions o;
  o.inputs = {data_file("las/point-color.las")};
  o.output = out;
  return o;
}

/// The files in `dir` (names).
std::vector<std::string> entries(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  return names;
}

}  // namespace

TEST(IndexJob, IndexHoldsEveryPointOfTheFile) {
  const fs::path out = temp_dir() / "point_color.rsi";
  jobs::IndexJobOptions o = index_options(out);
  o.attributes = "id";
  o.memory = "1M";
  const jobs::IndexJobResult r = jobs::run_index(o);
  const PointCloud cloud = io::read_point_cloud(o.inputs[0]);
  ASSERT_GT(cloud.size(), 0u);
  EXPECT_EQ(r.output, out);
  EXPECT_EQ(r.stats.points, cloud.size());
  EXPECT_EQ(r.stats.file_bytes, fs::file_size(out));
  EXPECT_EQ(r.stats.attributes, io::AttributeSet::parse("id"));
  const io::MappedIndex idx = io::MappedIndex::open(out);
  ASSERT_EQ(idx.positions().size(), cloud.size());
  ASSERT_TRUE(idx.has_ids());
  std::vector<bool> seen(cloud.size(), false);
  for (std::size_t s = 0; s < cloud.size(); ++s) {
    const std::size_t id = idx.ids()[s];
    ASSERT_LT(id, cloud.size());
    EXPECT_FALSE(seen[id]) << "id " << id << " stored twice";
    seen[id] = true;
    EXPECT_EQ(idx.positions()[s], cloud.positions[id]) << "slot " << s;
  }
}

TEST(IndexJob, AllMeansEveryAttributeAnIndexStores) {
  const fs::path all = temp_dir() / "all.rsi", listed = temp_dir() / "listed.rsi";
  jobs::IndexJobOptions a = index_options(all), b = index_options(listed);
  a.attributes = "all";
  b.attributes = "id,rgb,intensity,classification,gps_time";  // (the list `rayscan index --help` documents)
  const jobs::IndexJobResult ra = jobs::run_index(a), rb = jobs::run_index(b);
  EXPECT_EQ(ra.stats.attributes, rb.stats.attributes);
  EXPECT_TRUE(ra.stats.attributes.has(io::Attribute::id));
  EXPECT_EQ(file_bytes(all), file_bytes(listed));
  // "all" inside a list is AttributeSet::parse's: every attribute a reader knows, which the build
  // refuses, naming the field.
  jobs::IndexJobOptions c = index_options(temp_dir() / "c.rsi");
  c.attributes = "id,all";
  EXPECT_EQ(fields_of_option_error([&] { jobs::run_index(c); }), std::vector<std::string>{"attributes"});
}

TEST(IndexJob, SameFileForAnyThreadCount) {
  const fs::path one = temp_dir() / "t1.rsi", every = temp_dir() / "t0.rsi";
  jobs::IndexJobOptions a = index_options(one), b = index_options(every);
  a.control.threads = 1;
  a.memory = b.memory = "1M";
  jobs::run_index(a);
  jobs::run_index(b);
  EXPECT_EQ(file_bytes(one), file_bytes(every));
}

TEST(IndexJob, BadOptionsThrowAndWriteNothing) {
  const fs::path dir = temp_dir() / "bad_index";
  fs::create_directories(dir);
  jobs::IndexJobOptions o = index_options(dir / "site.idx");
  EXPECT_THROW(jobs::run_index(o), OptionError);  // not .rsi
  o.output = dir / "site.rsi";
  o.memory = "1000";  // below the build's minimum: named as IndexBuildOptions::memory_bytes
  EXPECT_EQ(fields_of_option_error([&] { jobs::run_index(o); }), std::vector<std::string>{"memory_bytes"});
  o.memory = "10Q";
  EXPECT_THROW(jobs::run_index(o), std::invalid_argument);
  o.memory = "4G";
  o.attributes = "colour";
  EXPECT_THROW(jobs::run_index(o), std::invalid_argument);
  o.attributes = "none";
  o.config.layout = OctreeLayout::layered;
  EXPECT_EQ(fields_of_option_error([&] { jobs::run_index(o); }), std::vector<std::string>{"layout"});
  EXPECT_TRUE(entries(dir).empty());
}

// A temporary folder that does not exist is refused (the rule db import's temporary index meets
// too), before anything is written, and it is not created: a mistyped --temp-dir must not leave a
// chain of new folders behind. The error names the option, not the hidden file it would have
// held. Both outputs: the sort runs of an index file, the records file of a COPC output (PDRF 2
// is converted into one).
TEST(IndexJob, MissingTempDirIsRefusedAndNotCreated) {
  const fs::path dir = temp_dir() / "missing_temp_dir";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path missing = dir / "nx" / "a";
  for (const char* name : {"site.rsi", "site.copc.laz"}) {
    SCOPED_TRACE(name);
    jobs::IndexJobOptions o = index_options(dir / name);
    o.temp_dir = missing;
    std::string what;
    try {
      jobs::run_index(o);
    } catch (const OptionError& e) {
      EXPECT_EQ(option_fields(e), std::vector<std::string>{"temp_dir"});
      what = e.what();
    }
    EXPECT_EQ(what, "temp_dir '" + missing.string() + "': not an existing folder");
    EXPECT_TRUE(entries(dir).empty());
  }
  fs::remove_all(dir);
}

// What a front end's cancel does: the progress callback throws, the exception reaches the caller
// unchanged and the build leaves neither output nor sort runs.
TEST(IndexJob, ProgressCallbackCancels) {
  struct Cancelled {};
  const fs::path dir = temp_dir() / "cancel";
  fs::create_directories(dir);
  jobs::IndexJobOptions o = index_options(dir / "site.rsi");
  int calls = 0;
  o.progress = [&calls](const char*, std::uint64_t, std::uint64_t) {
    ++calls;
    throw Cancelled{};
  };
  EXPECT_THROW(jobs::run_index(o), Cancelled);
  EXPECT_GT(calls, 0);
  EXPECT_TRUE(entries(dir).empty());
}
