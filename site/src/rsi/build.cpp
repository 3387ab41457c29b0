// The index build (build_index_file) around its point sections: the inputs, the read pass into
// sorted runs, the encodings, the section placement, the nodes and the header. The point sections
// themselves are merge.cpp's. docs/index-format.md, "Build (external memory)".
#include "index_build.hpp"
#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/input_file.hpp"
#include "rayscan/base/option_error.hpp"

#include "rayscan/io/cloud_stats.hpp"
#include "rayscan/octree/spacing.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <stdexcept>
#include <string>
#include <system_error>

namespace rayscan::io {

namespace rsi {

namespace {

bool same_crs(const PointReader& a, const PointReader& b) {
  if (a.info().epsg != 0 && b.info().epsg != 0) return a.info().epsg == b.info().epsg;
  return a.crs_wkt() == b.crs_wkt();
}
std::string crs_label(const PointReader& r) {
  if (r.info().epsg != 0) return "EPSG:" + std::to_string(r.info().epsg);
  if (r.crs_wkt().empty()) return "no CRS";
  return "WKT \"" + r.crs_wkt().substr(0, 40) + "...\"";
}

/// The folder of the sort runs, "<temp_dir>/.<output name>.runs.<pid>" (temp_dir empty: the
/// output's folder).
fs::path runs_folder(const fs::path& output, const IndexBuildOptions& opt) {
  fs::path dir = opt.temp_dir.empty() ? output.parent_path() : opt.temp_dir;
  if (dir.empty()) dir = ".";
  std::string name = ".";
  name += output.filename().string();
  name += ".runs." + std::to_string(::getpid());
  return dir / name;
}

}  // namespace

IndexBuild::IndexBuild(const std::vector<fs::path>& inputs_, const fs::path& output_, const IndexBuildOptions& opt_,
                       bool stored_colour_)
    : inputs(inputs_), output(output_), opt(opt_), stored_colour(stored_colour_) {}

std::optional<IndexBuildStats> IndexBuild::run() {
  check_options();
  open_inputs();
  plan_runs();
  create_output();
  read_pass();
  if (!decide_encodings()) return std::nullopt;
  place_sections();
  open_output();
  // The point sections in (code, id) order: straight from memory (one run), or by a k-way merge
  // of the runs. Then the nodes from the sorted codes, or (multi-run builds whose cells decide
  // the upper tree) during the merge from the merged positions (NodeBuilder::feed).
  plan_nodes();
  open_section_writers();
  if (in_memory) write_from_memory();
  else merge_runs();
  for (const fs::path& rp : run_files) fs::remove(rp);
  build_nodes();
  finish();
  return std::move(stats);
}

void IndexBuild::check_options() {
  opt.config.validate();
  if (opt.config.layout == OctreeLayout::layered)
    throw OptionError({option("layout"), " layered: not supported by the external-memory index build "
                                         "(use adaptive or fixed)"});
  if (inputs.empty()) throw std::invalid_argument("index build: no input file");
  if (opt.memory_bytes < (std::uint64_t{1} << 20))
    throw OptionError({option("memory_bytes"), " " + std::to_string(opt.memory_bytes) + " bytes: at least 1M"});
  if ((opt.attributes & kIndexAttributes) != opt.attributes)
    throw OptionError({option("attributes"), " " + opt.attributes.to_string() + ": an index stores " +
                                                 kIndexAttributes.to_string()});
  // The ids section only when asked (docs/index-format.md "Ids"); the readers deliver the rest.
  want_ids = opt.attributes.has(Attribute::id);
  read_attrs = AttributeSet{opt.attributes.bits & ~static_cast<std::uint32_t>(Attribute::id)};
  raw_colour = stored_colour && read_attrs.has(Attribute::rgb) &&
               std::all_of(inputs.begin(), inputs.end(), [](const fs::path& in) {
                 return format_from_extension(in) == Format::las;
               });
  // Inputs larger than the budget are read once, past the page cache (direct_records).
  std::uint64_t input_bytes = 0;
  for (const fs::path& in : inputs) {
    std::error_code ec;  // (a missing input is reported by its reader below)
    const std::uintmax_t size = fs::file_size(in, ec);
    if (!ec) input_bytes += size;
  }
  ropt = ReadOptions{.scalars = false, .stored_colour = raw_colour, .direct_records = input_bytes > opt.memory_bytes};
  // The runs folder is created in the temporary folder, never the folders above it: a missing
  // (mistyped) temporary folder is refused before any long work, by the rule of every output,
  // named as the option (the hidden runs folder's name means nothing to the user).
  require_temp_dir(opt.temp_dir);
  require_replaceable_output(runs_folder(output, opt));
}

void IndexBuild::open_inputs() {
  constexpr std::size_t kKeepOpen = 64;
  kept.resize(inputs.size());
  stored = opt.attributes;
  std::unique_ptr<PointReader> first_owned;
  const PointReader* first = nullptr;
  for (std::size_t f = 0; f < inputs.size(); ++f) {
    const fs::path& in = inputs[f];
    auto r = open_point_reader(in, read_attrs, ropt);
    if (first && !same_crs(*first, *r))
      throw IndexError(in.string() + ": CRS " + crs_label(*r) + " differs from " + crs_label(*first) + " of " +
                       inputs.front().string() + " (an index holds one coordinate system)");
    const AttributeSet lacking{read_attrs.bits & ~r->attributes().bits};
    if (lacking.bits != 0 && (stored.bits & lacking.bits) != 0) {
      stats.notes.push_back(in.string() + " has no " + lacking.to_string() + ": not stored");
      stored = AttributeSet{stored.bits & ~lacking.bits};
    }
    IndexSource s;
    s.path = fs::absolute(in).lexically_normal().string();
    s.size = fs::file_size(in);
    s.mtime_ns = mtime_ns(in);
    s.format = r->info().format + (r->info().version.empty() ? "" : " " + r->info().version);
    sources.push_back(s);
    announced += r->point_count();
    if (!first) crs = r->crs_wkt();
    if (inputs.size() <= kKeepOpen) {
      kept[f] = std::move(r);
      if (!first) first = kept[f].get();
    } else if (!first) {
      first_owned = std::move(r);
      first = first_owned.get();
    }
  }
}

void IndexBuild::plan_runs() {
  L = RecordLayout(stored);
  // Points per sort run within the memory budget (a record and a sort key per point; the buffer
  // actually holds positions, the stored attributes and a 16-byte key, a little less).
  run_cap = std::max<std::size_t>(
      1024, static_cast<std::size_t>(opt.memory_bytes * 3 / 4 / (L.bytes + sizeof(MortonKey))));
  // All points fit the budget (the readers announce exact counts or upper bounds): one read pass
  // into memory, the bounds from it, then sort and write the sections straight from memory. Else
  // a bounds pass first (the runs need the Morton grid), sorted runs on disk and a k-way merge.
  in_memory = announced <= run_cap;
  // The Morton grid of the runs (multi-run build) needs the bounds before the read pass. LAS
  // headers state them (min/max x, y, z): when every input is LAS, the union of their boxes on
  // the files' grids (header_box_on_grid, the rule `rayscan info` reports "differs" by) is taken
  // on trust and checked against the exact bounds of the read pass, which is repeated on the exact
  // grid when the headers were wrong (the tree must be build_bulk's, whose grid is the exact
  // bounds). Other inputs get a bounds pass first (positions only).
  grid_from_headers = !in_memory;
  for (const fs::path& in : inputs) {
    if (!grid_from_headers) break;
    auto r = open_point_reader(in, AttributeSet::none(), ReadOptions{.scalars = false});
    const auto grid = r->integer_grid();
    if (!grid || !r->info().header_bounds || r->point_count() == 0) grid_from_headers = false;
    else grid_bounds.expand(header_box_on_grid(*r->info().header_bounds, grid->first, grid->second));
  }
  if (!in_memory && !grid_from_headers) {
    grid_bounds = AABB{};
    std::uint64_t scanned = 0;
    PointCloud chunk;
    for (const fs::path& in : inputs) {
      auto pr = open_point_reader(in, AttributeSet::none(), ReadOptions{.scalars = false});
      while (pr->read(chunk, kDefaultChunkPoints) > 0) {
        for (const Vec3& p : chunk.positions) grid_bounds.expand(p);
        scanned += chunk.size();
        if (opt.progress) opt.progress("scan", scanned, 0);
      }
    }
  }
  grid_qz = OctreeRules::Quantizer(OctreeRules::root_cell(grid_bounds).lo, OctreeRules::root_side(grid_bounds));
}

void IndexBuild::create_output() {
  out.emplace(output);
  runs_dir.emplace(runs_folder(output, opt), output, RemoveOnInterrupt::Kind::folder);
}

void IndexBuild::read_pass() {
  // Points in id order into the buffer; a full buffer becomes a sorted run file (multi-run
  // build) written as records (code, id, position, attributes).
  buf.allocate(static_cast<std::size_t>(std::min<std::uint64_t>(run_cap, announced)), L, !in_memory);
  // The cells: the deepest level <= 7 whose 12 bytes per cell (the counts and their prefix
  // sums) fit 1/16 of the budget.
  while (cell_depth < 7 && (std::uint64_t{12} << (3 * (cell_depth + 1))) <= opt.memory_bytes / 16) ++cell_depth;
  for (int attempt = 0;; ++attempt) {
    read_inputs();
    if (in_memory) break;
    write_run();
    if (bounds.lo == grid_bounds.lo && bounds.hi == grid_bounds.hi) break;
    if (!grid_from_headers || attempt > 0)
      throw std::runtime_error(inputs.front().string() +
                               ": the inputs changed during the build (their bounds differ from the first pass)");
    stats.notes.push_back("the LAS headers' bounds differ from the points' bounds: read again on the exact grid");
    grid_bounds = bounds;
    grid_qz = OctreeRules::Quantizer(OctreeRules::root_cell(grid_bounds).lo, OctreeRules::root_side(grid_bounds));
  }
  run_keys = HugeArray<MortonKey>{};
  if (!in_memory) buf = PointBuffer{};  // the runs are on disk: release the buffer before the merge
  stats.runs = in_memory ? (total > 0 ? 1 : 0) : run_files.size();
}

void IndexBuild::read_inputs() {
  PointCloud c;
  codec = PositionCodec{};
  rgbc = RgbCodec{};
  bounds = AABB{};
  total = 0;
  run_first_id = 0;
  if (!in_memory) cell_points.assign(std::size_t{1} << (3 * cell_depth), 0);
  for (const fs::path& rp : run_files) fs::remove(rp);
  run_files.clear();
  run_layouts.clear();
  buf.clear();
  for (IndexSource& s : sources) s.points = 0;
  file_rgb_max.assign(inputs.size(), 0);
  for (std::size_t f = 0; f < inputs.size(); ++f) {
    std::unique_ptr<PointReader> r = std::move(kept[f]);
    if (!r) r = open_point_reader(inputs[f], AttributeSet{stored.bits & read_attrs.bits}, ropt);
    sources[f].first_id = total;
    codec.source(r->integer_grid());
    std::size_t n;
    while ((n = r->read(c, kDefaultChunkPoints)) > 0) {
      if (total + n >= 0xFFFFFFFFull) throw std::length_error("rayscan index: more than 2^32 - 2 points");
      if (in_memory && buf.size() + n > buf.capacity())
        throw std::runtime_error(inputs[f].string() + ": the inputs changed during the build (more points than " +
                                 std::to_string(announced) + " announced by the headers)");
      for (std::size_t i0 = 0; i0 < n;) {
        const std::size_t take = std::min(n - i0, buf.capacity() - buf.size());
        const BlockScan sc = buf.append(c, i0, take, L, codec, rgbc, raw_colour, in_memory ? nullptr : &grid_qz);
        file_rgb_max[f] = std::max(file_rgb_max[f], sc.rgb_max);
        bounds.expand(sc.box);
        codec.grid_ok = codec.grid_ok && sc.grid, codec.f32_ok = codec.f32_ok && sc.f32;
        rgbc.rule_out(sc.rgb_out);
        i0 += take;
        if (!in_memory && buf.size() == buf.capacity()) write_run();
      }
      total += n;
      sources[f].points += n;
      if (opt.progress) opt.progress("read", total, announced);
    }
  }
}

void IndexBuild::write_run() {
  if (buf.size() == 0) return;
  sort_keys(buf, grid_qz, run_keys);
  const HugeArray<MortonKey>& keys = run_keys;
  {  // the run's points per cell: one add per stretch of a cell (the keys are sorted)
    const unsigned shift = 3 * (kMortonBits - cell_depth);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, buf.size(), 1 << 16), [&](const auto& r) {
      for (std::size_t i = r.begin(); i < r.end();) {
        const std::uint64_t c = keys[i].code >> shift;
        std::size_t j = i + 1;
        while (j < r.end() && (keys[j].code >> shift) == c) ++j;
        std::atomic_ref<std::uint32_t>(cell_points[c]).fetch_add(static_cast<std::uint32_t>(j - i), std::memory_order_relaxed);
        i = j;
      }
    });
  }
  const fs::path rp = runs_dir->path() / ("run" + std::to_string(run_files.size()));
  // codec.grid_ok covers every point read so far, this run's included (append checked them).
  const RunLayout R(L, want_ids, codec.grid_ok && codec.grid_set);
  // O_DIRECT where possible: a run is written once and read once, so it bypasses the page
  // cache (no kernel copy, no cache pages to fill and evict; bench/notes/).
  Fd run_fd = Fd::direct(rp, O_WRONLY | O_CREAT | O_TRUNC);
  // Blocks of records gathered in parallel and written in order by one writer at a time (a
  // file's writes serialise on its inode lock: concurrent writers only spin), so the write of
  // block i overlaps the gather of the next ones. A block is up to kGatherBlock records, fewer
  // for a small budget (the four slots then hold about a quarter of a run), and a multiple of
  // 4096 records, so that every block's offset is page-aligned for O_DIRECT.
  const std::size_t blk_recs = std::clamp<std::size_t>(run_cap / 16 / 4096 * 4096, 4096, kGatherBlock);
  const std::size_t nb = (buf.size() + blk_recs - 1) / blk_recs;
  pipelined_blocks(nb, blk_recs * R.bytes, [&](std::size_t blk, std::uint8_t* recs) {
    const std::size_t b = blk * blk_recs, e = std::min(buf.size(), b + blk_recs);
    constexpr std::size_t kAhead = 16;  // prefetch distance (keys) of the random reads
    for (std::size_t k = b; k != e; ++k) {
      if (k + kAhead < e) {
        const std::uint32_t j = keys[k + kAhead].idx;
        __builtin_prefetch(&buf.pos[j]);
        if (L.rgb) __builtin_prefetch(&buf.rgb[j]);
      }
      const std::uint32_t i = keys[k].idx;
      std::uint8_t* rec = recs + (k - b) * R.bytes;
      std::memcpy(rec, &keys[k].code, 8);
      if (R.ids) {
        const auto pid = static_cast<std::uint32_t>(run_first_id + i);
        std::memcpy(rec + R.id_off, &pid, 4);
      }
      if (L.gps) std::memcpy(rec + R.gps_off, &buf.gps[i], 8);
      if (L.rgb) std::memcpy(rec + R.rgb_off, &buf.rgb[i], 6);
      if (L.intensity) std::memcpy(rec + R.int_off, &buf.intensity[i], 2);
      if (L.cls) rec[R.cls_off] = buf.cls[i];
      if (R.grid) {
        std::int32_t v[3];
        for (int a = 0; a < 3; ++a) v[a] = codec.grid_int(buf.pos[i][a], a);
        std::memcpy(rec + R.pos_off, v, 12);
      } else {
        std::memcpy(rec + R.pos_off, &buf.pos[i], 24);
      }
    }
    return (e - b) * R.bytes;
  }, [&](std::size_t blk, std::uint8_t* recs, std::size_t bytes) {
    // Direct writes are whole pages: the last block's tail is zero-padded, then cut off below.
    const std::size_t len = run_fd.is_direct() ? round_up_direct(bytes) : bytes;
    std::memset(recs + bytes, 0, len - bytes);
    run_fd.pwrite_all(recs, len, static_cast<std::uint64_t>(blk) * blk_recs * R.bytes);
  });
  const std::uint64_t run_bytes = static_cast<std::uint64_t>(buf.size()) * R.bytes;
  if (run_fd.is_direct() && run_bytes % kDirectAlign != 0 && ::ftruncate(run_fd.get(), static_cast<off_t>(run_bytes)) != 0)
    io_fail(rp, "cannot truncate to " + std::to_string(run_bytes) + " bytes");
  run_files.push_back(rp);
  run_layouts.push_back(R);
  run_first_id += buf.size();
  buf.clear();
}

bool IndexBuild::decide_encodings() {
  cell = OctreeRules::root_cell(bounds);
  codec.decide(opt.compact_positions);
  if (raw_colour && L.rgb) {  // false: the files disagree
    std::vector<std::uint64_t> points(sources.size());
    for (std::size_t f = 0; f < sources.size(); ++f) points[f] = sources[f].points;
    if (!rgbc.stored_scale(file_rgb_max, points)) return false;
  }
  if (L.rgb) rgbc.decide(opt.compact_rgb);
  rgb8 = L.rgb && rgbc.mul != 0;
  return true;
}

void IndexBuild::place_sections() {
  // Sources, crs, per-point sections, then nodes (size known after the build).
  h.points = total;
  h.cell = cell;
  h.config = opt.config;
  h.attributes = stored.bits;
  h.encoding = codec.enc;
  if (codec.enc == PositionEncoding::las_int32) h.grid_scale = codec.scale, h.grid_offset = codec.offset;
  h.rgb_mul = rgb8 ? rgbc.mul : 0u;
  src_text = encode_sources(sources);
  off = kHeaderBytes;
  s_src = place(kSources, src_text.size());
  s_crs = place(kCrs, crs.size());
  s_pos = place(kPositions, total * codec.bytes());
  s_ids = want_ids ? place(kIds, total * 4) : 0;
  if (L.rgb) s_rgb = rgb8 ? place(kRgb8, total * 3) : place(kRgb, total * 6);
  if (L.intensity) s_int = place(kIntensity, total * 2);
  if (L.cls) s_cls = place(kClassification, total);
  if (L.gps) s_gps = place(kGpsTime, total * 8);
}

std::size_t IndexBuild::place(std::uint32_t id, std::uint64_t size) {
  SectionEntry e{id, elem_size(id, codec.enc), off, size, 0};
  h.sections.push_back(e);
  off = align_up(off + size);
  return h.sections.size() - 1;
}

void IndexBuild::open_output() {
  fd.emplace(out->temp(), O_RDWR | O_CREAT | O_TRUNC);
  // The point sections are written once and not read back by this build but for the node
  // phase's positions: past the page cache where the file system allows (SectionWriter).
  dfd.emplace(Fd::direct(out->temp(), O_WRONLY));
  // Its background writes: 8 buffers of up to 4 MiB, more than are ever held at once (one per
  // section writer, at most 6, and one by the node file while it copies pages in). The section
  // writers use it on an O_DIRECT descriptor only; the node file always (through the page cache
  // where the file system refuses O_DIRECT).
  dw.emplace(8, std::clamp<std::size_t>(opt.memory_bytes / 128 / kDirectAlign * kDirectAlign, 64 << 10, 4 << 20));
  {
    const std::vector<std::uint8_t> zero(kHeaderBytes, 0);  // header slot, written last
    fd->pwrite_all(zero.data(), zero.size(), 0);
  }
  auto write_blob = [&](std::size_t s, const std::string& text) {
    if (!text.empty()) fd->pwrite_all(text.data(), text.size(), h.sections[s].offset);
    h.sections[s].crc = crc32_of(text.data(), text.size());
  };
  write_blob(s_src, src_text);
  write_blob(s_crs, crs);
}

void IndexBuild::plan_nodes() {
  node_file.emplace(*dfd, *dw, off, opt.node_stage_pages);  // the nodes section, after the points
  // The node phase after a merge (or of an in-memory build): subtrees of --memory/512 points at
  // most (1 Mi at most); each of the kPipelineSlots in flight holds its decoded positions, codes
  // and records (about 36 B/point) and its part of the positions map (12-24 B/point), about a
  // quarter of the budget in all (the merge's buffers are freed by then), so small budgets
  // release often too. (The fused build's subtrees are smaller: see below.)
  node_every = std::clamp<std::uint64_t>(opt.memory_bytes / 16 / 32, 1024, std::uint64_t{1} << 20);
  node_qz.emplace(cell.lo, OctreeRules::root_side(bounds));
  if (!in_memory && total > 0) {
    std::vector<std::uint64_t> prefix(cell_points.size() + 1, 0);
    for (std::size_t c = 0; c < cell_points.size(); ++c) prefix[c + 1] = prefix[c] + cell_points[c];
    if (prefix.back() != total) throw std::logic_error("index build: the cells lost points");
    const PositionView enc(codec.enc, nullptr, 0, codec.scale, codec.offset);
    fused.emplace(opt.config, nullptr, *node_qz, enc, cell.lo, *node_file, nullptr, nullptr, nullptr, total);
    // Subtrees of --memory/2048 points at most: up to kPipelineSlots of them (~50 B/point: the
    // encoded and decoded positions, codes, records) live beside the merge's buffers.
    fused->every = std::clamp<std::uint64_t>(opt.memory_bytes / 16 / 128, 1024, std::uint64_t{1} << 20);
    if (fused->plan_counts(prefix, cell_depth)) fused->begin_feed();
    else fused.reset();
  }
  std::vector<std::uint32_t>().swap(cell_points);
}

void IndexBuild::open_section_writers() {
  // Filled in (code, id) order by either path (write_from_memory, merge_runs); finish_points
  // flushes them and records their CRCs in the header.
  const std::size_t wbuf = in_memory ? 1 << 16 : 4 << 20;  // (buffered only; in memory: blocks go straight)
  DirectWriter* const dwp = &*dw;
  w_pos.emplace(*dfd, h.sections[s_pos].offset, wbuf, dwp);
  if (want_ids) w_ids.emplace(*dfd, h.sections[s_ids].offset, wbuf, dwp);
  if (L.rgb) w_rgb.emplace(*dfd, h.sections[s_rgb].offset, wbuf, dwp);
  if (L.intensity) w_int.emplace(*dfd, h.sections[s_int].offset, wbuf, dwp);
  if (L.cls) w_cls.emplace(*dfd, h.sections[s_cls].offset, wbuf, dwp);
  if (L.gps) w_gps.emplace(*dfd, h.sections[s_gps].offset, wbuf, dwp);
}

void IndexBuild::finish_points() {
  w_pos->flush();
  h.sections[s_pos].crc = w_pos->crc();
  if (w_ids) w_ids->flush(), h.sections[s_ids].crc = w_ids->crc();
  if (w_rgb) w_rgb->flush(), h.sections[s_rgb].crc = w_rgb->crc();
  if (w_int) w_int->flush(), h.sections[s_int].crc = w_int->crc();
  if (w_cls) w_cls->flush(), h.sections[s_cls].crc = w_cls->crc();
  if (w_gps) w_gps->flush(), h.sections[s_gps].crc = w_gps->crc();
  dw->drain();  // on disk before the node phase maps the positions
}

void IndexBuild::build_nodes() {
  // Nodes from the sorted codes (in memory) or, after a merge, the codes of the positions section
  // (mapped; its pages are file cache; the codes are the run sort's, as the grid is the final
  // root cell and the decoded positions are the read ones bit for bit), written in place into
  // the nodes section (NodeFile). The map's pages are dropped behind the finished subtrees, so
  // the node phase's resident set (anonymous and file-backed) does not grow with the site.
  const std::uint64_t nodes_off = off;  // the next aligned offset: where place() puts the nodes
  std::optional<ReadMap> file;
  std::optional<NodeBuilder> phase;
  if (fused) {
    fused->end_feed();
    stats.nodes_in_merge = true;
  } else {
    file.emplace(fd->get(), h.sections[s_pos].offset + total * codec.bytes(), out->temp());
    auto release = [&](std::size_t i) { file->release_below(h.sections[s_pos].offset + i * codec.bytes()); };
    auto ahead = [&](std::size_t b, std::size_t e) {
      file->populate(h.sections[s_pos].offset + b * codec.bytes(), (e - b) * codec.bytes());
    };
    phase.emplace(opt.config, in_memory ? mem_codes.data() : nullptr, *node_qz,
                  PositionView(codec.enc, static_cast<const std::uint8_t*>(file->p) + h.sections[s_pos].offset, total,
                               codec.scale, codec.offset),
                  cell.lo, *node_file, release, ahead, opt.progress, total);
    phase->every = node_every;
    phase->plan(total, [&] { file->drop(); });
    phase->build();
  }
  NodeBuilder& nb = fused ? *fused : *phase;
  mem_codes = HugeArray<std::uint64_t>{};
  const std::size_t s_nodes = place(kNodes, nb.count * kNodeBytes);
  if (h.sections[s_nodes].offset != nodes_off) throw std::logic_error("rayscan index: nodes section misplaced");
  h.sections[s_nodes].crc = node_file->crc(nb.count);
  h.nodes = nb.count;
  h.depth = nb.depth;
  h.levels = nb.levels;
  off = h.sections[s_nodes].offset + h.sections[s_nodes].size;  // the file ends with the nodes
}

void IndexBuild::finish() {
  h.bounds = bounds;
  dw->drain();  // (the node records)
  if (::ftruncate(fd->get(), static_cast<off_t>(off)) != 0) io_fail(out->temp(), "cannot set the file size");
  {
    const std::vector<std::uint8_t> hb = encode_header(h);
    fd->pwrite_all(hb.data(), hb.size(), 0);
  }
  // The auto radius (median nearest-neighbour spacing) over the finished tree, by the renderer's
  // own function, so that opening never runs kNN for it; then the final header.
  if (total >= 2) {
    // The phase counts the points sampled for the spacing, as every other phase counts points.
    const std::uint64_t samples = std::min<std::uint64_t>(total, kSpacingSamples);
    if (opt.progress) opt.progress("spacing", 0, samples);
    IndexOpenOptions oo;
    oo.verify = IndexOpenOptions::Verify::metadata_only;
    oo.check_sources = false;
    oo.trust_ids = true;  // written above: the ids need no check
    const MappedIndex m = MappedIndex::open(out->temp(), oo);
    // The map's pages are dropped from the process (MappedIndex::release_pages) behind the ids
    // pass (or every 1,024 samples read by slot without ids) and after every 256 kNN queries:
    // each page fault maps up to 64 KiB around it, so scattered reads would otherwise keep
    // gigabytes of the file resident.
    h.spacing = median_nn_spacing_by_id(
        m, samples, [&](std::size_t) { m.release_pages(); }, 256, [&] { m.release_pages(); });
    if (opt.progress) opt.progress("spacing", samples, samples);
    const std::vector<std::uint8_t> hb = encode_header(h);
    fd->pwrite_all(hb.data(), hb.size(), 0);
  }
  // A last progress call before the rename: a caller that stops the build from its callback
  // (rayscan index on SIGINT/SIGTERM) still gets no output when it stops here.
  if (opt.progress) opt.progress("done", total, total);
  if (::fsync(fd->get()) != 0) io_fail(out->temp(), "fsync failed");
  out->commit();

  stats.points = total;
  stats.nodes = h.nodes;
  stats.depth = h.depth;
  stats.attributes = stored;
  stats.positions = codec.enc;
  stats.rgb_multiplier = h.rgb_mul;
  stats.file_bytes = off;
}

}  // namespace rsi

IndexBuildStats build_index_file(const std::vector<std::filesystem::path>& inputs,
                                 const std::filesystem::path& output, const IndexBuildOptions& opt) {
  // LAS tiles are first read with their colour as stored; when they cannot share one colour rule
  // (some 8-bit, some 16-bit, or one all zero) the build is repeated with the readers' own
  // per-file normalisation (docs/index-format.md "Build (external memory)" 1).
  for (bool stored_colour = true;; stored_colour = false) {
    std::optional<IndexBuildStats> st = rsi::IndexBuild(inputs, output, opt, stored_colour).run();
    if (!st && stored_colour) continue;
    if (!st) throw std::logic_error("index build: a colour retry without colour read as stored");
    if (!stored_colour)
      st->notes.insert(st->notes.begin(), "the tiles' colour differs in kind (8-bit, 16-bit or all zero): read again "
                                          "with each file's own colour rule");
    return std::move(*st);
  }
}

}  // namespace rayscan::io
