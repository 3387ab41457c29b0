// Hardening: the input policy (regular files only, no blocking open, size cap), the output
// policy (no replacing special files, all-or-nothing multi-file outputs), the reader fixes built
// from hostile-input reproducers, and derived LAS / PLY files that keep every source field,
// checked against the files' own bytes.
#include "io_test_util.hpp"

#include "rayscan/base/atomic_file.hpp"
#include "rayscan/base/input_file.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <fstream>

namespace rayscan::test {
namespace {

fs::path scratch() { return process_temp_dir("rayscan_hardening"); }

void write_text(const fs::path& p, const std::string& s) { std::ofstream(p, std::ios::binary) << s; }
std::string read_text(const fs::path& p) {
  const auto b = slurp(p);
  return {b.begin(), b.end()};
}

// ---- Input policy.

TEST(InputPolicy, FifoIsRefusedWithoutBlocking) {
  const fs::path f = scratch() / "f.pcd";
  fs::remove(f);
  ASSERT_EQ(::mkfifo(f.c_str(), 0600), 0);
  // A blocking open would hang here forever (no writer): the policy opens with O_NONBLOCK.
  try {
    (void)read_text_file(f);
    ADD_FAILURE() << "a FIFO was read";
  } catch (const InputFileError& e) {
    EXPECT_NE(std::string(e.what()).find("f.pcd: is a FIFO"), std::string::npos) << e.what();
  }
  try {
    (void)io::read_point_cloud(f);
    ADD_FAILURE() << "a FIFO was read";
  } catch (const io::FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("is a FIFO"), std::string::npos) << e.what();
  }
  fs::remove(f);
}

TEST(InputPolicy, DevZeroAndSymlinksToItAreRefused) {
  EXPECT_THROW((void)read_text_file("/dev/zero"), InputFileError);
  const fs::path link = scratch() / "observers.csv";
  fs::remove(link);
  fs::create_symlink("/dev/zero", link);
  try {
    (void)read_text_file(link);
    ADD_FAILURE() << "a symlink to /dev/zero was read";
  } catch (const InputFileError& e) {
    EXPECT_NE(std::string(e.what()).find("observers.csv: is a character device"), std::string::npos) << e.what();
  }
  EXPECT_THROW(require_regular_file(link), InputFileError);
  EXPECT_THROW(require_regular_file(scratch()), InputFileError);  // a directory
}

TEST(InputPolicy, TextCapIsEnforcedFromTheFileSize) {
  const fs::path f = scratch() / "big.json";
  write_text(f, std::string(101, ' '));
  EXPECT_EQ(read_text_file(f, 101).size(), 101u);
  try {
    (void)read_text_file(f, 100);
    ADD_FAILURE() << "the cap was not applied";
  } catch (const InputFileError& e) {
    EXPECT_NE(std::string(e.what()).find("file is 101 bytes, over the 100-byte limit"), std::string::npos) << e.what();
  }
}

TEST(InputPolicy, OneLineEscapesControlCharacters) {
  EXPECT_EQ(one_line("a\nb\tc\x1b"), "a\\nb\\tc\\x1b");
}

// ---- Output policy (item 4).

TEST(OutputPolicy, SpecialFilesAndSymlinksAreNeverReplaced) {
  const fs::path d = scratch();
  const fs::path fifo = d / "out_fifo.las", link = d / "out_link.las", target = d / "target.las";
  fs::remove(fifo);
  fs::remove(link);
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  write_text(target, "old");
  fs::create_symlink(target, link);
  PointCloud pc;
  pc.positions = {Vec3(0, 0, 0), Vec3(1, 2, 3)};
  EXPECT_THROW(io::write_las(fifo, pc), OutputFileError);
  EXPECT_THROW(io::write_las(link, pc), OutputFileError);
  EXPECT_THROW(io::write_ply("/dev/null", pc), OutputFileError);
  EXPECT_THROW(io::write_ply(d, pc), OutputFileError);  // a directory
  struct stat st {};
  ASSERT_EQ(::lstat(fifo.c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode));
  ASSERT_EQ(::lstat(link.c_str(), &st), 0);
  EXPECT_TRUE(S_ISLNK(st.st_mode));
  EXPECT_EQ(read_text(target), "old");
  ASSERT_EQ(::lstat("/dev/null", &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode));
  fs::remove(fifo);
  fs::remove(link);
}

TEST(OutputPolicy, TransactionIsAllOrNothing) {
  const fs::path d = scratch();
  const fs::path a = d / "a.las", b = d / "b.ply";
  write_text(a, "old a");
  write_text(b, "old b");
  PointCloud pc;
  pc.positions = {Vec3(0, 0, 0), Vec3(1, 2, 3)};
  {
    OutputTransaction tx;
    io::write_las(a, pc);  // finished, but not yet in place
    EXPECT_EQ(read_text(a), "old a");
    // A later failure (here: the second output's path is a directory) abandons the transaction.
    EXPECT_THROW(io::write_ply(d, pc), OutputFileError);
  }
  EXPECT_EQ(read_text(a), "old a");
  EXPECT_EQ(read_text(b), "old b");
  for (const auto& e : fs::directory_iterator(d))
    EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << e.path();
  {
    OutputTransaction tx;
    io::write_las(a, pc);
    io::write_ply(b, pc);
    tx.commit();
  }
  EXPECT_EQ(io::read_point_cloud(a).size(), 2u);
  EXPECT_EQ(io::read_point_cloud(b).size(), 2u);
}

// ---- Reader reproducers (items 2 and 5).

std::string error_of(const std::string& s, io::Format f, const std::string& name) {
  try {
    io::read_point_cloud(std::span(reinterpret_cast<const std::uint8_t*>(s.data()), s.size()), f, name);
  } catch (const io::FormatError& e) {
    return e.what();
  }
  return "";
}

TEST(ReaderReproducers, PlyHugeElementCountWithoutPropertiesReturnsAtOnce) {
  // A 130-byte reproducer: skipping 2^40 empty items took about an hour.
  const std::string ply =
      "ply\nformat ascii 1.0\nelement face 1099511627776\nelement vertex 1\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n1 2 3\n";
  const PointCloud pc = io::read_point_cloud(std::span(reinterpret_cast<const std::uint8_t*>(ply.data()), ply.size()),
                                             io::Format::ply, "a.ply");
  ASSERT_EQ(pc.size(), 1u);
  EXPECT_EQ(pc.positions[0], Vec3(1, 2, 3));
  const std::string big =
      "ply\nformat ascii 1.0\nelement face 9223372036854775807\nproperty uchar a\nelement vertex 1\n"
      "property float x\nproperty float y\nproperty float z\nend_header\n1\n1 2 3\n";
  const std::string e = error_of(big, io::Format::ply, "b.ply");
  EXPECT_EQ(e.rfind("b.ply: line ", 0), 0u) << e;
  EXPECT_NE(e.find("announces 9223372036854775807 items"), std::string::npos) << e;
}

TEST(ReaderReproducers, PcdAsciiOverflowIsAnErrorNotZero) {
  const std::string head =
      "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n";
  const std::string e = error_of(head + "1e400 2 3\n", io::Format::pcd, "o.pcd");
  EXPECT_EQ(e.rfind("o.pcd: line 10: ", 0), 0u) << e;
  EXPECT_NE(e.find("'1e400' is out of the range of a double"), std::string::npos) << e;
  // Underflow is not an error: 1e-400 reads as zero, the nearest double.
  const std::string ok = head + "1e-400 2 3\n";
  const PointCloud pc =
      io::read_point_cloud(std::span(reinterpret_cast<const std::uint8_t*>(ok.data()), ok.size()), io::Format::pcd, "u.pcd");
  EXPECT_EQ(pc.positions.at(0).x, 0.0);
}

// ---- Derived LAS files keep every source field (item 10), checked against the bytes.

/// The raw fields of one point record (LAS 1.4 R15 tables 7-17).
struct RawPoint {
  std::int32_t xyz[3];
  std::uint16_t intensity;
  int ret, nret, cls, flags, channel, dir, edge;
  double angle_deg;
  int user, psid;
  double gps;
  std::uint16_t rgb[3];
};
struct RawLas {
  int pdrf = 0, rec_len = 0;
  std::vector<std::uint8_t> bytes;
  std::uint32_t offset = 0;
  std::uint64_t count = 0;
  RawPoint at(std::size_t i) const {
    const std::uint8_t* r = bytes.data() + offset + i * rec_len;
    RawPoint p{};
    std::memcpy(p.xyz, r, 12);
    std::memcpy(&p.intensity, r + 12, 2);
    const bool legacy = pdrf < 6;
    if (legacy) {
      p.ret = r[14] & 7, p.nret = (r[14] >> 3) & 7, p.dir = (r[14] >> 6) & 1, p.edge = r[14] >> 7;
      p.cls = r[15] & 31, p.flags = r[15] >> 5, p.channel = 0;
      p.angle_deg = static_cast<std::int8_t>(r[16]);
      p.user = r[17];
      p.psid = r[18] | (r[19] << 8);
    } else {
      p.ret = r[14] & 15, p.nret = r[14] >> 4;
      p.flags = r[15] & 15, p.channel = (r[15] >> 4) & 3, p.dir = (r[15] >> 6) & 1, p.edge = r[15] >> 7;
      p.cls = r[16];
      p.user = r[17];
      std::int16_t a;
      std::memcpy(&a, r + 18, 2);
      p.angle_deg = a * 0.006;
      p.psid = r[20] | (r[21] << 8);
    }
    const int gps_off = legacy ? 20 : 22;
    if (pdrf != 0 && pdrf != 2) std::memcpy(&p.gps, r + gps_off, 8);
    const int rgb_off = pdrf == 2 ? 20 : (pdrf == 3 || pdrf == 5) ? 28 : (pdrf >= 7 ? 30 : -1);
    if (rgb_off >= 0) std::memcpy(p.rgb, r + rgb_off, 6);
    return p;
  }
};
RawLas raw_las(const fs::path& p) {
  RawLas l;
  l.bytes = slurp(p);
  l.pdrf = l.bytes[104] & 63;
  l.rec_len = l.bytes[105] | (l.bytes[106] << 8);
  std::memcpy(&l.offset, &l.bytes[96], 4);
  std::uint32_t c32;
  std::memcpy(&c32, &l.bytes[107], 4);
  l.count = c32;
  if (l.bytes[25] >= 4) {
    std::uint64_t c64;
    std::memcpy(&c64, &l.bytes[247], 8);
    if (c64 != 0) l.count = c64;
  }
  return l;
}

void expect_derived_las_keeps_fields(const std::string& rel) {
  const fs::path src = data_file(rel);
  if (src.empty()) GTEST_SKIP() << rel << " absent";
  io::FileInfo info;
  PointCloud pc = io::read_point_cloud(src, {}, &info);
  std::vector<double> added(pc.size());
  for (std::size_t i = 0; i < added.size(); ++i) added[i] = double(i % 7);
  pc.scalars.push_back({"visible_count", added});
  io::LasWriteOptions lo;
  lo.scale = *info.scale;
  lo.offset = *info.offset;
  lo.has_offset = true;
  const fs::path out = scratch() / (fs::path(rel).stem().string() + "_derived.las");
  io::write_las(out, pc, lo);
  const RawLas a = raw_las(src), b = raw_las(out);
  ASSERT_EQ(a.count, b.count);
  const bool has_rgb = a.pdrf == 2 || a.pdrf == 3 || a.pdrf == 5 || a.pdrf >= 7;
  std::size_t bad = 0;
  for (std::size_t i = 0; i < a.count && bad < 5; ++i) {
    const RawPoint p = a.at(i), q = b.at(i);
    const bool same = std::memcmp(p.xyz, q.xyz, 12) == 0 && p.intensity == q.intensity && p.ret == q.ret &&
                      p.nret == q.nret && p.cls == q.cls && p.flags == q.flags && p.channel == q.channel &&
                      p.dir == q.dir && p.edge == q.edge && std::abs(p.angle_deg - q.angle_deg) <= 0.0031 &&
                      p.user == q.user && p.psid == q.psid && std::memcmp(&p.gps, &q.gps, 8) == 0 &&
                      (!has_rgb || std::memcmp(p.rgb, q.rgb, 6) == 0);
    if (!same) {
      ++bad;
      ADD_FAILURE() << rel << " point " << i << ": source rgb " << p.rgb[0] << "," << p.rgb[1] << "," << p.rgb[2]
                    << " derived " << q.rgb[0] << "," << q.rgb[1] << "," << q.rgb[2] << "; cls " << p.cls << "/"
                    << q.cls << " flags " << p.flags << "/" << q.flags << " angle " << p.angle_deg << "/"
                    << q.angle_deg << " dir " << p.dir << "/" << q.dir << " edge " << p.edge << "/" << q.edge;
    }
  }
  // The new field and every source scalar (extra bytes included) read back with their values.
  const PointCloud back = io::read_point_cloud(out);
  for (const ScalarField& f : pc.scalars) {
    const ScalarField* g = back.scalar(f.name);
    ASSERT_NE(g, nullptr) << f.name;
    if (f.name == "scan_angle") continue;  // compared above in the file's own units
    EXPECT_EQ(g->values, f.values) << f.name;
  }
}

TEST(DerivedLas, KeepsEveryFieldOf8BitColourPdrf3Source) { expect_derived_las_keeps_fields("las/autzen_trim.las"); }
TEST(DerivedLas, KeepsEveryFieldOfPdrf7Source) { expect_derived_las_keeps_fields("las/autzen_trim_7.las"); }
TEST(DerivedLas, KeepsExtraBytes) { expect_derived_las_keeps_fields("las/extrabytes.las"); }
TEST(DerivedLas, KeepsFlagsOfPdrf4Source) { expect_derived_las_keeps_fields("las/simple1_3.las"); }

// ---- PLY property names (item 9): the convention of docs/formats.md, and a round trip.

TEST(PlyNames, ScalarPrefixAndLoadableTypes) {
  PointCloud pc;
  pc.positions = {Vec3(1, 2, 3), Vec3(4, 5, 6)};
  pc.intensity = {1000, 65535};
  pc.classification = {2, 6};
  pc.gps_time = {123456.25, 123457.5};
  pc.rgb = {Rgb16{257 * 10, 257 * 20, 257 * 30}, Rgb16{0, 65535, 257}};
  pc.scalars.push_back({"visible_count", {3, 0}});
  const fs::path out = scratch() / "names.ply";
  io::write_ply(out, pc);
  const std::string text = read_text(out);
  const std::string header = text.substr(0, text.find("end_header"));
  for (const char* p : {"property double x\n", "property uchar red\n", "property float scalar_intensity\n",
                        "property uchar scalar_classification\n", "property double scalar_gps_time\n",
                        "property double scalar_visible_count\n"})
    EXPECT_NE(header.find(p), std::string::npos) << p << " missing in\n" << header;
  for (const char* t : {" ushort ", " short ", " uint ", " int "}) EXPECT_EQ(header.find(t), std::string::npos) << t;
  const PointCloud back = io::read_point_cloud(out);
  EXPECT_EQ(back.intensity, pc.intensity);
  EXPECT_EQ(back.classification, pc.classification);
  EXPECT_EQ(back.gps_time, pc.gps_time);
  ASSERT_NE(back.scalar("visible_count"), nullptr);
  EXPECT_EQ(back.scalar("visible_count")->values, pc.scalars[0].values);
}

}  // namespace
}  // namespace rayscan::test
