// Paths to the real data files the io tests read, and small helpers.
#pragma once

#include "../common/temp_dir.hpp"
#include "bytes.hpp"
#include "rayscan/io/point_io.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <unistd.h>
#include <iterator>
#include <string>
#include <vector>

namespace rayscan::test {

namespace fs = std::filesystem;

/// A file of the shared data set (path relative to ../shared/data, e.g. "las/autzen_trim.las"):
/// the copy in tests/data or scenes/data when the repository has one, else ../shared/data when
/// that folder exists beside the repository (CI), else "" (the caller skips).
inline fs::path data_file(const std::string& rel) {
  const fs::path name = fs::path(rel).filename();
  const std::string sub = fs::path(rel).begin()->string();  // las | pcd | ply
  for (const fs::path& p : {fs::path(RAYSCAN_TEST_DATA) / sub / name, fs::path(RAYSCAN_SCENE_DATA) / name})
    if (fs::exists(p)) return p;
  const fs::path shared = fs::path(RAYSCAN_SHARED_DATA) / rel;
  if (fs::exists(shared)) return shared;
  return {};
}

#define RAYSCAN_REQUIRE_FILE(var, rel)                                                   \
  const std::filesystem::path var = ::rayscan::test::data_file(rel);                     \
  if (var.empty()) GTEST_SKIP() << rel << " is not in tests/data and ../shared/data is absent"

/// The whole cloud of `p` (every attribute), its FileInfo in `info` when given.
inline PointCloud read(const fs::path& p, io::FileInfo* info = nullptr) { return io::read_point_cloud(p, {}, info); }

inline std::vector<std::uint8_t> slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline fs::path temp_dir() { return process_temp_dir("rayscan_io_tests"); }

/// The value of type T stored at byte `at` of `b` (a file's own little-endian bytes), and its
/// counterpart that overwrites it (to make a damaged or altered file): the readers' and writers'
/// own io::detail::load_le / store_le.
template <class T>
T load_at(const std::vector<std::uint8_t>& b, std::size_t at) {
  return io::detail::load_le<T>(b.data() + at);
}
template <class T>
void store_at(std::vector<std::uint8_t>& b, std::size_t at, T v) {
  io::detail::store_le(b, at, v);
}

}  // namespace rayscan::test
