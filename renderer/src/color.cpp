#include "rayscan/render/color.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <stdexcept>

namespace rayscan::render {

float linear_to_srgb(float v) {
  v = std::clamp(v, 0.0f, 1.0f);
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

float srgb_to_linear(float v) {
  v = std::clamp(v, 0.0f, 1.0f);
  return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

Ramp parse_ramp(const std::string& s) {
  if (s == "viridis") return Ramp::viridis;
  if (s == "terrain") return Ramp::terrain;
  if (s == "grey") return Ramp::grey;
  throw std::invalid_argument("expected \"viridis\", \"terrain\" or \"grey\", got \"" + s + "\"");
}

namespace {
// Stops are sRGB-encoded 8-bit values (as published), converted to linear light on use.
struct Stop { unsigned char r, g, b; };
constexpr Stop kViridis[] = {{68, 1, 84},    {72, 40, 120},  {62, 74, 137},
                             {49, 104, 142}, {38, 130, 142}, {31, 158, 137},
                             {53, 183, 121}, {109, 205, 89}, {180, 222, 44}, {253, 231, 37}};
constexpr Stop kTerrain[] = {{38, 115, 60}, {120, 170, 90}, {210, 200, 140}, {150, 110, 70},
                             {245, 245, 245}};
constexpr Stop kGrey[] = {{0, 0, 0}, {255, 255, 255}};

Color stop_linear(const Stop& s) {
  return {srgb_to_linear(s.r / 255.0f), srgb_to_linear(s.g / 255.0f), srgb_to_linear(s.b / 255.0f)};
}

template <std::size_t N>
Color lerp_stops(const Stop (&stops)[N], float u) {
  u = std::clamp(std::isnan(u) ? 0.0f : u, 0.0f, 1.0f) * float(N - 1);
  const std::size_t i = std::min<std::size_t>(static_cast<std::size_t>(u), N - 2);
  const float f = u - float(i);
  return stop_linear(stops[i]) * (1.0f - f) + stop_linear(stops[i + 1]) * f;
}
}  // namespace

Color eval_ramp(Ramp ramp, float u) {
  switch (ramp) {
    case Ramp::viridis: return lerp_stops(kViridis, u);
    case Ramp::terrain: return lerp_stops(kTerrain, u);
    case Ramp::grey: return lerp_stops(kGrey, u);
  }
  return Color(0.5f);
}

Color classification_color(std::uint8_t code) {
  Stop s{128, 128, 128};
  switch (code) {
    case 1: s = {170, 170, 170}; break;  // unclassified
    case 2: s = {166, 124, 82}; break;   // ground
    case 3: s = {180, 215, 120}; break;  // low vegetation
    case 4: s = {90, 170, 70}; break;    // medium vegetation
    case 5: s = {30, 110, 40}; break;    // high vegetation
    case 6: s = {200, 70, 60}; break;    // building
    case 7: s = {255, 0, 255}; break;    // low point (noise)
    case 9: s = {60, 110, 200}; break;   // water
    case 10: s = {110, 90, 80}; break;   // rail
    case 11: s = {70, 70, 70}; break;    // road surface
    case 17: s = {230, 200, 60}; break;  // bridge deck
    default: break;
  }
  return stop_linear(s);
}

}  // namespace rayscan::render
