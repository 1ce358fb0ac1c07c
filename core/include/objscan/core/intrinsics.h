#pragma once

#include <filesystem>
#include <optional>

namespace objscan {

/// Pinhole intrinsics of a depth/colour camera, in pixels. Pixel centres sit at integer
/// coordinates: a point (x, y, z) in the camera frame (z forward, metres) projects to u = fx * x /
/// z + cx, v = fy * y / z + cy.
struct Intrinsics {
  double fx_px = 570.3;  ///< focal length along u
  double fy_px = 570.3;  ///< focal length along v
  double cx_px = 319.5;  ///< principal point, u
  double cy_px = 239.5;  ///< principal point, v
  int width_px = 640;
  int height_px = 480;

  /// The Asus Xtion / Kinect v1 defaults OpenNI reports at 640×480 (fx = fy = 570.3, centre 319.5,
  /// 239.5).
  static Intrinsics xtionDefault() { return Intrinsics{}; }

  /// Throws std::invalid_argument with a sentence naming the bad field: focal lengths must be
  /// finite and positive, the image 1..16384 pixels on a side, the principal point inside the
  /// image.
  void validate() const;

  friend bool operator==(const Intrinsics&, const Intrinsics&) = default;
};

/// Reads `{"fx": .., "fy": .., "cx": .., "cy": .., "width": .., "height": ..}` (extra keys
/// ignored). With `depth_factor` given, the optional key "depth_factor" (raw depth units per metre,
/// as recordings store it beside their intrinsics) is read into it, or left empty when absent.
/// Throws InputError naming the file when it is missing, not JSON, lacks a key, fails validate(),
/// or has a depth_factor that is not a positive number.
Intrinsics readIntrinsicsJson(const std::filesystem::path& path,
                              std::optional<double>* depth_factor = nullptr);

/// Writes the same format atomically, with "depth_factor" when given. Throws OutputError.
void writeIntrinsicsJson(const std::filesystem::path& path, const Intrinsics& intrinsics,
                         std::optional<double> depth_factor = std::nullopt);

}  // namespace objscan
