// write_copc(): the file assembly of a COPC 1.0 file, see rayscan/site/copc_writer.hpp.
// Layout (COPC 1.0 specification, copc.io): LAS 1.4 header (375 bytes); the COPC info VLR as the
// first VLR (its payload at byte 429, section "Info VLR"); the LASzip VLR (section "LAZ": the
// layered-chunked compressor with variable chunks); the other VLRs; the 8-byte chunk table
// offset and one LAZ chunk per node (section "Hierarchy": each entry gives its chunk's offset
// and size); the chunk table; the hierarchy EVLR (user "copc", record 1000) holding the pages;
// the input's other EVLRs. The entry layout and the info VLR fields are the ones CopcInfo and
// CopcNode (rayscan/site/copc.hpp) read.
#include "rayscan/site/copc_writer.hpp"

#include "atomic_writer.hpp"
#include "bytes.hpp"
#include "copc_build.hpp"
#include "las/las_header.hpp"
#include "laz/encoder_v3.hpp"
#include "laz/laz.hpp"
#include "rayscan/base/version.hpp"
#include "rayscan/octree/position_view.hpp"
#include "rayscan/site/copc.hpp"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <utility>
#include <cstring>
#include <limits>
#include <optional>

namespace rayscan::io {

namespace {

using detail::load_le;

/// Little-endian byte buffer being built (the io library's append_le / append_fixed).
struct Bytes {
  std::vector<std::uint8_t> b;
  template <class T>
  void put(T v) {
    detail::append_le(b, v);
  }
  void fixed(const std::string& s, std::size_t n) { detail::append_fixed(b, s, n); }
  void raw(const void* p, std::size_t n) {
    const auto* c = static_cast<const std::uint8_t*>(p);
    b.insert(b.end(), c, c + n);
  }
};

/// A VLR (LAS 1.4 section 2.5) or EVLR (section 2.7) with its payload.
void put_vlr(Bytes& o, const copc::CarriedVlr& v, bool extended) {
  detail::append_vlr_header(o.b, v.user, v.record, v.payload.size(), v.description, extended);
  o.raw(v.payload.data(), v.payload.size());
}

/// GPS time as an unsigned key whose order is the doubles' (negatives reversed below the
/// positives; NaNs at the ends), a total order for sorting a node's records.
std::uint64_t time_key(const std::uint8_t* rec) {
  const auto u = load_le<std::uint64_t>(rec + 22);
  return (u >> 63) != 0 ? ~u : u | (std::uint64_t{1} << 63);
}

/// One hierarchy page: entries for nodes (index into the tree's nodes) and references to child
/// pages (index into the page list), in pre-order.
struct Page {
  struct Entry {
    std::size_t node;
    std::ptrdiff_t child_page;  // -1: the node's own entry
  };
  std::vector<Entry> entries;
  std::uint64_t offset = 0;  // absolute file offset
};

/// Splits the pre-order node list into pages (COPC 1.0 "Hierarchy pages"): a page starts at the
/// root and at every node whose level is a multiple of `levels` (0: one page); the parent page
/// holds an entry with point count -1 and the child page's range under that node's key, the
/// child page the node's own entry.
std::vector<Page> make_pages(const std::vector<copc::Node>& nodes, unsigned levels) {
  const std::size_t n = nodes.size();
  std::vector<std::size_t> end(n);  // one past the last node of each subtree (pre-order)
  {
    std::vector<std::size_t> stack;
    for (std::size_t i = 0; i < n; ++i) {
      while (!stack.empty() && nodes[stack.back()].level >= nodes[i].level) end[stack.back()] = i, stack.pop_back();
      stack.push_back(i);
    }
    for (std::size_t i : stack) end[i] = n;
  }
  std::vector<Page> pages(1);
  std::vector<std::size_t> roots{0};
  for (std::size_t p = 0; p < roots.size(); ++p) {
    const std::size_t r = roots[p];
    std::vector<Page::Entry> e{{r, -1}};
    for (std::size_t i = r + 1; i < end[r];) {
      if (levels > 0 && nodes[i].level % static_cast<int>(levels) == 0) {
        e.push_back({i, static_cast<std::ptrdiff_t>(roots.size())});
        roots.push_back(i);
        pages.emplace_back();
        i = end[i];
      } else {
        e.push_back({i, -1});
        ++i;
      }
    }
    pages[p].entries = std::move(e);
  }
  return pages;
}

/// The records' extremes (`st`, integers) decode within +-kMaxCoordinate, or nothing is written:
/// a LAS/LAZ input whose scale takes a point beyond the bound is refused with the LAS reader's
/// own line for its first such point (detail::checked_las_position at the byte the reader names,
/// from the input's point offset and record length), which a copy of the records would otherwise
/// carry into a file every reader refuses. Other inputs reach here through their readers, which
/// refuse such points first.
void refuse_beyond_bound(const std::filesystem::path& in, const copc::Records& r, const copc::RecordStats& st) {
  bool within = true;
  for (int k = 0; k < 3; ++k)
    within = within && std::abs(las_coordinate(st.lo[k], r.scale[k], r.offset[k])) <= kMaxCoordinate &&
             std::abs(las_coordinate(st.hi[k], r.scale[k], r.offset[k])) <= kMaxCoordinate;
  if (within) return;
  const std::string name = in.string();
  for (std::uint64_t i = 0; i < r.count; ++i)
    (void)detail::checked_las_position(name, r.in_point_offset + i * r.in_record_length, i,
                                       r.bytes + i * r.record_length, r.scale, r.offset);
}

}  // namespace

CopcWriteResult write_copc(const std::filesystem::path& in, const std::filesystem::path& out,
                           const CopcWriteOptions& options) {
  CopcWriteOptions opt = options;
  if (opt.temp_dir.empty()) opt.temp_dir = out.has_parent_path() ? out.parent_path() : std::filesystem::path(".");
  const copc::Records r = copc::read_records(in, out, opt);
  const copc::Tree t = copc::build_tree(r, opt);
  const copc::RecordStats& st = t.stats;
  const std::size_t rec = r.record_length;
  refuse_beyond_bound(in, r, st);
  const std::size_t extra = rec - static_cast<std::size_t>(detail::pdrf_length(r.pdrf));

  // VLRs: the info VLR first (its offsets patched once the hierarchy is placed), LASzip, WKT,
  // the input's others.
  std::vector<copc::CarriedVlr> vlrs;
  vlrs.push_back({"copc", 1, "copc info", std::vector<std::uint8_t>(160, 0)});
  vlrs.push_back({"laszip encoded", 22204, "by rayscan (LASzip 3.4 items)", laz::laszip_vlr_payload(r.pdrf, extra, 0xFFFFFFFFu)});
  std::vector<copc::CarriedVlr> evlrs_after;
  if (!r.crs_wkt.empty()) {
    copc::CarriedVlr w{"LASF_Projection", 2112, "OGC WKT", std::vector<std::uint8_t>(r.crs_wkt.begin(), r.crs_wkt.end())};
    w.payload.push_back(0);
    (w.payload.size() > 0xFFFF ? evlrs_after : vlrs).push_back(std::move(w));
  }
  vlrs.insert(vlrs.end(), r.vlrs.begin(), r.vlrs.end());
  evlrs_after.insert(evlrs_after.end(), r.evlrs.begin(), r.evlrs.end());
  Bytes vb;
  for (const copc::CarriedVlr& v : vlrs) put_vlr(vb, v, false);
  const std::uint64_t point_offset = 375 + vb.b.size();
  if (point_offset > 0xFFFFFFFFu) throw std::invalid_argument(in.string() + ": VLRs too large for a LAS header");

  detail::AtomicStream f(out);
  {
    const std::vector<std::uint8_t> zeros(point_offset + 8, 0);  // header, VLRs, chunk table offset
    f.write(zeros.data(), zeros.size());
  }

  // Chunks: nodes in pre-order, compressed in parallel by batches and written in order, so the
  // bytes do not depend on the scheduling.
  const std::size_t nn = t.nodes.size();
  std::vector<std::uint64_t> offset(nn);
  std::vector<std::uint32_t> sizes(nn), counts(nn);
  std::uint64_t pos = point_offset + 8, encoded = 0;
  struct Scratch {
    std::vector<std::uint8_t> recs;
    std::vector<std::pair<std::uint64_t, std::uint32_t>> order;
    std::optional<laz::LayeredChunkEncoder> enc;
  };
  tbb::enumerable_thread_specific<Scratch> scratch;
  constexpr std::uint64_t kBatchPoints = std::uint64_t{1} << 22;
  std::vector<std::vector<std::uint8_t>> chunks;
  for (std::size_t b0 = 0; b0 < nn;) {
    std::size_t b1 = b0;
    for (std::uint64_t pts = 0; b1 < nn && (b1 == b0 || pts + t.nodes[b1].count <= kBatchPoints); ++b1) pts += t.nodes[b1].count;
    chunks.assign(b1 - b0, {});
    tbb::parallel_for(b0, b1, [&](std::size_t i) {
      Scratch& s = scratch.local();
      if (!s.enc) s.enc.emplace(r.pdrf, extra);
      const copc::Node& nd = t.nodes[i];
      s.recs.resize(std::size_t{nd.count} * rec);
      // The node's records by GPS time, ties in input order (pairs (time key, record index),
      // indices unique): the acquisition order, which the layered coder predicts best (GPS time,
      // returns, scan lines), as untwine orders a chunk.
      s.order.resize(nd.count);
      for (std::uint32_t k = 0; k < nd.count; ++k) {
        const std::uint32_t id = t.slots[nd.begin + k].index;
        s.order[k] = {time_key(r.bytes + std::size_t{id} * rec), id};
      }
      std::sort(s.order.begin(), s.order.end());
      for (std::uint32_t k = 0; k < nd.count; ++k)
        std::memcpy(s.recs.data() + k * rec, r.bytes + std::size_t{s.order[k].second} * rec, rec);
      s.enc->encode(s.recs.data(), nd.count, rec, chunks[i - b0]);
    });
    for (std::size_t i = b0; i < b1; ++i) {
      const std::vector<std::uint8_t>& c = chunks[i - b0];
      if (c.size() > 0x7FFFFFFFu) throw std::runtime_error(out.string() + ": a node's chunk exceeds 2 GiB");
      offset[i] = pos;
      sizes[i] = static_cast<std::uint32_t>(c.size());
      counts[i] = t.nodes[i].count;
      encoded += counts[i];
      f.write(c.data(), c.size());
      pos += c.size();
    }
    if (opt.progress) opt.progress("encode", encoded, r.count);
    b0 = b1;
  }
  chunks.clear();
  const std::uint64_t table_at = pos;
  {
    const std::vector<std::uint8_t> table = laz::chunk_table_bytes(counts, sizes);
    f.write(table.data(), table.size());
    pos += table.size();
  }

  // Hierarchy EVLR: pages placed one after another, the root page first.
  const unsigned levels = opt.page_levels > 0 ? opt.page_levels : (nn <= 4096 ? 0u : 4u);
  std::vector<Page> pages = make_pages(t.nodes, levels);
  const std::uint64_t evlr_start = pos;
  std::uint64_t hier_bytes = 0;
  for (Page& p : pages) {
    p.offset = evlr_start + 60 + hier_bytes;
    hier_bytes += 32 * p.entries.size();
  }
  Bytes ev;
  ev.put<std::uint16_t>(0);
  ev.fixed("copc", 16);
  ev.put<std::uint16_t>(1000);
  ev.put<std::uint64_t>(hier_bytes);
  ev.fixed("copc hierarchy", 32);
  for (const Page& p : pages)
    for (const Page::Entry& e : p.entries) {
      // the entry layout read_copc_info() parses (CopcNode: key, offset, byte size, count)
      const copc::Node& nd = t.nodes[e.node];
      CopcNode c{nd.level, nd.x, nd.y, nd.z, offset[e.node], static_cast<std::int32_t>(sizes[e.node]),
                 static_cast<std::int32_t>(nd.count)};
      if (e.child_page >= 0) {
        const Page& cp = pages[static_cast<std::size_t>(e.child_page)];
        c.offset = cp.offset;
        c.byte_size = static_cast<std::int32_t>(32 * cp.entries.size());
        c.point_count = -1;  // a child hierarchy page
      }
      ev.put(c.level);
      ev.put(c.x);
      ev.put(c.y);
      ev.put(c.z);
      ev.put(c.offset);
      ev.put(c.byte_size);
      ev.put(c.point_count);
    }
  for (const copc::CarriedVlr& v : evlrs_after) put_vlr(ev, v, true);
  f.write(ev.b.data(), ev.b.size());
  pos += ev.b.size();

  // Info VLR payload (COPC 1.0 "Info VLR"): center x/y/z, halfsize, spacing, root hierarchy page
  // offset and size, GPS time minimum and maximum, 11 reserved uint64.
  const double spacing = 2.0 * t.cube.halfsize / kCopcGridCells;
  {
    Bytes info;
    info.put<double>(t.cube.center.x);
    info.put<double>(t.cube.center.y);
    info.put<double>(t.cube.center.z);
    info.put<double>(t.cube.halfsize);
    info.put<double>(spacing);
    info.put<std::uint64_t>(pages[0].offset);
    info.put<std::uint64_t>(32 * pages[0].entries.size());
    info.put<double>(st.gps_min);
    info.put<double>(st.gps_max);
    std::memcpy(vb.b.data() + 54, info.b.data(), info.b.size());  // the first VLR's payload
  }
  // Public header block (LAS 1.4 R15 section 2.4, table 3).
  Bytes h;
  h.raw("LASF", 4);
  h.put<std::uint16_t>(r.file_source_id);
  h.put<std::uint16_t>(static_cast<std::uint16_t>(r.global_encoding | (r.crs_wkt.empty() ? 0u : 1u << 4)));
  h.raw(r.guid, 16);
  h.put<std::uint8_t>(1);
  h.put<std::uint8_t>(4);
  h.fixed("rayscan", 32);
  h.fixed(software_name(), 32);
  h.put<std::uint16_t>(r.creation_day);
  h.put<std::uint16_t>(r.creation_year);
  h.put<std::uint16_t>(375);
  h.put<std::uint32_t>(static_cast<std::uint32_t>(point_offset));
  h.put<std::uint32_t>(static_cast<std::uint32_t>(vlrs.size()));
  h.put<std::uint8_t>(static_cast<std::uint8_t>(r.pdrf | 0x80));  // bit 7: LAZ-compressed (LASzip)
  h.put<std::uint16_t>(r.record_length);
  for (int k = 0; k < 6; ++k) h.put<std::uint32_t>(0);  // legacy counts: 0 for PDRF 6-10
  for (int k = 0; k < 3; ++k) h.put<double>(r.scale[k]);
  for (int k = 0; k < 3; ++k) h.put<double>(r.offset[k]);
  for (int k = 0; k < 3; ++k) {
    const double a = las_coordinate(st.lo[k], r.scale[k], r.offset[k]), b = las_coordinate(st.hi[k], r.scale[k], r.offset[k]);
    h.put<double>(std::max(a, b));
    h.put<double>(std::min(a, b));
  }
  h.put<std::uint64_t>(0);  // waveform data packet record start
  h.put<std::uint64_t>(evlr_start);
  h.put<std::uint32_t>(static_cast<std::uint32_t>(1 + evlrs_after.size()));
  h.put<std::uint64_t>(r.count);
  for (std::uint64_t c : st.by_return) h.put<std::uint64_t>(c);
  f.seek(0);
  f.write(h.b.data(), h.b.size());
  f.write(vb.b.data(), vb.b.size());
  const auto table_ptr = static_cast<std::int64_t>(table_at);
  f.write(&table_ptr, 8);
  f.commit();

  CopcWriteResult res;
  res.points = r.count;
  res.pdrf = r.pdrf;
  res.record_length = r.record_length;
  res.nodes = nn;
  res.pages = pages.size();
  for (const copc::Node& nd : t.nodes) {
    const auto l = static_cast<std::size_t>(nd.level);
    if (res.nodes_per_level.size() <= l) res.nodes_per_level.resize(l + 1, 0), res.points_per_level.resize(l + 1, 0);
    ++res.nodes_per_level[l];
    res.points_per_level[l] += nd.count;
  }
  res.depth = static_cast<int>(res.nodes_per_level.size());
  for (int k = 0; k < 3; ++k) res.center[k] = t.cube.center[k];
  res.halfsize = t.cube.halfsize;
  res.spacing = spacing;
  res.in_bytes = r.in_bytes;
  res.out_bytes = pos;
  res.notes = r.notes;
  res.warnings = r.warnings;
  return res;
}

}  // namespace rayscan::io
