#pragma once

// Private to objscan_capture: file checks and image decoding shared by the dataset-folder readers.

#include <filesystem>
#include <functional>
#include <opencv2/core/mat.hpp>
#include <optional>
#include <string_view>

#include "objscan/core/image_codec.h"

namespace objscan::capture::detail {

/// Whether `path` is a regular file; a path the system cannot even look at (a name too long,
/// no permission) is an InputError rather than a filesystem_error.
bool isFile(const std::filesystem::path& path);

/// Reads and decodes an image file (objscan::decodeImage's `decoding`). A PNG or JPEG must end with
/// its end marker (IEND chunk, EOI): that catches truncated files before the codec sees them, so
/// the user gets one clear error instead of the codec's own messages on stderr. `check_size` (which
/// throws when a size is wrong) sees the size the PNG or JPEG header declares before the image is
/// decoded, so a hostile header cannot make the decoder allocate for an image of any size, and
/// then the decoded image's size. Throws InputError naming the file when it is missing, empty,
/// truncated or cannot be decoded.
cv::Mat readImage(const std::filesystem::path& path, ImageDecoding decoding,
                  const std::function<void(cv::Size)>& check_size);

/// The width and height a PNG (IHDR) or baseline/progressive JPEG (SOF) header declares; none
/// when `bytes` start like neither or the header is cut short.
std::optional<cv::Size> declaredImageSize(std::string_view bytes);

/// Width and height from a PNG file's header (its first 24 bytes), without decoding it; none when
/// the file cannot be read or does not start like a PNG.
std::optional<cv::Size> pngImageSize(const std::filesystem::path& path);

}  // namespace objscan::capture::detail
