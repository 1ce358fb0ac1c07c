#include "objscan/core/organized_cloud.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <iomanip>
#include <limits>
#include <sstream>

#include <liblzf/lzf.h>

#include "objscan/core/error.h"
#include "test_support.h"

namespace objscan {
namespace {

using testing::expectInputError;
using testing::writeBytes;
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

/// A 4 x 3 organized cloud: a plane at z = 1 m seen by a 100 px camera, one pixel without a
/// reading, colours and labels (1 = table, 20 / 21 = two parts of object 2).
struct Points {
  int width = 4, height = 3;
  std::vector<Eigen::Vector3f> xyz;
  std::vector<std::uint32_t> rgba, label;
};

Points smallCloud() {
  Points p;
  for (int v = 0; v < p.height; ++v) {
    for (int u = 0; u < p.width; ++u) {
      const float z = 1.0f;
      p.xyz.emplace_back((u - 1.5f) / 100.0f * z, (v - 1.0f) / 100.0f * z, z);
      p.rgba.push_back(0xff000000u | (10u * u) << 16 | (20u * v) << 8 | 7u);
      p.label.push_back(u < 2 ? 1u : (v == 0 ? 20u : 21u));
    }
  }
  p.xyz[5] = Eigen::Vector3f::Constant(kNaN);
  return p;
}

std::string header(const Points& p, const std::string& data, const std::string& label_type = "U") {
  std::ostringstream h;
  h << "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS label x y z rgba\n"
    << "SIZE 4 4 4 4 4\nTYPE " << label_type << " F F F U\nCOUNT 1 1 1 1 1\nWIDTH " << p.width
    << "\nHEIGHT " << p.height << "\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << p.xyz.size() << "\nDATA "
    << data << "\n";
  return h.str();
}

template <typename T>
void append(std::string& bytes, T value) {
  bytes.append(reinterpret_cast<const char*>(&value), sizeof value);
}

std::string binaryPcd(const Points& p) {
  std::string bytes = header(p, "binary");
  for (std::size_t i = 0; i < p.xyz.size(); ++i) {
    append(bytes, p.label[i]);
    for (int k = 0; k < 3; ++k) append(bytes, p.xyz[i][k]);
    append(bytes, p.rgba[i]);
  }
  return bytes;
}

/// binary_compressed: each field's values together, compressed with liblzf (as PCL does).
std::string compressedPcd(const Points& p) {
  std::string raw;
  for (std::uint32_t l : p.label) append(raw, l);
  for (int k = 0; k < 3; ++k) {
    for (const Eigen::Vector3f& x : p.xyz) append(raw, x[k]);
  }
  for (std::uint32_t c : p.rgba) append(raw, c);
  std::string packed(raw.size() * 2 + 64, '\0');
  const unsigned int size = lzf_compress(raw.data(), static_cast<unsigned int>(raw.size()),
                                         packed.data(), static_cast<unsigned int>(packed.size()));
  EXPECT_GT(size, 0u);
  std::string bytes = header(p, "binary_compressed");
  append(bytes, static_cast<std::uint32_t>(size));
  append(bytes, static_cast<std::uint32_t>(raw.size()));
  bytes.append(packed.data(), size);
  return bytes;
}

std::string asciiPcd(const Points& p) {
  std::ostringstream text;
  text << header(p, "ascii") << std::fixed << std::setprecision(6);
  for (std::size_t i = 0; i < p.xyz.size(); ++i) {
    text << p.label[i];
    for (int k = 0; k < 3; ++k) {
      if (std::isfinite(p.xyz[i][k])) {
        text << ' ' << p.xyz[i][k];
      } else {
        text << " nan";
      }
    }
    text << ' ' << p.rgba[i] << '\n';
  }
  return text.str();
}

void expectCloud(const OrganizedCloud& c, const Points& p, float tolerance) {
  ASSERT_EQ(c.width, p.width);
  ASSERT_EQ(c.height, p.height);
  ASSERT_EQ(c.points_C.size(), p.xyz.size());
  ASSERT_EQ(c.colors.size(), p.xyz.size());
  ASSERT_EQ(c.labels.size(), p.xyz.size());
  for (std::size_t i = 0; i < p.xyz.size(); ++i) {
    if (!std::isfinite(p.xyz[i].z())) {
      EXPECT_FALSE(c.valid(i));
      continue;
    }
    EXPECT_TRUE(c.points_C[i].isApprox(p.xyz[i], tolerance)) << i;
    EXPECT_EQ(c.colors[i],
              Rgb8((p.rgba[i] >> 16) & 0xff, (p.rgba[i] >> 8) & 0xff, p.rgba[i] & 0xff));
    EXPECT_EQ(c.labels[i], p.label[i]);
  }
  EXPECT_EQ(c.validCount(), p.xyz.size() - 1);
}

TEST(Pcd, ReadsAllThreeEncodings) {
  testing::TempDir dir;
  const Points p = smallCloud();
  writeBytes(dir.path() / "b.pcd", binaryPcd(p));
  writeBytes(dir.path() / "c.pcd", compressedPcd(p));
  writeBytes(dir.path() / "a.pcd", asciiPcd(p));
  expectCloud(readPcd(dir.path() / "b.pcd"), p, 0.0f);
  expectCloud(readPcd(dir.path() / "c.pcd"), p, 0.0f);
  expectCloud(readPcd(dir.path() / "a.pcd"), p, 1e-5f);  // six decimals in the text
}

TEST(Pcd, WhatWritePcdWritesReadsBackAsItWas) {
  testing::TempDir dir;
  const Points p = smallCloud();
  OrganizedCloud cloud;
  cloud.width = p.width;
  cloud.height = p.height;
  cloud.points_C = p.xyz;
  for (std::uint32_t c : p.rgba)
    cloud.colors.emplace_back((c >> 16) & 0xff, (c >> 8) & 0xff, c & 0xff);
  cloud.labels = p.label;
  writePcd(dir.path() / "w.pcd", cloud);
  expectCloud(readPcd(dir.path() / "w.pcd"), p, 0.0f);
  // Without colours and labels: the points alone.
  cloud.colors.clear();
  cloud.labels.clear();
  writePcd(dir.path() / "points.pcd", cloud);
  const OrganizedCloud points = readPcd(dir.path() / "points.pcd");
  EXPECT_EQ(points.width, p.width);
  EXPECT_EQ(points.height, p.height);
  EXPECT_TRUE(points.colors.empty());
  EXPECT_TRUE(points.labels.empty());
  EXPECT_EQ(points.validCount(), p.xyz.size() - 1);
  // A cloud whose parts do not match is refused, and nothing is written.
  cloud.labels.assign(3, 1);
  EXPECT_THROW(writePcd(dir.path() / "bad.pcd", cloud), std::invalid_argument);
  cloud.labels.clear();
  cloud.width = 5;
  EXPECT_THROW(writePcd(dir.path() / "bad.pcd", cloud), std::invalid_argument);
  EXPECT_THROW(writePcd(dir.path() / "bad.pcd", OrganizedCloud{}), std::invalid_argument);
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "bad.pcd"));
}

TEST(Pcd, BadFilesGetOneClearError) {
  testing::TempDir dir;
  const Points p = smallCloud();
  const auto expect = [&](const std::string& name, const std::string& bytes,
                          const std::string& needle) {
    writeBytes(dir.path() / name, bytes);
    expectInputError([&] { readPcd(dir.path() / name); }, dir.path() / name, needle);
  };
  expectInputError([&] { readPcd(dir.path() / "missing.pcd"); }, dir.path() / "missing.pcd",
                   "no such file");
  expect("empty.pcd", "", "empty");
  const std::string binary = binaryPcd(p);
  expect("cut.pcd", binary.substr(0, binary.size() - 10), "truncated");
  expect("header.pcd", binary.substr(0, 40), "DATA");
  const std::string compressed = compressedPcd(p);
  expect("ccut.pcd", compressed.substr(0, compressed.size() - 5), "truncated");
  std::string corrupt = compressed;
  const std::size_t data = header(p, "binary_compressed").size() + 8;
  for (std::size_t i = data; i < corrupt.size(); ++i) corrupt[i] = static_cast<char>(0xe0);
  expect("corrupt.pcd", corrupt, "corrupt");
  std::string float_label = binaryPcd(p);
  float_label.replace(0, header(p, "binary").size(), header(p, "binary", "F"));
  expect("flabel.pcd", float_label, "a label must be an integer");
  std::string bad_count = binary;
  bad_count.replace(bad_count.find("POINTS 12"), 9, "POINTS 13");
  expect("points.pcd", bad_count, "does not match POINTS");
  expect("noxyz.pcd", "FIELDS a b\nSIZE 4 4\nTYPE F F\nWIDTH 1\nHEIGHT 1\nDATA ascii\n1 2\n",
         "no x y z");
  expect("text.pcd", asciiPcd(p).replace(asciiPcd(p).size() - 8, 4, "abcd"), "not a number");
  // Values a 32-bit field or a float cannot hold (converting them was undefined behaviour, found
  // by fuzz_pcd: the input it found is tests/core/fuzz_regressions/).
  const std::string two = "VERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F TYPE\nCOUNT 1 1 1 1\n"
                          "WIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n";
  const auto withType = [&](const char* type, const std::string& values) {
    std::string text = two;
    text.replace(text.find("TYPE\n"), 4, type);
    return text + values + "\n";
  };
  expect("urgb.pcd", withType("U", "0 0 1 1.002e+11"), "does not fit its 32-bit field");
  expect("nrgb.pcd", withType("U", "0 0 1 -1"), "does not fit its 32-bit field");
  expect("nanrgb.pcd", withType("U", "0 0 1 nan"), "does not fit its 32-bit field");
  expect("irgb.pcd", withType("I", "0 0 1 3e9"), "does not fit its 32-bit field");
  expect("frgb.pcd", withType("F", "0 0 1 1e300"), "does not fit its 32-bit field");
  expect("far.pcd", withType("U", "1e300 0 1 0"), "past float's range");
  const std::filesystem::path found =
      std::filesystem::path(OBJSCAN_SOURCE_DIR) / "tests/core/fuzz_regressions" /
                         "pcd_ascii_rgb_past_32_bits.pcd";
  expectInputError([&] { readPcd(found); }, found, "does not fit its 32-bit field");
  // Declared counts the data cannot hold are refused before anything is allocated for them (the
  // The hostile-input audit: 117 bytes of ascii PCD had the reader allocate 1.6 GB, 131 bytes of
  // binary_compressed 1.2 GB).
  const std::string huge =
      "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
      "WIDTH 100000000\nHEIGHT 1\nPOINTS 100000000\nDATA ";
  expect("huge_ascii.pcd", huge + "ascii\n1 2 3\n", "cannot hold the 100000000 points");
  expect("huge_lzf.pcd",
         huge + "binary_compressed\n" + std::string("\x00\x00\x00\x00\x00\x8c\x86\x47", 8),
         "0 bytes of LZF cannot hold 1200000000");
}

TEST(OrganizedMesh, JoinsNeighboursFacingTheCameraAndCutsDepthJumps) {
  Points p = smallCloud();
  OrganizedCloud c;
  c.width = p.width;
  c.height = p.height;
  c.points_C = p.xyz;
  std::vector<std::int32_t> pixels;
  TriangleMesh mesh = meshOrganized(c, {}, &pixels);
  EXPECT_EQ(mesh.positions.size(), 11u);
  ASSERT_EQ(pixels.size(), 11u);
  EXPECT_EQ(pixels[5], 6);  // pixel 5 has no reading
  // 3 x 2 blocks of 2 triangles, less the 4 that would use pixel 5 (each block around it keeps
  // the triangle of its other three pixels).
  EXPECT_EQ(mesh.triangles.size(), 8u);
  for (const Eigen::Vector3f& n : mesh.normals) EXPECT_LT(n.z(), -0.99f);  // towards the camera
  // The right half moved 10 cm back: a jump of ten pixels' footprints per pixel is cut.
  for (std::size_t i = 0; i < c.points_C.size(); ++i) {
    if (i % 4 >= 2) c.points_C[i] *= 1.1f;
  }
  mesh = meshOrganized(c);
  for (const Eigen::Vector3i& t : mesh.triangles) {
    const float z0 = mesh.positions[t[0]].z();
    for (int k = 1; k < 3; ++k) EXPECT_NEAR(mesh.positions[t[k]].z(), z0, 1e-4f);
  }
  // The blocks on each side of the jump: 2 on the left (around the hole), 4 on the right.
  EXPECT_EQ(mesh.triangles.size(), 6u);
  OrganizedCloud row = c;
  row.width = 12;
  row.height = 1;
  EXPECT_THROW(meshOrganized(row), std::invalid_argument);
}

TEST(OrganizedMesh, LabelsAreObjectPartsOrWholeObjects) {
  EXPECT_EQ(objectIdOfLabel(0), 0);
  EXPECT_EQ(objectIdOfLabel(7), 0);
  EXPECT_EQ(objectIdOfLabel(20), 20);
  EXPECT_EQ(objectIdOfLabel(21), 21);
  EXPECT_EQ(objectIdOfLabel(21, true), 2);
}

TEST(OrganizedCloud, AnUnorganizedCloudGoesBackOnItsPixelGrid) {
  // A 40 x 30 view of a tilted plane, its NaNs removed (as some files store it).
  Intrinsics k;
  k.fx_px = k.fy_px = 50.0;
  k.cx_px = 19.5;
  k.cy_px = 14.5;
  k.width_px = 40;
  k.height_px = 30;
  OrganizedCloud flat;
  flat.width = 0;
  flat.height = 1;
  std::vector<std::size_t> pixel;
  for (int v = 0; v < k.height_px; ++v) {
    for (int u = 0; u < k.width_px; ++u) {
      if ((u * 7 + v * 3) % 11 == 0) continue;  // holes
      const float z = 1.0f + 0.01f * static_cast<float>(u);
      flat.points_C.emplace_back(static_cast<float>((u - k.cx_px) / k.fx_px) * z,
                                 static_cast<float>((v - k.cy_px) / k.fy_px) * z, z);
      pixel.push_back(static_cast<std::size_t>(v * k.width_px + u));
      ++flat.width;
    }
  }
  const OrganizedCloud placed = placeOnPixelGrid(flat, k);
  for (std::size_t i = 0; i < pixel.size(); ++i) {
    EXPECT_EQ(placed.points_C[pixel[i]], flat.points_C[i]);
  }
  EXPECT_EQ(placed.validCount(), pixel.size());
  const std::optional<Intrinsics> fitted = fitPinhole(flat);
  ASSERT_TRUE(fitted.has_value());
  EXPECT_NEAR(fitted->fx_px, 50.0, 1e-3);
  EXPECT_NEAR(fitted->fy_px, 50.0, 1e-3);
  // The fitted grid may be cropped to the points; every point still lands on its own pixel.
  EXPECT_EQ(placeOnPixelGrid(flat, *fitted).validCount(), pixel.size());
  OrganizedCloud scattered;
  scattered.height = 1;
  for (int i = 0; i < 500; ++i) {
    scattered.points_C.emplace_back(std::sin(i * 1.3f), std::cos(i * 0.7f),
                                    2.0f + std::sin(i * 0.1f));
  }
  scattered.width = 500;
  EXPECT_FALSE(fitPinhole(scattered).has_value());
}

}  // namespace
}  // namespace objscan
