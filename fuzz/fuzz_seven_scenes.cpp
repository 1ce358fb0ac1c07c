// 7-Scenes / 3DMatch folders: capture::SevenScenesFolder's camera-intrinsics.txt, pose files and
// depth PNG header (the image size when the intrinsics file gives none), then decoding frame 0.
// The input holds four parts, each ended by a line "=====": camera-intrinsics.txt, frame 0's
// pose, frame 1's pose, frame 0's depth PNG. An empty part is a file that is not there (for the
// PNG: a valid 4x3 16-bit image); frame 1's depth image is always that valid one.

#include <string>
#include <string_view>
#include <vector>

#include "fuzz_input.h"
#include "objscan/capture/seven_scenes_folder.h"
#include "objscan/core/image_codec.h"

namespace fs = std::filesystem;

namespace {

std::string smallDepthPng() {
  return objscan::encodePng(cv::Mat(3, 4, CV_16UC1, cv::Scalar(1000)));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::string valid_png = smallDepthPng();
  static const fs::path dir = [] {
    const fs::path d = objscan::fuzz::inputFile(".7scenes");
    fs::create_directories(d);
    std::ofstream(d / "frame-000001.depth.png", std::ios::binary) << valid_png;
    return d;
  }();
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  constexpr std::string_view kEnd = "\n=====\n";
  const char* names[] = {"camera-intrinsics.txt", "frame-000000.pose.txt", "frame-000001.pose.txt",
                         "frame-000000.depth.png"};
  std::size_t at = 0;
  for (const char* name : names) {
    std::error_code ec;
    fs::remove(dir / name, ec);
    std::string_view part;
    if (at <= input.size()) {
      std::size_t end = input.find(kEnd, at);
      if (end == std::string_view::npos) end = input.size();
      part = input.substr(at, end - at);
      at = end + kEnd.size();
    }
    const bool png = std::string_view(name).find(".png") != std::string_view::npos;
    if (part.empty() && png) part = valid_png;
    if (!part.empty()) std::ofstream(dir / name, std::ios::binary) << part;
  }
  return objscan::fuzz::expectingRefusals([&] {
    const objscan::capture::SevenScenesFolder folder(dir);
    (void)folder.load(0);
  });
}
