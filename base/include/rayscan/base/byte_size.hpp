// Byte sizes as users write them on command lines and in options ("4G", "512M").
#pragma once

#include <cstdint>
#include <string>

namespace rayscan {

/// Parses a byte size "4G", "512M", "1.5G", "65536" (K/M/G/T binary multiples, optional "B" or
/// "iB", case-insensitive). Throws std::invalid_argument "size '<text>': expected ..." for anything
/// else (no number, an unknown unit, zero, negative, not finite, or more than 1e18 bytes).
std::uint64_t parse_byte_size(const std::string& text);

}  // namespace rayscan
