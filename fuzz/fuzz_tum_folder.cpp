// TUM RGB-D folders: the index files capture::TumFolder reads (associations.txt, or depth.txt
// with rgb.txt, and groundtruth.txt) in a folder whose rgb/ and depth/ hold a few images by name.
// The input holds the files one after the other, each ended by a line "=====": associations,
// depth, rgb, ground truth; an empty part is a file that is not there.
#include <string>
#include <string_view>

#include "fuzz_input.h"
#include "objscan/capture/tum_folder.h"

namespace fs = std::filesystem;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const fs::path dir = [] {
    const fs::path d = objscan::fuzz::inputFile(".tum");
    for (const char* sub : {"rgb", "depth"}) {
      fs::create_directories(d / sub);
      for (const char* name : {"1.png", "2.png", "1305031102.175304.png"}) {
        std::ofstream(d / sub / name) << "";
      }
    }
    return d;
  }();
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  constexpr std::string_view kEnd = "\n=====\n";
  const char* names[] = {"associations.txt", "depth.txt", "rgb.txt", "groundtruth.txt"};
  std::size_t at = 0;
  for (const char* name : names) {
    std::error_code ec;
    fs::remove(dir / name, ec);
    if (at > input.size()) continue;
    std::size_t end = input.find(kEnd, at);
    if (end == std::string_view::npos) end = input.size();
    if (end > at) std::ofstream(dir / name, std::ios::binary) << input.substr(at, end - at);
    at = end + kEnd.size();
  }
  return objscan::fuzz::expectingRefusals([&] {
    const objscan::capture::TumFolder folder(dir);
    (void)folder.frames();
  });
}
