// Helpers of the job tests: the data files, a scratch folder, and the option fields an
// OptionError names.
#pragma once

#include "../common/run_command.hpp"
#include "../common/temp_dir.hpp"
#include "rayscan/base/option_error.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <variant>
#include <vector>

namespace rayscan::test {

/// A file of tests/data (e.g. "las/simple1_3.las").
inline std::filesystem::path data_file(const std::string& rel) { return std::filesystem::path(RAYSCAN_TEST_DATA) / rel; }

/// Runs `rayscan ARGS` (the build's program) and returns its exit code and its stdout and stderr.
inline CommandResult rayscan_cli(const std::string& args) { return run_command(quoted(RAYSCAN_BIN) + " " + args); }

/// This test process's scratch folder.
inline std::filesystem::path temp_dir() { return process_temp_dir("rayscan_jobs_tests"); }

/// The bytes of a file.
inline std::string file_bytes(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// One variable length record of a LAS file's bytes: its user id, record id and the offset and
/// length of its payload (ASPRS LAS 1.4 R15 table 3: header size at byte 94, VLR count at 100;
/// each VLR a 54-byte header, user id at 2, record id at 18, length at 20).
struct LasVlr {
  std::string user_id;
  std::uint16_t record = 0;
  std::size_t payload = 0, length = 0;
};

/// The VLRs of the LAS bytes `b`, in file order, read from their headers.
inline std::vector<LasVlr> las_vlrs(const std::string& b) {
  std::vector<LasVlr> out;
  std::uint16_t header = 0, len = 0, record = 0;
  std::uint32_t n = 0;
  std::memcpy(&header, b.data() + 94, 2);
  std::memcpy(&n, b.data() + 100, 4);
  for (std::size_t pos = header, i = 0; i < n; ++i, pos += 54 + len) {
    std::memcpy(&record, b.data() + pos + 18, 2);
    std::memcpy(&len, b.data() + pos + 20, 2);
    out.push_back({std::string(b.c_str() + pos + 2), record, pos + 54, len});
  }
  return out;
}

/// The bytes of tests/data/las/file_with_both_wkt_and_geotiff_vlrs.las (a WKT VLR and GeoKeys of
/// the same CRS, EPSG:32104 in US survey foot) with its WKT VLR made text GDAL cannot read
/// ("XROJCS[..."), and, unless `keep_geokeys`, its GeoKeyDirectory VLR renamed away (record 0):
/// a LAS file whose CRS records are, respectively, an unreadable WKT beside readable GeoKeys, or
/// an unreadable WKT alone (the VLRs found by las_vlrs).
inline std::string las_with_unreadable_wkt(bool keep_geokeys) {
  std::string b = file_bytes(data_file("las/file_with_both_wkt_and_geotiff_vlrs.las"));
  for (const LasVlr& v : las_vlrs(b)) {
    if (v.user_id != "LASF_Projection") continue;
    if (v.record == 2112) b[v.payload] = 'X';                          // "XROJCS[...": not a CRS GDAL reads
    if (v.record == 34735 && !keep_geokeys) b[v.payload - 54 + 18] = 0;  // no GeoKeyDirectory left
  }
  return b;
}

/// The options fields an OptionError names, in order.
inline std::vector<std::string> option_fields(const OptionError& e) {
  std::vector<std::string> fields;
  for (const OptionError::Part& p : e.parts())
    if (const auto* n = std::get_if<OptionName>(&p)) fields.push_back(n->field);
  return fields;
}

/// Calls f and returns the fields named by the OptionError it throws; fails the test when it
/// throws nothing or another exception.
template <class F>
std::vector<std::string> fields_of_option_error(F&& f) {
  try {
    f();
  } catch (const OptionError& e) {
    return option_fields(e);
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected an OptionError, got: " << e.what();
    return {};
  }
  ADD_FAILURE() << "expected an OptionError, nothing was thrown";
  return {};
}

}  // namespace rayscan::test
