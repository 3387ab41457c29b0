// The chunked reader (point_reader.hpp): for every data file of every format, reading in chunks of
// odd sizes gives exactly the whole-file read (whose values the format tests check against the
// files' own bytes), and an attribute subset gives the same positions with only those attributes.
#include "io_test_util.hpp"

#include "rayscan/io/point_reader.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace rayscan::test {
namespace {

std::vector<fs::path> all_data_files() {
  std::vector<fs::path> out;
  for (const auto& de : fs::recursive_directory_iterator(RAYSCAN_TEST_DATA))
    if (de.is_regular_file() && de.path().extension() != ".md") out.push_back(de.path());
  std::sort(out.begin(), out.end());
  return out;
}

PointCloud read_chunked(io::PointReader& r, std::size_t chunk) {
  PointCloud all, c;
  while (r.read(c, chunk) > 0) {
    EXPECT_LE(c.size(), chunk);
    auto app = [](auto& d, const auto& s) { d.insert(d.end(), s.begin(), s.end()); };
    app(all.positions, c.positions);
    app(all.rgb, c.rgb);
    app(all.intensity, c.intensity);
    app(all.classification, c.classification);
    app(all.gps_time, c.gps_time);
    app(all.normals, c.normals);
    if (all.scalars.empty())
      for (const auto& f : c.scalars) all.scalars.push_back({f.name, {}});
    EXPECT_EQ(all.scalars.size(), c.scalars.size());
    for (std::size_t k = 0; k < c.scalars.size() && k < all.scalars.size(); ++k) {
      EXPECT_EQ(all.scalars[k].name, c.scalars[k].name);
      app(all.scalars[k].values, c.scalars[k].values);
    }
    if (!c.rgb.empty()) {
      EXPECT_EQ(c.rgb.size(), c.size());
    }
    if (!c.intensity.empty()) {
      EXPECT_EQ(c.intensity.size(), c.size());
    }
  }
  EXPECT_EQ(r.read(c, chunk), 0u);  // stays at the end
  all.crs_wkt = r.crs_wkt();
  return all;
}

void expect_same(const PointCloud& a, const PointCloud& b, const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  for (std::size_t i = 0; i < a.size(); ++i)
    ASSERT_TRUE(a.positions[i] == b.positions[i]) << what << " point " << i;  // bit-exact doubles
  EXPECT_TRUE(a.rgb == b.rgb) << what;
  EXPECT_TRUE(a.intensity == b.intensity) << what;
  EXPECT_TRUE(a.classification == b.classification) << what;
  EXPECT_TRUE(a.gps_time == b.gps_time) << what;
  EXPECT_TRUE(a.normals == b.normals) << what;
  if (a.empty()) return;  // an empty file delivers no chunk, hence no scalar names
  ASSERT_EQ(a.scalars.size(), b.scalars.size()) << what;
  for (std::size_t k = 0; k < a.scalars.size(); ++k) {
    EXPECT_EQ(a.scalars[k].name, b.scalars[k].name) << what;
    EXPECT_TRUE(a.scalars[k].values == b.scalars[k].values) << what << " " << a.scalars[k].name;
  }
  EXPECT_EQ(a.crs_wkt, b.crs_wkt) << what;
}

TEST(PointReader, ChunksOfAnySizeEqualTheWholeRead) {
  for (const fs::path& p : all_data_files()) {
    io::FileInfo whole_info;
    const PointCloud whole = io::read_point_cloud(p, {}, &whole_info);
    for (std::size_t chunk : {std::size_t{1}, std::size_t{7}, std::size_t{4096}}) {
      if (chunk == 1 && whole.size() > 20000) continue;
      auto r = io::open_point_reader(p);
      EXPECT_EQ(r->point_count(), whole.size()) << p;
      const PointCloud c = read_chunked(*r, chunk);
      expect_same(c, whole, p.string() + " chunk " + std::to_string(chunk));
      EXPECT_EQ(r->info().notes, whole_info.notes) << p;
      EXPECT_EQ(r->info().format, whole_info.format) << p;
    }
  }
}

// ReadOptions::direct_records: the uncompressed LAS files' records read with O_DIRECT into the
// reader's two buffers (the next block in the background) equal the whole read through the map,
// chunk by chunk (blocks crossing page boundaries at every offset: chunks of 7 records, and of
// 4093, a prime, whose starts move through the pages too). Where the file system refuses O_DIRECT
// the reader falls back to the map, which would compare the map with itself: skipped there.
// Chunks of 7 only for
// files of at most 20,000 points: each read() is one O_DIRECT read of the disk and one background
// thread, so the 110,000-point files took 16,000 of each (8 s of the release suite, 289 s under
// the sanitizers) for offsets the small files and the 4093-record chunks already cover.
TEST(PointReader, DirectRecordReadsEqualTheMappedRead) {
  std::size_t files = 0;
  for (const fs::path& p : all_data_files()) {
    if (p.extension() != ".las") continue;
    const int fd = ::open(p.c_str(), O_RDONLY | O_DIRECT | O_CLOEXEC);
    if (fd < 0) GTEST_SKIP() << p << ": the file system refuses O_DIRECT (" << std::strerror(errno) << ")";
    ::close(fd);
    ++files;
    const PointCloud whole = io::read_point_cloud(p);
    for (std::size_t chunk : {std::size_t{7}, std::size_t{4093}, std::size_t{4096}}) {
      if (chunk == 7 && whole.size() > 20000) continue;
      auto r = io::open_point_reader(p, io::AttributeSet::all(), io::ReadOptions{.direct_records = true});
      expect_same(read_chunked(*r, chunk), whole, p.string() + " direct, chunk " + std::to_string(chunk));
    }
  }
  EXPECT_GT(files, 0u);
}

// LAZ through the LAS reader, chunk by chunk (reads crossing LAZ chunk boundaries): every value
// equals the plain LAS file holding the same records (shared data README: autzen_trim.laz is
// autzen_trim.las compressed).
TEST(PointReader, LazChunksEqualTheSameLas) {
  RAYSCAN_REQUIRE_FILE(las, "las/autzen_trim.las");
  RAYSCAN_REQUIRE_FILE(laz, "laz/autzen_trim.laz");
  const PointCloud whole = io::read_point_cloud(las);
  for (std::size_t chunk : {std::size_t{4093}, std::size_t{70001}}) {
    auto r = io::open_point_reader(laz);
    EXPECT_EQ(r->info().format, "LAZ");
    expect_same(read_chunked(*r, chunk), whole, "autzen_trim.laz chunk " + std::to_string(chunk));
  }
}

// A LASzip 1.x pointwise LAZ (one stream of all points, decoded in sequence by one decoder kept
// across reads): every value equals the plain LAS holding its records (tests/data/README.md),
// for reads of 1, 100 and 4096 points (the colour pass at open restarts the decoder once).
TEST(PointReader, PointwiseLazReadsInSequenceEqualTheSameLas) {
  RAYSCAN_REQUIRE_FILE(las, "las/simple.las");
  RAYSCAN_REQUIRE_FILE(laz, "laz/simple-laszip-compressor-version-1.2r0.laz");
  const PointCloud whole = io::read_point_cloud(las);
  for (std::size_t chunk : {std::size_t{1}, std::size_t{100}, std::size_t{4096}}) {
    auto r = io::open_point_reader(laz);
    EXPECT_EQ(r->info().format, "LAZ");
    expect_same(read_chunked(*r, chunk), whole, "pointwise LAZ chunk " + std::to_string(chunk));
  }
}

TEST(PointReader, AttributeSubsetKeepsPositionsAndOnlyTheAskedAttributes) {
  for (const fs::path& p : all_data_files()) {
    const PointCloud whole = io::read_point_cloud(p);
    for (const char* list : {"none", "rgb", "intensity,classification", "gps_time,scalars"}) {
      const io::AttributeSet want = io::AttributeSet::parse(list);
      auto r = io::open_point_reader(p, want);
      EXPECT_EQ((r->attributes() & want), r->attributes()) << p << " " << list;
      const PointCloud c = read_chunked(*r, 5000);
      PointCloud expect = whole;
      if (!want.has(io::Attribute::rgb)) expect.rgb.clear();
      if (!want.has(io::Attribute::intensity)) expect.intensity.clear();
      if (!want.has(io::Attribute::classification)) expect.classification.clear();
      if (!want.has(io::Attribute::gps_time)) expect.gps_time.clear();
      if (!want.has(io::Attribute::normals)) expect.normals.clear();
      if (!want.has(io::Attribute::scalars)) expect.scalars.clear();
      expect_same(c, expect, p.string() + " attributes " + list);
    }
  }
}

TEST(PointReader, LasGridReproducesPositionsFromRecordIntegers) {
  RAYSCAN_REQUIRE_FILE(p, "las/autzen_trim.las");
  auto r = io::open_point_reader(p, io::AttributeSet::none());
  const auto grid = r->integer_grid();
  ASSERT_TRUE(grid.has_value());
  const PointCloud c = read_chunked(*r, 100000);
  // Oracle: the file's own bytes (LAS 1.4 R15 table 7: X, Y, Z int32 at record offsets 0, 4, 8).
  const auto bytes = slurp(p);
  std::uint32_t off = 0;
  std::uint16_t len = 0;
  std::memcpy(&off, bytes.data() + 96, 4);
  std::memcpy(&len, bytes.data() + 105, 2);
  for (std::size_t i = 0; i < c.size(); i += 997) {
    std::int32_t x = 0;
    std::memcpy(&x, bytes.data() + off + i * len, 4);
    EXPECT_EQ(c.positions[i].x, x * grid->first.x + grid->second.x);
  }
}

TEST(PointReader, AttributeSetParsesAndRejects) {
  EXPECT_EQ(io::AttributeSet::parse("rgb,Intensity").to_string(), "rgb,intensity");
  EXPECT_EQ(io::AttributeSet::parse("all"), io::AttributeSet::all());
  EXPECT_EQ(io::AttributeSet::parse(""), io::AttributeSet::none());
  EXPECT_THROW(io::AttributeSet::parse("rgb,colour"), std::invalid_argument);
}

}  // namespace
}  // namespace rayscan::test
