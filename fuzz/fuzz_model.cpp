// Model files of objscan train (JSON): discovery::ObjectnessModel::load, and
// the model scoring a segment (what discover --model does next).
#include "fuzz_input.h"
#include "objscan/discovery/scoring.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return objscan::fuzz::expectingRefusals([&] {
    const objscan::discovery::ObjectnessModel model =
        objscan::discovery::ObjectnessModel::load(objscan::fuzz::writeInput(data, size, ".json"));
    objscan::discovery::ShapeMeasures m;
    m.compactness = 0.5;
    m.symmetry = 0.1;
    m.smoothness = 0.8;
    m.local_convexity = 0.7;
    m.global_convexity = 0.002;
    m.recurrence = 1.0;
    (void)model.score(m);
  });
}
