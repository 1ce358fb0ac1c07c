#pragma once

#include <Eigen/Core>

#include "objscan/core/triangle_mesh.h"

/// Which way a scene mesh is up, from its faces alone: what the overview picture's camera
/// (render/snapshots.h) and the glTF objects (core/mesh_formats.h, Y-up) both need.
namespace objscan {

/// How the mesh's faces are oriented, from one pass over them.
struct FaceNormals {
  /// The area-weighted normal (by winding), flipped to agree with the vertex normals when the
  /// mesh has them (fusion's normals point to free space, the sensor's side).
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();  ///< sum of area * n n^T
};

FaceNormals faceNormals(const TriangleMesh& mesh);

/// sceneUp's direction from the face normals (see there).
Eigen::Vector3f upOf(const FaceNormals& normals);

/// The world's up direction as the scene shows it: the axis of the dominant surface orientation
/// (the eigenvector of the area-weighted normal scatter with the largest eigenvalue: the table or
/// the floor in the scenes objscan is for), turned towards the side the surfaces face. Throws
/// std::invalid_argument for a mesh without a triangle of positive area.
Eigen::Vector3f sceneUp(const TriangleMesh& mesh);

}  // namespace objscan
