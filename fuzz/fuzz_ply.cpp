// PLY (ascii, binary little and big endian): objscan::readPly, and the mesh it returns checked
// and written back (what every command does next).
#include "fuzz_input.h"
#include "objscan/core/ply_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return objscan::fuzz::expectingRefusals([&] {
    const objscan::TriangleMesh mesh = objscan::readPly(objscan::fuzz::writeInput(data, size, ".ply"));
    mesh.validate();
    (void)objscan::encodePly(mesh);
  });
}
