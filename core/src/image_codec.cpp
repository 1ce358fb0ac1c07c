#include "objscan/core/image_codec.h"

#include <spng.h>
#include <turbojpeg.h>
#include <zlib.h>

#include <cstdlib>
#include <memory>
#include <stdexcept>
#include <string>

namespace objscan {
namespace {

constexpr std::string_view kPngSignature("\x89PNG\r\n\x1a\n", 8);
/// Ancillary chunks (text, ICC profiles) are inflated in memory: a few of them could otherwise
/// ask for gigabytes. Image data are bounded by the callers' size checks instead.
constexpr std::size_t kPngChunkLimit = std::size_t{16} << 20;

struct SpngFree {
  void operator()(spng_ctx* ctx) const { spng_ctx_free(ctx); }
};
using Spng = std::unique_ptr<spng_ctx, SpngFree>;

struct TjFree {
  void operator()(void* handle) const { tjDestroy(handle); }
};
using TurboJpeg = std::unique_ptr<void, TjFree>;

cv::Mat decodePng(std::string_view bytes, ImageDecoding decoding) {
  const Spng ctx(spng_ctx_new(0));
  spng_ihdr ihdr{};
  if (!ctx || spng_set_png_buffer(ctx.get(), bytes.data(), bytes.size()) != 0 ||
      spng_set_chunk_limits(ctx.get(), kPngChunkLimit, 4 * kPngChunkLimit) != 0 ||
      spng_get_ihdr(ctx.get(), &ihdr) != 0 || ihdr.width > 1u << 30 || ihdr.height > 1u << 30) {
    return {};
  }
  const bool grey =
      decoding == ImageDecoding::kStoredGrey && ihdr.color_type == SPNG_COLOR_TYPE_GRAYSCALE;
  // SPNG_FMT_PNG keeps a 16-bit grey image's samples, in the host's byte order.
  const int format = !grey ? SPNG_FMT_RGB8 : ihdr.bit_depth == 16 ? SPNG_FMT_PNG : SPNG_FMT_G8;
  const int type = !grey ? CV_8UC3 : ihdr.bit_depth == 16 ? CV_16UC1 : CV_8UC1;
  std::size_t size = 0;
  if (spng_decoded_image_size(ctx.get(), format, &size) != 0) return {};
  cv::Mat image(static_cast<int>(ihdr.height), static_cast<int>(ihdr.width), type);
  if (size != image.total() * image.elemSize() ||
      spng_decode_image(ctx.get(), image.data, size, format, 0) != 0) {
    return {};
  }
  return image;
}

cv::Mat decodeJpeg(std::string_view bytes, ImageDecoding decoding) {
  const TurboJpeg tj(tjInitDecompress());
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  const auto size = static_cast<unsigned long>(bytes.size());
  int width = 0, height = 0, subsampling = 0, colourspace = 0;
  if (!tj ||
      tjDecompressHeader3(tj.get(), data, size, &width, &height, &subsampling, &colourspace) != 0 ||
      width <= 0 || height <= 0) {
    return {};
  }
  const bool grey = decoding == ImageDecoding::kStoredGrey && colourspace == TJCS_GRAY;
  cv::Mat image(height, width, grey ? CV_8UC1 : CV_8UC3);
  // TJFLAG_LIMITSCANS: a progressive JPEG of thousands of scans would take minutes to decode.
  // TJFLAG_STOPONWARNING: after a warning, TurboJPEG 2.1 reports a later fatal error as a warning
  // too, with the rows after it never written; a damaged stream is refused instead.
  if (tjDecompress2(tj.get(), data, size, image.data, width, static_cast<int>(image.step[0]),
                    height, grey ? TJPF_GRAY : TJPF_RGB,
                    TJFLAG_LIMITSCANS | TJFLAG_STOPONWARNING) != 0) {
    return {};
  }
  return image;
}

}  // namespace

cv::Mat decodeImage(std::string_view bytes, ImageDecoding decoding) {
  if (bytes.starts_with(kPngSignature)) return decodePng(bytes, decoding);
  if (bytes.starts_with("\xff\xd8")) return decodeJpeg(bytes, decoding);
  return {};
}

std::string encodePng(const cv::Mat& image) {
  if (image.empty()) throw std::invalid_argument("encodePng: the image is empty");
  spng_ihdr ihdr{};
  ihdr.width = static_cast<std::uint32_t>(image.cols);
  ihdr.height = static_cast<std::uint32_t>(image.rows);
  ihdr.bit_depth = 8;
  cv::Mat samples;  // the rows as the PNG holds them, one after another
  switch (image.type()) {
    case CV_8UC1:
    case CV_16UC1:
      ihdr.color_type = SPNG_COLOR_TYPE_GRAYSCALE;
      ihdr.bit_depth = image.type() == CV_16UC1 ? 16 : 8;
      samples = image.isContinuous() ? image : image.clone();
      break;
    case CV_8UC3:
    case CV_8UC4: {
      const int channels = image.channels();
      ihdr.color_type = channels == 3 ? SPNG_COLOR_TYPE_TRUECOLOR : SPNG_COLOR_TYPE_TRUECOLOR_ALPHA;
      samples.create(image.size(), image.type());
      for (int y = 0; y < image.rows; ++y) {
        const unsigned char* in = image.ptr<unsigned char>(y);
        unsigned char* out = samples.ptr<unsigned char>(y);
        for (int x = 0; x < image.cols * channels; x += channels) {
          out[x] = in[x + 2];  // B, G, R(, A) -> R, G, B(, A)
          out[x + 1] = in[x + 1];
          out[x + 2] = in[x];
          if (channels == 4) out[x + 3] = in[x + 3];
        }
      }
      break;
    }
    default:
      throw std::invalid_argument("encodePng: images of 8-bit grey, 16-bit grey, BGR or BGRA only");
  }
  const Spng ctx(spng_ctx_new(SPNG_CTX_ENCODER));
  std::size_t size = 0;
  int error = 0;
  // Fast rather than small, as OpenCV's imwrite: each row's sub filter, zlib's level 1 and its
  // run-length strategy (a synthetic recording writes three PNGs a frame).
  if (!ctx || spng_set_option(ctx.get(), SPNG_ENCODE_TO_BUFFER, 1) != 0 ||
      spng_set_option(ctx.get(), SPNG_FILTER_CHOICE, SPNG_FILTER_CHOICE_SUB) != 0 ||
      spng_set_option(ctx.get(), SPNG_IMG_COMPRESSION_LEVEL, 1) != 0 ||
      spng_set_option(ctx.get(), SPNG_IMG_COMPRESSION_STRATEGY, Z_RLE) != 0 ||
      spng_set_ihdr(ctx.get(), &ihdr) != 0 ||
      spng_encode_image(ctx.get(), samples.data, samples.total() * samples.elemSize(), SPNG_FMT_PNG,
                        SPNG_ENCODE_FINALIZE) != 0) {
    throw std::runtime_error("could not encode a PNG");
  }
  void* png = spng_get_png_buffer(ctx.get(), &size, &error);
  if (!png || error != 0) throw std::runtime_error("could not encode a PNG");
  std::string out(static_cast<const char*>(png), size);
  std::free(png);
  return out;
}

std::string encodeJpeg(const cv::Mat& bgr, int quality) {
  if (bgr.empty() || bgr.type() != CV_8UC3) {
    throw std::invalid_argument("encodeJpeg: a non-empty 8-bit BGR image only");
  }
  if (quality < 1 || quality > 100) throw std::invalid_argument("encodeJpeg: quality is 1-100");
  const TurboJpeg tj(tjInitCompress());
  unsigned char* jpeg = nullptr;
  unsigned long size = 0;
  if (!tj || tjCompress2(tj.get(), bgr.data, bgr.cols, static_cast<int>(bgr.step[0]), bgr.rows,
                         TJPF_BGR, &jpeg, &size, TJSAMP_420, quality, 0) != 0) {
    tjFree(jpeg);
    throw std::runtime_error("could not encode a JPEG");
  }
  std::string out(reinterpret_cast<const char*>(jpeg), size);
  tjFree(jpeg);
  return out;
}

}  // namespace objscan
