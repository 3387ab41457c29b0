#include "rayscan/render/color.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <stdexcept>

namespace rayscan::render {

namespace {
// sRGB-encoded 8-bit stops (as published), converted to linear light on use.
struct Stop { unsigned char r, g, b; };
Color stop_linear(const Stop& s) {
  return {srgb_to_linear(s.r / 255.0f), srgb_to_linear(s.g / 255.0f), srgb_to_linear(s.b / 255.0f)};
}
}  // namespace

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
