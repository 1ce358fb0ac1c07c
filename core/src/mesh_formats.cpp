#include "objscan/core/mesh_formats.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "objscan/core/atomic_file.h"
#include "objscan/core/byte_writing.h"
#include "objscan/core/error.h"
#include "objscan/core/file_names.h"
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
std::string encodeGlb(const TriangleMesh& mesh, const std::optional<Eigen::Vector3f>& up) {
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
  nlohmann::json node = {{"mesh", 0}};
  if (up && up->norm() > 0.0f && up->allFinite()) {
    // glTF is Y-up: the rotation (a unit quaternion x, y, z, w) that turns the scene's up onto +Y.
    const Eigen::Quaternionf q =
        Eigen::Quaternionf::FromTwoVectors(up->normalized(), Eigen::Vector3f::UnitY()).normalized();
    node["rotation"] = {q.x(), q.y(), q.z(), q.w()};
  }
  const nlohmann::json doc = {{"asset", {{"version", "2.0"}, {"generator", "objscan"}}},
                              {"scene", 0},
                              {"scenes", {{{"nodes", {0}}}}},
                              {"nodes", {node}},
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

std::string encodeMesh(const TriangleMesh& mesh, MeshFormat format,
                       const std::optional<Eigen::Vector3f>& up) {
  mesh.validate();
  switch (format) {
    case MeshFormat::kPly:
      return encodePly(mesh);
    case MeshFormat::kObj:
      return encodeObj(mesh);
    case MeshFormat::kStl:
      return encodeStl(mesh);
    case MeshFormat::kGlb:
      return encodeGlb(mesh, up);
  }
  throw std::invalid_argument("unknown mesh format");
}

namespace {

/// The 4-byte little-endian value at `offset` (the caller checked the size).
template <class T>
T littleEndianAt(const std::string& bytes, std::size_t offset) {
  static_assert(sizeof(T) == 4);
  std::uint32_t bits = 0;
  for (std::size_t i = 0; i < 4; ++i) {
    bits |= static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[offset + i])) << (8 * i);
  }
  return std::bit_cast<T>(bits);
}

/// The largest object file summarizeMeshFile reads: what objscan writes stays far below; a larger
/// file is not a mesh to count in memory.
constexpr std::uintmax_t kMaxMeshFileBytes = std::uintmax_t{2} << 30;

void summarizeObj(const std::filesystem::path& path, const std::string& text,
                  MeshFileSummary& out) {
  std::istringstream lines(text);
  std::string line;
  std::size_t number = 0;
  while (std::getline(lines, line)) {
    ++number;
    std::istringstream fields(line);
    std::string kind;
    fields >> kind;
    if (kind == "v") {
      float v[6];
      int n = 0;
      while (n < 6 && fields >> v[n]) ++n;
      if (n < 3) throw InputError(path, "line " + std::to_string(number) + ": a vertex needs x y z");
      out.bounds.extend(Eigen::Vector3f(v[0], v[1], v[2]));
      out.colours = out.colours || n == 6;
      ++out.vertices;
    } else if (kind == "vn") {
      out.normals = true;
    } else if (kind == "f") {
      std::size_t corners = 0;
      std::string corner;
      while (fields >> corner) ++corners;
      if (corners < 3) throw InputError(path, "line " + std::to_string(number) + ": a face needs 3 corners");
      out.triangles += corners - 2;
    }
  }
}

void summarizeStl(const std::filesystem::path& path, const std::string& bytes,
                  MeshFileSummary& out) {
  if (bytes.rfind("solid", 0) == 0 && bytes.find("facet") != std::string::npos) {
    throw InputError(path, "is an ASCII STL; objscan writes (and describes) binary STL");
  }
  if (bytes.size() < 84) throw InputError(path, "is shorter than a binary STL header (84 bytes)");
  const std::uint32_t count = littleEndianAt<std::uint32_t>(bytes, 80);
  if (bytes.size() != 84 + 50 * static_cast<std::uint64_t>(count)) {
    throw InputError(path, "is " + std::to_string(bytes.size()) + " bytes, but its header says " +
                               std::to_string(count) + " triangles (" +
                               std::to_string(84 + 50 * static_cast<std::uint64_t>(count)) +
                               " bytes): cut short or not a binary STL");
  }
  out.triangles = count;
  out.vertices = 3 * static_cast<std::size_t>(count);
  out.normals = true;  // one per facet
  for (std::size_t t = 0; t < count; ++t) {
    for (int k = 1; k <= 3; ++k) {
      const std::size_t at = 84 + 50 * t + 12 * static_cast<std::size_t>(k);
      out.bounds.extend(Eigen::Vector3f(littleEndianAt<float>(bytes, at),
                                        littleEndianAt<float>(bytes, at + 4),
                                        littleEndianAt<float>(bytes, at + 8)));
    }
  }
}

void summarizeGlb(const std::filesystem::path& path, const std::string& bytes,
                  MeshFileSummary& out) {
  if (bytes.size() < 20 || littleEndianAt<std::uint32_t>(bytes, 0) != 0x46546C67) {
    throw InputError(path, "is not a binary glTF file (no 'glTF' magic)");
  }
  if (littleEndianAt<std::uint32_t>(bytes, 4) != 2) {
    throw InputError(path, "is glTF version " +
                               std::to_string(littleEndianAt<std::uint32_t>(bytes, 4)) +
                               "; objscan describes version 2");
  }
  const std::uint32_t json_length = littleEndianAt<std::uint32_t>(bytes, 12);
  if (littleEndianAt<std::uint32_t>(bytes, 16) != 0x4E4F534A || 20 + std::uint64_t{json_length} > bytes.size()) {
    throw InputError(path, "has no whole JSON chunk (cut short?)");
  }
  const nlohmann::json doc =
      nlohmann::json::parse(bytes.begin() + 20, bytes.begin() + 20 + json_length, nullptr, false);
  try {
    if (doc.is_discarded()) throw std::invalid_argument("its JSON chunk is not JSON");
    const nlohmann::json& primitive = doc.at("meshes").at(0).at("primitives").at(0);
    const nlohmann::json& attributes = primitive.at("attributes");
    const nlohmann::json& position = doc.at("accessors").at(attributes.at("POSITION").get<std::size_t>());
    out.vertices = position.at("count").get<std::size_t>();
    if (position.contains("min") && position.contains("max")) {
      const auto corner = [](const nlohmann::json& a) {
        return Eigen::Vector3f(a.at(0).get<float>(), a.at(1).get<float>(), a.at(2).get<float>());
      };
      out.bounds.extend(corner(position.at("min")));
      out.bounds.extend(corner(position.at("max")));
    }
    out.normals = attributes.contains("NORMAL");
    out.colours = attributes.contains("COLOR_0");
    if (primitive.contains("indices") && primitive.value("mode", 4) == 4) {
      out.triangles =
          doc.at("accessors").at(primitive.at("indices").get<std::size_t>()).at("count").get<std::size_t>() / 3;
    }
    const nlohmann::json& node = doc.at("nodes").at(0);
    if (node.contains("rotation")) {
      const nlohmann::json& q = node.at("rotation");
      out.node_rotation = Eigen::Quaternionf(q.at(3).get<float>(), q.at(0).get<float>(),
                                             q.at(1).get<float>(), q.at(2).get<float>());
    }
  } catch (const std::exception& e) {
    throw InputError(path, std::string("is not a glTF file objscan can describe: ") + e.what());
  }
}

}  // namespace

MeshFileSummary summarizeMeshFile(const std::filesystem::path& path) {
  const std::string extension = lowercaseExtension(path);
  if (extension != ".obj" && extension != ".stl" && extension != ".glb") {
    throw InputError(path, "is not named .obj, .stl or .glb");
  }
  MeshFileSummary out;
  const std::string bytes = readWholeFile(path, kMaxMeshFileBytes);
  if (extension == ".obj") {
    out.format = MeshFormat::kObj;
    summarizeObj(path, bytes, out);
  } else if (extension == ".stl") {
    out.format = MeshFormat::kStl;
    summarizeStl(path, bytes, out);
  } else {
    out.format = MeshFormat::kGlb;
    summarizeGlb(path, bytes, out);
  }
  return out;
}

}  // namespace objscan
