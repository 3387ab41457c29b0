// `rayscan info`: the JSON agrees with the reader and the file's header; bad input gives exit
// code 2 and one line on stderr.
#include "io_test_util.hpp"

#include <nlohmann/json.hpp>

#include <cstdlib>
#include <sys/wait.h>

namespace rayscan::test {
namespace {

int run(const std::string& args, const fs::path& out, const fs::path& err) {
  const std::string cmd = std::string("'") + RAYSCAN_EXE + "' " + args + " >'" + out.string() + "' 2>'" + err.string() + "'";
  const int rc = std::system(cmd.c_str());
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

std::string text_of(const fs::path& p) {
  const auto b = slurp(p);
  return {b.begin(), b.end()};
}

TEST(InfoCli, JsonReportsFormatCountsBoundsAttributesAndCrs) {
  RAYSCAN_REQUIRE_FILE(p, "las/Haystack_Rock.las");
  const fs::path out = temp_dir() / "info.json", err = temp_dir() / "info.err";
  ASSERT_EQ(run("info --json '" + p.string() + "'", out, err), 0) << text_of(err);
  const auto j = nlohmann::json::parse(text_of(out));
  EXPECT_EQ(j["format"], "LAS");
  EXPECT_EQ(j["version"], "1.2");
  EXPECT_EQ(j["point_data_record_format"], 0);
  EXPECT_EQ(j["count"], 21932);
  EXPECT_EQ(j["crs"]["epsg"], 3645);
  EXPECT_EQ(j["crs"]["vertical_epsg"], 5703);
  EXPECT_NEAR(j["bounds"]["max"][2].get<double>(), 80.815, 1e-9);
  EXPECT_EQ(j["scale"][2], 0.001);
  bool has_intensity = false;
  for (const auto& a : j["attributes"]) has_intensity |= a["name"] == "intensity";
  EXPECT_TRUE(has_intensity);
}

TEST(InfoCli, TextReportsDroppedNanPointsAndDifferingHeaderBounds) {
  RAYSCAN_REQUIRE_FILE(pcd, "pcd/office1.pcd");
  const fs::path out = temp_dir() / "info.txt", err = temp_dir() / "info.err";
  ASSERT_EQ(run("info '" + pcd.string() + "'", out, err), 0) << text_of(err);
  const std::string t = text_of(out);
  EXPECT_NE(t.find("points:            254456 (header: 307200)"), std::string::npos) << t;
  EXPECT_NE(t.find("dropped:           52744 non-finite points"), std::string::npos) << t;
  RAYSCAN_REQUIRE_FILE(las, "las/conformance/simple1_3.las");
  ASSERT_EQ(run("info '" + las.string() + "'", out, err), 0) << text_of(err);
  EXPECT_NE(text_of(out).find("(differs)"), std::string::npos) << text_of(out);
}

TEST(InfoCli, BadFileExitsWithCode2AndOneLine) {
  const fs::path bad = temp_dir() / "bad.las";
  {
    std::ofstream o(bad, std::ios::binary);
    o << "LASF" << std::string(300, '\0');
  }
  const fs::path out = temp_dir() / "o", err = temp_dir() / "e";
  EXPECT_EQ(run("info '" + bad.string() + "'", out, err), 2);
  const std::string e = text_of(err);
  EXPECT_EQ(e.rfind("rayscan info: " + bad.string() + ": byte ", 0), 0u) << e;
  EXPECT_EQ(std::count(e.begin(), e.end(), '\n'), 1) << e;
  EXPECT_EQ(run("info /nonexistent.las", out, err), 2);
}

}  // namespace
}  // namespace rayscan::test
