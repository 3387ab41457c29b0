// Internal: the text format's one rule for what a header name means, shared by the reader (which
// columns are x, y, z, colour, intensity) and the writer (which scalar names would read back as
// something else and so are written with a suffix).
#pragma once

#include "field_names.hpp"

#include <string>
#include <string_view>

namespace rayscan::io::detail {

/// What a text column holds, by its header name.
enum class TextColumn { x, y, z, r, g, b, intensity, nx, ny, nz, scalar };

/// The column a header name names, ignoring ASCII case: x (also CloudCompare's "//x"), y, z,
/// r/red, g/green, b/blue, i/intensity, nx/ny/nz (also PDAL's NormalX/NormalY/NormalZ: the
/// reader takes them as normals when all three are there, else as scalars); any other name is a
/// scalar.
inline TextColumn text_column(std::string_view name) {
  std::string n(name);
  for (char& c : n)
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  if (n == "x" || n == "//x") return TextColumn::x;
  if (n == "y") return TextColumn::y;
  if (n == "z") return TextColumn::z;
  if (n == "r" || n == "red") return TextColumn::r;
  if (n == "g" || n == "green") return TextColumn::g;
  if (n == "b" || n == "blue") return TextColumn::b;
  if (n == "i" || n == "intensity") return TextColumn::intensity;
  if (n == "nx" || n == "normalx") return TextColumn::nx;
  if (n == "ny" || n == "normaly") return TextColumn::ny;
  if (n == "nz" || n == "normalz") return TextColumn::nz;
  return TextColumn::scalar;
}

/// True when a scalar written under the column name `name` would not read back as that scalar:
/// the name is one of text_column's dedicated columns, or a name the reader moves into a dedicated
/// field when the values fit (dedicated_field_name: classification, gps_time). The text writer
/// gives such a scalar a suffix (unique_field_name), so that its file reads back unambiguously.
inline bool text_name_reserved(std::string_view name) {
  return text_column(name) != TextColumn::scalar || dedicated_field_name(name) != nullptr;
}

}  // namespace rayscan::io::detail
