#include "objscan/capture/synthetic/synthetic_scene.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>

#include "objscan/capture/synthetic/shapes.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "objscan/core/ply_io.h"

namespace objscan::capture {
namespace fs = std::filesystem;

namespace {

constexpr float kPi = std::numbers::pi_v<float>;
/// Meshes from --object-dir larger than this are not household objects in metres; skipped.
constexpr float kMaxObjectExtent_m = 0.6f;
constexpr int kPlacementAttempts = 400;
constexpr int kShapeTries = 10;

const Rgb8 kWallColor(222, 216, 204), kFloorColor(118, 112, 108), kWoodColor(150, 108, 66),
    kCounterColor(205, 205, 198), kPaperColor(246, 246, 240), kCableColor(35, 35, 38);

/// Object colours: saturated enough to tell apart in the pictures.
const Rgb8 kPalette[] = {{200, 60, 50},  {50, 110, 190},  {240, 190, 40}, {60, 160, 90},
                         {150, 80, 170}, {240, 130, 40},  {40, 170, 170}, {190, 190, 60},
                         {120, 70, 40},  {220, 100, 150}, {90, 90, 95},   {250, 250, 250}};

/// A rectangle where objects may stand: x in [x0, x1], y in [y0, y1] at height z, with at most
/// max_height of free space above.
struct Area {
  float x0, x1, y0, y1, z, max_height;
};

/// A footprint on a support: centre, rotation about z, half extents in its own axes.
struct Footprint {
  Eigen::Vector2f centre;
  float yaw;
  Eigen::Vector2f half;
  int area;

  Eigen::Matrix2f rotation() const { return Eigen::Rotation2Df(yaw).toRotationMatrix(); }
  std::array<Eigen::Vector2f, 4> corners() const {
    const Eigen::Matrix2f R = rotation();
    return {centre + R * Eigen::Vector2f(half.x(), half.y()),
            centre + R * Eigen::Vector2f(-half.x(), half.y()),
            centre + R * Eigen::Vector2f(-half.x(), -half.y()),
            centre + R * Eigen::Vector2f(half.x(), -half.y())};
  }
  /// Half extents along the world axes, exact when yaw is a multiple of 90 degrees.
  Eigen::Vector2f worldHalf() const {
    const Eigen::Matrix2f R = rotation();
    return {std::abs(R(0, 0)) * half.x() + std::abs(R(0, 1)) * half.y(),
            std::abs(R(1, 0)) * half.x() + std::abs(R(1, 1)) * half.y()};
  }
};

/// Separating-axis test for two rectangles; touching (zero gap) does not count as overlap.
bool overlap(const Footprint& a, const Footprint& b) {
  if (a.area != b.area) return false;
  const auto ca = a.corners(), cb = b.corners();
  const Eigen::Matrix2f Ra = a.rotation(), Rb = b.rotation();
  for (const Eigen::Vector2f& axis : {Eigen::Vector2f(Ra.col(0)), Eigen::Vector2f(Ra.col(1)),
                                      Eigen::Vector2f(Rb.col(0)), Eigen::Vector2f(Rb.col(1))}) {
    float a0 = 1e9f, a1 = -1e9f, b0 = 1e9f, b1 = -1e9f;
    for (int k = 0; k < 4; ++k) {
      a0 = std::min(a0, axis.dot(ca[k]));
      a1 = std::max(a1, axis.dot(ca[k]));
      b0 = std::min(b0, axis.dot(cb[k]));
      b1 = std::max(b1, axis.dot(cb[k]));
    }
    if (a1 <= b0 + 1e-5f || b1 <= a0 + 1e-5f) return false;
  }
  return true;
}

bool inside(const Footprint& f, const Area& area) {
  for (const Eigen::Vector2f& c : f.corners()) {
    if (c.x() < area.x0 - 1e-5f || c.x() > area.x1 + 1e-5f || c.y() < area.y0 - 1e-5f ||
        c.y() > area.y1 + 1e-5f) {
      return false;
    }
  }
  return true;
}

void addSupport(TriangleMesh& scene, TriangleMesh part, const Rgb8& color) {
  shapes::paint(part, color, 0);
  shapes::append(scene, part);
}

/// The preset's fixed geometry (label 0) and the areas objects stand on.
std::vector<Area> buildSupports(ScenePreset preset, TriangleMesh& scene, Eigen::Vector3f& look_at) {
  const float wall = SyntheticScene::kWallY;
  addSupport(scene, shapes::translated(shapes::box(5.0f, 4.0f, 0.02f), {0, wall - 2.0f, -0.02f}),
             kFloorColor);
  addSupport(scene, shapes::translated(shapes::box(5.0f, 0.05f, 2.6f), {0, wall + 0.025f, 0}),
             kWallColor);
  std::vector<Area> areas;
  switch (preset) {
    case ScenePreset::kDesk: {
      const float top = 0.75f, w = 1.6f, d = 0.8f;
      addSupport(scene,
                 shapes::translated(shapes::box(w, d, 0.03f), {0, wall - d / 2, top - 0.03f}),
                 kWoodColor);
      for (const float sx : {-1.0f, 1.0f}) {
        for (const float sy : {-1.0f, 1.0f}) {
          addSupport(
              scene,
              shapes::translated(shapes::box(0.05f, 0.05f, top - 0.03f),
                                 {sx * (w / 2 - 0.05f), wall - d / 2 + sy * (d / 2 - 0.05f), 0}),
              kWoodColor);
        }
      }
      areas.push_back({-w / 2 + 0.02f, w / 2 - 0.02f, wall - d + 0.02f, wall, top, 1.0f});
      look_at = {0, wall - d / 2, top + 0.05f};
      break;
    }
    case ScenePreset::kShelf: {
      const float w = 1.0f, d = 0.32f, board = 0.02f;
      const float levels[] = {0.45f, 0.85f, 1.25f, 1.65f};
      for (const float sx : {-1.0f, 1.0f}) {
        addSupport(scene,
                   shapes::translated(shapes::box(board, d, 1.67f),
                                      {sx * (w / 2 + board / 2), wall - d / 2, 0}),
                   kWoodColor);
      }
      for (std::size_t i = 0; i < std::size(levels); ++i) {
        addSupport(
            scene,
            shapes::translated(shapes::box(w, d, board), {0, wall - d / 2, levels[i] - board}),
            kWoodColor);
        if (i + 1 < std::size(levels)) {
          areas.push_back({-w / 2, w / 2, wall - d, wall, levels[i],
                           levels[i + 1] - board - levels[i] - 0.01f});
        }
      }
      look_at = {0, wall - d / 2, 0.9f};
      break;
    }
    case ScenePreset::kCounter: {
      const float top = 0.9f, w = 2.0f, d = 0.6f;
      addSupport(scene, shapes::translated(shapes::box(w, d, top), {0, wall - d / 2, 0}),
                 kCounterColor);
      addSupport(scene, shapes::translated(shapes::box(w, 0.35f, 0.7f), {0, wall - 0.175f, 1.5f}),
                 kWoodColor);
      areas.push_back({-w / 2 + 0.02f, w / 2 - 0.02f, wall - d + 0.02f, wall, top, 0.55f});
      look_at = {0, wall - d / 2, top + 0.05f};
      break;
    }
  }
  return areas;
}

/// Whether an object's top is flat enough to stand another on (a box, a book, a can, a block).
bool flatTopped(const std::string& name) {
  for (const char* word : {"box", "book", "block", "cube", "can", "brick", "dice"}) {
    if (name.find(word) != std::string::npos) return true;
  }
  return false;
}

/// Paints an object for hard_clutter: one colour, or with `split` in (0, 1) a second colour above
/// that share of its height (a lid, a label band).
void paintObject(TriangleMesh& object, const Rgb8& a, const Rgb8& b, float split, std::int32_t id) {
  shapes::paint(object, a, id);
  if (!(split > 0.0f && split < 1.0f)) return;
  const Eigen::AlignedBox3f box = object.bounds();
  const float z = box.min().z() + split * box.sizes().z();
  for (std::size_t v = 0; v < object.positions.size(); ++v) {
    if (object.positions[v].z() > z) object.colors[v] = b;
  }
}

struct Candidate {
  std::string name;
  bool builtin = true;  ///< made with a fresh variation each time; otherwise `mesh` from a file
  TriangleMesh mesh;
};

std::vector<Candidate> candidatePool(const SceneConfig& config) {
  std::vector<Candidate> pool;
  for (const std::string& name : shapes::builtinNames()) pool.push_back({name, true, {}});
  if (config.object_dir.empty()) return pool;
  std::vector<fs::path> files;
  try {
    for (const auto& entry : fs::directory_iterator(config.object_dir)) {
      if (entry.is_regular_file() && entry.path().extension() == ".ply") {
        files.push_back(entry.path());
      }
    }
  } catch (const fs::filesystem_error& e) {
    throw InputError(config.object_dir,
                     std::string("cannot list the folder: ") + e.code().message());
  }
  std::sort(files.begin(), files.end());  // directory order is not stable; the seed must be
  for (const fs::path& file : files) {
    TriangleMesh m = readPly(file);
    if (m.triangles.empty())
      throw InputError(file, "has no faces; objects must be triangle meshes");
    if (m.bounds().sizes().minCoeff() <= 0.0f) {
      throw InputError(file,
                       "is flat or a single point (zero extent along an axis); not an object");
    }
    m.normals.clear();
    m.colors.clear();
    m.labels.clear();
    m.weights.clear();
    m.ignore.clear();
    shapes::restOnGround(m);
    if (m.bounds().sizes().maxCoeff() > kMaxObjectExtent_m) {
      log::warning(file.string() + ": larger than 0.6 m, not used as an object (is it in metres?)");
      continue;
    }
    pool.push_back({file.stem().string(), false, std::move(m)});
  }
  return pool;
}

}  // namespace

const char* toString(ScenePreset preset) {
  switch (preset) {
    case ScenePreset::kDesk:
      return "desk";
    case ScenePreset::kShelf:
      return "shelf";
    case ScenePreset::kCounter:
      return "counter";
  }
  return "?";
}

ScenePreset scenePresetFromString(const std::string& name) {
  for (const ScenePreset p : {ScenePreset::kDesk, ScenePreset::kShelf, ScenePreset::kCounter}) {
    if (name == toString(p)) return p;
  }
  throw std::invalid_argument("unknown scene preset '" + name + "' (use desk, shelf or counter)");
}

void SceneConfig::validate() const {
  if (objects < 1 || objects > 30) throw std::invalid_argument("scene: objects must be 1..30");
  if (!(touching_fraction >= 0.0 && touching_fraction <= 1.0)) {
    throw std::invalid_argument("scene: touching_fraction must be in [0, 1]");
  }
  if (!object_dir.empty() && !fs::is_directory(object_dir)) {
    throw std::invalid_argument("scene: --object-dir " + object_dir.string() + " is not a folder");
  }
}

SyntheticScene composeScene(const SceneConfig& config) {
  config.validate();
  std::mt19937_64 rng(config.seed);
  auto uniform = [&](float a, float b) { return std::uniform_real_distribution<float>(a, b)(rng); };

  SyntheticScene scene;
  scene.preset = config.preset;
  const std::vector<Area> areas = buildSupports(config.preset, scene.mesh, scene.look_at_W);
  const std::vector<Candidate> pool = candidatePool(config);

  std::vector<Footprint> taken;
  // Sheets of paper lie flat on the main area: clutter, part of the support.
  if (config.preset != ScenePreset::kShelf) {
    const int sheets = 1 + static_cast<int>(rng() % 2);
    for (int s = 0; s < sheets; ++s) {
      const Area& a = areas.front();
      const Footprint f{
          {uniform(a.x0, a.x1), uniform(a.y0, a.y1)}, uniform(0, kPi), {0.105f, 0.1485f}, 0};
      // Sheets never overlap one another: two boxes in one plane would flicker in the renders.
      if (!inside(f, a) || std::any_of(taken.begin(), taken.end(),
                                       [&](const Footprint& t) { return overlap(f, t); })) {
        continue;
      }
      const Pose T = Pose(Eigen::Translation3f(f.centre.x(), f.centre.y(), a.z) *
                          Eigen::AngleAxisf(f.yaw, Eigen::Vector3f::UnitZ()));
      addSupport(scene.mesh, shapes::transformed(shapes::box(0.21f, 0.297f, 0.001f), T),
                 kPaperColor);
      taken.push_back(f);
    }
  }
  const bool hard = config.hard_clutter;
  // A potted plant, with room around it for its leaves: clutter that is not an object.
  if (hard && config.preset != ScenePreset::kShelf) {
    const Area& a = areas.front();
    for (int attempt = 0; attempt < 50; ++attempt) {
      const Footprint f{{uniform(a.x0, a.x1), uniform(a.y0, a.y1)}, 0.0f, {0.16f, 0.16f}, 0};
      if (!inside(f, a) || std::any_of(taken.begin(), taken.end(),
                                       [&](const Footprint& t) { return overlap(f, t); })) {
        continue;
      }
      shapes::append(scene.mesh, shapes::translated(shapes::plant(uniform(0.0f, 1.0f), rng()),
                                                    {f.centre.x(), f.centre.y(), a.z}));
      taken.push_back(f);
      break;
    }
  }
  const std::size_t clutter = taken.size();
  // Objects with a flat top (hard_clutter): the world height of the top and the footprint.
  struct Base {
    std::size_t footprint;
    float top_z;
  };
  std::vector<Base> bases;
  const double touching_fraction =
      hard ? std::max(config.touching_fraction, 0.5) : config.touching_fraction;

  for (int i = 0; i < config.objects; ++i) {
    const std::int32_t id = static_cast<std::int32_t>(scene.objects.size()) + 1;
    const bool touching = uniform(0.0f, 1.0f) < touching_fraction;
    bool done = false;
    // A shape that finds no room is swapped for another before giving up.
    for (int shape_try = 0; shape_try < kShapeTries && !done; ++shape_try) {
      const Candidate* pick = &pool[rng() % pool.size()];
      Candidate small;
      Rgb8 colour = kPalette[static_cast<std::size_t>(id - 1) % std::size(kPalette)], second;
      float split = 0.0f;
      bool stack = false;
      if (hard) {
        if (uniform(0.0f, 1.0f) < 0.35f) {
          small = {shapes::smallNames()[rng() % shapes::smallNames().size()], true, {}};
          pick = &small;
        }
        colour = kPalette[rng() % std::size(kPalette)];
        second = kPalette[rng() % std::size(kPalette)];
        if (uniform(0.0f, 1.0f) < 0.5f) split = uniform(0.3f, 0.8f);
        stack = !bases.empty() && uniform(0.0f, 1.0f) < 0.2f;
      }
      TriangleMesh object =
          pick->builtin ? shapes::builtin(pick->name, uniform(0.0f, 1.0f)) : pick->mesh;
      const Eigen::AlignedBox3f box = object.bounds();
      const Eigen::Vector2f half = 0.5f * box.sizes().head<2>();
      const auto place = [&](const Footprint& f, float z, bool on_object) {
        SceneObject o;
        o.id = id;
        o.name = pick->name;
        o.T_W_O = Pose(Eigen::Translation3f(f.centre.x(), f.centre.y(), z) *
                       Eigen::AngleAxisf(f.yaw, Eigen::Vector3f::UnitZ()));
        o.box_min_O = box.min();
        o.box_max_O = box.max();
        o.vertex_count = object.positions.size();
        o.touching = touching || on_object;
        o.stacked = on_object;
        object = shapes::transformed(std::move(object), o.T_W_O);
        if (hard) {
          paintObject(object, colour, second, split, id);
        } else {
          shapes::paint(object, colour, id);
        }
        shapes::append(scene.mesh, object);
        scene.objects.push_back(o);
        // One level of stacking: what stands on an object is not a base itself.
        if (hard && !on_object && flatTopped(pick->name)) {
          bases.push_back({taken.size(), z + box.sizes().z()});
        }
        taken.push_back(f);
        done = true;
      };
      // On top of an earlier object whose top is flat and large enough, within its footprint.
      for (int attempt = 0; stack && attempt < 20 && !done; ++attempt) {
        const Base& base = bases[rng() % bases.size()];
        const Footprint under = taken[base.footprint];
        const Area& a = areas[static_cast<std::size_t>(under.area)];
        if (base.top_z + box.sizes().z() > a.z + a.max_height) continue;
        if (half.x() > under.half.x() || half.y() > under.half.y()) continue;
        const Eigen::Vector2f slack = under.half - half;
        const Eigen::Vector2f offset(uniform(-slack.x(), slack.x()),
                                     uniform(-slack.y(), slack.y()));
        // Its own area (above the object under it), so that it overlaps only what stands there.
        const Footprint f{under.centre + under.rotation() * offset, under.yaw, half,
                          1000 + static_cast<int>(base.footprint)};
        if (std::any_of(taken.begin(), taken.end(),
                        [&](const Footprint& t) { return overlap(f, t); })) {
          continue;
        }
        place(f, base.top_z, true);
      }
      for (int attempt = 0; attempt < kPlacementAttempts && !done; ++attempt) {
        const int area_index = static_cast<int>(rng() % areas.size());
        const Area& a = areas[static_cast<std::size_t>(area_index)];
        if (box.sizes().z() > a.max_height) continue;
        Footprint f{{uniform(a.x0, a.x1), uniform(a.y0, a.y1)},
                    uniform(0.0f, 2.0f * kPi),
                    half,
                    area_index};
        if (touching) {
          f.yaw = 0.5f * kPi * static_cast<float>(rng() % 4);
          const Eigen::Vector2f wh = f.worldHalf();
          // Against the wall, or against the side of an earlier axis-aligned object.
          std::vector<const Footprint*> neighbours;
          for (std::size_t k = clutter; k < taken.size(); ++k) {
            if (taken[k].area == area_index && std::fmod(taken[k].yaw, 0.5f * kPi) == 0.0f) {
              neighbours.push_back(&taken[k]);
            }
          }
          if (neighbours.empty() || rng() % 2 == 0) {
            f.centre.y() = a.y1 - wh.y();
          } else {
            const Footprint& n = *neighbours[rng() % neighbours.size()];
            const Eigen::Vector2f nh = n.worldHalf();
            const int side = static_cast<int>(rng() % 4);
            const float along = uniform(-0.5f, 0.5f);
            if (side < 2) {
              f.centre.x() = n.centre.x() + (side == 0 ? 1.0f : -1.0f) * (nh.x() + wh.x());
              f.centre.y() = n.centre.y() + along * std::min(nh.y(), wh.y());
            } else {
              f.centre.y() = n.centre.y() + (side == 2 ? 1.0f : -1.0f) * (nh.y() + wh.y());
              f.centre.x() = n.centre.x() + along * std::min(nh.x(), wh.x());
            }
          }
        }
        if (!inside(f, a)) continue;
        if (std::any_of(taken.begin(), taken.end(),
                        [&](const Footprint& t) { return overlap(f, t); }))
          continue;
        place(f, a.z, false);
      }
    }
    if (!done) {
      throw std::runtime_error("scene: object " + std::to_string(id) + " does not fit on the " +
                               std::string(toString(config.preset)) + " after " +
                               std::to_string(kShapeTries) + " shapes; ask for fewer objects");
    }
  }

  // A cable lying across the main area from the wall, around the objects: clutter.
  for (int cable = 0; cable < (hard ? 3 : 1) && config.preset != ScenePreset::kShelf; ++cable) {
    const Area& a = areas.front();
    const float radius = 0.003f;
    for (int attempt = 0; attempt < 50; ++attempt) {
      const float x0 = uniform(a.x0 + 0.1f, a.x1 - 0.1f), x1 = uniform(a.x0 + 0.1f, a.x1 - 0.1f);
      const float wiggle = uniform(0.02f, 0.06f), phase = uniform(0.0f, 2.0f * kPi);
      const float length = uniform(0.3f, 0.6f) * (a.y1 - a.y0);
      auto centre = [&](float t) {
        return Eigen::Vector3f(x0 + (x1 - x0) * t + wiggle * std::sin(6.0f * t + phase),
                               a.y1 - 0.005f - length * t, a.z + radius);
      };
      bool clear = true;
      for (int k = 0; k <= 60 && clear; ++k) {
        const Eigen::Vector3f c = centre(static_cast<float>(k) / 60.0f);
        const Footprint dot{c.head<2>(), 0.0f, {radius, radius}, 0};
        clear = inside(dot, a) && std::none_of(taken.begin(), taken.end(),
                                               [&](const Footprint& t) { return overlap(dot, t); });
      }
      if (!clear) continue;
      addSupport(scene.mesh,
                 shapes::tube(
                     centre, [&](float) { return radius; }, 61, 8),
                 kCableColor);
      break;
    }
  }
  scene.mesh.computeNormals();
  return scene;
}

void HandheldPathConfig::validate() const {
  if (frames < 1) throw std::invalid_argument("path: frames must be >= 1");
  if (!(rate_hz > 0.0)) throw std::invalid_argument("path: rate_hz must be > 0");
  if (!(min_distance_m > 0.0) || !(max_distance_m >= min_distance_m)) {
    throw std::invalid_argument("path: need 0 < min_distance_m <= max_distance_m");
  }
  if (!(min_elevation_rad >= 0.0) || !(max_elevation_rad >= min_elevation_rad) ||
      max_elevation_rad >= 1.5) {
    throw std::invalid_argument("path: need 0 <= min_elevation_rad <= max_elevation_rad < 1.5");
  }
}

Trajectory makeHandheldPath(const SyntheticScene& scene, const HandheldPathConfig& config) {
  config.validate();
  std::mt19937_64 rng(config.seed * 7919 + 17);
  auto uniform = [&](double a, double b) {
    return std::uniform_real_distribution<double>(a, b)(rng);
  };
  // Smooth wobble: a few sinusoids with random frequencies (0.2-1.5 Hz) and phases per axis.
  struct Wave {
    double amplitude, hz, phase;
  };
  auto waves = [&](double amplitude) {
    std::vector<Wave> w;
    for (int k = 0; k < 3; ++k)
      w.push_back({amplitude / 3.0, uniform(0.2, 1.5), uniform(0, 2 * std::numbers::pi)});
    return w;
  };
  auto sum = [](const std::vector<Wave>& w, double t) {
    double s = 0.0;
    for (const Wave& x : w) s += x.amplitude * std::sin(2 * std::numbers::pi * x.hz * t + x.phase);
    return s;
  };
  const std::vector<Wave> jitter[3] = {waves(config.jitter_m), waves(config.jitter_m),
                                       waves(config.jitter_m)};
  const std::vector<Wave> look[3] = {waves(0.05), waves(0.05), waves(0.03)};
  const std::vector<Wave> roll = waves(config.roll_rad);
  const double distance_phase = uniform(0, 2 * std::numbers::pi);
  const double elevation_phase = uniform(0, 2 * std::numbers::pi);
  const double direction = rng() % 2 ? 1.0 : -1.0;

  Trajectory path;
  const Eigen::Vector3d target = scene.look_at_W.cast<double>();
  // A hand moves at walking-around-a-desk speeds whatever the recording's length: the sweep
  // turns at most kMaxSweepRate (0.15 m/s at 1.2 m) and the distance and height change with
  // periods of seconds, so a short recording covers a short stretch of the arc.
  constexpr double kMaxSweepRate_rad_per_s = 0.12;
  constexpr double kDistancePeriod_s = 8.0, kElevationPeriod_s = 12.0;
  const double duration = (config.frames - 1) / config.rate_hz;
  const double sweep = std::min(config.sweep_rad, kMaxSweepRate_rad_per_s * duration);
  for (int i = 0; i < config.frames; ++i) {
    const double t = i / config.rate_hz;
    const double s = duration > 0.0 ? t / duration : 0.5;
    // From one side to the other with an easing, so the hand slows at the ends.
    const double azimuth = direction * sweep * 0.5 * -std::cos(std::numbers::pi * s);
    const double mid_d = 0.5 * (config.min_distance_m + config.max_distance_m);
    const double amp_d = 0.5 * (config.max_distance_m - config.min_distance_m);
    const double distance =
        mid_d + amp_d * std::sin(2 * std::numbers::pi * t / kDistancePeriod_s + distance_phase);
    const double mid_e = 0.5 * (config.min_elevation_rad + config.max_elevation_rad);
    const double amp_e = 0.5 * (config.max_elevation_rad - config.min_elevation_rad);
    const double elevation =
        mid_e + amp_e * std::sin(2 * std::numbers::pi * t / kElevationPeriod_s + elevation_phase);
    // In front of the wall is -y; azimuth turns about z.
    const Eigen::Vector3d offset(distance * std::cos(elevation) * std::sin(azimuth),
                                 -distance * std::cos(elevation) * std::cos(azimuth),
                                 distance * std::sin(elevation));
    const Eigen::Vector3d position =
        target + offset + Eigen::Vector3d(sum(jitter[0], t), sum(jitter[1], t), sum(jitter[2], t));
    const Eigen::Vector3d aim =
        target + Eigen::Vector3d(sum(look[0], t), sum(look[1], t), sum(look[2], t));

    const Eigen::Vector3d z = (aim - position).normalized();
    const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();  // right, level
    const Eigen::Vector3d y = z.cross(x);                                      // down
    Eigen::Matrix3d R;
    R << x, y, z;
    R = R * Eigen::AngleAxisd(sum(roll, t), Eigen::Vector3d::UnitZ()).toRotationMatrix();
    Pose T_W_C = Pose::Identity();
    T_W_C.linear() = R.cast<float>();
    T_W_C.translation() = position.cast<float>();
    path.poses.push_back({t, T_W_C});
  }
  return path;
}

}  // namespace objscan::capture
