#pragma once

#include <string>

#include "objscan/core/triangle_mesh.h"
#include "objscan/fusion/tsdf_volume.h"

namespace objscan::fusion {

/// The zero level set of the volume as a triangle mesh in the world frame (Lorensen and Cline's
/// marching cubes over the allocated blocks; cubes with an unobserved corner are skipped).
/// Vertices sit on the grid edges where the distance changes sign and are shared by every
/// triangle using that edge (no duplicate vertices); triangles with a repeated vertex or zero
/// area are dropped. Triangles are counter-clockwise seen from the positive (free, observed) side,
/// and normals, the area-weighted mean of the adjacent triangles', point there too: outward, toward
/// where the sensor was. Colours are interpolated along the edges, and so are the voxels' weights
/// (observations, capped at VolumeConfig::max_weight) into TriangleMesh::weights, which every
/// extracted mesh has: each lies in [1, max_weight].
///
/// Written here rather than taken from a library: VTK's and PCL's marching cubes need a dense
/// grid, and Open3D's works only on its own volume types. The case table is generated at start-up
/// from the cube's faces (see the .cpp) instead of being typed in.
/// `progress_label` non-empty: a progress bar (with the time left) over both passes, for fine
/// volumes that take many seconds.
TriangleMesh extractMesh(const TsdfVolume& volume, const std::string& progress_label = {});

}  // namespace objscan::fusion
