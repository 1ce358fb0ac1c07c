#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include "objscan/core/triangle_mesh.h"

/// Mesh files other than PLY, for handing objects to other tools: Wavefront OBJ (MeshLab,
/// CloudCompare, Blender; vertex colours as the common "v x y z r g b" extension), binary STL
/// (printers and CAD; geometry only) and binary glTF 2.0 (.glb: every browser's three.js,
/// Blender, Windows' 3D viewer; positions, normals, vertex colours).
///
/// Written by hand: Debian 12 packages no small glTF writer (tinygltf and cgltf are absent), and
/// Assimp, which writes all three, would add a large library for three formats of a page each.
namespace objscan {

enum class MeshFormat { kPly, kObj, kStl, kGlb };

/// "ply", "obj", "stl" or "glb"; throws std::invalid_argument naming the choices otherwise.
MeshFormat meshFormatFromName(std::string_view name);
const char* toString(MeshFormat format);
/// ".ply", ".obj", ".stl", ".glb".
std::string extensionOf(MeshFormat format);

/// The file's bytes. PLY is binary little-endian (encodePly). Throws std::invalid_argument for a
/// mesh that fails TriangleMesh::validate().
///
/// `up`: the scene's up direction in the mesh's frame (sceneUp of the scene an object was cut
/// from). glTF is Y-up (its specification: "+Y is up"), so a GLB's one node then carries the
/// rotation that turns `up` onto +Y, and the object stands in any glTF viewer as it stood in the
/// scene; without it, an object of a z-up scene lies on its back. The positions stay in the
/// mesh's frame (objects/rank_NNN.json's T_W_O holds for them). PLY, OBJ and STL have no
/// convention of up and ignore it.
std::string encodeMesh(const TriangleMesh& mesh, MeshFormat format,
                       const std::optional<Eigen::Vector3f>& up = std::nullopt);

/// What `objscan info` says of an OBJ, STL or GLB file: counted from the file, not a mesh.
struct MeshFileSummary {
  MeshFormat format = MeshFormat::kObj;
  std::size_t vertices = 0;   ///< STL: three per triangle (STL shares none)
  std::size_t triangles = 0;  ///< 0: points
  bool normals = false, colours = false;
  Eigen::AlignedBox3f bounds;  ///< of the positions as stored (before a glTF node's transform)
  /// GLB only: the first node's "rotation" (x, y, z, w), as a viewer applies it; nothing: none.
  std::optional<Eigen::Quaternionf> node_rotation;
};

/// Reads an OBJ, binary STL or GLB file far enough to count and bound it (the format from the
/// extension). Throws InputError naming the file when it is cut short or not of that format.
MeshFileSummary summarizeMeshFile(const std::filesystem::path& path);

}  // namespace objscan
