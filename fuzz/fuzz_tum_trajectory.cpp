// TUM trajectories (t tx ty tz qx qy qz qw per line): objscan::readTumTrajectory.
#include "fuzz_input.h"
#include "objscan/core/trajectory.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return objscan::fuzz::expectingRefusals([&] {
    (void)objscan::readTumTrajectory(objscan::fuzz::writeInput(data, size, ".txt"));
  });
}
