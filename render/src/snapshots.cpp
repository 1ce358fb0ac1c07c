#include "objscan/render/snapshots.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "objscan/render/offscreen_renderer.h"
#include "objscan/core/mesh_orientation.h"
#include "objscan/core/palette.h"

namespace objscan::render {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kHorizontalFovDeg = 60.0;
/// The share of the image's half-width left free around the framed points.
constexpr double kMargin = 0.06;
/// Scene vertices outside this share (the farthest out, per side) may fall outside the overview:
/// a stray wall or floor patch should not shrink the scene to a stamp.
constexpr double kSceneOutlierShare = 0.02;
constexpr int kProbeWidth = 160, kProbeHeight = 120;
const cv::Vec3b kBackgroundBgr(250, 248, 246);
const cv::Vec3b kOutlineBgr(40, 40, 40);

cv::Scalar bgrOf(std::size_t rank) {
  const auto c = rankColour(rank);
  return {static_cast<double>(c[2]), static_cast<double>(c[1]), static_cast<double>(c[0])};
}

/// A camera with a horizontal field of view of kHorizontalFovDeg and square pixels.
Intrinsics snapshotIntrinsics(int width, int height) {
  Intrinsics in;
  in.width_px = width;
  in.height_px = height;
  in.fx_px = in.fy_px = 0.5 * width / std::tan(0.5 * kHorizontalFovDeg * kPi / 180.0);
  in.cx_px = 0.5 * (width - 1);
  in.cy_px = 0.5 * (height - 1);
  in.validate();
  return in;
}

/// Camera axes looking along `forward` with `up` as near the image's up as possible.
Eigen::Matrix3f lookAlong(const Eigen::Vector3f& forward, const Eigen::Vector3f& up) {
  const Eigen::Vector3f z = forward.normalized();
  Eigen::Vector3f x = z.cross(up);
  if (x.norm() < 1e-4f) x = z.cross(z.unitOrthogonal());  // looking straight along `up`
  x.normalize();
  Eigen::Matrix3f R;
  R.col(0) = x;
  R.col(1) = z.cross(x);  // y points down in the image
  R.col(2) = z;
  return R;
}

/// The camera position, for fixed axes R, nearest to the points from which all of `required` and
/// all but kSceneOutlierShare (per side) of `scene` are inside the frustum with a margin. Each side
/// of the frustum is a half-space constraint linear in the camera offset; the offset across is
/// chosen so that both sides of an axis touch, and the one along the axis is the largest that
/// satisfies both axes.
Eigen::Vector3f framedPosition(const Eigen::Matrix3f& R, const Intrinsics& in,
                               const std::vector<Eigen::Vector3f>& required,
                               const std::vector<Eigen::Vector3f>& scene) {
  const double tx = (1.0 - kMargin) * 0.5 * in.width_px / in.fx_px;
  const double ty = (1.0 - kMargin) * 0.5 * in.height_px / in.fy_px;
  // For each axis, a_i = z - x/t and b_i = z + x/t: the camera offset (d, dz) sees point i when
  // dz <= a_i + d/t and dz <= b_i - d/t.
  std::array<std::vector<double>, 4> scene_terms, required_terms;
  const auto collect = [&](const std::vector<Eigen::Vector3f>& points,
                           std::array<std::vector<double>, 4>& terms) {
    for (auto& t : terms) t.reserve(points.size());
    for (const Eigen::Vector3f& p : points) {
      const Eigen::Vector3d q = (R.transpose() * p).cast<double>();
      terms[0].push_back(q.z() - q.x() / tx);
      terms[1].push_back(q.z() + q.x() / tx);
      terms[2].push_back(q.z() - q.y() / ty);
      terms[3].push_back(q.z() + q.y() / ty);
    }
  };
  collect(required, required_terms);
  collect(scene, scene_terms);
  std::array<double, 4> lowest;
  for (int k = 0; k < 4; ++k) {
    double low = std::numeric_limits<double>::infinity();
    if (!required_terms[k].empty()) {
      low = *std::min_element(required_terms[k].begin(), required_terms[k].end());
    }
    std::vector<double>& s = scene_terms[k];
    if (!s.empty()) {
      const auto nth = s.begin() + static_cast<std::ptrdiff_t>(kSceneOutlierShare * s.size());
      std::nth_element(s.begin(), nth, s.end());
      low = std::min(low, *nth);
    }
    lowest[k] = low;
  }
  if (!std::isfinite(lowest[0])) throw std::invalid_argument("snapshot: nothing to frame");
  const double dx = tx * (lowest[1] - lowest[0]) / 2.0;
  const double dy = ty * (lowest[3] - lowest[2]) / 2.0;
  const double dz = std::min((lowest[0] + lowest[1]) / 2.0, (lowest[2] + lowest[3]) / 2.0);
  return R * Eigen::Vector3d(dx, dy, dz).cast<float>();
}

/// At most `limit` of the mesh's vertices, evenly spread over its index range.
std::vector<Eigen::Vector3f> sampleVertices(const TriangleMesh& mesh, std::size_t limit) {
  const std::size_t n = mesh.positions.size();
  const std::size_t step = std::max<std::size_t>(1, n / limit);
  std::vector<Eigen::Vector3f> out;
  out.reserve(n / step + 1);
  for (std::size_t i = 0; i < n; i += step) out.push_back(mesh.positions[i]);
  return out;
}

/// The horizontal direction towards the side the surfaces face: the mean normal (`mean`, from
/// faceNormals) without its up part, or (when it has none) the horizontal axis across which the
/// scene is thinnest.
Eigen::Vector3f frontOf(const TriangleMesh& mesh, const Eigen::Vector3d& mean,
                        const Eigen::Vector3f& up) {
  Eigen::Vector3f front = (mean - mean.dot(up.cast<double>()) * up.cast<double>()).cast<float>();
  if (front.norm() > 0.05f * static_cast<float>(mean.norm()) && front.norm() > 0.0f) {
    return front.normalized();
  }
  const Eigen::Vector3f a = up.unitOrthogonal(), b = up.cross(a);
  double sa = 0.0, sb = 0.0, ma = 0.0, mb = 0.0;
  const std::vector<Eigen::Vector3f> sample = sampleVertices(mesh, 20000);
  for (const Eigen::Vector3f& p : sample) {
    ma += a.dot(p);
    mb += b.dot(p);
  }
  ma /= static_cast<double>(sample.size());
  mb /= static_cast<double>(sample.size());
  for (const Eigen::Vector3f& p : sample) {
    sa += std::pow(a.dot(p) - ma, 2);
    sb += std::pow(b.dot(p) - mb, 2);
  }
  return sa < sb ? a : b;
}

Eigen::Matrix3f rotationAbout(const Eigen::Vector3f& axis, double degrees) {
  return Eigen::AngleAxisf(static_cast<float>(degrees * kPi / 180.0), axis.normalized())
      .toRotationMatrix();
}

/// Camera axes of the trajectory's typical view: the mean of its viewing and up directions; when
/// those disagree too much to average (a path round the scene), the axes of the pose nearest the
/// mean position.
Eigen::Matrix3f trajectoryAxes(const Trajectory& trajectory) {
  Eigen::Vector3f forward = Eigen::Vector3f::Zero(), up = Eigen::Vector3f::Zero();
  Eigen::Vector3f centre = Eigen::Vector3f::Zero();
  for (const StampedPose& p : trajectory.poses) {
    forward += p.T_W_C.linear().col(2);
    up -= p.T_W_C.linear().col(1);
    centre += p.T_W_C.translation();
  }
  const float n = static_cast<float>(trajectory.size());
  forward /= n;
  up /= n;
  centre /= n;
  if (forward.norm() >= 0.5f && up.norm() >= 0.5f) return lookAlong(forward, up);
  const StampedPose* nearest = &trajectory.poses.front();
  for (const StampedPose& p : trajectory.poses) {
    if ((p.T_W_C.translation() - centre).squaredNorm() <
        (nearest->T_W_C.translation() - centre).squaredNorm()) {
      nearest = &p;
    }
  }
  return nearest->T_W_C.linear();
}

/// Draws a filled disc in the rank's colour with its number, a white ring and a dark rim.
void drawRankBadge(cv::Mat& bgr, cv::Point centre, std::size_t rank, int radius) {
  const cv::Scalar colour = bgrOf(rank);
  cv::circle(bgr, centre, radius + 2, cv::Scalar(30, 30, 30), cv::FILLED, cv::LINE_AA);
  cv::circle(bgr, centre, radius, cv::Scalar(255, 255, 255), cv::FILLED, cv::LINE_AA);
  cv::circle(bgr, centre, radius - std::max(2, radius / 8), colour, cv::FILLED, cv::LINE_AA);
  const std::string text = std::to_string(rank);
  const int font = cv::FONT_HERSHEY_DUPLEX;
  const int thickness = std::max(1, radius / 8);
  const double scale =
      cv::getFontScaleFromHeight(font, radius, thickness) * (text.size() > 1 ? 0.75 : 1.0);
  int baseline = 0;
  const cv::Size size = cv::getTextSize(text, font, scale, thickness, &baseline);
  const double luminance = 0.299 * colour[2] + 0.587 * colour[1] + 0.114 * colour[0];
  const cv::Scalar ink = luminance > 150 ? cv::Scalar(20, 20, 20) : cv::Scalar(255, 255, 255);
  cv::putText(bgr, text, {centre.x - size.width / 2, centre.y + size.height / 2}, font, scale, ink,
              thickness, cv::LINE_AA);
}

}  // namespace

ViewKind parseViewKind(const std::string& name) {
  if (name == "auto") return ViewKind::kAuto;
  if (name == "trajectory") return ViewKind::kTrajectory;
  if (name == "three-quarter") return ViewKind::kThreeQuarter;
  if (name == "top") return ViewKind::kTop;
  throw std::invalid_argument("unknown view '" + name +
                              "' (use auto, trajectory, three-quarter or top)");
}

const char* toString(ViewKind kind) {
  switch (kind) {
    case ViewKind::kAuto:
      return "auto";
    case ViewKind::kTrajectory:
      return "trajectory";
    case ViewKind::kThreeQuarter:
      return "three-quarter";
    case ViewKind::kTop:
      return "top";
  }
  return "?";
}

Eigen::Vector3f sceneUp(const TriangleMesh& mesh) { return objscan::sceneUp(mesh); }

SnapshotView overviewView(const TriangleMesh& scene, const Trajectory* trajectory,
                          const std::vector<PaintedHypothesis>& hypotheses, int width, int height,
                          ViewKind kind) {
  const bool has_trajectory = trajectory != nullptr && !trajectory->empty();
  if (kind == ViewKind::kAuto)
    kind = has_trajectory ? ViewKind::kTrajectory : ViewKind::kThreeQuarter;
  if (kind == ViewKind::kTrajectory && !has_trajectory) {
    throw std::invalid_argument("the trajectory view needs a trajectory (trajectory.txt)");
  }
  if (scene.positions.empty()) throw std::invalid_argument("snapshot: the mesh is empty");
  SnapshotView view;
  view.kind = kind;
  view.intrinsics = snapshotIntrinsics(width, height);
  Eigen::Matrix3f R;
  if (kind == ViewKind::kTrajectory) {
    R = trajectoryAxes(*trajectory);
  } else {
    const FaceNormals normals = faceNormals(scene);  // one pass serves both directions
    const Eigen::Vector3f up = upOf(normals);
    const Eigen::Vector3f front = frontOf(scene, normals.mean, up);
    if (kind == ViewKind::kTop) {
      R = lookAlong(-up, front);
    } else {
      // From the front, 45 degrees round and 35 degrees up: the camera sits at `eye`'s side.
      const Eigen::Vector3f round = rotationAbout(up, 45.0) * front;
      const float elevation = static_cast<float>(35.0 * kPi / 180.0);
      const Eigen::Vector3f eye = std::cos(elevation) * round + std::sin(elevation) * up;
      R = lookAlong(-eye, up);
    }
  }
  std::vector<Eigen::Vector3f> required;
  for (const PaintedHypothesis& h : hypotheses) {
    for (std::int32_t v : h.vertices) required.push_back(scene.positions.at(v));
  }
  view.T_W_C.linear() = R;
  view.T_W_C.translation() =
      framedPosition(R, view.intrinsics, required, sampleVertices(scene, 50000));
  return view;
}

struct SnapshotRenderer::Impl {
  TriangleMesh painted;  // the scene with paled colours, hypothesis colours, ranks as labels
  std::vector<PaintedHypothesis> hypotheses;
  std::vector<std::unique_ptr<OffscreenRenderer>> renderers;  // one per camera

  /// The scene's renderer for this camera (OSMesa's framebuffer and projection are fixed per
  /// renderer; the views of one run use two or three cameras).
  RenderedView render(const SnapshotView& view) {
    for (auto& r : renderers) {
      if (r->intrinsics() == view.intrinsics) return r->render(view.T_W_C);
    }
    renderers.push_back(std::make_unique<OffscreenRenderer>(view.intrinsics, 0.005f, 200.0f));
    renderers.back()->setMesh(painted);
    return renderers.back()->render(view.T_W_C);
  }

  /// The picture: background where nothing was hit, dark outlines round painted regions.
  static cv::Mat compose(const RenderedView& view) {
    cv::Mat bgr;
    cv::cvtColor(view.color_rgb, bgr, cv::COLOR_RGB2BGR);
    const cv::Mat& ranks = view.label;
    cv::Mat outline = cv::Mat::zeros(ranks.size(), CV_8UC1);
    for (int y = 0; y < ranks.rows; ++y) {
      const auto* row = ranks.ptr<std::int32_t>(y);
      const float* depth = view.depth_m.ptr<float>(y);
      auto* out = bgr.ptr<cv::Vec3b>(y);
      auto* edge = outline.ptr<std::uint8_t>(y);
      for (int x = 0; x < ranks.cols; ++x) {
        if (depth[x] <= 0.0f) out[x] = kBackgroundBgr;
        if (row[x] <= 0) continue;
        const bool border = (x > 0 && row[x - 1] != row[x]) ||
                            (x + 1 < ranks.cols && row[x + 1] != row[x]) ||
                            (y > 0 && ranks.at<std::int32_t>(y - 1, x) != row[x]) ||
                            (y + 1 < ranks.rows && ranks.at<std::int32_t>(y + 1, x) != row[x]);
        if (border) edge[x] = 255;
      }
    }
    if (bgr.cols >= 960) cv::dilate(outline, outline, cv::Mat());
    bgr.setTo(cv::Scalar(kOutlineBgr[0], kOutlineBgr[1], kOutlineBgr[2]), outline);
    return bgr;
  }
};

SnapshotRenderer::SnapshotRenderer(const TriangleMesh& scene,
                                   std::vector<PaintedHypothesis> hypotheses)
    : impl_(std::make_unique<Impl>()) {
  scene.validate();
  Impl& d = *impl_;
  d.painted.positions = scene.positions;
  d.painted.triangles = scene.triangles;
  const std::size_t n = scene.positions.size();
  d.painted.colors.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    // Paled and mostly grey: the scene stays recognisable, the painted colours stand out.
    const Rgb8 c = scene.colors.empty() ? Rgb8(200, 200, 200) : scene.colors[i];
    const double grey = 0.299 * c.x() + 0.587 * c.y() + 0.114 * c.z();
    const auto pale = [&](double channel) {
      return static_cast<std::uint8_t>(std::lround(0.25 * channel + 0.45 * grey + 0.30 * 235.0));
    };
    d.painted.colors[i] = Rgb8(pale(c.x()), pale(c.y()), pale(c.z()));
  }
  d.painted.labels.assign(n, 0);
  std::vector<std::size_t> order(hypotheses.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  // Worse ranks first, so that the better rank wins a shared vertex.
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return hypotheses[a].rank > hypotheses[b].rank; });
  for (std::size_t i : order) {
    const PaintedHypothesis& h = hypotheses[i];
    if (h.rank == 0) throw std::invalid_argument("snapshot: hypothesis ranks start at 1");
    const auto c = rankColour(h.rank);
    for (std::int32_t v : h.vertices) {
      if (v < 0 || static_cast<std::size_t>(v) >= n) {
        throw std::invalid_argument("snapshot: hypothesis " + std::to_string(h.rank) +
                                    " names vertex " + std::to_string(v) + ", but the mesh has " +
                                    std::to_string(n));
      }
      d.painted.colors[v] = Rgb8(c[0], c[1], c[2]);
      d.painted.labels[v] = static_cast<std::int32_t>(h.rank);
    }
  }
  d.hypotheses = std::move(hypotheses);
}

SnapshotRenderer::~SnapshotRenderer() = default;

const std::vector<PaintedHypothesis>& SnapshotRenderer::hypotheses() const {
  return impl_->hypotheses;
}

Snapshot SnapshotRenderer::overview(const SnapshotView& view) {
  const RenderedView rendered = impl_->render(view);
  Snapshot shot;
  shot.bgr = Impl::compose(rendered);
  shot.ranks = rendered.label;  // `rendered` goes out of scope: no copy needed
  const int radius = std::clamp(view.intrinsics.height_px / 44, 1,
                                std::max(1, std::min(shot.bgr.cols, shot.bgr.rows) / 2 - 6));
  for (const PaintedHypothesis& h : impl_->hypotheses) {
    const cv::Mat mask = shot.ranks == static_cast<std::int32_t>(h.rank);
    const cv::Rect box = cv::boundingRect(mask);
    if (box.area() == 0) continue;
    // The label sits at the pixel farthest inside the visible region.
    cv::Mat padded;
    cv::copyMakeBorder(mask(box), padded, 1, 1, 1, 1, cv::BORDER_CONSTANT, 0);
    cv::Mat distance;
    cv::distanceTransform(padded, distance, cv::DIST_L2, 3);
    cv::Point inside;
    cv::minMaxLoc(distance, nullptr, nullptr, nullptr, &inside);
    const cv::Point centre(
        std::clamp(box.x + inside.x - 1, radius + 2, shot.bgr.cols - radius - 3),
        std::clamp(box.y + inside.y - 1, radius + 2, shot.bgr.rows - radius - 3));
    drawRankBadge(shot.bgr, centre, h.rank, radius);
    shot.labelled.push_back(h.rank);
  }
  std::sort(shot.labelled.begin(), shot.labelled.end());
  return shot;
}

Snapshot SnapshotRenderer::closeUp(std::size_t index, const SnapshotView& overview, int width,
                                   int height) {
  Impl& d = *impl_;
  const PaintedHypothesis& h = d.hypotheses.at(index);
  if (h.vertices.empty()) throw std::invalid_argument("snapshot: a hypothesis has no vertices");
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(INFINITY), hi = -lo;
  for (std::int32_t v : h.vertices) {
    lo = lo.cwiseMin(d.painted.positions[v]);
    hi = hi.cwiseMax(d.painted.positions[v]);
  }
  const Eigen::Vector3f target = 0.5f * (lo + hi);
  float radius = 1e-3f;
  for (std::int32_t v : h.vertices) {
    radius = std::max(radius, (d.painted.positions[v] - target).norm());
  }
  const Eigen::Matrix3f& R0 = overview.T_W_C.linear();
  const Eigen::Vector3f up = -R0.col(1), right = R0.col(0), forward = R0.col(2);
  // The overview's direction, turned 40 degrees either way, and from higher up.
  const std::array<Eigen::Vector3f, 4> directions = {forward, rotationAbout(up, 40.0) * forward,
                                                     rotationAbout(up, -40.0) * forward,
                                                     rotationAbout(right, -30.0) * forward};
  const auto cameraFor = [&](const Eigen::Vector3f& f, int w, int hgt) {
    SnapshotView v;
    v.kind = overview.kind;
    v.intrinsics = snapshotIntrinsics(w, hgt);
    const double half_v = std::atan(0.5 * hgt / v.intrinsics.fy_px);
    const double half_u = std::atan(0.5 * w / v.intrinsics.fx_px);
    const float distance = radius / static_cast<float>(std::tan(std::min(half_u, half_v)) * 0.7);
    v.T_W_C.linear() = lookAlong(f, up);
    v.T_W_C.translation() = target - distance * f.normalized();
    return v;
  };
  const std::int32_t label = static_cast<std::int32_t>(h.rank);
  std::size_t best = 0;
  int best_pixels = -1;
  for (std::size_t k = 0; k < directions.size(); ++k) {
    const RenderedView probe = d.render(cameraFor(directions[k], kProbeWidth, kProbeHeight));
    const int pixels = cv::countNonZero(probe.label == label);
    if (pixels > best_pixels) {
      best_pixels = pixels;
      best = k;
    }
  }
  const SnapshotView view = cameraFor(directions[best], width, height);
  const RenderedView rendered = d.render(view);
  Snapshot shot;
  shot.bgr = Impl::compose(rendered);
  shot.ranks = rendered.label;  // `rendered` goes out of scope: no copy needed
  const int badge = std::max(9, height / 16);
  if (h.show_rank) drawRankBadge(shot.bgr, {badge + 8, badge + 8}, h.rank, badge);
  if (cv::countNonZero(shot.ranks == label) > 0) shot.labelled.push_back(h.rank);
  return shot;
}

cv::Mat contactSheet(const std::vector<cv::Mat>& closeups,
                     const std::vector<PaintedHypothesis>& hypotheses, int columns) {
  if (closeups.size() != hypotheses.size()) {
    throw std::invalid_argument("contact sheet: one close-up per hypothesis is needed");
  }
  if (closeups.empty()) return {};
  const cv::Size tile = closeups.front().size();
  for (const cv::Mat& c : closeups) {
    if (c.size() != tile || c.type() != CV_8UC3) {
      throw std::invalid_argument("contact sheet: the close-ups differ in size or type");
    }
  }
  const int n = static_cast<int>(closeups.size());
  if (columns <= 0) {
    columns = n <= 3 ? n : static_cast<int>(std::ceil(std::sqrt(static_cast<double>(n))));
  }
  const int rows = (n + columns - 1) / columns;
  const int gap = 8, caption = std::max(28, tile.height / 9);
  cv::Mat sheet(rows * (tile.height + caption + gap) + gap, columns * (tile.width + gap) + gap,
                CV_8UC3, cv::Scalar(255, 255, 255));
  const int font = cv::FONT_HERSHEY_SIMPLEX;
  const double scale = cv::getFontScaleFromHeight(font, caption / 2, 1);
  for (int i = 0; i < n; ++i) {
    const int x = gap + (i % columns) * (tile.width + gap);
    const int y = gap + (i / columns) * (tile.height + caption + gap);
    closeups[i].copyTo(sheet(cv::Rect(x, y, tile.width, tile.height)));
    const PaintedHypothesis& h = hypotheses[i];
    const int swatch = caption / 2 - 3;
    const cv::Point dot(x + swatch + 2, y + tile.height + caption / 2);
    cv::circle(sheet, dot, swatch, bgrOf(h.rank), cv::FILLED, cv::LINE_AA);
    char text[64];
    std::snprintf(text, sizeof text, "#%zu   %s %+.3f", h.rank,
                  h.object_score ? "object score" : "score", h.score);
    cv::putText(sheet, text, {dot.x + swatch + 8, dot.y + caption / 4}, font, scale,
                cv::Scalar(30, 30, 30), 1, cv::LINE_AA);
  }
  return sheet;
}

}  // namespace objscan::render
