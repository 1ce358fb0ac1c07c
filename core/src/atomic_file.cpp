#include "objscan/core/atomic_file.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <optional>
#include <random>
#include <string>

#include "objscan/core/error.h"

namespace objscan {
namespace fs = std::filesystem;

namespace {

std::string errnoText() { return std::strerror(errno); }

/// What marks a temporary file's name, before "<pid>-<random>" (temporarySibling makes such
/// names, temporaryWriter reads them back).
constexpr std::string_view kTemporaryMark = ".tmp-";

/// The writer's pid when `name` is exactly what temporarySibling makes ("NAME.tmp-PID-N" with N
/// below 10^9, or ".objscan.tmp-PID-N"); 0 for any other name.
long temporaryWriter(const std::string& name) {
  const std::size_t at = name.rfind(kTemporaryMark);
  constexpr std::size_t kMark = kTemporaryMark.size();
  if (at == std::string::npos || at == 0) return 0;
  const auto digits = [&](std::size_t from, std::size_t to) {
    return to > from && std::all_of(name.begin() + static_cast<std::ptrdiff_t>(from),
                                    name.begin() + static_cast<std::ptrdiff_t>(to),
                                    [](char c) { return c >= '0' && c <= '9'; });
  };
  const std::size_t dash = name.find('-', at + kMark);
  if (dash == std::string::npos || !digits(at + kMark, dash) || dash - at - kMark > 9 ||
      !digits(dash + 1, name.size()) || name.size() - dash - 1 > 9) {
    return 0;
  }
  return std::strtol(name.c_str() + at + kMark, nullptr, 10);
}

/// Writes all of `bytes` to `fd`; false (errno set) when a write fails.
bool writeAll(int fd, std::string_view bytes) {
  const char* data = bytes.data();
  size_t left = bytes.size();
  while (left > 0) {
    const ssize_t n = ::write(fd, data, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    data += n;
    left -= static_cast<size_t>(n);
  }
  return true;
}

/// Creates `file` (which must not exist), writes `bytes` to it and flushes it to disk (fsync),
/// with `mode` when given. On any failure removes it and throws OutputError naming `named` (the
/// file a user asked for, where `file` is its temporary).
void writeNewFlushed(const fs::path& file, const fs::path& named, std::string_view bytes,
                     std::optional<mode_t> mode) {
  const int fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd < 0) throw OutputError(named, "cannot create a file there: " + errnoText());
  if (mode) ::fchmod(fd, *mode);
  auto fail = [&](const std::string& what) {
    const std::string reason = what + ": " + errnoText();
    ::close(fd);
    ::unlink(file.c_str());
    throw OutputError(named, reason);
  };
  if (!writeAll(fd, bytes)) fail("write failed");
  if (::fsync(fd) != 0) fail("fsync failed");
  if (::close(fd) != 0) {
    const std::string reason = "close failed: " + errnoText();
    ::unlink(file.c_str());
    throw OutputError(named, reason);
  }
}

/// Makes the names in `folder` durable. Best effort: some file systems refuse fsync on folders.
void flushFolder(const fs::path& folder) {
  const int fd = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

}  // namespace

/// "<name>.tmp-<pid>-<random>", or ".objscan.tmp-<pid>-<random>" when that would pass the file
/// system's 255-byte name limit (a file named near the limit can still be written).
fs::path temporarySibling(const fs::path& path) {
  static thread_local std::mt19937_64 rng{std::random_device{}()};
  const std::string suffix = std::string(kTemporaryMark) + std::to_string(::getpid()) + "-" +
                             std::to_string(rng() % 1000000000ULL);
  constexpr std::size_t kMaxNameBytes = 255;
  if (path.filename().string().size() + suffix.size() > kMaxNameBytes) {
    return path.parent_path() / (".objscan" + suffix);
  }
  fs::path tmp = path;
  tmp += suffix;
  return tmp;
}

std::size_t removeStaleTemporaries(const fs::path& folder) {
  std::size_t removed = 0;
  std::error_code ec;
  for (auto it = fs::directory_iterator(folder, ec); !ec && it != fs::directory_iterator();
       it.increment(ec)) {
    const long pid = temporaryWriter(it->path().filename().string());
    if (pid <= 0 || pid == ::getpid() || it->symlink_status(ec).type() != fs::file_type::regular) {
      continue;
    }
    if (::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) continue;  // still running
    std::error_code remove_ec;
    removed += fs::remove(it->path(), remove_ec) ? 1 : 0;
  }
  return removed;
}

void writeFileAtomically(const fs::path& path, std::string_view bytes) {
  const fs::path tmp = temporarySibling(path);
  // A replaced file keeps its permissions; a new one gets 0666 less the umask, as open() gives.
  struct stat existing {};
  const bool replacing = ::stat(path.c_str(), &existing) == 0 && S_ISREG(existing.st_mode);
  writeNewFlushed(tmp, path, bytes,
                  replacing ? std::optional<mode_t>(existing.st_mode & 07777) : std::nullopt);
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string reason = "cannot rename the finished file into place: " + errnoText();
    ::unlink(tmp.c_str());
    throw OutputError(path, reason);
  }
  // Make the rename itself durable.
  flushFolder(path.has_parent_path() ? path.parent_path() : fs::path("."));
}

void writeStagedFile(const fs::path& path, std::string_view bytes) {
  writeNewFlushed(path, path, bytes, std::nullopt);
}

void makeStagedFolderDurable(const fs::path& folder) {
  // Its files were flushed as they were written; this makes their names durable.
  flushFolder(folder);
}

std::string readWholeFile(const fs::path& path, std::uintmax_t max_bytes) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (status.type() == fs::file_type::not_found) {
    throw InputError(path, "no such file or directory");
  }
  if (ec) throw InputError(path, "cannot access: " + ec.message());
  if (status.type() == fs::file_type::directory) {
    throw InputError(path, "is a directory, not a file");
  }
  if (status.type() != fs::file_type::regular) {
    throw InputError(path, "is not a regular file (a device, a FIFO or a socket)");
  }
  if (const std::uintmax_t bytes = fs::file_size(path, ec); !ec && bytes > max_bytes) {
    throw InputError(path, "is " + std::to_string(bytes) + " bytes, more than the " +
                               std::to_string(max_bytes) + " such a file can be");
  }

  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot open for reading: " + errnoText());
  std::string bytes;
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  if (size < 0) throw InputError(path, "cannot determine the file size");
  if (static_cast<std::uintmax_t>(size) > max_bytes) {  // it grew since it was looked at
    throw InputError(path, "is " + std::to_string(size) + " bytes, more than the " +
                               std::to_string(max_bytes) + " such a file can be");
  }
  bytes.resize(static_cast<size_t>(size));
  in.seekg(0, std::ios::beg);
  in.read(bytes.data(), size);
  if (in.gcount() != size)
    throw InputError(path, "read failed after " + std::to_string(in.gcount()) + " bytes");
  return bytes;
}

int probeWritableFolder(const std::filesystem::path& folder) {
  // An unnamed file first: a process killed here leaves nothing behind.
  int fd = ::open(folder.c_str(), O_WRONLY | O_TMPFILE | O_CLOEXEC, 0600);
  if (fd >= 0) {
    ::close(fd);
    return 0;
  }
  if (errno != EOPNOTSUPP && errno != EISDIR) return errno;
  // The file system has no unnamed files: a named one, under a temporary name of
  // temporarySibling's form, which removeStaleTemporaries clears if this process dies here.
  const fs::path probe = temporarySibling(folder / ".objscan-write-probe");
  fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) return errno;
  ::close(fd);
  ::unlink(probe.c_str());
  return 0;
}

}  // namespace objscan
