#pragma once

#include <sys/types.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "objscan/discovery/discover.h"
#include "objscan/discovery/scenes.h"
#include "objscan/fusion/tsdf_volume.h"
#include "objscan/pipeline/fuse.h"

/// What `--serve` shows while a scan runs: the fusing thread hands each frame to a LiveSession,
/// which keeps a small snapshot of it now and then (a few times a second), copies the volume a
/// few blocks per frame for an online discovery worker, and answers the live page's questions
/// from other threads. Nothing here ever makes the fusing thread wait for a client: it holds a
/// mutex only to swap a snapshot in, and every picture is made on the asking thread.
namespace objscan::server {

struct LiveSettings {
  std::string command;            ///< "scan" or "fuse", for the page
  std::string source;             ///< as the user named it
  std::filesystem::path results;  ///< the output folder, served read-only under /results/
  /// Online discovery: a worker meshes a copy of the volume and finds objects in it every
  /// `discovery_interval_s`, on a thread that runs only when a core would otherwise idle.
  bool discovery = true;
  double discovery_interval_s = 3.0;
  discovery::DiscoveryConfig discovery_config;
  std::size_t shown_hypotheses = 10;  ///< listed and painted on the page
  double snapshot_interval_s = 0.15;  ///< a new picture for the page at most this often
};

/// One hypothesis as the page lists it.
struct LiveHypothesis {
  int rank = 0;
  double score = 0.0;
  std::size_t vertices = 0;
  Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
  Eigen::Vector3f extents = Eigen::Vector3f::Zero();
};

/// What the page shows of the frames so far; updated every frame.
struct LiveCounts {
  std::int64_t frame = 0;
  double elapsed_s = 0.0;
  std::size_t read = 0, total = 0, fused = 0, lost = 0, dropped = 0;
  double frames_per_s = 0.0;
  std::string tracking, reason;
  std::size_t volume_bytes = 0, blocks = 0;
  float voxel_m = 0.0f;
};

/// The end of the run, for the page's last state.
struct LiveFinal {
  std::string outcome;  ///< one line: "finished", "stopped by Ctrl-C", an error
  bool failed = false;
  std::vector<LiveHypothesis> hypotheses;                  ///< the final ranking (scan), best first
  std::vector<std::pair<std::string, std::string>> files;  ///< label, name in the results folder
  /// The vertices of each of `hypotheses` (same order), to paint the last model picture with the
  /// final ranking's colours; empty: it keeps the last online round's.
  std::vector<std::vector<Eigen::Vector3f>> painted;

  /// A run that ended without results to show: stopped, or failed.
  static LiveFinal without(std::string outcome) {
    LiveFinal f;
    f.outcome = std::move(outcome);
    f.failed = true;
    return f;
  }
  /// Adds the first `shown` hypotheses of a discovery run, and their vertices to paint.
  void addHypotheses(const discovery::SceneDiscovery& run, std::size_t shown);
};

class LiveSession {
 public:
  explicit LiveSession(LiveSettings settings);
  ~LiveSession();  ///< stops the worker
  LiveSession(const LiveSession&) = delete;
  LiveSession& operator=(const LiveSession&) = delete;

  // The fusing thread.
  /// After every frame (pipeline::FuseLimits::on_frame). Cheap: a snapshot every
  /// snapshot_interval_s, and a bounded share of the volume copy.
  void onFrame(const pipeline::FrameEvent& event);
  /// The stage the command is in ("meshing the volume", "discovering objects", ...). Fusion is
  /// over once it is called: online discovery starts no other round, and its copy is freed.
  void setStage(const std::string& stage);
  /// The run is over: the page shows `final` and stops asking. Stops the worker.
  void finish(LiveFinal final);
  /// Memory online discovery holds or is about to take besides fusion's: the volume copy, and
  /// about 1 kB per vertex of its mesh (discovery's measured peak), for fusion's memory guard.
  double extraMemoryBytes() const { return extra_bytes_.load(); }

  // Any thread (the server's).
  /// The state as JSON. Waits up to `wait` for a state newer than `after` (long polling), and
  /// returns at once when there is one or the run is over.
  std::string stateJson(std::uint64_t after, std::chrono::milliseconds wait);
  /// JPEG of the model raycast from the current pose, shaded, with the current hypotheses in
  /// their rank colours; empty before the first frame. Made once per snapshot, on the first ask.
  std::string modelJpeg();
  /// JPEG of the current colour frame (half size); empty when the source has no colour.
  std::string colorJpeg();
  const LiveSettings& settings() const { return settings_; }
  /// A page asked for the state within the last two seconds.
  bool pageActive();
  /// A page has been sent the final state.
  bool finalServed();

 private:
  struct Snapshot;
  struct Objects;
  void worker();
  /// Discovery on the copy; runs on the worker thread.
  std::shared_ptr<Objects> discoverOnCopy(int round, std::int64_t at_frame);
  /// Ends online discovery; the fusing thread frees the copy when the worker holds none.
  void stopWorkerLocked();

  LiveSettings settings_;
  std::mutex mutex_;
  std::condition_variable changed_;  ///< the page's long polls wait on it
  std::condition_variable work_;     ///< the worker waits on it (never woken by a new frame)
  std::uint64_t seq_ = 0;            ///< bumped by every change the page can see
  std::shared_ptr<const Snapshot> snapshot_;
  std::optional<LiveCounts> counts_;
  std::shared_ptr<const Objects> objects_;
  std::string stage_ = "starting";
  std::optional<LiveFinal> final_;
  bool final_served_ = false;
  std::chrono::steady_clock::time_point last_state_request_{};
  // Frame counters, on the fusing thread (copied into snapshots).
  std::chrono::steady_clock::time_point started_, last_snapshot_;
  std::vector<double> recent_frame_s_;  ///< times of the last frames, for frames/s
  std::size_t fused_ = 0, lost_ = 0, dropped_ = 0;
  std::int64_t last_device_frame_ = -1;
  // Pictures made from the current snapshot, shared by every client.
  std::mutex picture_mutex_;
  std::pair<std::uint64_t, int> model_key_{0, 0};  ///< snapshot seq, discovery round
  std::uint64_t color_seq_ = 0;
  std::string model_jpeg_, color_jpeg_;
  // The volume copy for the worker: filled by the fusing thread a bounded share per frame while
  // the worker is idle, read by the worker while it works (never both).
  enum class CopyState { kIdle, kCopying, kWorking, kStopped };
  CopyState copy_state_ = CopyState::kIdle;
  bool worker_holds_copy_ = false;  ///< from kWorking until the worker's round has ended
  std::unique_ptr<fusion::TsdfVolume> copy_;
  std::size_t copy_next_ = 0;
  std::int64_t copy_frame_ = 0;  ///< the frame the copy was begun at
  /// Which way was up for the camera until then (viewUp of the trajectory): the context's hint.
  std::optional<Eigen::Vector3f> copy_view_up_;
  std::chrono::steady_clock::time_point last_round_;
  std::atomic<bool> stopping_{false};  ///< checked by the worker between its steps
  std::atomic<double> extra_bytes_{0.0};
  std::atomic<pid_t> worker_tid_{0};
  std::thread worker_;
};

}  // namespace objscan::server
