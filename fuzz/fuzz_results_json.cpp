// The results files' readers (report/results_io.h): hypotheses.json, timings.json,
// settings.json, evaluation.json and renders/overview_camera.json. The input's first byte
// chooses the reader, the rest is the file.
#include "fuzz_input.h"
#include "objscan/report/results_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::uint8_t which = data[0] % 5;
  const std::filesystem::path& file = objscan::fuzz::writeInput(data + 1, size - 1, ".json");
  return objscan::fuzz::expectingRefusals([&] {
    switch (which) {
      case 0: (void)objscan::report::readHypotheses(file); break;
      case 1: (void)objscan::report::readTimings(file); break;
      case 2: (void)objscan::report::readSettings(file); break;
      case 3: (void)objscan::report::readEvaluation(file); break;
      default: (void)objscan::report::readOverviewCamera(file); break;
    }
  });
}
