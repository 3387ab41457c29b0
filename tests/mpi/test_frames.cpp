// The frames job (rayscan render --frames) in one process. Oracle: run_render
// of each camera alone; the camera list reader against hand-written files.
#include "../common/temp_dir.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/jobs/render.hpp"
#include "rayscan/base/work_distributor.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <cstring>
#include <fstream>

using namespace rayscan;
using namespace rayscan::render;
using namespace rayscan::jobs;
namespace fs = std::filesystem;

namespace {

const PointCloud& autzen() {
  static const PointCloud pc = io::read_point_cloud(fs::path(RAYSCAN_TEST_DATA) / "las" / "autzen_trim.las");
  return pc;
}

Camera view(double dx, std::uint32_t w, std::uint32_t h) {
  LookAtParams la;
  la.position = Vec3(636300.0 + dx, 848450.0, 1050.0);
  la.look_at = Vec3(636600.0, 849230.0, 420.0);
  return Camera::look_at(la, w, h);
}

template <class T>
bool same_bytes(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0;
}

TEST(Frames, EachFrameEqualsARenderOfItsCameraAlone) {
  RenderJobOptions o;
  o.cloud = &autzen();
  o.write = false;
  o.scene.radius = 1.5;
  o.scene.spp = 2;
  o.scene.seed = 5;
  o.scene.max_depth = 2;
  o.scene.output.aovs = {Aov::index, Aov::depth};
  const std::vector<Camera> cams = {view(0, 24, 16), view(150, 20, 12), view(300, 24, 16)};
  const RenderFramesResult fr = run_render_frames(o, cams);
  ASSERT_EQ(fr.frames, 3u);
  ASSERT_EQ(fr.images.size(), 3u);
  std::uint64_t queries = 0;
  for (std::size_t f = 0; f < cams.size(); ++f) {
    RenderJobOptions one = o;
    one.scene.camera = cams[f];
    const RenderJobResult r = run_render(one);
    queries += r.stats.queries;
    EXPECT_EQ(fr.images[f].width, cams[f].width());
    EXPECT_TRUE(same_bytes(fr.images[f].beauty, r.image.beauty)) << "frame " << f;
    EXPECT_TRUE(same_bytes(fr.images[f].index, r.image.index)) << "frame " << f;
    EXPECT_TRUE(same_bytes(fr.images[f].depth, r.image.depth)) << "frame " << f;
  }
  EXPECT_EQ(fr.job.stats.queries, queries);
}

TEST(Frames, TilesPackAndUnpackToTheSameFramebuffer) {
  RenderJobOptions o;
  o.cloud = &autzen();
  o.write = false;
  o.scene.radius = 1.5;
  o.scene.spp = 1;
  o.scene.camera = view(0, 37, 21);  // tiles of 16 that do not divide the image
  o.scene.output.aovs = {Aov::index, Aov::normal, Aov::cost};
  const RenderJobResult r = run_render(o);
  Framebuffer src = r.image;
  Framebuffer dst = empty_framebuffer(*o.scene.camera, o.scene.output.aovs);
  const std::uint64_t tiles = 3 * 2;
  for (std::uint64_t t = 0; t < tiles; t += 2) unpack_tiles(dst, 16, t, 2, pack_tiles(src, 16, t, 2));
  EXPECT_TRUE(same_bytes(dst.beauty, src.beauty));
  EXPECT_TRUE(same_bytes(dst.index, src.index));
  EXPECT_TRUE(same_bytes(dst.normal, src.normal));
  EXPECT_TRUE(same_bytes(dst.cost, src.cost));
  // 37 x 21 px x (12 beauty + 4 index + 12 normal + 4 cost) bytes.
  EXPECT_EQ(pack_tiles(src, 16, 0, tiles).size(), std::size_t(37) * 21 * 32);
  std::vector<std::byte> bad = pack_tiles(src, 16, 0, 1);
  bad.pop_back();
  EXPECT_THROW(unpack_tiles(dst, 16, 0, 1, bad), std::runtime_error);
}

TEST(Frames, CameraListReaderAndFrameNames) {
  const fs::path d = rayscan::test::process_temp_dir("rayscan_frames");
  std::ofstream(d / "c1.json") << R"({"width": 8, "height": 6, "position": [0, -10, 2], "look_at": [0, 0, 0]})";
  std::ofstream(d / "list.json") << R"({"cameras": ["c1.json", {"width": 4, "height": 2, "position": [1, -10, 2], "look_at": [0, 0, 0]}]})";
  const std::vector<Camera> cams = load_camera_list(d / "list.json");
  ASSERT_EQ(cams.size(), 2u);
  EXPECT_EQ(cams[0].width(), 8u);
  EXPECT_EQ(cams[1].height(), 2u);
  std::ofstream(d / "bad.json") << R"([{"width": 4, "height": 2, "position": [1, -10, 2], "look_at": [0, 0, 0]}, 3])";
  try {
    load_camera_list(d / "bad.json");
    ADD_FAILURE() << "no error";
  } catch (const SceneError& e) {
    EXPECT_EQ(std::string(e.what()), (d / "bad.json").string() + ": /1: expected a camera object or a camera file name");
  }
  std::ofstream(d / "empty.json") << "[]";
  EXPECT_THROW(load_camera_list(d / "empty.json"), SceneError);
  EXPECT_EQ(frame_file_name("out/fly.png", 7), fs::path("out/fly_0007.png"));
  EXPECT_EQ(frame_file_name("fly.exr", 12345), fs::path("fly_12345.exr"));
  fs::remove_all(d);
}

}  // namespace
