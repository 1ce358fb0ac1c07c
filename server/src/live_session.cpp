#include "objscan/server/live_session.h"

#include <sched.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

#include <tbb/task_arena.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "objscan/core/clock.h"
#include "objscan/core/image_codec.h"
#include "objscan/core/log.h"
#include "objscan/core/palette.h"
#include "objscan/fusion/marching_cubes.h"

namespace objscan::server {
namespace {

using Clock = std::chrono::steady_clock;
using Json = nlohmann::json;

/// Blocks of the volume copied per frame for the worker: 1024 blocks of 8^3 voxels are about
/// 4 MB (4-byte voxels and their colour), about a millisecond of copying, so a 30 Hz loop never
/// waits long for it, and a volume of 30,000 blocks is copied in a second.
constexpr std::size_t kCopyBlocksPerFrame = 1024;
/// Hypotheses are painted on the model picture by the 1 cm cell their vertices fall in.
constexpr float kPaintCell = 0.01f;
/// Frames/s is measured over this many recent frames.
constexpr std::size_t kRateWindow = 30;
constexpr int kJpegQuality = 80;
/// Discovery's peak memory per vertex of its mesh (measured: 0.6-0.75 kB, docs/discovery.md), and
/// the vertices marching cubes makes per block of a fused surface (about 37 on 7-Scenes and the
/// synthetic desk): online discovery's memory, for fusion's guard.
constexpr double kDiscoveryBytesPerVertex = 1000.0;
constexpr double kVerticesPerBlock = 40.0;

std::uint64_t cellKey(const Eigen::Vector3f& p) {
  const auto part = [](float c) {
    return static_cast<std::uint64_t>(static_cast<std::int64_t>(std::floor(c / kPaintCell)) +
                                      (1 << 20)) &
           ((1u << 21) - 1);
  };
  return (part(p.x()) << 42) | (part(p.y()) << 21) | part(p.z());
}

std::string rankColorText(int rank) {
  const auto& c = rankColour(static_cast<std::size_t>(rank));
  char text[8];
  std::snprintf(text, sizeof text, "#%02x%02x%02x", c[0], c[1], c[2]);
  return text;
}

const char* trackingText(fusion::FrameStatus status) {
  switch (status) {
    case fusion::FrameStatus::kTracked:
      return "tracking";
    case fusion::FrameStatus::kGivenPose:
      return "given pose";
    case fusion::FrameStatus::kFirst:
      return "started";
    case fusion::FrameStatus::kLost:
      return "lost";
    case fusion::FrameStatus::kNoDepth:
      return "no depth";
  }
  return "unknown";
}

Json vectorJson(const Eigen::Vector3f& v) { return Json::array({v.x(), v.y(), v.z()}); }

Json hypothesesJson(const std::vector<LiveHypothesis>& list) {
  Json out = Json::array();
  for (const LiveHypothesis& h : list) {
    out.push_back({{"rank", h.rank},
                   {"score", h.score},
                   {"vertices", h.vertices},
                   {"centroid_m", vectorJson(h.centroid)},
                   {"extents_m", vectorJson(h.extents)},
                   {"color", rankColorText(h.rank)}});
  }
  return out;
}

/// The page's JPEG of `bgr`; empty (nothing to show yet) for an empty image.
std::string pageJpeg(const cv::Mat& bgr) {
  return bgr.empty() ? std::string() : encodeJpeg(bgr, kJpegQuality);
}

/// Makes the calling thread run only when a core would otherwise idle (Linux's SCHED_IDLE:
/// below every nice level), so online discovery takes nothing from fusion. Threads it starts
/// inherit it.
void runOnlyWhenIdle() {
  sched_param param{};
  param.sched_priority = 0;
  if (sched_setscheduler(0, SCHED_IDLE, &param) != 0) {
    log::debug("online discovery: could not lower its thread's priority");
  }
}

}  // namespace

void LiveFinal::addHypotheses(const discovery::SceneDiscovery& run, std::size_t shown) {
  for (std::size_t i = 0; i < run.ranked.size() && i < shown; ++i) {
    const discovery::Hypothesis& h = run.ranked[i].hypothesis;
    hypotheses.push_back({static_cast<int>(i) + 1, h.score, h.segment.vertices.size(),
                          h.segment.centroid, h.segment.extents});
    const TriangleMesh& mesh = run.scenes.at(run.ranked[i].scene).mesh;
    std::vector<Eigen::Vector3f>& vertices = painted.emplace_back();
    vertices.reserve(h.segment.vertices.size());
    for (const std::int32_t v : h.segment.vertices) {
      vertices.push_back(mesh.positions[static_cast<std::size_t>(v)]);
    }
  }
}

struct LiveSession::Snapshot {
  std::uint64_t seq = 0;
  cv::Mat color_rgb;
  int model_width = 0, model_height = 0;
  Eigen::Vector3f camera_W = Eigen::Vector3f::Zero();
  std::vector<Eigen::Vector3f> vertices_W, normals_W;
};

struct LiveSession::Objects {
  int round = 0;
  std::int64_t at_frame = 0;
  double seconds = 0.0;
  std::size_t mesh_vertices = 0;
  std::string message;
  std::vector<LiveHypothesis> list;
  std::unordered_map<std::uint64_t, int> paint;  ///< 1 cm cell -> the best rank in it
};

LiveSession::LiveSession(LiveSettings settings)
    : settings_(std::move(settings)), started_(Clock::now()), last_round_(Clock::now()) {
  if (settings_.discovery) worker_ = std::thread([this] { worker(); });
}

LiveSession::~LiveSession() {
  {
    std::lock_guard lock(mutex_);
    stopWorkerLocked();
  }
  work_.notify_all();
  // A round under way finishes its current step (it checks stopping_ between steps), at normal
  // priority now, so that the end of the run never waits for an idle core.
  if (const pid_t tid = worker_tid_.load(); tid != 0) {
    sched_param param{};
    sched_setscheduler(tid, SCHED_OTHER, &param);
  }
  if (worker_.joinable()) worker_.join();
}

void LiveSession::stopWorkerLocked() {
  stopping_ = true;
  // The fusing thread owns the copy except while the worker works on it; then the worker frees
  // it when it ends. (Called again once stopped, the state no longer says who holds it.)
  if (!worker_holds_copy_) {
    copy_.reset();
    extra_bytes_ = 0.0;
  }
  copy_state_ = CopyState::kStopped;
}

void LiveSession::onFrame(const pipeline::FrameEvent& e) {
  const auto now = Clock::now();
  switch (e.outcome.status) {
    case fusion::FrameStatus::kTracked:
    case fusion::FrameStatus::kGivenPose:
    case fusion::FrameStatus::kFirst:
      ++fused_;
      break;
    case fusion::FrameStatus::kLost:
      ++lost_;
      break;
    case fusion::FrameStatus::kNoDepth:
      break;
  }
  if (e.frame.device_frame >= 0) {
    if (last_device_frame_ >= 0 && e.frame.device_frame > last_device_frame_ + 1) {
      dropped_ += static_cast<std::size_t>(e.frame.device_frame - last_device_frame_ - 1);
    }
    last_device_frame_ = e.frame.device_frame;
  }
  recent_frame_s_.push_back(secondsSince(started_));
  if (recent_frame_s_.size() > kRateWindow) recent_frame_s_.erase(recent_frame_s_.begin());

  if (settings_.discovery) {
    // The copy for online discovery: begun every discovery_interval_s once the worker is idle,
    // then a bounded share per frame until it is whole.
    CopyState state;
    {
      std::lock_guard lock(mutex_);
      if (copy_state_ == CopyState::kIdle &&
          std::chrono::duration<double>(now - last_round_).count() >=
              settings_.discovery_interval_s) {
        copy_state_ = CopyState::kCopying;
        copy_next_ = 0;
        copy_frame_ = e.frame.index;
        copy_view_up_ = viewUp(e.fusion.trajectory());
        if (!copy_) copy_ = std::make_unique<fusion::TsdfVolume>(e.fusion.volume().config());
      }
      state = copy_state_;
    }
    if (state == CopyState::kCopying) {
      copy_next_ = e.fusion.volume().copyBlocksInto(*copy_, copy_next_, kCopyBlocksPerFrame);
      // The copy, and discovery's about 1 kB per vertex of its mesh (about 40 vertices a block).
      extra_bytes_ =
          static_cast<double>(copy_->memoryBytes()) +
          kDiscoveryBytesPerVertex * kVerticesPerBlock * static_cast<double>(copy_->blockCount());
      if (copy_next_ >= e.fusion.volume().blockCount()) {
        {
          std::lock_guard lock(mutex_);
          copy_state_ = CopyState::kWorking;
          worker_holds_copy_ = true;
        }
        work_.notify_all();
      }
    }
  }

  // The counts, every frame (the page's last state must hold the last frame's).
  LiveCounts counts;
  counts.frame = e.frame.index;
  counts.elapsed_s = secondsSince(started_);
  counts.read = e.frames_read;
  counts.total = e.frames_total;
  counts.fused = fused_;
  counts.lost = lost_;
  counts.dropped = dropped_;
  if (recent_frame_s_.size() >= 2 && recent_frame_s_.back() > recent_frame_s_.front()) {
    counts.frames_per_s = static_cast<double>(recent_frame_s_.size() - 1) /
                          (recent_frame_s_.back() - recent_frame_s_.front());
  }
  counts.tracking = trackingText(e.outcome.status);
  counts.reason = e.outcome.reason;
  counts.volume_bytes = e.fusion.volume().memoryBytes();
  counts.blocks = e.fusion.volume().blockCount();
  counts.voxel_m = e.fusion.volume().config().voxel_size_m;
  // The pictures, a few times a second.
  std::shared_ptr<Snapshot> s;
  if (!snapshot_ || std::chrono::duration<double>(now - last_snapshot_).count() >=
                        settings_.snapshot_interval_s) {
    last_snapshot_ = now;
    s = std::make_shared<Snapshot>();
    if (!e.frame.color_rgb.empty()) s->color_rgb = e.frame.color_rgb.clone();
    const fusion::ModelMaps& model = e.fusion.model();
    if (!model.vertices_W.empty()) {
      s->model_width = model.intrinsics.width_px;
      s->model_height = model.intrinsics.height_px;
      s->camera_W = model.T_W_C.translation();
      s->vertices_W = model.vertices_W;
      s->normals_W = model.normals_W;
    }
  }
  {
    std::lock_guard lock(mutex_);
    counts_ = std::move(counts);
    if (!s) return;
    if (stage_ == "starting") stage_ = "fusing";
    s->seq = ++seq_;
    snapshot_ = std::move(s);
  }
  changed_.notify_all();
}

void LiveSession::setStage(const std::string& stage) {
  {
    std::lock_guard lock(mutex_);
    stage_ = stage;
    ++seq_;
    // Fusion is over: no round starts, a round under way is dropped (both would show an older
    // volume than the final one), and the copy is freed.
    stopWorkerLocked();
  }
  work_.notify_all();
  changed_.notify_all();
}

void LiveSession::finish(LiveFinal final) {
  std::shared_ptr<Objects> painted;
  if (!final.painted.empty()) {
    // The last picture in the final ranking's colours.
    painted = std::make_shared<Objects>();
    painted->round = -1;
    painted->list = final.hypotheses;
    for (std::size_t i = 0; i < final.painted.size() && i < final.hypotheses.size(); ++i) {
      for (const Eigen::Vector3f& p : final.painted[i]) {
        painted->paint.emplace(cellKey(p), final.hypotheses[i].rank);
      }
    }
    final.painted.clear();
  }
  std::shared_ptr<const Objects> old;  // destroyed after the lock is let go
  {
    std::lock_guard lock(mutex_);
    stage_ = final.failed ? "failed" : "done";
    final_ = std::move(final);
    if (painted) {
      old = std::move(objects_);
      objects_ = std::move(painted);
    }
    stopWorkerLocked();
    ++seq_;
  }
  work_.notify_all();
  changed_.notify_all();
}

bool LiveSession::pageActive() {
  std::lock_guard lock(mutex_);
  return last_state_request_ != Clock::time_point{} &&
         Clock::now() - last_state_request_ < std::chrono::seconds(2);
}

bool LiveSession::finalServed() {
  std::lock_guard lock(mutex_);
  return final_served_;
}

void LiveSession::worker() {
  worker_tid_ = static_cast<pid_t>(syscall(SYS_gettid));
  runOnlyWhenIdle();
  int round = 0;
  for (;;) {
    std::int64_t at_frame = 0;
    {
      std::unique_lock lock(mutex_);
      work_.wait(lock, [this] {
        return copy_state_ == CopyState::kWorking || copy_state_ == CopyState::kStopped;
      });
      if (copy_state_ == CopyState::kStopped) {
        // Stopped before this round began: the copy handed over is freed here.
        worker_holds_copy_ = false;
        copy_.reset();
        extra_bytes_ = 0.0;
        return;
      }
      at_frame = copy_frame_;
    }
    std::shared_ptr<Objects> objects = discoverOnCopy(++round, at_frame);
    std::shared_ptr<const Objects> old;  // destroyed after the lock is let go: it may be large
    bool stopped = false;
    {
      std::lock_guard lock(mutex_);
      stopped = copy_state_ == CopyState::kStopped;
      worker_holds_copy_ = false;
      if (stopped) {
        copy_.reset();  // the worker held it; fusion is over
        extra_bytes_ = 0.0;
      } else {
        copy_state_ = CopyState::kIdle;
        last_round_ = Clock::now();
      }
      if (!stopping_) {
        old = std::move(objects_);
        objects_ = std::move(objects);
        ++seq_;
      }
    }
    changed_.notify_all();
    if (stopped) return;
  }
}

std::shared_ptr<LiveSession::Objects> LiveSession::discoverOnCopy(int round,
                                                                  std::int64_t at_frame) {
  auto objects = std::make_shared<Objects>();
  objects->round = round;
  objects->at_frame = at_frame;
  const auto start = Clock::now();
  // One thread: discovery's parallel loops stay on this (idle-priority) thread instead of
  // taking oneTBB's workers, which fusion uses.
  tbb::task_arena arena(1);
  try {
    arena.execute([&] {
      const TriangleMesh mesh = fusion::extractMesh(*copy_);
      objects->mesh_vertices = mesh.positions.size();
      if (stopping_) {
        objects->message = "stopped: the scan ended";
        return;
      }
      if (mesh.triangles.empty()) {
        objects->message = "no surface yet";
        return;
      }
      discovery::DiscoveryConfig config = settings_.discovery_config;
      config.objects.context.view_up = copy_view_up_;
      const std::vector<discovery::Hypothesis> found = discovery::discoverObjects(mesh, config);
      const std::size_t shown = std::min(found.size(), settings_.shown_hypotheses);
      for (std::size_t i = 0; i < shown; ++i) {
        const discovery::Hypothesis& h = found[i];
        const int rank = static_cast<int>(i) + 1;
        objects->list.push_back(
            {rank, h.score, h.segment.vertices.size(), h.segment.centroid, h.segment.extents});
        for (const std::int32_t v : h.segment.vertices) {
          // Better ranks come first, so emplace keeps the best rank of a shared cell.
          objects->paint.emplace(cellKey(mesh.positions[static_cast<std::size_t>(v)]), rank);
        }
      }
      if (found.empty()) objects->message = "no object candidates yet";
    });
  } catch (const std::exception& e) {
    // Too little surface, or too little memory for a round: the page says so; fusion goes on.
    objects->message = e.what();
  }
  objects->seconds = secondsSince(start);
  return objects;
}

std::string LiveSession::stateJson(std::uint64_t after, std::chrono::milliseconds wait) {
  std::shared_ptr<const Snapshot> s;
  std::shared_ptr<const Objects> objects;
  std::optional<LiveCounts> counts;
  Json j;
  {
    std::unique_lock lock(mutex_);
    last_state_request_ = Clock::now();
    changed_.wait_for(lock, wait, [&] { return seq_ > after || final_.has_value(); });
    final_served_ = final_served_ || final_.has_value();
    s = snapshot_;
    counts = counts_;
    objects = objects_;
    j["seq"] = seq_;
    j["stage"] = stage_;
    j["discovery_running"] = copy_state_ == CopyState::kWorking;
    if (final_) {
      Json files = Json::array();
      for (const auto& [label, name] : final_->files) {
        files.push_back({{"label", label}, {"href", "/results/" + name}});
      }
      j["final"] = {{"outcome", final_->outcome},
                    {"failed", final_->failed},
                    {"hypotheses", hypothesesJson(final_->hypotheses)},
                    {"files", files}};
    } else {
      j["final"] = nullptr;
    }
  }
  j["command"] = settings_.command;
  j["source"] = settings_.source;
  if (s && counts) {
    const LiveCounts& c = *counts;
    j["frame"] = c.frame;
    j["picture"] = s->seq;
    j["elapsed_s"] = c.elapsed_s;
    j["tracking"] = {{"state", c.tracking}, {"reason", c.reason}};
    j["frames"] = {{"read", c.read},       {"total", c.total > 0 ? Json(c.total) : Json(nullptr)},
                   {"fused", c.fused},     {"lost", c.lost},
                   {"dropped", c.dropped}, {"per_second", c.frames_per_s}};
    j["volume"] = {{"bytes", c.volume_bytes}, {"blocks", c.blocks}, {"voxel_m", c.voxel_m}};
    j["has_color"] = !s->color_rgb.empty();
  }
  if (!settings_.discovery) {
    j["discovery"] = nullptr;
  } else if (objects) {
    j["discovery"] = {{"round", objects->round},     {"at_frame", objects->at_frame},
                      {"seconds", objects->seconds}, {"mesh_vertices", objects->mesh_vertices},
                      {"message", objects->message}, {"hypotheses", hypothesesJson(objects->list)}};
  } else {
    j["discovery"] = {{"round", 0}, {"hypotheses", Json::array()}};
  }
  // A path or message that is not UTF-8 (a source named in Latin-1, say) is shown with U+FFFD
  // instead of failing the request.
  return j.dump(-1, ' ', false, Json::error_handler_t::replace);
}

std::string LiveSession::modelJpeg() {
  std::shared_ptr<const Snapshot> s;
  std::shared_ptr<const Objects> objects;
  {
    std::lock_guard lock(mutex_);
    s = snapshot_;
    objects = objects_;
  }
  if (!s || s->vertices_W.empty()) return {};
  std::lock_guard lock(picture_mutex_);
  // One picture per snapshot and discovery round, however many clients ask.
  const std::pair<std::uint64_t, int> key{s->seq, objects ? objects->round : 0};
  if (model_key_ == key && !model_jpeg_.empty()) return model_jpeg_;
  cv::Mat bgr(s->model_height, s->model_width, CV_8UC3, cv::Scalar(40, 40, 40));
  for (int y = 0; y < bgr.rows; ++y) {
    auto* row = bgr.ptr<cv::Vec3b>(y);
    for (int x = 0; x < bgr.cols; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(bgr.cols) +
                            static_cast<std::size_t>(x);
      const Eigen::Vector3f& v = s->vertices_W[i];
      const Eigen::Vector3f& n = s->normals_W[i];
      if (!std::isfinite(v.x()) || !std::isfinite(n.x())) continue;
      // Lit from the camera, as KinectFusion's preview is.
      const Eigen::Vector3f to_camera = (s->camera_W - v).normalized();
      const float shade = 0.25f + 0.75f * std::max(0.0f, n.dot(to_camera));
      float r = 220.0f, g = 220.0f, b = 220.0f;
      if (objects && !objects->paint.empty()) {
        const auto it = objects->paint.find(cellKey(v));
        if (it != objects->paint.end()) {
          const auto& c = rankColour(static_cast<std::size_t>(it->second));
          r = c[0];
          g = c[1];
          b = c[2];
        }
      }
      row[x] = cv::Vec3b(cv::saturate_cast<std::uint8_t>(b * shade),
                         cv::saturate_cast<std::uint8_t>(g * shade),
                         cv::saturate_cast<std::uint8_t>(r * shade));
    }
  }
  model_jpeg_ = pageJpeg(bgr);
  model_key_ = key;
  return model_jpeg_;
}

std::string LiveSession::colorJpeg() {
  std::shared_ptr<const Snapshot> s;
  {
    std::lock_guard lock(mutex_);
    s = snapshot_;
  }
  if (!s || s->color_rgb.empty()) return {};
  std::lock_guard lock(picture_mutex_);
  if (color_seq_ == s->seq && !color_jpeg_.empty()) return color_jpeg_;
  cv::Mat half, bgr;
  cv::resize(s->color_rgb, half, cv::Size(s->color_rgb.cols / 2, s->color_rgb.rows / 2), 0, 0,
             cv::INTER_AREA);
  cv::cvtColor(half, bgr, cv::COLOR_RGB2BGR);
  color_jpeg_ = pageJpeg(bgr);
  color_seq_ = s->seq;
  return color_jpeg_;
}

}  // namespace objscan::server
