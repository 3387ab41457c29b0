// Scene and camera files: a valid file parses to the documented values; every malformed field is
// reported with the file and its JSON pointer.
#include "../common/temp_dir.hpp"
#include "render_test_data.hpp"
#include "rayscan/render/scene.hpp"

#include "rayscan/jobs/render.hpp"

#include "rayscan/io/point_io.hpp"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cstring>
#include <filesystem>
#include <fstream>

using namespace rayscan;
using namespace rayscan::render;
namespace fs = std::filesystem;

namespace {

fs::path scene_temp_dir() { return rayscan::test::process_temp_dir("rayscan_render_scene"); }

fs::path write(const std::string& name, const std::string& text) {
  const fs::path p = scene_temp_dir() / name;
  std::ofstream(p) << text;
  return p;
}

const char* kCam = R"("camera": {"width": 60, "height": 40, "position": [0, -10, 2], "look_at": [0, 0, 0]})";

std::string error_of(const fs::path& p) {
  try {
    load_scene(p);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST(Scene, ParsesValuesAndResolvesPathsAgainstTheSceneFolder) {
  fs::create_directories(scene_temp_dir() / "sub");
  write("sub/cam.json", R"({"width": 64, "height": 32, "position": [1, 2, 3], "look_at": [1, 3, 3], "vfov_deg": 30})");
  const fs::path p = write("sub/s.json", R"({"cloud": "../data/c.las", "radius": 0.25, "hit": "closest_point",
    "index": {"type": "octree", "layout": "layered", "capacity": 8},
    "material": {"color": [0.2, 0.3, 0.4]}, "background": {"type": "constant", "color": [1, 1, 1]},
    "sun": {"direction": [0, 0, 2], "angular_diameter_deg": 1}, "camera": "cam.json",
    "spp": 3, "max_depth": 7, "seed": 99, "output": {"image": "img.exr", "aovs": ["depth", "index"]}})");
  const Scene s = load_scene(p);
  EXPECT_EQ(s.cloud, (scene_temp_dir() / "data/c.las").lexically_normal());
  EXPECT_EQ(s.output.image, (scene_temp_dir() / "sub/img.exr").lexically_normal());
  ASSERT_TRUE(s.radius.has_value());
  EXPECT_EQ(*s.radius, 0.25);
  EXPECT_EQ(s.hit, HitMode::closest_point);
  EXPECT_EQ(s.index.type, "octree-layered");
  EXPECT_EQ(s.index.capacity, 8u);
  EXPECT_EQ(s.material.mode, ColorMode::constant);
  EXPECT_FLOAT_EQ(s.material.constant.g, 0.3f);
  EXPECT_FALSE(s.background.gradient);
  EXPECT_TRUE(s.sun.enabled);
  EXPECT_DOUBLE_EQ(s.sun.direction.z, 1.0);
  ASSERT_TRUE(s.camera.has_value());
  EXPECT_EQ(s.camera->width(), 64u);
  EXPECT_EQ(s.spp, 3u);
  EXPECT_EQ(s.max_depth, 7u);
  EXPECT_EQ(s.seed, 99u);
  ASSERT_EQ(s.output.aovs.size(), 2u);
  EXPECT_EQ(s.output.aovs[1], Aov::index);
}

TEST(Scene, DefaultsAreTheDocumentedOnes) {
  const Scene s = load_scene(write("d.json", std::string(R"({"cloud": "x.xyz", )") + kCam + "}"));
  EXPECT_FALSE(s.radius.has_value());  // "auto"
  EXPECT_EQ(s.hit, HitMode::sphere);
  EXPECT_EQ(s.index.type, "octree-adaptive");
  EXPECT_EQ(s.material.mode, ColorMode::rgb);
  EXPECT_TRUE(s.background.gradient);
  EXPECT_FALSE(s.sun.enabled);
  EXPECT_EQ(s.spp, 16u);
  EXPECT_EQ(s.max_depth, 4u);
}

TEST(Scene, BadFieldsNameFileAndJsonPointer) {
  const fs::path p1 = write("e1.json", R"({"cloud": "x.xyz", "camera": {"width": 60, "height": 40,
    "position": [0, -10, 2], "look_at": [0, 0, 0], "vfov_deg": 200}})");
  EXPECT_EQ(error_of(p1), p1.string() + ": /camera/vfov_deg: expected a number in (0, 180)");

  const fs::path p2 = write("e2.json", std::string(R"({"cloud": "x.xyz", "spp": 0, )") + kCam + "}");
  EXPECT_EQ(error_of(p2), p2.string() + ": /spp: expected an integer in [1, 1048576]");

  const fs::path p3 = write("e3.json", std::string(R"({"cloud": "x.xyz", "colour": "rgb", )") + kCam + "}");
  EXPECT_NE(error_of(p3).find(p3.string() + ": /colour: unknown key (allowed here:"), std::string::npos);

  const fs::path p4 = write("e4.json", std::string(R"({"cloud": "x.xyz", "material": {"color": "height"}, )") + kCam + "}");
  EXPECT_NE(error_of(p4).find("/material/color: expected one of \"rgb\", \"intensity\", \"elevation\", \"classification\""),
            std::string::npos);

  const fs::path p5 = write("e5.json", std::string(R"({"cloud": "x.xyz", "radius": -1, )") + kCam + "}");
  EXPECT_EQ(error_of(p5), p5.string() + ": /radius: expected a finite number > 0 (world units) or auto");

  const fs::path p6 = write("e6.json", R"({"cloud": "x.xyz"})");
  EXPECT_NE(error_of(p6).find(": /camera: required"), std::string::npos);

  const fs::path p7 = write("e7.json", R"({"cloud": "x.xyz", )");
  EXPECT_NE(error_of(p7).find(p7.string() + ": byte "), std::string::npos);

  const fs::path p8 = write("e8.json", std::string(R"({"cloud": "x.xyz", "background": {"type": "constant", "colr": [1,1,1]}, )") + kCam + "}");
  EXPECT_NE(error_of(p8).find(": /background/colr: unknown key"), std::string::npos);

  const fs::path p9 = write("e9.json", R"({"cloud": "x.xyz", "camera": {"width": 60, "height": 40,
    "K": [[100, 0, 30], [0, 100, 20], [0, 0, 1]], "R": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "t": [0, 0, "a"]}})");
  EXPECT_EQ(error_of(p9), p9.string() + ": /camera/t/2: expected an array of 3 finite numbers");

  // The index's depth range is the library's (OctreeConfig::validate, the CLI's --max-depth), named
  // by its pointer here rather than failing later inside the build.
  const fs::path p10 = write("e10.json", std::string(R"({"cloud": "x.xyz", "index": {"max_depth": 0}, )") + kCam + "}");
  EXPECT_EQ(error_of(p10), p10.string() + ": /index/max_depth: expected an integer in [1, 21]");

  EXPECT_NE(error_of(scene_temp_dir() / "missing.json").find("missing.json: cannot open file"), std::string::npos);
}

TEST(Scene, CombinationsWithoutMeaningNameTheirPointer) {
  // JPEG stores 8 bits per channel: a 16-bit depth there would be written as 8 bits.
  const fs::path j16 = write("j16.json", std::string(R"({"cloud": "x.xyz", "output": {"image": "a.jpeg", "bit_depth": 16}, )") + kCam + "}");
  EXPECT_EQ(error_of(j16), j16.string() + ": /output/bit_depth: expected 8 with a JPEG image (8 bits per channel); 16 needs a .png or .tif image");
  const Scene p16 = load_scene(write("p16.json", std::string(R"({"cloud": "x.xyz", "output": {"image": "a.png", "bit_depth": 16}, )") + kCam + "}"));
  EXPECT_EQ(p16.output.bit_depth, 16u);
  // Discs are hit exactly (first_surfel_hit): the sphere's closest-point order does not apply.
  const fs::path cs = write("cs.json", std::string(R"({"cloud": "x.xyz", "hit": "closest_point", "primitive": "surfel", )") + kCam + "}");
  EXPECT_EQ(error_of(cs), cs.string() + ": /hit: \"closest_point\" applies to primitive \"sphere\" only; primitive is \"surfel\" (discs are hit exactly)");
  EXPECT_EQ(load_scene(write("ss.json", std::string(R"({"cloud": "x.xyz", "hit": "sphere", "primitive": "surfel", )") + kCam + "}")).primitive,
            Primitive::surfel);
}

// An index key the octree's layout does not use is refused at its pointer, by the rule rayscan
// query, rayscan index and Python apply (check_applicable), instead of being read and ignored. A
// scene giving only the keys its layout uses still renders, and its image is the one another
// layout gives: the ray queries are exact, so the tree must not show. Oracle: that render, and the
// scene the parser reads back from Scene::to_json.
TEST(Scene, IndexKeysTheLayoutDoesNotUseAreRefused) {
  const std::string cloud = R"({"cloud": ")" + std::string(RAYSCAN_RENDER_TEST_DATA) + R"(/autzen_subset.xyz", )";
  auto index_scene = [&](const std::string& name, const std::string& index) {
    return write(name, cloud + R"("index": )" + index + ", " + kCam + "}");
  };
  const fs::path fc = index_scene("fc.json", R"({"type": "octree", "layout": "fixed", "capacity": 8})");
  EXPECT_EQ(error_of(fc), fc.string() + R"(: /index/capacity: applies to "layout": "adaptive" and "layered" only (got "layout": "fixed"))");
  const fs::path fm = index_scene("fm.json", R"({"type": "octree", "layout": "fixed", "depth": 3, "max_depth": 9})");
  EXPECT_EQ(error_of(fm), fm.string() + R"(: /index/max_depth: applies to "layout": "adaptive" and "layered" only (got "layout": "fixed"))");
  const fs::path ld = index_scene("ld.json", R"({"type": "octree", "layout": "layered", "depth": 3})");
  EXPECT_EQ(error_of(ld), ld.string() + R"(: /index/depth: applies to "layout": "fixed" only (got "layout": "layered"))");
  const fs::path ad = index_scene("ad.json", R"({"depth": 3})");  // the default layout
  EXPECT_EQ(error_of(ad), ad.string() + R"(: /index/depth: applies to "layout": "fixed" only (got "layout": "adaptive"))");
  // The kd-tree and brute force read no octree key: each is unknown there, as before.
  const fs::path kd = index_scene("kd.json", R"({"type": "kdtree", "depth": 3})");
  EXPECT_NE(error_of(kd).find(kd.string() + ": /index/depth: unknown key"), std::string::npos) << error_of(kd);
  const fs::path bc = index_scene("bc.json", R"({"type": "brute", "capacity": 8})");
  EXPECT_NE(error_of(bc).find(bc.string() + ": /index/capacity: unknown key"), std::string::npos) << error_of(bc);

  const Scene fixed = load_scene(index_scene("fixed.json", R"({"type": "octree", "layout": "fixed", "depth": 3, "build": "insertion"})"));
  EXPECT_EQ(fixed.index.type, "octree-fixed");
  EXPECT_EQ(fixed.index.depth, 3u);
  EXPECT_TRUE(fixed.index.insertion);
  const Scene adaptive = load_scene(index_scene("adaptive.json", R"({"type": "octree", "capacity": 8, "max_depth": 9})"));
  // The written scene gives only the keys its layout uses, so it reads back.
  for (const Scene* s : {&fixed, &adaptive}) {
    const nlohmann::json w = nlohmann::json::parse(s->to_json());
    const Scene back = load_scene(write("back.json", w.dump()));
    EXPECT_EQ(back.index.type, s->index.type);
    EXPECT_EQ(back.index.depth, s->index.depth);
    EXPECT_EQ(back.index.max_depth, s->index.max_depth);
    EXPECT_EQ(back.index.insertion, s->index.insertion);
    EXPECT_EQ(index_capacity(back.index), index_capacity(s->index));
  }
  EXPECT_FALSE(nlohmann::json::parse(fixed.to_json()).at("index").contains("capacity"));
  EXPECT_FALSE(nlohmann::json::parse(adaptive.to_json()).at("index").contains("depth"));

  jobs::RenderJobResult r[2];
  for (int k = 0; k < 2; ++k) {
    jobs::RenderJobOptions o;
    o.scene = k == 0 ? fixed : adaptive;
    o.scene.camera = rayscan::render::test::subset_scene(40, 30).camera;  // kCam does not see the cloud
    o.scene.material.mode = ColorMode::elevation;  // the subset has no colours
    o.scene.spp = 2;
    o.scene.output.aovs = {Aov::index};
    o.write = false;
    o.control.threads = 2;
    r[k] = jobs::run_render(o);
  }
  ASSERT_EQ(r[0].image.beauty.size(), r[1].image.beauty.size());
  EXPECT_EQ(std::memcmp(r[0].image.beauty.data(), r[1].image.beauty.data(), r[0].image.beauty.size() * sizeof(Color)), 0);
  EXPECT_EQ(r[0].image.index, r[1].image.index);
  std::size_t hit = 0;
  for (auto id : r[0].image.index) hit += id != kNoPoint;
  EXPECT_GT(hit, r[0].image.index.size() / 4);  // the comparison is not vacuous
}

// A key given twice in one object is refused, in every JSON input, with the pointer of the key
// (its object's pointer, then the key); nlohmann alone would keep the last one silently.
TEST(Scene, DuplicateKeysNameTheirObjectAndKey) {
  const fs::path top = write("dup_top.json", std::string(R"({"cloud": "nonexist.xyz", "cloud": "x.xyz", )") + kCam + "}");
  EXPECT_EQ(error_of(top), top.string() + ": /cloud: duplicate key (given twice in the object /; expected each key once)");
  const fs::path nested = write("dup_cam.json", R"({"cloud": "x.xyz", "camera": {"width": 60, "height": 40,
    "position": [0, -10, 2], "look_at": [0, 0, 0], "position": [9, 9, 9]}})");
  EXPECT_EQ(error_of(nested),
            nested.string() + ": /camera/position: duplicate key (given twice in the object /camera; expected each key once)");
  // RFC 6901 escaping of '/' and '~' in the key and in the path to it; an unknown key given twice
  // is reported as the duplicate it is (the parse sees it first).
  const fs::path esc = write("dup_esc.json", R"({"cloud": "x.xyz", "a/b": {"c~d": 1, "c~d": 2}})");
  EXPECT_EQ(error_of(esc), esc.string() + ": /a~1b/c~0d: duplicate key (given twice in the object /a~1b; expected each key once)");
  // The same key in different objects is no duplicate.
  EXPECT_EQ(error_of(write("same_key.json", std::string(R"({"cloud": "x.xyz", "material": {"color": [1, 1, 1]},
    "background": {"type": "constant", "color": [1, 1, 1]}, )") + kCam + "}")), "(no error)");

  // A camera file.
  const fs::path cam = write("dup_camera.json", R"({"width": 60, "height": 40, "width": 80,
    "position": [0, -10, 2], "look_at": [0, 0, 0]})");
  try {
    load_camera(cam);
    ADD_FAILURE() << "no error";
  } catch (const SceneError& e) {
    EXPECT_EQ(std::string(e.what()), cam.string() + ": /width: duplicate key (given twice in the object /; expected each key once)");
  }

  // A camera list (render --frames): the pointer counts the array's elements, nested arrays
  // included; elements with the same keys are no duplicates.
  const std::string c = R"({"width": 8, "height": 6, "position": [0, -10, 2], "look_at": [0, 0, 0]})";
  EXPECT_EQ(jobs::load_camera_list(write("list_ok.json", "[" + c + ", " + c + "]")).size(), 2u);
  const fs::path list = write("dup_list.json", R"({"cameras": [)" + c + ", " + c + R"(, {"width": 8, "height": 6,
    "position": [0, -10, 2], "look_at": [0, 0, 0], "up": [0, 0, 1], "up": [0, 1, 0]}]})");
  try {
    jobs::load_camera_list(list);
    ADD_FAILURE() << "no error";
  } catch (const SceneError& e) {
    EXPECT_EQ(std::string(e.what()),
              list.string() + ": /cameras/2/up: duplicate key (given twice in the object /cameras/2; expected each key once)");
  }
}

TEST(Scene, LookAtCameraRejectsPinholeKeys) {
  // K/R/t are pinhole keys: with an explicit look-at model they must not be silently ignored.
  const fs::path p = write("la_k.json", R"({"cloud": "x.xyz", "camera": {"model": "look_at", "width": 60,
    "height": 40, "position": [0, -10, 2], "look_at": [0, 0, 0], "K": [[100, 0, 30], [0, 100, 20], [0, 0, 1]]}})");
  const std::string e = error_of(p);
  EXPECT_EQ(e.rfind(p.string() + ": /camera/K: unknown key (allowed here:", 0), 0u) << e;
  EXPECT_EQ(e.find("K,"), std::string::npos) << e;  // K is not in the allowed list

  const fs::path pt = write("la_t.json", R"({"cloud": "x.xyz", "camera": {"model": "look_at", "width": 60,
    "height": 40, "position": [0, -10, 2], "look_at": [0, 0, 0], "t": [0, 0, 1]}})");
  EXPECT_EQ(error_of(pt).rfind(pt.string() + ": /camera/t: unknown key", 0), 0u) << error_of(pt);

  // Camera files too, with the JSON pointer from the file's root.
  const fs::path c = write("la_cam.json", R"({"model": "look_at", "width": 60, "height": 40,
    "position": [0, -10, 2], "look_at": [0, 0, 0], "R": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]})");
  try {
    load_camera(c);
    ADD_FAILURE() << "no error";
  } catch (const SceneError& err) {
    EXPECT_EQ(std::string(err.what()).rfind(c.string() + ": /R: unknown key", 0), 0u) << err.what();
  }

  // Without "model", K still selects the pinhole model; and a pinhole camera rejects look-at keys.
  const fs::path ok = write("ph.json", R"({"cloud": "x.xyz", "camera": {"width": 60, "height": 40,
    "K": [[100, 0, 30], [0, 100, 20], [0, 0, 1]], "R": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "t": [0, 0, 0]}})");
  EXPECT_EQ(error_of(ok), "(no error)");
  const fs::path pp = write("ph_pos.json", R"({"cloud": "x.xyz", "camera": {"width": 60, "height": 40,
    "K": [[100, 0, 30], [0, 100, 20], [0, 0, 1]], "R": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "t": [0, 0, 0],
    "position": [0, 0, 0]}})");
  EXPECT_EQ(error_of(pp).rfind(pp.string() + ": /camera/position: unknown key", 0), 0u) << error_of(pp);
}

TEST(Scene, ImageExtensionsAreOneList) {
  // The scene parser and `--out` share is_image_file_name(); check it against the list itself.
  for (const std::string& e : image_extensions()) {
    EXPECT_TRUE(is_image_file_name("a/b" + e)) << e;
    std::string upper;
    for (char c : e) upper += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    EXPECT_TRUE(is_image_file_name("b" + upper)) << upper;
    EXPECT_NE(image_file_name_expected().find(e), std::string::npos) << e;
  }
  for (const char* bad : {"x.bmp", "x", "x.png.txt", "x.gif", ".png/x"}) EXPECT_FALSE(is_image_file_name(bad)) << bad;
  const fs::path p = write("bmp.json", std::string(R"({"cloud": "x.xyz", "output": {"image": "o.bmp"}, )") + kCam + "}");
  EXPECT_EQ(error_of(p), p.string() + ": /output/image: " + image_file_name_expected());
}

TEST(Scene, RampAndRangeOnlyWithScalarColorModes) {
  auto scene = [](const std::string& name, const std::string& material) {
    return write(name, std::string(R"({"cloud": "x.xyz", "material": )") + material + ", " + kCam + "}");
  };
  const fs::path p1 = scene("rr1.json", R"({"color": "rgb", "ramp": "terrain"})");
  EXPECT_EQ(error_of(p1), p1.string() +
            ": /material/ramp: only used with color \"intensity\" or \"elevation\"; color is \"rgb\"");
  const fs::path p2 = scene("rr2.json", R"({"color": "classification", "range": [0, 10]})");
  EXPECT_EQ(error_of(p2), p2.string() +
            ": /material/range: only used with color \"intensity\" or \"elevation\"; color is \"classification\"");
  const fs::path p3 = scene("rr3.json", R"({"range": [0, 10]})");
  EXPECT_NE(error_of(p3).find(": /material/range: only used with"), std::string::npos) << error_of(p3);
  const fs::path p4 = scene("rr4.json", R"({"color": [0.5, 0.5, 0.5], "ramp": "grey"})");
  EXPECT_NE(error_of(p4).find(": /material/ramp: only used with"), std::string::npos) << error_of(p4);

  for (const char* mode : {"intensity", "elevation"}) {
    const Scene s = load_scene(scene(std::string("rr_ok_") + mode + ".json",
                                     std::string(R"({"color": ")") + mode + R"(", "ramp": "grey", "range": [2, 5]})"));
    EXPECT_EQ(s.material.ramp, Ramp::grey) << mode;
    ASSERT_TRUE(s.material.range.has_value()) << mode;
    EXPECT_EQ((*s.material.range)[1], 5.0) << mode;
  }
}

TEST(Scene, CloudErrorsNameTheSceneAndPointer) {
  const fs::path p = write("nocloud.json", std::string(R"({"cloud": "data/nonexist.las", )") + kCam + "}");
  const Scene s = load_scene(p);
  // Oracle: the reader's own message for the same file, prefixed with the scene context.
  std::string reader_msg;
  try {
    io::read_point_cloud(s.cloud);
  } catch (const std::exception& e) {
    reader_msg = e.what();
  }
  ASSERT_FALSE(reader_msg.empty());
  try {
    load_cloud(s);
    ADD_FAILURE() << "no error";
  } catch (const SceneError& e) {
    EXPECT_EQ(std::string(e.what()), p.string() + ": /cloud: " + reader_msg);
  }

  write("empty.xyz", "");
  const Scene se = load_scene(write("empty.json", std::string(R"({"cloud": "empty.xyz", )") + kCam + "}"));
  try {
    load_cloud(se);
    ADD_FAILURE() << "no error";
  } catch (const SceneError& e) {
    EXPECT_EQ(std::string(e.what()), se.file.string() + ": /cloud: " + se.cloud.string() + ": the point cloud has no points");
  }

  write("three.xyz", "0 0 0\n1 0 0\n0 1 0\n");
  const Scene s3 = load_scene(write("three.json", std::string(R"({"cloud": "three.xyz", )") + kCam + "}"));
  const PointCloud c = load_cloud(s3);
  ASSERT_EQ(c.size(), 3u);
  EXPECT_EQ(c.positions[1], Vec3(1, 0, 0));
}
