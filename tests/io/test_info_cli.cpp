// `rayscan info`: the JSON agrees with the reader and the file's header; bad input gives exit
// code 2 and one line on stderr.
#include "io_test_util.hpp"

#include "rayscan/io/cloud_stats.hpp"
#include "rayscan/io/point_reader.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <cstdlib>
#include <cstring>
#include <map>
#include <sys/wait.h>

namespace rayscan::test {
namespace {

int run(const std::string& args, const fs::path& out, const fs::path& err) {
  const std::string cmd = std::string("'") + RAYSCAN_EXE + "' " + args + " >'" + out.string() + "' 2>'" + err.string() + "'";
  const int rc = std::system(cmd.c_str());
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

std::string text_of(const fs::path& p) {
  const auto b = slurp(p);
  return {b.begin(), b.end()};
}

TEST(InfoCli, CopcReportsTheOctreeFromItsHierarchy) {
  // Oracle: the hierarchy EVLR itself, walked by an independent few lines here (32-byte entries:
  // level, x, y, z, offset, byte size, point count; one page in this file).
  RAYSCAN_REQUIRE_FILE(p, "laz/lone-star.copc.laz");
  const fs::path out = temp_dir() / "copc.json", err = temp_dir() / "copc.err";
  ASSERT_EQ(run("info --json '" + p.string() + "'", out, err), 0) << text_of(err);
  const auto j = nlohmann::json::parse(text_of(out));
  EXPECT_EQ(j["format"], "COPC");
  EXPECT_EQ(j["count"], 518862);
  std::uint64_t hier_off = 0, hier_len = 0;
  for (const auto& v : j["vlrs"])
    if (v["user_id"] == "copc" && v["record_id"] == 1000) hier_off = v["offset"].get<std::uint64_t>() + 60, hier_len = v["length"];
  ASSERT_GT(hier_len, 0u);
  const auto bytes = slurp(p);
  std::map<int, std::pair<std::uint64_t, std::uint64_t>> per_level;
  for (std::uint64_t e = hier_off; e < hier_off + hier_len; e += 32) {
    std::int32_t level, count;
    std::memcpy(&level, bytes.data() + e, 4);
    std::memcpy(&count, bytes.data() + e + 28, 4);
    ASSERT_GE(count, 0) << "test assumes a single hierarchy page";
    ++per_level[level].first;
    per_level[level].second += static_cast<std::uint64_t>(count);
  }
  ASSERT_EQ(j["copc"]["depth"], per_level.size());
  for (const auto& [l, np] : per_level) {
    EXPECT_EQ(j["copc"]["nodes_per_level"][l], np.first) << "level " << l;
    EXPECT_EQ(j["copc"]["points_per_level"][l], np.second) << "level " << l;
  }
  // The text report names the COPC specification's version over the file's LAS version (header
  // bytes 24-25: major, minor).
  ASSERT_EQ(run("info '" + p.string() + "'", out, err), 0) << text_of(err);
  const std::string las_version = std::to_string(int(bytes[24])) + "." + std::to_string(int(bytes[25]));
  EXPECT_NE(text_of(out).find("format:            COPC 1.0 (LAS " + las_version + ")\n"), std::string::npos)
      << text_of(out);
}

TEST(InfoCli, JsonReportsFormatCountsBoundsAttributesAndCrs) {
  RAYSCAN_REQUIRE_FILE(p, "las/Haystack_Rock.las");
  const fs::path out = temp_dir() / "info.json", err = temp_dir() / "info.err";
  ASSERT_EQ(run("info --json '" + p.string() + "'", out, err), 0) << text_of(err);
  const auto j = nlohmann::json::parse(text_of(out));
  EXPECT_EQ(j["format"], "LAS");
  EXPECT_EQ(j["version"], "1.2");
  EXPECT_EQ(j["point_data_record_format"], 0);
  EXPECT_EQ(j["count"], 21932);
  EXPECT_EQ(j["crs"]["epsg"], 3645);
  EXPECT_EQ(j["crs"]["vertical_epsg"], 5703);
  EXPECT_NEAR(j["bounds"]["max"][2].get<double>(), 80.815, 1e-9);
  EXPECT_EQ(j["scale"][2], 0.001);
  bool has_intensity = false;
  for (const auto& a : j["attributes"]) has_intensity |= a["name"] == "intensity";
  EXPECT_TRUE(has_intensity);
}

// Strings of the file that are not UTF-8 or hold control characters: a WKT VLR with a Latin-1
// byte (0xE9) made `info --json` exit 2 with nlohmann's "invalid UTF-8 byte" naming neither file
// nor field; an escape character in the WKT reached the terminal raw. Now the JSON is valid
// (strictly parsed) with the byte replaced and a warning, and the text shows \x1b.
TEST(InfoCli, NonUtf8AndControlBytesOfTheFileAreReplacedOrEscaped) {
  RAYSCAN_REQUIRE_FILE(src, "las/autzen_trim.las");
  auto b = slurp(src);
  const std::string wkt = "PROJCS[\"NAD_1983", geog = "GEOGCS[\"GCS_North";
  const auto at = [&](const std::string& s) {
    const auto it = std::search(b.begin(), b.end(), s.begin(), s.end());
    EXPECT_NE(it, b.end()) << s;
    return static_cast<std::size_t>(it - b.begin());
  };
  b[at(geog) + 12] = 0xE9;  // Latin-1 e-acute: "GCS_\xe9orth"
  b[at(wkt) + 16] = 0x1B;   // ESC inside the WKT's name: "NAD_1983\x1bHARN"
  const fs::path bad = temp_dir() / "latin1.las", out = temp_dir() / "latin1.out", err = temp_dir() / "latin1.err";
  {
    std::ofstream f(bad, std::ios::binary);
    f.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
  }
  ASSERT_EQ(run("info --json '" + bad.string() + "'", out, err), 0) << text_of(err);
  const auto j = nlohmann::json::parse(text_of(out));  // strict: throws on invalid UTF-8
  ASSERT_TRUE(j.contains("warnings")) << j.dump(2);
  EXPECT_NE(j["warnings"][0].get<std::string>().find("not UTF-8"), std::string::npos);
  EXPECT_NE(j["crs"]["wkt"].get<std::string>().find("GCS_\xEF\xBF\xBDorth"), std::string::npos);  // U+FFFD
  ASSERT_EQ(run("info '" + bad.string() + "'", out, err), 0) << text_of(err);
  const std::string text = text_of(out);
  EXPECT_EQ(text.find('\x1b'), std::string::npos);
  EXPECT_NE(text.find("NAD_1983\\x1bHARN"), std::string::npos) << text;
}

// Colour as stored (as `pdal info`): autzen_trim stores 8-bit values in the 16-bit fields, shown
// before as the readers' x 257 rendering (10280..60652). The CRS's units, from its WKT (UNIT
// ["foot",0.3048]); and lone-star, whose CRS is geocentric (GEOCCS) over UTM-like metres 4,945 km
// from the Earth's centre, gets a warning (its GeoTIFF showed "Invalid angle"). Oracle: the
// file's own bytes.
TEST(InfoCli, ColourAsStoredUnitsAndAGeographicCrsOverProjectedCoordinates) {
  RAYSCAN_REQUIRE_FILE(p, "las/autzen_trim.las");
  const auto b = slurp(p);
  std::uint32_t off = 0, n = 0;
  std::uint16_t len = 0;
  std::memcpy(&off, b.data() + 96, 4);
  std::memcpy(&len, b.data() + 105, 2);
  std::memcpy(&n, b.data() + 107, 4);
  ASSERT_EQ(b[104], 3);  // PDRF 3: red at byte 28 of a record
  std::uint16_t lo = 65535, hi = 0;
  for (std::uint32_t i = 0; i < n; ++i) {
    std::uint16_t red = 0;
    std::memcpy(&red, b.data() + off + std::size_t{i} * len + 28, 2);
    lo = std::min(lo, red), hi = std::max(hi, red);
  }
  const fs::path out = temp_dir() / "units.json", err = temp_dir() / "units.err";
  ASSERT_EQ(run("info --json '" + p.string() + "'", out, err), 0) << text_of(err);
  const auto j = nlohmann::json::parse(text_of(out));
  bool seen = false;
  for (const auto& a : j["attributes"])
    if (a["name"] == "red") {
      seen = true;
      EXPECT_EQ(a["min"].get<double>(), lo);
      EXPECT_EQ(a["max"].get<double>(), hi);
    }
  EXPECT_TRUE(seen);
  EXPECT_EQ(j["crs"]["horizontal_unit"], "foot");
  EXPECT_FALSE(j.contains("warnings")) << j["warnings"];
  RAYSCAN_REQUIRE_FILE(copc, "laz/lone-star.copc.laz");
  ASSERT_EQ(run("info --json '" + copc.string() + "'", out, err), 0) << text_of(err);
  const auto c = nlohmann::json::parse(text_of(out));
  ASSERT_TRUE(c.contains("warnings")) << c["crs"].dump();
  EXPECT_NE(c["warnings"][0].get<std::string>().find("the CRS is geocentric (ECEF) but the points lie 4945 km"),
            std::string::npos) << c["warnings"];
}

// `info --stats`: each attribute's mean and population standard deviation, against the file's own
// bytes (autzen's red channel at byte 28 and X at byte 0 of each PDRF 3 record, summed here in
// long double); the streaming merge of chunks (Chan et al.) against one chunk; and the CRS as
// WKT2 and PROJJSON, which gdalsrsinfo (GDAL's own tool) reads back to the same PROJJSON.
TEST(InfoCli, StatsMeanAndStddevFromTheFileBytesAndCrsAsWkt2AndProjjson) {
  RAYSCAN_REQUIRE_FILE(p, "las/autzen_trim.las");
  const auto b = slurp(p);
  std::uint32_t off = 0, n = 0;
  std::uint16_t len = 0;
  double scale_x = 0, offset_x = 0;
  std::memcpy(&off, b.data() + 96, 4);
  std::memcpy(&len, b.data() + 105, 2);
  std::memcpy(&n, b.data() + 107, 4);
  std::memcpy(&scale_x, b.data() + 131, 8);
  std::memcpy(&offset_x, b.data() + 155, 8);
  long double sr = 0, sr2 = 0, sx = 0, sx2 = 0;
  for (std::uint32_t i = 0; i < n; ++i) {
    std::uint16_t red = 0;
    std::int32_t xi = 0;
    std::memcpy(&red, b.data() + off + std::size_t{i} * len + 28, 2);
    std::memcpy(&xi, b.data() + off + std::size_t{i} * len, 4);
    const long double x = (long double)(xi * scale_x + offset_x);
    sr += red, sr2 += (long double)red * red, sx += x, sx2 += x * x;
  }
  const double mean_r = double(sr / n), sd_r = double(std::sqrt(sr2 / n - (sr / n) * (sr / n)));
  const double mean_x = double(sx / n), sd_x = double(std::sqrt(sx2 / n - (sx / n) * (sx / n)));
  const fs::path out = temp_dir() / "stats.json", err = temp_dir() / "stats.err";
  ASSERT_EQ(run("info --stats --json '" + p.string() + "'", out, err), 0) << text_of(err);
  const auto j = nlohmann::json::parse(text_of(out));
  int seen = 0;
  for (const auto& a : j["attributes"]) {
    if (a["name"] == "red") {
      ++seen;
      EXPECT_EQ(a["count"], n);
      EXPECT_NEAR(a["mean"].get<double>(), mean_r, 1e-9 * mean_r);
      EXPECT_NEAR(a["stddev"].get<double>(), sd_r, 1e-7 * sd_r);
    } else if (a["name"] == "X") {
      ++seen;
      EXPECT_NEAR(a["mean"].get<double>(), mean_x, 1e-12 * mean_x);
      EXPECT_NEAR(a["stddev"].get<double>(), sd_x, 1e-6 * sd_x);
    }
  }
  EXPECT_EQ(seen, 2);
  // Without --stats the report keeps to min and max.
  ASSERT_EQ(run("info --json '" + p.string() + "'", out, err), 0) << text_of(err);
  EXPECT_FALSE(nlohmann::json::parse(text_of(out))["attributes"][0].contains("mean"));

  // Chunks of 1,000 points merge to the single pass's figures.
  const auto one = io::scan_point_cloud(*io::open_point_reader(p, io::AttributeSet::all()), 1u << 20);
  const auto many = io::scan_point_cloud(*io::open_point_reader(p, io::AttributeSet::all()), 1000);
  ASSERT_EQ(one.ranges.size(), many.ranges.size());
  for (std::size_t k = 0; k < one.ranges.size(); ++k) {
    EXPECT_EQ(one.ranges[k].count, many.ranges[k].count) << one.ranges[k].name;
    EXPECT_NEAR(one.ranges[k].mean, many.ranges[k].mean, 1e-9 * (1 + std::abs(one.ranges[k].mean))) << one.ranges[k].name;
    EXPECT_NEAR(one.ranges[k].stddev(), many.ranges[k].stddev(), 1e-7 * (1 + one.ranges[k].stddev())) << one.ranges[k].name;
  }

  // WKT2 and PROJJSON of the file's CRS; gdalsrsinfo turns the WKT2 into the same PROJJSON.
  const auto& crs = j["crs"];
  ASSERT_TRUE(crs.contains("wkt2"));
  EXPECT_EQ(crs["wkt2"].get<std::string>().rfind("PROJCRS[", 0), 0u) << crs["wkt2"];
  EXPECT_EQ(crs["projjson"]["type"], "ProjectedCRS");
  std::ofstream(temp_dir() / "crs.wkt") << crs["wkt2"].get<std::string>();
  const fs::path pj = temp_dir() / "crs.projjson";
  if (std::system(("gdalsrsinfo -o projjson '" + (temp_dir() / "crs.wkt").string() + "' > '" + pj.string() + "' 2>/dev/null").c_str()) == 0) {
    const auto g = nlohmann::json::parse(text_of(pj));
    EXPECT_EQ(g["name"], crs["projjson"]["name"]);
    EXPECT_EQ(g["conversion"], crs["projjson"]["conversion"]);
    EXPECT_EQ(g["coordinate_system"], crs["projjson"]["coordinate_system"]);
  } else {
    std::printf("gdalsrsinfo not available: PROJJSON checked against its schema's type only\n");
  }
}

TEST(InfoCli, TextReportsDroppedNanPointsAndDifferingHeaderBounds) {
  RAYSCAN_REQUIRE_FILE(pcd, "pcd/office1.pcd");
  const fs::path out = temp_dir() / "info.txt", err = temp_dir() / "info.err";
  ASSERT_EQ(run("info '" + pcd.string() + "'", out, err), 0) << text_of(err);
  const std::string t = text_of(out);
  EXPECT_NE(t.find("points:            254456 (header: 307200)"), std::string::npos) << t;
  EXPECT_NE(t.find("dropped:           52744 non-finite points"), std::string::npos) << t;
  RAYSCAN_REQUIRE_FILE(las, "las/conformance/simple1_3.las");
  ASSERT_EQ(run("info '" + las.string() + "'", out, err), 0) << text_of(err);
  EXPECT_NE(text_of(out).find("(differs)"), std::string::npos) << text_of(out);
}

TEST(InfoCli, BadFileExitsWithCode2AndOneLine) {
  const fs::path bad = temp_dir() / "bad.las";
  {
    std::ofstream o(bad, std::ios::binary);
    o << "LASF" << std::string(300, '\0');
  }
  const fs::path out = temp_dir() / "o", err = temp_dir() / "e";
  EXPECT_EQ(run("info '" + bad.string() + "'", out, err), 2);
  const std::string e = text_of(err);
  EXPECT_EQ(e.rfind("rayscan info: " + bad.string() + ": byte ", 0), 0u) << e;
  EXPECT_EQ(std::count(e.begin(), e.end(), '\n'), 1) << e;
  EXPECT_EQ(run("info /nonexistent.las", out, err), 2);
}

}  // namespace
}  // namespace rayscan::test
