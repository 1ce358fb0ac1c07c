// intrinsics.json (fx, fy, cx, cy, width, height): objscan::readIntrinsicsJson.
#include "fuzz_input.h"
#include "objscan/core/intrinsics.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return objscan::fuzz::expectingRefusals([&] {
    (void)objscan::readIntrinsicsJson(objscan::fuzz::writeInput(data, size, ".json"));
  });
}
