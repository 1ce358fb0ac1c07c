#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <thread>

#include "objscan/capture/frame_source.h"

namespace objscan::capture {

/// Reads a recorded source (a folder, an .oni file, a synthetic scene) on a thread of its own,
/// up to `depth` frames ahead of the consumer, so that decoding the next frame overlaps with
/// processing this one. next() hands out what the inner source produced, in its order: frames,
/// bad frames, the end, or the exception it threw (rethrown once, after the frames before it).
/// The inner source is called, and destroyed, only on the reading thread once reading started.
/// A live sensor should be read directly: frames waiting in a queue grow old.
class ReadAheadSource : public FrameSource {
 public:
  /// Starts reading at once. Throws std::invalid_argument for a null source or depth 0.
  explicit ReadAheadSource(std::unique_ptr<FrameSource> inner, std::size_t depth = 4);
  /// Stops the reader (it finishes the frame it is decoding) and joins it. Not to be called while
  /// another thread waits in next().
  ~ReadAheadSource() override;
  ReadAheadSource(const ReadAheadSource&) = delete;
  ReadAheadSource& operator=(const ReadAheadSource&) = delete;

  /// The inner source's info, taken before reading started.
  const SourceInfo& info() const override { return info_; }
  FrameResult next() override;

 private:
  void read();

  std::unique_ptr<FrameSource> inner_;  ///< reset by the reader when it stops
  SourceInfo info_;
  std::size_t depth_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<FrameResult> queue_;
  std::exception_ptr error_;  ///< what the inner source threw, once the queue before it is empty
  bool finished_ = false;     ///< the inner source ended or threw: nothing more will be queued
  bool stop_ = false;         ///< the destructor asks the reader to stop
  std::thread reader_;
};

}  // namespace objscan::capture
