// PCD (ascii, binary, binary_compressed): objscan::readPcd, then the cloud meshed as discover
// meshes a single view.
#include "fuzz_input.h"
#include "objscan/core/organized_cloud.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return objscan::fuzz::expectingRefusals([&] {
    const objscan::OrganizedCloud cloud = objscan::readPcd(objscan::fuzz::writeInput(data, size, ".pcd"));
    (void)objscan::meshOrganized(cloud);
  });
}
