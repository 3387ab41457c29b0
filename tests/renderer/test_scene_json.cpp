// Scene::to_json and io::camera_to_json are the inverses of the parsers: a written scene or camera
// reads back to the same rays bit for bit (every scene in scenes/, every camera model, resized
// ones included); Camera::resized equals the camera built at that size; fit_image_size is the one
// keep-aspect rule; the quick look's printed scene states the camera it renders; and a scene given
// as text, or points given in memory, resolve as their files do.
#include "rayscan/base/option_error.hpp"
#include "rayscan/camera/camera_file.hpp"
#include "rayscan/io/point_io.hpp"
#include "rayscan/jobs/quick_look.hpp"
#include "rayscan/render/scene.hpp"
#include "rayscan/render/scene_json.hpp"

#include "../common/temp_dir.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>

namespace fs = std::filesystem;
using namespace rayscan;
using namespace rayscan::render;

namespace {

// The rays of pixel corners, centres and the image centre, with two lens samples, equal bit for bit.
void expect_same_rays(const Camera& a, const Camera& b) {
  ASSERT_EQ(a.width(), b.width());
  ASSERT_EQ(a.height(), b.height());
  const double w = a.width(), h = a.height();
  for (double u : {-0.5, 0.0, 0.5 * (w - 1.0), w - 1.0, w - 0.5})
    for (double v : {-0.5, 0.0, 0.5 * (h - 1.0), h - 1.0, h - 0.5})
      for (auto [lu, lv] : {std::pair{0.5, 0.5}, std::pair{0.1, 0.9}}) {
        const Ray ra = a.generate_ray(u, v, lu, lv), rb = b.generate_ray(u, v, lu, lv);
        EXPECT_EQ(ra.origin(), rb.origin()) << u << "," << v;
        EXPECT_EQ(ra.direction(), rb.direction()) << u << "," << v;
      }
}

Camera written_and_read(const Camera& c) {
  return io::parse_camera(nlohmann::json::parse(io::camera_to_json(c).dump()), "(test)", "");
}

std::vector<Camera> one_of_each_model() {
  const LookAtParams la{Vec3(0.1, -3.7, 2.2), Vec3(1.0 / 3.0, 2.0 / 7.0, 0.3), Vec3(0, 0, 1), 37.3, 0.05, 4.2};
  const double c = std::cos(0.3), s = std::sin(0.3);
  PinholeParams ph;
  ph.K = {{{812.3, 0.0, 401.7}, {0.0, 799.1, 300.2}, {0.0, 0.0, 1.0}}};
  ph.R = {{{c, -s, 0.0}, {s, c, 0.0}, {0.0, 0.0, 1.0}}};
  ph.t = Vec3(0.3, -1.0 / 7.0, 5.5);
  return {Camera::look_at(la, 123, 77),
          Camera::pinhole(ph, 800, 600),
          Camera::pinhole_distorted(ph, LensDistortion{0.1, -0.05, 0.001, 0.002, 0.01}, 800, 600),
          Camera::orthographic({Vec3(10, 20, 100), Vec3(10.5, 20, 0), Vec3(0, 1, 0), 50.0 / 3.0}, 200, 100),
          Camera::equirectangular({Vec3(1, 2, 3), Vec3(1.1, 3.0 / 7.0, 3.2), Vec3(0, 0, 1)}, 360, 180)};
}

}  // namespace

TEST(CameraFile, EveryModelWritesBackBitForBit) {
  for (const Camera& c : one_of_each_model()) {
    SCOPED_TRACE(io::camera_to_json(c).dump());
    expect_same_rays(c, written_and_read(c));
    const Camera r = c.resized(61, 45);  // another aspect ratio
    expect_same_rays(r, written_and_read(r));
  }
  const Camera grid = Camera::orthographic_grid(Vec3(0), Vec3(1, 0, 0), Vec3(0, -1, 0), Vec3(0, 0, -1), 4, 4);
  EXPECT_THROW((void)io::camera_to_json(grid), std::invalid_argument);
}

TEST(Camera, ResizedIsTheCameraBuiltAtThatSize) {
  const LookAtParams la{Vec3(0.1, -3.7, 2.2), Vec3(1.0 / 3.0, 2.0 / 7.0, 0.3), Vec3(0, 0, 1), 37.3, 0.0, 0.0};
  expect_same_rays(Camera::look_at(la, 600, 400).resized(101, 67), Camera::look_at(la, 101, 67));
  const OrthographicParams op{Vec3(10, 20, 100), Vec3(10, 20, 0), Vec3(0, 1, 0), 50.0};
  expect_same_rays(Camera::orthographic(op, 200, 100).resized(31, 17), Camera::orthographic(op, 31, 17));
  // K/[R|t]: K scales per axis, so the image's outer pixel edges keep their rays.
  const std::vector<Camera> cams = one_of_each_model();
  for (const Camera* c : {&cams[1], &cams[2]}) {
    const Camera r = c->resized(300, 200);
    for (auto [u, v, u2, v2] : {std::array{-0.5, -0.5, -0.5, -0.5}, std::array{799.5, 599.5, 299.5, 199.5},
                                std::array{-0.5, 599.5, -0.5, 199.5}}) {
      const Vec3 a = c->generate_ray(u, v).direction(), b = r.generate_ray(u2, v2).direction();
      EXPECT_NEAR(glm::length(a - b), 0.0, 1e-9) << u << "," << v;
    }
  }
}

TEST(Camera, FitImageSizeKeepsTheAspectRatio) {
  const auto fit = [](ImageSize s, std::optional<std::uint32_t> w, std::optional<std::uint32_t> h) {
    const ImageSize r = fit_image_size(s, w, h);
    return std::pair{r.width, r.height};
  };
  EXPECT_EQ(fit({600, 400}, 60, std::nullopt), (std::pair{60u, 40u}));
  EXPECT_EQ(fit({600, 400}, std::nullopt, 100), (std::pair{150u, 100u}));
  EXPECT_EQ(fit({600, 400}, 101, std::nullopt), (std::pair{101u, 67u}));  // 67.33 rounds to 67
  EXPECT_EQ(fit({600, 400}, 50, 50), (std::pair{50u, 50u}));
  EXPECT_EQ(fit({600, 400}, std::nullopt, std::nullopt), (std::pair{600u, 400u}));
  try {
    (void)fit_image_size({1, 65536}, 65536, std::nullopt);
    FAIL() << "expected OptionError";
  } catch (const OptionError& e) {
    EXPECT_STREQ(e.what(), "the camera's aspect ratio 1:65536 gives an image height of 4294967296 pixels, "
                           "expected 1 to 65536; give both width and height");
  }
}

TEST(SceneJson, EverySceneWritesBackToTheSameScene) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(RAYSCAN_SCENES_DIR)) {
    if (e.path().extension() != ".json" || e.path().filename().string().front() == '.') continue;
    SCOPED_TRACE(e.path().string());
    const Scene s = load_scene(e.path());
    const std::string text = s.to_json();
    // Read back as a file in another folder: the paths must not depend on the scene's folder.
    const Scene r = parse_scene_json(nlohmann::json::parse(text), fs::temp_directory_path() / "elsewhere.json");
    EXPECT_EQ(r.to_json(), text);
    EXPECT_EQ(r.cloud, fs::absolute(s.cloud).lexically_normal());
    EXPECT_EQ(r.spp, s.spp);
    EXPECT_EQ(r.radius, s.radius);
    EXPECT_EQ(r.sun.direction, s.sun.direction);
    EXPECT_EQ(r.up, s.up);
    EXPECT_EQ(r.output.aovs, s.output.aovs);
    expect_same_rays(*s.camera, *r.camera);
    ++n;
  }
  EXPECT_GE(n, 5);
}

TEST(SceneJson, QuickLookPrintsTheCameraItRenders) {
  // A look-at camera file resized to another aspect ratio (101 x 67 from 600 x 400), over a scene
  // file: the printed scene must build the camera the render uses.
  const fs::path d = rayscan::test::process_temp_dir("rayscan_scene_json");
  std::ofstream(d / "cam.json") << R"({"width": 600, "height": 400, "position": [1, -8, 3.5],
    "look_at": [0.25, 0.5, 0.125], "vfov_deg": 41.5})";
  std::ofstream(d / "s.json") << R"({"cloud": "c.xyz", "camera": "cam.json", "spp": 3})";
  jobs::SceneOverrides ov;
  ov.width = 101;
  ov.aovs = {"depth"};
  const jobs::ResolvedScene rs = jobs::resolve_scene(d / "s.json", ov, [](const fs::path&) -> jobs::CloudSummary {
    throw std::logic_error("the cloud is not needed with a camera");
  });
  ASSERT_TRUE(rs.scene.camera);
  EXPECT_EQ(rs.scene.camera->width(), 101u);
  EXPECT_EQ(rs.scene.camera->height(), 67u);
  const Scene printed = parse_scene_json(nlohmann::json::parse(rs.json), d / "printed.json");
  expect_same_rays(*rs.scene.camera, *printed.camera);
  EXPECT_EQ(printed.output.aovs, std::vector<Aov>{Aov::depth});
  EXPECT_EQ(printed.spp, 3u);
  fs::remove_all(d);
}

TEST(SceneJson, TextAndPointsInMemoryResolveLikeTheirFiles) {
  // A scene given as text means what the same file in the working directory means; errors name it
  // by the name given. The quick look of points in memory is the quick look of their file.
  const fs::path d = rayscan::test::process_temp_dir("rayscan_scene_text");
  PointCloud pc;
  for (int i = 0; i < 400; ++i) pc.positions.emplace_back(i % 20, i / 20, 0.1 * (i % 7));
  io::write_point_cloud(d / "c.ply", pc);
  std::optional<PointCloud> read;
  const auto summary = [&](const fs::path& f) { return jobs::summarize_cloud_file(f, read); };
  const jobs::ResolvedScene file = jobs::resolve_scene(d / "c.ply", {}, summary);
  const jobs::ResolvedScene memory =
      jobs::resolve_quick_look(jobs::summarize_cloud(pc.positions, false, false, std::nullopt), {});
  ASSERT_TRUE(file.scene.camera && memory.scene.camera && memory.overview);
  expect_same_rays(*file.scene.camera, *memory.scene.camera);
  EXPECT_TRUE(memory.scene.cloud.empty());
  EXPECT_EQ(memory.scene.primitive, file.scene.primitive);

  const fs::path cwd = fs::current_path();
  fs::current_path(d);
  const jobs::ResolvedScene text =
      jobs::resolve_scene_text(R"({"cloud": "c.ply", "spp": 2})", "scene dict", {}, summary);
  fs::current_path(cwd);
  EXPECT_EQ(text.scene.cloud, (d / "c.ply").lexically_normal());
  EXPECT_EQ(text.scene.spp, 2u);
  EXPECT_EQ(text.scene.file, fs::path("scene dict"));
  expect_same_rays(*file.scene.camera, *text.scene.camera);  // no camera: the overview camera
  const auto message = [&](const std::string& json, bool cloud_given) {
    try {
      (void)jobs::resolve_scene_text(json, "scene dict", {}, summary, cloud_given);
    } catch (const SceneError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message(R"({"cloud": "c.ply", "camera": 5})", false),
            "scene dict: /camera: expected a camera file name or a camera object");
  EXPECT_EQ(message(R"({"spp": 1})", false).rfind("scene dict: /cloud: required", 0), 0u);
  EXPECT_EQ(message("[1]", false), "scene dict: /: expected a JSON object (a scene)");
  EXPECT_EQ(message("{", false).rfind("scene dict: byte ", 0), 0u);
  EXPECT_NE(message("{", false).find("invalid JSON"), std::string::npos);
  // With the points supplied by the caller a scene needs no "cloud".
  const jobs::ResolvedScene given = jobs::resolve_scene_text(R"({"spp": 1})", "scene dict", {},
                                                             [&](const fs::path& f) {
                                                               EXPECT_TRUE(f.empty());
                                                               return jobs::summarize_cloud_file(d / "c.ply", read);
                                                             },
                                                             true);
  EXPECT_TRUE(given.scene.cloud.empty());
  fs::remove_all(d);
}
