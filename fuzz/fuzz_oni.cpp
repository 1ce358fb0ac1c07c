// OpenNI2 recordings (.oni): objscan's own container walker, capture::inspectOniFile, strict and
// tolerant of an unfinished file (as `objscan info` and replay use it), and its description.
#include "fuzz_input.h"
#include "objscan/capture/oni_container.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::filesystem::path& file = objscan::fuzz::writeInput(data, size, ".oni");
  objscan::fuzz::expectingRefusals([&] { (void)objscan::capture::inspectOniFile(file, false); });
  return objscan::fuzz::expectingRefusals([&] {
    (void)objscan::capture::describe(objscan::capture::inspectOniFile(file, true));
  });
}
