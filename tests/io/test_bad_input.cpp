// Malformed input: every case raises io::FormatError with one line naming the file and the byte
// offset or line, never crashes and never allocates from an unchecked count.
#include "io_test_util.hpp"
#include "../common/index_crcs.hpp"
#include "../common/run_command.hpp"
#include "rayscan/io/las_records.hpp"
#include "rayscan/octree/batch.hpp"
#include "rayscan/octree/normals.hpp"
#include "rayscan/octree/point_query.hpp"
#include "rayscan/octree/ray_query.hpp"
#include "rayscan/site/copc.hpp"
#include "rayscan/site/index_file.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <map>
#include <random>
#include <set>

namespace rayscan::test {
namespace {

std::string error_of(const std::vector<std::uint8_t>& b, io::Format f, const std::string& name = "bad") {
  try {
    io::read_point_cloud(b, f, name);
  } catch (const io::FormatError& e) {
    return e.what();
  }
  return "";
}
std::string error_of(const std::string& s, io::Format f) {
  return error_of(std::vector<std::uint8_t>(s.begin(), s.end()), f);
}
template <class T>
void poke(std::vector<std::uint8_t>& b, std::size_t off, T v) {
  std::memcpy(&b[off], &v, sizeof v);
}

void expect_one_line(const std::string& e, const std::string& must_contain) {
  EXPECT_FALSE(e.empty()) << "no error raised (expected '" << must_contain << "')";
  EXPECT_EQ(e.find('\n'), std::string::npos) << e;
  EXPECT_EQ(e.rfind("bad: ", 0), 0u) << e;
  EXPECT_NE(e.find(must_contain), std::string::npos) << e;
}

std::vector<std::uint8_t> las_bytes() { return slurp(data_file("las/conformance/point-color-time.las")); }

TEST(BadInput, LasWrongMagicAndTruncatedHeader) {
  auto b = las_bytes();
  b[0] = 'X';
  expect_one_line(error_of(b, io::Format::las), "byte 0: expected file signature \"LASF\"");
  const auto full = las_bytes();
  expect_one_line(error_of(std::vector<std::uint8_t>(full.begin(), full.begin() + 100), io::Format::las),
                  "byte 0: file ends");
  // A header cut short is told the least size of its own version (LAS 1.4 R15 table 3 and the
  // 1.2 / 1.3 specifications: 227, 235, 375 bytes), from the version bytes 24-25 it still holds.
  for (const auto& [minor, need] : {std::pair{2, 227}, {3, 235}, {4, 375}}) {
    std::vector<std::uint8_t> cut(full.begin(), full.begin() + 100);
    cut[25] = std::uint8_t(minor);
    EXPECT_EQ(error_of(cut, io::Format::las), "bad: byte 0: file ends (size 100) inside LAS 1." + std::to_string(minor) +
                                                  " public header block (needs " + std::to_string(need) + " bytes)");
  }
  // Too short to hold the version: the least size of any version.
  EXPECT_EQ(error_of(std::vector<std::uint8_t>(full.begin(), full.begin() + 20), io::Format::las),
            "bad: byte 0: file ends (size 20) inside LAS public header block (needs 227 bytes)");
}

TEST(BadInput, LasPointCountLargerThanTheFile) {
  auto b = las_bytes();
  poke<std::uint32_t>(b, 107, 1066);  // one more point than the 1065 the file holds
  expect_one_line(error_of(b, io::Format::las), "byte 107: header announces 1066 points");
  b.resize(b.size() - 10);  // a truncated file: the last record is incomplete
  poke<std::uint32_t>(b, 107, 1065);
  expect_one_line(error_of(b, io::Format::las), "header announces 1065 points");
}

TEST(BadInput, LasAbsurdLas14CountDoesNotAllocate) {
  auto b = slurp(data_file("las/conformance/test1_4.las"));
  poke<std::uint64_t>(b, 247, std::uint64_t{1} << 60);
  expect_one_line(error_of(b, io::Format::las), "byte 247: header announces 1152921504606846976 points");
}

TEST(BadInput, LasRecordLengthSmallerThanTheFormat) {
  auto b = las_bytes();
  poke<std::uint16_t>(b, 105, 20);  // PDRF 3 needs 34
  expect_one_line(error_of(b, io::Format::las), "byte 105: point record length 20 smaller than the 34 bytes");
}

TEST(BadInput, LasVlrRunningPastTheEnd) {
  auto b = las_bytes();
  std::uint16_t hs;
  std::memcpy(&hs, &b[94], 2);
  ASSERT_GT(b.size(), hs + 54u);
  poke<std::uint16_t>(b, hs + 20, 60000);  // first VLR's record length
  expect_one_line(error_of(b, io::Format::las), "runs past the start of point data");
  b = las_bytes();
  poke<std::uint32_t>(b, 96, 100000000);  // offset to point data past EOF
  expect_one_line(error_of(b, io::Format::las), "byte 96: offset to point data 100000000 past end of file");
}

TEST(BadInput, LasNonFiniteScale) {
  auto b = las_bytes();
  poke<double>(b, 139, std::nan(""));
  expect_one_line(error_of(b, io::Format::las), "byte 139: scale factor Y");
}

// The coordinate bound (rayscan::kMaxCoordinate, 1e9 world units) is inclusive: a coordinate of
// exactly +-1e9 reads, one step beyond is refused naming the point, the axis and the value; an
// offset beyond the bound is refused at the header. Oracle: the LAS formula X x scale + offset on
// integers and scales/offsets chosen here, exact in double.
TEST(BadInput, LasCoordinateBoundIsInclusiveAndAnOffsetBeyondItIsRefused) {
  auto b = las_bytes();
  const std::uint32_t at = load_at<std::uint32_t>(b, 96);
  const std::uint16_t len = load_at<std::uint16_t>(b, 105);
  const std::uint32_t count = load_at<std::uint32_t>(b, 107);
  ASSERT_GE(count, 3u);
  // Scale 1 on X and Y, offsets 10 inside the bound, every stored X and Y 0 (the offsets).
  poke<double>(b, 131, 1.0);
  poke<double>(b, 139, 1.0);
  poke<double>(b, 155, 1e9 - 10);
  poke<double>(b, 163, -(1e9 - 10));
  for (std::uint32_t i = 0; i < count; ++i) {
    poke<std::int32_t>(b, at + std::size_t{i} * len, 0);
    poke<std::int32_t>(b, at + std::size_t{i} * len + 4, 0);
  }
  poke<std::int32_t>(b, at + std::size_t{1} * len, 10);       // point 1: X = 1e9
  poke<std::int32_t>(b, at + std::size_t{2} * len + 4, -10);  // point 2: Y = -1e9
  const PointCloud pc = io::read_point_cloud(b, io::Format::las, "bad");
  ASSERT_EQ(pc.positions.size(), count);
  EXPECT_EQ(pc.positions[1].x, 1e9);
  EXPECT_EQ(pc.positions[2].y, -1e9);

  auto beyond = b;
  poke<std::int32_t>(beyond, at + std::size_t{1} * len, 11);
  expect_one_line(error_of(beyond, io::Format::las),
                  "byte " + std::to_string(at + len) + ": point 1: X coordinate is 1000000001 (stored integer 11 x scale 1 + "
                  "offset 999999990; expected within +-1e+09");
  beyond = b;
  poke<std::int32_t>(beyond, at + std::size_t{2} * len + 4, -11);
  expect_one_line(error_of(beyond, io::Format::las), "point 2: Y coordinate is -1000000001");

  // An offset beyond the bound is refused at its header field, before any point is read.
  beyond = b;
  poke<double>(beyond, 171, -1.5e9);
  expect_one_line(error_of(beyond, io::Format::las), "byte 171: offset Z is -1.5e+09 (expected within +-1e+09");
}

TEST(BadInput, PlyUnknownTypeTruncatedBodyAndNanCoordinate) {
  expect_one_line(error_of(std::string("ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n"),
                           io::Format::ply),
                  "line 4: unknown PLY type 'float128'");
  expect_one_line(error_of(std::string("ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\n"
                                       "property float x\nproperty float y\nproperty float z\nend_header\n1234"),
                           io::Format::ply),
                  "announces 1000000000000 items");
  expect_one_line(error_of(std::string("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                                       "property float z\nend_header\n1 2 3\nnan 2 3\n"),
                           io::Format::ply),
                  "line 9: vertex 1 has a non-finite coordinate");
  expect_one_line(error_of(std::string("ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                                       "property float z\nend_header\n1 2 3\n4 5\n"),
                           io::Format::ply),
                  "file ends, expected a value for property 'z'");
  expect_one_line(error_of(std::string("PLY\n"), io::Format::ply), "line 1: expected the magic line \"ply\"");
}

TEST(BadInput, PcdDataBeforeFieldsAndCountsBeyondTheFile) {
  expect_one_line(error_of(std::string("VERSION .7\nDATA ascii\nFIELDS x y z\n"), io::Format::pcd),
                  "line 2: DATA before FIELDS");
  expect_one_line(error_of(std::string("VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1000000000000\n"
                                       "HEIGHT 1\nPOINTS 1000000000000\nDATA binary\n123456789012"),
                           io::Format::pcd),
                  "header announces 1000000000000 points of 12 bytes");
  using namespace std::string_literals;
  // 16 bytes of "LZF" claiming to expand to 100000 points * 12 bytes = 1200000 (0x124F80).
  expect_one_line(error_of("VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 100000\n"
                           "HEIGHT 1\nPOINTS 100000\nDATA binary_compressed\n\x10\0\0\0\x80\x4f\x12\0abcdefghijklmnop"s,
                           io::Format::pcd),
                  "impossible for 16 bytes of LZF data");
  // A back reference before the start of the output (liblzf: EINVAL), and a literal run of 32
  // bytes into the 12 bytes stated (E2BIG): each named, not "decompresses to 0 bytes".
  const std::string one_point = "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nHEIGHT 1\nPOINTS 1\n"
                                "DATA binary_compressed\n";
  expect_one_line(error_of(one_point + "\x02\0\0\0\x0c\0\0\0\x20\x00"s, io::Format::pcd),
                  "LZF data is corrupt: a back reference or literal run past its bounds");
  expect_one_line(error_of(one_point + "\x21\0\0\0\x0c\0\0\0\x1f"s + std::string(32, 'a'), io::Format::pcd),
                  "LZF data is corrupt: it decodes to more than the 12 bytes stated");
  // An empty stream for 12 bytes: refused before liblzf, which would read a control byte past it.
  expect_one_line(error_of(one_point + "\0\0\0\0\x0c\0\0\0"s, io::Format::pcd),
                  "compressed size 0 for 12 bytes of point data");
  expect_one_line(error_of(std::string("VERSION .7\nFIELDS x y z h\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 900000\n"
                                       "WIDTH 1\nPOINTS 1\nDATA ascii\n"),
                           io::Format::pcd),
                  "line 8: FIELDS/COUNT declare 900003 values per point");
  expect_one_line(error_of(std::string("VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F Q\nDATA ascii\n"), io::Format::pcd),
                  "line 4: TYPE 'Q'");
}

TEST(BadInput, TextNonNumberAndMissingColumns) {
  expect_one_line(error_of(std::string("1 2 3\n4 five 6\n"), io::Format::text), "line 2: column 2: expected a finite number");
  expect_one_line(error_of(std::string("x,y,z\n1,2\n"), io::Format::text), "line 2: expected 3 columns, got 2");
  expect_one_line(error_of(std::string("1 2 inf\n"), io::Format::text), "line 1: non-finite coordinate");
}

// PCD, text and .f64 points hold the LAS reader's coordinate bound (rayscan::kMaxCoordinate, 1e9
// world units, inclusive): a finite coordinate beyond it is refused naming the point (0-based in
// file order, a dropped NaN point counted), the axis and the value, at the point's line (ascii),
// record byte (binary, .f64) or the LZF data (binary_compressed); PCD still drops a NaN point.
// Oracle: the values written here, and the byte of record i = end of header + i x record length.
TEST(BadInput, PcdTextAndF64CoordinatesBeyondTheBoundAreRefused) {
  using namespace std::string_literals;
  const std::string tail = " (expected within +-1e+09, the coordinate bound in world units)";
  const std::string ascii = "VERSION .7\nFIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nWIDTH 3\nHEIGHT 1\nPOINTS 3\n"
                            "DATA ascii\n1e9 -1e9 0\nnan 0 0\n";
  io::FileInfo info;
  const std::string inside = ascii + "0 0 1e9\n";
  const PointCloud pc = io::read_point_cloud(std::vector<std::uint8_t>(inside.begin(), inside.end()), io::Format::pcd,
                                             "bad", {}, &info);
  ASSERT_EQ(pc.positions.size(), 2u);
  EXPECT_EQ(pc.positions[0], Vec3(1e9, -1e9, 0));
  EXPECT_EQ(pc.positions[1], Vec3(0, 0, 1e9));
  EXPECT_EQ(info.dropped_nonfinite, 1u);
  EXPECT_EQ(error_of(ascii + "0 0 -1000000001\n", io::Format::pcd),
            "bad: line 11: point 2: Z coordinate is -1000000001" + tail);

  // binary: three points of 24 bytes after the header; point 2's Y is 2e9.
  std::string bin = "VERSION .7\nFIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nWIDTH 3\nHEIGHT 1\nPOINTS 3\nDATA binary\n";
  const std::size_t body = bin.size();
  const double v[9] = {1, 2, 3, std::nan(""), 0, 0, 4, 2e9, 6};
  bin.append(reinterpret_cast<const char*>(v), sizeof v);
  EXPECT_EQ(error_of(bin, io::Format::pcd), "bad: byte " + std::to_string(body + 2 * 24) + ": point 2: Y coordinate is 2e+09" + tail);

  // binary_compressed, one point (its struct of arrays is its record): an LZF literal run of 24
  // bytes (control byte 23), named at the LZF data, 8 bytes after the header.
  std::string lzf = "VERSION .7\nFIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA binary_compressed\n";
  const std::size_t cbody = lzf.size();
  const double w[3] = {-3e9, 0, 0};
  lzf += "\x19\0\0\0\x18\0\0\0\x17"s;
  lzf.append(reinterpret_cast<const char*>(w), sizeof w);
  EXPECT_EQ(error_of(lzf, io::Format::pcd), "bad: byte " + std::to_string(cbody + 8) + ": point 0: X coordinate is -3e+09" + tail);

  // text: line 3 is the second point (the header names the columns); exactly 1e9 reads.
  const std::string text = "x y z\n1000000000 -1000000000 0\n0 -1000000000.5 0\n";
  EXPECT_EQ(error_of(text, io::Format::text), "bad: line 3: point 1: Y coordinate is -1000000000.5" + tail);
  expect_one_line(error_of(std::string("1 2 inf\n"), io::Format::text), "line 1: non-finite coordinate");

  // .f64: headerless x, y, z doubles; point 1 (byte 24) has X beyond the bound.
  std::vector<std::uint8_t> f64(48);
  const double u[6] = {1e9, 0, -1e9, 1.5e9, 0, 0};
  std::memcpy(f64.data(), u, sizeof u);
  EXPECT_EQ(error_of(f64, io::Format::f64), "bad: byte 24: point 1: X coordinate is 1.5e+09" + tail);
  poke<double>(f64, 24, 0.0);
  const PointCloud ok = io::read_point_cloud(f64, io::Format::f64, "ok");
  ASSERT_EQ(ok.positions.size(), 2u);
  EXPECT_EQ(ok.positions[0], Vec3(1e9, 0, -1e9));
}

// PLY vertices hold the same bound: a finite coordinate beyond +-1e9 is refused naming the vertex
// (0-based), the axis and the value, at its line (ascii) or its first byte (binary, little- and
// big-endian); exactly 1e9 reads. Oracle: the values written here, and the byte of vertex i = end
// of header + i x 12 (three floats), or + i x 24 (three doubles).
TEST(BadInput, PlyCoordinatesBeyondTheBoundAreRefused) {
  const std::string tail = " (expected within +-1e+09, the coordinate bound in world units)";
  const std::string head = "ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\nproperty double y\n"
                           "property double z\nend_header\n";
  const std::string inside = head + "1e9 -1e9 0\n0 0 1000000000\n";
  const PointCloud pc = io::read_point_cloud(std::vector<std::uint8_t>(inside.begin(), inside.end()), io::Format::ply,
                                             "bad");
  ASSERT_EQ(pc.positions.size(), 2u);
  EXPECT_EQ(pc.positions[0], Vec3(1e9, -1e9, 0));
  EXPECT_EQ(pc.positions[1], Vec3(0, 0, 1e9));
  // line 9 is the second vertex.
  EXPECT_EQ(error_of(head + "1 2 3\n0 0 -1000000000.5\n", io::Format::ply),
            "bad: line 9: point 1: Z coordinate is -1000000000.5" + tail);

  // binary_little_endian floats: vertex 2's Y is 2e9 (a float holds it exactly).
  std::string le = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                   "property float z\nend_header\n";
  const std::size_t le_body = le.size();
  const float v[9] = {1, 2, 3, 4, 5, 6, 7, 2e9f, 9};
  le.append(reinterpret_cast<const char*>(v), sizeof v);
  EXPECT_EQ(error_of(le, io::Format::ply),
            "bad: byte " + std::to_string(le_body + 2 * 12) + ": point 2: Y coordinate is 2e+09" + tail);

  // binary_big_endian doubles: vertex 1's X is -3e9, stored most significant byte first.
  std::string be = "ply\nformat binary_big_endian 1.0\nelement vertex 2\nproperty double x\nproperty double y\n"
                   "property double z\nend_header\n";
  const std::size_t be_body = be.size();
  for (const double d : {0.0, 0.0, 0.0, -3e9, 0.0, 0.0}) {
    std::uint64_t bits = 0;
    std::memcpy(&bits, &d, 8);
    for (int k = 7; k >= 0; --k) be += static_cast<char>((bits >> (8 * k)) & 0xFF);
  }
  EXPECT_EQ(error_of(be, io::Format::ply),
            "bad: byte " + std::to_string(be_body + 24) + ": point 1: X coordinate is -3e+09" + tail);
}

TEST(BadInput, DuplicateColumnsAndProperties) {
  // Two columns with the same role ("i" and "intensity") are refused, not both read into intensity
  // (tests/fuzz/regressions/text/duplicate-intensity-column.csv is a fuzz_text input of it).
  expect_one_line(error_of(std::string("x,y,z,i,intensity\n1,2,3,4,5\n"), io::Format::text),
                  "line 1: columns 4 and 5 ('i', 'intensity') name the same attribute");
  // PLY: the second property with the same role stays a named scalar.
  const std::string ply = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                          "property float z\nproperty ushort intensity\nproperty ushort scalar_intensity\n"
                          "end_header\n1 2 3 4 5\n6 7 8 9 10\n";
  const PointCloud pc = io::read_point_cloud(std::vector<std::uint8_t>(ply.begin(), ply.end()), io::Format::ply, "d.ply");
  pc.validate();
  EXPECT_EQ(pc.intensity, (std::vector<std::uint16_t>{4, 9}));
  ASSERT_NE(pc.scalar("scalar_intensity"), nullptr);
  EXPECT_EQ(pc.scalar("scalar_intensity")->values, (std::vector<double>{5, 10}));
}

TEST(BadInput, AsciiIntegersOutsideTheirTypeAreRefusedFloatsPastTheirFieldClamped) {
  // Casting "nan" to an ascii uchar intensity's integer or a huge double to float is undefined
  // behaviour (tests/fuzz/regressions/ply/nan-integer-intensity.ply is a fuzz_ply input of the
  // first). A value its declared integer type cannot hold is an error naming the line and
  // property; values of a float type that do not fit their destination are clamped.
  const std::string head = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                           "property float z\nproperty uchar intensity\nproperty double nx\nproperty double ny\n"
                           "property double nz\nproperty double red\nproperty double green\nproperty double blue\n"
                           "end_header\n";
  auto read = [&](const std::string& body) {
    const std::string ply = head + body;
    return io::read_point_cloud(std::vector<std::uint8_t>(ply.begin(), ply.end()), io::Format::ply, "r.ply");
  };
  for (const std::string v : {"nan", "300", "-1", "1.5"}) {
    SCOPED_TRACE(v);
    try {
      (void)read("0 0 0 7 1e300 0 0 1e300 0 0\n1 1 1 " + v + " 0 1 0 0 0 1e300\n");
      ADD_FAILURE() << "accepted";
    } catch (const io::FormatError& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find("r.ply: line 16: property 'intensity' is uchar: expected an integer in 0..255, got '" + v + "'"),
                std::string::npos) << m;
    }
  }
  const PointCloud pc = read("0 0 0 7 1e300 0 0 1e300 0 0\n1 1 1 255 0 1 0 0 0 1e300\n");
  pc.validate();
  EXPECT_EQ(pc.intensity, (std::vector<std::uint16_t>{7, 255}));
  EXPECT_EQ(pc.normals[1], glm::vec3(0, 1, 0));
  EXPECT_GT(pc.normals[0].x, 3e38f);
  EXPECT_EQ(pc.rgb[0].r, pc.rgb[1].b);  // both channels hold the (clamped) maximum
}

TEST(BadInput, LasEvlrStartBeforeThePointDataIsRefused) {
  // An EVLR start inside the VLRs read their bytes as an EVLR (and translate copied it).
  auto b = slurp(data_file("las/conformance/1_4_w_evlr.las"));
  std::uint64_t start = 0;
  std::uint32_t offset = 0;
  std::memcpy(&start, &b[235], 8);
  std::memcpy(&offset, &b[96], 4);
  ASSERT_GE(start, offset);  // the file as written is valid
  poke<std::uint64_t>(b, 235, 400);
  expect_one_line(error_of(b, io::Format::las),
                  "byte 235: EVLR start 400 lies before the point data at byte " + std::to_string(offset));
}

TEST(BadInput, LasWaveformRecordCutShortIsRefusedWithItsOffsetAndLength) {
  // simple1_3.las: LAS 1.3, global encoding bit 1 (waveform packets in the file), its waveform
  // data packet record after the points. Oracle: the file's own header bytes (byte 227: the
  // record's start; the record's 60-byte header: user id at +2, length after header at +20).
  RAYSCAN_REQUIRE_FILE(p, "las/simple1_3.las");
  const auto b = slurp(p);
  ASSERT_EQ(load_at<std::uint16_t>(b, 6) & 2u, 2u);
  const auto start = load_at<std::uint64_t>(b, 227);
  ASSERT_LE(start + 60, b.size());
  const auto declared = load_at<std::uint64_t>(b, start + 20);
  ASSERT_GT(declared, 0u);
  ASSERT_EQ(start + 60 + declared, b.size());  // the intact file ends with the record
  const std::string user = io::detail::fixed_string(b.data() + start + 2, 16);
  // Intact, it reads: every point the header announces.
  EXPECT_EQ(io::read_point_cloud(b, io::Format::las, "bad").size(), load_at<std::uint32_t>(b, 107));

  // Cut after the record's header: its declared payload runs past the end, named where the
  // length is stored, with the record's start and length (the EVLRs' check and words).
  const std::vector<std::uint8_t> cut(b.begin(), b.begin() + static_cast<std::ptrdiff_t>(start + 60));
  const std::string want = "byte " + std::to_string(start + 20) + ": waveform data packet record at byte " +
                           std::to_string(start) + " (" + user + ") of " + std::to_string(declared) +
                           " bytes runs past end of file (size " + std::to_string(cut.size()) + ")";
  EXPECT_EQ(error_of(cut, io::Format::las), "bad: " + want);
  // Cut inside the record's header.
  const std::vector<std::uint8_t> cut_head(b.begin(), b.begin() + static_cast<std::ptrdiff_t>(start + 30));
  expect_one_line(error_of(cut_head, io::Format::las),
                  "byte " + std::to_string(start) + ": file ends (size " + std::to_string(start + 30) + ")");
  // A start inside the header or VLRs would read their bytes as the record: refused at byte 227.
  auto early = b;
  store_at<std::uint64_t>(early, 227, 300);
  expect_one_line(error_of(early, io::Format::las),
                  "byte 227: start of waveform data packet record 300 lies before the point data at byte " +
                      std::to_string(load_at<std::uint32_t>(b, 96)));

  // Through the CLI: info and translate exit 2 with that one line; translate writes nothing.
  const fs::path in = temp_dir() / "wave_cut.las", out = temp_dir() / "wave_cut_out.las";
  {
    std::ofstream f(in, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(cut.data()), static_cast<std::streamsize>(cut.size()));
  }
  for (const std::string& cmd : {" info " + quoted(in), " translate -q " + quoted(in) + " " + quoted(out)}) {
    const CommandResult r = run_command(std::string("'") + RAYSCAN_EXE + "'" + cmd);
    EXPECT_EQ(r.code, 2) << cmd << ": " << r.out;
    EXPECT_NE(r.out.find(in.string() + ": " + want), std::string::npos) << r.out;
    EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  }
  EXPECT_FALSE(fs::exists(out));
}

TEST(BadInput, ControlBytesInAQuotedTokenAreEscapedNotTheEndOfTheMessage) {
  // A NUL in the quoted token is escaped: unescaped, it would end what() there ("... got '").
  std::string t = "x y z\n1 2 3\n4 5 ";
  t += std::string("6\0\x01z", 4);
  t += "\n";
  const std::string e = error_of(t, io::Format::text);
  expect_one_line(e, "line 3: column 3: expected a finite number, got '6\\x00\\x01z'");
}

TEST(BadInput, FileThatDoesNotExistOrHasAnUnknownExtension) {
  EXPECT_THROW(io::read_point_cloud("/nonexistent/x.las"), io::FormatError);
  EXPECT_THROW(io::read_point_cloud(data_file("las/conformance/point10.las").replace_extension(".e57")), io::FormatError);
}

TEST(BadInput, ExtraBytesDescriptorWithReservedTypeIsSkippedWithANote) {
  // A reserved data type (50) must not index past the type-size table
  // (tests/fuzz/regressions/las/extra-bytes-reserved-type.las is a fuzz_las input of it).
  auto b = slurp(data_file("las/conformance/extrabytes.las"));
  const std::string s(b.begin(), b.end());
  const std::size_t vlr = s.find("LASF_Spec");
  ASSERT_NE(vlr, std::string::npos);
  b[vlr - 2 + 54 + 2] = 50;  // data type of the first descriptor
  io::FileInfo info;
  const PointCloud pc = io::read_point_cloud(b, io::Format::las, "eb.las", {}, &info);
  EXPECT_EQ(pc.size(), 1065u);
  EXPECT_EQ(pc.scalars.size(), 9u);  // only the standard ones (5 fields, 4 flag fields)
  bool noted = false;
  for (const std::string& n : info.notes) noted |= n.find("reserved data type 50") != std::string::npos;
  EXPECT_TRUE(noted);
}

// The replay of tests/fuzz/regressions/ below runs each finding through the reader calls of the
// libFuzzer target that found it (tests/fuzz/fuzz_<format>.cpp), as far as they are reachable from
// this executable: the SQL target calls the SQLite extension's functions, which only
// rayscan_sqlite_tests loads, so regressions/sql is not replayed here.

/// fuzz_rsi.cpp's three ways of opening an input (it picks one by the input's size modulo 3; the
/// replay uses all three): 0 every check, 1 the node records without CRCs or ids (a file above
/// deep_check_bytes), 2 no record checks at all.
io::IndexOpenOptions fuzz_index_open_options(int mode) {
  io::IndexOpenOptions opt;
  if (mode == 0) opt.verify = io::IndexOpenOptions::Verify::always;
  if (mode == 1) opt.deep_check_bytes = 0;
  if (mode == 2) opt.verify = io::IndexOpenOptions::Verify::metadata_only;
  opt.check_sources = false;  // the inputs name files of the machine that built them
  return opt;
}

/// The root box fuzz_rsi.cpp queries around: the root node's bounds when they are finite, ordered
/// and under 1e12 wide, else the unit box (unverified bounds may be anything; a negative radius
/// derived from them would be the harness's error, not the library's).
AABB fuzz_query_box(const AABB& root) {
  bool sane = true;
  for (int a = 0; a < 3; ++a)
    sane = sane && std::isfinite(root.lo[a]) && std::isfinite(root.hi[a]) && root.lo[a] <= root.hi[a] &&
           root.hi[a] - root.lo[a] < 1e12;
  return sane ? root : AABB{Vec3(0.0), Vec3(1.0)};
}

/// Opens the index file `path` as fuzz_rsi.cpp does in `mode` and runs its calls: ray queries in
/// both orders, kNN, radius search, to_point_cloud, the per-slot accessors and (after an open that
/// checked the node records) the surfel set-up. Throws IndexError as the library does.
void replay_index(const fs::path& path, int mode) {
  const io::MappedIndex m = io::MappedIndex::open(path, fuzz_index_open_options(mode));
  if (m.empty()) return;
  const AABB box = fuzz_query_box(m.node_bounds(m.root()));
  const Vec3 c = (box.lo + box.hi) * 0.5;
  std::vector<Ray> rays;
  rays.emplace_back(box.lo - Vec3(1.0), (box.hi - box.lo) + Vec3(1e-3));
  rays.emplace_back(Vec3(c.x, c.y, box.hi.z + 1.0), Vec3(0.0, 0.0, -1.0));
  for (RayOrder order : {RayOrder::ray, RayOrder::sphere_hit}) {
    RayQuery q;
    q.order = order;
    q.radius = 0.05 * (box.hi.x - box.lo.x) + 1e-3;
    q.k = 8;
    (void)ray_query_batch(m, rays, q);
  }
  (void)knn(m, c, 5);
  (void)radius_search(m, c, 0.1 * (box.hi.x - box.lo.x) + 1e-3);
  const PointCloud pc = m.to_point_cloud();
  (void)m.points_per_level();
  for (std::size_t s = 0; s < m.positions().size() && s < 64; ++s) {
    (void)m.positions()[s];
    if (!m.rgb().empty()) (void)m.rgb()[s];
    (void)m.ids()[s];
  }
  if (mode != 2 && pc.size() >= 2 && pc.size() <= 4096) {
    try {
      (void)estimate_surfels_over(m, std::span<const Vec3>(pc.positions), SurfelOptions{});
    } catch (const std::runtime_error& e) {
      if (std::string(e.what()).find("surfels:") == std::string::npos) throw;
    }
  }
}

/// fuzz_copc.cpp's calls on a COPC file: its info VLR and hierarchy, the z layer of its records,
/// then the file opened in place and walked (at most 4096 nodes, every slot's position), the first
/// and last point's positions and one ray query. Throws FormatError as the library does.
void replay_copc(const fs::path& path) {
  const std::vector<std::uint8_t> b = slurp(path);
  const std::string name = path.filename().string();
  (void)io::read_copc_info(b, name);
  (void)io::read_las_records(b, name, io::las_layers::z);
  io::CopcIndex idx(path, std::size_t{64} << 20);
  if (idx.empty()) return;
  std::vector<io::CopcIndex::Node> todo{idx.root()};
  for (std::size_t seen = 0; !todo.empty() && seen < 4096; ++seen) {
    const io::CopcIndex::Node n = todo.back();
    todo.pop_back();
    const SlotRange s = idx.node_points(n);
    for (std::uint32_t k = s.begin; k < s.end; ++k) (void)idx.positions()[k];
    for (unsigned c = 0; c < idx.child_count(n); ++c) todo.push_back(idx.child(n, c));
  }
  const std::uint64_t count = idx.info().point_count;
  (void)idx.position_of(0);
  (void)idx.position_of(static_cast<PointIndex>(count - 1));
  const AABB box = idx.node_bounds(idx.root());
  std::vector<RayHit> hits;
  RayQuery q;
  q.k = 4;
  q.radius = box.max_extent() / 16 + 1e-9;
  ray_query(idx, Ray(box.lo - Vec3(1.0), Vec3(1.0, 1.0, 1.0)), q, hits);
}

/// Runs `call` on the regression input `file`: it must return, or throw `Refusal`, the project's
/// error for bad input of that kind (FormatError; IndexError for an index file), naming the input.
/// Any other exception fails the test with the file's name.
template <class Refusal>
void reads_or_fails_cleanly(const std::string& file, const std::function<void()>& call) {
  try {
    call();
  } catch (const Refusal& e) {
    EXPECT_NE(std::string(e.what()).find(file), std::string::npos) << e.what();
    // A finding refused for its format version no longer reaches what it was kept for (it must
    // be made again on a file of the current version).
    EXPECT_EQ(std::string(e.what()).find("index format version"), std::string::npos) << e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << file << ": not the reader's error for bad input: " << e.what();
  }
}

TEST(BadInput, CheckedInFuzzerFindingsReadOrFailCleanly) {
  const fs::path root(RAYSCAN_FUZZ_REGRESSIONS);
  const std::map<std::string, std::function<void(const fs::path&, const std::string&)>> replays = {
      {"las", [](const fs::path& p, const std::string& n) { io::read_point_cloud(slurp(p), io::Format::las, n).validate(); }},
      {"ply", [](const fs::path& p, const std::string& n) { io::read_point_cloud(slurp(p), io::Format::ply, n).validate(); }},
      {"pcd", [](const fs::path& p, const std::string& n) { io::read_point_cloud(slurp(p), io::Format::pcd, n).validate(); }},
      {"text", [](const fs::path& p, const std::string& n) { io::read_point_cloud(slurp(p), io::Format::text, n).validate(); }},
      {"laz",  // fuzz_laz.cpp's reader call, then the whole cloud as read_point_cloud decodes it
       [](const fs::path& p, const std::string& n) {
         const std::vector<std::uint8_t> b = slurp(p);
         (void)io::read_las_records(b, n);
         io::read_point_cloud(b, io::Format::las, n).validate();
       }},
      {"copc", [](const fs::path& p, const std::string&) { replay_copc(p); }},
  };
  const std::set<std::string> not_here = {"sql"};  // see the note above fuzz_index_open_options
  std::map<std::string, std::size_t> replayed;
  for (const auto& dir : fs::directory_iterator(root)) {
    const std::string format = dir.path().filename().string();
    if (not_here.count(format) != 0 || fs::is_empty(dir.path())) continue;
    // Every folder of findings is replayed: one with no entry here fails until it has one.
    EXPECT_TRUE(replays.count(format) != 0 || format == "rsi") << "tests/fuzz/regressions/" << format << " is not replayed";
    for (const auto& de : fs::directory_iterator(dir.path())) {
      const std::string name = de.path().filename().string();
      SCOPED_TRACE(format + "/" + name);
      ++replayed[format];
      if (format != "rsi") {
        if (replays.count(format) != 0) reads_or_fails_cleanly<io::FormatError>(name, [&] { replays.at(format)(de.path(), name); });
        continue;
      }
      // fuzz_rsi.cpp recomputes the checksums of an input unless its size is 15 modulo 16.
      std::vector<std::uint8_t> b = slurp(de.path());
      if (b.size() % 16 != 15) fix_index_crcs(b);
      const fs::path copy = temp_dir() / (name + ".rsi");
      {
        std::ofstream out(copy, std::ios::binary | std::ios::trunc);
        out.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
        ASSERT_TRUE(out.good()) << copy;
      }
      for (int mode = 0; mode < 3; ++mode) {
        SCOPED_TRACE("open mode " + std::to_string(mode));
        reads_or_fails_cleanly<io::IndexError>(name, [&] { replay_index(copy, mode); });
      }
    }
  }
  for (const char* format : {"las", "ply", "pcd", "text", "laz", "copc", "rsi"})
    EXPECT_GE(replayed[format], 1u) << "no finding replayed from tests/fuzz/regressions/" << format;
}

// The finding rsi-crash-6b17b69c... is an index whose root node record holds finite bounds that are
// reversed on every axis and up to 6e19, from which fuzz_rsi.cpp would derive a negative query
// radius (ray_query_batch's OptionError, out of the harness). The root's box is checked at every
// open (docs/index-format.md, "Opening and validation" 1), so each of the harness's open modes
// refuses the file naming the record's byte (fuzz_query_box stays as a guard for boxes that are
// valid but too wide to query around).
TEST(BadInput, IndexFindingWithReversedRootBoundsIsRefusedAtOpen) {
  const fs::path p = fs::path(RAYSCAN_FUZZ_REGRESSIONS) / "rsi" / "rsi-crash-6b17b69c28ea146fa82667e447263d19a461a135";
  std::vector<std::uint8_t> b = slurp(p);
  ASSERT_FALSE(b.empty()) << p;
  ASSERT_NE(b.size() % 16, 15u);  // so the fuzz target recomputes its checksums, as done here
  fix_index_crcs(b);
  EXPECT_TRUE(b == slurp(p)) << "the file is stored with its checksums right";
  ASSERT_GT(load_at<float>(b, 12288), load_at<float>(b, 12288 + 12));  // the root record's lo.x > hi.x
  for (int mode = 0; mode < 3; ++mode) {
    SCOPED_TRACE("open mode " + std::to_string(mode));
    try {
      (void)io::MappedIndex::open(p, fuzz_index_open_options(mode));
      ADD_FAILURE() << "opened";
    } catch (const io::IndexError& e) {
      const std::string m = e.what();
      EXPECT_EQ(m.find(p.string() + ": byte 12288: node 0 (the root): box of axis 0 ["), 0u) << m;
      EXPECT_NE(m.find("(expected minimum <= maximum)"), std::string::npos) << m;
    }
  }
}

/// Deterministic mutation sweep over real files of every format: truncations and byte flips must
/// either read or raise FormatError (the libFuzzer targets in tests/fuzz do this at scale).
TEST(BadInput, TruncatedAndCorruptedRealFilesNeverCrash) {
  const std::pair<const char*, io::Format> files[] = {
      {"las/conformance/point-color-time.las", io::Format::las}, {"las/conformance/extrabytes.las", io::Format::las},
      {"las/conformance/1_4_w_evlr.las", io::Format::las},       {"ply/conformance/cube_binary.ply", io::Format::ply},
      {"ply/conformance/text_extradim.ply", io::Format::ply},    {"pcd/milk.pcd", io::Format::pcd},
      {"pcd/cloud_bin_0.pcd", io::Format::pcd},                  {"pcd/lamppost.pcd", io::Format::pcd}};
  std::mt19937_64 rng(20240601);
  int errors = 0, reads = 0;
  for (const auto& [rel, fmt] : files) {
    const auto orig = slurp(data_file(rel));
    ASSERT_FALSE(orig.empty()) << rel;
    for (int t = 0; t < 60; ++t) {
      auto b = orig;
      if (t % 2 == 0) {
        b.resize(std::uniform_int_distribution<std::size_t>(0, b.size() - 1)(rng));
      } else {
        const std::size_t limit = std::min<std::size_t>(b.size(), 600);  // mostly headers
        for (int k = 0; k < 4; ++k)
          b[std::uniform_int_distribution<std::size_t>(0, limit - 1)(rng)] =
              static_cast<std::uint8_t>(std::uniform_int_distribution<int>(0, 255)(rng));
      }
      try {
        const PointCloud pc = io::read_point_cloud(b, fmt, "mutant");
        pc.validate();
        ++reads;
      } catch (const io::FormatError&) {
        ++errors;
      }
    }
  }
  EXPECT_GT(errors, 100);  // truncation must be detected in almost every case
}

}  // namespace
}  // namespace rayscan::test
