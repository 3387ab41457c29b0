// The viewshed of a raster DSM by exact line of sight, the way GIS tools compute it on a surface
// model (gdal_viewshed, GRASS r.viewshed): the site's surface as one height per cell, the targets
// at the cell centres. rayscan's own DSM (the ortho map's top surface, analysis/ortho_map.hpp) is
// the surface; the per-point line of sight over the points themselves is visibility.hpp.
#pragma once

#include "rayscan/analysis/observer.hpp"
#include "rayscan/analysis/raster.hpp"
#include "rayscan/octree/geometry.hpp"

#include <span>

namespace rayscan::analysis {

/// The viewshed of `dsm` (heights in world units, NaN = no surface) from the `eyes` (world
/// coordinates, the cloud's frame and units; an eye may lie outside the grid): 1 where the target
/// at a cell's centre, `target_height` above its surface, is seen from at least one eye, 0 where
/// none sees it, NaN where the DSM has no value. The line of sight is exact over the surface
/// interpolated linearly between cell centres: Franklin & Ray's R3 ("Higher isn't necessarily
/// better: visibility algorithms and experiments", 1994, section 3): the sight line from the eye
/// to the target crosses the lines through the cell centres of the major axis (columns when it
/// runs more east-west than north-south, else rows); at each crossing the surface height is the
/// linear interpolation between the two cell centres it passes between, and the target is hidden
/// when one of them lies above the sight line. Cells without a value do not block. No earth
/// curvature or refraction (gdal_viewshed -cc 0). O(cells x cells along a line) per eye, the rows
/// spread over `threads` (0 = all cores). `progress`: report the rows done on stderr (Progress,
/// rayscan/base/progress.hpp: "rows", the rate in cells/s). Throws std::invalid_argument when the
/// DSM's value count is not cols x rows, a target height is negative or not finite, or an eye is
/// not finite.
Raster dsm_viewshed(const Raster& dsm, std::span<const Vec3> eyes, double target_height, unsigned threads = 0,
                    bool progress = false);

/// dsm_viewshed from `observers` (their positions as the eyes) within their limits, as the
/// per-point line of sight applies them (visibility.hpp): a cell counts for an observer only when
/// its surface point at the cell centre lies within the observer's max_distance (else
/// `max_distance`; world units, the 3-D distance from the eye; +inf = no limit) and inside its
/// azimuth and elevation limits (within_angle_limits). Throws as dsm_viewshed, and
/// std::invalid_argument for a negative or NaN max_distance.
Raster dsm_viewshed(const Raster& dsm, std::span<const Observer> observers, double max_distance,
                    double target_height, unsigned threads = 0, bool progress = false);

}  // namespace rayscan::analysis
