// scan_point_cloud(): one streaming pass over a PointReader.
#include "rayscan/io/cloud_stats.hpp"

#include <algorithm>
#include <array>

namespace rayscan::io {

namespace {

/// Running min/max per named attribute, in the order attributes are first seen.
struct Ranges {
  std::vector<AttributeRange> r;
  std::size_t k = 0;  // next slot for this chunk
  void begin_chunk() { k = 0; }
  template <class V, class F>
  void add(const char* name, const V& v, F get) {
    add(std::string(name), v, get);
  }
  template <class V, class F>
  void add(const std::string& name, const V& v, F get) {
    if (v.empty()) return;
    double lo = static_cast<double>(get(v[0])), hi = lo;
    for (const auto& e : v) {
      const double x = static_cast<double>(get(e));
      lo = std::min(lo, x);
      hi = std::max(hi, x);
    }
    auto it = std::find_if(r.begin(), r.end(), [&](const AttributeRange& a) { return a.name == name; });
    if (it == r.end()) {
      r.push_back({name, lo, hi});
    } else {
      it->lo = std::min(it->lo, lo);
      it->hi = std::max(it->hi, hi);
    }
  }
};

}  // namespace

CloudStats scan_point_cloud(PointReader& reader, std::size_t chunk_points) {
  CloudStats st;
  Ranges rg;
  PointCloud c;
  std::array<std::uint64_t, 256> cls{};
  while (reader.read(c, std::max<std::size_t>(chunk_points, 1)) > 0) {
    st.count += c.size();
    for (const Vec3& p : c.positions) st.bounds.expand(p);
    rg.add("X", c.positions, [](const Vec3& p) { return p.x; });
    rg.add("Y", c.positions, [](const Vec3& p) { return p.y; });
    rg.add("Z", c.positions, [](const Vec3& p) { return p.z; });
    rg.add("intensity", c.intensity, [](auto v) { return v; });
    rg.add("classification", c.classification, [](auto v) { return v; });
    rg.add("gps_time", c.gps_time, [](auto v) { return v; });
    rg.add("red", c.rgb, [](const Rgb16& x) { return x.r; });
    rg.add("green", c.rgb, [](const Rgb16& x) { return x.g; });
    rg.add("blue", c.rgb, [](const Rgb16& x) { return x.b; });
    rg.add("normal_x", c.normals, [](const glm::vec3& n) { return n.x; });
    rg.add("normal_y", c.normals, [](const glm::vec3& n) { return n.y; });
    rg.add("normal_z", c.normals, [](const glm::vec3& n) { return n.z; });
    for (const ScalarField& f : c.scalars) rg.add(f.name, f.values, [](double v) { return v; });
    for (std::uint8_t k : c.classification) ++cls[k];
  }
  st.ranges = std::move(rg.r);
  for (int k = 0; k < 256; ++k)
    if (cls[k] != 0) st.classification_counts[k] = cls[k];
  return st;
}

}  // namespace rayscan::io
