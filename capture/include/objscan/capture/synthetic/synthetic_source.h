#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "objscan/capture/frame_source.h"
#include "objscan/capture/synthetic/sensor_model.h"
#include "objscan/capture/synthetic/synthetic_scene.h"
#include "objscan/core/intrinsics.h"
#include "objscan/core/trajectory.h"

namespace objscan::render {
class OffscreenRenderer;
}  // namespace objscan::render

namespace objscan::capture {

/// Everything a synthetic source needs besides the camera: the scene, the path and the sensor.
struct SynthSpec {
  SceneConfig scene;             ///< preset, object count, seed
  HandheldPathConfig path;       ///< frame count; its seed is replaced by the scene's final seed
  SensorModelConfig sensor;      ///< `enabled` is noise=on|off
  std::uint64_t noise_seed = 1;  ///< seeds the sensor noise, as `objscan synth --seed` does
};

/// Parses the source spec `synth:<seed>[,preset=desk|shelf|counter][,frames=N][,objects=K]
/// [,noise=on|off][,clutter=plain|hard]`, options in any order. Everything not given is what
/// `objscan synth` uses by default, and <seed> feeds the scene, the path and the noise as `objscan
/// synth --seed` does, so `synth:7` streams the frames `objscan synth --seed 7` writes. Throws
/// std::invalid_argument with one line that starts with the spec and names the bad part, e.g.
/// "synth:abc: the seed must be a whole number >= 0".
SynthSpec parseSynthSpec(const std::string& spec);

/// Streams a synthetic scene frame by frame, as `objscan synth` would write it: frame i is
/// renderSyntheticFrame() of pose i of the path (the same pixels writeSyntheticRecording writes,
/// before its 16-bit PNG quantisation of the depth). RgbdFrame::index is the position in the full
/// path and stamp_s the path's time stamp, whatever the selection. Not thread-safe: call next()
/// from one thread; the first call creates the OSMesa renderer, which stays bound to that thread.
class SyntheticSource : public capture::FrameSource {
 public:
  /// Composes the scene and its path at once (composeSceneSeenAlongPath with `intrinsics`);
  /// frames are rendered only when next() asks for them. Throws std::invalid_argument for a bad
  /// spec, intrinsics or selection, or a selection that starts past the last frame;
  /// std::runtime_error when the objects do not fit or OSMesa is missing.
  SyntheticSource(const SynthSpec& spec, const Intrinsics& intrinsics,
                  const capture::FrameSelection& selection = {},
                  std::string intrinsics_origin = "synthetic camera (exact)");
  ~SyntheticSource() override;
  SyntheticSource(const SyntheticSource&) = delete;
  SyntheticSource& operator=(const SyntheticSource&) = delete;

  /// frame_count after the selection; ground_truth is the whole path (stamps = frame stamps).
  const capture::SourceInfo& info() const override;
  /// The next selected frame (kOk), then kEndOfStream for ever. Never kBadFrame.
  capture::FrameResult next() override;

  /// The composed scene, for writing its ground truth (scene_gt.ply, object poses and boxes).
  const SyntheticScene& scene() const { return scene_; }
  /// The seed the scene was finally composed with (see composeSceneSeenAlongPath).
  std::uint64_t sceneSeed() const { return scene_seed_; }
  const SynthSpec& spec() const { return spec_; }

 private:
  SynthSpec spec_;
  Intrinsics intrinsics_;
  capture::FrameSelection selection_;
  SyntheticScene scene_;
  Trajectory path_;
  std::uint64_t scene_seed_ = 0;
  capture::SourceInfo info_;
  std::size_t next_index_ = 0;  ///< position in the path of the next frame to consider
  std::unique_ptr<render::OffscreenRenderer> renderer_;
};

/// Opens a source that needs no OpenNI2: `synth:<seed>[,...]` (a SyntheticSource; the Xtion
/// camera unless `intrinsics` is given) or a dataset folder (capture::openFolderSource). Shared by
/// the command line and the virtual OpenNI2 sensor. Throws as those two do.
std::unique_ptr<capture::FrameSource> openSynthOrFolderSource(
    const std::string& spec, const capture::FrameSelection& selection = {},
    const std::optional<Intrinsics>& intrinsics = std::nullopt,
    const std::string& intrinsics_origin = {});

}  // namespace objscan::capture
