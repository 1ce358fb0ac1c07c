#pragma once

// Private to objscan_capture: file checks and image decoding shared by the dataset-folder readers.

#include <filesystem>
#include <opencv2/core/mat.hpp>
#include <optional>

namespace objscan::capture::detail {

/// Whether `path` is a regular file; a path the system cannot even look at (a name too long,
/// no permission) is an InputError rather than a filesystem_error.
bool isFile(const std::filesystem::path& path);

/// Reads and decodes an image file (cv::imdecode `flags`). A PNG or JPEG must end with its end
/// marker (IEND chunk, EOI): that catches truncated files before the codec sees them, so the user
/// gets one clear error instead of the codec's own messages on stderr. Throws InputError naming
/// the file when it is missing, empty, truncated or cannot be decoded.
cv::Mat readImage(const std::filesystem::path& path, int flags);

/// Width and height from a PNG file's header (its first 24 bytes), without decoding it; none when
/// the file cannot be read or does not start like a PNG.
std::optional<cv::Size> pngImageSize(const std::filesystem::path& path);

}  // namespace objscan::capture::detail
