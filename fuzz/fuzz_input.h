// What every fuzz target shares: objscan's readers take a path, so each input is written to one
// file per process first, and the errors a reader documents for bad input are the expected
// outcome of most inputs. Anything else (a crash, a sanitizer report, a hang, an allocation past
// libFuzzer's -malloc_limit_mb) is a finding.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace objscan::fuzz {

/// A file of this process that holds the current input, under $TMPDIR (or /dev/shm, else /tmp),
/// named with `suffix` (readers look at the extension).
inline const std::filesystem::path& inputFile(const char* suffix) {
  static const std::filesystem::path path = [&] {
    const char* tmp = std::getenv("TMPDIR");
    std::filesystem::path dir = tmp && *tmp ? tmp : "/dev/shm";
    std::error_code ec;
    if (!std::filesystem::is_directory(dir, ec)) dir = "/tmp";
    return dir / ("objscan-fuzz-" + std::to_string(::getpid()) + suffix);
  }();
  return path;
}

/// Writes the input to inputFile(suffix) and returns that path.
inline const std::filesystem::path& writeInput(const std::uint8_t* data, std::size_t size,
                                               const char* suffix) {
  const std::filesystem::path& path = inputFile(suffix);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  return path;
}

/// Runs `read` on the input: a std::exception (InputError, std::invalid_argument, ...) is how a
/// reader refuses bad input, and is expected.
template <typename Read>
int expectingRefusals(Read&& read) {
  try {
    read();
  } catch (const std::exception&) {
  }
  return 0;
}

}  // namespace objscan::fuzz
