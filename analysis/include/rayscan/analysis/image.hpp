// The image type and image files of analysis (compare, heat maps, raster previews, visibility
// index files) are rayscan's one image module, rayscan::image (image/include/rayscan/image/),
// shared with the renderer's output. These names keep analysis:: spellings working.
#pragma once

#include "rayscan/image/image.hpp"
#include "rayscan/image/image_file.hpp"

namespace rayscan::analysis {

using rayscan::Image;
using rayscan::ImageMetadata;
using rayscan::ImageWriteOptions;
using rayscan::PixelFormat;
using rayscan::find_channel;
using rayscan::make_image;
using rayscan::read_image;
using rayscan::read_index_misses;
using rayscan::renderer_channel_alias;
using rayscan::resize_image;
using rayscan::select_channels;
using rayscan::write_image;

}  // namespace rayscan::analysis
