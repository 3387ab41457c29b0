#include "rayscan/analysis/solar_irradiation.hpp"

#include "rayscan/analysis/site_location.hpp"
#include "rayscan/base/number_text.hpp"

#include <cmath>
#include <map>
#include <tuple>
#include <numbers>
#include <stdexcept>
#include <utility>

namespace rayscan::analysis {

namespace {


bool open_bit(std::span<const std::uint64_t> mask, std::size_t k) { return (mask[k / 64] >> (k % 64)) & 1u; }

}  // namespace

std::string sunshine_criterion() { return "DNI >= " + shortest_text(kSunshineThreshold) + " W/m2"; }

SunMap build_sun_map(std::vector<SolarStep> steps, double sector_deg) {
  if (!(sector_deg >= 0.0) || !std::isfinite(sector_deg))
    throw std::invalid_argument("sun map: the sector size must be a finite number of degrees >= 0");
  SunMap map;
  std::map<std::tuple<long, long, std::uint32_t>, std::uint32_t> cells;  // (azimuth, elevation, group) -> sector
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
    const std::tuple<long, long, std::uint32_t> key{long(std::floor(az / sector_deg)), long(std::floor(el / sector_deg)),
                                                   s.group};
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
  // The sums per sector (and of the steps without beam).
  map.sums.resize(map.directions.size());
  std::uint32_t groups = 1;
  for (const SolarStep& s : map.steps) groups = std::max(groups, s.group + 1);
  map.no_beam.resize(groups);
  for (std::uint32_t k = 0; k < groups; ++k) map.no_beam[k].group = k;
  for (std::uint32_t t = 0; t < map.steps.size(); ++t) {
    const SolarStep& s = map.steps[t];
    const bool beam = s.beam_normal > 0.0 && s.ray_direction.z > 0.0;
    SectorSums& g = beam ? map.sums[s.sector] : map.no_beam[s.group];
    g.group = s.group;
    const double h = s.hours, dh = s.diffuse_horizontal * h;
    g.steps.push_back(t);
    g.hours += h;
    if (s.beam_normal >= kSunshineThreshold) g.sunshine_hours += h;
    g.diffuse += dh;
    g.reflect_lit += s.global_horizontal * h;
    g.reflect_shadow += (s.reflected_from_global ? s.global_horizontal : s.diffuse_horizontal) * h;
    if (!beam) continue;
    g.beam += s.beam_normal * h * s.direction;
    g.axis += s.direction;
    g.sunlit_a += dh * (1.0 - s.kb);
    g.sunlit_b += dh * muneer_n(s.kb) * (1.0 - s.kb);
    if (s.sun.elevation >= kLowSunElevation) {
      g.sunlit_c += dh * s.kb / std::sin(s.sun.elevation) * s.direction;
    } else {
      const double w = dh * s.kb / (0.1 - 0.008 * s.sun.elevation);
      g.low_cos += w * std::cos(s.sun.azimuth);
      g.low_sin += w * std::sin(s.sun.azimuth);
    }
  }
  for (SectorSums& g : map.sums) {
    g.axis = glm::normalize(g.axis);
    double min_cos = 1.0;
    for (std::uint32_t t : g.steps) min_cos = std::min(min_cos, glm::dot(g.axis, map.steps[t].direction));
    // Rounded up a little: the test n . axis > sin_spread must never take a straddling sector whole.
    g.sin_spread = min_cos <= 0.0 ? 2.0 : std::sqrt(std::max(0.0, 1.0 - min_cos * min_cos)) + 1e-12;
  }
  return map;
}

PointIrradiation accumulate_irradiation(const SunMap& map, std::span<const Vec3> sky, const Vec3& normal,
                                        double convergence_deg, double albedo,
                                        std::span<const std::uint64_t> open, std::span<double> global_by_group) {
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
  const MuneerSurfaceTerms m = muneer_surface_terms(surface);
  const double shadow_ratio = m.flat ? 1.0 : m.r_sky + kMuneerShadowN * m.fg;
  double diffuse = 0.0, ground = 0.0;  // diffuse before the sky view; the ground-reflected source
  // The ground view: the share of the surface's cosine-weighted hemisphere that is not open sky.
  // The sky part of a tilted plane's hemisphere is (1 + cos slope) / 2 and the traced sky view is
  // the open fraction of it, so an open plane keeps r.sun's ground view (1 - cos slope) / 2
  // (drad()), and a wall, a tree or a street canyon that hides the sky reflects onto the point instead.
  const double rr = 1.0 - out.sky_view * (1.0 + std::cos(surface.slope)) / 2.0;
  // What a group of steps added to the sums since the marks: its global irradiation.
  double beam_mark = 0.0, diffuse_mark = 0.0, ground_mark = 0.0;
  auto credit = [&](std::uint32_t group) {
    if (global_by_group.empty()) return;
    if (group >= global_by_group.size()) throw std::invalid_argument("irradiation: a step group has no entry");
    global_by_group[group] += (out.beam - beam_mark) + (diffuse - diffuse_mark) * out.sky_view +
                              albedo * (ground - ground_mark) * rr;
    beam_mark = out.beam;
    diffuse_mark = diffuse;
    ground_mark = ground;
  };
  // One step at a time: the sectors whose steps lie on both sides of the surface's plane.
  auto step_by_step = [&](const SolarStep& s, bool open) {
    const double c = std::clamp(glm::dot(normal, s.direction), -1.0, 1.0);
    const bool lit = open && s.beam_normal > 0.0 && s.ray_direction.z > 0.0 && c > 0.0;
    if (lit) {
      out.beam += s.beam_normal * c * s.hours;
      if (s.beam_normal >= kSunshineThreshold) out.sun_hours += s.hours;
    }
    if (s.diffuse_horizontal > 0.0) {
      const double ratio = lit ? muneer_diffuse_ratio(s.sun, surface, c, false, s.kb) : shadow_ratio;
      diffuse += s.diffuse_horizontal * ratio * s.hours;
    }
    ground += (lit || s.reflected_from_global ? s.global_horizontal : s.diffuse_horizontal) * s.hours;
  };
  for (std::size_t k = 0; k < nsec; ++k) {
    const SectorSums& g = map.sums[k];
    const bool open_k = open_bit(open, k);
    const double facing = glm::dot(normal, g.axis);
    if (facing > g.sin_spread && open_k) {  // every step in front of the surface, and lit
      out.beam += glm::dot(normal, g.beam);
      out.sun_hours += g.sunshine_hours;
      diffuse += m.flat ? g.diffuse
                        : m.r_sky * g.sunlit_a + m.fg * g.sunlit_b + glm::dot(normal, g.sunlit_c) +
                              m.sin_slope * (m.cos_aspect * g.low_cos + m.sin_aspect * g.low_sin);
      ground += g.reflect_lit;
    } else if (facing > g.sin_spread || facing < -g.sin_spread) {  // in shadow, or every step behind
      diffuse += shadow_ratio * g.diffuse;
      ground += g.reflect_shadow;
    } else {
      for (std::uint32_t t : g.steps) step_by_step(map.steps[t], open_k);
    }
    credit(g.group);
  }
  for (const SectorSums& g : map.no_beam) {
    diffuse += shadow_ratio * g.diffuse;
    ground += g.reflect_shadow;
    credit(g.group);
  }
  out.diffuse = diffuse * out.sky_view;
  out.reflected = albedo * ground * rr;
  return out;
}

}  // namespace rayscan::analysis
