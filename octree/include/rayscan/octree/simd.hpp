// Runtime-dispatched SIMD kernels of the one traversal: the node test of all children
// of a node at once on their float boxes, and a conservative point filter on a leaf's double
// positions. Both are *filters*: the traversal confirms every survivor with the exact scalar double
// code, so answers are bit-identical on every path (the property tests run once per forced path).
//
// Paths: scalar (the reference), sse2 (x86-64 baseline), avx2 (+FMA), avx512 (F+VL). The best path
// the CPU supports is chosen once at start-up with __builtin_cpu_supports; the environment variable
// RAYSCAN_SIMD=scalar|sse2|avx2|avx512 or set_simd_path() forces one (tests, benchmarks).
// On the avx2 and avx512 paths the first-hit ray traversal, its packets and knn_query run
// instances of the one traversal compiled for that instruction set with these kernels inlined
// (the library's private detail/simd_kernels.hpp and detail/ray_query_impl.hpp); elsewhere the
// kernels are called through simd::Kernels.
#pragma once

#include "rayscan/octree/geometry.hpp"

#include <bit>
#include <concepts>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>

namespace rayscan {

/// A code path of the SIMD kernels (ordered: each needs the instruction sets of the ones before).
enum class SimdPath : std::uint8_t { scalar = 0, sse2 = 1, avx2 = 2, avx512 = 3 };

/// "scalar" | "sse2" | "avx2" | "avx512".
const char* to_string(SimdPath p);
/// Parses a name of to_string; nullopt for anything else.
std::optional<SimdPath> parse_simd_path(const std::string& s);
/// The best path this CPU supports (__builtin_cpu_supports: avx512f+avx512vl, avx2+fma, sse2).
SimdPath best_simd_path();
/// True when this CPU can run path p.
bool simd_path_supported(SimdPath p);
/// The active path: RAYSCAN_SIMD if set and supported (an unsupported or unknown value is reported
/// once on stderr and ignored), else best_simd_path(); changed by set_simd_path.
SimdPath simd_path();
/// Forces path p for all later queries of the process (not thread-safe against running queries).
/// Returns false (and changes nothing) when the CPU cannot run p.
bool set_simd_path(SimdPath p);
/// One line for `rayscan --version`: the active path (and, for avx2 / avx512, that the ray and kNN
/// traversals run their instances compiled for it: detail/simd_kernels.hpp) and what the CPU supports.
std::string simd_description();

namespace simd {

/// Per-ray constants of the child slab test in float, relative to the index's float origin.
/// The caller (the traversal) grows the slabs by the pad plus a margin covering every float
/// rounding of positions, so the float test never rejects a box the double test accepts.
struct SlabRayF {
  float o_plus[3];   ///< origin + (pad + margin), relative to the origin of the float boxes
  float o_minus[3];  ///< origin - (pad + margin)
  float inv_d[3];    ///< 1 / direction (finite: rays with a zero component use the scalar test)
  float t_lo, t_hi;  ///< parameter interval the slab interval must meet (already widened)
  /// The k-bound on the entry (the traversal's live test, rounded up): a box entered after it
  /// is rejected. +inf: no bound.
  float enter_max = std::numeric_limits<float>::infinity();
  /// The least key a result can have (t_min, rounded down): entries are raised to at least this.
  float lb_floor = -std::numeric_limits<float>::infinity();
};

/// Child order keys (ChildSlabKeysFn): a child's entry lower bound e in an order-preserving
/// unsigned encoding (IEEE bits with the sign flipped, negatives complemented) whose low 3 bits
/// are replaced by the child's number i < 8, so that sorting the keys sorts the children by entry
/// (ties by number). Clearing the low bits rounds e down (by at most 7 ulps), so the bound a key
/// decodes to (child_key_bound) is still a lower bound of the entry. A key of ~0u marks no child.
[[nodiscard]] inline std::uint32_t child_key(float e, unsigned i) {
  const std::uint32_t b = std::bit_cast<std::uint32_t>(e);
  const std::uint32_t u = (b & 0x80000000u) ? ~b : (b | 0x80000000u);
  return (u & ~7u) | i;
}
/// The child number of a key.
[[nodiscard]] inline unsigned child_key_index(std::uint32_t key) { return key & 7u; }
/// The lower bound a key holds: <= the entry it was made from (-inf for -inf, whose rounded key
/// would decode to NaN).
[[nodiscard]] inline double child_key_bound(std::uint32_t key) {
  const std::uint32_t u = key & ~7u;
  const float f = std::bit_cast<float>((u & 0x80000000u) ? (u & 0x7FFFFFFFu) : ~u);
  return f == f ? static_cast<double>(f) : -std::numeric_limits<double>::infinity();
}

/// Float boxes of n <= 8 sibling nodes stored with a fixed stride: box i has lo at
/// base[i * stride + 0..2] and hi at base[i * stride + 3..5].
struct ChildBoxesF {
  const float* base = nullptr;
  unsigned stride = 0;  ///< in floats, >= 8: the kernels read 8 floats from each box's lo (transposed in registers)
  unsigned count = 0;   ///< number of children (<= 8)
  /// True when 8 rows are readable from base (8 floats from base + i * stride, i < 8), as for
  /// children that are not the last of the node array: the 8-wide kernels then load rows past
  /// count as they are (their lanes are masked off) instead of clamping each row to box 0.
  bool rows8 = false;
  /// The same boxes transposed, or nullptr: 6 rows of 8 floats (lo.x, lo.y, lo.z, hi.x, hi.y,
  /// hi.z of boxes 0..7; lanes past count hold anything), read by the 8-wide kernels as they are
  /// instead of transposing 8 records in registers (the Octree's child blocks). base and stride
  /// stay valid for the other kernels.
  const float* soa = nullptr;
};

/// SlabRayF of a packet of up to 16 rays, one lane per ray (the SIMD-over-rays form of the child
/// test, for coherent rays). Unused lanes must hold a never-hitting ray (t_lo > t_hi).
struct SlabPacketF {
  alignas(64) float o_plus[3][16];
  alignas(64) float o_minus[3][16];
  alignas(64) float inv_d[3][16];
  alignas(64) float t_lo[16];
  alignas(64) float t_hi[16];
};

/// Per-ray constants of the point filter (double, world coordinates).
struct PointFilterD {
  double o[3];       ///< ray origin
  double d[3];       ///< unit direction
  double d2_max;     ///< keep points whose squared orthogonal distance <= d2_max (already widened)
  double t_lo, t_hi; ///< keep points whose projection t_p lies in [t_lo, t_hi] (already widened)
  /// Optional (orders with d != 0; the d = 0 loops ignore it): each point's own radius, radii[i]
  /// for xyz point i (world units, one float per point of the call), and keep only points with
  /// d^2 <= radii[i]^2 + d2_slack as well (e.g. the disc radii of surfel rendering, in slot order:
  /// RefinedKey's filter_radii). A NaN radius keeps the d2_max bound. Null: d2_max alone.
  const float* radii = nullptr;
  double d2_slack = 0.0;  ///< widening of radii[i]^2 (world units^2; covers the filter's rounding)
  /// With radii: keep only points with t_p >= t_lo_own - radii[i] as well (already widened; a NaN
  /// radius keeps t_lo): the least ray parameter of a hit (e.g. RefinedKey's key_min), less each
  /// point's own radius, for geometry that lies within that radius of its point.
  double t_lo_own = -std::numeric_limits<double>::infinity();
  /// Optional (with radii, d != 0): each point's disc normal, normals[3i .. 3i + 2] (unit, float),
  /// for the ray-disc test of a disc centred on the point with radius radii[i] (pbrt-v4 6.4.2, as
  /// render::ray_disc_t): the AVX2 and AVX-512 kernels also drop the points whose disc the ray
  /// provably misses, crossing its plane at t = ((p - o).n) / (d.n) outside [disc_t_lo - e,
  /// disc_t_hi + e] (e = disc_slack + 2^-36 |t|) or farther than radius from p (|t d - (p - o)|^2
  /// > r^2 + 2^-32 (r^2 + |p - o|^2)). These margins cover the difference between any two
  /// evaluations of the test in double when |d.n| >= 2^-10 |n|; rays closer to parallel to a disc,
  /// and NaN normals, keep the point (a NaN radius drops no lane by distance: only by t). The SSE2
  /// kernel and the scalar tails ignore it (a filter may keep).
  const float* normals = nullptr;
  double disc_t_lo = -std::numeric_limits<double>::infinity();  ///< with normals: least disc hit t
  double disc_t_hi = std::numeric_limits<double>::infinity();   ///< with normals: largest disc hit t
  double disc_slack = 0.0;  ///< with normals: t margin (world units), >= 2^-36 max |p - o|
};

/// Slab test of up to 8 child boxes: bit i of the result is set when box i grown as in `r`
/// meets [t_lo, t_hi] and is entered no later than enter_max (conservatively); entry[i] receives
/// a lower bound of its entry parameter, at least lb_floor.
using ChildSlabFn = unsigned (*)(const ChildBoxesF& boxes, const SlabRayF& r, float* entry);
/// ChildSlabFn with the entries as child order keys: returns the same mask, writes keys[0..8):
/// child_key(entry[i], i) for each child i of the mask, ~0u for every other lane, and sets `near`
/// to the least of them. The first-hit traversal's child step (ray_query.hpp), so that ordering
/// the children is one sort of 8 keys.
using ChildSlabKeysFn = unsigned (*)(const ChildBoxesF& boxes, const SlabRayF& r, std::uint32_t* keys,
                                     std::uint32_t& near);
/// Sorts keys[0..8) ascending (a sorting network: no branch on the data).
using SortKeys8Fn = void (*)(std::uint32_t* keys);
/// The child step's pushes for 32-bit nodes in one kernel: sorts the 8 keys of child_slab_keys
/// (n of them passing, the other lanes ~0u) and writes the n - 1 farther children as node stack
/// entries, farthest first, to out[0 .. n - 1): 16 bytes each, {double lb = child_key_bound(key)
/// at byte 0, uint32 node = first_child + child_key_index(key) at byte 8, zero bytes 12..15} (the
/// layout of the traversals' entries for a 32-bit Node; knn_query's points flag at byte 12 reads
/// false). out must have room for 8 entries (128 bytes): all 8 are
/// written, those from n - 1 on mean nothing. No branch on the data (bench/notes/: the scalar push
/// loop after sort_keys8 reloaded each key from the sorted store and mispredicted its trip count).
using SortPushKeys8Fn = void (*)(const std::uint32_t* keys, unsigned n, std::uint32_t first_child, void* out);
/// Slab test of up to 8 child boxes against the rays of lanes [0, lanes) of a packet (lanes <= 16):
/// bit j of hits[i] is set when box i grown as in lane j meets its [t_lo, t_hi] (the same
/// conservative test as ChildSlabFn), entry[i * 16 + j] receives a lower bound of the entry
/// parameter. Lanes past `lanes` (up to the next multiple of the vector width) may be computed too.
using PacketChildSlabFn = void (*)(const ChildBoxesF& boxes, const SlabPacketF& p, unsigned lanes,
                                   std::uint32_t* hits, float* entry);
/// Point filter over positions xyz[0..count) (AoS doubles, 3 per point): writes the local
/// indices of the points that may pass to out (capacity count) and returns how many; out[ret,
/// count) may be overwritten. The filter may keep points that fail (never drops one that passes);
/// with per-point radii (and d != 0), every point it keeps passed its widened tests, the last
/// count % width points included (a scalar tail, or an overlapping last step), so a caller may
/// skip its own radius test.
using PointFilterFn = unsigned (*)(const double* xyz, unsigned count, const PointFilterD& f,
                                   std::uint32_t* out);

/// The point filter's per-ray constants for the rays of a packet, one lane per ray (up to 16):
/// lane i holds ray i's PointFilterD o, d, d2_max, t_lo and t_hi (already widened; no per-point
/// radii or normals), so that one point is tested against every ray at once (SIMD over the rays).
struct PointFilterPacketD {
  alignas(64) double o[3][16];
  alignas(64) double d[3][16];
  alignas(64) double d2_max[16];
  alignas(64) double t_lo[16];
  alignas(64) double t_hi[16];
};

/// Point filter of a packet over positions xyz[0..count) (AoS doubles, 3 per point): point j may
/// pass for ray i (a bit of `rays`, i < 16) when it passes lane i's test of PointFilterFn (the
/// same expressions in the same order, so the same points pass as with lane i's PointFilterD
/// alone). Writes, for each point that may pass for some ray, idx[n] = j and masks[n] = those
/// rays, in ascending j, and returns n. idx and masks have room for count entries; entries past
/// n may be overwritten. Lanes outside `rays` are not read into the result.
using PacketPointFilterFn = unsigned (*)(const double* xyz, unsigned count, const PointFilterPacketD& f,
                                         std::uint32_t rays, std::uint32_t* idx, std::uint32_t* masks);

/// Lower bounds of the squared distance (MINDIST^2) from q (relative to the boxes' origin) to up to
/// 8 child boxes: each axis gap is shrunk by `margin` (position space, covering the float rounding
/// of q and of the differences) and the sum scaled down by 2^-20 relative. Writes lb2[0..count).
using ChildDist2Fn = void (*)(const ChildBoxesF& boxes, const float* q, float margin, float* lb2);
/// ChildDist2Fn with the bounds as child order keys (child_key, as ChildSlabKeysFn): returns the
/// mask of the children i < count whose bound lb2[i] <= `bound` (a float the caller rounds up from
/// its double bound), writes keys[0..8): child_key(lb2[i], i) for each child of the mask, ~0u for
/// every other lane, and sets `near` to the least of them (~0u when the mask is empty). knn_query's
/// child step, so that ordering the children is one sort of 8 keys (no insertion sort whose
/// branches mispredict).
using ChildDist2KeysFn = unsigned (*)(const ChildBoxesF& boxes, const float* q, float margin, float bound,
                                      std::uint32_t* keys, std::uint32_t& near);

/// Conservative test of one ray against one box, for the first-hit traversals' root test: false
/// only when the traversal's own node test (ray_query.hpp, test_node: slab_interval_grown of the
/// box grown by pad + tol, t in [t_lo - tol, t_hi + tol], tol = node_test_tolerance(o, box), with
/// pad <= the `pad` given here) rejects the ray. It grows the box and the interval by
/// node_test_tolerance_bound(mag) >= tol instead (mag: the largest |coordinate| of o, lo and hi;
/// no square root), with the same slab expressions in double (1 / d, box - (o +- grow), times 1 /
/// d: each correctly rounded, so a wider growth only widens each axis' interval) and ignores an
/// axis whose interval is NaN. A ray it keeps may still fail the node test. lo, hi: the box's
/// corners; o: the origin; d: the unit direction (finite); 3 doubles each, world coordinates.
/// pad >= 0 and finite (world units); t_lo <= t_hi: ray parameters along d (world units), may be
/// infinite. Coordinates must be far below 1e308 (node_test_tolerance finite).
using RayBoxFn = bool (*)(const double* lo, const double* hi, const double* o, const double* d, double pad,
                          double t_lo, double t_hi);

/// RayBoxFn for the n <= 16 rays of a packet at once: bit i of the result is set when RayBoxFn
/// would return true for ray i (the same expressions lane by lane), whose origin is the 3 doubles
/// at o + i * stride and whose direction those at d + i * stride (stride in doubles; e.g. an
/// array of Ray). Bits from n on are 0.
using PacketRayBoxFn = std::uint32_t (*)(const double* lo, const double* hi, const double* o, const double* d,
                                         std::size_t stride, unsigned n, double pad, double t_lo, double t_hi);

/// Box test of points xyz[0..count) (AoS doubles, 3 per point, world coordinates): writes the
/// local indices of the points with lo <= p <= hi on every axis (the closed box of
/// AABB::contains, lo and hi 3 doubles each) to out in ascending order and returns how many. Exact,
/// not a filter: the same double comparisons as AABB::contains (a NaN coordinate fails), so every
/// path keeps the same points (box_query's nodes the query box cuts). With `ids` (not null: the
/// points' ids, ids[0..count)) it writes ids[j] instead of each kept index j, moved with the mask
/// as the indices are (no second pass over the kept indices). out has room for count entries;
/// out[ret, count) may be overwritten.
using BoxPointsFn = unsigned (*)(const double* xyz, unsigned count, const double* lo, const double* hi,
                                 const std::uint32_t* ids, std::uint32_t* out);
/// The kernels of one path.
struct Kernels {
  SimdPath path;
  ChildSlabFn child_slab;      ///< nullptr for the scalar path
  PointFilterFn point_filter;  ///< nullptr for the scalar path (with d = 0 it filters |p - o|^2)
  ChildDist2Fn child_dist2;    ///< nullptr for the scalar path
  ChildDist2KeysFn child_dist2_keys;    ///< nullptr for the scalar and sse2 paths
  PacketChildSlabFn packet_child_slab;  ///< nullptr for the scalar path
  ChildSlabKeysFn child_slab_keys;      ///< nullptr for the scalar and sse2 paths
  SortKeys8Fn sort_keys8;               ///< nullptr for the scalar and sse2 paths
  SortPushKeys8Fn sort_push_keys8;      ///< nullptr for the scalar and sse2 paths
  RayBoxFn ray_box;                     ///< nullptr for the scalar and sse2 paths
  PacketPointFilterFn packet_point_filter;  ///< nullptr for the scalar and sse2 paths
  PacketRayBoxFn packet_ray_box;            ///< AVX-512 only (else nullptr: ray_box per ray)
  BoxPointsFn box_points;                   ///< nullptr for the scalar and sse2 paths
};

/// The kernels of the active path (simd_path()). Per CPU family (amd_cpu_family), a path's table
/// may take one kernel from a narrower path where that was measured faster (the AVX-512 table's
/// box_points on Zen 4 and Zen 5: the AVX2 kernel); every kernel of a slot keeps the same answers.
const Kernels& active_kernels();

/// The family of this CPU when its vendor is AMD, from CPUID leaf 1 (AMD64 Architecture
/// Programmer's Manual vol. 3, "CPUID Fn0000_0001_EAX": the base family, plus the extended family
/// when the base is 0xF): 0x19 for Zen 3 and Zen 4, 0x1A for Zen 5; 0 for other vendors and off
/// x86. (GCC 12's __builtin_cpu_is names neither Zen 4 nor Zen 5.)
unsigned amd_cpu_family();

}  // namespace simd

namespace detail {

/// An index that exposes its children's float boxes for the SIMD child test (simd.hpp): the optional
/// extension of SpatialIndex (Octree, io::MappedIndex, io::CopcIndex; others: the scalar node test).
template <class I>
concept FloatChildBoxes = requires(const I& idx, typename I::Node n) {
  { idx.child_boxes_f(n) } -> std::convertible_to<simd::ChildBoxesF>;
  { idx.float_origin() } -> std::convertible_to<Vec3>;
  { idx.float_extent() } -> std::convertible_to<double>;
};

/// Rounds x to float towards -inf (down) or +inf (up): infinities are kept, finite values past
/// the float range go to -inf / FLT_MAX (down) and -FLT_MAX / +inf (up), NaN stays NaN.
/// Branch-free: the nearest float, stepped one unit in its IEEE bits (the magnitude up or down by
/// the sign bit) when it lies on the wrong side of x (a branch on that mispredicted about once per
/// camera hit: bench/notes/). A nonzero x's nearest float keeps x's sign,
/// so a +0 only ever steps up to denorm_min and a -0 only down to -denorm_min: the bit step holds.
inline float round_float_down(double x) {
  const float f = static_cast<float>(x);
  const std::uint32_t b = std::bit_cast<std::uint32_t>(f);
  const std::uint32_t wrong = 0u - static_cast<std::uint32_t>(static_cast<double>(f) > x);  // all ones or 0
  return std::bit_cast<float>(b + (wrong & (((b >> 31) << 1) - 1u)));  // negative: +1, else -1
}
inline float round_float_up(double x) {
  const float f = static_cast<float>(x);
  const std::uint32_t b = std::bit_cast<std::uint32_t>(f);
  const std::uint32_t wrong = 0u - static_cast<std::uint32_t>(static_cast<double>(f) < x);
  return std::bit_cast<float>(b + (wrong & (1u - ((b >> 31) << 1))));  // negative: -1, else +1
}

}  // namespace detail
}  // namespace rayscan
