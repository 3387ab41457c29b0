// Links rayscan::render and rayscan::analysis from an installed package: renders an in-memory
// cloud with the render job and runs the visibility job on it. Exit 0 = the calls ran and their
// results agree with the geometry (a camera looking at a plane hits it; every point of an open
// plane sees the sky). Then writes a PNG and reads it back through rayscan::image, whose
// OpenImageIO module (librayscan_oiio.so) run_consumer.cmake points at in the installed prefix
// (RAYSCAN_OIIO_MODULE), so the installed module is the one that loads.
#include "rayscan/jobs/visibility.hpp"
#include "rayscan/image/image_file.hpp"
#include "rayscan/jobs/render.hpp"

#include <cstdio>
#include <filesystem>

int main() {
  using namespace rayscan;
  PointCloud cloud;
  for (int x = 0; x < 30; ++x)
    for (int y = 0; y < 30; ++y) cloud.positions.emplace_back(0.1 * x, 0.1 * y, 0.0);

  jobs::RenderJobOptions ro;
  ro.scene.camera = Camera::look_at({.position = {1.45, 1.45, 3.0}, .look_at = {1.45, 1.45, 0.0}, .up = {0, 1, 0}}, 16, 16);
  ro.scene.material.mode = render::ColorMode::constant;
  ro.scene.spp = 1;
  ro.scene.output.aovs = {render::Aov::index};
  ro.cloud = &cloud;
  ro.write = false;
  const jobs::RenderJobResult r = jobs::run_render(ro);
  const std::uint32_t centre = r.image.index[8 * 16 + 8];
  if (centre == kNoPoint) {
    std::fprintf(stderr, "consumer: the centre pixel misses the plane\n");
    return 1;
  }

  jobs::VisibilityJobOptions vo;
  vo.cloud = &cloud;
  vo.sky_rays = 8;
  const jobs::VisibilityJobResult v = jobs::run_visibility(vo);
  for (double s : v.sky_view)
    if (s != 1.0) {
      std::fprintf(stderr, "consumer: a point of an open plane does not see the whole sky (%g)\n", s);
      return 1;
    }
  Image img = make_image(4, 3, {"R", "G", "B"}, 0.0f);
  img.pixels[5] = 1.0f;  // pixel (1, 0), blue
  const std::filesystem::path png = std::filesystem::temp_directory_path() / "rayscan-consumer.png";
  write_image(img, png.string(), PixelFormat::uint8);
  const Image back = read_image(png.string());
  std::filesystem::remove(png);
  if (back.width != 4 || back.height != 3 || back.nchannels() != 3 || back.pixels != img.pixels) {
    std::fprintf(stderr, "consumer: the PNG read back differs from the image written\n");
    return 1;
  }
  std::printf("consumer: render radius %.4f, centre pixel hits point %u; sky view 1 for %zu points\n",
              r.radius.radius, centre, v.sky_view.size());
  return 0;
}
