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
#include <string>
#include <vector>

namespace rayscan::analysis {

/// The direct normal irradiance from which an hour counts as sunshine, W/m²: the WMO's threshold
/// for sunshine duration (WMO-No. 8, Guide to Instruments and Methods of Observation, Part I,
/// chapter 8), which sunshine recorders and the climate normals' sunshine hours follow. Below it
/// (an overcast sky's faint beam, the clear sky's first minutes after sunrise) the sun casts no
/// distinct shadow.
inline constexpr double kSunshineThreshold = 120.0;

/// kSunshineThreshold as the outputs state it, "DNI >= 120 W/m2" (ASCII, as the result fields'
/// LAS descriptors and units write W/m2): the description of sun_hours and the title of its map.
std::string sunshine_criterion();

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
  /// The part of the period the step belongs to (e.g. its month, 0..11): steps of different
  /// groups never share a sector, so that each group's sum can be told apart.
  std::uint32_t group = 0;
};

/// Sums over a group of steps, each term weighted by the step's hours, from which the sum of
/// the group's irradiance on any surface follows in a few products (MuneerSurfaceTerms): the
/// beam n . beam, the sunlit diffuse r_i sunlit_a + f_g sunlit_b + n . sunlit_c + sin(slope)
/// (cos(aspect) low_cos + sin(aspect) low_sin), the shadowed diffuse (r_i + 0.252271 f_g) diffuse.
struct SectorSums {
  Vec3 beam{0.0};             ///< sum of B_0 s (s: the step's true direction), Wh/m²
  double hours = 0.0;         ///< sum of the steps' hours
  double sunshine_hours = 0.0;  ///< sum of the hours of the steps with B_0 >= kSunshineThreshold
  double diffuse = 0.0;       ///< sum of D_h, Wh/m²
  double sunlit_a = 0.0;      ///< sum of D_h (1 - Kb)
  double sunlit_b = 0.0;      ///< sum of D_h N(Kb) (1 - Kb)
  Vec3 sunlit_c{0.0};         ///< sum of D_h Kb s / sin h0 over the steps with h0 >= 0.1 rad
  double low_cos = 0.0;       ///< sum of D_h Kb cos(A) / (0.1 - 0.008 h0) over the steps with h0 < 0.1 rad
  double low_sin = 0.0;       ///< the same with sin(A) (A: the sun's compass azimuth)
  double reflect_lit = 0.0;   ///< sum of G_h: the ground-reflected source of a lit surface
  double reflect_shadow = 0.0;  ///< sum of D_h, or G_h for measured steps: that of a surface without beam
  /// Normalised mean of the steps' true directions, and the sine of the largest angle between it
  /// and a step's (2 when some step lies 90 degrees or more away): a surface normal n with
  /// n . axis > sin_spread faces every step of the group, one with n . axis < -sin_spread none.
  Vec3 axis{0.0, 0.0, 1.0};
  double sin_spread = 0.0;
  std::vector<std::uint32_t> steps;  ///< the group's steps (indices into SunMap::steps)
  std::uint32_t group = 0;           ///< the steps' SolarStep::group
};

/// The time steps, the directions every point traces, and the sums per sector.
struct SunMap {
  std::vector<SolarStep> steps;
  /// The sectors' directions (unit, cloud frame): the normalised mean of their steps' ray
  /// directions (a lone step keeps its own).
  std::vector<Vec3> directions;
  std::vector<SectorSums> sums;     ///< per sector, the steps with beam
  std::vector<SectorSums> no_beam;  ///< per group, the steps without beam (night, or no direct sun measured)
};

/// Groups the steps with beam (beam_normal > 0 and the sun above the horizon, ray_direction.z > 0)
/// into sectors of their ray directions and SolarStep::group: cells of `sector_deg` in elevation
/// and `sector_deg` in azimuth, measured in the cloud's frame; sector_deg = 0 gives every such step its own sector (exact casting). Sets
/// each step's `sector` and returns the map. Throws std::invalid_argument for a negative or
/// non-finite sector size or a direction that is not unit length.
SunMap build_sun_map(std::vector<SolarStep> steps, double sector_deg);

/// A point's irradiation over the steps (Wh/m², on its own surface) and its hours of sun.
struct PointIrradiation {
  double beam = 0.0, diffuse = 0.0, reflected = 0.0;
  /// Hours of sunshine on the surface: steps with the beam B_0 >= kSunshineThreshold (WMO's
  /// sunshine duration), the sun up, in front of the surface and not blocked.
  double sun_hours = 0.0;
  double sky_view = 0.0;   ///< the cosine-weighted fraction of the sky-map directions seen, 0..1
  [[nodiscard]] double global() const { return beam + diffuse + reflected; }
};

/// The sum over map.steps of the irradiance on a surface with unit `normal` (cloud frame, pointing
/// away from the surface into the open) at a site whose grid north lies `convergence_deg` from
/// true north (SiteLocation), from each sector's SectorSums (per step only for a sector whose steps
/// lie on both sides of the surface's plane): per step, beam B_0c cos(incidence) when the step's sector is open
/// (bit `sector` of `open`) and the sun is in front of the surface; diffuse D_hc x Muneer's ratio
/// (muneer_diffuse_ratio, shadowed form without beam) x the sky view V; reflected albedo x (G_hc or
/// D_hc) x the ground view 1 - V (1 + cos slope) / 2, the part of the surface's hemisphere that is
/// not open sky (for an open surface, V = 1, r.sun's (1 - cos slope) / 2) -- for an open surface,
/// clear_sky_irradiance() and measured_irradiance_on_surface() of each step, summed. The sky view is sum(open_k max(0, n . s_k)) / sum(max(0, n . s_k)) over the
/// `sky` directions s_k, whose open bits follow the sectors' (bit map.directions.size() + k); an
/// empty `sky` is the open sky (1). `open` holds (map.directions.size() + sky.size() + 63) / 64
/// words. With `global_by_group` (one entry per step group, or empty), each group's global
/// irradiation (Wh/m²) is added to its entry; they sum to the result's global().
PointIrradiation accumulate_irradiation(const SunMap& map, std::span<const Vec3> sky, const Vec3& normal,
                                        double convergence_deg, double albedo,
                                        std::span<const std::uint64_t> open,
                                        std::span<double> global_by_group = {});

}  // namespace rayscan::analysis
