#include "image_files.h"

#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <string_view>

#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"

namespace objscan::capture::detail {
namespace fs = std::filesystem;

namespace {
constexpr std::string_view kPngMagic("\x89PNG\r\n\x1a\n", 8);
}  // namespace

bool isFile(const fs::path& path) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (ec && ec != std::errc::no_such_file_or_directory && ec != std::errc::not_a_directory) {
    throw InputError(path, "cannot access: " + ec.message());
  }
  return status.type() == fs::file_type::regular;
}

cv::Mat readImage(const fs::path& path, int flags) {
  const std::string bytes = readWholeFile(path);
  if (bytes.empty()) throw InputError(path, "the image file is empty");
  static constexpr std::string_view kPngEnd("IEND\xae\x42\x60\x82", 8);
  const std::string_view view(bytes);
  if (view.starts_with(kPngMagic) && !view.ends_with(kPngEnd)) {
    throw InputError(path, "the PNG file is truncated (it has no IEND end chunk)");
  }
  if (view.starts_with("\xff\xd8") && !view.ends_with("\xff\xd9")) {
    throw InputError(path, "the JPEG file is truncated (it has no end-of-image marker)");
  }
  cv::Mat image = cv::imdecode(
      cv::Mat(1, static_cast<int>(bytes.size()), CV_8UC1, const_cast<char*>(bytes.data())), flags);
  if (image.empty()) throw InputError(path, "cannot be decoded as a PNG or JPEG image");
  return image;
}

std::optional<cv::Size> pngImageSize(const fs::path& path) {
  // Signature (8 bytes), then the IHDR chunk: length (4), "IHDR" (4), width (4), height (4), all
  // big-endian.
  std::ifstream in(path, std::ios::binary);
  char header[24] = {};
  if (!in.read(header, sizeof header)) return std::nullopt;
  const std::string_view view(header, sizeof header);
  if (!view.starts_with(kPngMagic) || view.substr(12, 4) != "IHDR") return std::nullopt;
  const auto u32 = [&](std::size_t at) {
    std::uint32_t v = 0;
    for (std::size_t k = 0; k < 4; ++k) v = (v << 8) | static_cast<unsigned char>(header[at + k]);
    return v;
  };
  const std::uint32_t width = u32(16), height = u32(20);
  if (width == 0 || height == 0 || width > 1u << 30 || height > 1u << 30) return std::nullopt;
  return cv::Size(static_cast<int>(width), static_cast<int>(height));
}

}  // namespace objscan::capture::detail
