// make_copc: writes a COPC 1.0 file from any cloud rayscan reads, for the COPC render
// benchmark on a file larger than the shared lone-star.copc.laz (bench/copc_render.sh).
//   make_copc IN.las OUT.copc.laz [max_points_per_node]
// Benchmark-only: PDAL's writers.copc is the usual tool, but Debian 12 packages no PDAL, so this
// writes the file with rayscan's own layered LAZ encoder (the one `rayscan translate` uses).
//
// Layout (COPC 1.0, copc.io): LAS 1.4 header (375 bytes), the COPC info VLR first (user "copc",
// record 1, 160 bytes), the LASzip VLR (layered-chunked, variable chunk size 0xFFFFFFFF,
// POINT14 version 3), the point data (8-byte chunk table offset, one LAZ chunk per octree node),
// the LASzip chunk table (variable chunks: point count and byte size per chunk, arithmetic
// coded; LASzip lasreadpoint.cpp read_chunk_table), and one hierarchy EVLR (user "copc", record
// 1000) holding every node in a single page. Records are PDRF 6 (30 bytes): X, Y, Z at scale
// 0.01 m, intensity and classification from the input, single return, GPS time 0.
//
// Octree (the sampling of PDAL/untwine's COPC writer, simplified): the root cube encloses the
// bounds; the points, in a fixed pseudo-random order, fill each node's 128^3 grid one point per
// cell; a node keeps all its points when it has at most max_points_per_node (default 50,000) or
// is at depth 12, else the points left over after the grid sample go to its eight children.
#include "rayscan/io/point_io.hpp"

#include "laz/encoder_v2.hpp"
#include "laz/encoder_v3.hpp"
#include "laz/laz.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <random>
#include <string>
#include <vector>

using namespace rayscan;

namespace {

template <class T>
void put(std::vector<std::uint8_t>& v, std::size_t at, T x) {
  if (v.size() < at + sizeof(T)) v.resize(at + sizeof(T), 0);
  std::memcpy(v.data() + at, &x, sizeof(T));  // little-endian host (x86-64, as the rest of io)
}
template <class T>
void add(std::vector<std::uint8_t>& v, T x) {
  put(v, v.size(), x);
}

struct Node {
  std::int32_t level, x, y, z;
  std::vector<std::uint32_t> points;  // kept in this node
};

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: make_copc IN OUT.copc.laz [max_points_per_node]\n");
    return 2;
  }
  const std::size_t max_node = argc > 3 ? std::size_t(std::atoll(argv[3])) : 50000;
  const auto t0 = std::chrono::steady_clock::now();
  const PointCloud pc = io::read_point_cloud(argv[1], io::ReadOptions{.scalars = false});
  const std::size_t n = pc.size();
  if (n == 0 || n > 0x7FFFFFFF) {
    std::fprintf(stderr, "make_copc: %s has %zu points (expected 1 to 2^31 - 1)\n", argv[1], n);
    return 2;
  }
  // Quantise (scale 0.01, offset the bounds' centre); the cube from the quantised positions.
  const AABB b0 = pc.bounds();
  const Vec3 scale(0.01), offset = glm::floor(b0.center());
  std::vector<std::int32_t> q(3 * n);
  AABB b;
  for (std::size_t i = 0; i < n; ++i) {
    Vec3 p;
    for (int a = 0; a < 3; ++a) {
      q[3 * i + a] = static_cast<std::int32_t>(std::llround((pc.positions[i][a] - offset[a]) / scale[a]));
      p[a] = q[3 * i + a] * scale[a] + offset[a];
    }
    b.expand(p);
  }
  const Vec3 center = b.center();
  const double halfsize = 0.5 * b.max_extent() + 0.01;
  constexpr int kGrid = 128, kMaxLevel = 12;
  const double spacing = 2 * halfsize / kGrid;
  // The fixed pseudo-random order of the grid sample.
  std::vector<std::uint32_t> all(n);
  for (std::uint32_t i = 0; i < n; ++i) all[i] = i;
  std::shuffle(all.begin(), all.end(), std::mt19937(12345));
  std::vector<Node> nodes;
  std::vector<std::uint32_t> stamp(std::size_t(kGrid) * kGrid * kGrid, 0xFFFFFFFFu);
  struct Work {
    std::int32_t level, x, y, z;
    std::vector<std::uint32_t> pts;
  };
  std::vector<Work> todo;
  todo.push_back({0, 0, 0, 0, std::move(all)});
  while (!todo.empty()) {
    Work w = std::move(todo.back());
    todo.pop_back();
    const std::uint32_t id = static_cast<std::uint32_t>(nodes.size());
    nodes.push_back({w.level, w.x, w.y, w.z, {}});
    if (w.pts.size() <= max_node || w.level == kMaxLevel) {
      nodes.back().points = std::move(w.pts);
      continue;
    }
    const double edge = 2 * halfsize / std::ldexp(1.0, w.level);
    const Vec3 lo = center - Vec3(halfsize) + Vec3(w.x, w.y, w.z) * edge;
    std::vector<std::uint32_t> kept, child[8];
    for (std::uint32_t i : w.pts) {
      int c[3], o = 0;
      for (int a = 0; a < 3; ++a) {
        const double u = (q[3 * i + a] * scale[a] + offset[a] - lo[a]) / edge;  // in [0, 1]
        c[a] = std::clamp(static_cast<int>(std::clamp(u, 0.0, 1.0) * kGrid), 0, kGrid - 1);
        o |= (c[a] >= kGrid / 2 ? 1 : 0) << a;
      }
      std::uint32_t& s = stamp[(std::size_t(c[2]) * kGrid + std::size_t(c[1])) * kGrid + std::size_t(c[0])];
      if (s != id) {
        s = id;
        kept.push_back(i);
      } else {
        child[o].push_back(i);
      }
    }
    nodes[id].points = std::move(kept);
    for (int o = 0; o < 8; ++o)
      if (!child[o].empty())
        todo.push_back({w.level + 1, 2 * w.x + (o & 1), 2 * w.y + ((o >> 1) & 1), 2 * w.z + (o >> 2), std::move(child[o])});
  }

  // Header, COPC info VLR (first), LASzip VLR.
  std::vector<std::uint8_t> head(375, 0);
  std::memcpy(head.data(), "LASF", 4);
  put<std::uint16_t>(head, 6, 0x10);  // global encoding: WKT (required for PDRF 6-10)
  put<std::uint8_t>(head, 24, 1);
  put<std::uint8_t>(head, 25, 4);
  std::memcpy(head.data() + 26, "rayscan bench", 13);
  std::memcpy(head.data() + 58, "rayscan make_copc", 17);
  put<std::uint16_t>(head, 94, 375);
  put<std::uint32_t>(head, 100, 2);
  put<std::uint8_t>(head, 104, 6 | 0x80);  // PDRF 6, compressed bit (LASzip convention)
  put<std::uint16_t>(head, 105, 30);
  for (int a = 0; a < 3; ++a) {
    put<double>(head, 131 + 8 * a, scale[a]);
    put<double>(head, 155 + 8 * a, offset[a]);
    put<double>(head, 179 + 16 * a, b.hi[a]);
    put<double>(head, 187 + 16 * a, b.lo[a]);
  }
  put<std::uint64_t>(head, 247, n);
  put<std::uint64_t>(head, 255, n);  // all single returns
  std::vector<std::uint8_t> vlr_copc(54, 0);
  std::memcpy(vlr_copc.data() + 2, "copc", 4);
  put<std::uint16_t>(vlr_copc, 18, 1);
  put<std::uint16_t>(vlr_copc, 20, 160);
  std::memcpy(vlr_copc.data() + 22, "COPC info", 9);
  const std::size_t info_at = head.size() + vlr_copc.size();
  std::vector<std::uint8_t> laszip;  // LASzip VLR payload (laszip.cpp LASzip::pack)
  add<std::uint16_t>(laszip, 3);     // layered-chunked
  add<std::uint16_t>(laszip, 0);     // arithmetic coder
  add<std::uint8_t>(laszip, 3);
  add<std::uint8_t>(laszip, 4);
  add<std::uint16_t>(laszip, 3);
  add<std::uint32_t>(laszip, 0);
  add<std::uint32_t>(laszip, 0xFFFFFFFFu);  // variable chunk size
  add<std::int64_t>(laszip, -1);
  add<std::int64_t>(laszip, -1);
  add<std::uint16_t>(laszip, 1);
  add<std::uint16_t>(laszip, io::laz::kPoint14);
  add<std::uint16_t>(laszip, 30);
  add<std::uint16_t>(laszip, 3);
  std::vector<std::uint8_t> vlr_lz(54, 0);
  std::memcpy(vlr_lz.data() + 2, "laszip encoded", 14);
  put<std::uint16_t>(vlr_lz, 18, 22204);
  put<std::uint16_t>(vlr_lz, 20, static_cast<std::uint16_t>(laszip.size()));
  head.insert(head.end(), vlr_copc.begin(), vlr_copc.end());
  head.resize(head.size() + 160, 0);
  head.insert(head.end(), vlr_lz.begin(), vlr_lz.end());
  head.insert(head.end(), laszip.begin(), laszip.end());
  put<std::uint32_t>(head, 96, static_cast<std::uint32_t>(head.size()));

  std::ofstream f(argv[2], std::ios::binary | std::ios::trunc);
  if (!f) {
    std::fprintf(stderr, "make_copc: cannot create %s\n", argv[2]);
    return 2;
  }
  f.write(reinterpret_cast<const char*>(head.data()), std::streamsize(head.size()));
  std::uint64_t at = head.size() + 8;
  f.write("\0\0\0\0\0\0\0\0", 8);  // chunk table offset, patched below
  // One chunk per node with points.
  struct Entry {
    std::int32_t level, x, y, z;
    std::uint64_t offset;
    std::int32_t bytes, count;
  };
  std::vector<Entry> entries;
  io::laz::LayeredChunkEncoder enc(6, 0);
  std::vector<std::uint8_t> recs, chunk;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> table;  // count, bytes
  for (const Node& nd : nodes) {
    Entry e{nd.level, nd.x, nd.y, nd.z, 0, 0, 0};
    if (!nd.points.empty()) {
      recs.assign(nd.points.size() * 30, 0);
      for (std::size_t k = 0; k < nd.points.size(); ++k) {
        const std::uint32_t i = nd.points[k];
        std::uint8_t* r = recs.data() + 30 * k;
        std::memcpy(r, &q[3 * i], 12);
        const std::uint16_t inten = pc.intensity.empty() ? 0 : pc.intensity[i];
        std::memcpy(r + 12, &inten, 2);
        r[14] = 0x11;  // return 1 of 1
        r[16] = pc.classification.empty() ? 1 : pc.classification[i];
      }
      chunk.clear();
      enc.encode(recs.data(), nd.points.size(), 30, chunk);
      f.write(reinterpret_cast<const char*>(chunk.data()), std::streamsize(chunk.size()));
      e.offset = at;
      e.bytes = static_cast<std::int32_t>(chunk.size());
      e.count = static_cast<std::int32_t>(nd.points.size());
      table.emplace_back(static_cast<std::uint32_t>(nd.points.size()), static_cast<std::uint32_t>(chunk.size()));
      at += chunk.size();
    }
    entries.push_back(e);
  }
  // Chunk table (variable chunks: count in context 0, bytes in context 1, each against the last).
  const std::uint64_t table_at = at;
  std::vector<std::uint8_t> t;
  add<std::uint32_t>(t, 0);
  add<std::uint32_t>(t, static_cast<std::uint32_t>(table.size()));
  {
    io::laz::ArithmeticEncoder ae(t);
    io::laz::IntegerCompressor ic(32, 2);
    std::int32_t pc_prev = 0, pb_prev = 0;
    for (const auto& [cnt, bytes] : table) {
      ic.compress(ae, pc_prev, static_cast<std::int32_t>(cnt), 0);
      pc_prev = static_cast<std::int32_t>(cnt);
      ic.compress(ae, pb_prev, static_cast<std::int32_t>(bytes), 1);
      pb_prev = static_cast<std::int32_t>(bytes);
    }
    ae.done();
  }
  f.write(reinterpret_cast<const char*>(t.data()), std::streamsize(t.size()));
  at += t.size();
  // Hierarchy EVLR: one page with every node.
  const std::uint64_t evlr_at = at;
  std::vector<std::uint8_t> ev(60, 0);
  std::memcpy(ev.data() + 2, "copc", 4);
  put<std::uint16_t>(ev, 18, 1000);
  put<std::uint64_t>(ev, 20, entries.size() * 32);
  std::memcpy(ev.data() + 28, "EPT hierarchy", 13);
  for (const Entry& e : entries) {
    add<std::int32_t>(ev, e.level);
    add<std::int32_t>(ev, e.x);
    add<std::int32_t>(ev, e.y);
    add<std::int32_t>(ev, e.z);
    add<std::uint64_t>(ev, e.offset);
    add<std::int32_t>(ev, e.bytes);
    add<std::int32_t>(ev, e.count);
  }
  f.write(reinterpret_cast<const char*>(ev.data()), std::streamsize(ev.size()));
  // Patch: chunk table offset, EVLR start and count, COPC info.
  std::vector<std::uint8_t> info(160, 0);
  for (int a = 0; a < 3; ++a) put<double>(info, 8 * a, center[a]);
  put<double>(info, 24, halfsize);
  put<double>(info, 32, spacing);
  put<std::uint64_t>(info, 40, evlr_at + 60);
  put<std::uint64_t>(info, 48, entries.size() * 32);
  f.seekp(std::streamoff(head.size()));
  f.write(reinterpret_cast<const char*>(&table_at), 8);
  std::vector<std::uint8_t> ehdr;
  put<std::uint64_t>(ehdr, 0, evlr_at);
  put<std::uint32_t>(ehdr, 8, 1);
  f.seekp(235);
  f.write(reinterpret_cast<const char*>(ehdr.data()), 12);
  f.seekp(std::streamoff(info_at));
  f.write(reinterpret_cast<const char*>(info.data()), 160);
  f.close();
  if (!f) {
    std::fprintf(stderr, "make_copc: write to %s failed\n", argv[2]);
    return 2;
  }
  int depth = 0;
  for (const Node& nd : nodes) depth = std::max(depth, nd.level + 1);
  std::printf("make_copc: %zu points, %zu nodes (%zu chunks), depth %d, %.1f s\n", n, nodes.size(), table.size(), depth,
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  return 0;
}
