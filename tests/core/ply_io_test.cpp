#include "objscan/core/ply_io.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "objscan/core/error.h"
#include "test_support.h"

namespace objscan {
namespace {

using testing::TempDir;
using testing::writeBytes;

/// Binary encoding helper for hand-made files: values appended in the given byte order.
struct Bytes {
  bool big_endian = false;
  std::string data;
  template <class T>
  Bytes& put(T v) {
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    if (big_endian) std::reverse(b, b + sizeof(T));
    data.append(b, sizeof(T));
    return *this;
  }
};

/// Expects readPly to throw an InputError whose message starts with the path and contains `needle`.
void expectReadError(const std::filesystem::path& path, const std::string& needle) {
  testing::expectInputError([&] { readPly(path); }, path, needle);
}

class PlyRoundTrip : public ::testing::TestWithParam<PlyFormat> {};

TEST_P(PlyRoundTrip, PositionsNormalsColoursAndFacesAreBitExact) {
  TempDir dir;
  const TriangleMesh mesh = testing::makeRandomMesh(7, 500, 900);
  writePly(dir / "m.ply", mesh, GetParam());
  const TriangleMesh back = readPly(dir / "m.ply");
  EXPECT_TRUE(testing::bitwiseEqual(mesh, back));
}

TEST_P(PlyRoundTrip, MeshesWithoutNormalsOrColoursStayWithout) {
  TempDir dir;
  for (int variant = 0; variant < 4; ++variant) {
    const TriangleMesh mesh = testing::makeRandomMesh(11, 40, 60, variant & 1, variant & 2);
    writePly(dir / "m.ply", mesh, GetParam());
    const TriangleMesh back = readPly(dir / "m.ply");
    EXPECT_TRUE(testing::bitwiseEqual(mesh, back)) << "variant " << variant;
    EXPECT_EQ(back.hasNormals(), mesh.hasNormals());
    EXPECT_EQ(back.hasColors(), mesh.hasColors());
  }
}

TEST_P(PlyRoundTrip, PointCloudWithoutFacesReadsAsMeshWithoutTriangles) {
  TempDir dir;
  TriangleMesh cloud = testing::makeRandomMesh(3, 25, 0);
  writePly(dir / "c.ply", cloud, GetParam());
  PlyReadReport report;
  const TriangleMesh back = readPly(dir / "c.ply", &report);
  EXPECT_TRUE(testing::bitwiseEqual(cloud, back));
  EXPECT_EQ(report.faces, 0u);
}

TEST_P(PlyRoundTrip, WeightsAndIgnoreFlagsAreBitExact) {
  TempDir dir;
  TriangleMesh mesh = testing::makeRandomMesh(13, 40, 60);
  // Awkward floats first (zero, subnormal, a third, the largest finite), then fusion-like counts.
  const float awkward[] = {0.0f, 1.4e-45f, 1.0f / 3.0f, std::numeric_limits<float>::max()};
  for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
    mesh.weights.push_back(i < std::size(awkward) ? awkward[i]
                                                  : 1.0f + 0.37f * static_cast<float>(i));
    mesh.ignore.push_back(i % 3 == 0 ? 1 : 0);
  }
  writePly(dir / "m.ply", mesh, GetParam());
  const TriangleMesh back = readPly(dir / "m.ply");
  EXPECT_TRUE(testing::bitwiseEqual(mesh, back));
  EXPECT_EQ(back.labels, mesh.labels);
  // Either alone, and the header names them as MeshLab and CloudCompare expect.
  mesh.ignore.clear();
  writePly(dir / "w.ply", mesh, GetParam());
  PlyReadReport report;
  EXPECT_TRUE(testing::bitwiseEqual(mesh, readPly(dir / "w.ply", &report)));
  ASSERT_EQ(report.header.elements.size(), 2u);
  const auto& props = report.header.elements[0].properties;
  ASSERT_FALSE(props.empty());
  EXPECT_EQ(props.back().name, "quality");
  EXPECT_EQ(props.back().type, "float");
  mesh.weights.clear();
  mesh.ignore.assign(mesh.positions.size(), 1);
  writePly(dir / "i.ply", mesh, GetParam());
  EXPECT_TRUE(testing::bitwiseEqual(mesh, readPly(dir / "i.ply", &report)));
  EXPECT_EQ(report.header.elements[0].properties.back().name, "ignore");
  EXPECT_EQ(report.header.elements[0].properties.back().type, "uchar");
}

INSTANTIATE_TEST_SUITE_P(AllFormats, PlyRoundTrip,
                         ::testing::Values(PlyFormat::kAscii, PlyFormat::kBinaryLittleEndian,
                                           PlyFormat::kBinaryBigEndian),
                         [](const ::testing::TestParamInfo<PlyFormat>& p) {
                           return std::string(toString(p.param));
                         });

TEST(PlyIo, ReadsPropertiesInAnyOrderAndIgnoresExtras) {
  TempDir dir;
  writeBytes(
      dir / "m.ply",
      "ply\r\nformat ascii 1.0\r\ncomment hand made\r\nobj_info order test\r\n"
      "element vertex 3\r\n"
      "property uchar red\r\nproperty float nx\r\nproperty double z\r\nproperty float quality\r\n"
      "property float x\r\nproperty list uchar float extra\r\nproperty float y\r\nproperty uchar "
      "alpha\r\n"
      "property uchar green\r\nproperty float ny\r\nproperty uchar blue\r\nproperty float nz\r\n"
      "element edge 1\r\nproperty int vertex1\r\nproperty int vertex2\r\n"
      "element face 1\r\nproperty int flags\r\nproperty list int int vertex_indices\r\n"
      "end_header\r\n"
      "10 1 3.5 0.25 1.5 2 9 9 2.5 255 20 0 30 0\r\n"
      "11 0 -3 0 -1 0 -2 7 21 1 31 0\r\n"
      "12 0 0 0 0 1 5 0 0 22 0 32 1\r\n"
      "0 1\r\n"
      "77 3 2 1 0\r\n");
  PlyReadReport report;
  const TriangleMesh m = readPly(dir / "m.ply", &report);
  ASSERT_EQ(m.positions.size(), 3u);
  EXPECT_EQ(m.positions[0], Eigen::Vector3f(1.5f, 2.5f, 3.5f));
  EXPECT_EQ(m.positions[1], Eigen::Vector3f(-1.0f, -2.0f, -3.0f));
  EXPECT_EQ(m.positions[2], Eigen::Vector3f(0.0f, 0.0f, 0.0f));
  EXPECT_EQ(m.normals[0], Eigen::Vector3f(1, 0, 0));
  EXPECT_EQ(m.normals[1], Eigen::Vector3f(0, 1, 0));
  EXPECT_EQ(m.normals[2], Eigen::Vector3f(0, 0, 1));
  EXPECT_EQ(m.colors[0], Rgb8(10, 20, 30));
  EXPECT_EQ(m.colors[2], Rgb8(12, 22, 32));
  ASSERT_EQ(m.triangles.size(), 1u);
  EXPECT_EQ(m.triangles[0], Eigen::Vector3i(2, 1, 0));
  EXPECT_EQ(m.weights, (std::vector<float>{0.25f, 0.0f, 0.0f}));
  EXPECT_EQ(report.header.comments.size(), 2u);
  const std::vector<std::string> ignored = {"vertex.extra", "vertex.alpha", "edge", "face.flags"};
  EXPECT_EQ(report.ignored, ignored);
}

TEST(PlyIo, ReadsEveryNumericTypeAndIntListCounts) {
  TempDir dir;
  for (const bool big : {false, true}) {
    Bytes b{big, ""};
    b.put<double>(0.125)
        .put<std::int16_t>(-7)
        .put<std::uint32_t>(4000000000u)
        .put<float>(0.5f)
        .put<float>(0.25f)
        .put<float>(1.0f);
    b.put<double>(1.0)
        .put<std::int16_t>(2)
        .put<std::uint32_t>(3)
        .put<float>(0.0f)
        .put<float>(0.0f)
        .put<float>(0.5f);
    b.put<double>(2.0)
        .put<std::int16_t>(3)
        .put<std::uint32_t>(4)
        .put<float>(1.0f)
        .put<float>(1.0f)
        .put<float>(0.0f);
    b.put<std::int32_t>(3).put<std::uint32_t>(0).put<std::uint32_t>(1).put<std::uint32_t>(2);
    writeBytes(dir / "t.ply",
               std::string("ply\nformat ") + (big ? "binary_big_endian" : "binary_little_endian") +
                   " 1.0\nelement vertex 3\nproperty float64 x\nproperty int16 y\nproperty uint z\n"
                   "property float32 red\nproperty float green\nproperty float blue\n"
                   "element face 1\nproperty list int uint vertex_indices\nend_header\n" +
                   b.data);
    const TriangleMesh m = readPly(dir / "t.ply");
    ASSERT_EQ(m.positions.size(), 3u) << (big ? "big" : "little");
    EXPECT_EQ(m.positions[0], Eigen::Vector3f(0.125f, -7.0f, 4e9f));
    EXPECT_EQ(m.colors[0], Rgb8(128, 64, 255)) << "float colours are 0..1";
    EXPECT_EQ(m.triangles[0], Eigen::Vector3i(0, 1, 2));
  }
}

TEST(PlyIo, ReadsCharUshortAndIntScalarsWithUshortColoursScaled) {
  TempDir dir;
  for (const bool big : {false, true}) {
    Bytes b{big, ""};
    b.put<std::int8_t>(-128).put<std::uint16_t>(65535).put<std::int32_t>(-2147483647);
    b.put<std::uint16_t>(65535).put<std::uint16_t>(0).put<std::uint16_t>(32896);  // 255, 0, 128
    writeBytes(dir / "t.ply", std::string("ply\nformat ") +
                                  (big ? "binary_big_endian" : "binary_little_endian") +
                                  " 1.0\nelement vertex 1\nproperty char x\nproperty ushort y\n"
                                  "property int32 z\nproperty ushort red\nproperty uint16 green\n"
                                  "property ushort blue\nend_header\n" +
                                  b.data);
    const TriangleMesh m = readPly(dir / "t.ply");
    EXPECT_EQ(m.positions[0], Eigen::Vector3f(-128.0f, 65535.0f, -2147483647.0f));
    EXPECT_EQ(m.colors[0], Rgb8(255, 0, 128));
  }
}

TEST(PlyIo, PolygonsAreFanTriangulatedAndDegenerateTrianglesDropped) {
  TempDir dir;
  writeBytes(dir / "p.ply",
             "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float "
             "y\nproperty float z\n"
             "element face 3\nproperty list uchar int vertex_index\nend_header\n"
             "0 0 0\n1 0 0\n1 1 0\n0 1 0\n-1 1 0\n-1 0 0\n"
             "4 0 1 2 3\n5 0 1 2 3 4\n4 0 0 1 2\n");
  PlyReadReport report;
  const TriangleMesh m = readPly(dir / "p.ply", &report);
  const std::vector<Eigen::Vector3i> expected = {{0, 1, 2}, {0, 2, 3}, {0, 1, 2},
                                                 {0, 2, 3}, {0, 3, 4}, {0, 1, 2}};
  EXPECT_EQ(m.triangles, expected);
  EXPECT_EQ(report.faces, 3u);
  EXPECT_EQ(report.degenerate_dropped, 1u);  // (0, 0, 1) of the last quad
}

TEST(PlyIo, MeshLabLayoutWithCameraQualityAndFaceColoursIsRead) {
  // The layout of VCGLIB's PLY exporter (MeshLab's writer), with every optional part that sits
  // around what we read: binary little endian, "comment VCGLIB generated", a camera element before
  // the vertices (21 floats, 2 ints), vertex colour with alpha and a quality value, per-face flags
  // and colour after vertex_indices, and an edge element at the end.
  TempDir dir;
  const TriangleMesh cube = testing::makeCube(0.2f);
  Bytes b;
  for (int k = 0; k < 17; ++k) b.put<float>(static_cast<float>(k));
  b.put<std::int32_t>(640).put<std::int32_t>(480);
  for (int k = 0; k < 4; ++k) b.put<float>(0.0f);
  for (std::size_t i = 0; i < cube.positions.size(); ++i) {
    for (int k = 0; k < 3; ++k) b.put<float>(cube.positions[i][k]);
    const Eigen::Vector3f n = cube.positions[i].normalized();
    for (int k = 0; k < 3; ++k) b.put<float>(n[k]);
    b.put<std::uint8_t>(static_cast<std::uint8_t>(i * 30))
        .put<std::uint8_t>(7)
        .put<std::uint8_t>(200)
        .put<std::uint8_t>(255)
        .put<float>(0.5f);  // quality
  }
  for (const auto& t : cube.triangles) {
    b.put<std::uint8_t>(3).put<std::int32_t>(t[0]).put<std::int32_t>(t[1]).put<std::int32_t>(t[2]);
    b.put<std::int32_t>(0);  // flags
    b.put<std::uint8_t>(1).put<std::uint8_t>(2).put<std::uint8_t>(3).put<std::uint8_t>(4);
  }
  b.put<std::int32_t>(0).put<std::int32_t>(1);  // one edge
  std::string camera = "element camera 1\n";
  for (const char* name : {"view_px", "view_py", "view_pz", "x_axisx", "x_axisy", "x_axisz",
                           "y_axisx", "y_axisy", "y_axisz", "z_axisx", "z_axisy", "z_axisz",
                           "focal", "scalex", "scaley", "centerx", "centery"}) {
    camera += std::string("property float ") + name + "\n";
  }
  camera += "property int viewportx\nproperty int viewporty\n";
  for (const char* name : {"k1", "k2", "k3", "k4"})
    camera += std::string("property float ") + name + "\n";
  writeBytes(
      dir / "meshlab.ply",
      "ply\nformat binary_little_endian 1.0\ncomment VCGLIB generated\n" + camera +
          "element vertex 8\n"
          "property float x\nproperty float y\nproperty float z\nproperty float nx\n"
          "property float ny\nproperty float nz\nproperty uchar red\nproperty uchar green\n"
          "property uchar blue\nproperty uchar alpha\nproperty float quality\n"
          "element face 12\nproperty list uchar int vertex_indices\nproperty int flags\n"
          "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n"
          "element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n" +
          b.data);
  PlyReadReport report;
  const TriangleMesh m = readPly(dir / "meshlab.ply", &report);
  EXPECT_EQ(m.positions, cube.positions);
  EXPECT_EQ(m.triangles, cube.triangles);
  EXPECT_EQ(m.colors[3], Rgb8(90, 7, 200));
  EXPECT_NEAR(m.normals[5].norm(), 1.0f, 1e-6f);
  EXPECT_EQ(m.weights, std::vector<float>(8, 0.5f)) << "MeshLab's quality is read as the weight";
  const std::vector<std::string> ignored = {"camera",     "vertex.alpha", "face.flags", "face.red",
                                            "face.green", "face.blue",    "face.alpha", "edge"};
  EXPECT_EQ(report.ignored, ignored);
}

TEST(PlyIo, EveryTruncationIsAnErrorNamingTheFile) {
  TempDir dir;
  const TriangleMesh mesh = testing::makeRandomMesh(5, 6, 4);
  for (const PlyFormat format : {PlyFormat::kAscii, PlyFormat::kBinaryLittleEndian}) {
    writePly(dir / "whole.ply", mesh, format);
    const std::string bytes = testing::readBytes(dir / "whole.ply");
    ASSERT_NO_THROW(readPly(dir / "whole.ply"));
    // An ASCII file cut inside its last value, or just before its final line break, reads as a
    // file without a final line break does (MeshLab and Open3D read those): with a warning,
    // reported as unterminated_last_value.
    const std::size_t last_value = bytes.find_last_of(" \n", bytes.size() - 2) + 1;
    for (std::size_t size = 0; size < bytes.size(); ++size) {
      const auto cut = dir / "cut.ply";
      writeBytes(cut, bytes.substr(0, size));
      if (format == PlyFormat::kAscii && size > last_value) {
        PlyReadReport report;
        EXPECT_NO_THROW(readPly(cut, &report)) << "cut at byte " << size;
        EXPECT_TRUE(report.unterminated_last_value.has_value()) << "cut at byte " << size;
        continue;
      }
      EXPECT_THROW(
          {
            try {
              readPly(cut);
            } catch (const InputError& e) {
              EXPECT_EQ(std::string(e.what()).rfind(cut.string() + ": ", 0), 0u) << e.what();
              throw;
            }
          },
          InputError)
          << toString(format) << " cut at byte " << size << " of " << bytes.size();
    }
  }
}

TEST(PlyIo, TruncationMessagesSayWhereTheDataEnds) {
  TempDir dir;
  writeBytes(dir / "a.ply",
             "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float "
             "y\nproperty float z\n"
             "end_header\n0 0 0\n1 1    ");
  expectReadError(dir / "a.ply", "vertex 1 of 2, property 'z' (line 9): the file ends early");
  writeBytes(dir / "h.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty fl");
  expectReadError(dir / "h.ply", "no 'end_header' line");
}

TEST(PlyIo, FaceIndexOutOfRangeIsAnError) {
  TempDir dir;
  const std::string header =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float "
      "z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n";
  writeBytes(dir / "oor.ply", header + "3 0 1 3\n");
  expectReadError(dir / "oor.ply",
                  "face 0 of 1, property 'vertex_indices' (line 13): it refers to vertex 3, but "
                  "the file has 3 vertices");
  writeBytes(dir / "neg.ply", header + "3 0 -1 2\n");
  expectReadError(dir / "neg.ply", "refers to vertex -1");
  writeBytes(dir / "two.ply", header + "2 0 1\n\n\n\n");
  expectReadError(dir / "two.ply", "a face needs at least 3 vertex indices");
}

TEST(PlyIo, NanOrInfiniteCoordinatesAreAnError) {
  TempDir dir;
  const std::string header =
      "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float "
      "z\nend_header\n";
  writeBytes(dir / "nan.ply", header + "0 0 0\n1 nan 1\n");
  expectReadError(dir / "nan.ply", "vertex 1 has a non-finite position");
  writeBytes(dir / "inf.ply", header + "0 0 0\n1 1 -inf\n");
  expectReadError(dir / "inf.ply", "vertex 1 has a non-finite position");

  Bytes b;
  b.put<float>(0)
      .put<float>(0)
      .put<float>(0)
      .put<float>(std::numeric_limits<float>::quiet_NaN())
      .put<float>(0)
      .put<float>(0);
  writeBytes(
      dir / "nan_bin.ply",
      "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
      "property float z\nend_header\n" +
          b.data);
  expectReadError(dir / "nan_bin.ply", "vertex 1 has a non-finite position");
}

TEST(PlyIo, CorruptHeadersAreErrors) {
  TempDir dir;
  struct Case {
    std::string text;
    std::string needle;
  };
  const std::string xyz = "property float x\nproperty float y\nproperty float z\n";
  const std::vector<Case> cases = {
      {"plx\nformat ascii 1.0\nend_header\n", "not a PLY file"},
      {"OFF\n8 12 0\n", "not a PLY file"},
      {"ply\nformat utf8 1.0\nend_header\n", "unknown format 'utf8'"},
      {"ply\nformat ascii 2.0\nend_header\n", "unsupported PLY version"},
      {"ply\nelement vertex 1\n" + xyz + "end_header\n0 0 0\n", "no 'format' line"},
      {"ply\nformat ascii 1.0\nproperty float x\nend_header\n", "property before any element"},
      {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n",
       "unknown type 'float128'"},
      {"ply\nformat ascii 1.0\nelement vertex -1\n" + xyz + "end_header\n", "non-negative count"},
      {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 "
       "0\n",
       "lacks one of the properties x, y, z"},
      {"ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int "
       "vertex_indices\nend_header\n",
       "no 'vertex' element"},
      {"ply\nformat ascii 1.0\nelement vertex 1\n" + xyz + "weird line\nend_header\n",
       "unknown keyword 'weird'"},
      {"ply\nformat ascii 1.0\nelement vertex 1\n" + xyz +
           "element face 1\nproperty list float int vertex_indices\nend_header\n",
       "list count type 'float' must be an integer type"},
      {"ply\nformat ascii 1.0\nelement vertex 1\n" + xyz + "end_header\n0 zero 0\n",
       "'zero' is not a number"},
  };
  for (std::size_t i = 0; i < cases.size(); ++i) {
    SCOPED_TRACE("case " + std::to_string(i));
    writeBytes(dir / "bad.ply", cases[i].text);
    expectReadError(dir / "bad.ply", cases[i].needle);
  }
}

TEST(PlyIo, HugeCountsAreRejectedBeforeAllocating) {
  TempDir dir;
  // 10^15 vertices would need petabytes; the reader must refuse from the header alone.
  writeBytes(
      dir / "huge.ply",
      "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000000\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n" +
          std::string(12, '\0'));
  expectReadError(dir / "huge.ply",
                  "truncated: the header announces 1000000000000000 'vertex' elements");
  writeBytes(
      dir / "huge_ascii.ply",
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float "
      "z\n"
      "element face 99999999999\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n");
  expectReadError(dir / "huge_ascii.ply", "99999999999 'face'");
}

TEST(PlyIo, HugeListLengthsAreRejectedBeforeAllocating) {
  // One face claiming 4294967295 indices: refused from the bytes left, not after trying to
  // allocate 32 GB.
  TempDir dir;
  Bytes b;
  for (int k = 0; k < 9; ++k) b.put<float>(static_cast<float>(k));
  b.put<std::uint32_t>(4294967295u)
      .put<std::uint32_t>(0)
      .put<std::uint32_t>(1)
      .put<std::uint32_t>(2);
  const std::string xyz = "property float x\nproperty float y\nproperty float z\n";
  writeBytes(dir / "list.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 3\n" + xyz +
                                   "element face 1\nproperty list uint uint vertex_indices\n"
                                   "end_header\n" +
                                   b.data);
  expectReadError(dir / "list.ply",
                  "list length 4294967295 is more than the rest of the file can hold");
  writeBytes(dir / "list_ascii.ply",
             "ply\nformat ascii 1.0\nelement vertex 3\n" + xyz +
                 "element face 1\nproperty list uint int vertex_indices\nend_header\n"
                 "0 0 0\n1 0 0\n0 1 0\n4294967295 0 1 2\n");
  expectReadError(dir / "list_ascii.ply", "list length 4294967295 is more than");
  // The same for a list that is skipped rather than read.
  writeBytes(dir / "skipped.ply",
             "ply\nformat ascii 1.0\nelement vertex 1\n" + xyz +
                 "property list uint float extra\nend_header\n0 0 0 4000000000 1\n");
  expectReadError(dir / "skipped.ply", "list length 4000000000 is more than");
}

TEST(PlyIo, ElementsWithoutPropertiesCannotClaimRows) {
  // 2^64 - 1 rows of nothing would pass any size check and loop for ever.
  TempDir dir;
  writeBytes(dir / "junk.ply",
             "ply\nformat ascii 1.0\nelement junk 18446744073709551615\nelement vertex 1\n"
             "property float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n");
  expectReadError(dir / "junk.ply",
                  "element 'junk' declares 18446744073709551615 rows but no properties");
}

TEST(PlyIo, DataAfterTheLastElementIsIgnoredAndCounted) {
  // Issue 18, defect 10: MeshLab and Open3D read such files; objscan refused them. It now reads
  // them, counts what it ignored, and warns (a header that under-counts the vertices is the
  // usual cause).
  TempDir dir;
  Bytes b;
  for (int k = 0; k < 9; ++k) b.put<float>(static_cast<float>(k));
  writeBytes(dir / "extra.ply",
             "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\n"
             "property float y\nproperty float z\nend_header\n" +
                 b.data);
  PlyReadReport report;
  EXPECT_EQ(readPly(dir / "extra.ply", &report).positions.size(), 2u);
  EXPECT_EQ(report.trailing_bytes, 12u);
  const std::string xyz = "property float x\nproperty float y\nproperty float z\n";
  writeBytes(dir / "extra_ascii.ply", "ply\nformat ascii 1.0\nelement vertex 1\n" + xyz +
                                          "end_header\n0 0 0\n1 1 1\n  \n");
  EXPECT_EQ(readPly(dir / "extra_ascii.ply", &report).positions.size(), 1u);
  EXPECT_EQ(report.trailing_bytes, 9u);  // "1 1 1\n  \n" (the line break before it is skipped)
}

TEST(PlyIo, AnAsciiFileWithoutItsFinalLineBreakIsReadWithAWarning) {
  TempDir dir;
  const std::string xyz = "property float x\nproperty float y\nproperty float z\n";
  const std::string faces = "element face 1\nproperty list uchar int vertex_indices\n";
  writeBytes(dir / "a.ply", "ply\nformat ascii 1.0\nelement vertex 3\n" + xyz + faces +
                                "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2");
  PlyReadReport report;
  const TriangleMesh mesh = readPly(dir / "a.ply", &report);
  ASSERT_EQ(mesh.triangles.size(), 1u);
  EXPECT_EQ(mesh.triangles[0], Eigen::Vector3i(0, 1, 2));
  EXPECT_EQ(report.unterminated_last_value, std::optional<std::string>("2"));
  EXPECT_EQ(report.trailing_bytes, 0u);
}

TEST(PlyIo, AFaceOfFewerThanThreeIndicesIsNamedAsSuch) {
  // Was reported as "truncated" from the header's size estimate.
  TempDir dir;
  const std::string xyz = "property float x\nproperty float y\nproperty float z\n";
  const std::string faces = "element face 2\nproperty list uchar int vertex_indices\n";
  for (const std::string& face : {std::string("2 0 1"), std::string("0")}) {
    writeBytes(dir / "f.ply", "ply\nformat ascii 1.0\nelement vertex 3\n" + xyz + faces +
                                  "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n" + face + "\n");
    expectReadError(dir / "f.ply", "face 1 of 2, property 'vertex_indices' (line 14): a face needs "
                                   "at least 3 vertex indices, this one has " +
                                       face.substr(0, 1));
  }
}

TEST(PlyIo, MalformedValuesAndHeaderLinesAreErrors) {
  TempDir dir;
  const std::string xyz = "property float x\nproperty float y\nproperty float z\n";
  writeBytes(dir / "sign.ply",
             "ply\nformat ascii 1.0\nelement vertex 1\n" + xyz + "end_header\n0 +-5 0\n");
  expectReadError(dir / "sign.ply", "'+-5' is not a number");
  writeBytes(dir / "plus.ply",
             "ply\nformat ascii 1.0\nelement vertex 1\n" + xyz + "end_header\n0 +5 0\n");
  EXPECT_EQ(readPly(dir / "plus.ply").positions[0], Eigen::Vector3f(0, 5, 0));
  writeBytes(dir / "format2.ply",
             "ply\nformat ascii 1.0\nformat binary_little_endian 1.0\nelement vertex 1\n" + xyz +
                 "end_header\n0 0 0\n");
  expectReadError(dir / "format2.ply", "header line 3: a second 'format' line");
  writeBytes(dir / "endh.ply",
             "ply\nformat ascii 1.0\nelement vertex 1\n" + xyz + "end_header junk\n0 0 0\n");
  expectReadError(dir / "endh.ply", "unexpected text after 'end_header'");
  writeBytes(dir / "floatid.ply", "ply\nformat ascii 1.0\nelement vertex 1\n" + xyz +
                                      "property float object_id\nend_header\n0 0 0 1.5\n");
  expectReadError(dir / "floatid.ply", "vertex property 'object_id' must have an integer type");
  writeBytes(dir / "nancolour.ply",
             "ply\nformat ascii 1.0\nelement vertex 1\n" + xyz +
                 "property float red\nproperty float green\nproperty float blue\nend_header\n"
                 "0 0 0 0.5 nan 1\n");
  expectReadError(dir / "nancolour.ply", "a colour value is NaN");
}

TEST(PlyIo, LabelIsReadAsObjectIdsAndIgnoreAsFlags) {
  // The layout of a hand-labelled mesh: `label` (int) for the object ids, `ignore` (uchar) for the
  // vertices not to score, and a quality of another type.
  TempDir dir;
  for (const bool big : {false, true}) {
    Bytes b{big, ""};
    const std::int32_t labels[] = {0, 10, -3};
    const std::uint8_t ignore[] = {0, 1, 7};
    for (int i = 0; i < 3; ++i) {
      b.put<float>(static_cast<float>(i)).put<float>(static_cast<float>(i % 2)).put<float>(0.0f);
      b.put<std::int32_t>(labels[i]).put<std::uint8_t>(ignore[i]).put<double>(2.5 * i);
    }
    b.put<std::uint8_t>(3).put<std::int32_t>(0).put<std::int32_t>(1).put<std::int32_t>(2);
    writeBytes(dir / "l.ply", std::string("ply\nformat ") +
                                  (big ? "binary_big_endian" : "binary_little_endian") +
                                  " 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                  "property float z\nproperty int label\nproperty uchar ignore\n"
                                  "property double quality\nelement face 1\n"
                                  "property list uchar int vertex_indices\nend_header\n" +
                                  b.data);
    PlyReadReport report;
    const TriangleMesh m = readPly(dir / "l.ply", &report);
    EXPECT_EQ(m.labels, (std::vector<std::int32_t>{0, 10, -3})) << (big ? "big" : "little");
    EXPECT_EQ(m.ignore, (std::vector<std::uint8_t>{0, 1, 1})) << "any non-zero value is 1";
    EXPECT_EQ(m.weights, (std::vector<float>{0.0f, 2.5f, 5.0f}));
    EXPECT_TRUE(report.ignored.empty());
  }
  // ASCII, a ushort label.
  writeBytes(dir / "a.ply",
             "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
             "property float z\nproperty ushort label\nend_header\n0 0 0 40\n1 0 0 0\n");
  EXPECT_EQ(readPly(dir / "a.ply").labels, (std::vector<std::int32_t>{40, 0}));
}

TEST(PlyIo, LabelAndObjectIdTogetherOrFlagsOfAFloatTypeAreErrors) {
  TempDir dir;
  const std::string xyz = "property float x\nproperty float y\nproperty float z\n";
  writeBytes(dir / "both.ply", "ply\nformat ascii 1.0\nelement vertex 1\n" + xyz +
                                   "property int object_id\nproperty int label\nend_header\n"
                                   "0 0 0 1 2\n");
  expectReadError(dir / "both.ply", "both 'label' and 'object_id'");
  writeBytes(dir / "floatlabel.ply", "ply\nformat ascii 1.0\nelement vertex 1\n" + xyz +
                                         "property float label\nend_header\n0 0 0 1.5\n");
  expectReadError(dir / "floatlabel.ply", "vertex property 'label' must have an integer type");
  writeBytes(dir / "floatignore.ply", "ply\nformat ascii 1.0\nelement vertex 1\n" + xyz +
                                          "property float ignore\nend_header\n0 0 0 1\n");
  expectReadError(dir / "floatignore.ply", "vertex property 'ignore' must have an integer type");
}

TEST(PlyIo, AQualityThatCannotBeAWeightIsIgnored) {
  // MeshLab keeps any scalar in `quality` (curvature, say): a file whose values cannot be fusion
  // weights is read without them, not refused.
  TempDir dir;
  const std::string xyz = "property float x\nproperty float y\nproperty float z\n";
  for (const char* bad : {"-0.5", "nan", "inf"}) {
    writeBytes(dir / "q.ply", "ply\nformat ascii 1.0\nelement vertex 2\n" + xyz +
                                  "property float quality\nend_header\n0 0 0 1\n0 1 0 " + bad +
                                  "\n");
    PlyReadReport report;
    const TriangleMesh m = readPly(dir / "q.ply", &report);
    EXPECT_EQ(m.positions.size(), 2u) << bad;
    EXPECT_FALSE(m.hasWeights()) << bad;
    EXPECT_EQ(report.ignored, std::vector<std::string>{"vertex.quality"}) << bad;
  }
}

TEST(PlyIo, MissingEmptyAndDirectoryPathsAreErrors) {
  TempDir dir;
  expectReadError(dir / "absent.ply", "no such file or directory");
  writeBytes(dir / "empty.ply", "");
  expectReadError(dir / "empty.ply", "the file is empty");
  std::filesystem::create_directory(dir / "folder.ply");
  expectReadError(dir / "folder.ply", "is a directory");
}

TEST(PlyIo, WriteReplacesAtomicallyAndLeavesNoTemporaryFiles) {
  TempDir dir;
  const TriangleMesh a = testing::makeCube(1.0f);
  const TriangleMesh b = testing::makeRandomMesh(9, 30, 20);
  writePly(dir / "m.ply", a);
  writePly(dir / "m.ply", b);
  EXPECT_TRUE(testing::bitwiseEqual(readPly(dir / "m.ply"), b));
  EXPECT_EQ(testing::entryCount(dir.path()), 1u);
  EXPECT_THROW(writePly(dir / "no_such_dir" / "m.ply", a), OutputError);
}

TEST(PlyIo, WriteRefusesInvalidMeshes) {
  TempDir dir;
  TriangleMesh m = testing::makeCube();
  m.triangles.push_back({0, 1, 8});
  EXPECT_THROW(writePly(dir / "m.ply", m), std::invalid_argument);
  EXPECT_FALSE(std::filesystem::exists(dir / "m.ply"));
}

}  // namespace
}  // namespace objscan
