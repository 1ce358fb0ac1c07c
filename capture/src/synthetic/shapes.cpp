#include "objscan/capture/synthetic/shapes.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>

#include <Eigen/Geometry>

namespace objscan::capture::shapes {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;
constexpr int kSegments = 48;  // around a lathe or tube: facets of 2 mm on a 4 cm mug

void addQuad(TriangleMesh& m, int a, int b, int c, int d) {
  // Quad a-b-c-d counter-clockwise seen from outside; degenerate halves (poles) are skipped.
  if (a != b && b != c && a != c) m.triangles.emplace_back(a, b, c);
  if (a != c && c != d && a != d) m.triangles.emplace_back(a, c, d);
}

TriangleMesh mug(float v) {
  const float r = 0.040f + 0.006f * v, h = 0.095f, wall = 0.004f, floor = 0.006f;
  TriangleMesh m =
      lathe({{0, 0}, {r, 0}, {r, h}, {r - wall, h}, {r - wall, floor}, {0, floor}}, kSegments);
  // The handle: a bent tube from low on the wall to high on it, ends sunk into the wall.
  append(m, tube(
                [&](float t) {
                  return Eigen::Vector3f(r - 0.003f + 0.03f * std::sin(kPi * t), 0.0f,
                                         0.022f + 0.052f * t);
                },
                [](float) { return 0.0065f; }, 24, 16));
  return m;
}

TriangleMesh cup(float v) {
  const float bottom = 0.028f, top = 0.040f + 0.004f * v, h = 0.10f, wall = 0.003f;
  return lathe(
      {{0, 0}, {bottom, 0}, {top, h}, {top - wall, h}, {bottom - wall, 0.005f}, {0, 0.005f}},
      kSegments);
}

TriangleMesh bowl(float v) {
  const float r = 0.075f + 0.015f * v, h = 0.055f + 0.01f * v;
  return lathe({{0, 0},
                {0.45f * r, 0},
                {0.92f * r, 0.7f * h},
                {r, h},
                {r - 0.005f, h},
                {0.9f * r - 0.004f, 0.75f * h},
                {0.42f * r, 0.008f},
                {0, 0.008f}},
               kSegments);
}

TriangleMesh can(float v) {
  const float r = 0.033f + 0.006f * v, h = 0.10f + 0.03f * v;
  return lathe({{0, 0}, {r - 0.003f, 0}, {r, 0.004f}, {r, h - 0.004f}, {r - 0.003f, h}, {0, h}},
               kSegments);
}

TriangleMesh bottle(float v) {
  const float r = 0.032f + 0.008f * v, h = 0.20f + 0.06f * v;
  return lathe({{0, 0},
                {r, 0},
                {r, 0.62f * h},
                {0.75f * r, 0.75f * h},
                {0.014f, 0.88f * h},
                {0.014f, h},
                {0, h}},
               kSegments);
}

/// A sphere of radius r resting on z = 0.
TriangleMesh sphere(float r) {
  std::vector<Eigen::Vector2f> profile;
  const int steps = 24;
  for (int k = 0; k <= steps; ++k) {
    const float a = kPi * static_cast<float>(k) / steps;
    profile.emplace_back(k == 0 || k == steps ? 0.0f : r * std::sin(a), r * (1.0f - std::cos(a)));
  }
  return lathe(profile, kSegments);
}

TriangleMesh ball(float v) { return sphere(0.035f + 0.03f * v); }

/// A brick of 2 x 4 studs (3.2 x 1.6 x 1.15 cm with its studs), scaled up to 1.3 times.
TriangleMesh brick(float v) {
  const float k = 1.0f + 0.3f * v, h = 0.0096f * k, pitch = 0.008f * k;
  TriangleMesh m = box(4 * pitch, 2 * pitch, h);
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 2; ++j) {
      append(m, translated(
                    lathe({{0, 0}, {0.0024f * k, 0}, {0.0024f * k, 0.0018f * k}, {0, 0.0018f * k}},
                          12),
                    {(i - 1.5f) * pitch, (j - 0.5f) * pitch, h}));
    }
  }
  return m;
}

/// A strawberry-like cone with a rounded tip, 2.5-3.5 cm tall, lying on its side.
TriangleMesh berry(float v) {
  const float h = 0.025f + 0.01f * v, r = 0.45f * h;
  TriangleMesh m = lathe({{0, 0},
                          {0.3f * r, 0.05f * h},
                          {0.75f * r, 0.3f * h},
                          {r, 0.65f * h},
                          {0.85f * r, 0.9f * h},
                          {0.4f * r, h},
                          {0, h}},
                         24);
  // On its side: the axis along x.
  for (Eigen::Vector3f& p : m.positions) p = Eigen::Vector3f(p.z(), p.y(), p.x());
  // The swap mirrors the surface: turn the triangles back so that they face outwards.
  for (Eigen::Vector3i& t : m.triangles) std::swap(t[1], t[2]);
  return m;
}

/// A spoon-like shape: a thin handle and a shallow oval bowl, 14-17 cm long, lying flat.
TriangleMesh spoon(float v) {
  const float length = 0.14f + 0.03f * v;
  return tube([&](float t) { return Eigen::Vector3f((t - 0.5f) * length, 0.0f, 0.0045f); },
              [](float t) {
                // The handle (t < 0.65) 4 mm thick, then the bowl, up to 2 cm across.
                if (t < 0.65f) return 0.004f;
                const float u = (t - 0.65f) / 0.35f;
                return 0.004f + 0.0055f * std::sqrt(std::max(0.0f, std::sin(kPi * u)));
              },
              40, 16);
}

TriangleMesh keyboard(float v) {
  const float w = 0.42f + 0.04f * v, d = 0.14f, h = 0.02f;
  TriangleMesh m = box(w, d, h);
  const int columns = 14, rows = 4;
  const float key = 0.017f, pitch_x = (w - 0.03f) / columns, pitch_y = (d - 0.03f) / rows;
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < columns; ++j) {
      append(m, translated(box(key, key, 0.008f), {-0.5f * w + 0.015f + (j + 0.5f) * pitch_x,
                                                   -0.5f * d + 0.015f + (i + 0.5f) * pitch_y, h}));
    }
  }
  return m;
}

TriangleMesh stapler(float v) {
  const float length = 0.15f + 0.03f * v;
  TriangleMesh m = box(length, 0.04f, 0.012f);
  append(m, translated(box(length - 0.01f, 0.034f, 0.02f), {0.005f, 0.0f, 0.016f}));
  append(m, translated(box(0.025f, 0.04f, 0.036f), {0.5f * length - 0.0125f, 0.0f, 0.0f}));
  return m;
}

TriangleMesh banana(float v) {
  const float bend = 0.12f + 0.03f * v, thickness = 0.018f;
  return tube(
      [&](float t) {
        const float a = (t - 0.5f) * 1.8f;
        return Eigen::Vector3f(bend * std::sin(a), bend * (1.0f - std::cos(a)), thickness);
      },
      [&](float t) { return 0.004f + thickness * std::sqrt(std::max(0.0f, std::sin(kPi * t))); },
      32, 20);
}

}  // namespace

TriangleMesh translated(TriangleMesh m, const Eigen::Vector3f& offset_m) {
  for (auto& p : m.positions) p += offset_m;
  return m;
}

TriangleMesh transformed(TriangleMesh m, const Pose& T) {
  for (auto& p : m.positions) p = T * p;
  for (auto& n : m.normals) n = T.linear() * n;
  return m;
}

void restOnGround(TriangleMesh& m) {
  const Eigen::AlignedBox3f box = m.bounds();
  const Eigen::Vector3f shift(-0.5f * (box.min().x() + box.max().x()),
                              -0.5f * (box.min().y() + box.max().y()), -box.min().z());
  for (auto& p : m.positions) p += shift;
}

TriangleMesh box(float sx, float sy, float sz) {
  TriangleMesh m;
  for (int i = 0; i < 8; ++i) {
    m.positions.emplace_back((i & 1) ? 0.5f * sx : -0.5f * sx, (i & 2) ? 0.5f * sy : -0.5f * sy,
                             (i & 4) ? sz : 0.0f);
  }
  addQuad(m, 0, 2, 3, 1);  // bottom (-z)
  addQuad(m, 4, 5, 7, 6);  // top (+z)
  addQuad(m, 0, 1, 5, 4);  // -y
  addQuad(m, 2, 6, 7, 3);  // +y
  addQuad(m, 0, 4, 6, 2);  // -x
  addQuad(m, 1, 3, 7, 5);  // +x
  return m;
}

TriangleMesh lathe(const std::vector<Eigen::Vector2f>& profile, int segments) {
  TriangleMesh m;
  std::vector<int> first;  // index of each profile point's first vertex
  for (const Eigen::Vector2f& p : profile) {
    first.push_back(static_cast<int>(m.positions.size()));
    if (p.x() <= 0.0f) {
      m.positions.emplace_back(0.0f, 0.0f, p.y());
      continue;
    }
    for (int j = 0; j < segments; ++j) {
      const float a = 2.0f * kPi * static_cast<float>(j) / static_cast<float>(segments);
      m.positions.emplace_back(p.x() * std::cos(a), p.x() * std::sin(a), p.y());
    }
  }
  auto at = [&](std::size_t k, int j) {
    return profile[k].x() <= 0.0f ? first[k] : first[k] + (j % segments);
  };
  for (std::size_t k = 0; k + 1 < profile.size(); ++k) {
    for (int j = 0; j < segments; ++j)
      addQuad(m, at(k, j), at(k, j + 1), at(k + 1, j + 1), at(k + 1, j));
  }
  return m;
}

TriangleMesh tube(const std::function<Eigen::Vector3f(float)>& centre,
                  const std::function<float(float)>& radius, int rings, int segments) {
  TriangleMesh m;
  Eigen::Vector3f normal = Eigen::Vector3f::Zero();
  std::vector<Eigen::Vector3f> centres;
  for (int i = 0; i < rings; ++i) {
    const float t = static_cast<float>(i) / static_cast<float>(rings - 1);
    const float dt = 1e-3f;
    const Eigen::Vector3f tangent =
        (centre(std::min(1.0f, t + dt)) - centre(std::max(0.0f, t - dt))).normalized();
    // Parallel transport of the normal keeps the rings from twisting.
    if (i == 0) {
      const Eigen::Vector3f ref =
          std::abs(tangent.z()) < 0.9f ? Eigen::Vector3f::UnitZ() : Eigen::Vector3f::UnitX();
      normal = tangent.cross(ref).cross(tangent).normalized();
    } else {
      normal = (normal - normal.dot(tangent) * tangent).normalized();
    }
    const Eigen::Vector3f binormal = tangent.cross(normal);
    const Eigen::Vector3f c = centre(t);
    const float r = radius(t);
    centres.push_back(c);
    for (int j = 0; j < segments; ++j) {
      const float a = 2.0f * kPi * static_cast<float>(j) / static_cast<float>(segments);
      m.positions.push_back(c + r * (std::cos(a) * normal + std::sin(a) * binormal));
    }
  }
  auto at = [&](int i, int j) { return i * segments + (j % segments); };
  for (int i = 0; i + 1 < rings; ++i) {
    for (int j = 0; j < segments; ++j)
      addQuad(m, at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i + 1, j));
  }
  const int start = static_cast<int>(m.positions.size());
  m.positions.push_back(centres.front());
  m.positions.push_back(centres.back());
  for (int j = 0; j < segments; ++j) {
    m.triangles.emplace_back(start, at(0, j + 1), at(0, j));
    m.triangles.emplace_back(start + 1, at(rings - 1, j), at(rings - 1, j + 1));
  }
  return m;
}

void append(TriangleMesh& mesh, const TriangleMesh& part) {
  const int offset = static_cast<int>(mesh.positions.size());
  const bool normals = (mesh.empty() || mesh.hasNormals()) && part.hasNormals();
  const bool colors = (mesh.empty() || mesh.hasColors()) && part.hasColors();
  const bool labels = (mesh.empty() || mesh.hasLabels()) && part.hasLabels();
  const bool weights = (mesh.empty() || mesh.hasWeights()) && part.hasWeights();
  const bool ignore = (mesh.empty() || mesh.hasIgnore()) && part.hasIgnore();
  if (!normals) mesh.normals.clear();
  if (!colors) mesh.colors.clear();
  if (!labels) mesh.labels.clear();
  if (!weights) mesh.weights.clear();
  if (!ignore) mesh.ignore.clear();
  mesh.positions.insert(mesh.positions.end(), part.positions.begin(), part.positions.end());
  if (normals) mesh.normals.insert(mesh.normals.end(), part.normals.begin(), part.normals.end());
  if (colors) mesh.colors.insert(mesh.colors.end(), part.colors.begin(), part.colors.end());
  if (labels) mesh.labels.insert(mesh.labels.end(), part.labels.begin(), part.labels.end());
  if (weights) mesh.weights.insert(mesh.weights.end(), part.weights.begin(), part.weights.end());
  if (ignore) mesh.ignore.insert(mesh.ignore.end(), part.ignore.begin(), part.ignore.end());
  for (const auto& t : part.triangles)
    mesh.triangles.push_back(t + Eigen::Vector3i::Constant(offset));
}

void paint(TriangleMesh& mesh, const Rgb8& color, std::int32_t label) {
  mesh.colors.assign(mesh.positions.size(), color);
  mesh.labels.assign(mesh.positions.size(), label);
}

const std::vector<std::string>& smallNames() {
  static const std::vector<std::string> names = {"marble", "golf_ball", "dice",
                                                 "brick",  "berry",     "spoon"};
  return names;
}

TriangleMesh plant(float v, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  const auto uniform = [&](float a, float b) {
    return std::uniform_real_distribution<float>(a, b)(rng);
  };
  const float pot_r = 0.055f + 0.02f * v, pot_h = 0.10f + 0.03f * v;
  TriangleMesh m = lathe({{0, 0}, {0.8f * pot_r, 0}, {pot_r, pot_h}, {0, pot_h}}, kSegments);
  paint(m, Rgb8(170, 85, 55), 0);
  // Leaves: thin slabs on curved stems from the soil, spread around and up.
  const int leaves = 14 + static_cast<int>(rng() % 12);
  for (int k = 0; k < leaves; ++k) {
    const float azimuth = uniform(0.0f, 2.0f * kPi), rise = uniform(0.5f, 1.3f);
    const float stem = uniform(0.08f, 0.22f), size = uniform(0.03f, 0.06f);
    const Eigen::Vector3f out(std::cos(azimuth), std::sin(azimuth), 0.0f);
    const auto along = [&](float t) -> Eigen::Vector3f {
      return Eigen::Vector3f(0, 0, pot_h) + stem * t * (std::cos(rise) * out) +
             Eigen::Vector3f(0, 0, stem * std::sin(rise) * t - 0.3f * stem * t * t);
    };
    TriangleMesh part = tube(
        along, [](float) { return 0.0015f; }, 8, 6);
    // The leaf: a slab at the stem's end, tilted along it.
    TriangleMesh leaf = box(size, 0.4f * size, 0.002f);
    const Eigen::Vector3f tip = along(1.0f), dir = (tip - along(0.9f)).normalized();
    Pose T = Pose::Identity();
    T.linear() =
        Eigen::Quaternionf::FromTwoVectors(Eigen::Vector3f::UnitX(), dir).toRotationMatrix() *
        Eigen::AngleAxisf(uniform(-0.8f, 0.8f), Eigen::Vector3f::UnitX()).toRotationMatrix();
    T.translation() = tip + 0.5f * size * dir;
    append(part, transformed(translated(leaf, {0, 0, -0.001f}), T));
    const auto g = static_cast<std::uint8_t>(110 + rng() % 60);
    paint(part, Rgb8(static_cast<std::uint8_t>(40 + rng() % 30), g, 45), 0);
    append(m, part);
  }
  return m;
}

const std::vector<std::string>& builtinNames() {
  static const std::vector<std::string> names = {"mug",     "bowl",   "box",  "can",
                                                 "bottle",  "ball",   "book", "keyboard",
                                                 "stapler", "banana", "cup"};
  return names;
}

TriangleMesh builtin(const std::string& name, float v) {
  TriangleMesh m;
  if (name == "mug")
    m = mug(v);
  else if (name == "cup")
    m = cup(v);
  else if (name == "bowl")
    m = bowl(v);
  else if (name == "can")
    m = can(v);
  else if (name == "bottle")
    m = bottle(v);
  else if (name == "ball")
    m = ball(v);
  else if (name == "box")
    m = box(0.09f + 0.05f * v, 0.07f + 0.03f * v, 0.05f + 0.06f * v);
  else if (name == "book")
    m = box(0.15f + 0.04f * v, 0.22f + 0.03f * v, 0.025f + 0.02f * v);
  else if (name == "keyboard")
    m = keyboard(v);
  else if (name == "stapler")
    m = stapler(v);
  else if (name == "banana")
    m = banana(v);
  else if (name == "marble")
    m = sphere(0.008f + 0.004f * v);
  else if (name == "golf_ball")
    m = sphere(0.0213f);
  else if (name == "dice")
    m = box(0.016f + 0.004f * v, 0.016f + 0.004f * v, 0.016f + 0.004f * v);
  else if (name == "brick")
    m = brick(v);
  else if (name == "berry")
    m = berry(v);
  else if (name == "spoon")
    m = spoon(v);
  else
    throw std::invalid_argument("unknown built-in object '" + name + "'");
  restOnGround(m);
  return m;
}

}  // namespace objscan::capture::shapes
