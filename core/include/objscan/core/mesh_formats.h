#pragma once

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
std::string encodeMesh(const TriangleMesh& mesh, MeshFormat format);

}  // namespace objscan
