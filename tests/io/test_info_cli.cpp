// `rayscan info`: the JSON agrees with the reader and the file's header; bad input gives exit
// code 2 and one line on stderr.
#include "io_test_util.hpp"

#include "rayscan/io/cloud_stats.hpp"
#include "rayscan/io/point_reader.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <cstdlib>
#include <cstring>
#include <map>
#include <sstream>
#include <utility>
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
// byte (0xE9) must not stop `info --json` (nlohmann's dump throws "invalid UTF-8 byte", naming
// neither file nor field), and an escape character in the WKT must not reach the terminal raw:
// the JSON is valid (strictly parsed) with the byte replaced and a warning, and the text shows
// \x1b.
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

/// The whitespace-separated values after `label` on its line of `text` ("" when absent).
std::vector<std::string> values_of(const std::string& text, const std::string& label) {
  const std::size_t at = text.find("\n" + label);
  if (at == std::string::npos) return {};
  const std::size_t b = at + 1 + label.size(), e = text.find('\n', b);
  std::istringstream in(text.substr(b, e - b));
  std::vector<std::string> v;
  for (std::string t; in >> t;) v.push_back(t);
  return v;
}

/// Digits after the decimal point of `t` (0 without one).
int decimals_of(const std::string& t) {
  const std::size_t dot = t.find('.');
  return dot == std::string::npos ? 0 : static_cast<int>(t.size() - dot - 1);
}

// The text report prints the LAS offsets and scales exactly (they read back bit-identical to the
// header's doubles: lone-star's y offset 4918360.74375 once printed as 4918360.744), and the
// bounds and the X, Y, Z ranges with the decimals of the scale (0.00025: 5), to within float
// rounding of the header's own min/max. Oracle: the header bytes (LAS 1.4 R15 table 3: scale at
// 131, offset at 155, max/min x y z at 179..227).
TEST(InfoCli, TextPrintsOffsetsExactlyAndCoordinatesToTheScalesResolution) {
  RAYSCAN_REQUIRE_FILE(p, "laz/lone-star.copc.laz");
  const auto b = slurp(p);
  const fs::path out = temp_dir() / "lone.txt", err = temp_dir() / "lone.err";
  ASSERT_EQ(run("info '" + p.string() + "'", out, err), 0) << text_of(err);
  const std::string t = text_of(out);
  const auto scale = values_of(t, "scale:"), offset = values_of(t, "offset:");
  const auto lo = values_of(t, "bounds min:"), hi = values_of(t, "bounds max:");
  ASSERT_EQ(scale.size(), 3u) << t;
  ASSERT_EQ(offset.size(), 3u) << t;
  ASSERT_EQ(lo.size(), 3u) << t;
  ASSERT_EQ(hi.size(), 3u) << t;
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(std::strtod(scale[k].c_str(), nullptr), load_at<double>(b, 131 + 8 * k)) << scale[k];
    EXPECT_EQ(std::strtod(offset[k].c_str(), nullptr), load_at<double>(b, 155 + 8 * k)) << offset[k];
    ASSERT_EQ(load_at<double>(b, 131 + 8 * k), 0.00025);
    EXPECT_EQ(decimals_of(lo[k]), 5) << lo[k];
    EXPECT_EQ(decimals_of(hi[k]), 5) << hi[k];
    EXPECT_NEAR(std::strtod(hi[k].c_str(), nullptr), load_at<double>(b, 179 + 16 * k), 1e-9) << hi[k];
    EXPECT_NEAR(std::strtod(lo[k].c_str(), nullptr), load_at<double>(b, 187 + 16 * k), 1e-9) << lo[k];
  }
  // The X row of the attributes: the same numbers as the bounds.
  const auto x = values_of(t, "  X");
  ASSERT_EQ(x.size(), 2u) << t;
  EXPECT_EQ(x[0], lo[0]);
  EXPECT_EQ(x[1], hi[0]);
}

/// A decimal written as text ("0.005", "-2.5"): its digits without the point, as an integer, and
/// the number of digits after the point.
struct DecimalText {
  std::int64_t digits = 0;
  int decimals = 0;
};
DecimalText decimal_text_of(const std::string& t) {
  const std::size_t dot = t.find('.');
  std::string d = t;
  if (dot != std::string::npos) d.erase(dot, 1);
  return {std::stoll(d), dot == std::string::npos ? 0 : static_cast<int>(t.size() - dot - 1)};
}

/// The value with `decimals` decimals whose digits, without the point, are `units` ("-6.775" for
/// -6775 and 3): decimal text made with integers only.
std::string fixed_point_text(std::int64_t units, int decimals) {
  std::int64_t p = 1;
  for (int i = 0; i < decimals; ++i) p *= 10;
  const std::int64_t a = units < 0 ? -units : units;
  std::string frac = std::to_string(a % p);
  frac.insert(0, static_cast<std::size_t>(decimals) - frac.size(), '0');
  std::string t = units < 0 ? "-" : "";
  t += std::to_string(a / p);
  if (decimals > 0) t += '.', t += frac;
  return t;
}

// A LAS grid whose offset has more decimals than its scale (x: scale 0.01, offset 0.005, points at
// x.xx5) prints its bounds and X, Y, Z ranges with the offset's decimals, not rounded off the grid
// to the scale's (123.455 once printed as 123.45 or 123.46), in the file's text report and in its
// index file's; the JSON keeps the exact doubles. Oracle: the file is built here (LAS 1.2, PDRF 0:
// ASPRS LAS 1.4 R15 table 3 offsets, 20-byte records) and each expected text is made from the
// record's integer and the scale and offset written as decimal text, with integers only.
TEST(InfoCli, BoundsPrintWithTheDecimalsOfAnOffsetFinerThanTheScale) {
  const std::array<std::string, 3> scale_text = {"0.01", "0.001", "0.01"};
  const std::array<std::string, 3> offset_text = {"0.005", "-20.0005", "100"};
  const std::vector<std::array<std::int32_t, 3>> ints = {{12345, -4321, 150}, {-678, 99999, -25}, {1000000, 7, 3}};
  const std::uint32_t n = static_cast<std::uint32_t>(ints.size());
  std::vector<std::uint8_t> b(227, 0);
  std::memcpy(&b[0], "LASF", 4);
  b[24] = 1, b[25] = 2;
  store_at<std::uint16_t>(b, 94, 227);          // header size
  store_at<std::uint32_t>(b, 96, 227);          // offset to the points (no VLRs)
  b[104] = 0;                                   // PDRF 0
  store_at<std::uint16_t>(b, 105, 20);          // record length
  store_at<std::uint32_t>(b, 107, n);           // legacy point count
  store_at<std::uint32_t>(b, 111, n);           // all first returns
  std::array<std::int32_t, 3> lo_int{}, hi_int{};
  for (int k = 0; k < 3; ++k) {
    store_at<double>(b, 131 + 8 * k, std::strtod(scale_text[k].c_str(), nullptr));
    store_at<double>(b, 155 + 8 * k, std::strtod(offset_text[k].c_str(), nullptr));
    lo_int[k] = hi_int[k] = ints[0][k];
    for (const auto& p : ints) lo_int[k] = std::min(lo_int[k], p[k]), hi_int[k] = std::max(hi_int[k], p[k]);
  }
  // X * scale + offset in double, as ASPRS defines the coordinates (and the header's min and max).
  const auto coordinate = [&](std::int32_t v, int k) {
    return static_cast<double>(v) * load_at<double>(b, 131 + 8 * k) + load_at<double>(b, 155 + 8 * k);
  };
  for (int k = 0; k < 3; ++k) {
    store_at<double>(b, 179 + 16 * k, coordinate(hi_int[k], k));
    store_at<double>(b, 187 + 16 * k, coordinate(lo_int[k], k));
  }
  for (const auto& p : ints) {
    const std::size_t at = b.size();
    b.resize(at + 20, 0);
    for (int k = 0; k < 3; ++k) store_at<std::int32_t>(b, at + 4 * static_cast<std::size_t>(k), p[k]);
    b[at + 14] = 0x09;  // return 1 of 1
  }
  const fs::path las = temp_dir() / "offset_grid.las";
  std::ofstream(las, std::ios::binary).write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));

  // The expected text of grid integer `v` on axis k: in units of 10^-d, d the larger of the scale's
  // and the offset's decimals, v * scale + offset is an integer.
  const auto grid_text = [&](std::int32_t v, int k) {
    const DecimalText s = decimal_text_of(scale_text[k]), o = decimal_text_of(offset_text[k]);
    const int d = std::max(s.decimals, o.decimals);
    std::int64_t ps = 1, po = 1;
    for (int i = s.decimals; i < d; ++i) ps *= 10;
    for (int i = o.decimals; i < d; ++i) po *= 10;
    return fixed_point_text(std::int64_t{v} * s.digits * ps + o.digits * po, d);
  };
  const std::vector<std::string> want_lo = {grid_text(lo_int[0], 0), grid_text(lo_int[1], 1), grid_text(lo_int[2], 2)};
  const std::vector<std::string> want_hi = {grid_text(hi_int[0], 0), grid_text(hi_int[1], 1), grid_text(hi_int[2], 2)};
  ASSERT_EQ(want_lo[0], "-6.775");  // the oracle itself: -678 * 0.01 + 0.005
  ASSERT_EQ(want_hi[1], "79.9985");  // 99999 * 0.001 - 20.0005

  const fs::path out = temp_dir() / "offset_grid.out", err = temp_dir() / "offset_grid.err";
  ASSERT_EQ(run("info '" + las.string() + "'", out, err), 0) << text_of(err);
  std::string t = text_of(out);
  EXPECT_EQ(values_of(t, "bounds min:"), want_lo) << t;
  EXPECT_EQ(values_of(t, "bounds max:"), want_hi) << t;
  const char* names[] = {"  X", "  Y", "  Z"};
  for (int k = 0; k < 3; ++k)
    EXPECT_EQ(values_of(t, names[k]), (std::vector<std::string>{want_lo[k], want_hi[k]})) << t;

  ASSERT_EQ(run("info --json '" + las.string() + "'", out, err), 0) << text_of(err);
  const auto j = nlohmann::json::parse(text_of(out));
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(j["bounds"]["min"][k].get<double>(), coordinate(lo_int[k], k)) << k;
    EXPECT_EQ(j["bounds"]["max"][k].get<double>(), coordinate(hi_int[k], k)) << k;
  }

  // Its index file stores the LAS integers on the same grid and prints its bounds alike.
  const fs::path rsi = temp_dir() / "offset_grid.rsi";
  ASSERT_EQ(run("index -q '" + las.string() + "' -o '" + rsi.string() + "'", out, err), 0) << text_of(err);
  ASSERT_EQ(run("info '" + rsi.string() + "'", out, err), 0) << text_of(err);
  t = text_of(out);
  ASSERT_NE(t.find("positions:         las_int32"), std::string::npos) << t;
  EXPECT_EQ(values_of(t, "bounds min:"), want_lo) << t;
  EXPECT_EQ(values_of(t, "bounds max:"), want_hi) << t;
}

/// Brute force over a LAS file's own point records (uncompressed, any PDRF): the box of
/// X * scale + offset per axis, in double as the LAS specification defines the coordinates.
AABB las_points_box(const std::vector<std::uint8_t>& b) {
  const std::uint32_t off = load_at<std::uint32_t>(b, 96);
  const std::uint16_t len = load_at<std::uint16_t>(b, 105);
  const std::uint32_t n = load_at<std::uint32_t>(b, 107);
  AABB box;
  for (std::uint32_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      const double v = static_cast<double>(load_at<std::int32_t>(b, off + std::size_t{i} * len + 4 * k)) *
                           load_at<double>(b, 131 + 8 * k) +
                       load_at<double>(b, 155 + 8 * k);
      box.lo[k] = std::min(box.lo[k], v);
      box.hi[k] = std::max(box.hi[k], v);
    }
  return box;
}

// `info` of an index file reports the exact bounds its header stores (not the root node's float
// box), in JSON and as text; `info` and `index` apply one rule to a LAS header's box: autzen's
// header stores max x 637179.2200000001 for points whose largest x decodes to 637179.22 (half a
// step is 0.005), so info says it does not differ and a several-run index build (whose grid comes
// from the headers) trusts it, with no note; a header one step off is reported by both. Oracle:
// the LAS file's own records (las_points_box) and header bytes.
TEST(InfoCli, IndexFileBoundsAreExactAndInfoAndIndexJudgeTheLasHeaderAlike) {
  RAYSCAN_REQUIRE_FILE(las, "las/autzen_trim.las");
  auto b = slurp(las);
  const AABB want = las_points_box(b);
  const fs::path rsi = temp_dir() / "bounds.rsi", out = temp_dir() / "bounds.out", err = temp_dir() / "bounds.err";
  ASSERT_EQ(run("index '" + las.string() + "' -o '" + rsi.string() + "' --memory 1M", out, err), 0) << text_of(err);
  // Several sort runs: the runs' grid comes from the header.
  EXPECT_EQ(text_of(out).find(" 1 sort runs"), std::string::npos) << text_of(out);
  EXPECT_EQ(text_of(err).find("note:"), std::string::npos) << text_of(err);
  ASSERT_EQ(run("info --json '" + las.string() + "'", out, err), 0) << text_of(err);
  EXPECT_FALSE(nlohmann::json::parse(text_of(out))["header_bounds"]["differs"].get<bool>());

  ASSERT_EQ(run("info --json '" + rsi.string() + "'", out, err), 0) << text_of(err);
  const auto j = nlohmann::json::parse(text_of(out));
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(j["bounds"]["min"][k].get<double>(), want.lo[k]) << k;
    EXPECT_EQ(j["bounds"]["max"][k].get<double>(), want.hi[k]) << k;
  }
  ASSERT_EQ(run("info '" + rsi.string() + "'", out, err), 0) << text_of(err);
  char line[256];
  std::snprintf(line, sizeof line, "\nbounds min:        %.2f %.2f %.2f\nbounds max:        %.2f %.2f %.2f\n", want.lo.x,
                want.lo.y, want.lo.z, want.hi.x, want.hi.y, want.hi.z);
  EXPECT_NE(text_of(out).find(line), std::string::npos) << text_of(out);

  // The header's max x one step (0.01) too large: both say so.
  store_at<double>(b, 179, load_at<double>(b, 179) + 0.01);
  const fs::path off = temp_dir() / "off_by_one_step.las";
  std::ofstream(off, std::ios::binary).write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
  ASSERT_EQ(run("info --json '" + off.string() + "'", out, err), 0) << text_of(err);
  EXPECT_TRUE(nlohmann::json::parse(text_of(out))["header_bounds"]["differs"].get<bool>());
  ASSERT_EQ(run("index '" + off.string() + "' -o '" + rsi.string() + "' --memory 1M", out, err), 0) << text_of(err);
  // The note is a line of its own, prefixed as every other line of the command.
  EXPECT_NE(("\n" + text_of(err)).find("\nrayscan index: note: the LAS headers' bounds differ from the points' bounds"),
            std::string::npos)
      << text_of(err);
  // -q: no progress and no note.
  ASSERT_EQ(run("index -q '" + off.string() + "' -o '" + rsi.string() + "' --memory 1M", out, err), 0) << text_of(err);
  EXPECT_EQ(text_of(err), "");
}

// The CRS's name, as GDAL reads it from the WKT, beside its EPSG code (text) and as crs.name
// (JSON), for a cloud and for its index file. Oracle: the name in the WKT VLR's own bytes
// (PROJCS["<name>", ...).
TEST(InfoCli, CrsNameFromTheWktInTextAndJson) {
  RAYSCAN_REQUIRE_FILE(las, "las/autzen_trim.las");
  const auto b = slurp(las);
  const std::string bytes(b.begin(), b.end()), key = "PROJCS[\"";
  const std::size_t at = bytes.find(key);
  ASSERT_NE(at, std::string::npos);
  const std::string name = bytes.substr(at + key.size(), bytes.find('"', at + key.size()) - at - key.size());
  ASSERT_FALSE(name.empty());
  const fs::path out = temp_dir() / "crs.out", err = temp_dir() / "crs.err", rsi = temp_dir() / "crs.rsi";
  ASSERT_EQ(run("info '" + las.string() + "'", out, err), 0) << text_of(err);
  EXPECT_NE(text_of(out).find("\nCRS:               " + name + " (no EPSG code) from WKT VLR\n"), std::string::npos)
      << text_of(out);
  ASSERT_EQ(run("info --json '" + las.string() + "'", out, err), 0) << text_of(err);
  EXPECT_EQ(nlohmann::json::parse(text_of(out))["crs"]["name"], name);
  ASSERT_EQ(run("index -q '" + las.string() + "' -o '" + rsi.string() + "'", out, err), 0) << text_of(err);
  ASSERT_EQ(run("info --json '" + rsi.string() + "'", out, err), 0) << text_of(err);
  EXPECT_EQ(nlohmann::json::parse(text_of(out))["crs"]["name"], name);
}

// The "CRS:" line of a text report without where the CRS came from (" from GeoKeys"), and the
// "units:" and "warning:" lines.
std::vector<std::string> crs_lines(const std::string& report) {
  std::vector<std::string> lines;
  std::istringstream in(report);
  for (std::string l; std::getline(in, l);) {
    if (l.rfind("CRS:", 0) == 0) lines.push_back(l.substr(0, l.rfind(" from ")));
    if (l.rfind("units:", 0) == 0 || l.rfind("warning:", 0) == 0) lines.push_back(l);
  }
  return lines;
}

// Key id -> value of the GeoKeys held in their entry (location 0) of a LAS file's
// GeoKeyDirectoryTag VLR (LASF_Projection 34735), read from the bytes: VLR headers of 54 bytes
// after the public header (LAS 1.4 R15 section 2.5: record id at 18, length at 20), the directory
// {version, revision, minor, count} then {id, location, count, value} (GeoTIFF 1.0 section 2.4).
std::map<int, int> geokeys(const std::vector<std::uint8_t>& b) {
  auto u16 = [&](std::size_t at) { return int(b[at] | (b[at + 1] << 8)); };
  std::uint32_t vlrs = 0;
  std::memcpy(&vlrs, b.data() + 100, 4);
  std::map<int, int> keys;
  for (std::size_t at = std::size_t(u16(94)), v = 0; v < vlrs; ++v) {
    const std::size_t data = at + 54, len = std::size_t(u16(at + 20));
    if (std::string(reinterpret_cast<const char*>(b.data() + at + 2), 16).rfind("LASF_Projection", 0) == 0 &&
        u16(at + 18) == 34735)
      for (int k = 0; k < u16(data + 6); ++k)
        if (u16(data + 8 + 8 * k + 2) == 0) keys[u16(data + 8 + 8 * k)] = u16(data + 8 + 8 * k + 6);
    at = data + len;
  }
  return keys;
}

// `info` of an index file describes its CRS as `info` of the file it was built from: the same
// name, EPSG codes, units and warnings (text and JSON), although the index keeps only the WKT.
// Haystack_Rock's CRS comes from GeoKeys (oracle: the codes in its GeoKeyDirectoryTag bytes,
// compound with a vertical CRS), lone-star.copc's from a WKT VLR (geocentric over projected
// coordinates: a warning), and a PLY written here carries WGS 84 (AUTHORITY EPSG 4326) over
// coordinates that are not degrees (a warning).
TEST(InfoCli, IndexFileDescribesItsCrsAsItsSourceDoes) {
  RAYSCAN_REQUIRE_FILE(haystack, "las/Haystack_Rock.las");
  RAYSCAN_REQUIRE_FILE(copc, "laz/lone-star.copc.laz");
  const std::map<int, int> keys = geokeys(slurp(haystack));
  ASSERT_TRUE(keys.count(3072) && keys.count(4096));  // ProjectedCSTypeGeoKey, VerticalCSTypeGeoKey
  const fs::path ply = temp_dir() / "wgs84.ply";
  std::ofstream(ply) << "ply\nformat ascii 1.0\ncomment crs GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS 84\","
                        "6378137,298.257223563,AUTHORITY[\"EPSG\",\"7030\"]],AUTHORITY[\"EPSG\",\"6326\"]],PRIMEM["
                        "\"Greenwich\",0,AUTHORITY[\"EPSG\",\"8901\"]],UNIT[\"degree\",0.0174532925199433,AUTHORITY["
                        "\"EPSG\",\"9122\"]],AUTHORITY[\"EPSG\",\"4326\"]]\nelement vertex 3\nproperty double x\n"
                        "property double y\nproperty double z\nend_header\n515368.6 4918340.4 2322.9\n"
                        "515401.0 4918381.1 2338.6\n515380.5 4918360.2 2330.1\n";
  struct Case {
    fs::path file;
    std::string label;  // in the CRS line
    bool warns;
  };
  const Case cases[] = {
      {haystack, "(EPSG:" + std::to_string(keys.at(3072)) + " + EPSG:" + std::to_string(keys.at(4096)) + " vertical)",
       false},
      {copc, "unnamed (no EPSG code)", true},
      {ply, "WGS 84 (EPSG:4326)", true},
  };
  const fs::path out = temp_dir() / "crs_rsi.out", err = temp_dir() / "crs_rsi.err", rsi = temp_dir() / "crs.rsi";
  for (const Case& c : cases) {
    SCOPED_TRACE(c.file.string());
    ASSERT_EQ(run("info '" + c.file.string() + "'", out, err), 0) << text_of(err);
    const std::vector<std::string> source = crs_lines(text_of(out));
    ASSERT_EQ(run("info --json '" + c.file.string() + "'", out, err), 0) << text_of(err);
    const auto sj = nlohmann::json::parse(text_of(out));
    ASSERT_EQ(run("index -q '" + c.file.string() + "' -o '" + rsi.string() + "'", out, err), 0) << text_of(err);
    ASSERT_EQ(run("info '" + rsi.string() + "'", out, err), 0) << text_of(err);
    const std::string index_text = text_of(out);
    ASSERT_EQ(run("info --json '" + rsi.string() + "'", out, err), 0) << text_of(err);
    const auto ij = nlohmann::json::parse(text_of(out));

    ASSERT_FALSE(source.empty());
    EXPECT_NE(source[0].find(c.label), std::string::npos) << source[0];
    EXPECT_EQ(source[1].rfind("units:", 0), 0u) << source[1];
    EXPECT_EQ(source.size() == 3 && source[2].rfind("warning:", 0) == 0, c.warns) << ::testing::PrintToString(source);
    EXPECT_EQ(crs_lines(index_text), source) << index_text;
    EXPECT_NE(index_text.find(" from index file\n"), std::string::npos) << index_text;
    for (const char* key : {"name", "epsg", "vertical_epsg", "horizontal_unit", "vertical_unit", "wkt"})
      EXPECT_EQ(ij["crs"].value(key, nlohmann::json()), sj["crs"].value(key, nlohmann::json())) << key;
    EXPECT_EQ(ij.value("warnings", nlohmann::json()), sj.value("warnings", nlohmann::json()));
  }
}

// The "units:" line of a CRS given as WKT (oracle: the UNIT nodes written here, and the EPSG
// registry's units). A local (engineering) CRS's x and y are in its linear unit; a vertical unit
// is named only where the CRS has a vertical part: a projected CRS alone states none, a compound
// one states its vertical part's, whatever the horizontal unit.
TEST(InfoCli, UnitsOfLocalProjectedAndCompoundCrss) {
  const std::string geogcs = "GEOGCS[\"NAD83\",DATUM[\"North_American_Datum_1983\",SPHEROID[\"GRS 1980\",6378137,"
                             "298.257222101]],PRIMEM[\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433]]";
  const std::string projcs = "PROJCS[\"NAD83(HARN) / Oregon GIC Lambert (ft)\"," + geogcs +
                             ",PROJECTION[\"Lambert_Conformal_Conic_2SP\"],PARAMETER[\"latitude_of_origin\",41.75],"
                             "PARAMETER[\"central_meridian\",-120.5],PARAMETER[\"standard_parallel_1\",43],"
                             "PARAMETER[\"standard_parallel_2\",45.5],PARAMETER[\"false_easting\",1312335.958],"
                             "PARAMETER[\"false_northing\",0],UNIT[\"foot\",0.3048]]";
  const std::string vert_cs = "VERT_CS[\"NAVD88 height\",VERT_DATUM[\"North American Vertical Datum 1988\",2005],"
                              "UNIT[\"metre\",1],AXIS[\"Gravity-related height\",UP]]";
  const std::pair<std::string, std::string> cases[] = {
      {"LOCAL_CS[\"site grid\",LOCAL_DATUM[\"arbitrary\",32767],UNIT[\"foot\",0.3048],AXIS[\"Easting\",EAST],"
       "AXIS[\"Northing\",NORTH]]",
       "units:             foot (horizontal)"},
      {projcs, "units:             foot (horizontal)"},
      {"COMPD_CS[\"Oregon ft + NAVD88 height\"," + projcs + "," + vert_cs + "]",
       "units:             foot (horizontal), metre (vertical)"},
  };
  const fs::path ply = temp_dir() / "units.ply", out = temp_dir() / "units.out", err = temp_dir() / "units.err";
  for (const auto& [wkt, units] : cases) {
    SCOPED_TRACE(wkt);
    std::ofstream(ply) << "ply\nformat ascii 1.0\ncomment crs " << wkt
                       << "\nelement vertex 1\nproperty double x\nproperty double y\nproperty double z\nend_header\n"
                          "1312000 400000 100\n";
    ASSERT_EQ(run("info '" + ply.string() + "'", out, err), 0) << text_of(err);
    const std::vector<std::string> lines = crs_lines(text_of(out));
    ASSERT_GE(lines.size(), 2u) << text_of(out);
    EXPECT_EQ(lines[1], units);
  }
}

// A file without points: "bounds" is null in the JSON (a key a script can rely on), and the
// text has no bounds lines. Oracle: the header's point count (bytes 107-110) is 0.
TEST(InfoCli, EmptyFileJsonBoundsIsNull) {
  RAYSCAN_REQUIRE_FILE(las, "las/no-points-1.3.las");
  ASSERT_EQ(load_at<std::uint32_t>(slurp(las), 107), 0u);
  const fs::path out = temp_dir() / "empty.out", err = temp_dir() / "empty.err";
  ASSERT_EQ(run("info --json '" + las.string() + "'", out, err), 0) << text_of(err);
  const auto j = nlohmann::json::parse(text_of(out));
  EXPECT_EQ(j["count"], 0);
  ASSERT_TRUE(j.contains("bounds"));
  EXPECT_TRUE(j["bounds"].is_null());
  ASSERT_EQ(run("info '" + las.string() + "'", out, err), 0) << text_of(err);
  EXPECT_EQ(text_of(out).find("bounds min:"), std::string::npos) << text_of(out);
}

// A LAS or LAZ file whose scale puts a point beyond the coordinate bound (1e9 world units) is
// refused by `info` with exit code 2 and one line naming the file, the point, the axis, the value
// and the bound; the same file with its own scale reads, points at +-1e8 included. Oracle: the
// stored integers are the coordinates themselves (scale 1, offset 0, chosen here), so point 1's
// X becomes 1 x 1e290 + 0 once the header's X scale (byte 131, outside the LAZ compression) is
// overwritten.
TEST(InfoCli, ScaleThatPutsAPointBeyondTheCoordinateBoundExitsWith2) {
  PointCloud cloud;
  cloud.positions = {Vec3(0, 0, 0), Vec3(1, 2, 3), Vec3(1e8, -1e8, 1e8)};
  io::LasWriteOptions opt;
  opt.scale = Vec3(1.0);
  opt.offset = Vec3(0.0);
  opt.has_offset = true;
  for (const std::string ext : {".las", ".laz"}) {
    const fs::path p = temp_dir() / ("beyond_bound" + ext), out = temp_dir() / "bound.out", err = temp_dir() / "bound.err";
    io::write_las(p, cloud, opt);
    ASSERT_EQ(run("info --json '" + p.string() + "'", out, err), 0) << ext << ": " << text_of(err);
    const auto j = nlohmann::json::parse(text_of(out));
    EXPECT_EQ(j["bounds"]["max"][0].get<double>(), 1e8) << ext;
    EXPECT_EQ(j["bounds"]["min"][1].get<double>(), -1e8) << ext;
    auto b = slurp(p);
    ASSERT_EQ(load_at<double>(b, 131), 1.0) << ext;
    store_at<double>(b, 131, 1e290);
    std::ofstream(p, std::ios::binary | std::ios::trunc).write(reinterpret_cast<const char*>(b.data()),
                                                               static_cast<std::streamsize>(b.size()));
    EXPECT_EQ(run("info '" + p.string() + "'", out, err), 2) << ext << ": " << text_of(out);
    const std::string e = text_of(err);
    EXPECT_EQ(e.rfind("rayscan info: " + p.string() + ": byte ", 0), 0u) << e;
    EXPECT_NE(e.find(": point 1: X coordinate is 1e+290 (stored integer 1 x scale 1e+290 + offset 0; expected "
                     "within +-1e+09, the coordinate bound in world units)"),
              std::string::npos)
        << e;
    EXPECT_EQ(std::count(e.begin(), e.end(), '\n'), 1) << e;
  }
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
