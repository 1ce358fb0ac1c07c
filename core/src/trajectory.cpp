#include "objscan/core/trajectory.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <string_view>

#include <Eigen/Geometry>

#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"

namespace objscan {
namespace {

constexpr double kQuaternionNormTolerance = 0.01;

/// Splits a line on spaces, tabs and commas and parses each field as a double.
bool parseNumbers(std::string_view line, std::vector<double>& out, std::string& bad) {
  out.clear();
  std::size_t i = 0;
  auto sep = [](char c) { return c == ' ' || c == '\t' || c == ',' || c == '\r'; };
  while (i < line.size()) {
    while (i < line.size() && sep(line[i])) ++i;
    if (i == line.size()) break;
    const std::size_t start = i;
    while (i < line.size() && !sep(line[i])) ++i;
    const char* b = line.data() + start;
    const char* e = line.data() + i;
    if (*b == '+') ++b;
    double v = 0.0;
    const auto [ptr, ec] = std::from_chars(b, e, v);
    if (ec != std::errc() || ptr != e) {
      bad = std::string(line.substr(start, std::min<std::size_t>(i - start, 40)));
      return false;
    }
    out.push_back(v);
  }
  return true;
}

}  // namespace

StampedPose stampedPoseFromTum(const std::array<double, 8>& v) {
  for (double x : v) {
    if (!std::isfinite(x)) throw std::invalid_argument("contains NaN or infinity");
  }
  const Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
  if (std::abs(q.norm() - 1.0) > kQuaternionNormTolerance) {
    throw std::invalid_argument("quaternion (qx qy qz qw) has norm " + std::to_string(q.norm()) +
                                ", not 1 (is the column order 't tx ty tz qx qy qz qw'?)");
  }
  StampedPose sp;
  sp.stamp_s = v[0];
  sp.T_W_C = poseFromTranslationQuaternion(Eigen::Vector3d(v[1], v[2], v[3]).cast<float>(),
                                           q.normalized().cast<float>());
  if (!sp.T_W_C.translation().allFinite()) {
    throw std::invalid_argument("a coordinate is too large (more than 3.4e38 m)");
  }
  return sp;
}

double Trajectory::durationS() const {
  return poses.size() < 2 ? 0.0 : poses.back().stamp_s - poses.front().stamp_s;
}

double Trajectory::pathLengthM() const {
  double length = 0.0;
  for (std::size_t i = 1; i < poses.size(); ++i) {
    length +=
        (poses[i].T_W_C.translation() - poses[i - 1].T_W_C.translation()).cast<double>().norm();
  }
  return length;
}

Trajectory readTumTrajectory(const std::filesystem::path& path) {
  const std::string text = readWholeFile(path);
  if (text.empty()) throw InputError(path, "the file is empty");
  Trajectory trajectory;
  std::vector<double> v;
  std::string bad;
  std::size_t pos = 0;
  int line_no = 0;
  while (pos < text.size()) {
    std::size_t eol = text.find('\n', pos);
    if (eol == std::string::npos) eol = text.size();
    const std::string_view line(text.data() + pos, eol - pos);
    pos = eol + 1;
    ++line_no;
    const std::string where = "line " + std::to_string(line_no) + ": ";
    const std::size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string_view::npos || line[first] == '#') continue;
    if (!parseNumbers(line, v, bad)) {
      throw InputError(path,
                       where + "'" + bad + "' is not a number (expected 't tx ty tz qx qy qz qw')");
    }
    if (v.size() != 8) {
      throw InputError(path, where + "expected 8 numbers 't tx ty tz qx qy qz qw', found " +
                                 std::to_string(v.size()));
    }
    StampedPose sp;
    try {
      sp = stampedPoseFromTum({v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7]});
    } catch (const std::invalid_argument& e) {
      throw InputError(path, where + e.what());
    }
    if (!trajectory.poses.empty() && sp.stamp_s < trajectory.poses.back().stamp_s) {
      throw InputError(path, where + "time stamp " + std::to_string(sp.stamp_s) +
                                 " is earlier than the line before");
    }
    trajectory.poses.push_back(sp);
  }
  if (trajectory.empty()) throw InputError(path, "contains no poses");
  return trajectory;
}

void writeTumTrajectory(const std::filesystem::path& path, const Trajectory& trajectory) {
  std::string out =
      "# objscan trajectory, TUM format: timestamp tx ty tz qx qy qz qw (T_W_C, metres)\n";
  char buf[64];
  auto put = [&](float x) {
    const auto r = std::to_chars(buf, buf + sizeof buf, x);  // shortest exact representation
    out += ' ';
    out.append(buf, r.ptr);
  };
  for (std::size_t i = 1; i < trajectory.poses.size(); ++i) {
    if (trajectory.poses[i].stamp_s < trajectory.poses[i - 1].stamp_s) {
      // readTumTrajectory (and the TUM tools) would refuse the file: never write one.
      throw std::invalid_argument(path.string() + ": pose " + std::to_string(i + 1) +
                                  " is earlier than the pose before; a trajectory is written in "
                                  "time order");
    }
  }
  for (const StampedPose& sp : trajectory.poses) {
    std::snprintf(buf, sizeof buf, "%.6f", sp.stamp_s);
    out += buf;
    const Eigen::Vector3f t = sp.T_W_C.translation();
    const Eigen::Quaternionf q(sp.T_W_C.rotation());
    put(t.x());
    put(t.y());
    put(t.z());
    put(q.x());
    put(q.y());
    put(q.z());
    put(q.w());
    out += '\n';
  }
  writeFileAtomically(path, out);
}

std::optional<Eigen::Vector3f> viewUp(const Trajectory& trajectory) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const StampedPose& p : trajectory.poses) {
    sum -= p.T_W_C.linear().col(1).cast<double>();
  }
  // Half the poses facing up, half down: no direction.
  if (!(sum.norm() > 1e-3 * static_cast<double>(trajectory.size()))) return std::nullopt;
  return sum.normalized().cast<float>();
}

std::optional<Pose> nearestPose(const Trajectory& trajectory, double stamp_s, double max_dt_s) {
  const auto it = std::lower_bound(trajectory.poses.begin(), trajectory.poses.end(), stamp_s,
                                   [](const StampedPose& p, double s) { return p.stamp_s < s; });
  const StampedPose* best = nullptr;
  if (it != trajectory.poses.end()) best = &*it;
  if (it != trajectory.poses.begin()) {
    const StampedPose& before = *(it - 1);
    if (!best || stamp_s - before.stamp_s < best->stamp_s - stamp_s) best = &before;
  }
  if (!best || std::abs(best->stamp_s - stamp_s) > max_dt_s) return std::nullopt;
  return best->T_W_C;
}

TrajectoryError absoluteTrajectoryError(const Trajectory& estimate, const Trajectory& truth,
                                        double max_dt_s) {
  // Candidate pairs: each estimated pose with the nearest true poses on either side in time.
  struct Pair {
    double dt;
    std::size_t e, t;
  };
  std::vector<Pair> candidates;
  for (std::size_t e = 0; e < estimate.size(); ++e) {
    const double stamp = estimate.poses[e].stamp_s;
    const auto it = std::lower_bound(truth.poses.begin(), truth.poses.end(), stamp,
                                     [](const StampedPose& p, double s) { return p.stamp_s < s; });
    const auto at = static_cast<std::size_t>(it - truth.poses.begin());
    for (std::size_t t : {at, at - 1}) {
      if (t >= truth.size()) continue;  // also catches at - 1 wrapping below 0
      const double dt = std::abs(truth.poses[t].stamp_s - stamp);
      if (dt <= max_dt_s) candidates.push_back({dt, e, t});
    }
  }
  std::sort(candidates.begin(), candidates.end(),
            [](const Pair& a, const Pair& b) { return a.dt < b.dt; });
  std::vector<bool> estimate_used(estimate.size()), truth_used(truth.size());
  std::vector<Eigen::Vector3d> from, to;
  for (const Pair& p : candidates) {
    if (estimate_used[p.e] || truth_used[p.t]) continue;
    estimate_used[p.e] = truth_used[p.t] = true;
    from.push_back(estimate.poses[p.e].T_W_C.translation().cast<double>());
    to.push_back(truth.poses[p.t].T_W_C.translation().cast<double>());
  }
  if (from.size() < 3) {
    throw std::invalid_argument("only " + std::to_string(from.size()) +
                                " poses pair up in time with the ground truth (3 needed)");
  }
  Eigen::Matrix3Xd src(3, static_cast<Eigen::Index>(from.size())), dst(3, src.cols());
  for (std::size_t i = 0; i < from.size(); ++i) {
    src.col(static_cast<Eigen::Index>(i)) = from[i];
    dst.col(static_cast<Eigen::Index>(i)) = to[i];
  }
  const Eigen::Matrix4d T = Eigen::umeyama(src, dst, false);
  TrajectoryError error;
  error.matched = from.size();
  error.T_truth_estimate.matrix() = T.cast<float>();
  double sum_sq = 0.0, sum = 0.0;
  for (Eigen::Index i = 0; i < src.cols(); ++i) {
    const double d =
        (T.topLeftCorner<3, 3>() * src.col(i) + T.topRightCorner<3, 1>() - dst.col(i)).norm();
    sum_sq += d * d;
    sum += d;
    error.max_m = std::max(error.max_m, d);
  }
  const double n = static_cast<double>(src.cols());
  error.rmse_m = std::sqrt(sum_sq / n);
  error.mean_m = sum / n;
  return error;
}

}  // namespace objscan
