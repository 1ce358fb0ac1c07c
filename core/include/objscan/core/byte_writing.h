#pragma once

// Appending numbers to a file's bytes: the mesh writers (PLY in ply_io.cpp; OBJ, STL and glTF in
// mesh_formats.cpp) and the 3-D view's binary mesh (report/src/mesh_view.cpp, the viewer's routes).

#include <algorithm>
#include <bit>
#include <charconv>
#include <cstring>
#include <string>

namespace objscan::byte_writing {

/// `v`'s bytes in host order, reversed when `swap`.
template <class T>
void putBinary(std::string& out, T v, bool swap = false) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &v, sizeof(T));
  if (swap) std::reverse(bytes, bytes + sizeof(T));
  out.append(bytes, sizeof(T));
}

/// `v`'s bytes little-endian, whatever the host's order.
template <class T>
void putLittleEndian(std::string& out, T v) {
  putBinary(out, v, std::endian::native == std::endian::big);
}

/// The shortest text that reads back to the same value.
template <class T>
void putText(std::string& out, T v) {
  char buf[64];
  const auto result = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, result.ptr);
}

}  // namespace objscan::byte_writing
