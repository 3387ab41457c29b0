// The COPC writer (rayscan/site/copc_writer.hpp) checked by independent readers: copc.js (npm
// `copc`, with laz-perf's chunk decoder) walks the hierarchy pages and decodes every node;
// laz-perf's LASZip reader decodes the whole file through the chunk table; the union of the
// nodes' records equals the input's records as a multiset; every node's points lie in its cube;
// rayscan's COPC reader and a query on the output agree with a brute force over the input.
#include "../io/io_test_util.hpp"
#include "../common/las_patch.hpp"
#include "../common/npm_tools.hpp"

#include "rayscan/io/crs.hpp"
#include "rayscan/io/las_records.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/jobs/index.hpp"
#include "rayscan/jobs/query.hpp"
#include "rayscan/jobs/translate.hpp"
#include "rayscan/site/copc.hpp"
#include "rayscan/site/copc_writer.hpp"

#include <tbb/task_arena.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <optional>
#include <random>
#include <set>
#include <sstream>

namespace rayscan::test {
namespace {

std::string text_of(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

/// One node as copc.js decoded it.
struct JsNode {
  std::int32_t level, x, y, z, count;
  std::vector<std::uint8_t> records;
};

/// Runs copcjs_read.js on `copc`: its JSON summary, and the nodes it decoded.
nlohmann::json copcjs(const fs::path& modules, const fs::path& copc, std::vector<JsNode>* nodes) {
  const fs::path bin = temp_dir() / "copcjs.nodes", js = temp_dir() / "copcjs.json";
  const std::string cmd = "node '" + std::string(RAYSCAN_SOURCE_DIR) + "/tests/site/copcjs_read.js' '" + modules.string() +
                          "' '" + copc.string() + "' '" + bin.string() + "' > '" + js.string() + "'";
  if (std::system(cmd.c_str()) != 0) {
    ADD_FAILURE() << "copc.js failed: " << cmd;
    return {};
  }
  const nlohmann::json j = nlohmann::json::parse(text_of(js));
  if (nodes != nullptr) {
    const std::vector<std::uint8_t> b = slurp(bin);
    const std::size_t len = j["record_length"];
    nodes->clear();
    for (std::size_t at = 0; at + 20 <= b.size();) {
      JsNode n;
      std::memcpy(&n.level, b.data() + at, 4);
      std::memcpy(&n.x, b.data() + at + 4, 4);
      std::memcpy(&n.y, b.data() + at + 8, 4);
      std::memcpy(&n.z, b.data() + at + 12, 4);
      std::memcpy(&n.count, b.data() + at + 16, 4);
      at += 20;
      n.records.assign(b.begin() + static_cast<std::ptrdiff_t>(at),
                       b.begin() + static_cast<std::ptrdiff_t>(at + len * static_cast<std::size_t>(n.count)));
      at += len * static_cast<std::size_t>(n.count);
      nodes->push_back(std::move(n));
    }
  }
  return j;
}

/// The comparable content of one record, whatever its PDRF: X, Y, Z, intensity, return number,
/// number of returns, classification, user data, point source id, GPS time bits, RGB (0 when
/// absent), then the extra bytes; for PDRF 6-8 simply the raw record.
std::string record_key(const std::uint8_t* p, int pdrf, std::size_t len) {
  if (pdrf >= 6) return std::string(reinterpret_cast<const char*>(p), len);
  std::string k(reinterpret_cast<const char*>(p), 14);  // X Y Z intensity
  const int core = pdrf == 0 ? 20 : pdrf == 1 ? 28 : pdrf == 2 ? 26 : 34;
  k.push_back(static_cast<char>(p[14] & 7));
  k.push_back(static_cast<char>((p[14] >> 3) & 7));
  k.push_back(static_cast<char>(p[15] & 31));
  k.push_back(static_cast<char>(p[17]));
  k.append(reinterpret_cast<const char*>(p + 18), 2);
  const char zero[8] = {};
  k.append(pdrf == 1 || pdrf == 3 ? reinterpret_cast<const char*>(p + 20) : zero, 8);
  k.append(pdrf == 2 ? reinterpret_cast<const char*>(p + 20) : pdrf == 3 ? reinterpret_cast<const char*>(p + 28) : zero, 6);
  k.append(reinterpret_cast<const char*>(p + core), len - static_cast<std::size_t>(core));
  return k;
}
/// Same for a PDRF 6/7 record written from a legacy one (the fields the legacy format has).
std::string record_key_as_legacy(const std::uint8_t* p, int legacy_pdrf, std::size_t len) {
  std::string k(reinterpret_cast<const char*>(p), 14);
  k.push_back(static_cast<char>(p[14] & 15));
  k.push_back(static_cast<char>(p[14] >> 4));
  k.push_back(static_cast<char>(p[16]));
  k.push_back(static_cast<char>(p[17]));
  k.append(reinterpret_cast<const char*>(p + 20), 2);
  k.append(reinterpret_cast<const char*>(p + 22), 8);
  const char zero[8] = {};
  const bool rgb = legacy_pdrf == 2 || legacy_pdrf == 3;
  k.append(rgb ? reinterpret_cast<const char*>(p + 30) : zero, 6);
  const std::size_t core = rgb ? 36 : 30;
  k.append(reinterpret_cast<const char*>(p + core), len - core);
  return k;
}

std::vector<std::string> keys_of(const std::vector<std::uint8_t>& recs, std::size_t len, int pdrf) {
  std::vector<std::string> k;
  for (std::size_t at = 0; at + len <= recs.size(); at += len) k.push_back(record_key(recs.data() + at, pdrf, len));
  std::sort(k.begin(), k.end());
  return k;
}

struct Case {
  const char* rel;
  int pdrf;  // expected output PDRF
};
// PDRF 7 (autzen), 6 (test1_4), 3 + extra bytes (extrabytes, deprecated array descriptors) -> 7, 8 + 3 extra bytes from LAZ
// (append-bug), 3 -> 7 (autzen_trim), 1 -> 6 (point-time), a COPC file rewritten (lone-star).
constexpr Case kCases[] = {{"las/autzen_trim_7.las", 7}, {"las/test1_4.las", 6},         {"las/extrabytes.las", 7},
                           {"laz/append-bug.laz", 8},    {"las/autzen_trim.las", 7},    {"las/point-time.las", 6},
                           {"laz/lone-star.copc.laz", 6}};

// write_copc copies a LAS input's records as they are: one whose scale takes a point beyond the
// coordinate bound (1e9) is refused with the LAS reader's own line for it (oracle: the reader's
// error on the same file) before the output exists.
TEST(CopcWriter, AnInputPointBeyondTheCoordinateBoundIsRefusedAsTheReaderRefusesIt) {
  PointCloud pc;
  pc.positions = {Vec3(0, 0, 0), Vec3(2, 0, 0), Vec3(0, 0, 0)};
  const fs::path las = temp_dir() / "copc_beyond_in.las", out = temp_dir() / "copc_beyond.copc.laz";
  write_unit_grid_las(las, pc);
  patch_las_x_scale(las, -6e8);  // point 1: 2 x -6e8 = -1.2e9
  const std::string reader = reader_error(las);
  ASSERT_NE(reader.find(": point 1: X coordinate is -1.2e+09"), std::string::npos) << reader;
  fs::remove(out);
  try {
    io::write_copc(las, out);
    ADD_FAILURE() << "written";
  } catch (const io::FormatError& e) {
    EXPECT_EQ(std::string(e.what()), reader);
  }
  EXPECT_FALSE(fs::exists(out));
}

TEST(CopcWriter, CopcJsReadsEveryNodeTheUnionIsTheInputAndNodesLieInTheirCubes) {
  std::string why;
  const fs::path modules = npm_modules(why);
  if (modules.empty()) GTEST_SKIP() << why;
  int ran = 0;
  for (const Case& c : kCases) {
    const fs::path src = data_file(c.rel);
    if (src.empty()) continue;
    ++ran;
    const io::LasRecords in = io::read_las_records(src);
    const fs::path out = temp_dir() / "w.copc.laz";
    io::CopcWriteOptions o;
    o.leaf_points = 3000;  // several levels even for the small files
    o.page_levels = 2;     // and child hierarchy pages
    const io::CopcWriteResult w = io::write_copc(src, out, o);
    EXPECT_EQ(w.pdrf, c.pdrf) << c.rel;
    EXPECT_EQ(w.record_length, in.record_length - (in.pdrf >= 6 ? 0 : (in.pdrf == 0 ? 20 : in.pdrf == 1 ? 28 : in.pdrf == 2 ? 26 : 34)) +
                                   (in.pdrf >= 6 ? 0 : (w.pdrf == 7 ? 36 : 30)))
        << c.rel << ": extra bytes kept";
    std::vector<JsNode> nodes;
    const nlohmann::json j = copcjs(modules, out, &nodes);
    ASSERT_FALSE(j.is_null()) << c.rel;
    EXPECT_EQ(j["header_points"], in.count) << c.rel;
    EXPECT_EQ(j["points"], in.count) << c.rel;
    EXPECT_EQ(j["pdrf"], w.pdrf) << c.rel;
    EXPECT_EQ(j["nodes"], w.nodes) << c.rel;
    EXPECT_EQ(j["pages"], w.pages) << c.rel;
    if (w.depth > 2) {
      EXPECT_GT(w.pages, 1u) << c.rel << ": page_levels 2 wrote one page";
    }
    EXPECT_EQ(j["points_per_level"].get<std::vector<std::uint64_t>>(), w.points_per_level) << c.rel;
    // (c) the union of the nodes' records is the input's, as a multiset
    std::vector<std::string> got;
    const std::size_t len = w.record_length;
    for (const JsNode& n : nodes)
      for (std::size_t at = 0; at < n.records.size(); at += len)
        got.push_back(in.pdrf >= 6 ? std::string(reinterpret_cast<const char*>(n.records.data() + at), len)
                                   : record_key_as_legacy(n.records.data() + at, in.pdrf, len));
    std::sort(got.begin(), got.end());
    EXPECT_TRUE(got == keys_of(in.records, in.record_length, in.pdrf)) << c.rel << ": the nodes' records differ from the input's";
    // (d) every node's points lie in its cube (copc.js's root cube, halved per level), and a
    // node with children holds at most one point per cell of its 64^3 grid: cells of edge = the
    // level's spacing (the root edge / 64, as copc.js reads the info VLR)
    const std::vector<double> cube = j["cube"];
    const double grid = 64;
    EXPECT_DOUBLE_EQ(j["spacing"].get<double>(), (cube[3] - cube[0]) / grid) << c.rel;
    std::set<std::tuple<int, int, int, int>> keys;
    for (const JsNode& n : nodes) keys.insert({n.level, n.x, n.y, n.z});
    const io::CopcInfo info = io::read_copc_info(out);
    for (const JsNode& n : nodes) {
      const double edge = (cube[3] - cube[0]) / std::ldexp(1.0, n.level);
      const double lo[3] = {cube[0] + n.x * edge, cube[1] + n.y * edge, cube[2] + n.z * edge};
      bool parent = false;
      for (int c8 = 0; c8 < 8; ++c8)
        parent = parent || keys.count({n.level + 1, 2 * n.x + (c8 & 1), 2 * n.y + ((c8 >> 1) & 1), 2 * n.z + ((c8 >> 2) & 1)});
      std::set<std::tuple<long, long, long>> cells;
      for (std::size_t at = 0; at < n.records.size(); at += len) {
        long cell[3];
        for (int k = 0; k < 3; ++k) {
          std::int32_t v;
          std::memcpy(&v, n.records.data() + at + 4 * k, 4);
          const double wv = v * info.scale[k] + info.offset[k];
          const double eps = 1e-9 * edge * std::ldexp(1.0, n.level);
          ASSERT_GE(wv, lo[k] - eps) << c.rel << " node " << n.level << "-" << n.x << "-" << n.y << "-" << n.z;
          ASSERT_LE(wv, lo[k] + edge + eps) << c.rel << " node " << n.level << "-" << n.x << "-" << n.y << "-" << n.z;
          cell[k] = std::clamp(static_cast<long>(std::floor((wv - lo[k]) / edge * grid)), 0L, static_cast<long>(grid) - 1);
        }
        if (parent) {
          EXPECT_TRUE(cells.insert({cell[0], cell[1], cell[2]}).second)
              << c.rel << ": two points in one grid cell of inner node " << n.level << "-" << n.x << "-" << n.y << "-" << n.z;
        }
      }
    }
  }
  EXPECT_GT(ran, 0);
}

TEST(CopcWriter, LazPerfDecodesTheWholeFileThroughTheChunkTable) {
  std::string why;
  const fs::path modules = npm_modules(why);
  if (modules.empty()) GTEST_SKIP() << why;
  for (const char* rel : {"las/autzen_trim_7.las", "laz/append-bug.laz", "las/extrabytes.las"}) {
    const fs::path src = data_file(rel);
    if (src.empty()) continue;
    const fs::path out = temp_dir() / "lp.copc.laz", rec = temp_dir() / "lp.rec";
    io::CopcWriteOptions o;
    o.leaf_points = 5000;
    const io::CopcWriteResult w = io::write_copc(src, out, o);
    const std::string cmd = "node '" + std::string(RAYSCAN_SOURCE_DIR) + "/tests/io/lazperf_decode.js' '" +
                            modules.string() + "' '" + out.string() + "' '" + rec.string() + "' >/dev/null";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    const io::LasRecords in = io::read_las_records(src);
    const std::vector<std::uint8_t> recs = slurp(rec);
    std::vector<std::string> got;
    for (std::size_t at = 0; at + w.record_length <= recs.size(); at += w.record_length)
      got.push_back(in.pdrf >= 6 ? std::string(reinterpret_cast<const char*>(recs.data() + at), w.record_length)
                                 : record_key_as_legacy(recs.data() + at, in.pdrf, w.record_length));
    std::sort(got.begin(), got.end());
    EXPECT_TRUE(got == keys_of(in.records, in.record_length, in.pdrf)) << rel;
    // and rayscan's own LAZ reader through the same chunk table: the same records in file order
    const io::LasRecords back = io::read_las_records(out);
    EXPECT_TRUE(back.copc);
    EXPECT_EQ(back.chunks, w.nodes);
    EXPECT_TRUE(back.records == slurp(rec)) << rel;
  }
}

TEST(CopcWriter, OwnReaderAndQueryAgreeWithABruteForceOverTheInput) {
  RAYSCAN_REQUIRE_FILE(src, "las/autzen_trim.las");
  const fs::path out = temp_dir() / "q.copc.laz";
  io::CopcWriteOptions o;
  o.leaf_points = 4000;
  o.page_levels = 3;
  const io::CopcWriteResult w = io::write_copc(src, out, o);
  const io::CopcInfo info = io::read_copc_info(out);
  EXPECT_EQ(info.nodes.size(), w.nodes);
  EXPECT_EQ(info.hierarchy_pages, w.pages);
  EXPECT_EQ(info.points_per_level, w.points_per_level);
  EXPECT_DOUBLE_EQ(info.halfsize, w.halfsize);
  EXPECT_DOUBLE_EQ(info.spacing, 2 * w.halfsize / 64);
  EXPECT_EQ(info.pdrf, 7);
  EXPECT_TRUE(io::is_copc_file(out));
  // the whole file read back: the same positions (as a multiset) as the input
  const PointCloud a = io::read_point_cloud(src, io::ReadOptions{.scalars = false});
  const PointCloud b = io::read_point_cloud(out, io::ReadOptions{.scalars = false});
  ASSERT_EQ(a.size(), b.size());
  auto sorted = [](std::vector<Vec3> v) {
    std::sort(v.begin(), v.end(), [](const Vec3& p, const Vec3& q) { return std::tie(p.x, p.y, p.z) < std::tie(q.x, q.y, q.z); });
    return v;
  };
  EXPECT_TRUE(sorted(a.positions) == sorted(b.positions));
  // rays on the COPC hierarchy (CopcIndex) against the brute force over the input cloud: the same
  // hits (t, distance, position; indices differ since the file order differs)
  const AABB box = a.bounds();
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  jobs::QueryJobOptions copc;
  copc.cloud_file = out;
  copc.cache_bytes = std::size_t{4} << 20;  // forces evictions
  for (int q = 0; q < 40; ++q)
    copc.rays.emplace_back(box.lo + Vec3(u(rng), u(rng), u(rng)) * (box.hi - box.lo),
                           Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5));
  copc.query.k = 5;
  copc.query.radius = 2.0;
  jobs::QueryJobOptions brute = copc;
  brute.cloud_file.clear();
  brute.cloud = &a;
  brute.index.type = "brute";
  const jobs::QueryJobResult rc = jobs::run_query(copc), rb = jobs::run_query(brute);
  EXPECT_EQ(rc.copc_nodes, w.nodes);
  ASSERT_EQ(rc.hits.size(), rb.hits.size());
  std::size_t flat = 0, total = 0;
  for (std::size_t r = 0; r < rc.hits.size(); ++r) {
    ASSERT_EQ(rc.hits[r].size(), rb.hits[r].size()) << "ray " << r;
    for (std::size_t k = 0; k < rc.hits[r].size(); ++k, ++flat) {
      EXPECT_EQ(rc.hits[r][k].t, rb.hits[r][k].t) << "ray " << r;
      EXPECT_EQ(rc.hits[r][k].distance, rb.hits[r][k].distance) << "ray " << r;
      EXPECT_EQ(rc.hit_positions[flat], a.positions[rb.hits[r][k].index]) << "ray " << r;
    }
    total += rc.hits[r].size();
  }
  EXPECT_GT(total, 20u);
}

TEST(CopcWriter, DeterministicWhateverTheThreads) {
  RAYSCAN_REQUIRE_FILE(src, "las/autzen_trim_7.las");
  const fs::path a = temp_dir() / "d1.copc.laz", b = temp_dir() / "d2.copc.laz", c = temp_dir() / "d3.copc.laz";
  io::CopcWriteOptions o;
  o.leaf_points = 2000;
  io::write_copc(src, a, o);
  io::write_copc(src, b, o);
  tbb::task_arena one(1);
  one.execute([&] { io::write_copc(src, c, o); });
  const auto x = slurp(a);
  EXPECT_TRUE(x == slurp(b));
  EXPECT_TRUE(x == slurp(c)) << "one thread wrote other bytes";
}

TEST(CopcWriter, HeaderVlrOrderAndInfo) {
  RAYSCAN_REQUIRE_FILE(src, "las/autzen_trim.las");
  const fs::path out = temp_dir() / "h.copc.laz";
  const io::CopcWriteResult w = io::write_copc(src, out);
  const std::vector<std::uint8_t> f = slurp(out);
  auto u16 = [&](std::size_t at) { return load_at<std::uint16_t>(f, at); };
  auto u32 = [&](std::size_t at) { return load_at<std::uint32_t>(f, at); };
  auto u64 = [&](std::size_t at) { return load_at<std::uint64_t>(f, at); };
  auto f64 = [&](std::size_t at) { return load_at<double>(f, at); };
  EXPECT_EQ(f[24], 1);
  EXPECT_EQ(f[25], 4);
  EXPECT_EQ(u16(94), 375u);
  EXPECT_EQ(f[104] & 63, 7);
  // the COPC info VLR is the first, right after the header (COPC 1.0 "Info VLR")
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(f.data() + 377), 4), "copc");
  EXPECT_EQ(u16(393), 1u);
  EXPECT_EQ(u16(395), 160u);
  EXPECT_EQ(f64(429 + 24), w.halfsize);
  EXPECT_EQ(f64(429 + 32), w.spacing);
  // the root page offset points inside the hierarchy EVLR (after its 60-byte header)
  const std::uint64_t evlr = u64(235), root = u64(429 + 40);
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(f.data() + evlr + 2), 4), "copc");
  EXPECT_EQ(u16(evlr + 18), 1000u);
  EXPECT_EQ(root, evlr + 60);
  EXPECT_EQ(u64(429 + 48) % 32, 0u);
  // gps time range: the input's
  const PointCloud pc = io::read_point_cloud(src);
  const auto [mn, mx] = std::minmax_element(pc.gps_time.begin(), pc.gps_time.end());
  EXPECT_EQ(f64(429 + 56), *mn);
  EXPECT_EQ(f64(429 + 64), *mx);
  // the second VLR is LASzip's with compressor 3 (layered) and variable chunks
  const std::size_t lz = 429 + 160;
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(f.data() + lz + 2), 14), "laszip encoded");
  EXPECT_EQ(u16(lz + 54), 3u);
  EXPECT_EQ(u32(lz + 54 + 12), 0xFFFFFFFFu);
  // a CRS: WKT bit and a WKT VLR
  if (!io::open_point_reader(src, io::AttributeSet::none())->crs_wkt().empty()) {
    EXPECT_NE(u16(6) & 16u, 0u);
    EXPECT_FALSE(io::open_point_reader(out, io::AttributeSet::none())->crs_wkt().empty());
  }
}

TEST(CopcWriter, PdrfFromTheAttributesAndExtraBytesKept) {
  // a coloured PLY -> PDRF 7 (the colourless inputs -> 6 are in the copc.js test); its scalars
  // become extra bytes
  RAYSCAN_REQUIRE_FILE(ply, "ply/text_extradim.ply");
  const fs::path out = temp_dir() / "ply.copc.laz";
  const io::CopcWriteResult w = io::write_copc(ply, out);
  const PointCloud in = io::read_point_cloud(ply), back = io::read_point_cloud(out);
  ASSERT_FALSE(in.rgb.empty()) << "the test file has colour";
  EXPECT_EQ(w.pdrf, 7);
  EXPECT_EQ(back.size(), in.size());
  for (const ScalarField& s : in.scalars)
    EXPECT_TRUE(std::any_of(back.scalars.begin(), back.scalars.end(), [&](const ScalarField& b) { return b.name == s.name; }))
        << s.name << ": the PLY's extra property is not kept as an extra byte field";
  RAYSCAN_REQUIRE_FILE(eb, "las/extrabytes.las");
  const fs::path out2 = temp_dir() / "eb.copc.laz";
  const io::CopcWriteResult w2 = io::write_copc(eb, out2);
  const io::LasRecords r = io::read_las_records(eb);
  EXPECT_EQ(w2.pdrf, 7);
  EXPECT_EQ(w2.record_length, r.record_length + 2) << "PDRF 3 (34 bytes) -> 7 (36 bytes), the extra bytes kept";
  // every extra byte field the reader sees in the input, with its values (as a multiset)
  const PointCloud a = io::read_point_cloud(eb), b = io::read_point_cloud(out2);
  ASSERT_EQ(a.size(), b.size());
  std::size_t extra_fields = 0;
  for (const ScalarField& s : a.scalars) {
    const auto it = std::find_if(b.scalars.begin(), b.scalars.end(), [&](const ScalarField& x) { return x.name == s.name; });
    ASSERT_NE(it, b.scalars.end()) << s.name;
    if (s.name == "scan_angle") continue;  // degrees from the rank vs 0.006-degree steps
    std::vector<double> u = s.values, v = it->values;
    std::sort(u.begin(), u.end());
    std::sort(v.begin(), v.end());
    EXPECT_TRUE(u == v) << s.name;
    ++extra_fields;
  }
  EXPECT_GT(extra_fields, 5u);
}

TEST(CopcWriter, AStopInAnyPhaseLeavesNoFiles) {
  // The progress callback's exception is how `rayscan index` is interrupted: the output's
  // temporary and the temporary records file of a LAZ input are removed, nothing is renamed.
  RAYSCAN_REQUIRE_FILE(src, "laz/append-bug.laz");
  for (const char* stop : {"read", "tree", "encode"}) {
    const fs::path dir = temp_dir() / (std::string("stop_") + stop);
    fs::create_directories(dir);
    io::CopcWriteOptions o;
    o.leaf_points = 2000;
    bool seen = false;
    o.progress = [&](const char* phase, std::uint64_t, std::uint64_t) {
      if (std::string(phase) == stop) {
        seen = true;
        throw std::runtime_error("stop");
      }
    };
    EXPECT_THROW(io::write_copc(src, dir / "x.copc.laz", o), std::runtime_error) << stop;
    EXPECT_TRUE(seen) << stop;
    EXPECT_TRUE(fs::is_empty(dir)) << stop << ": files left behind";
  }
}

/// Runs the rayscan program; returns its exit code, stdout and stderr in `out`/`err`.
int run_cli(const std::string& args, std::string& out, std::string& err) {
  const fs::path o = temp_dir() / "cli.out", e = temp_dir() / "cli.err";
  const std::string cmd = std::string("'") + RAYSCAN_EXE + "' " + args + " >'" + o.string() + "' 2>'" + e.string() + "'";
  const int rc = std::system(cmd.c_str());
  out = text_of(o);
  err = text_of(e);
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

/// The payload of the OGC WKT VLR (user "LASF_Projection", record 2112: LAS 1.4 R15 section
/// 2.5.1) in the LAS-family file bytes `f`, found by walking the 54-byte VLR headers from the
/// header size (byte 94) over the VLR count (byte 100); its byte offset in `at`. nullopt when the
/// file has none.
std::optional<std::string> wkt_vlr_payload(const std::vector<std::uint8_t>& f, std::size_t* at = nullptr) {
  std::size_t v = load_at<std::uint16_t>(f, 94);
  for (std::uint32_t k = load_at<std::uint32_t>(f, 100); k > 0 && v + 54 <= f.size(); --k) {
    const std::size_t len = load_at<std::uint16_t>(f, v + 20);
    const char* user = reinterpret_cast<const char*>(f.data() + v + 2);  // 16 bytes, NUL-padded
    if (std::string(user, strnlen(user, 16)) == "LASF_Projection" &&
        load_at<std::uint16_t>(f, v + 18) == 2112 && v + 54 + len <= f.size()) {
      if (at != nullptr) *at = v + 54;
      return std::string(reinterpret_cast<const char*>(f.data() + v + 54), len);
    }
    v += 54 + len;
  }
  return std::nullopt;
}

/// Whether GDAL's own gdalsrsinfo (not rayscan's CRS code) reads `wkt` (trailing NULs dropped)
/// as a CRS.
bool gdalsrsinfo_reads(std::string wkt) {
  while (!wkt.empty() && wkt.back() == '\0') wkt.pop_back();
  const fs::path p = temp_dir() / "srs.wkt";
  std::ofstream(p, std::ios::binary) << wkt;
  return std::system(("gdalsrsinfo -o wkt1 '" + p.string() + "' >/dev/null 2>&1").c_str()) == 0;
}

// The COPC writer stores a CRS only as WKT that GDAL reads, as write_las does: an input whose
// OGC WKT VLR GDAL cannot read (one with an infinite false easting) is refused with the LAS
// writer's line, naming the input, exit 2, before any file exists; a PLY whose "comment crs" GDAL
// cannot read likewise (named as the PLY, not as the intermediate LAS). Oracles: gdalsrsinfo on
// the VLR's own bytes, and the WKT VLR bytes of the input and of the output it was copied to.
TEST(CopcWriter, AnInputCrsGdalCannotReadIsRefusedAsWriteLasRefusesIt) {
  PointCloud pc;
  pc.positions = {Vec3(500000, 4100000, 10), Vec3(500001, 4100002, 11), Vec3(500003, 4100001, 12)};
  pc.crs_wkt = io::crs_wkt_from_user_input("EPSG:32610");
  const fs::path in = temp_dir() / "copc_crs_in.las", good = temp_dir() / "copc_crs_good.copc.laz";
  io::write_las(in, pc);
  // The readable WKT is copied: the output's WKT VLR holds the input's bytes, which GDAL reads.
  std::vector<std::uint8_t> b = slurp(in);
  std::size_t at = 0;
  const std::optional<std::string> wkt = wkt_vlr_payload(b, &at);
  ASSERT_TRUE(wkt.has_value()) << "write_las wrote no WKT VLR";
  ASSERT_TRUE(gdalsrsinfo_reads(*wkt));
  io::write_copc(in, good);
  EXPECT_EQ(wkt_vlr_payload(slurp(good)), wkt);
  // The same VLR overwritten in place by WKT that GDAL cannot read, NUL-padded to its length.
  const std::string bad =
      "PROJCS[\"x\",GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS 84\",6378137,298.257223563]],"
      "PRIMEM[\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433]],PROJECTION[\"Transverse_Mercator\"],"
      "PARAMETER[\"false_easting\",Inf],UNIT[\"unknown\",1E-305]]";
  ASSERT_LT(bad.size(), wkt->size());
  std::fill(b.begin() + static_cast<std::ptrdiff_t>(at), b.begin() + static_cast<std::ptrdiff_t>(at + wkt->size()), 0);
  std::copy(bad.begin(), bad.end(), b.begin() + static_cast<std::ptrdiff_t>(at));
  std::ofstream(in, std::ios::binary).write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
  ASSERT_FALSE(gdalsrsinfo_reads(*wkt_vlr_payload(slurp(in)))) << "GDAL reads the WKT: no case to test";
  const fs::path ply = temp_dir() / "copc_crs_in.ply";
  std::ofstream(ply) << "ply\nformat ascii 1.0\ncomment crs " << bad
                     << "\nelement vertex 2\nproperty double x\nproperty double y\nproperty double z\nend_header\n"
                        "0 0 0\n1 2 3\n";
  const std::string why = ": the CRS is WKT that GDAL cannot read ('" + bad.substr(0, 40) + "...'); expected a CRS GDAL reads, or none";
  const fs::path dir = temp_dir() / "copc_crs_out", out = dir / "x.copc.laz";
  fs::create_directories(dir);
  for (const fs::path& src : {in, ply}) {
    try {
      io::write_copc(src, out);
      ADD_FAILURE() << src << ": written";
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()), src.string() + why);
    }
    std::string o, err;
    for (const std::string& cmd : {"translate -q '" + src.string() + "' '" + out.string() + "'",
                                   "index -q '" + src.string() + "' -o '" + out.string() + "'"}) {
      EXPECT_EQ(run_cli(cmd, o, err), 2) << cmd;
      EXPECT_NE(err.find(src.string() + why), std::string::npos) << err;
      EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
    }
    EXPECT_TRUE(fs::is_empty(dir)) << src << ": a refused COPC write left files behind";
  }
}

TEST(CopcWriter, CliTranslateAndIndexWriteCopcAndFailCleanly) {
  RAYSCAN_REQUIRE_FILE(src, "las/autzen_trim.las");
  std::string out, err;
  const fs::path t = temp_dir() / "cli_t.copc.laz", i = temp_dir() / "cli_i.copc.laz";
  ASSERT_EQ(run_cli("translate -q '" + src.string() + "' '" + t.string() + "'", out, err), 0) << err;
  EXPECT_NE(out.find("COPC 1.0 (PDRF 7"), std::string::npos) << out;
  EXPECT_TRUE(io::is_copc_file(t));
  ASSERT_EQ(run_cli("index -q '" + src.string() + "' -o '" + i.string() + "'", out, err), 0) << err;
  EXPECT_NE(out.find("level 0: 1 nodes"), std::string::npos) << out;
  EXPECT_TRUE(slurp(t) == slurp(i)) << "translate and index wrote different COPC files";
  // over the memory budget: exit 2, one line naming the budget, nothing written
  const fs::path m = temp_dir() / "cli_m.copc.laz";
  EXPECT_EQ(run_cli("translate -q --memory 1M '" + src.string() + "' '" + m.string() + "'", out, err), 2);
  EXPECT_NE(err.find("memory budget of 0.0 GiB"), std::string::npos) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_FALSE(fs::exists(m));
  // a malformed input: exit 2, one line, no output (nor a temporary) left
  const fs::path bad = temp_dir() / "bad.las";
  {
    std::vector<std::uint8_t> b = slurp(src);
    b.resize(400);
    std::ofstream(bad, std::ios::binary).write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
  }
  const fs::path x = temp_dir() / "bad_out" / "x.copc.laz";
  fs::create_directories(x.parent_path());
  EXPECT_EQ(run_cli("translate -q '" + bad.string() + "' '" + x.string() + "'", out, err), 2);
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_TRUE(fs::is_empty(x.parent_path())) << "a failed COPC write left files behind";
  // --format las/laz under a COPC name: refused (a plain LAZ named .copc.laz would pass for COPC)
  const fs::path f = temp_dir() / "cli_f.copc.laz";
  for (const char* format : {"laz", "las"}) {
    EXPECT_EQ(run_cli(std::string("translate -q --format ") + format + " '" + src.string() + "' '" + f.string() + "'", out, err), 2);
    EXPECT_NE(err.find(std::string("--format ") + format + " writes plain LAS/LAZ, not COPC"), std::string::npos) << err;
    EXPECT_FALSE(fs::exists(f));
  }
  // index: one input only
  EXPECT_EQ(run_cli("index -q '" + src.string() + "' '" + src.string() + "' -o '" + i.string() + "'", out, err), 2);
  EXPECT_NE(err.find("one input"), std::string::npos) << err;
  // the library: the budget is checked before the points are read
  io::CopcWriteOptions none;
  none.memory_bytes = 0;
  EXPECT_THROW(io::write_copc(src, temp_dir() / "none.copc.laz", none), io::CopcMemoryError);
  EXPECT_FALSE(fs::exists(temp_dir() / "none.copc.laz"));
}

}  // namespace
}  // namespace rayscan::test
