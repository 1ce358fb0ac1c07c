// TUM trajectories (t tx ty tz qx qy qz qw per line): objscan::readTumTrajectory, and the camera's
// up discovery takes from a trajectory beside a mesh (objscan::viewUp): a unit vector or nothing.
#include <cmath>
#include <cstdlib>
#include <optional>

#include "fuzz_input.h"
#include "objscan/core/trajectory.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return objscan::fuzz::expectingRefusals([&] {
    const objscan::Trajectory t =
        objscan::readTumTrajectory(objscan::fuzz::writeInput(data, size, ".txt"));
    const std::optional<Eigen::Vector3f> up = objscan::viewUp(t);
    if (up && !(std::abs(up->norm() - 1.0f) < 1e-3f)) std::abort();
  });
}
