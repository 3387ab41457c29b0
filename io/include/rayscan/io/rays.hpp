// Ray files: the input of `rayscan query` and of any program that batches ray queries.
#pragma once

#include "rayscan/octree/ray.hpp"

#include <filesystem>
#include <vector>

namespace rayscan::io {

/// Reads rays from `path`:
///  - ".f64" (case-insensitive): headerless little-endian float64, 6 values per ray
///    (ox, oy, oz, dx, dy, dz), so the file size must be a multiple of 48 bytes;
///  - anything else: CSV text with the header line "ox,oy,oz,dx,dy,dz" (blanks ignored), then
///    one ray per line; blank lines are skipped.
/// Origins are world coordinates, directions need not be unit (Ray normalises them).
/// Throws io::FormatError, one line naming the file and the byte offset or line number and what
/// was expected, for an unreadable file, a bad header, a malformed number, a wrong value count or
/// a zero / non-finite direction.
std::vector<Ray> read_rays(const std::filesystem::path& path);

}  // namespace rayscan::io
