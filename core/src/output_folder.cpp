#include "objscan/core/output_folder.h"

#include "objscan/core/atomic_file.h"
#include "objscan/core/log.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <system_error>

namespace objscan {
namespace fs = std::filesystem;

namespace {

/// "process 1234: objscan discover ..." for the process that holds the flock on the folder
/// `dir_fd` refers to, from /proc/locks and /proc/PID/cmdline; empty when it cannot be found.
std::string holderOf(int dir_fd) {
  struct stat st {};
  if (::fstat(dir_fd, &st) != 0) return {};
  std::ifstream locks("/proc/locks");
  std::string inode = ":";
  inode.append(std::to_string(st.st_ino));
  std::string line;
  while (std::getline(locks, line)) {
    // "1: FLOCK  ADVISORY  WRITE 1234 08:01:5678 0 EOF"
    std::istringstream fields(line);
    std::string number, kind, advisory, mode, pid, device;
    if (!(fields >> number >> kind >> advisory >> mode >> pid >> device)) continue;
    if (kind != "FLOCK" || device.size() < inode.size() ||
        device.compare(device.size() - inode.size(), inode.size(), inode) != 0) {
      continue;
    }
    std::ifstream cmdline("/proc/" + pid + "/cmdline", std::ios::binary);
    std::string args((std::istreambuf_iterator<char>(cmdline)), std::istreambuf_iterator<char>());
    // The program and its command: the first argument after it that is not an option.
    std::string command;
    std::size_t begin = 0;
    for (int i = 0; begin < args.size(); ++i) {
      const std::size_t nul = args.find('\0', begin);
      const std::string arg = args.substr(begin, nul - begin);
      if (i == 0 || (!arg.empty() && arg[0] != '-')) {
        if (!command.empty()) command.push_back(' ');
        command.append(fs::path(arg).filename().string());
        if (i > 0) break;
      }
      if (nul == std::string::npos) break;
      begin = nul + 1;
    }
    std::string holder = "process ";
    holder.append(pid);
    if (!command.empty()) holder.append(": ").append(command);
    return holder;
  }
  return {};
}

}  // namespace

OutputFolderLock::OutputFolderLock(const fs::path& out) {
  const int fd = ::open(out.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0)
    throw OutputError(out, std::string("cannot open the folder: ") + std::strerror(errno));
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    const std::string holder = error == EWOULDBLOCK ? holderOf(fd) : std::string();
    ::close(fd);
    if (error == EBADF || error == ENOLCK || error == EOPNOTSUPP || error == ENOSYS ||
        error == EINVAL) {
      // File systems that cannot lock a folder (NFS emulates flock with fcntl locks, which need
      // a file open for writing): go on unlocked rather than refuse every run there.
      log::warning(out.string() + ": cannot lock the folder on this file system (" +
                   std::strerror(error) + "); make sure no other objscan run writes into it");
      return;
    }
    if (error == EWOULDBLOCK) {
      throw FolderBusyError(
          out, "another objscan run" + (holder.empty() ? std::string() : " (" + holder + ")") +
                   " is writing into this folder; wait for it to finish or choose another --out");
    }
    throw OutputError(out, std::string("cannot lock the folder: ") + std::strerror(error));
  }
  fd_ = fd;
}

OutputFolderLock::~OutputFolderLock() {
  if (fd_ >= 0) ::close(fd_);  // releases the flock
}

OutputFolderLock& OutputFolderLock::operator=(OutputFolderLock&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = other.fd_;
    other.fd_ = -1;
  }
  return *this;
}

OutputFolderLock prepareOutputFolder(const fs::path& out) {
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec || !fs::is_directory(out)) {
    throw OutputError(out, "cannot create the output folder" +
                               (ec ? ": " + ec.message() : std::string(" (a file is in the way)")));
  }
  OutputFolderLock lock(out);
  // What runs killed mid-write left under temporary names (objects/ and renders/ are written
  // whole as NAME.partial, which the next run replaces); only when the lock is really held, so
  // that no other run writes here now.
  if (lock.held()) removeStaleTemporaries(out);
  return lock;
}

}  // namespace objscan
