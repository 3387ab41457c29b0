// Cameras: the look-at thin-lens camera of Ray Tracing in One Weekend (sections 11-12) and the
// photogrammetric pinhole with intrinsic matrix K and extrinsic [R|t] (OpenCV convention, Hartley &
// Zisserman, "Multiple View Geometry", 2nd ed., section 6.1), both reduced to one ray generator; plus orthographic and
// equirectangular projections and OpenCV lens distortion.
#pragma once

#include "rayscan/camera/lens_distortion.hpp"
#include "rayscan/octree/ray.hpp"

#include <glm/mat3x3.hpp>

#include <array>
#include <cstdint>
#include <optional>

namespace rayscan {

/// Look-at camera description (RTIOW "positionable camera" and "defocus blur").
struct LookAtParams {
  Vec3 position{0.0};           ///< eye, world coordinates
  Vec3 look_at{0.0, 0.0, -1.0}; ///< point the view centre passes through, world coordinates
  Vec3 up{0.0, 0.0, 1.0};       ///< world up (must not be parallel to look_at - position)
  double vfov_deg = 40.0;       ///< vertical field of view, degrees, in (0, 180)
  double aperture = 0.0;        ///< lens diameter, world units (0 = pinhole)
  double focus_distance = 0.0;  ///< distance to the plane in focus, world units (0 = |look_at - position|)
};

/// Photogrammetric pinhole: x_cam = R x_world + t, pixel ~ K x_cam (OpenCV: camera x right, y down,
/// z forward; pixel (0,0) is the centre of the top-left pixel).
struct PinholeParams {
  std::array<std::array<double, 3>, 3> K{};  ///< intrinsics, pixels; K[2] must be (0, 0, 1)
  std::array<std::array<double, 3>, 3> R{};  ///< world-to-camera rotation (orthonormal, det +1)
  Vec3 t{0.0};                               ///< world-to-camera translation, world units
};

/// How a camera maps pixels to rays (camera JSON "type").
enum class Projection {
  perspective,     ///< pinhole / thin lens (look-at or K/[R|t], optional OpenCV distortion)
  orthographic,    ///< parallel rays (pbrt-v4 section 5.1.4): pixel -> origin on the image plane
  equirectangular  ///< 360 x 180 degree panorama from one position (pbrt-v4 section 5.3, the
                   ///< "equirectangular" spherical camera)
};

/// Orthographic view: the image plane is centred on `position`, perpendicular to look_at -
/// position, `view_height` world units tall (square pixels); rays travel along the view direction.
struct OrthographicParams {
  Vec3 position{0.0};            ///< centre of the image plane (ray origins), world coordinates
  Vec3 look_at{0.0, 0.0, -1.0};  ///< fixes the view direction (position -> look_at)
  Vec3 up{0.0, 0.0, 1.0};        ///< world up (not parallel to the view direction)
  double view_height = 1.0;      ///< height of the image plane, world units (> 0)
};

/// Equirectangular panorama: column u spans longitude -180..180 degrees around `up` (0 towards
/// `look_at`, increasing to the right), row v spans latitude +90 (top) .. -90 (bottom).
struct EquirectangularParams {
  Vec3 position{0.0};           ///< centre of projection (a scanner station), world coordinates
  Vec3 look_at{0.0, 1.0, 0.0};  ///< a point in the direction of the image centre (the direction
                                ///< position -> look_at, projected onto the horizon)
  Vec3 up{0.0, 0.0, 1.0};       ///< zenith direction
};

/// How a camera was described: the camera-file model (scenes/README.md) it was built from.
enum class CameraModel {
  look_at,            ///< LookAtParams (Camera::look_at)
  pinhole,            ///< PinholeParams K/[R|t], optional OpenCV distortion (Camera::pinhole, pinhole_distorted)
  orthographic,       ///< OrthographicParams (Camera::orthographic)
  orthographic_grid,  ///< a per-pixel grid (Camera::orthographic_grid): no camera-file form
  equirectangular     ///< EquirectangularParams (Camera::equirectangular)
};

/// The parameters a camera was built from, kept so that the camera can be written back to a
/// camera file exactly (io::camera_to_json) and resized from its description rather than from
/// derived matrices. Only the member of `model` is meaningful.
struct CameraDescription {
  CameraModel model = CameraModel::look_at;
  LookAtParams look_at;                   ///< CameraModel::look_at
  PinholeParams pinhole;                  ///< CameraModel::pinhole
  LensDistortion distortion;              ///< CameraModel::pinhole: OpenCV coefficients (all 0: none)
  OrthographicParams orthographic;        ///< CameraModel::orthographic
  EquirectangularParams equirectangular;  ///< CameraModel::equirectangular
};

/// The largest image side (width or height) of any camera, pixels: the bound that the camera
/// constructors, camera files, COLMAP models, fit_image_size and the command line's --width /
/// --height all check (at most 65536 x 65536 = 2^32 pixels per image).
inline constexpr std::uint32_t kMaxImageSide = 65536;

/// An image size in pixels.
struct ImageSize {
  std::uint32_t width = 0, height = 0;
};

/// The one resize rule of rayscan (`--width` / `--height`, scene overrides, fly-through frames):
/// both given: that size; one given: the other follows the aspect ratio of `current`, rounded to
/// the nearest pixel; none: `current`. Throws OptionError naming the fields "width" and "height"
/// when a side comes out outside [1, 65536] ("the camera's aspect ratio 1:65536 gives an image
/// height of 4294967296 pixels, expected 1 to 65536; give both width and height").
ImageSize fit_image_size(ImageSize current, std::optional<std::uint32_t> width, std::optional<std::uint32_t> height);

/// A camera that maps continuous pixel coordinates to world rays.
///
/// Pixel coordinates follow OpenCV: the centre of pixel (i, j) (column i, row j from the top) is at
/// (i, j); a pixel covers [i - 0.5, i + 0.5] x [j - 0.5, j + 0.5]. Internally a pinhole ray has
/// origin C (the centre of projection) and direction M (u, v, 1) with M = R^T K^-1, so look-at and
/// K/[R|t] descriptions of the same pose produce the same rays.
class Camera {
 public:
  /// Look-at camera of `width` x `height` pixels (square pixels, principal point at the image
  /// centre ((width-1)/2, (height-1)/2)). Throws std::invalid_argument for a zero size, vfov outside
  /// (0, 180), coincident position/look_at, up parallel to the view direction, or negative aperture.
  static Camera look_at(const LookAtParams& p, std::uint32_t width, std::uint32_t height);
  /// K/[R|t] camera. Throws std::invalid_argument for a zero size, a singular K or K[2] != (0,0,1),
  /// or an R that is not a rotation (|R^T R - I| > 1e-6 or det < 0).
  static Camera pinhole(const PinholeParams& p, std::uint32_t width, std::uint32_t height);
  /// K/[R|t] camera with OpenCV lens distortion: a pixel is un-projected by K^-1, undistorted
  /// (undistort(), Newton) and rotated by R^T. Same errors as pinhole().
  static Camera pinhole_distorted(const PinholeParams& p, const LensDistortion& k, std::uint32_t width,
                                  std::uint32_t height);
  /// Orthographic camera (camera_orthographic.cpp). Throws std::invalid_argument for a zero size,
  /// view_height <= 0, coincident position/look_at or up parallel to the view direction.
  static Camera orthographic(const OrthographicParams& p, std::uint32_t width, std::uint32_t height);
  /// Orthographic camera given per pixel: the ray of pixel (u, v) starts at
  /// origin00 + u step_u + v step_v and travels along `direction` (a top-down map grid).
  /// Throws std::invalid_argument for a zero size or zero/non-finite vectors.
  static Camera orthographic_grid(const Vec3& origin00, const Vec3& step_u, const Vec3& step_v,
                                  const Vec3& direction, std::uint32_t width, std::uint32_t height);
  /// Equirectangular panorama (camera_equirect.cpp). Throws std::invalid_argument for a zero size or
  /// forward parallel to up.
  static Camera equirectangular(const EquirectangularParams& p, std::uint32_t width, std::uint32_t height);

  /// The projection type.
  [[nodiscard]] Projection projection() const { return projection_; }
  /// Lens distortion of a pinhole camera (all zero otherwise).
  [[nodiscard]] const LensDistortion& distortion() const { return distortion_; }

  /// The ray through continuous pixel coordinates (u, v); lens_u, lens_v in [0,1) pick a point on
  /// the aperture disk (ignored for a pinhole). Direction is unit length (Ray normalises).
  [[nodiscard]] Ray generate_ray(double u, double v, double lens_u = 0.5, double lens_v = 0.5) const;

  /// Image width in pixels.
  [[nodiscard]] std::uint32_t width() const { return width_; }
  /// Image height in pixels.
  [[nodiscard]] std::uint32_t height() const { return height_; }
  /// Centre of projection, world coordinates.
  [[nodiscard]] const Vec3& center() const { return center_; }
  /// Unit viewing direction (camera +z).
  [[nodiscard]] const Vec3& forward() const { return forward_; }
  /// The parameters this camera was built from (its camera-file form).
  [[nodiscard]] const CameraDescription& description() const { return desc_; }
  /// Returns the camera rebuilt from its description at another image size, keeping the field of
  /// view: a look-at camera keeps its vertical field of view and square pixels (the horizontal one
  /// follows the new aspect ratio); a K/[R|t] camera scales K per axis (u' = s (u + 0.5) - 0.5, so
  /// both fields of view are kept); an orthographic camera keeps its view height and square
  /// pixels; a grid keeps the covered plane; a panorama always covers the sphere. Throws
  /// std::invalid_argument for a size outside [1, 65536].
  [[nodiscard]] Camera resized(std::uint32_t width, std::uint32_t height) const;
  /// resized() to fit_image_size({width(), height()}, width, height). Throws OptionError (see
  /// fit_image_size).
  [[nodiscard]] Camera resized(std::optional<std::uint32_t> width, std::optional<std::uint32_t> height) const;

 private:
  Camera() = default;
  std::uint32_t width_ = 0, height_ = 0;
  Vec3 center_{0.0};
  glm::dmat3 pixel_to_dir_{1.0};  // M = R^T K^-1: (u, v, 1) -> world direction (not unit)
  Vec3 forward_{0.0, 0.0, 1.0};
  Vec3 lens_x_{1.0, 0.0, 0.0}, lens_y_{0.0, 1.0, 0.0};  // aperture basis (unit)
  double lens_radius_ = 0.0, focus_distance_ = 1.0;
  Projection projection_ = Projection::perspective;
  LensDistortion distortion_;     // pinhole_distorted only
  glm::dmat3 k_inv_{1.0}, r_t_{1.0};  // pinhole_distorted: K^-1 and R^T separately
  Vec3 origin00_{0.0}, step_u_{0.0}, step_v_{0.0};  // orthographic: pixel -> ray origin
  Vec3 right_{1.0, 0.0, 0.0}, up_{0.0, 0.0, 1.0};    // equirectangular basis with forward_
  CameraDescription desc_;
  [[nodiscard]] Ray generate_special(double u, double v) const;
};

}  // namespace rayscan
