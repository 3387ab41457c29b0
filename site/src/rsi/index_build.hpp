// The state of one index build and its phases in order: the inputs opened, the read pass into
// sorted runs (or into memory), the encodings decided, the sections placed, the point sections
// written (from memory or by the k-way merge), the nodes, the header. build.cpp holds the phases
// around the point sections, merge.cpp the point sections themselves.
// docs/index-format.md, "Build (external memory)".
#pragma once

#include "codecs.hpp"
#include "direct_io.hpp"
#include "external_sort.hpp"
#include "format.hpp"
#include "node_builder.hpp"
#include "rayscan/base/atomic_file.hpp"

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace rayscan::io::rsi {

/// One attempt at building an index file. run() performs the phases in the order the format's
/// "Build" section describes; an attempt that reads LAS colour as stored may find that the tiles
/// cannot share one colour rule, and then ends early so that build_index_file repeats the build
/// with the readers' own per-file rule. Each member is one of the build's values, declared in the
/// order the phases make them, so that they are released in the reverse order (the temporary
/// output last) whether the attempt finishes, ends early or throws.
class IndexBuild {
 public:
  /// `stored_colour`: read LAS/LAZ colour as stored (ReadOptions::stored_colour) and apply the
  /// readers' colour rule in the read pass (RgbCodec::stored_scale); false: the readers' own rule.
  IndexBuild(const std::vector<fs::path>& inputs, const fs::path& output, const IndexBuildOptions& opt,
             bool stored_colour);
  IndexBuild(const IndexBuild&) = delete;
  IndexBuild& operator=(const IndexBuild&) = delete;

  /// Builds the file. std::nullopt when the inputs were read with their colour as stored and the
  /// files differ in kind (8-bit, 16-bit or all zero): nothing is written (the temporaries go
  /// with this object) and the build must be repeated with stored_colour false.
  std::optional<IndexBuildStats> run();

 private:
  // ---- phases (build.cpp) ----
  /// Rejects what the build does not support (std::invalid_argument) and sets up the read
  /// options: the attributes read, colour as stored or not, records past the page cache.
  void check_options();
  /// Step 1: every input opened once: CRS agreement, the stored attributes, the announced
  /// point counts; the readers stay open for the read pass when there are few of them.
  void open_inputs();
  /// The run buffer's size within the budget, whether one run holds every point, and the
  /// Morton grid of a multi-run build (from the LAS headers or a bounds pass).
  void plan_runs();
  /// The temporary output (AtomicFile) and the folder of the sort runs beside it (or in
  /// IndexBuildOptions::temp_dir).
  void create_output();
  /// The read pass (steps 2 and 3): every point into the buffer, full buffers written as sorted
  /// runs; repeated on the exact grid when the LAS headers' bounds were not exact.
  void read_pass();
  /// One pass over every input from the first point (state reset first).
  void read_inputs();
  /// Sorts the buffered points and writes them as the next run file (multi-run builds), counting
  /// the points per cell for the fused node build.
  void write_run();
  /// The positions and colour encodings from what the read pass saw. False when colour read as
  /// stored cannot keep one rule across the files (the build is repeated: run()).
  bool decide_encodings();
  /// The header's fields known before the sections and the place of every section but the nodes.
  void place_sections();
  /// Appends section `id` of `size` bytes at the next aligned offset; returns its table index.
  std::size_t place(std::uint32_t id, std::uint64_t size);
  /// Creates the temporary output, its background writer, the header slot and the sources and
  /// crs sections.
  void open_output();
  /// The nodes section's writer and, in a multi-run build whose cell counts decide the upper
  /// tree, the node build fused into the merge (NodeBuilder::plan_counts).
  void plan_nodes();
  /// The writers of the point sections (positions, ids, the stored attributes).
  void open_section_writers();
  /// Flushes the point sections' writers, records their CRCs, waits for their writes.
  void finish_points();
  /// Step 4: the nodes section (fused build: its end; else the node phase over the positions
  /// written), its CRC and the header's node fields.
  void build_nodes();
  /// The header (twice: before and after the spacing pass over the finished file), the file's
  /// size, fsync and the rename into place; the build's statistics.
  void finish();

  // ---- the point sections (merge.cpp) ----
  /// Step 2: the point sections gathered from the in-memory buffer in key order.
  void write_from_memory();
  /// Step 3: the point sections from the k-way merge of the run files (feeding the fused node
  /// build when there is one).
  void merge_runs();
  /// The k-way merge's state: its run readers and the slots of the parts in flight.
  struct RunMerge;

  // ---- the build's values, in the order the phases make them ----
  const std::vector<fs::path>& inputs;
  const fs::path& output;
  const IndexBuildOptions& opt;
  const bool stored_colour;
  bool want_ids = false;  ///< the ids section is written (docs/index-format.md "Ids")
  AttributeSet read_attrs;  ///< the attributes asked of the readers (all stored ones but id)
  IndexBuildStats stats;
  /// LAS/LAZ colour as stored (ReadOptions::stored_colour): the readers skip their whole-file
  /// colour pass (a read of every record before the first point), and the read pass applies the
  /// same rule from the largest value of each file (RgbCodec::stored_scale).
  bool raw_colour = false;
  ReadOptions ropt;
  std::vector<IndexSource> sources;
  std::vector<std::unique_ptr<PointReader>> kept;  ///< readers kept open for the read pass
  AttributeSet stored;  ///< the attributes every input has (and the ids when asked)
  std::string crs;
  std::uint64_t announced = 0;  ///< points announced by the readers (exact counts or upper bounds)
  RecordLayout L{AttributeSet::none()};
  std::size_t run_cap = 0;  ///< points per sort run within the memory budget
  bool in_memory = false;   ///< one run holds every point: no run files, no merge
  AABB grid_bounds;         ///< the bounds of the runs' Morton grid (multi-run builds)
  bool grid_from_headers = false;  ///< grid_bounds is the union of the LAS headers' boxes
  OctreeRules::Quantizer grid_qz{Vec3(0.0), 1.0};  ///< the runs' Morton grid
  std::optional<AtomicFile> out;
  std::optional<IntermediateFile> runs_dir;  ///< the sort runs' folder (Kind::folder)
  AABB bounds;              ///< exact bounds of the points read
  std::uint64_t total = 0;  ///< points read
  PointBuffer buf;
  std::vector<fs::path> run_files;
  std::vector<RunLayout> run_layouts;
  std::uint64_t run_first_id = 0;  ///< the id of the next run's first point
  PositionCodec codec;
  RgbCodec rgbc;
  HugeArray<MortonKey> run_keys;  ///< the sort keys of a run (one array for every run)
  /// Points per cell of depth cell_depth on the runs' grid, counted from each sorted run: the
  /// merge then builds the nodes as it goes (NodeBuilder::plan_counts, feed).
  unsigned cell_depth = 0;
  std::vector<std::uint32_t> cell_points;
  std::vector<std::uint16_t> file_rgb_max;  ///< the largest stored colour value of each input (raw_colour)
  AABB cell;          ///< the root cell (from the exact bounds)
  bool rgb8 = false;  ///< colour in the 3-byte rgb8 section
  Header h;
  std::string src_text;  ///< the sources section
  std::uint64_t off = kHeaderBytes;  ///< the next section's offset
  std::size_t s_src = 0, s_crs = 0, s_pos = 0, s_ids = 0, s_rgb = 0, s_int = 0, s_cls = 0, s_gps = 0;
  std::optional<Fd> fd;   ///< the temporary output
  std::optional<Fd> dfd;  ///< ... opened O_DIRECT where the file system allows it
  std::optional<DirectWriter> dw;
  HugeArray<std::uint64_t> mem_codes;  ///< sorted codes of the in-memory build
  std::optional<NodeFile> node_file;
  std::uint64_t node_every = 0;  ///< the node phase's largest subtree built as one task
  std::optional<OctreeRules::Quantizer> node_qz;
  std::optional<NodeBuilder> fused;  ///< the node build fused into the merge
  std::optional<SectionWriter> w_pos, w_ids, w_rgb, w_int, w_cls, w_gps;
};

}  // namespace rayscan::io::rsi
