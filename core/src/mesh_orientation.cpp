#include "objscan/core/mesh_orientation.h"

#include <stdexcept>

#include <Eigen/Eigenvalues>

namespace objscan {

FaceNormals faceNormals(const TriangleMesh& mesh) {
  FaceNormals out;
  Eigen::Vector3d& sum = out.mean;
  Eigen::Vector3d vertex_sum = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3i& t : mesh.triangles) {
    const Eigen::Vector3d a = mesh.positions[t[0]].cast<double>();
    const Eigen::Vector3d cross =
        (mesh.positions[t[1]].cast<double>() - a).cross(mesh.positions[t[2]].cast<double>() - a);
    const double twice_area = cross.norm();
    if (!(twice_area > 0.0)) continue;
    sum += cross;  // = 2 area * unit normal
    out.scatter += cross * cross.transpose() / twice_area;
    if (!mesh.normals.empty()) {
      vertex_sum += (mesh.normals[t[0]] + mesh.normals[t[1]] + mesh.normals[t[2]]).cast<double>();
    }
  }
  if (!mesh.normals.empty() && sum.dot(vertex_sum) < 0.0) sum = -sum;
  return out;
}

Eigen::Vector3f upOf(const FaceNormals& normals) {
  if (!(normals.scatter.trace() > 0.0)) {
    throw std::invalid_argument("snapshot: the mesh has no triangle of positive area");
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(normals.scatter);
  Eigen::Vector3d up = solver.eigenvectors().col(2);  // largest eigenvalue last
  if (up.dot(normals.mean) < 0.0) up = -up;
  return up.cast<float>().normalized();
}

Eigen::Vector3f sceneUp(const TriangleMesh& mesh) { return upOf(faceNormals(mesh)); }

}  // namespace objscan
