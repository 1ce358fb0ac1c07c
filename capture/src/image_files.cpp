#include "image_files.h"

#include <algorithm>
#include <cstdint>
#include <fstream>
#include <limits>
#include <string>
#include <string_view>

#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"
#include "objscan/core/image_codec.h"

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

std::optional<cv::Size> declaredImageSize(std::string_view bytes) {
  const auto byte = [&](std::size_t at) { return static_cast<unsigned char>(bytes[at]); };
  const auto u16 = [&](std::size_t at) { return (byte(at) << 8) | byte(at + 1); };
  if (bytes.starts_with(kPngMagic)) {
    // IHDR comes first: length (4), "IHDR" (4), width (4), height (4), big-endian.
    if (bytes.size() < 24 || bytes.substr(12, 4) != "IHDR") return std::nullopt;
    const auto side = [&](std::size_t at) {
      const std::uint64_t v = (static_cast<std::uint64_t>(u16(at)) << 16) | u16(at + 2);
      return static_cast<int>(std::min<std::uint64_t>(v, std::numeric_limits<int>::max()));
    };
    return cv::Size(side(16), side(20));
  }
  if (!bytes.starts_with("\xff\xd8")) return std::nullopt;
  // JPEG: segments FF <marker> <big-endian length, itself included> until a start of frame
  // (SOF0-15 but DHT C4, JPG C8, DAC CC): precision (1), height (2), width (2). Bytes between
  // segments are skipped, as libjpeg skips them.
  std::size_t at = 2;
  while (at + 4 <= bytes.size()) {
    if (byte(at) != 0xff) {
      ++at;
      continue;
    }
    const unsigned marker = byte(at + 1);
    if (marker == 0xff) {  // fill byte
      ++at;
      continue;
    }
    if (marker >= 0xc0 && marker <= 0xcf && marker != 0xc4 && marker != 0xc8 && marker != 0xcc) {
      if (at + 9 > bytes.size()) return std::nullopt;
      return cv::Size(u16(at + 7), u16(at + 5));
    }
    if (marker == 0x01 || (marker >= 0xd0 && marker <= 0xd8)) {  // markers without a length
      at += 2;
      continue;
    }
    at += 2 + static_cast<std::size_t>(u16(at + 2));
  }
  return std::nullopt;
}

cv::Mat readImage(const fs::path& path, ImageDecoding decoding,
                  const std::function<void(cv::Size)>& check_size) {
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
  // Only PNG and JPEG, and only once the size their header declares has been checked: the
  // decoder allocates for that size before it reads any pixel.
  const std::optional<cv::Size> declared = declaredImageSize(view);
  if (!declared) {
    throw InputError(path, view.starts_with(kPngMagic) || view.starts_with("\xff\xd8")
                               ? "cannot be decoded as a PNG or JPEG image (its header gives "
                                 "no image size)"
                               : "not a PNG or JPEG image");
  }
  check_size(*declared);
  if (view.starts_with(kPngMagic) && view.size() >= 26) {
    // Deflate expands its input 1032 times at most: more pixels than that are not in the file.
    const int bits_per_sample = static_cast<unsigned char>(view[24]);
    const int colour_type = static_cast<unsigned char>(view[25]);
    const int samples = colour_type == 2 ? 3 : colour_type == 4 ? 2 : colour_type == 6 ? 4 : 1;
    const double raw_bytes =
        static_cast<double>(declared->width) * declared->height * samples * bits_per_sample / 8.0;
    if (raw_bytes > 1032.0 * static_cast<double>(view.size()) + 65536.0) {
      throw InputError(path, "the PNG declares " + std::to_string(declared->width) + "x" +
                                 std::to_string(declared->height) +
                                 " pixels, more than its compressed data can hold");
    }
  }
  cv::Mat image = decodeImage(view, decoding);
  if (image.empty()) throw InputError(path, "cannot be decoded as a PNG or JPEG image");
  check_size(image.size());
  return image;
}

std::optional<cv::Size> pngImageSize(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  char header[24] = {};
  if (!in.read(header, sizeof header)) return std::nullopt;
  const std::string_view view(header, sizeof header);
  if (!view.starts_with(kPngMagic)) return std::nullopt;
  const std::optional<cv::Size> size = declaredImageSize(view);
  if (!size || size->width == 0 || size->height == 0 || size->width > 1 << 30 ||
      size->height > 1 << 30) {
    return std::nullopt;
  }
  return size;
}

}  // namespace objscan::capture::detail
