// Writing a render (Framebuffer) and its AOVs: the framebuffer becomes rayscan::Image values that
// the one image writer (rayscan/image/image_file.hpp) stores (PNG/JPEG/TIFF with the sRGB
// transfer at 8/16 bit; OpenEXR linear half/float with AOVs as extra channels).
#pragma once

#include "rayscan/image/image_file.hpp"
#include "rayscan/render/render.hpp"
#include "rayscan/render/scene.hpp"

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace rayscan::render {

/// Key/value metadata stored in the image header; the image module's type (rayscan/image/image_file.hpp).
using rayscan::ImageMetadata;

/// Write `fb` to `out.image`:
///  - .png/.tif/.tiff: RGB, sRGB transfer (IEC 61966-2-1), out.bit_depth 8 or 16 bit;
///    .jpg/.jpeg: 8 bit, quality 95. AOVs, if any, go to "<stem>.aovs.exr" next to the image.
///  - .exr: linear RGB (half or float per out.exr_half) plus AOV channels: depth "Z" (float),
///    normal "N.X N.Y N.Z", position "P.X P.Y P.Z" (float; relative to fb.position_origin, which is
///    recorded as "rayscan:position_origin"), index "id" (uint32, 0xFFFFFFFF for a miss), albedo
///    "albedo.R albedo.G albedo.B", cost "cost" (float).
/// `metadata` is stored in every file's header (PNG text chunks, EXR string attributes); TIFF and
/// JPEG, which keep no free-form keys, get its "rayscan:*" entries as the ImageDescription, one
/// "key: value" line each. Pixel values are scaled by 2^out.exposure first; 8/16-bit formats then
/// clip them to [0, 1] (no tone mapping) before the sRGB transfer, EXR keeps them linear. Each file is written by rayscan::write_image
/// to a temporary sibling; the image and its AOV file form one OutputTransaction
/// (rayscan/base/atomic_file.hpp): both are renamed into place only when both were written, so a
/// failure leaves the old files intact. Paths that are not regular files (device, FIFO,
/// directory, symlink) are refused. Returns the files written.
/// Throws std::runtime_error naming the file when OpenImageIO cannot create or write it.
std::vector<std::filesystem::path> write_image(const Framebuffer& fb, const OutputDesc& out,
                                               const ImageMetadata& metadata);

}  // namespace rayscan::render
