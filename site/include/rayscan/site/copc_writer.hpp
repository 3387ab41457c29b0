// Writing COPC 1.0 (Cloud Optimized Point Cloud, https://copc.io): any readable point file to a
// LAZ 1.4 file whose variable-size chunks are the nodes of an octree, each node a grid subsample
// of its subtree, described by the hierarchy EVLR. The reading side is rayscan/site/copc.hpp.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

namespace rayscan::io {

/// Options of write_copc().
struct CopcWriteOptions {
  /// Memory budget in bytes. The octree is built from 12 bytes per point in memory (Morton code
  /// and record index; the records stay on disk, mapped): 12 bytes per point plus 256 MiB of
  /// batches must fit, else write_copc() throws CopcMemoryError before reading any point.
  std::uint64_t memory_bytes = std::uint64_t{4} << 30;
  /// A node whose subtree holds at most this many points keeps them all (a leaf); a larger one
  /// keeps one point per cell of its kCopcGridCells^3 grid and hands the rest to its children.
  std::uint32_t leaf_points = 100000;
  /// Levels per hierarchy page: 0 = automatic (one page up to 4096 nodes, else a page every 4
  /// levels); n > 0 = a new page at every level that is a multiple of n (COPC 1.0 "Hierarchy
  /// pages": an entry with point count -1 points to the child page holding that node).
  unsigned page_levels = 0;
  /// Folder for the temporary records file (LAZ, PDRF 0-3 or non-LAS input: the records in the
  /// output format, uncompressed; removed at the end) (default: the output's folder).
  std::filesystem::path temp_dir;
  /// Called with (phase "read" (decoding or converting into the temporary records file), "tree"
  /// or "encode"; points done; points in all) every batch (may be empty). An exception it
  /// throws stops the build and removes the temporary files (how `rayscan index` is interrupted).
  std::function<void(const char* phase, std::uint64_t done, std::uint64_t total)> progress;
};

/// Grid cells per axis of a node's subsample, as a power of two: a node keeps at most one point
/// per cell, and the info VLR's spacing is the root edge / kCopcGridCells. 64, where untwine and
/// PDAL's writers.copc use 128: an inner node's points lie a cell apart, so the LAZ coder predicts
/// their coordinates, GPS times and colours worse and they cost about twice a leaf point's bytes;
/// a 64^3 grid puts about a quarter as many points in inner nodes, which keeps the file within
/// 10% of plain LAZ of the same records (bench/notes/2026-11-27-table1-box-faces-copc-grid.md).
inline constexpr int kCopcGridBits = 6;
inline constexpr int kCopcGridCells = 1 << kCopcGridBits;

/// Deepest octree level write_copc() creates (nodes there are leaves whatever their size): the
/// 21-bit Morton grid must resolve each level's grid cells (14 + kCopcGridBits < 21; at level 14
/// a cell is 2 Morton cells wide, so the point nearest its centre is still a choice).
inline constexpr int kCopcMaxLevel = 14;

/// The input does not fit write_copc()'s in-memory build within CopcWriteOptions::memory_bytes.
struct CopcMemoryError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// What write_copc() wrote.
struct CopcWriteResult {
  std::uint64_t points = 0;     ///< point records written (= the input's)
  int pdrf = 6;                 ///< point data record format written (6, 7 or 8)
  std::uint16_t record_length = 0;  ///< bytes per record (the PDRF's plus the extra bytes)
  std::uint64_t nodes = 0;      ///< octree nodes (= LAZ chunks)
  int depth = 0;                ///< deepest level + 1
  std::uint64_t pages = 0;      ///< hierarchy pages
  std::vector<std::uint64_t> nodes_per_level, points_per_level;
  double center[3] = {0, 0, 0}, halfsize = 0, spacing = 0;  ///< root cube and spacing, file units
  std::uint64_t in_bytes = 0, out_bytes = 0;                ///< file sizes
  std::vector<std::string> notes;  ///< conversions made (e.g. PDRF 3 records written as PDRF 7)
  /// What the user is told even when notes are not: the input's CRS taken from its GeoKeys, its
  /// WKT VLR unreadable (FileInfo::crs_warning, naming the input).
  std::vector<std::string> warnings;
};

/// Writes the point file `in` (any format read_point_cloud() reads) to `out` as COPC 1.0:
/// LAS 1.4 header (global encoding bit 4 and an OGC WKT VLR when the input has a CRS), the COPC
/// info VLR first (user "copc", record 1, 160 bytes: root cube centre and half size, spacing =
/// root edge / kCopcGridCells, root hierarchy page, GPS time range), the LASzip VLR (layered-chunked
/// compressor 3, item version 3, variable chunk size 0xFFFFFFFF), the input's other VLRs
/// (Extra Bytes kept), one LAZ chunk per octree node, the chunk table, then the hierarchy EVLR
/// (user "copc", record 1000; pages of 32-byte entries) and the input's other EVLRs.
///
/// Records: LAS/LAZ inputs of PDRF 6, 7, 8 are copied byte for byte; PDRF 0-3 become 6 (7 with
/// RGB) by the LAS 1.4 field mapping (return numbers, classification and its flags, scan angle
/// rank x 1/0.006, GPS time 0 when absent), extra bytes kept; other formats go through
/// write_las() (PDRF 6/7/8 chosen from the attributes, other attributes as extra bytes) into a
/// temporary LAS file first. Positions keep the input's LAS scale and offset (X, Y, Z integers
/// unchanged).
///
/// Octree: the root cube is the cube around the points' bounding box (centre of the box, half
/// its largest edge). Points are sorted by their 21-bit Morton code in the root cube; a node
/// whose subtree has more than `leaf_points` points (and whose level is below kCopcMaxLevel)
/// keeps, in each cell of a 64^3 grid (kCopcGridCells) over its cube, the point nearest the cell's
/// centre (ties: the lowest Morton code, then the earliest input record), and its other points go
/// down to its children; so every level is a grid subsample of spacing edge / 64. Within a node points
/// are in GPS-time order, ties in input order (as untwine orders a chunk). Output bytes depend only on the input and the options (not on threads);
/// nodes are compressed in parallel (TBB). Memory: 12 bytes per point (the Morton sort and the
/// octree are built on codes and indices) and bounded batches; the records are read from the
/// mapped input, or from a temporary uncompressed file of converted records for LAZ, PDRF 0-3
/// and non-LAS inputs (disk: count x record length); CopcMemoryError beyond `memory_bytes`.
/// Written through a temporary file renamed into place (no partial output).
///
/// Throws FormatError for an unreadable input or one whose points decode beyond +-kMaxCoordinate
/// (the LAS reader's line for the first, before the output is created), std::invalid_argument for a waveform PDRF
/// (4, 5, 9, 10), an empty input, a record over 65535 bytes after conversion, VLRs too large
/// for a LAS header or a CRS whose WKT GDAL cannot read (write_las's line, naming `in`),
/// CopcMemoryError (above; also for 2^32 points or more, which the 32-bit
/// record indices of the build cannot address), std::runtime_error for I/O failures. Sources: COPC 1.0 specification (copc.io, sections "Info VLR", "Hierarchy",
/// "LAZ chunks"), ASPRS LAS 1.4 R15 sections 2.4-2.7, LASzip (docs/formats.md "LAZ").
CopcWriteResult write_copc(const std::filesystem::path& in, const std::filesystem::path& out,
                           const CopcWriteOptions& options = {});

}  // namespace rayscan::io
