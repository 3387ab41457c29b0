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

/// The OpenEXR standard camera attributes of `camera` (OpenEXR's ImfStandardAttributes.h), as
/// ImageWriteOptions::matrices stores them (m44f, row-vector convention: p * M):
///  - "worldtocamera" (EXR worldToCamera): world coordinates to OpenEXR's camera space, world
///    units, origin at Camera::center() (an orthographic camera's image-plane centre), x right and
///    y up in the image, z along the view (left-handed; points in front have z > 0).
///  - "worldtoNDC" (EXR worldToNDC): world coordinates to NDC after the homogeneous divide:
///    x = (u + 0.5) / width, y = (v + 0.5) / height for the continuous pixel (u, v) the point
///    projects to (Camera's pixel convention), so (0, 0) and (1, 1) are the upper-left and
///    lower-right corners of the image; z is 1 / camera z (perspective) or camera z
///    (orthographic), which keeps the matrix invertible (OpenEXR says to discard it).
/// Both for a perspective camera without lens distortion (look-at, thin lens: its rays through the
/// lens centre; K/[R|t]) and an orthographic one; a distorted K/[R|t] camera, which no matrix
/// projects, gets worldtocamera only (its pose, R and t); a panorama and a map's grid get none.
/// They are derived from the camera's own rays (Camera::generate_ray), so that a point projects
/// to the pixel whose ray passes through it, to float precision: at georeferenced coordinates
/// (10^6 world units) that is about 0.1 world units; "rayscan:camera" keeps the camera in doubles.
std::vector<MatrixAttribute> exr_camera_matrices(const Camera& camera);

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
/// clip them to [0, 1] (no tone mapping, no dither) before the sRGB transfer, EXR keeps them
/// linear. The image (not the AOV file, whose channels are neither scaled nor encoded) records
/// both as "rayscan:exposure" (stops, shortest decimal) and "rayscan:transfer" ("sRGB" or
/// "linear"). Given `camera` (the camera the framebuffer was traced through: same size, else
/// std::invalid_argument), every EXR written, the image or the AOV file, also carries
/// exr_camera_matrices(*camera). Each file is written by rayscan::write_image
/// to a temporary sibling; the image and its AOV file form one OutputTransaction
/// (rayscan/base/atomic_file.hpp): both are renamed into place only when both were written, so a
/// failure leaves the old files intact. Paths that are not regular files (device, FIFO,
/// directory, symlink) are refused. Returns the files written.
/// Throws std::runtime_error naming the file when OpenImageIO cannot create or write it.
std::vector<std::filesystem::path> write_image(const Framebuffer& fb, const OutputDesc& out,
                                               const ImageMetadata& metadata, const Camera* camera = nullptr);

}  // namespace rayscan::render
