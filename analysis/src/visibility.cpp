#include "rayscan/analysis/visibility.hpp"
#include "site_dispatch.hpp"

#include "rayscan/base/job.hpp"
#include "rayscan/base/progress.hpp"
#include "rayscan/octree/surfel.hpp"
#include "rayscan/octree/traverse.hpp"
#include "rayscan/base/threads.hpp"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace rayscan::analysis {

namespace {

constexpr std::uint32_t kChunk = 512;  // points (or pixel rows' worth of pixels) per work item

template <class Index>
std::size_t index_size(const Index& index) {
  return visit_index([](const auto& i) { return detail::index_points(i); }, index);
}

// First hits of `count` rays, ray(k) for k < count, in batches of up to kBatch for
// ray_first_hit_each (each answer is the single query's, so the batching changes no result),
// use(k, hit) for each k in order. One per thread (its ray buffer is reused).
struct FirstHitBatches {
  static constexpr std::uint32_t kBatch = 64;
  std::vector<Ray> rays;
  std::optional<RayHit> hit[kBatch];

  FirstHitBatches() { rays.reserve(kBatch); }

  template <class Idx, class MakeRay, class Use>
  void run(const Idx& idx, const RayQuery& q, std::uint64_t count, MakeRay&& ray, Use&& use) {
    for (std::uint64_t k0 = 0; k0 < count; k0 += kBatch) {  // (64-bit: no wrap)
      const auto nk = static_cast<std::uint32_t>(std::min<std::uint64_t>(kBatch, count - k0));
      rays.clear();
      for (std::uint64_t k = k0; k < k0 + nk; ++k) rays.push_back(ray(k));
      ray_first_hit_each(idx, std::span<const Ray>(rays), q, std::span<std::optional<RayHit>>(hit, nk));
      for (std::uint32_t j = 0; j < nk; ++j) use(k0 + j, hit[j]);
    }
  }
};

// Height of the surface disc j (centre c, unit normal n, radius r) stands for at horizontal offset
// (dx, dy) from its centre, inside its footprint: for a disc within 45 degrees of level (n_z^2 >=
// 1/2: ground, roofs) the height of its plane there, n . (q - c) = 0, limited to the disc's own
// vertical extent c.z +- r sqrt(1 - n_z^2); for a steeper disc (walls, leaves) its top, c.z + r
// sqrt(1 - n_z^2) (what a first-return DSM records over a wall).
double disc_top(const Vec3& c, const glm::vec3& n, double r, double dx, double dy) {
  const double nz2 = double(n.z) * double(n.z);
  const double e = r * std::sqrt(std::max(0.0, 1.0 - nz2));
  if (nz2 < 0.5) return c.z + e;
  return std::clamp(c.z - (double(n.x) * dx + double(n.y) * dy) / double(n.z), c.z - e, c.z + e);
}

// The surfel rule (is_visible in the header): true when the segment eye -> aim passes below the
// surface of some disc j: c_j projects onto the segment at a parameter t* strictly inside (0, 1),
// the segment's point at t* lies horizontally within r_j of c_j (over or under the disc's
// footprint), and disc_top there exceeds the segment's height by more than `tol`. The surface is
// the height field of the discs, solid below them, like a DSM (first-return surface). Discs of the
// target's own surface that overlap its disc (same_surface and centres within r_i + r_j)
// are not obstacles: the sampled surface must not hide itself at grazing angles. One traversal of
// the index: a node is entered only when the segment's horizontal projection passes within R (the
// largest disc radius) of its box (Liang & Barsky 1984 clipping in x and y) and the box's top plus
// R lies above the segment's lowest point over that stretch (a depth_first walk, traverse.hpp, that
// stops at the first blocking disc).
template <class I>
bool height_field_blocked(const I& idx, const SurfelAttributes& sa, const Vec3& eye, const Vec3& aim,
                          const LeavingSurface& target, double tol) {
  const Vec3 v = aim - eye;
  const double h2 = v.x * v.x + v.y * v.y;
  if (!(h2 > 1e-24)) return false;  // the target lies straight below or above the eye
  const double R = sa.max_radius;
  const auto pos = idx.positions();
  const IdView ids = idx.ids();
  using Node = typename I::Node;
  // The node test: the segment's horizontal projection passes within R of the box, and the box's
  // top plus R lies above the segment's lowest point over that stretch.
  const auto near_segment = [&](Node n) {
    const AABB b = idx.node_bounds(n);
    double t0 = 0.0, t1 = 1.0;
    bool miss = false;
    for (int a = 0; a < 2 && !miss; ++a) {
      const double lo = b.lo[a] - R - eye[a], hi = b.hi[a] + R - eye[a];
      if (std::abs(v[a]) < 1e-300) {
        miss = lo > 0.0 || hi < 0.0;
        continue;
      }
      double ta = lo / v[a], tb = hi / v[a];
      if (ta > tb) std::swap(ta, tb);
      t0 = std::max(t0, ta);
      t1 = std::min(t1, tb);
      miss = t0 > t1;
    }
    if (miss) return Enter::no;
    if (b.hi.z + R <= eye.z + std::min(t0 * v.z, t1 * v.z) + tol) return Enter::no;  // box below the segment there
    return Enter::yes;
  };
  // The leaf: true (stop) at the first disc that blocks the segment.
  const auto blocks = [&](const NodeVisit<Node>& nv) {
    for (std::uint32_t s = nv.slots.begin; s < nv.slots.end; ++s) {
      const PointIndex j = ids[s];
      const Vec3& c = pos[s];
      const double t = ((c.x - eye.x) * v.x + (c.y - eye.y) * v.y) / h2;
      if (!(t > 0.0 && t < 1.0)) continue;  // beside the eye or beyond the target
      const double rj = sa.radii[j];
      const double zr = eye.z + t * v.z + tol;  // the segment's height there (plus tolerance)
      if (!(c.z + rj > zr)) continue;
      const double dx = eye.x + t * v.x - c.x, dy = eye.y + t * v.y - c.y;
      if (dx * dx + dy * dy > rj * rj) continue;
      if (!(disc_top(c, sa.normals[j], rj, dx, dy) > zr)) continue;
      const Vec3 w = c - target.position;
      const double reach = target.radius + rj;  // discs overlapping the target's own disc
      if (glm::dot(w, w) <= reach * reach && same_surface(target, j, c, Vec3(sa.normals[j]), rj)) continue;
      return true;
    }
    return false;
  };
  return depth_first(idx, near_segment, blocks);
}

// One line-of-sight decision (see is_visible in the header). `queried` is set when a ray query
// was issued; `dist` receives D.
template <class I>
bool line_of_sight(const I& idx, const Observer& obs, double max_d,
                   const Vec3& p, PointIndex i, const VisibilityOptions& opts,
                   std::vector<RayHit>& hits, bool& queried, double& dist) {
  queried = false;
  const Vec3 v = p - obs.position;
  const double D = glm::length(v);
  dist = D;
  if (!within_view_limits(obs, max_d, v, D)) return false;
  const double r = opts.radius;
  if (D <= r) return true;
  const Vec3 aim = v + Vec3(0.0, 0.0, opts.target_height);  // towards P' = P + h_t z
  const double Da = glm::length(aim);
  if (Da <= r) return true;
  const Ray ray(obs.position, aim);
  if (opts.surfels) {
    queried = true;
    const SurfelAttributes& sa = *opts.surfels;
    const LeavingSurface target{i, p, Vec3(sa.normals[i]), sa.radii[i]};
    return !height_field_blocked(idx, sa, obs.position, p + Vec3(0.0, 0.0, opts.target_height), target,
                                 opts.tolerance);
  }
  RayQuery q;
  q.k = 1;
  q.radius = r;
  q.order = RayOrder::sphere_hit;
  q.t_min = 0.0;
  q.t_max = Da - r;
  ray_query(idx, ray, q, hits);
  queried = true;
  if (hits.empty()) return true;
  const RayHit& h = hits.front();
  if (h.index == i) return true;
  const double tj = ray_point_terms(ray.origin(), ray.direction(), idx.positions()[h.slot]).t;
  return tj >= Da - opts.tolerance;
}

void check(const VisibilityOptions& o) {
  if (!(o.radius > 0.0) || !std::isfinite(o.radius))
    throw std::invalid_argument("visibility: sphere radius must be a finite number > 0");
  if (!(o.tolerance >= 0.0)) throw std::invalid_argument("visibility: tolerance must be >= 0");
  if (!(o.max_distance >= 0.0)) throw std::invalid_argument("visibility: max distance must be >= 0");
  if (!(o.target_height >= 0.0) || !std::isfinite(o.target_height))
    throw std::invalid_argument("visibility: target height must be a finite number >= 0");
  if (o.surfels && o.surfels->radii.size() != o.surfels->normals.size())
    throw std::invalid_argument("visibility: surfel normals and radii differ in count");
}

/// Runs `run_chunks(c0, c1)` over the `chunks` point chunks (kChunk slots each, in the index's
/// storage order `ids`, stored or the identity) through the distributor (MPI, docs/mpi.md): chunks are handed out in
/// batches of `batch`, and the per-point result `fields` (arrays indexed by original point id) of
/// each batch's slots travel back to the root, field after field. `what` names the job in the
/// error for a malformed message. Progress counts points.
template <class RunChunks>
void distribute_point_chunks(WorkDistributor& dist, std::size_t n, std::size_t chunks, unsigned batch,
                             IdView ids, RunChunks& run_chunks, Progress& progress, const char* what,
                             std::span<const GatheredField> fields) {
  auto slots = [n](std::uint64_t first, std::uint64_t count) {
    return std::pair{std::size_t(first * kChunk), std::min<std::size_t>(n, (first + count) * kChunk)};
  };
  std::size_t record = 0;
  for (const GatheredField& f : fields) record += f.size;
  WorkStage stage;
  stage.items = chunks;
  stage.batch = batch;
  stage.compute = [&](std::uint64_t first, std::uint64_t count) { run_chunks(first, first + count); };
  stage.pack = [&](std::uint64_t first, std::uint64_t count) {
    const auto [s0, s1] = slots(first, count);
    std::vector<std::byte> out;
    out.reserve((s1 - s0) * record);
    for (const GatheredField& f : fields)
      for (std::size_t s = s0; s < s1; ++s) {
        const std::byte* v = f.data + std::size_t(ids[s]) * f.size;
        out.insert(out.end(), v, v + f.size);
      }
    return out;
  };
  stage.unpack = [&](std::uint64_t first, std::uint64_t count, std::span<const std::byte> bytes) {
    const auto [s0, s1] = slots(first, count);
    std::size_t off = 0;
    for (const GatheredField& f : fields)
      for (std::size_t s = s0; s < s1; ++s) read_bytes(bytes, off, std::span(f.data + std::size_t(ids[s]) * f.size, f.size));
    if (off != bytes.size()) throw std::runtime_error(std::string(what) + ": chunk message has trailing bytes");
    progress.tile_done(s1 - s0);
  };
  dist.run(stage);
}

}  // namespace

template <class Index>
bool is_visible_over(const Index& index, std::span<const Vec3> positions, const Observer& observer,
                PointIndex i, const VisibilityOptions& opts, std::vector<RayHit>& scratch) {
  check(opts);
  if (i >= positions.size()) throw std::out_of_range("is_visible: point index out of range");
  if (opts.surfels && opts.surfels->radii.size() != positions.size())
    throw std::invalid_argument("visibility: surfel attributes were not computed for these positions");
  const double max_d = observer.max_distance.value_or(opts.max_distance);
  bool queried;
  double dist;
  return visit_index(
      [&](const auto& idx) {
        [[maybe_unused]] const auto scope = detail::chunk_scope(idx);
        return line_of_sight(idx, observer, max_d, positions[i], i, opts, scratch, queried, dist);
      },
      index);
}

template <class Index>
VisibilityResult compute_visibility_over(const Index& index, std::span<const Vec3> positions,
                                    std::span<const Observer> observers, const VisibilityOptions& opts) {
  check(opts);
  if (index_size(index) != positions.size())
    throw std::invalid_argument("visibility: the index was not built over these positions");
  if (opts.surfels && opts.surfels->radii.size() != positions.size())
    throw std::invalid_argument("visibility: surfel attributes were not computed for these positions");
  const std::size_t n = positions.size(), m = observers.size();
  VisibilityResult res;
  res.count.assign(n, 0);
  res.nearest.assign(n, -1.0);
  res.per_observer.assign(m, 0);
  res.pairs = std::uint64_t(n) * m;
  res.threads = resolve_threads(opts.threads);
  if (n == 0 || m == 0) return res;
  std::vector<double> max_d(m);
  for (std::size_t k = 0; k < m; ++k) max_d[k] = observers[k].max_distance.value_or(opts.max_distance);

  // The points' visiting order on a COPC file in place (empty elsewhere: the index's slot order).
  const std::vector<PointIndex> order =
      visit_index([&](const auto& i) { return detail::loop_order(i, positions); }, index);
  const std::size_t chunks = (n + kChunk - 1) / kChunk;
  Progress progress(chunks, opts.progress,
                            ProgressUnits{"chunks", "points/s", 1.0, 0});
  struct Local {
    std::vector<std::uint64_t> seen;
    std::uint64_t queries = 0;
    std::vector<RayHit> hits;
  };
  tbb::enumerable_thread_specific<Local> locals([m] { return Local{std::vector<std::uint64_t>(m, 0), 0, {}}; });
  tbb::task_arena arena(static_cast<int>(res.threads));
  const auto t0 = std::chrono::steady_clock::now();
  // Chunks [c0, c1) of kChunk points in the index's storage order.
  auto run_chunks = [&](std::size_t c0, std::size_t c1) {
    arena.execute([&] {
      visit_index(
          [&](const auto& idx) {
            const auto pos = detail::loop_positions(idx, positions, order);
            const IdView ids = detail::loop_ids(idx, order);
            tbb::parallel_for(tbb::blocked_range<std::size_t>(c0, c1, 1), [&](const auto& range) {
              Local& L = locals.local();
              for (std::size_t c = range.begin(); c != range.end(); ++c) {
                throw_if_cancelled(opts.cancel);  // out of the loop: TBB skips the ranges not started
                [[maybe_unused]] const auto scope = detail::chunk_scope(idx);
                const std::size_t s0 = c * kChunk, s1 = std::min(n, s0 + kChunk);
                // Observer-major inside a chunk: consecutive rays share most of their nodes.
                for (std::size_t k = 0; k < m; ++k)
                  for (std::size_t s = s0; s < s1; ++s) {
                    const PointIndex i = ids[s];
                    bool queried;
                    double dist;
                    const bool vis = line_of_sight(idx, observers[k], max_d[k], pos[s], i, opts,
                                                   L.hits, queried, dist);
                    L.queries += queried;
                    if (!vis) continue;
                    ++res.count[i];
                    ++L.seen[k];
                    if (res.nearest[i] < 0.0 || dist < res.nearest[i]) res.nearest[i] = dist;
                  }
                progress.tile_done(s1 - s0);  // points of the chunk, each against every observer
              }
            });
          },
          index);
    });
  };
  WorkDistributor* dist = opts.distributor;
  if (!dist || dist->size() <= 1) {
    run_chunks(0, chunks);
  } else {
    // Point chunks handed out by the distributor; per-point count and distance gathered to the root.
    const IdView ids = visit_index([&](const auto& i) { return detail::loop_ids(i, order); }, index);
    const GatheredField fields[] = {GatheredField::of(res.count), GatheredField::of(res.nearest)};
    distribute_point_chunks(*dist, n, chunks, res.threads, ids, run_chunks, progress, "visibility", fields);
  }
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  progress.finish();
  for (const Local& L : locals) {
    res.queries += L.queries;
    for (std::size_t k = 0; k < m; ++k) res.per_observer[k] += L.seen[k];
  }
  if (opts.distributor && opts.distributor->size() > 1) {
    res.per_observer.push_back(res.queries);
    opts.distributor->sum_to_root(res.per_observer);
    res.queries = res.per_observer.back();
    res.per_observer.pop_back();
  }
  return res;
}

namespace {

template <class Index>
void trace_directions_over(const Index& index, std::span<const Vec3> positions, std::span<const Vec3> dirs,
                           std::span<const Vec3> normals, const VisibilityOptions& opts,
                           const std::function<void(PointIndex, std::span<const std::uint64_t>)>& visit,
                           bool cull, std::span<const GatheredField> gather) {
  check(opts);
  if (index_size(index) != positions.size())
    throw std::invalid_argument("directions: the index was not built over these positions");
  if (opts.surfels && opts.surfels->radii.size() != positions.size())
    throw std::invalid_argument("directions: surfel attributes were not computed for these positions");
  if (!normals.empty() && normals.size() != positions.size())
    throw std::invalid_argument("directions: normals and positions differ in count");
  const std::size_t n = positions.size(), m = dirs.size(), words = (m + 63) / 64;
  if (n == 0) return;
  // Surfels: far enough that every point of the site lies between the observer and P_i.
  double far = 0.0;
  if (opts.surfels) {
    AABB box;
    for (const Vec3& p : positions) box.expand(p);
    far = 2.0 * glm::length(box.extent()) + 1.0;
  }
  // The points' visiting order on a COPC file in place (empty elsewhere: the index's slot order).
  const std::vector<PointIndex> order =
      visit_index([&](const auto& i) { return detail::loop_order(i, positions); }, index);
  const std::size_t chunks = (n + kChunk - 1) / kChunk;
  Progress progress(chunks, opts.progress, ProgressUnits{"chunks", "points/s", 1.0, 0});
  struct Local {
    std::vector<std::uint64_t> mask;  // the open directions of a group's points, `words` each
    std::vector<RayHit> hits;
    std::vector<Ray> rays;
    std::optional<RayHit> hit[kMaxRayPacket];
    Observer sun;  // surfels: the far eye of the current ray (only its position changes)
  };
  tbb::enumerable_thread_specific<Local> locals;
  // Spheres: one first-hit query per direction from the point outward, as the sky view's rays,
  // starting target_height above the point; a sphere entered within `tolerance` of the start is
  // the point's own surface.
  RayQuery q;
  q.k = 1;
  q.radius = opts.radius;
  q.order = RayOrder::sphere_hit;
  q.t_min = opts.tolerance;
  q.t_max = kInf;
  q.validate();
  const unsigned threads = resolve_threads(opts.threads);
  tbb::task_arena arena(static_cast<int>(threads));
  // Chunks [c0, c1) of kChunk points in the index's storage order.
  auto run_chunks = [&](std::size_t c0, std::size_t c1) {
  arena.execute([&] {
    visit_index(
        [&](const auto& idx) {
          const auto pos = detail::loop_positions(idx, positions, order);
          const IdView ids = detail::loop_ids(idx, order);
          tbb::parallel_for(tbb::blocked_range<std::size_t>(c0, c1, 1), [&](const auto& range) {
            Local& L = locals.local();
            for (std::size_t c = range.begin(); c != range.end(); ++c) {
              throw_if_cancelled(opts.cancel);
              [[maybe_unused]] const auto scope = detail::chunk_scope(idx);
              const std::size_t s0 = c * kChunk, s1 = std::min(n, s0 + kChunk);
              // Groups of up to kMaxRayPacket neighbouring points (storage order: an octree
              // leaf's points, or neighbouring leaves), traced direction by direction: the
              // group's rays in one direction are parallel with nearby origins, a coherent packet
              // (ray_first_hit_packet; with spheres 15 % less CPU than each point's directions
              // as a batch on autzen at 3-degree sectors, bench/notes/), and the answers are
              // those of single rays bit for bit.
              for (std::size_t g0 = s0; g0 < s1; g0 += kMaxRayPacket) {
                const std::size_t ng = std::min<std::size_t>(kMaxRayPacket, s1 - g0);
                L.mask.assign(ng * words, 0);
                PointIndex id[kMaxRayPacket];
                Vec3 origin[kMaxRayPacket];
                for (std::size_t j = 0; j < ng; ++j) {
                  id[j] = ids[g0 + j];
                  // Spheres: the ray starts target_height above the point; a sphere entered
                  // within `tolerance` of the start is the point's own surface (q.t_min).
                  origin[j] = pos[g0 + j] + opts.target_height * (normals.empty() ? Vec3(0.0, 0.0, 1.0) : normals[id[j]]);
                }
                for (std::uint32_t k = 0; k < m; ++k) {
                  const std::uint64_t bit = std::uint64_t(1) << (k % 64);
                  std::uint32_t which[kMaxRayPacket], nsel = 0;
                  for (std::size_t j = 0; j < ng; ++j)  // the points whose surface faces direction k
                    if (!cull || normals.empty() || glm::dot(normals[id[j]], dirs[k]) > 0.0)
                      which[nsel++] = static_cast<std::uint32_t>(j);
                  if (opts.surfels) {
                    // Surfels: the line of sight from a sun far beyond the site (is_visible's rule).
                    for (std::uint32_t t = 0; t < nsel; ++t) {
                      const std::uint32_t j = which[t];
                      L.sun.position = pos[g0 + j] + far * dirs[k];
                      const Observer& sun = L.sun;
                      bool queried;
                      double dist;
                      if (line_of_sight(idx, sun, kInf, pos[g0 + j], id[j], opts, L.hits, queried, dist))
                        L.mask[j * words + k / 64] |= bit;
                    }
                    continue;
                  }
                  if (nsel == 0) continue;
                  L.rays.clear();
                  for (std::uint32_t t = 0; t < nsel; ++t) L.rays.push_back(Ray(origin[which[t]], dirs[k]));
                  ray_first_hit_packet(idx, std::span<const Ray>(L.rays), q, std::span<std::optional<RayHit>>(L.hit, nsel));
                  for (std::uint32_t t = 0; t < nsel; ++t)
                    if (!L.hit[t] || L.hit[t]->index == id[which[t]]) L.mask[which[t] * words + k / 64] |= bit;
                }
                for (std::size_t j = 0; j < ng; ++j)
                  visit(id[j], std::span<const std::uint64_t>(L.mask.data() + j * words, words));
              }
              progress.tile_done(s1 - s0);
            }
          });
        },
        index);
  });
  };
  WorkDistributor* dist = opts.distributor;
  if (!dist || dist->size() <= 1) {
    run_chunks(0, chunks);
  } else {
    // Point chunks handed out by the distributor; the visitor's per-point results gathered to the root.
    const IdView ids = visit_index([&](const auto& i) { return detail::loop_ids(i, order); }, index);
    distribute_point_chunks(*dist, n, chunks, threads, ids, run_chunks, progress, "directions", gather);
  }
  progress.finish();
}

}  // namespace

Vec3 sky_direction(std::uint32_t k, std::uint32_t n, double rotation, SkyWeighting weighting) {
  const double u = (double(k) + 0.5) / double(n);  // in (0, 1)
  const double z = weighting == SkyWeighting::uniform ? 1.0 - u : std::sqrt(1.0 - u);
  const double s = std::sqrt(std::max(0.0, 1.0 - z * z));
  // 2 pi k / golden ratio = 2 pi k (phi - 1), taken modulo 2 pi on the fractional part first.
  const double frac = std::fmod(double(k) * (std::numbers::phi - 1.0), 1.0);
  const double phi = 2.0 * std::numbers::pi * frac + rotation;
  return {s * std::cos(phi), s * std::sin(phi), z};
}

double sky_rotation(std::uint64_t seed, std::uint64_t i) {
  // SplitMix64 (Steele, Lea, Flood 2014) of the combined key.
  std::uint64_t z = seed * 0x9E3779B97F4A7C15ull + i + 0x632BE59BD9B4E019ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return 2.0 * std::numbers::pi * (double(z >> 11) * 0x1.0p-53);
}

template <class Index>
std::vector<double> compute_sky_view_over(const Index& index, std::span<const Vec3> positions,
                                     const SkyViewOptions& opts, std::uint64_t* queries) {
  if (opts.rays == 0) throw std::invalid_argument("sky view: the number of rays must be >= 1");
  if (!(opts.radius > 0.0) || !std::isfinite(opts.radius))
    throw std::invalid_argument("sky view: sphere radius must be a finite number > 0");
  if (!(opts.lift >= 0.0) || !std::isfinite(opts.lift))
    throw std::invalid_argument("sky view: lift must be a finite number >= 0");
  if (!(opts.max_distance >= 0.0)) throw std::invalid_argument("sky view: max distance must be >= 0");
  if (index_size(index) != positions.size())
    throw std::invalid_argument("sky view: the index was not built over these positions");
  const std::size_t n = positions.size();
  std::vector<double> out(n, 0.0);
  if (n == 0) return out;
  // The points' visiting order on a COPC file in place (empty elsewhere: the index's slot order).
  const std::vector<PointIndex> order =
      visit_index([&](const auto& i) { return detail::loop_order(i, positions); }, index);
  const std::size_t chunks = (n + kChunk - 1) / kChunk;
  Progress progress(chunks, opts.progress,
                            ProgressUnits{"chunks", "points/s", 1.0, 0});
  std::atomic<std::uint64_t> total{0};
  RayQuery q;
  q.k = 1;
  q.radius = opts.radius;
  q.order = RayOrder::sphere_hit;
  q.t_min = 0.0;
  q.t_max = opts.max_distance;
  q.validate();  // (once: ray_first_hit_each does not validate)
  const unsigned threads = resolve_threads(opts.threads);
  tbb::task_arena arena(static_cast<int>(threads));
  auto run_chunks = [&](std::size_t c0, std::size_t c1) {
    arena.execute([&] {
      visit_index(
          [&](const auto& idx) {
            const auto pos = detail::loop_positions(idx, positions, order);
            const IdView ids = detail::loop_ids(idx, order);
            tbb::parallel_for(tbb::blocked_range<std::size_t>(c0, c1, 1), [&](const auto& range) {
              FirstHitBatches batches;  // a point's sky rays
              for (std::size_t c = range.begin(); c != range.end(); ++c) {
                throw_if_cancelled(opts.cancel);
                [[maybe_unused]] const auto scope = detail::chunk_scope(idx);
                const std::size_t s0 = c * kChunk, s1 = std::min(n, s0 + kChunk);
                for (std::size_t s = s0; s < s1; ++s) {
                  const PointIndex i = ids[s];
                  const Vec3 origin = pos[s] + Vec3(0.0, 0.0, opts.lift);
                  const double rot = sky_rotation(opts.seed, i);
                  std::uint32_t open = 0;
                  batches.run(
                      idx, q, opts.rays,
                      [&](std::uint64_t k) {
                        return Ray(origin, sky_direction(static_cast<std::uint32_t>(k), opts.rays, rot, opts.weighting));
                      },
                      [&](std::uint64_t, const std::optional<RayHit>& hit) { open += !hit.has_value(); });
                  out[i] = double(open) / double(opts.rays);
                }
                const std::uint64_t nq = std::uint64_t(s1 - s0) * opts.rays;
                total += nq;
                progress.tile_done(s1 - s0);
              }
            });
          },
          index);
    });
  };
  WorkDistributor* dist = opts.distributor;
  if (!dist || dist->size() <= 1) {
    run_chunks(0, chunks);
  } else {
    const IdView ids = visit_index([&](const auto& i) { return detail::loop_ids(i, order); }, index);
    const GatheredField fields[] = {GatheredField::of(out)};
    distribute_point_chunks(*dist, n, chunks, threads, ids, run_chunks, progress, "sky view", fields);
    std::uint64_t t = total.load();
    dist->sum_to_root(std::span<std::uint64_t>(&t, 1));
    total = t;
  }
  progress.finish();
  if (queries) *queries = total.load();
  return out;
}

template <class Index>
std::vector<std::uint32_t> camera_first_hits_over(const Index& index, const Camera& camera,
                                             double radius, double max_distance, unsigned threads,
                                             bool progress_bar, WorkDistributor* distributor,
                                             const std::atomic<bool>* cancel) {
  if (!(radius > 0.0) || !std::isfinite(radius))
    throw std::invalid_argument("camera visibility: sphere radius must be a finite number > 0");
  if (!(max_distance >= 0.0)) throw std::invalid_argument("camera visibility: max distance must be >= 0");
  const std::uint32_t W = camera.width(), H = camera.height();
  std::vector<std::uint32_t> out(std::size_t(W) * H, kNoPoint);
  if (out.empty() || index_size(index) == 0) return out;
  RayQuery q;
  q.k = 1;
  q.radius = radius;
  q.order = RayOrder::sphere_hit;
  q.t_min = 0.0;
  q.t_max = max_distance;
  q.validate();  // (once: ray_first_hit_each does not validate)
  Progress progress(H, progress_bar,
                            ProgressUnits{"rows", "M rays/s", 1e-6, 2});
  const unsigned nthreads = resolve_threads(threads);
  tbb::task_arena arena(static_cast<int>(nthreads));
  auto run_rows = [&](std::uint32_t y0, std::uint32_t y1) {
    arena.execute([&] {
      visit_index(
          [&](const auto& idx) {
            tbb::parallel_for(tbb::blocked_range<std::uint32_t>(y0, y1, 1), [&](const auto& range) {
              FirstHitBatches batches;  // a row's rays
              for (std::uint32_t y = range.begin(); y != range.end(); ++y) {
                throw_if_cancelled(cancel);
                [[maybe_unused]] const auto scope = detail::chunk_scope(idx);
                batches.run(
                    idx, q, W, [&](std::uint64_t x) { return camera.generate_ray(static_cast<std::uint32_t>(x), y); },
                    [&](std::uint64_t x, const std::optional<RayHit>& hit) {
                      if (hit) out[std::size_t(y) * W + x] = hit->index;
                    });
                progress.tile_done(W);
              }
            });
          },
          index);
    });
  };
  if (!distributor || distributor->size() <= 1) {
    run_rows(0, H);
  } else {
    // Image rows handed out by the distributor; the first hit per pixel gathered to the root.
    WorkStage stage;
    stage.items = H;
    stage.batch = nthreads;
    stage.compute = [&](std::uint64_t first, std::uint64_t count) {
      run_rows(std::uint32_t(first), std::uint32_t(first + count));
    };
    stage.pack = [&](std::uint64_t first, std::uint64_t count) {
      std::vector<std::byte> bytes;
      append_bytes(bytes, std::span<const std::uint32_t>(out).subspan(first * W, count * W));
      return bytes;
    };
    stage.unpack = [&](std::uint64_t first, std::uint64_t count, std::span<const std::byte> bytes) {
      std::size_t off = 0;
      read_values(bytes, off, std::span<std::uint32_t>(out).subspan(first * W, count * W));
      if (off != bytes.size()) throw std::runtime_error("camera visibility: row message has trailing bytes");
      progress.tile_done(count * W);
    };
    distributor->run(stage);
  }
  progress.finish();
  return out;
}

std::vector<std::uint32_t> count_pixel_hits(std::span<const std::uint32_t> pixel_hits, std::size_t npoints) {
  std::vector<std::uint32_t> count(npoints, 0);
  for (const std::uint32_t i : pixel_hits) {
    if (i == kNoPoint) continue;
    if (i >= npoints) throw std::out_of_range("camera visibility: pixel hit index out of range");
    ++count[i];
  }
  return count;
}

bool is_visible(const Site& site, std::span<const Vec3> positions, const Observer& observer, PointIndex i,
                const VisibilityOptions& opts, std::vector<RayHit>& scratch) {
  return detail::over_site<bool>(site, [&](const auto& index) {
    return is_visible_over(index, positions, observer, i, opts, scratch);
  });
}
VisibilityResult compute_visibility(const Site& site, std::span<const Vec3> positions,
                                    std::span<const Observer> observers, const VisibilityOptions& opts) {
  return detail::over_site<VisibilityResult>(site, [&](const auto& index) {
    return compute_visibility_over(index, positions, observers, opts);
  });
}
void trace_directions(const Site& site, std::span<const Vec3> positions, std::span<const Vec3> dirs,
                      std::span<const Vec3> normals, const VisibilityOptions& opts,
                      const std::function<void(PointIndex, std::span<const std::uint64_t>)>& visit,
                      bool cull, std::span<const GatheredField> gather) {
  detail::over_site<int>(site, [&](const auto& index) {
    trace_directions_over(index, positions, dirs, normals, opts, visit, cull, gather);
    return 0;
  });
}

std::size_t orient_steep_normals(const Site& site, std::span<const Vec3> positions, std::span<Vec3> normals,
                                 double radius, unsigned threads) {
  if (!(radius > 0.0) || !std::isfinite(radius))
    throw std::invalid_argument("normal orientation: the radius must be a finite number > 0");
  if (normals.size() != positions.size())
    throw std::invalid_argument("normal orientation: normals and positions differ in count");
  RayQuery q;
  q.k = 1;
  q.radius = radius;
  q.order = RayOrder::sphere_hit;
  q.t_min = 2.0 * radius;
  q.t_max = kInf;
  q.validate();
  std::atomic<std::size_t> turned{0};
  detail::over_site<int>(site, [&](const auto& index) {
    visit_index(
        [&](const auto& idx) {
          const std::vector<PointIndex> order = detail::loop_order(idx, positions);  // (COPC; else empty)
          tbb::task_arena arena(static_cast<int>(resolve_threads(threads)));
          arena.execute([&] {
            tbb::parallel_for(tbb::blocked_range<std::size_t>(0, positions.size(), kChunk), [&](const auto& range) {
              [[maybe_unused]] const auto scope = detail::chunk_scope(idx);
              std::size_t local = 0;
              for (std::size_t k = range.begin(); k != range.end(); ++k) {
                const std::size_t i = order.empty() ? k : order[k];
                Vec3& n = normals[i];
                if (!(std::abs(n.z) < 0.5)) continue;
                // 20 degrees up: off the ground at once, where a level ray would graze it.
                const Vec3 h = glm::normalize(Vec3(n.x, n.y, 0.0));
                const Vec3 up(0.0, 0.0, 0.364);
                const auto out = ray_first_hit(idx, Ray(positions[i] + radius * h, glm::normalize(h + up)), q);
                const auto in = ray_first_hit(idx, Ray(positions[i] - radius * h, glm::normalize(up - h)), q);
                const double t_out = out ? out->t : kInf, t_in = in ? in->t : kInf;
                if (t_in > t_out) {
                  n = -n;
                  ++local;
                }
              }
              turned += local;
            });
          });
          return 0;
        },
        index);
    return 0;
  });
  return turned.load();
}
std::vector<double> compute_sky_view(const Site& site, std::span<const Vec3> positions, const SkyViewOptions& opts,
                                     std::uint64_t* queries) {
  return detail::over_site<std::vector<double>>(site, [&](const auto& index) {
    return compute_sky_view_over(index, positions, opts, queries);
  });
}
std::vector<std::uint32_t> camera_first_hits(const Site& site, const Camera& camera, double radius,
                                             double max_distance, unsigned threads, bool progress_bar,
                                             WorkDistributor* distributor, const std::atomic<bool>* cancel) {
  return detail::over_site<std::vector<std::uint32_t>>(site, [&](const auto& index) {
    return camera_first_hits_over(index, camera, radius, max_distance, threads, progress_bar, distributor, cancel);
  });
}

}  // namespace rayscan::analysis
