// Per-point albedo of the Lambertian material (Ray Tracing in One Weekend, section 10.3), from
// the point's colour or a scalar attribute through a colour ramp.
#pragma once

#include "rayscan/point_cloud.hpp"
#include "rayscan/render/color.hpp"
#include "rayscan/render/scene.hpp"

#include <vector>

namespace rayscan::render {

/// Albedo of every point (linear RGB in [0,1], indexed like cloud.positions).
///  - rgb: the point's 16-bit colour, sRGB-decoded. 8-bit data stored in 16-bit fields (max <= 255,
///    as in many LAS files) is detected and scaled by 1/255 instead of 1/65535.
///  - intensity / elevation (coordinate along `up`): mapped through material.ramp, from
///    material.range or else the 2nd..98th percentile of the values.
///  - classification: classification_color().
///  - constant: material.constant.
/// Every albedo is multiplied by material.albedo_scale and clamped to [0,1].
/// Throws std::invalid_argument when the mode needs an attribute the cloud lacks (naming it).
std::vector<Color> compute_albedo(const PointCloud& cloud, const MaterialDesc& material, const Vec3& up);

}  // namespace rayscan::render
