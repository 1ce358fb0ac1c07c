#include "objscan/capture/frame_source.h"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace objscan::capture {

void FrameSelection::validate() const {
  if (every == 0) throw std::invalid_argument("--every must be at least 1");
  if (end && *end <= start) {
    std::string problem = "--end (";
    problem.append(std::to_string(*end)).append(") must be greater than --start (");
    problem.append(std::to_string(start)).append(")");
    throw std::invalid_argument(problem);
  }
}

std::size_t FrameSelection::count(std::size_t total) const {
  const std::size_t stop = end ? std::min(*end, total) : total;
  if (stop <= start || every == 0) return 0;
  return (stop - start + every - 1) / every;
}

bool FrameSelection::selects(std::size_t index) const {
  if (index < start || (end && index >= *end) || every == 0) return false;
  return (index - start) % every == 0;
}

}  // namespace objscan::capture
