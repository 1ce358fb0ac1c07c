#include "objscan/core/progress.h"

#include <unistd.h>

#include <algorithm>
#include <exception>
#include <string>

#include "objscan/core/clock.h"
#include "objscan/core/log.h"

namespace objscan {
namespace {

using Clock = SteadyClock;
constexpr auto kRedrawInterval = std::chrono::milliseconds(100);
constexpr auto kLineInterval = std::chrono::seconds(10);
constexpr int kBarWidth = 30;

}  // namespace

ProgressBar::ProgressBar(std::string label, std::size_t total, Style style, std::FILE* out)
    : label_(std::move(label)),
      total_(total),
      redraw_(style == Style::kRedraw || (style == Style::kAuto && ::isatty(::fileno(out)) == 1)),
      silent_(label_.empty() || !log::enabled(log::Level::kInfo)),
      out_(out),
      start_(Clock::now()),
      last_draw_(start_),
      uncaught_at_start_(std::uncaught_exceptions()) {}

ProgressBar::~ProgressBar() {
  if (std::uncaught_exceptions() > uncaught_at_start_) {
    if (!finished_.exchange(true) && !silent_ && redraw_ && drawn_) {
      std::fputs("\r\033[K", out_);
      std::fflush(out_);
    }
    return;
  }
  finish();
}

void ProgressBar::advance(std::size_t n) {
  const std::size_t now_done = done_.fetch_add(n) + n;
  if (silent_ || finished_.load()) return;
  // Only one thread draws; the others carry on rather than wait.
  std::unique_lock lock(draw_mutex_, std::try_to_lock);
  if (!lock.owns_lock()) return;
  draw(now_done, false);
}

void ProgressBar::finish() {
  if (finished_.exchange(true) || silent_) return;
  std::lock_guard lock(draw_mutex_);
  draw(done_.load(), true);
}

void ProgressBar::draw(std::size_t done, bool final) {
  const auto now = Clock::now();
  const double elapsed_s = secondsSince(start_);
  const double fraction =
      total_ > 0 ? std::min(1.0, static_cast<double>(done) / static_cast<double>(total_)) : 0.0;
  const double rate = elapsed_s > 0.0 ? static_cast<double>(done) / elapsed_s : 0.0;

  char counts[96];
  if (total_ > 0) {
    std::snprintf(counts, sizeof counts, "%3d%% (%zu/%zu)", static_cast<int>(fraction * 100.0),
                  done, total_);
  } else {
    std::snprintf(counts, sizeof counts, "%zu", done);
  }

  if (final) {
    std::fprintf(out_, "%s%s: %s in %.1f s\n", redraw_ ? "\r\033[K" : "", label_.c_str(), counts,
                 elapsed_s);
    std::fflush(out_);
    return;
  }

  if (redraw_) {
    if (drawn_ && now - last_draw_ < kRedrawInterval) return;
    drawn_ = true;
    last_draw_ = now;
    std::string bar;
    if (total_ > 0) {
      const int filled = static_cast<int>(fraction * kBarWidth);
      bar += '[';
      bar.append(static_cast<std::size_t>(filled), '#');
      bar.append(static_cast<std::size_t>(kBarWidth - filled), '.');
      bar += "] ";
    }
    char eta[48] = "";
    if (total_ > 0 && done > 0 && rate > 0.0) {
      std::snprintf(eta, sizeof eta, ", %.0f s left",
                    static_cast<double>(total_ - std::min(done, total_)) / rate);
    }
    std::fprintf(out_, "\r\033[K%s: %s%s, %.1f/s%s", label_.c_str(), bar.c_str(), counts, rate,
                 eta);
    std::fflush(out_);
    return;
  }

  // Plain lines: one at each new 10 % step, and at least every kLineInterval.
  const int decile = total_ > 0 ? static_cast<int>(fraction * 10.0) : -1;
  const bool new_step = total_ > 0 && decile > last_decile_ && decile < 10;
  if (!new_step && now - last_draw_ < kLineInterval) return;
  last_decile_ = std::max(last_decile_, decile);
  last_draw_ = now;
  std::fprintf(out_, "%s: %s, %.1f/s\n", label_.c_str(), counts, rate);
  std::fflush(out_);
}

}  // namespace objscan
