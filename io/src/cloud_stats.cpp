// scan_point_cloud(): one streaming pass over a PointReader.
#include "rayscan/io/cloud_stats.hpp"

#include "rayscan/octree/position_view.hpp"

#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace rayscan::io {

namespace {

/// Minimum and maximum of get(e) over a non-empty v (std::min / std::max from the first element:
/// a NaN first element gives NaN, later NaNs are skipped), and the mean and sum of squared
/// deviations (two passes over the chunk, which is in memory).
template <class V, class F>
AttributeRange range_of(std::string name, const V& v, F get) {
  double lo = static_cast<double>(get(v[0])), hi = lo, sum = 0.0;
  for (const auto& e : v) {
    const double x = static_cast<double>(get(e));
    lo = std::min(lo, x);
    hi = std::max(hi, x);
    sum += x;
  }
  const double mean = sum / double(v.size());
  double m2 = 0.0;
  for (const auto& e : v) {
    const double d = static_cast<double>(get(e)) - mean;
    m2 += d * d;
  }
  return {std::move(name), lo, hi, v.size(), mean, m2};
}

/// Merges the statistics of b into a (Chan, Golub and LeVeque 1979, the pairwise update of the
/// mean and the sum of squared deviations).
void merge(AttributeRange& a, const AttributeRange& b) {
  a.lo = std::min(a.lo, b.lo);
  a.hi = std::max(a.hi, b.hi);
  const double n = double(a.count + b.count);
  const double delta = b.mean - a.mean;
  a.m2 += b.m2 + delta * delta * double(a.count) * double(b.count) / n;
  a.mean += delta * double(b.count) / n;
  a.count += b.count;
}

}  // namespace

CloudStats scan_point_cloud(PointReader& reader, std::size_t chunk_points) {
  CloudStats st;
  std::vector<AttributeRange> all;  // in the order attributes are first seen
  PointCloud c;
  std::array<std::uint64_t, 256> cls{};
  while (reader.read(c, std::max<std::size_t>(chunk_points, 1)) > 0) {
    st.count += c.size();
    // One job per attribute of the chunk (each a pass over one array), run in parallel: the
    // summary pass is most of `rayscan info`'s time, and the reader decodes in parallel already.
    std::vector<std::function<AttributeRange()>> jobs;
    auto add = [&](std::string name, const auto& v, auto get) {
      if (!v.empty()) jobs.emplace_back([name = std::move(name), &v, get] { return range_of(name, v, get); });
    };
    add("X", c.positions, [](const Vec3& p) { return p.x; });
    add("Y", c.positions, [](const Vec3& p) { return p.y; });
    add("Z", c.positions, [](const Vec3& p) { return p.z; });
    add("intensity", c.intensity, [](auto v) { return v; });
    add("classification", c.classification, [](auto v) { return v; });
    add("gps_time", c.gps_time, [](auto v) { return v; });
    add("red", c.rgb, [](const Rgb16& x) { return x.r; });
    add("green", c.rgb, [](const Rgb16& x) { return x.g; });
    add("blue", c.rgb, [](const Rgb16& x) { return x.b; });
    add("normal_x", c.normals, [](const glm::vec3& n) { return n.x; });
    add("normal_y", c.normals, [](const glm::vec3& n) { return n.y; });
    add("normal_z", c.normals, [](const glm::vec3& n) { return n.z; });
    for (const ScalarField& f : c.scalars) add(f.name, f.values, [](double v) { return v; });
    std::vector<AttributeRange> chunk(jobs.size());
    tbb::parallel_invoke(
        [&] {
          tbb::parallel_for(std::size_t{0}, jobs.size(), [&](std::size_t j) { chunk[j] = jobs[j](); });
        },
        [&] {
          for (std::uint8_t k : c.classification) ++cls[k];
        });
    for (AttributeRange& r : chunk) {
      auto it = std::find_if(all.begin(), all.end(), [&](const AttributeRange& a) { return a.name == r.name; });
      if (it == all.end()) {
        all.push_back(std::move(r));
      } else {
        merge(*it, r);
      }
    }
  }
  // The bounds are the X, Y, Z ranges (the same per-axis min/max over the same positions).
  if (st.count > 0 && all.size() >= 3 && all[0].name == "X")
    st.bounds = AABB{Vec3(all[0].lo, all[1].lo, all[2].lo), Vec3(all[0].hi, all[1].hi, all[2].hi)};
  st.ranges = std::move(all);
  for (int k = 0; k < 256; ++k)
    if (cls[k] != 0) st.classification_counts[k] = cls[k];
  return st;
}

AABB header_box_on_grid(const AABB& header, const Vec3& scale, const Vec3& offset) {
  auto snap = [](double v, double scale, double offset) {
    const double q = std::nearbyint((v - offset) / scale);
    if (!(std::abs(q) <= 2147483647.0)) return v;  // (NaN too)
    return las_coordinate(static_cast<std::int32_t>(q), scale, offset);
  };
  AABB b = header;
  for (int k = 0; k < 3; ++k) {
    b.lo[k] = snap(header.lo[k], scale[k], offset[k]);
    b.hi[k] = snap(header.hi[k], scale[k], offset[k]);
  }
  return b;
}

bool header_bounds_differ(const FileInfo& info, const AABB& points) {
  if (!info.header_bounds || points.empty()) return false;
  const AABB h = info.scale && info.offset ? header_box_on_grid(*info.header_bounds, *info.scale, *info.offset)
                                           : *info.header_bounds;
  return h.lo != points.lo || h.hi != points.hi;
}

}  // namespace rayscan::io
