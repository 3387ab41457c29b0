#include "rayscan/analysis/solar_irradiation.hpp"

#include "rayscan/analysis/site_location.hpp"

#include <cmath>
#include <map>
#include <numbers>
#include <stdexcept>
#include <utility>

namespace rayscan::analysis {

namespace {


bool open_bit(std::span<const std::uint64_t> mask, std::size_t k) { return (mask[k / 64] >> (k % 64)) & 1u; }

}  // namespace

SunMap build_sun_map(std::vector<SolarStep> steps, double sector_deg) {
  if (!(sector_deg >= 0.0) || !std::isfinite(sector_deg))
    throw std::invalid_argument("sun map: the sector size must be a finite number of degrees >= 0");
  SunMap map;
  std::map<std::pair<long, long>, std::uint32_t> cells;  // (azimuth cell, elevation cell) -> sector
  std::vector<Vec3> sums;
  std::vector<std::uint32_t> count;
  for (SolarStep& s : steps) {
    s.sector = 0;
    if (!(s.beam_normal > 0.0) || !(s.ray_direction.z > 0.0)) continue;
    const double len = glm::length(s.ray_direction);
    if (!(std::abs(len - 1.0) < 1e-9)) throw std::invalid_argument("sun map: a step's direction is not unit length");
    if (sector_deg == 0.0) {
      s.sector = static_cast<std::uint32_t>(sums.size());
      sums.push_back(s.ray_direction);
      count.push_back(1);
      continue;
    }
    // Cells in the cloud's own frame: grid bearing and elevation of the direction.
    double az = std::atan2(s.ray_direction.x, s.ray_direction.y) / kDegree;
    if (az < 0.0) az += 360.0;
    const double el = std::asin(std::min(1.0, s.ray_direction.z)) / kDegree;
    const std::pair<long, long> key{long(std::floor(az / sector_deg)), long(std::floor(el / sector_deg))};
    auto [it, added] = cells.try_emplace(key, static_cast<std::uint32_t>(sums.size()));
    if (added) {
      sums.emplace_back(0.0);
      count.push_back(0);
    }
    sums[it->second] += s.ray_direction;
    ++count[it->second];
    s.sector = it->second;
  }
  map.directions.reserve(sums.size());
  for (std::size_t k = 0; k < sums.size(); ++k)  // a lone step keeps its exact direction
    map.directions.push_back(count[k] == 1 ? sums[k] : glm::normalize(sums[k]));
  map.steps = std::move(steps);
  return map;
}

PointIrradiation accumulate_irradiation(const SunMap& map, std::span<const Vec3> sky, const Vec3& normal,
                                        double convergence_deg, double albedo,
                                        std::span<const std::uint64_t> open) {
  PointIrradiation out;
  const std::size_t nsec = map.directions.size();
  if (open.size() < (nsec + sky.size() + 63) / 64)
    throw std::invalid_argument("irradiation: the open-direction mask is too short");
  // Sky view of the tilted surface: the open share of the sky it faces, cosine-weighted.
  if (sky.empty()) {
    out.sky_view = 1.0;
  } else {
    double seen = 0.0, all = 0.0;
    for (std::size_t k = 0; k < sky.size(); ++k) {
      const double w = std::max(0.0, glm::dot(normal, sky[k]));
      all += w;
      if (open_bit(open, nsec + k)) seen += w;
    }
    out.sky_view = all > 0.0 ? seen / all : 0.0;
  }
  SurfaceOrientation surface = orientation_from_normal(normal.x, normal.y, normal.z);
  surface.aspect -= convergence_deg * kDegree;  // grid bearing -> compass azimuth
  const double rr = (1.0 - std::cos(surface.slope)) / 2.0;  // ground view of the tilted plane
  for (const SolarStep& s : map.steps) {
    if (!(s.diffuse_horizontal > 0.0) && !(s.beam_normal > 0.0) && !(s.global_horizontal > 0.0)) continue;
    const double c = std::clamp(glm::dot(normal, s.direction), -1.0, 1.0);
    const bool up = s.beam_normal > 0.0 && s.ray_direction.z > 0.0;
    const bool lit = up && c > 0.0 && open_bit(open, s.sector);
    if (lit) {
      out.beam += s.beam_normal * c * s.hours;
      out.sun_hours += s.hours;
    }
    if (s.diffuse_horizontal > 0.0) {
      const double ratio = s.sun.elevation > 0.0 ? muneer_diffuse_ratio(s.sun, surface, c, !lit, s.kb)
                                                 : muneer_diffuse_ratio(s.sun, surface, -1.0, true, 0.0);
      out.diffuse += s.diffuse_horizontal * ratio * out.sky_view * s.hours;
    }
    const double ground = (lit || s.reflected_from_global) ? s.global_horizontal : s.diffuse_horizontal;
    out.reflected += albedo * ground * rr * s.hours;
  }
  return out;
}

}  // namespace rayscan::analysis
