// Irradiation of the points of a scanned site over a period: the sun map (the time steps'
// sun directions grouped into sectors that share one shadow ray per point), the sky map (the
// directions that sample each point's view of the sky), and the sum over the time steps of the
// clear-sky (ESRA, as GRASS r.sun) or measured (EPW) irradiance on each point's own surface.
// The scheme is the sun map / sky map of ArcGIS's Area Solar Radiation (Fu & Rich 2002, "A
// geometric solar radiation model with applications in agriculture and forestry", Computers and
// Electronics in Agriculture 37) on points instead of raster cells: one ray per sector, not per
// time step, while the irradiance of every step keeps its exact sun direction.
#pragma once

#include "rayscan/analysis/clear_sky.hpp"
#include "rayscan/octree/geometry.hpp"

#include <cstdint>
#include <span>
#include <vector>

namespace rayscan::analysis {

/// The sky at one time step, the same for every point of the site.
struct SolarStep {
  double hours = 1.0;        ///< length of the step, hours (its irradiance x hours = Wh/m²)
  /// Unit vector towards the sun's true (airless) position in the cloud's frame (x grid east,
  /// y grid north, z up): the incidence angle on a surface, as ESRA and r.sun take it.
  Vec3 direction{0, 0, 1};
  /// Unit vector towards the sun as seen, refraction included: the shadow ray (light arrives
  /// along it). The sectors group these.
  Vec3 ray_direction{0, 0, 1};
  double beam_normal = 0.0;  ///< B_0c or the measured DNI, W/m² (0: no beam, e.g. the sun is down)
  double diffuse_horizontal = 0.0;  ///< D_hc or the measured DHI, W/m²
  double global_horizontal = 0.0;   ///< G_hc or the measured GHI, W/m²
  SunDirection sun;          ///< true elevation and compass azimuth, radians (Muneer's model)
  double kb = 0.0;           ///< beam fraction Kb (muneer_diffuse_ratio), 0..1
  /// Ground-reflected term of a point that receives no beam: false (clear sky, as r.sun's
  /// shadow_drops_reflected_beam) uses D_hc, true (measured) uses the GHI always.
  bool reflected_from_global = false;
  std::uint32_t sector = 0;  ///< index into SunMap::directions (meaningful when beam_normal > 0)
};

/// The time steps and the directions every point traces.
struct SunMap {
  std::vector<SolarStep> steps;
  /// The sectors' directions (unit, cloud frame): the normalised mean of their steps' directions.
  std::vector<Vec3> directions;
};

/// Groups the steps with beam (beam_normal > 0 and the sun above the horizon, ray_direction.z > 0)
/// into sectors of their ray directions: cells of `sector_deg` in elevation and `sector_deg` in
/// azimuth, measured in the cloud's frame; sector_deg = 0 gives every such step its own sector (exact casting). Sets
/// each step's `sector` and returns the map. Throws std::invalid_argument for a negative or
/// non-finite sector size or a direction that is not unit length.
SunMap build_sun_map(std::vector<SolarStep> steps, double sector_deg);

/// A point's irradiation over the steps (Wh/m², on its own surface) and its hours of sun.
struct PointIrradiation {
  double beam = 0.0, diffuse = 0.0, reflected = 0.0;
  double sun_hours = 0.0;  ///< hours with beam on the surface (sun up, in front of it, not blocked)
  double sky_view = 0.0;   ///< the cosine-weighted fraction of the sky-map directions seen, 0..1
  [[nodiscard]] double global() const { return beam + diffuse + reflected; }
};

/// The sum over map.steps of the irradiance on a surface with unit `normal` (cloud frame, pointing
/// away from the surface into the open) at a site whose grid north lies `convergence_deg` from
/// true north (SiteLocation): per step, beam B_0c cos(incidence) when the step's sector is open
/// (bit `sector` of `open`) and the sun is in front of the surface; diffuse D_hc x Muneer's ratio
/// (muneer_diffuse_ratio, shadowed form without beam) x the sky view; reflected albedo x (G_hc or
/// D_hc) x (1 - cos slope) / 2 -- clear_sky_irradiance() and measured_irradiance_on_surface() of
/// each step, summed. The sky view is sum(open_k max(0, n . s_k)) / sum(max(0, n . s_k)) over the
/// `sky` directions s_k, whose open bits follow the sectors' (bit map.directions.size() + k); an
/// empty `sky` is the open sky (1). `open` holds (map.directions.size() + sky.size() + 63) / 64
/// words.
PointIrradiation accumulate_irradiation(const SunMap& map, std::span<const Vec3> sky, const Vec3& normal,
                                        double convergence_deg, double albedo,
                                        std::span<const std::uint64_t> open);

}  // namespace rayscan::analysis
