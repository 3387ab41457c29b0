#include "rayscan/image/color_ramp.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <span>
#include <stdexcept>

namespace rayscan {

float linear_to_srgb(float v) {
  v = std::clamp(v, 0.0f, 1.0f);
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

float srgb_to_linear(float v) {
  v = std::clamp(v, 0.0f, 1.0f);
  return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

namespace {

// Stops are sRGB-encoded 8-bit values (as published).
struct Stop {
  unsigned char r, g, b;
};
constexpr Stop kViridis[] = {{68, 1, 84},    {72, 40, 120},  {62, 74, 137},  {49, 104, 142}, {38, 130, 142},
                             {31, 158, 137}, {53, 183, 121}, {109, 205, 89}, {180, 222, 44}, {253, 231, 37}};
constexpr Stop kTerrain[] = {{38, 115, 60}, {120, 170, 90}, {210, 200, 140}, {150, 110, 70}, {245, 245, 245}};
constexpr Stop kGrey[] = {{0, 0, 0}, {255, 255, 255}};
constexpr Stop kHeat[] = {{0, 0, 0}, {255, 0, 0}, {255, 255, 0}, {255, 255, 255}};

std::span<const Stop> stops(Ramp r) {
  switch (r) {
    case Ramp::viridis: return kViridis;
    case Ramp::terrain: return kTerrain;
    case Ramp::grey: return kGrey;
    case Ramp::heat: return kHeat;
  }
  return kGrey;
}

glm::vec3 encoded(const Stop& s) { return {s.r / 255.0f, s.g / 255.0f, s.b / 255.0f}; }

glm::vec3 linear(const Stop& s) {
  return {srgb_to_linear(s.r / 255.0f), srgb_to_linear(s.g / 255.0f), srgb_to_linear(s.b / 255.0f)};
}

// Position u in [0, 1] on an N-stop table: segment i and fraction f.
template <class F>
glm::vec3 interpolate(std::span<const Stop> st, double u, F convert) {
  const std::size_t n = st.size();
  u = std::clamp(std::isnan(u) ? 0.0 : u, 0.0, 1.0) * double(n - 1);
  const std::size_t i = std::min<std::size_t>(static_cast<std::size_t>(u), n - 2);
  const float f = static_cast<float>(u - double(i));
  return convert(st[i]) * (1.0f - f) + convert(st[i + 1]) * f;
}

}  // namespace

const std::vector<std::string>& ramp_names() {
  static const std::vector<std::string> v{"viridis", "terrain", "grey", "heat"};
  return v;
}

Ramp parse_ramp(const std::string& s) {
  const auto& n = ramp_names();
  for (std::size_t i = 0; i < n.size(); ++i)
    if (s == n[i]) return static_cast<Ramp>(i);
  throw std::invalid_argument("expected \"viridis\", \"terrain\", \"grey\" or \"heat\", got \"" + s + "\"");
}

glm::vec3 ramp_linear(Ramp ramp, float u) { return interpolate(stops(ramp), u, linear); }

glm::vec3 ramp_display(Ramp ramp, double t) { return interpolate(stops(ramp), t, encoded); }

std::string heat_ramp_legend(double lo, double hi) {
  char buf[256];
  const double d = hi - lo;
  std::snprintf(buf, sizeof buf, "black %.6g -> red %.6g -> yellow %.6g -> white %.6g", lo, lo + d / 3.0,
                lo + 2.0 * d / 3.0, hi);
  return buf;
}

}  // namespace rayscan
