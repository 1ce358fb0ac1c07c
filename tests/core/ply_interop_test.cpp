// PLY files cross between objscan and the libraries people use: files written by PCL and Open3D
// read correctly here, and files written here read correctly there (label: interop).

#include <gtest/gtest.h>

#include <open3d/geometry/TriangleMesh.h>
#include <open3d/io/TriangleMeshIO.h>
#include <pcl/PolygonMesh.h>
#include <pcl/conversions.h>
#include <pcl/io/ply_io.h>
#include <pcl/point_types.h>

#include "objscan/core/atomic_file.h"
#include "objscan/core/mesh_formats.h"
#include "objscan/core/ply_io.h"
#include "test_support.h"

namespace objscan {
namespace {

/// A mesh with normals and colours whose floats survive PCL's 5-digit ASCII output within 1e-5.
TriangleMesh sampleMesh() {
  TriangleMesh m = testing::makeRandomMesh(21, 300, 500);
  for (auto& p : m.positions) p = p.cwiseMax(-1.0f).cwiseMin(1.0f);  // no huge or tiny values
  return m;
}

pcl::PolygonMesh toPcl(const TriangleMesh& m) {
  pcl::PointCloud<pcl::PointXYZRGBNormal> cloud;
  for (std::size_t i = 0; i < m.positions.size(); ++i) {
    pcl::PointXYZRGBNormal p;
    p.x = m.positions[i].x();
    p.y = m.positions[i].y();
    p.z = m.positions[i].z();
    p.normal_x = m.normals[i].x();
    p.normal_y = m.normals[i].y();
    p.normal_z = m.normals[i].z();
    p.r = m.colors[i][0];
    p.g = m.colors[i][1];
    p.b = m.colors[i][2];
    cloud.push_back(p);
  }
  pcl::PolygonMesh mesh;
  pcl::toPCLPointCloud2(cloud, mesh.cloud);
  for (const auto& t : m.triangles) {
    pcl::Vertices v;
    v.vertices = {t[0], t[1], t[2]};
    mesh.polygons.push_back(v);
  }
  return mesh;
}

void expectClose(const TriangleMesh& expected, const TriangleMesh& actual, float tol) {
  ASSERT_EQ(actual.positions.size(), expected.positions.size());
  ASSERT_EQ(actual.triangles, expected.triangles);
  ASSERT_EQ(actual.hasNormals(), expected.hasNormals());
  ASSERT_EQ(actual.hasColors(), expected.hasColors());
  for (std::size_t i = 0; i < expected.positions.size(); ++i) {
    ASSERT_LE((actual.positions[i] - expected.positions[i]).cwiseAbs().maxCoeff(), tol)
        << "vertex " << i;
    if (expected.hasNormals()) {
      ASSERT_LE((actual.normals[i] - expected.normals[i]).cwiseAbs().maxCoeff(), tol);
    }
    if (expected.hasColors()) {
      ASSERT_EQ(actual.colors[i], expected.colors[i]) << "vertex " << i;
    }
  }
}

TEST(PlyInterop, ReadsPclBinaryAndAsciiFiles) {
  testing::TempDir dir;
  const TriangleMesh m = sampleMesh();
  const pcl::PolygonMesh pm = toPcl(m);
  ASSERT_EQ(pcl::io::savePLYFileBinary((dir / "pcl_bin.ply").string(), pm), 0);
  ASSERT_EQ(pcl::io::savePLYFile((dir / "pcl_ascii.ply").string(), pm, 8), 0);
  expectClose(m, readPly(dir / "pcl_bin.ply"), 0.0f);
  // PCL prints ASCII with the requested 8 significant digits: within 1e-7 for |values| <= 1.
  expectClose(m, readPly(dir / "pcl_ascii.ply"), 1e-7f);
}

TEST(PlyInterop, ReadsOpen3DBinaryAndAsciiFiles) {
  testing::TempDir dir;
  const TriangleMesh m = sampleMesh();
  open3d::geometry::TriangleMesh om;
  for (std::size_t i = 0; i < m.positions.size(); ++i) {
    om.vertices_.push_back(m.positions[i].cast<double>());
    om.vertex_normals_.push_back(m.normals[i].cast<double>());
    om.vertex_colors_.push_back(m.colors[i].cast<double>() / 255.0);
  }
  for (const auto& t : m.triangles) om.triangles_.push_back(t);
  ASSERT_TRUE(open3d::io::WriteTriangleMesh((dir / "o3d_bin.ply").string(), om, false));
  ASSERT_TRUE(open3d::io::WriteTriangleMesh((dir / "o3d_ascii.ply").string(), om, true));
  // Open3D writes doubles (binary: exact for our floats) and 0..255 colours.
  expectClose(m, readPly(dir / "o3d_bin.ply"), 0.0f);
  expectClose(m, readPly(dir / "o3d_ascii.ply"), 1e-6f);
}

TEST(PlyInterop, PclAndOpen3DReadWhatObjscanWrites) {
  testing::TempDir dir;
  const TriangleMesh m = sampleMesh();
  for (const PlyFormat format : {PlyFormat::kBinaryLittleEndian, PlyFormat::kAscii}) {
    SCOPED_TRACE(toString(format));
    writePly(dir / "ours.ply", m, format);

    open3d::geometry::TriangleMesh om;
    ASSERT_TRUE(open3d::io::ReadTriangleMesh((dir / "ours.ply").string(), om));
    ASSERT_EQ(om.vertices_.size(), m.positions.size());
    ASSERT_EQ(om.triangles_.size(), m.triangles.size());
    for (std::size_t i = 0; i < m.positions.size(); ++i) {
      ASSERT_EQ(om.vertices_[i].cast<float>(), m.positions[i]);
      ASSERT_EQ(om.vertex_normals_[i].cast<float>(), m.normals[i]);
      ASSERT_EQ((om.vertex_colors_[i] * 255.0).array().round().cast<int>().matrix(),
                m.colors[i].cast<int>());
    }
    for (std::size_t t = 0; t < m.triangles.size(); ++t)
      ASSERT_EQ(om.triangles_[t], m.triangles[t]);

    pcl::PolygonMesh pm;
    ASSERT_EQ(pcl::io::loadPLYFile((dir / "ours.ply").string(), pm), 0);
    pcl::PointCloud<pcl::PointXYZRGBNormal> cloud;
    pcl::fromPCLPointCloud2(pm.cloud, cloud);
    ASSERT_EQ(cloud.size(), m.positions.size());
    ASSERT_EQ(pm.polygons.size(), m.triangles.size());
    for (std::size_t i = 0; i < m.positions.size(); ++i) {
      ASSERT_EQ(cloud[i].getVector3fMap(), m.positions[i]);
      ASSERT_EQ(cloud[i].getNormalVector3fMap(), m.normals[i]);
      ASSERT_EQ(Rgb8(cloud[i].r, cloud[i].g, cloud[i].b), m.colors[i]);
    }
    for (std::size_t t = 0; t < m.triangles.size(); ++t) {
      for (int k = 0; k < 3; ++k)
        ASSERT_EQ(static_cast<int>(pm.polygons[t].vertices[k]), m.triangles[t][k]);
    }
  }
}

TEST(MeshFormatInterop, Open3DReadsTheObjStlAndGlbObjscanWrites) {
  // objects/rank_NNN.{obj,stl,glb} (discover --object-format): Open3D reads them through its own
  // OBJ and STL readers and tinygltf. OBJ and glTF keep vertices as written; STL has three
  // corners per triangle.
  testing::TempDir dir;
  const TriangleMesh m = sampleMesh();
  for (const MeshFormat format : {MeshFormat::kObj, MeshFormat::kStl, MeshFormat::kGlb}) {
    SCOPED_TRACE(toString(format));
    const auto file = dir / ("ours" + extensionOf(format));
    writeFileAtomically(file, encodeMesh(m, format));
    open3d::geometry::TriangleMesh om;
    ASSERT_TRUE(open3d::io::ReadTriangleMesh(file.string(), om));
    ASSERT_EQ(om.triangles_.size(), m.triangles.size());
    for (std::size_t t = 0; t < m.triangles.size(); ++t) {
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3f read = om.vertices_[om.triangles_[t][k]].cast<float>();
        ASSERT_LT((read - m.positions[m.triangles[t][k]]).norm(), 1e-6f) << t;
      }
    }
    if (format == MeshFormat::kStl) continue;
    // Colours, corner by corner (Open3D's OBJ reader may order the vertices its own way).
    ASSERT_EQ(om.vertex_colors_.size(), om.vertices_.size());
    for (std::size_t t = 0; t < m.triangles.size(); ++t) {
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d c = om.vertex_colors_[om.triangles_[t][k]] * 255.0;
        ASSERT_EQ(c.array().round().cast<int>().matrix(), m.colors[m.triangles[t][k]].cast<int>())
            << t;
      }
    }
  }
}

}  // namespace
}  // namespace objscan
