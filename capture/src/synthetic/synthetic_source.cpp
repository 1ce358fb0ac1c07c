#include "objscan/capture/synthetic/synthetic_source.h"

#include "objscan/capture/folder_source.h"

#include <algorithm>
#include <cassert>
#include <charconv>
#include <limits>
#include <optional>
#include <set>
#include <stdexcept>
#include <string_view>
#include <utility>
#include <vector>

#include "objscan/capture/synthetic/synthetic_recording.h"
#include "objscan/render/offscreen_renderer.h"

namespace objscan::capture {

namespace {

constexpr std::string_view kPrefix = "synth:";

[[noreturn]] void fail(const std::string& spec, std::string_view problem) {
  std::string message = spec;
  message.append(": ").append(problem);
  throw std::invalid_argument(message);
}

/// "<key> <rule>, not '<value>'" as a spec error.
[[noreturn]] void failValue(const std::string& spec, std::string_view key, std::string_view rule,
                            std::string_view value) {
  std::string problem(key);
  problem.append(" ").append(rule).append(", not '").append(value).append("'");
  fail(spec, problem);
}

bool allDigits(std::string_view text) {
  return !text.empty() && text.find_first_not_of("0123456789") == std::string_view::npos;
}

/// A whole number in [min, max] written with digits only (no sign, no spaces), or nothing.
template <class T>
std::optional<T> parseWhole(std::string_view text, T min, T max) {
  if (!allDigits(text)) return std::nullopt;
  T value{};
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || value < min || value > max) {
    return std::nullopt;
  }
  return value;
}

}  // namespace

SynthSpec parseSynthSpec(const std::string& spec) {
  const std::string_view text = spec;
  if (!text.starts_with(kPrefix)) {
    fail(spec,
         "a synthetic source is written synth:<seed>[,preset=desk|shelf|counter][,frames=N]"
         "[,objects=K][,noise=on|full|off][,clutter=plain|hard]");
  }
  std::vector<std::string_view> parts;  // the seed, then the options
  for (std::size_t begin = kPrefix.size();;) {
    const std::size_t comma = text.find(',', begin);
    parts.push_back(text.substr(begin, comma == std::string_view::npos ? comma : comma - begin));
    if (comma == std::string_view::npos) break;
    begin = comma + 1;
  }

  // Everything not given keeps the config defaults, which are those of `objscan synth`
  // (app/synth_command.h: desk, 10 objects, 300 frames, noise on).
  SynthSpec result;
  const std::string_view seed_text = parts.front();
  const auto seed =
      parseWhole<std::uint64_t>(seed_text, 0, std::numeric_limits<std::uint64_t>::max());
  if (!seed) {
    fail(spec, seed_text.empty()      ? "the seed is missing, e.g. synth:7"
               : allDigits(seed_text) ? "the seed is too large (at most 18446744073709551615)"
                                      : "the seed must be a whole number >= 0");
  }
  // As `objscan synth --seed` does: one seed for the scene, its path and the sensor noise.
  result.scene.seed = *seed;
  result.path.seed = *seed;
  result.noise_seed = *seed;

  std::set<std::string_view> given;
  for (std::size_t i = 1; i < parts.size(); ++i) {
    const std::string_view part = parts[i];
    if (part.empty()) fail(spec, "an option is empty (two commas in a row, or one at the end)");
    const std::size_t eq = part.find('=');
    if (eq == std::string_view::npos) {
      std::string problem = "option '";
      problem.append(part).append("' needs a value, e.g. frames=100");
      fail(spec, problem);
    }
    const std::string_view key = part.substr(0, eq);
    const std::string_view value = part.substr(eq + 1);
    if (!given.insert(key).second) {
      std::string problem = "option '";
      problem.append(key).append("' is given twice");
      fail(spec, problem);
    }
    if (key == "preset") {
      try {
        result.scene.preset = scenePresetFromString(std::string(value));
      } catch (const std::invalid_argument& e) {
        fail(spec, e.what());
      }
    } else if (key == "frames") {
      const auto frames = parseWhole<int>(value, 1, std::numeric_limits<int>::max());
      if (!frames) failValue(spec, key, "must be a whole number >= 1", value);
      result.path.frames = *frames;
    } else if (key == "objects") {
      const auto objects = parseWhole<int>(value, 1, 30);  // SceneConfig::validate's range
      if (!objects) failValue(spec, key, "must be a whole number from 1 to 30", value);
      result.scene.objects = *objects;
    } else if (key == "noise") {
      const std::optional<SensorModelConfig> sensor = sensorForNoise(value);
      if (!sensor) failValue(spec, key, "must be 'on', 'full' or 'off'", value);
      result.sensor = *sensor;
    } else if (key == "clutter") {
      if (value != "plain" && value != "hard") {
        failValue(spec, key, "must be 'plain' or 'hard'", value);
      }
      result.scene.hard_clutter = value == "hard";
    } else {
      std::string problem = "unknown option '";
      problem.append(key).append("' (use preset, frames, objects, noise or clutter)");
      fail(spec, problem);
    }
  }
  return result;
}

SyntheticSource::SyntheticSource(const SynthSpec& spec, const Intrinsics& intrinsics,
                                 const capture::FrameSelection& selection,
                                 std::string intrinsics_origin)
    : spec_(spec), intrinsics_(intrinsics), selection_(selection) {
  selection_.validate();
  spec_.sensor.validate();
  intrinsics_.validate();
  // Before composing, which takes a while: the path has exactly spec.path.frames poses.
  if (spec_.path.frames > 0 && selection_.start >= static_cast<std::size_t>(spec_.path.frames)) {
    std::string problem = "--start ";
    problem.append(std::to_string(selection_.start))
        .append(" is past the last frame of the synthetic path (")
        .append(std::to_string(spec_.path.frames))
        .append(" frames)");
    throw std::invalid_argument(problem);
  }
  SceneAndPath composed = composeSceneSeenAlongPath(spec_.scene, spec_.path, intrinsics_);
  scene_ = std::move(composed.scene);
  path_ = std::move(composed.path);
  scene_seed_ = composed.scene_seed;
  assert(path_.size() == static_cast<std::size_t>(spec_.path.frames));

  std::string description = "synthetic ";
  description.append(toString(scene_.preset))
      .append(" scene, seed ")
      .append(std::to_string(spec_.scene.seed))
      .append(", ")
      .append(std::to_string(scene_.objects.size()))
      .append(" objects, ")
      .append(std::to_string(path_.size()))
      .append(" frames");
  if (!spec_.sensor.enabled) description.append(", no sensor noise");
  if (spec_.sensor.distortion_radial != 0.0 || spec_.sensor.distortion_wave != 0.0) {
    description.append(", with depth distortion");
  }
  info_.description = std::move(description);
  info_.frame_count = selection_.count(path_.size());
  info_.intrinsics = intrinsics_;
  info_.intrinsics_origin = std::move(intrinsics_origin);
  info_.ground_truth = path_;
  info_.live = false;
  next_index_ = selection_.start;
}

SyntheticSource::~SyntheticSource() = default;

const capture::SourceInfo& SyntheticSource::info() const { return info_; }

capture::FrameResult SyntheticSource::next() {
  const std::size_t stop = selection_.end ? std::min(*selection_.end, path_.size()) : path_.size();
  if (next_index_ >= stop) return capture::FrameResult::end();
  const std::size_t i = next_index_;
  next_index_ = selection_.every < stop - i ? i + selection_.every : stop;
  if (!renderer_) {
    renderer_ = std::make_unique<render::OffscreenRenderer>(intrinsics_);
    renderer_->setMesh(scene_.mesh);
  }
  const StampedPose& pose = path_.poses[i];
  SyntheticFrame rendered =
      renderSyntheticFrame(*renderer_, pose.T_W_C, i, spec_.sensor, spec_.noise_seed);
  RgbdFrame frame;
  frame.index = static_cast<std::int64_t>(i);
  frame.stamp_s = pose.stamp_s;
  frame.depth_m = std::move(rendered.depth_m);
  frame.color_rgb = std::move(rendered.view.color_rgb);
  frame.intrinsics = intrinsics_;
  return capture::FrameResult::ok(std::move(frame));
}

std::unique_ptr<capture::FrameSource> openSynthOrFolderSource(
    const std::string& spec, const capture::FrameSelection& selection,
    const std::optional<Intrinsics>& intrinsics, const std::string& intrinsics_origin) {
  if (spec.rfind("synth:", 0) != 0) {
    return capture::openFolderSource(spec, selection, intrinsics, intrinsics_origin);
  }
  const SynthSpec synth = parseSynthSpec(spec);
  if (!intrinsics)
    return std::make_unique<SyntheticSource>(synth, Intrinsics::xtionDefault(), selection);
  return std::make_unique<SyntheticSource>(synth, *intrinsics, selection,
                                           intrinsics_origin.empty() ? "given" : intrinsics_origin);
}

}  // namespace objscan::capture
