#include "objscan/core/mesh_formats.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "objscan/core/byte_writing.h"
#include "objscan/core/ply_io.h"

namespace objscan {
namespace {

using byte_writing::putText;

/// Little-endian, as STL and glTF store every number.
template <class T>
void put(std::string& out, T value) {
  byte_writing::putLittleEndian(out, value);
}

std::string encodeObj(const TriangleMesh& mesh) {
  std::string out = "# written by objscan: v x y z [r g b in 0..1], vn, f with 1-based indices\n";
  const bool colors = mesh.hasColors(), normals = mesh.hasNormals();
  for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
    out += 'v';
    for (int a = 0; a < 3; ++a) {
      out += ' ';
      putText(out, mesh.positions[i][a]);
    }
    if (colors) {
      for (int c = 0; c < 3; ++c) {
        out += ' ';
        putText(out, static_cast<float>(mesh.colors[i][c]) / 255.0f);
      }
    }
    out += '\n';
  }
  if (normals) {
    for (const Eigen::Vector3f& n : mesh.normals) {
      out += "vn";
      for (int a = 0; a < 3; ++a) {
        out += ' ';
        putText(out, n[a]);
      }
      out += '\n';
    }
  }
  for (const Eigen::Vector3i& t : mesh.triangles) {
    out += 'f';
    for (int k = 0; k < 3; ++k) {
      const std::string index = std::to_string(t[k] + 1);
      out += ' ' + index;
      if (normals) out += "//" + index;
    }
    out += '\n';
  }
  return out;
}

std::string encodeStl(const TriangleMesh& mesh) {
  std::string out(80, '\0');
  const char header[] = "binary STL written by objscan (metres)";
  std::memcpy(out.data(), header, sizeof header - 1);
  out.reserve(84 + 50 * mesh.triangles.size());
  put<std::uint32_t>(out, static_cast<std::uint32_t>(mesh.triangles.size()));
  for (const Eigen::Vector3i& t : mesh.triangles) {
    const Eigen::Vector3f& a = mesh.positions[t[0]];
    const Eigen::Vector3f& b = mesh.positions[t[1]];
    const Eigen::Vector3f& c = mesh.positions[t[2]];
    const Eigen::Vector3f n = (b - a).cross(c - a).normalized();
    for (const Eigen::Vector3f* v : {&n, &a, &b, &c}) {
      for (int k = 0; k < 3; ++k) put<float>(out, std::isfinite((*v)[k]) ? (*v)[k] : 0.0f);
    }
    put<std::uint16_t>(out, 0);
  }
  return out;
}

/// glTF 2.0 binary: one scene, one node, one mesh of one triangle primitive (points when the
/// mesh has no triangles); attributes POSITION, NORMAL, COLOR_0 (RGBA8, normalised).
std::string encodeGlb(const TriangleMesh& mesh) {
  std::string bin;
  nlohmann::json views = nlohmann::json::array(), accessors = nlohmann::json::array();
  const auto count = mesh.positions.size();
  const auto addView = [&](const std::string& bytes, int target) {
    while (bin.size() % 4 != 0) bin.push_back('\0');
    views.push_back({{"buffer", 0},
                     {"byteOffset", bin.size()},
                     {"byteLength", bytes.size()},
                     {"target", target}});
    bin += bytes;
    return views.size() - 1;
  };
  nlohmann::json attributes;
  {
    std::string bytes;
    Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
    Eigen::Vector3f hi = -lo;
    for (const Eigen::Vector3f& p : mesh.positions) {
      for (int k = 0; k < 3; ++k) put<float>(bytes, p[k]);
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    if (count == 0) lo = hi = Eigen::Vector3f::Zero();
    accessors.push_back({{"bufferView", addView(bytes, 34962)},
                         {"componentType", 5126},
                         {"count", count},
                         {"type", "VEC3"},
                         {"min", {lo.x(), lo.y(), lo.z()}},
                         {"max", {hi.x(), hi.y(), hi.z()}}});
    attributes["POSITION"] = accessors.size() - 1;
  }
  if (mesh.hasNormals()) {
    std::string bytes;
    for (const Eigen::Vector3f& n : mesh.normals) {
      for (int k = 0; k < 3; ++k) put<float>(bytes, n[k]);
    }
    accessors.push_back({{"bufferView", addView(bytes, 34962)},
                         {"componentType", 5126},
                         {"count", count},
                         {"type", "VEC3"}});
    attributes["NORMAL"] = accessors.size() - 1;
  }
  if (mesh.hasColors()) {
    std::string bytes;
    for (const Rgb8& c : mesh.colors) {
      for (int k = 0; k < 3; ++k) put<std::uint8_t>(bytes, c[k]);
      put<std::uint8_t>(bytes, 255);
    }
    accessors.push_back({{"bufferView", addView(bytes, 34962)},
                         {"componentType", 5121},
                         {"normalized", true},
                         {"count", count},
                         {"type", "VEC4"}});
    attributes["COLOR_0"] = accessors.size() - 1;
  }
  nlohmann::json primitive = {{"attributes", attributes}, {"mode", 0}};
  if (!mesh.triangles.empty()) {
    std::string bytes;
    for (const Eigen::Vector3i& t : mesh.triangles) {
      for (int k = 0; k < 3; ++k) put<std::uint32_t>(bytes, static_cast<std::uint32_t>(t[k]));
    }
    accessors.push_back({{"bufferView", addView(bytes, 34963)},
                         {"componentType", 5125},
                         {"count", 3 * mesh.triangles.size()},
                         {"type", "SCALAR"}});
    primitive["indices"] = accessors.size() - 1;
    primitive["mode"] = 4;
  }
  while (bin.size() % 4 != 0) bin.push_back('\0');
  const nlohmann::json doc = {{"asset", {{"version", "2.0"}, {"generator", "objscan"}}},
                              {"scene", 0},
                              {"scenes", {{{"nodes", {0}}}}},
                              {"nodes", {{{"mesh", 0}}}},
                              {"meshes", {{{"primitives", {primitive}}}}},
                              {"buffers", {{{"byteLength", bin.size()}}}},
                              {"bufferViews", views},
                              {"accessors", accessors}};
  std::string json = doc.dump();
  while (json.size() % 4 != 0) json.push_back(' ');
  std::string out;
  out.reserve(28 + json.size() + bin.size());
  put<std::uint32_t>(out, 0x46546C67);  // "glTF"
  put<std::uint32_t>(out, 2);
  put<std::uint32_t>(out, static_cast<std::uint32_t>(28 + json.size() + bin.size()));
  put<std::uint32_t>(out, static_cast<std::uint32_t>(json.size()));
  put<std::uint32_t>(out, 0x4E4F534A);  // "JSON"
  out += json;
  put<std::uint32_t>(out, static_cast<std::uint32_t>(bin.size()));
  put<std::uint32_t>(out, 0x004E4942);  // "BIN\0"
  out += bin;
  return out;
}

}  // namespace

MeshFormat meshFormatFromName(std::string_view name) {
  if (name == "ply") return MeshFormat::kPly;
  if (name == "obj") return MeshFormat::kObj;
  if (name == "stl") return MeshFormat::kStl;
  if (name == "glb") return MeshFormat::kGlb;
  throw std::invalid_argument("unknown mesh format '" + std::string(name) +
                              "' (choose ply, obj, stl or glb)");
}

const char* toString(MeshFormat format) {
  switch (format) {
    case MeshFormat::kPly:
      return "ply";
    case MeshFormat::kObj:
      return "obj";
    case MeshFormat::kStl:
      return "stl";
    case MeshFormat::kGlb:
      return "glb";
  }
  return "?";
}

std::string extensionOf(MeshFormat format) { return std::string(".") + toString(format); }

std::string encodeMesh(const TriangleMesh& mesh, MeshFormat format) {
  mesh.validate();
  switch (format) {
    case MeshFormat::kPly:
      return encodePly(mesh);
    case MeshFormat::kObj:
      return encodeObj(mesh);
    case MeshFormat::kStl:
      return encodeStl(mesh);
    case MeshFormat::kGlb:
      return encodeGlb(mesh);
  }
  throw std::invalid_argument("unknown mesh format");
}

}  // namespace objscan
