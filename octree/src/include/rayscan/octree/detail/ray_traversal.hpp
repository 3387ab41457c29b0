// The one traversal of the ray query (paper Algorithm 1): RayTraversal, its node test, leaf work
// and candidate sink (the policies every single-ray and packet query shares).
// Part of the ray query's private implementation (include detail/ray_query_impl.hpp).
#pragma once

#include "rayscan/octree/detail/ray_scratch.hpp"

#include <bit>

namespace rayscan::detail {

/// The one traversal of the ray query (see ray_query for the semantics), as the per-ray state and
/// its policies: the node test (test_node, and test_children: all children of a node at once, SIMD
/// on FloatChildBoxes indexes), the leaf work (eval_points: SIMD filter + exact double test) and
/// the candidate sink (push_candidate with the dynamic k filter), plus the depth-first loop
/// (traverse_from, in steps of one node: step). ray_traverse runs the loop from the root for one
/// ray; first_hit_pair steps two rays' loops in turn; the packet first hit (first_hit_packet)
/// drives several of these states down one shared stack and hands a subtree to traverse_from when
/// the packet diverges, so all use the same node test and leaf work.
///
/// Candidates go to the per-thread k-heap (scratch.cands) or, with kBest1 (k = 1: the first hit of
/// a renderer), to `best` alone: no heap and no vector (a compile-time policy, not a copy).
/// Expects a validated query, a non-empty index and k >= 1. `key_policy`: OrderKey or RefinedKey.
/// `K`: the kernel policy, simd::Kernels (the active path's table, called through pointers) or a
/// compile-time policy of simd_kernels.hpp for the instances compiled per ISA (ray_traverse).
/// prepare() clears the per-thread scratch (one traversal per thread and scratch at a time; the
/// states of one packet are all prepared before any of them traverses; the two rays of
/// first_hit_pair use two scratches).
/// What the first-hit traversals' root test found (root_test).
enum class RootTest {
  miss,   ///< the ray misses the root: nothing to set up or traverse
  enter,  ///< the ray may enter (RayTraversal::enters_root: without its own root test where it can)
  exact,  ///< no kernel test applies: the traversal's own node test decides at the root
};

template <bool kBest1, SpatialIndex I, class KeyPolicy = OrderKey, class K = simd::Kernels>
struct RayTraversal {
  using Node = typename I::Node;
  static constexpr bool per_node = KeyPolicy::node_radius;
  static constexpr bool per_box = KeyPolicy::node_box;
  // The per-node geometry boxes in float: the SIMD child test on them is final (RefinedKey).
  static constexpr bool per_box_f = KeyPolicy::child_boxes_f && detail::FloatChildBoxes<I>;

  const I& index;
  const RayQuery& q;
  Candidate& best;
  RayQueryStats* stats;
  const KeyPolicy& key_policy;
  Vec3 o, d, inv_d;
  std::remove_cvref_t<decltype(std::declval<const I&>().positions())> pos;
  IdView ids;
  bool bounded;
  bool found = false;  // kBest1: best holds a candidate
  bool sphere, ray_order, exact, has_planes;
  bool done = false;  // any_hit: a candidate was found
  double radius, r2;
  AABB root_box;
  double dist_center;  // |o - centre of the root box|
  double tol;
  // Current bounds, tightened by the dynamic k filter (Algorithm 1, step 2).
  double worst = kInf;  // worst kept key once k candidates are held
  double pad;           // node distance bound: r, tightened to the k-bound for order ray
  Vec3 o_plus, o_minus;  // slab planes of the box grown by pad
  double t_lo, t_hi;
  // Geometry boxes (RefinedKey::node_box): the least ray parameter a hit inside one can have: t_lo,
  // raised to the key functor's key_min() when it has one (the query's own t_lo may lie far below).
  static constexpr bool key_floor_known = per_box && requires(const KeyPolicy& kp) { kp.key.key_min(); };
  double box_t_lo;
  RayScratch<Node>& scratch;
  KernelsOf<K> kern;
  double slack_t = 0, slack_d2 = 0;
  simd::PointFilterD pf;
  simd::SlabRayF sr{};
  simd::SlabRayF sr_box{};  // per_box_f: the ray's slabs for the float geometry boxes (no pad)
  bool simd_children = false;
  Vec3 o_rel{0.0};
  double mag = 0;
  bool slab_is_final = false;  // children whose SIMD slab result is final (else it only prefilters)
  bool child_keys = false;     // traverse_from's child step on child order keys (child_slab_keys)
  bool prepared = false;       // prepare() ran
  Node skip = static_cast<Node>(-1);  // entry_final: a subtree already traversed (not again)
  double entry_t0 = 0;                // entry_node: the ray's entry into the grown root box
  unsigned entry_ijk[3] = {0, 0, 0};  // entry_node: its cell in the deepest grid
  unsigned entry_depth = 0;           // entry_node: its node's depth
  bool radii_filter = false;   // the SIMD point filter applies the key functor's per-slot radii
  bool normals_filter = false;  // ... and its per-slot disc normals (filter_normals)

  /// `scratch_`: the per-thread scratch to use (node stack, survivors), by default ray_scratch<Node>().
  /// `sibling`: a traversal of the same index and query (first_hit_packet's previous ray), or
  /// nullptr: its root box is taken instead of read again, and, when its origin is this ray's
  /// (the rays of a pinhole camera), its distance to the root's centre and tolerance instead of
  /// computed (the same values: the same expressions of the same inputs).
  RayTraversal(const I& index_, const Ray& ray, const RayQuery& q_, Candidate& best_, RayQueryStats* stats_,
               const KeyPolicy& key_policy_, RayScratch<Node>* scratch_ = nullptr,
               const RayTraversal* sibling = nullptr)
      : index(index_), q(q_), best(best_), stats(stats_), key_policy(key_policy_), o(ray.origin()),
        d(ray.direction()), inv_d(1.0 / d), pos(index_.positions()), ids(index_.ids()),
        bounded(kBest1 || q_.k != kAllPoints), sphere(q_.order == RayOrder::sphere_hit),
        ray_order(q_.order == RayOrder::ray), exact(q_.node_distance == NodeDistance::exact),
        has_planes(!q_.planes.empty()), radius(q_.radius), r2(q_.radius * q_.radius),
        root_box(sibling ? sibling->root_box : index_.node_bounds(index_.root())),
        scratch(scratch_ ? *scratch_ : detail::ray_scratch<Node>()), kern(kernels_of<K>()) {
    if (per_node && ray_order)
      throw std::invalid_argument("ray query: per-node radii need order time or sphere_hit");
    if (sibling && sibling->o == o) {
      dist_center = sibling->dist_center;
      tol = sibling->tol;
    } else {
      dist_center = glm::length(o - root_box.center());
      tol = node_test_tolerance(o, root_box, dist_center);  // (distance.hpp: with the coordinates' magnitude)
    }
    pad = radius;
    o_plus = o + (pad + tol);
    o_minus = o - (pad + tol);
    t_lo = q.t_min - tol;
    t_hi = (sphere ? q.t_max + radius : q.t_max) + tol;  // sphere keys satisfy t_p <= key + r
    box_t_lo = t_lo;
    if constexpr (key_floor_known) box_t_lo = std::max(t_lo, key_policy.key.key_min() - tol);
    // The rest of the set-up (prepare) waits for the root test: a ray that the traversal's own
    // root test rejects pays only this much (bench/notes/); on the paths
    // with a root kernel most misses never get here (detail::root_test). A per-node radius sets
    // the root's own pad first, which the root test needs.
    if constexpr (per_node) prepare();
  }
  RayTraversal(const RayTraversal&) = delete;
  RayTraversal& operator=(const RayTraversal&) = delete;

  /// The set-up the traversal needs past the root test: clears the per-thread scratch and computes
  /// the SIMD constants (point filter bounds, float slabs). Idempotent; called by ray_traverse once
  /// the root passed, and for every ray of a packet that passed it, before any of them traverses.
  void prepare() {
    if (prepared) return;
    prepared = true;
    scratch.top = 0;
    scratch.cands.clear();

    // SIMD policies (simd.hpp). Point filter: bounds widened by far more than the difference
    // between the SIMD (possibly fused) and the scalar evaluation of t_p and d^2 (a few ulps of
    // |p - o| and |p - o|^2; |p - o| <= vmax for every point in the root box).
    const double vmax = dist_center + 0.5 * glm::length(root_box.hi - root_box.lo);
    slack_t = 1e-12 * vmax + 1e-300;
    slack_d2 = 1e-12 * vmax * vmax + 1e-300;
    pf = simd::PointFilterD{{o.x, o.y, o.z}, {d.x, d.y, d.z}, 0, 0, 0, nullptr, slack_d2};
    // Child test: float slabs relative to the index's float origin; rays with a direction
    // component whose float reciprocal is not finite keep the scalar node test.
    if constexpr (detail::FloatChildBoxes<I>) {
      if (has_kernel(kern.child_slab)) {
        o_rel = o - index.float_origin();
        const float fx = static_cast<float>(inv_d.x), fy = static_cast<float>(inv_d.y),
                    fz = static_cast<float>(inv_d.z);
        simd_children = std::isfinite(fx) && std::isfinite(fy) && std::isfinite(fz);
        sr.inv_d[0] = fx, sr.inv_d[1] = fy, sr.inv_d[2] = fz;
        sr_box.inv_d[0] = fx, sr_box.inv_d[1] = fy, sr_box.inv_d[2] = fz;
        mag = std::max({std::abs(o_rel.x), std::abs(o_rel.y), std::abs(o_rel.z)}) + index.float_extent();
      }
    }
    // Child entries are raised to t_min (no key lies below it), rounded down once per ray.
    sr.lb_floor = sr_box.lb_floor = round_float_down(q.t_min);
    if constexpr (per_node) set_node_pad(index.root());
    if constexpr (requires { key_policy.key.filter_radii(); }) radii_filter = key_policy.key.filter_radii() != nullptr;
    if constexpr (key_floor_known && requires { key_policy.key.filter_normals(); }) {
      normals_filter = radii_filter && key_policy.key.filter_normals() != nullptr;
      pf.disc_slack = 0x1p-36 * vmax + tol;
    }
    update_simd();
    slab_is_final = !ray_order && !has_planes && (!per_node || per_box_f);
    if constexpr (detail::FloatChildBoxes<I>)  // (pad is the query radius here: per node only with per_box_f)
      child_keys = has_kernel(kern.child_slab_keys) && bounded && slab_is_final && simd_children && (per_box_f || pad < kInf);
  }

  /// Per-node state on entering node n (with per-node radii): the pad and the point filter's
  /// distance bound become n's own; the float child slabs too, unless the children are tested on
  /// their float geometry boxes (per_box_f), whose slabs do not depend on the node.
  /// With per-slot radii in the point filter (radii_filter) and float geometry boxes, nothing: the
  /// pad stays the root's (the filter's distance bound in update_simd, valid for every point; each
  /// point's own radius is below it), and nothing else reads it (test_child leaves it alone).
  __attribute__((always_inline)) void enter_node([[maybe_unused]] Node n) {
    if constexpr (per_node) {
      if constexpr (per_box_f) {
        if (radii_filter) return;
        set_node_pad(n);
        pf.d2_max = pad * pad + slack_d2;
      } else {
        set_node_pad(n);
        update_simd();
      }
    }
  }

  /// Refreshes the per-ray SIMD constants after the pad changed (per-node radii, or the dynamic k
  /// filter of order ray), and at the start.
  void update_simd() {
    pf.d2_max = (ray_order ? std::min(r2, worst * worst * (1.0 + 1e-12)) : per_node ? pad * pad : r2) + slack_d2;
    // A point whose geometry (within radius of it) holds a hit has t_p >= the key floor less the
    // radius (without a floor, box_t_lo = t_lo and this is t_lo); with per-slot radii in the
    // filter, each point's own: t_p >= the floor less its radius.
    pf.t_lo = std::max(t_lo, box_t_lo - radius) - slack_t;
    pf.t_lo_own = box_t_lo - slack_t;
    // Disc hits (filter_normals): t in [key_min, t_max], and a refined key above the k-bound fails.
    pf.disc_t_lo = box_t_lo;
    if constexpr (per_box_f) {
      if (has_kernel(kern.child_slab)) {
        // As below with pad 0, the magnitudes including the geometry's reach past the float
        // cell (at most the query radius).
        const double margin = 0x1p-20 * (mag + radius) + tol;
        for (int a = 0; a < 3; ++a) {
          sr_box.o_plus[a] = static_cast<float>(o_rel[a] + margin);
          sr_box.o_minus[a] = static_cast<float>(o_rel[a] - margin);
        }
        sr_box.t_lo = round_float_down(box_t_lo);
      }
    } else if constexpr (detail::FloatChildBoxes<I>) {
      if (has_kernel(kern.child_slab) && pad < kInf) {
        // Position-space margin: float rounding of the slab origins and of box - origin
        // differences (each <= 2^-24 of the magnitudes involved); 2^-20 of their sum covers both.
        // The margin is 16x the rounding of o_plus / o_minus to float, so plain casts stay
        // outside the grown box; t_lo / t_hi are rounded outwards (round_float_down / round_float_up).
        const double margin = 0x1p-20 * (mag + pad) + tol;
        for (int a = 0; a < 3; ++a) {
          sr.o_plus[a] = static_cast<float>(o_rel[a] + (pad + margin));
          sr.o_minus[a] = static_cast<float>(o_rel[a] - (pad + margin));
        }
        sr.t_lo = round_float_down(t_lo);
      }
    }
    update_t_hi();
  }

  /// The SIMD constants that depend on t_hi and the k-bound alone: all that the dynamic k filter
  /// of orders time and sphere_hit moves (push_candidate), so a new best hit costs only these.
  /// The child test's enter_max is live()'s bound rounded up (order ray bounds a distance: none).
  void update_t_hi() {
    pf.t_hi = t_hi + slack_t;
    pf.disc_t_hi = std::min(q.t_max, worst);
    sr.t_hi = sr_box.t_hi = round_float_up(t_hi);
    if (bounded && !ray_order) sr.enter_max = sr_box.enter_max = round_float_up(worst + tol);
  }

  /// Sets lane i of a packet's point filter constants to this ray's (pf; first_hit_packet's leaf
  /// test over the rays, which needs the plain filter: no per-point radii or normals).
  void set_filter_lane(simd::PointFilterPacketD& f, unsigned i) const {
    for (int a = 0; a < 3; ++a) {
      f.o[a][i] = pf.o[a];
      f.d[a][i] = pf.d[a];
    }
    f.d2_max[i] = pf.d2_max;
    f.t_lo[i] = pf.t_lo;
    f.t_hi[i] = pf.t_hi;
  }

  /// Per-node radius policy: pad becomes the node's own bound (never above the query radius).
  void set_node_pad([[maybe_unused]] Node n) {
    if constexpr (per_node) {
      pad = std::min(radius, static_cast<double>(key_policy.node_radius_of(n)));
      o_plus = o + (pad + tol);
      o_minus = o - (pad + tol);
    }
  }

  /// True when a node with key lower bound lb can still hold a better result (k filter).
  [[nodiscard]] bool live(double lb) const { return !(bounded && lb > worst + tol); }

  /// Whether the ray enters the root, after detail::root_test found `root` (enter or exact): the
  /// node test of the root (lb0 its bound), unless the root kernel's test stands for it (enter,
  /// and none of the conditions it does not test: planes, order ray's distance, a per-node
  /// radius below the query's; lb0 = -inf: no bound).
  [[nodiscard]] bool enters_root(RootTest root, double& lb0) {
    lb0 = -kInf;
    if (root == RootTest::enter && !has_planes && !ray_order && !per_node) return true;
    return test_node(root_box, lb0);
  }

  /// Whether the entry-point search (entry_node, entry_final) applies: a first hit (kBest1) of the
  /// plain keys (OrderKey: a refined key need not be the ray parameter of its hit) ordered along
  /// the ray (orders time and sphere_hit: every key is a ray parameter), without planes, on an
  /// index with an entry grid, unless turned off (set_entry_point_search).
  [[nodiscard]] bool entry_search_applies() const {
    if constexpr (kBest1 && std::is_same_v<KeyPolicy, OrderKey> && EntryGridIndex<I>)
      return !ray_order && !has_planes && entry_point_search_enabled();
    return false;
  }

  /// Entry-point search, first part (after prepare): the node of the deepest entry grid's cell
  /// (EntryGrid) where the ray enters the root's box grown by the radius, when the ray
  /// passes its node test (n and its bound lb); false: none (also where the grid is not for first
  /// hits, EntryGrid::first_hits, unless EntryPointSearch::always), the traversal starts at the root.
  /// The node's subtree is traversed first (traverse_from or steps from begin_at), then
  /// entry_final says whether its first hit is final or where to go on: so most rays skip the
  /// steps from the root down to it and the stack entries of their other children (Havran's
  /// entry-point search; the entry points of Reshetov et al.'s multi-level ray tracing,
  /// SIGGRAPH 2005).
  bool entry_node(Node& n, double& lb) {
    if constexpr (EntryGridIndex<I>) {
      const auto g = index.entry_grid();
      if (g.cells == nullptr || !(g.first_hits || entry_point_search_always())) return false;
      const Interval iv = slab_interval_grown(o_plus, o_minus, inv_d, root_box, t_lo, t_hi);
      if (iv.empty()) return false;
      entry_t0 = std::max(iv.lo, q.t_min);
      const Vec3 p0 = o + d * entry_t0;
      for (unsigned a = 0; a < 3; ++a) entry_ijk[a] = g.coord(p0[a], a);
      const auto cell = g.at(g.depth, entry_ijk[0], entry_ijk[1], entry_ijk[2]);
      if (cell.node == index.root() || !test_node(index.node_bounds(cell.node), lb)) return false;
      entry_depth = cell.depth;
      n = cell.node;
      return true;
    }
    return false;
  }

  /// Entry-point search, second part, once the subtree of entry_node's n has been traversed:
  /// true when `best` is final; false when the traversal must go on from `restart` with bound
  /// `lb` (on entry: the root and its bound, kept when the root it is), skipping n, whose points
  /// were all tested, with the hit found, if any, as its bound.
  /// Why this is exact: a better point comes within the radius of the ray at a parameter in
  /// S = [t0, t1] (t0: the entry into the grown root box, below which no key lies; t1: the hit's
  /// key, above which no key is better), so it lies in the region R = S grown by the radius (and
  /// rounding allowances), clipped to the root's box, which holds every point. The smallest grid
  /// cell holding both R and the entry cell holds every better point, and its node's subtree
  /// every point of that cell (EntryGrid): when that is n's cell or inside it, nothing better
  /// exists; else the traversal from that cell's node (an ancestor of n) finds it.
  bool entry_final(Node n, Node& restart, double& lb) {
    skip = n;
    if (!found) return false;
    if (done) return true;  // any_hit: any hit will do
    if constexpr (EntryGridIndex<I>) {
      const auto g = index.entry_grid();
      const Vec3 p0 = o + d * entry_t0, p1 = o + d * best.key;
      // The radius, the node test's allowance for rounding on the ray (p0, p1, and a point's
      // distance to the ray) and some to spare. A coordinate's grid cell is its Morton cell
      // (EntryGrid), so a point between R's faces on an axis has its cell between theirs.
      const double m = radius + 2.0 * tol + 0x1p-40 * g.side;
      unsigned level = g.depth;  // the deepest level whose cell holds R and the entry cell
      unsigned ijk[3];
      for (unsigned a = 0; a < 3; ++a) {
        const double lo = std::max(std::min(p0[a], p1[a]) - m, root_box.lo[a]);
        const double hi = std::min(std::max(p0[a], p1[a]) + m, root_box.hi[a]);
        const unsigned c0 = g.coord(lo, a), c1 = g.coord(hi, a);
        const unsigned diff = (c0 ^ c1) | (c0 ^ entry_ijk[a]);
        level = std::min(level, g.shared_level(diff));
        ijk[a] = c0;
      }
      if (level >= entry_depth) return true;
      const unsigned sh = g.depth - level;
      const auto cell = g.at(level, ijk[0] >> sh, ijk[1] >> sh, ijk[2] >> sh);
      if (cell.node == index.root()) return false;
      restart = cell.node;
      if (!test_node(index.node_bounds(restart), lb)) lb = -kInf;  // (conservative: it holds the hit)
      return false;
    }
    return true;
  }

  /// The traversal of a first hit from the root (after prepare; the root passed with bound lb0):
  /// through the entry-point search where it applies (entry_node, entry_final), else
  /// traverse_from the root.
  void traverse_first_hit(double lb0) {
    Node n;
    double lb;
    if (entry_search_applies() && entry_node(n, lb)) {
      traverse_from(n, lb);
      Node restart = index.root();
      lb = lb0;
      if (entry_final(n, restart, lb)) return;
      traverse_from(restart, lb);
      return;
    }
    traverse_from(index.root(), lb0);
  }

  /// Node test (section 3.3): false prunes the node; otherwise lb receives a lower bound of the key
  /// of any result inside it.
  __attribute__((always_inline)) bool test_node(const AABB& b, double& lb) {
    Interval iv;
    if (pad < kInf) {
      // Slab test of the box grown by pad: every qualifying point projects inside iv.
      iv = slab_interval_grown(o_plus, o_minus, inv_d, b, t_lo, t_hi);
      if (iv.empty()) return false;
    } else {
      iv = dist_plane_bounds(o, d, b);  // projected time interval, eq. 4 via eq. 2
      iv.lo = std::max(iv.lo, t_lo);
      iv.hi = std::min(iv.hi, t_hi);
      if (iv.empty()) return false;
    }
    if (has_planes)
      for (const Plane& pl : q.planes)
        if (dist_plane_bounds(pl.point, pl.normal, b).lo > tol) return false;
    if (ray_order) {
      // Minimum distance of the box to the ray segment (section 3.3): a cheap separating-axis
      // bound (or eq. 3) first, the exact distance only for boxes large against the bound.
      double dmin = exact ? node_ray_distance_sat(o, d, b) : node_ray_distance_eq3(o, d, b);
      if (dmin > pad + tol) return false;
      if (exact && b.max_extent() > 8.0 * std::min(pad, dmin + 1e-300)) {
        dmin = std::sqrt(segment_box_distance2(o, d, iv.lo, iv.hi, b));
        if (dmin > pad + tol) return false;
      }
      lb = dmin;
    } else {
      // For orders time and sphere_hit the slab of the box grown by r bounds the distance in the
      // L-infinity sense; refining it with the exact distance was measured to prune < 2% more
      // nodes at a 25% higher cost, so it is not done.
      lb = std::max(iv.lo, q.t_min);
    }
    return live(lb);
  }

  /// Node test of child c: test_node of its box (grown by its own radius with per-node radii), or,
  /// with per-node geometry boxes, the slab test of c's box without pad.
  /// With per-node geometry boxes the pad is neither read nor changed (it is the bound of the node
  /// whose points are tested, or the root's: see enter_node).
  __attribute__((always_inline)) bool test_child(Node c, double& lb) {
    if constexpr (per_box) {
      const AABB b = key_policy.node_box_of(c);
      const Interval iv = slab_interval_grown(o + tol, o - tol, inv_d, b, box_t_lo, t_hi);
      if (iv.empty()) return false;
      if (has_planes)
        for (const Plane& pl : q.planes)
          if (dist_plane_bounds(pl.point, pl.normal, b).lo > tol) return false;
      lb = std::max(iv.lo, q.t_min);
      return live(lb);
    } else {
      if constexpr (per_node) set_node_pad(c);
      return test_node(index.node_bounds(c), lb);
    }
  }

  /// Node test of the nc <= 8 children of n at once: bit i of the result is set when child i
  /// passes, and lb[i] then holds its lower bound. SIMD policy on FloatChildBoxes indexes (all
  /// children on their float boxes, or on the key policy's float geometry boxes; the result is
  /// final for orders time / sphere_hit without planes, and with per-node radii only on the
  /// geometry boxes, else it prefilters the exact test), the scalar test otherwise.
  __attribute__((always_inline)) unsigned test_children(Node n, unsigned nc, double* lb) {
    unsigned out = 0;
    if constexpr (detail::FloatChildBoxes<I>) {
      // The float boxes: the policy's geometry boxes with the ray's own slabs (per_box_f), else
      // the index's child boxes with the slabs grown by pad.
      if (simd_children && (per_box_f || pad < kInf)) {
        float entry[8];
        unsigned m;
        if constexpr (per_box_f)
          m = kern.child_slab(key_policy.child_boxes_f_of(n), sr_box, entry);
        else
          m = kern.child_slab(index.child_boxes_f(n), sr, entry);
        while (m) {
          const unsigned i = static_cast<unsigned>(__builtin_ctz(m));
          m &= m - 1;
          if (slab_is_final) {
            lb[i] = entry[i];  // (>= t_min rounded down, and live: the kernel tested enter_max)
          } else if (!test_child(index.child(n, i), lb[i])) {
            continue;
          }
          out |= 1u << i;
        }
        return out;
      }
    }
    for (unsigned i = 0; i < nc; ++i)
      if (test_child(index.child(n, i), lb[i])) out |= 1u << i;
    return out;
  }

  __attribute__((always_inline)) void push_candidate(const detail::Candidate& c) {
    if constexpr (kBest1) {
      if (found && !detail::cand_less(c, best)) return;
      best = c;
      found = true;
      if (q.any_hit) {
        done = true;
        return;
      }
    } else if (q.any_hit) {
      scratch.cands.push_back(c);
      done = true;
      return;
    }
    if constexpr (!kBest1) {
      auto& cands = scratch.cands;
      if (!bounded) {
        cands.push_back(c);
        return;
      }
      if (cands.size() < q.k) {
        cands.push_back(c);
        std::push_heap(cands.begin(), cands.end(), detail::cand_less);
      } else if (detail::cand_less(c, cands.front())) {
        std::pop_heap(cands.begin(), cands.end(), detail::cand_less);
        cands.back() = c;
        std::push_heap(cands.begin(), cands.end(), detail::cand_less);
      } else {
        return;
      }
      if (cands.size() != q.k) return;
    }
    {  // dynamic k filter: tighten r (order ray) or t_max
      worst = kBest1 ? best.key : scratch.cands.front().key;
      if (ray_order) {
        pad = std::min(radius, worst);
        o_plus = o + (pad + tol);
        o_minus = o - (pad + tol);
        update_simd();
      } else {
        t_hi = (sphere ? std::min(q.t_max, worst) + radius : std::min(q.t_max, worst)) + tol;
        update_t_hi();
      }
    }
  }

  /// The exact test of the point in slot s and its push (push_candidate) when it qualifies.
  /// p: the position of slot s (pos[s], bit for bit: from the SIMD filter's decoded block, so a
  /// compact encoding is decoded once per leaf, not again per survivor).
  /// radius_filtered: the point passed the SIMD filter with the policy's per-slot radii, which
  /// already made reject()'s test (up to the filter's slack; the key functor decides exactly).
  __attribute__((always_inline)) void eval_slot(std::uint32_t s, const Vec3& p, bool radius_filtered) {
    if constexpr (KeyPolicy::refines && requires { key_policy.key.exact_key(s, PointIndex{}, p); }) {
      // A key that decides alone (RefinedKey, exact_key): no projection terms, sphere key or
      // base-key tests before it; the terms only for a point it keeps (RayHit::t, distance).
      if (!has_planes && sphere) {
        const PointIndex id = ids[s];
        const double key = key_policy.key.exact_key(s, id, p);
        if (!(key <= worst) || !(key < kInf)) return;
        const RayPointTerms pt = ray_point_terms(o, d, p);
        push_candidate({key, id, s, sphere ? sphere_entry(pt.t, pt.d2, radius) : pt.t, pt.d2});
        return;
      }
    }
    const RayPointTerms pt = ray_point_terms(o, d, p);
    if (pt.d2 > r2) return;
    if constexpr (KeyPolicy::refines) {
      // The policy's early rejection by storage slot (RefinedKey), before any per-point work.
      if constexpr (requires { key_policy.key.reject(s, pt.d2); })
        if (!radius_filtered && key_policy.key.reject(s, pt.d2)) return;
    }
    const double t = sphere ? sphere_entry(pt.t, pt.d2, radius) : pt.t;
    if (t < q.t_min || t > q.t_max) return;
    if (has_planes) {
      bool inside = true;
      for (const Plane& pl : q.planes)
        if (dist_plane(pl.point, pl.normal, p) > 0.0) { inside = false; break; }
      if (!inside) return;
    }
    double key = ray_order ? std::sqrt(pt.d2) : t;
    if (key > worst) return;
    if constexpr (KeyPolicy::refines) {
      key = key_policy.key(ids[s], pt.t, pt.d2, key);
      if (!(key <= worst) || !(key < kInf)) return;
    }
    push_candidate({key, ids[s], s, t, pt.d2});
  }

  /// Leaf work: the points stored at node n (every node of a layered octree holds some).
  __attribute__((always_inline)) void eval_points(Node n) {
    const SlotRange range = index.node_points(n);
    if (stats) {
      ++stats->nodes_visited;
      stats->points_tested += range.size();
    }
    if (has_kernel(kern.point_filter) && range.size() >= 4) {
      // SIMD filter, then the exact test on the survivors only (in slot order, as below).
      auto& sel = scratch.sel;
      if (sel.size() < range.size()) sel.resize(range.size());
      const double* xyz = position_block(pos, range.begin, range.size(), scratch.block);
      // The policy's per-slot radii (RefinedKey): its early rejection inside the SIMD filter.
      if constexpr (requires { key_policy.key.filter_radii(); })
        if (radii_filter) pf.radii = key_policy.key.filter_radii() + range.begin;
      if constexpr (requires { key_policy.key.filter_normals(); })
        if (normals_filter) pf.normals = key_policy.key.filter_normals() + 3 * std::size_t{range.begin};
      const unsigned m = kern.point_filter(xyz, range.size(), pf, sel.data());
      for (unsigned j = 0; j < m; ++j) {
        const double* p = xyz + 3 * std::size_t{sel[j]};
        eval_slot(range.begin + sel[j], Vec3(p[0], p[1], p[2]), radii_filter);
        if (done) return;
      }
      return;
    }
    for (std::uint32_t s = range.begin; s < range.end; ++s) {
      eval_slot(s, pos[s], false);
      if (done) return;
    }
  }

  /// The depth-first loop over the subtree of `start` (which passed the node test with bound lb0,
  /// or, for the root, enters_root with lb0 = -inf).
  /// With k set: the children of each node pushed far-to-near (so the nearest is expanded first
  /// and the k filter tightens early), skipping any popped node whose lower bound exceeds the
  /// current k-bound; the nearest child is expanded right away instead of being pushed and popped
  /// (the store and reload of its entry and its live() branch sat on the loop's critical path:
  /// first hits 5-10% faster, bench/notes/). Without k: plain
  /// depth-first. Uses the per-thread node stack above its current top, and leaves it as it found
  /// it.
  ///
  /// The child step, when the children's SIMD slab result is final and k is set (child_keys): the
  /// kernel writes each passing child's entry as a child order key (simd.hpp, child_key) and
  /// reduces the least in registers. The next node comes straight from the mask (one child) or
  /// from that key (more), never through a store and reload (the loop is latency-bound: the chain
  /// from one node to the next is its time); the farther of two children is pushed after one
  /// compare (one or two children: 63% of the octree's nodes on the camera rays of bench_rays),
  /// three or more are sorted by a network on the 8 keys and, on indexes with ContiguousChildren32,
  /// written to the stack by the same kernel (sort_push_keys8: no reload of each sorted key and no
  /// loop whose trip count mispredicts; camera hits ~3% faster; else sort_keys8 and a loop).
  /// Otherwise the children are tested by test_children and sorted by insertion. (bench/notes/:
  /// -17% instructions per camera hit; a network for two children as well was slower.)
  ///
  /// The loop is written as steps of one node over a Cursor (begin_at, step, end), so that
  /// first_hit_pair can interleave two rays' traversals node by node; traverse_from runs one.
  void traverse_from(Node start, double lb0) {
    Cursor c = begin_at(start, lb0);
    while (step(c)) {
    }
    end(c);
  }

  /// One ray's place in the loop between two nodes: `e` is the next node when `next`, else the
  /// stack entries [base, top) hold what is left (the per-thread stack of this traversal's
  /// scratch, its storage and size held here rather than reloaded from the vector: the pushes'
  /// stores could not then make the compiler reload the vector's pointers; refreshed where it grows).
  struct Cursor {
    detail::NodeEntry<Node> e;
    bool next;
    std::size_t base, top, cap;
    detail::NodeEntry<Node>* stack;
  };

  /// The cursor at the subtree of `start` (which passed the node test with bound lb0, or
  /// enters_root), over the stack above its current top.
  [[nodiscard]] Cursor begin_at(Node start, double lb0) {
    const std::size_t base = scratch.top;
    return {{lb0, start}, live(lb0), base, base, scratch.nodes.size(), scratch.nodes.data()};
  }

  /// Leaves the stack as begin_at found it (after the last step).
  void end(const Cursor& c) { scratch.top = c.base; }

  /// One node of the loop (traverse_from): pops the next live node unless c holds one, evaluates
  /// its points and steps to its children. Returns false once the ray is done (nothing left, or an
  /// any_hit query found its hit); then call end(c).
  __attribute__((always_inline)) bool step(Cursor& c) {
    auto& nodes = scratch.nodes;
    auto& e = c.e;
    auto& next = c.next;
    auto& top = c.top;
    auto& cap = c.cap;
    auto& stack = c.stack;
    const std::size_t base = c.base;
    detail::NodeEntry<Node> kids[8];
    if (!next) {
      if (top == base) return false;
      e = stack[--top];
      if (!live(e.lb)) return true;
    }
    next = false;
    if constexpr (EntryGridIndex<I>)
      if (e.node == skip) return true;
    // Per-node radii: the node's subtree bound for its own points' SIMD filter and (without
    // float geometry boxes) its children's SIMD slab prefilter (test_children); with per-slot
    // radii in the filter and float geometry boxes, nothing (see enter_node).
    enter_node(e.node);
    eval_points(e.node);
    if (done) return false;
    const unsigned nc = index.child_count(e.node);
    if (nc == 0) return true;  // a leaf: no child test (nor an indirect SIMD call)
    // Room for every child (the one capacity test of the node's pushes).
    if (const std::size_t room = nc > 8 ? nc : 8; top + room > cap) [[unlikely]] {
      nodes.resize(cap + room + 64);
      stack = nodes.data();
      cap = nodes.size();
    }
    if (nc > 8) {  // (no index here has more than 8 children; kept general)
      for (unsigned i = 0; i < nc; ++i) {
        const Node ch = index.child(e.node, i);
        double lb;
        if (test_child(ch, lb)) stack[top++] = {lb, ch};
      }
      return true;
    }
    if constexpr (detail::FloatChildBoxes<I>) {
      if (child_keys) {
        alignas(32) std::uint32_t keys[8];
        std::uint32_t near;  // the least key: the next node (its bound is not needed)
        unsigned m;
        if constexpr (per_box_f)
          m = kern.child_slab_keys(key_policy.child_boxes_f_of(e.node), sr_box, keys, near);
        else
          m = kern.child_slab_keys(index.child_boxes_f(e.node), sr, keys, near);
        if (m == 0) return true;
        if ((m & (m - 1)) == 0) {  // one: straight from the mask
          e.node = index.child(e.node, static_cast<unsigned>(__builtin_ctz(m)));
          next = true;
          return true;
        }
        top = detail::push_farther_children(index, kern, e.node, m, keys, stack, top);
        e.node = index.child(e.node, simd::child_key_index(near));
        next = true;
        return true;
      }
    }
    double lb[8];
    unsigned m = test_children(e.node, nc, lb);
    if (!bounded) {
      for (; m; m &= m - 1) {
        const unsigned i = static_cast<unsigned>(__builtin_ctz(m));
        stack[top++] = {lb[i], index.child(e.node, i)};
      }
      return true;
    }
    unsigned nk = 0;
    for (; m; m &= m - 1) {
      // Insertion sort into kids[] by descending lb (at most 8 children).
      const unsigned i = static_cast<unsigned>(__builtin_ctz(m));
      unsigned j = nk++;
      while (j > 0 && kids[j - 1].lb < lb[i]) {
        kids[j] = kids[j - 1];
        --j;
      }
      kids[j] = {lb[i], index.child(e.node, i)};
    }
    if (nk == 0) return true;
    // The nearest child next, without a trip through the stack (it passed live() just now).
    for (unsigned j = 0; j + 1 < nk; ++j) stack[top++] = kids[j];
    e = kids[nk - 1];
    next = true;
    return true;
  }
};
}  // namespace rayscan::detail
