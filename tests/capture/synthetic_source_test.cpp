#include "objscan/capture/synthetic/synthetic_source.h"

#include <gtest/gtest.h>

#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <sstream>
#include <vector>

#include "objscan/capture/synthetic/synthetic_recording.h"
#include "test_support.h"

namespace objscan::capture {
namespace {

namespace fs = std::filesystem;

/// A quarter of the Xtion's 640x480 camera: small enough for quick tests, large enough for
/// every object of a 4-object scene to show.
Intrinsics smallCamera() { return testing::centredCamera(160, 120, 570.3 / 4); }

/// Frames start, start + every, ... below end (none: to the last).
capture::FrameSelection selectFrames(std::size_t start,
                                     std::optional<std::size_t> end = std::nullopt,
                                     std::size_t every = 1) {
  capture::FrameSelection s;
  s.start = start;
  s.end = end;
  s.every = every;
  return s;
}

constexpr const char* kSpec = "synth:3,objects=4,frames=6";

/// Every frame next() gives until the end of the stream; fails the test on anything but kOk.
std::vector<RgbdFrame> drain(capture::FrameSource& source) {
  std::vector<RgbdFrame> frames;
  for (;;) {
    capture::FrameResult r = source.next();
    if (r.status == capture::FrameStatus::kEndOfStream) break;
    EXPECT_EQ(r.status, capture::FrameStatus::kOk) << r.reason;
    if (r.status != capture::FrameStatus::kOk) break;
    frames.push_back(std::move(r.frame));
  }
  EXPECT_EQ(source.next().status, capture::FrameStatus::kEndOfStream) << "the end stays the end";
  return frames;
}

bool bitIdentical(const cv::Mat& a, const cv::Mat& b) {
  if (a.type() != b.type() || a.size() != b.size()) return false;
  for (int v = 0; v < a.rows; ++v) {
    if (std::memcmp(a.ptr(v), b.ptr(v), a.cols * a.elemSize()) != 0) return false;
  }
  return true;
}

void expectSameFrame(const RgbdFrame& a, const RgbdFrame& b) {
  EXPECT_EQ(a.index, b.index);
  EXPECT_EQ(a.stamp_s, b.stamp_s);
  EXPECT_EQ(a.intrinsics, b.intrinsics);
  EXPECT_TRUE(bitIdentical(a.depth_m, b.depth_m)) << "depth of frame " << a.index;
  EXPECT_TRUE(bitIdentical(a.color_rgb, b.color_rgb)) << "colour of frame " << a.index;
}

/// Compares streamed frames with the TUM folder writeSyntheticRecording (or `objscan synth`)
/// wrote: colour identical, depth within half a step of its 16-bit PNG (value / 5000 = metres,
/// rounded to nearest; 1e-6 m for float rounding) and readings in exactly the same pixels.
void expectFramesMatchFolder(const std::vector<RgbdFrame>& frames, const fs::path& dir) {
  const std::vector<std::string> rows =
      testing::lines(testing::readBytes(dir / "associations.txt"));
  ASSERT_EQ(rows.size(), frames.size());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    SCOPED_TRACE("frame " + std::to_string(i));
    std::istringstream row(rows[i]);
    double rgb_stamp = 0, depth_stamp = 0;
    std::string rgb_file, depth_file;
    row >> rgb_stamp >> rgb_file >> depth_stamp >> depth_file;
    EXPECT_NEAR(depth_stamp, frames[i].stamp_s, 1e-6);  // the file names carry 6 decimals
    const cv::Mat bgr = cv::imread((dir / rgb_file).string(), cv::IMREAD_COLOR);
    const cv::Mat depth16 = cv::imread((dir / depth_file).string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(depth16.type(), CV_16UC1);
    cv::Mat rgb;
    cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
    EXPECT_TRUE(bitIdentical(rgb, frames[i].color_rgb));

    const cv::Mat& depth = frames[i].depth_m;
    ASSERT_EQ(depth.size(), depth16.size());
    std::size_t readings = 0, zero_mismatches = 0;
    float worst_m = 0.0f;
    for (int v = 0; v < depth.rows; ++v) {
      for (int u = 0; u < depth.cols; ++u) {
        const float d = depth.at<float>(v, u);
        const float written_m = depth16.at<std::uint16_t>(v, u) / 5000.0f;
        zero_mismatches += (d == 0.0f) != (written_m == 0.0f);
        readings += d > 0.0f;
        worst_m = std::max(worst_m, std::abs(d - written_m));
      }
    }
    EXPECT_EQ(zero_mismatches, 0u);
    EXPECT_LE(worst_m, 0.5f / 5000.0f + 1e-6f);
    EXPECT_GT(readings, depth.total() / 2) << "most pixels see the scene";
  }
}

/// One source for the spec above, streamed once and shared by the tests below.
class SyntheticSourceTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    source_ = new SyntheticSource(parseSynthSpec(kSpec), smallCamera());
    frames_ = new std::vector<RgbdFrame>(drain(*source_));
  }
  static void TearDownTestSuite() {
    delete frames_;
    delete source_;
  }
  static SyntheticSource* source_;
  static std::vector<RgbdFrame>* frames_;
};
SyntheticSource* SyntheticSourceTest::source_ = nullptr;
std::vector<RgbdFrame>* SyntheticSourceTest::frames_ = nullptr;

TEST_F(SyntheticSourceTest, FramesEqualTheRecordingWrittenForTheSameSpec) {
  ASSERT_EQ(frames_->size(), 6u);
  for (const RgbdFrame& f : *frames_) {
    EXPECT_NO_THROW(f.validate());
    EXPECT_EQ(f.depth_m.type(), CV_32FC1);
    EXPECT_EQ(f.color_rgb.type(), CV_8UC3);
  }
  const SynthSpec& spec = source_->spec();
  ASSERT_TRUE(spec.sensor.enabled) << "the comparison covers the noise seed too";
  testing::TempDir dir;
  writeSyntheticRecording(source_->scene(), *source_->info().ground_truth, smallCamera(),
                          spec.sensor, spec.noise_seed, dir / "rec");
  expectFramesMatchFolder(*frames_, dir / "rec");
}

TEST_F(SyntheticSourceTest, SameSpecGivesBitIdenticalFrames) {
  SyntheticSource again(parseSynthSpec(kSpec), smallCamera());
  const std::vector<RgbdFrame> frames = drain(again);
  ASSERT_EQ(frames.size(), frames_->size());
  for (std::size_t i = 0; i < frames.size(); ++i) expectSameFrame(frames[i], (*frames_)[i]);
  // The sensor noise really is in them: another noise seed changes the depth, not the colour.
  SynthSpec other = parseSynthSpec(kSpec);
  other.noise_seed += 1;
  SyntheticSource reseeded(other, smallCamera(), selectFrames(2, 3));
  const capture::FrameResult r = reseeded.next();
  ASSERT_EQ(r.status, capture::FrameStatus::kOk);
  EXPECT_FALSE(bitIdentical(r.frame.depth_m, (*frames_)[2].depth_m));
  EXPECT_TRUE(bitIdentical(r.frame.color_rgb, (*frames_)[2].color_rgb));
}

TEST_F(SyntheticSourceTest, SelectionKeepsPathIndicesAndCounts) {
  struct Case {
    capture::FrameSelection selection;
    std::vector<std::int64_t> indices;
  };
  const std::vector<Case> cases = {
      {selectFrames(1, 5, 2), {1, 3}},          {selectFrames(4), {4, 5}},
      {selectFrames(2, 100, 3), {2, 5}},  // an end past the path is the path's end
      {selectFrames(0, std::nullopt, 10), {0}}, {selectFrames(5, 6), {5}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE("start " + std::to_string(c.selection.start) + " every " +
                 std::to_string(c.selection.every));
    SyntheticSource source(parseSynthSpec(kSpec), smallCamera(), c.selection);
    EXPECT_EQ(source.info().frame_count, c.indices.size());
    const std::vector<RgbdFrame> frames = drain(source);
    ASSERT_EQ(frames.size(), c.indices.size());
    for (std::size_t k = 0; k < frames.size(); ++k) {
      EXPECT_EQ(frames[k].index, c.indices[k]);
      // Frame i is frame i of the full stream: same stamp, same pixels, same noise.
      expectSameFrame(frames[k], (*frames_)[static_cast<std::size_t>(c.indices[k])]);
    }
  }
  EXPECT_THROW(SyntheticSource(parseSynthSpec(kSpec), smallCamera(), selectFrames(6)),
               std::invalid_argument)
      << "a selection that starts past the last frame";
  EXPECT_THROW(
      SyntheticSource(parseSynthSpec(kSpec), smallCamera(), selectFrames(0, std::nullopt, 0)),
      std::invalid_argument);
}

TEST_F(SyntheticSourceTest, InfoDescribesTheSceneAndItsGroundTruthIsThePath) {
  const capture::SourceInfo& info = source_->info();
  EXPECT_EQ(info.description, "synthetic desk scene, seed 3, 4 objects, 6 frames");
  EXPECT_EQ(info.frame_count, 6u);
  EXPECT_EQ(info.intrinsics, smallCamera());
  EXPECT_FALSE(info.intrinsics_origin.empty());
  EXPECT_FALSE(info.live);

  // The same scene and path composeSceneSeenAlongPath gives, bit for bit.
  const SynthSpec spec = parseSynthSpec(kSpec);
  const SceneAndPath expected = composeSceneSeenAlongPath(spec.scene, spec.path, smallCamera());
  EXPECT_TRUE(testing::bitwiseEqual(source_->scene().mesh, expected.scene.mesh));
  EXPECT_EQ(source_->scene().objects.size(), 4u);
  EXPECT_EQ(source_->sceneSeed(), expected.scene_seed);
  ASSERT_TRUE(info.ground_truth.has_value());
  const Trajectory& gt = *info.ground_truth;
  ASSERT_EQ(gt.size(), expected.path.size());
  ASSERT_EQ(gt.size(), frames_->size());
  for (std::size_t i = 0; i < gt.size(); ++i) {
    EXPECT_EQ(gt.poses[i].stamp_s, expected.path.poses[i].stamp_s);
    EXPECT_TRUE(gt.poses[i].T_W_C.matrix() == expected.path.poses[i].T_W_C.matrix()) << i;
    EXPECT_EQ((*frames_)[i].stamp_s, gt.poses[i].stamp_s) << "frames are keyed by the gt stamps";
    EXPECT_EQ((*frames_)[i].index, static_cast<std::int64_t>(i));
  }
}

TEST(SyntheticSource, NoiseOffGivesTheIdealDepthAndTheDescriptionSaysSo) {
  SyntheticSource source(parseSynthSpec("synth:3,objects=4,frames=6,noise=off"), smallCamera(),
                         selectFrames(1, 2));
  EXPECT_EQ(source.info().description,
            "synthetic desk scene, seed 3, 4 objects, 6 frames, no sensor noise");
  const capture::FrameResult r = source.next();
  ASSERT_EQ(r.status, capture::FrameStatus::kOk);
  render::OffscreenRenderer renderer(smallCamera());
  renderer.setMesh(source.scene().mesh);
  const render::RenderedView ideal = renderer.render(source.info().ground_truth->poses[1].T_W_C);
  EXPECT_TRUE(bitIdentical(r.frame.depth_m, ideal.depth_m));
  EXPECT_TRUE(bitIdentical(r.frame.color_rgb, ideal.color_rgb));
}

TEST(SyntheticSource, StreamsWhatObjscanSynthWritesForTheSameSeed) {
  // The CLI at its defaults (640x480 Xtion camera, noise on), made short.
  testing::TempDir dir;
  const testing::ProcessResult r =
      testing::runProcess({OBJSCAN_EXE, "synth", "--seed", "7", "--objects", "4", "--frames", "3",
                           "--out", (dir / "rec").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  SyntheticSource source(parseSynthSpec("synth:7,objects=4,frames=3"), Intrinsics::xtionDefault());
  expectFramesMatchFolder(drain(source), dir / "rec");
}

TEST(ParseSynthSpec, DefaultsAreThoseOfObjscanSynth) {
  const SynthSpec spec = parseSynthSpec("synth:7");
  // app/synth_command.h: --preset desk --objects 10 --frames 300 --noise on, no --object-dir.
  EXPECT_EQ(spec.scene.preset, ScenePreset::kDesk);
  EXPECT_EQ(spec.scene.objects, 10);
  EXPECT_TRUE(spec.scene.object_dir.empty());
  EXPECT_EQ(spec.path.frames, 300);
  EXPECT_EQ(spec.path.rate_hz, 30.0);
  EXPECT_TRUE(spec.sensor.enabled);
  EXPECT_EQ(spec.sensor.distortion_radial, 0.0) << "noise=on has no fixed distortion";
  const SynthSpec full = parseSynthSpec("synth:7,noise=full");
  EXPECT_TRUE(full.sensor.enabled);
  EXPECT_EQ(full.sensor.distortion_radial,
            SensorModelConfig{}.withDeviceDistortion().distortion_radial);
  EXPECT_EQ(full.sensor.distortion_wave,
            SensorModelConfig{}.withDeviceDistortion().distortion_wave);
  EXPECT_GT(full.sensor.distortion_radial, 0.0);
  EXPECT_FALSE(spec.scene.hard_clutter);
  EXPECT_TRUE(parseSynthSpec("synth:7,clutter=hard").scene.hard_clutter);
  EXPECT_FALSE(parseSynthSpec("synth:7,clutter=plain").scene.hard_clutter);
  // One seed for all three, as `objscan synth --seed 7` uses it.
  EXPECT_EQ(spec.scene.seed, 7u);
  EXPECT_EQ(spec.path.seed, 7u);
  EXPECT_EQ(spec.noise_seed, 7u);

  const SynthSpec all = parseSynthSpec(
      "synth:18446744073709551615,noise=off,objects=30,"
      "preset=counter,frames=1");
  EXPECT_EQ(all.scene.seed, 18446744073709551615u);
  EXPECT_EQ(all.noise_seed, 18446744073709551615u);
  EXPECT_EQ(all.scene.preset, ScenePreset::kCounter);
  EXPECT_EQ(all.scene.objects, 30);
  EXPECT_EQ(all.path.frames, 1);
  EXPECT_FALSE(all.sensor.enabled);
  EXPECT_EQ(parseSynthSpec("synth:0,preset=shelf").scene.preset, ScenePreset::kShelf);
  EXPECT_EQ(parseSynthSpec("synth:007").scene.seed, 7u);
}

TEST(ParseSynthSpec, BadSpecsAreOneLineErrorsNamingTheBadPart) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"synth:abc", "the seed must be a whole number >= 0"},
      {"synth:-1", "the seed must be a whole number >= 0"},
      {"synth: 7", "the seed must be a whole number >= 0"},
      {"synth:7.5", "the seed must be a whole number >= 0"},
      {"synth:18446744073709551616", "the seed is too large"},
      {"synth:", "the seed is missing"},
      {"synth:,frames=3", "the seed is missing"},
      {"synt:7", "synth:<seed>"},
      {"7", "synth:<seed>"},
      {"synth:7,frames=0", "frames must be a whole number >= 1, not '0'"},
      {"synth:7,frames=ten", "frames must be a whole number >= 1, not 'ten'"},
      {"synth:7,frames=99999999999", "frames must be a whole number >= 1"},
      {"synth:7,objects=31", "objects must be a whole number from 1 to 30, not '31'"},
      {"synth:7,objects=", "objects must be a whole number from 1 to 30, not ''"},
      {"synth:7,noise=maybe", "noise must be 'on', 'full' or 'off', not 'maybe'"},
      {"synth:7,clutter=dense", "clutter must be 'plain' or 'hard', not 'dense'"},
      {"synth:7,preset=kitchen", "unknown scene preset 'kitchen'"},
      {"synth:7,colour=red", "unknown option 'colour'"},
      {"synth:7,frames", "option 'frames' needs a value"},
      {"synth:7,", "an option is empty"},
      {"synth:7,,frames=3", "an option is empty"},
      {"synth:7,frames=3,frames=4", "option 'frames' is given twice"},
  };
  for (const auto& [spec, needle] : cases) {
    try {
      parseSynthSpec(spec);
      ADD_FAILURE() << spec << " was accepted";
    } catch (const std::invalid_argument& e) {
      const std::string message = e.what();
      EXPECT_EQ(message.rfind(spec + ": ", 0), 0u) << message;
      EXPECT_NE(message.find(needle), std::string::npos) << message;
      EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    }
  }
}

}  // namespace
}  // namespace objscan::capture
