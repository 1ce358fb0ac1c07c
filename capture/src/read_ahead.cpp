#include "objscan/capture/read_ahead.h"

#include <stdexcept>
#include <utility>

namespace objscan::capture {

ReadAheadSource::ReadAheadSource(std::unique_ptr<FrameSource> inner, std::size_t depth)
    : inner_(std::move(inner)), depth_(depth) {
  if (!inner_) throw std::invalid_argument("ReadAheadSource: no source to read");
  if (depth_ == 0) throw std::invalid_argument("ReadAheadSource: the depth must be at least 1");
  info_ = inner_->info();
  reader_ = std::thread([this] { read(); });
}

ReadAheadSource::~ReadAheadSource() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  changed_.notify_all();
  reader_.join();
}

void ReadAheadSource::read() {
  // Every call into the inner source, its destruction included, happens on this thread: an
  // off-screen renderer's OpenGL context, for one, belongs to the thread that made it current.
  struct Release {
    std::unique_ptr<FrameSource>& source;
    ~Release() { source.reset(); }
  } release{inner_};
  for (;;) {
    {
      std::unique_lock<std::mutex> lock(mutex_);
      changed_.wait(lock, [&] { return stop_ || queue_.size() < depth_; });
      if (stop_) return;
    }
    // Decoding happens outside the lock: the consumer takes queued frames meanwhile.
    FrameResult r;
    std::exception_ptr error;
    try {
      r = inner_->next();
    } catch (...) {
      error = std::current_exception();
    }
    bool last = error || r.status == FrameStatus::kEndOfStream;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!error) {
        try {
          queue_.push_back(std::move(r));
        } catch (...) {  // out of memory: handed to the consumer like the source's own errors
          error = std::current_exception();
          last = true;
        }
      }
      if (error) error_ = error;
      finished_ = last;
    }
    changed_.notify_all();
    if (last) return;
  }
}

FrameResult ReadAheadSource::next() {
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [&] { return !queue_.empty() || finished_; });
  if (!queue_.empty()) {
    // The end stays queued: every later call returns it too, as the inner source would.
    if (queue_.front().status == FrameStatus::kEndOfStream) return FrameResult::end();
    FrameResult r = std::move(queue_.front());
    queue_.pop_front();
    lock.unlock();
    changed_.notify_all();
    return r;
  }
  if (error_) {
    std::exception_ptr error = std::exchange(error_, nullptr);
    std::rethrow_exception(error);
  }
  return FrameResult::end();  // after the error was rethrown once
}

}  // namespace objscan::capture
