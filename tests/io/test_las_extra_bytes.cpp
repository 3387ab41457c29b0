// Decoded LAS Extra Bytes values (ASPRS LAS 1.4 R15 section 2.5.6, tables 24 and 25) against an
// oracle the reader does not compute: the standard fields of the same records, read here straight
// from the file's bytes, and a file built byte by byte below with known raw values, scale and
// offset.
#include "io_test_util.hpp"

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace rayscan::test {
namespace {

/// The scalar `name` of `pc`, failing the test (with the names present) when it is missing.
const ScalarField& extra_field(const PointCloud& pc, const std::string& name) {
  static const ScalarField none;
  if (const ScalarField* f = pc.scalar(name)) return *f;
  std::string names;
  for (const ScalarField& s : pc.scalars) names += " '" + s.name + "'";
  ADD_FAILURE() << "no scalar '" << name << "'; the cloud has" << names;
  return none;
}

// extrabytes.las (PDAL's test file, PDRF 3 + 27 extra bytes) was written with its extra fields
// holding copies of standard fields of the same record: Colors (type 23, 3 x uint16) the RGB,
// Intensity (type 5, uint32) the intensity, Flags (type 12, 2 x uint8) the return number and the
// number of returns. The standard fields are read here from the record bytes (PDRF 3, table 10:
// intensity at byte 12, return number in bits 0-2 of byte 14, red/green/blue at 28/30/32), so the
// oracle is the file itself, not the reader's decoding of it.
TEST(LasExtraBytes, PdalFileFieldsEqualTheStandardFieldsTheyCopy) {
  RAYSCAN_REQUIRE_FILE(p, "las/conformance/extrabytes.las");
  const std::vector<std::uint8_t> b = slurp(p);
  ASSERT_GE(b.size(), 227u);
  ASSERT_EQ(b[104], 3) << "point data record format";
  const std::uint32_t data = load_at<std::uint32_t>(b, 96);
  const std::uint16_t rec = load_at<std::uint16_t>(b, 105);
  const std::uint32_t n = load_at<std::uint32_t>(b, 107);
  ASSERT_EQ(rec, 34 + 27);
  ASSERT_EQ(b.size(), data + std::uint64_t{n} * rec);

  const PointCloud pc = io::read_point_cloud(p);
  ASSERT_EQ(pc.size(), n);
  const ScalarField* colors[3] = {&extra_field(pc, "Colors[0]"), &extra_field(pc, "Colors[1]"),
                                  &extra_field(pc, "Colors[2]")};
  const ScalarField& intensity = extra_field(pc, "Intensity");
  const ScalarField& flags0 = extra_field(pc, "Flags[0]");
  for (const ScalarField* f : {colors[0], colors[1], colors[2], &intensity, &flags0}) ASSERT_EQ(f->values.size(), n) << f->name;

  std::size_t distinct_returns = 0;  // the comparison must see more than one value to mean anything
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::size_t r = data + std::size_t{i} * rec;
    SCOPED_TRACE("point " + std::to_string(i));
    for (int c = 0; c < 3; ++c) EXPECT_EQ(colors[c]->values[i], load_at<std::uint16_t>(b, r + 28 + 2 * c)) << "channel " << c;
    EXPECT_EQ(intensity.values[i], load_at<std::uint16_t>(b, r + 12));
    EXPECT_EQ(flags0.values[i], b[r + 14] & 0x07);
    distinct_returns += i > 0 && (b[r + 14] & 0x07) != (b[r - rec + 14] & 0x07);
  }
  EXPECT_GT(distinct_returns, 0u);
}

/// Appends `v` to `b` as little-endian bytes.
template <class T>
void append_le(std::vector<std::uint8_t>& b, T v) {
  const std::size_t at = b.size();
  b.resize(at + sizeof v);
  store_at(b, at, v);
}

/// One 192-byte Extra Bytes descriptor (table 24): data type, options (table 25), name, no_data
/// (8 bytes at 40, the field's own type widened), scale (at 112) and offset (at 136).
struct Descriptor {
  std::uint8_t type, options;
  std::string name;
  std::int64_t no_data = 0;
  double scale = 0.0, offset = 0.0;
};

std::vector<std::uint8_t> descriptor_bytes(const Descriptor& d) {
  std::vector<std::uint8_t> e(192, 0);
  e[2] = d.type;
  e[3] = d.options;
  std::memcpy(&e[4], d.name.data(), d.name.size());
  store_at(e, 40, d.no_data);
  store_at(e, 112, d.scale);
  store_at(e, 136, d.offset);
  const std::string desc = "test field";
  std::memcpy(&e[160], desc.data(), desc.size());
  return e;
}

// A LAS 1.4 file of PDRF 6 records with 11 extra bytes, built here: each descriptor sets a
// different combination of the options bits (table 25: bit 0 no_data, bit 3 scale, bit 4
// offset) and fills the scale and offset fields even where its bits are clear, so a reader that
// ignored the bits would decode other values.
TEST(LasExtraBytes, ScaleAndOffsetOnlyWhereTheOptionsBitsSaySo) {
  const Descriptor temp{4, 0x01 | 0x08 | 0x10, "temperature", -32768, 0.01, 20.0};  // int16: no_data, scale, offset
  const Descriptor gain{1, 0x08, "gain", 0, 0.5, 1000.0};                           // uint8: scale only
  const Descriptor shift{9, 0x10, "shift", 0, 3.0, -5.25};                          // float: offset only
  const Descriptor plain{6, 0x00, "plain", 0, 7.0, 11.0};                           // int32: neither
  struct Raw {
    std::int16_t temp;
    std::uint8_t gain;
    float shift;
    std::int32_t plain;
  };
  const std::vector<Raw> raws = {{-32768, 0, 0.0f, 0},  // temperature at its no_data value
                                 {1234, 255, 1.5f, -2000000000},
                                 {-1, 7, -1e6f, 2147483647}};
  const std::uint32_t n = static_cast<std::uint32_t>(raws.size());
  const std::uint16_t record = 30 + 2 + 1 + 4 + 4;
  const std::uint32_t vlr_bytes = 54 + 4 * 192, data = 375 + vlr_bytes;

  std::vector<std::uint8_t> b(375, 0);
  std::memcpy(&b[0], "LASF", 4);
  store_at<std::uint16_t>(b, 6, 0x10);  // global encoding: WKT (required for PDRF 6-10; no CRS here)
  b[24] = 1, b[25] = 4;
  store_at<std::uint16_t>(b, 94, 375);
  store_at<std::uint32_t>(b, 96, data);
  store_at<std::uint32_t>(b, 100, 1);
  b[104] = 6;
  store_at<std::uint16_t>(b, 105, record);
  for (int k = 0; k < 3; ++k) store_at<double>(b, 131 + 8 * k, 0.001);
  // Every point at (1, 2, 3) (the integers 1000, 2000, 3000): the header's bounds are that point.
  for (int k = 0; k < 3; ++k) {
    store_at<double>(b, 179 + 16 * k, k + 1.0);
    store_at<double>(b, 187 + 16 * k, k + 1.0);
  }
  store_at<std::uint64_t>(b, 247, n);
  store_at<std::uint64_t>(b, 255, n);  // all first returns

  b.resize(b.size() + 54, 0);  // the Extra Bytes VLR header (section 2.5.2)
  std::memcpy(&b[375 + 2], "LASF_Spec", 9);
  store_at<std::uint16_t>(b, 375 + 18, 4);
  store_at<std::uint16_t>(b, 375 + 20, static_cast<std::uint16_t>(4 * 192));
  for (const Descriptor& d : {temp, gain, shift, plain}) {
    const auto e = descriptor_bytes(d);
    b.insert(b.end(), e.begin(), e.end());
  }
  ASSERT_EQ(b.size(), data);
  for (const Raw& r : raws) {
    const std::size_t at = b.size();
    for (std::int32_t c : {1000, 2000, 3000}) append_le(b, c);
    append_le<std::uint16_t>(b, 0);  // intensity
    append_le<std::uint8_t>(b, 0x11);  // return 1 of 1
    b.resize(at + 30, 0);              // flags, class, user data, scan angle, source id, GPS time
    append_le(b, r.temp);
    append_le(b, r.gain);
    append_le(b, r.shift);
    append_le(b, r.plain);
  }
  ASSERT_EQ(b.size(), data + std::size_t{n} * record);

  io::FileInfo info;
  const PointCloud pc = io::read_point_cloud(b, io::Format::las, "scaled.las", {}, &info);
  ASSERT_EQ(pc.size(), n);
  EXPECT_EQ(info.extra_bytes_per_point, 11);
  const ScalarField &t = extra_field(pc, "temperature"), &g = extra_field(pc, "gain"), &s = extra_field(pc, "shift"),
                    &p = extra_field(pc, "plain");
  for (const ScalarField* f : {&t, &g, &s, &p}) ASSERT_EQ(f->values.size(), n) << f->name;
  for (std::uint32_t i = 0; i < n; ++i) {
    SCOPED_TRACE("point " + std::to_string(i));
    EXPECT_DOUBLE_EQ(t.values[i], raws[i].temp * 0.01 + 20.0);  // raw * scale + offset
    EXPECT_DOUBLE_EQ(g.values[i], raws[i].gain * 0.5);         // scale only: the offset field is not used
    EXPECT_DOUBLE_EQ(s.values[i], raws[i].shift - 5.25);       // offset only: the scale field is not used
    EXPECT_EQ(p.values[i], raws[i].plain);                     // neither: the raw value
  }
  // The reader has no rule for no_data (docs/formats.md, "Extra bytes": a described field becomes
  // a scalar with scale and offset applied): a record holding the no_data value is kept and
  // decoded like any other, -32768 * 0.01 + 20 here, not dropped and not turned into NaN.
  EXPECT_DOUBLE_EQ(t.values[0], -307.68);
}

}  // namespace
}  // namespace rayscan::test
