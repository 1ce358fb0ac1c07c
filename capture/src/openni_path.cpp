#include "openni_path.h"

#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <system_error>
#include <vector>

#include "objscan/capture/virtual_sensor.h"
#include "objscan/core/error.h"

namespace objscan::capture::openni_detail {
namespace fs = std::filesystem;

bool openNICanTake(const std::string& path) {
  if (path.size() > kMaxOpenNIPathBytes) return false;
  for (const char c : path) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte > 0x7e) return false;
  }
  return true;
}

OpenNIPath::OpenNIPath(const fs::path& target, const std::string& alias_name,
                       std::size_t suffix_bytes) {
  if (openNICanTake(target.string()) &&
      target.string().size() + suffix_bytes <= kMaxOpenNIPathBytes) {
    path_ = target.string();
    return;
  }
  std::error_code ec;
  const fs::path absolute = fs::absolute(target, ec);
  if (ec) throw OutputError(target, "cannot resolve the path for OpenNI2: " + ec.message());
  // $TMPDIR first, as every program that needs a scratch folder does; /tmp when $TMPDIR is
  // itself a path OpenNI2 cannot take.
  std::vector<std::string> bases;
  if (const char* tmpdir = std::getenv("TMPDIR"); tmpdir != nullptr && *tmpdir != '\0') {
    bases.emplace_back(tmpdir);
  }
  bases.emplace_back("/tmp");
  std::string why = "no temporary folder";
  for (const std::string& base : bases) {
    std::string pattern = (fs::path(base) / "objscan-openni-XXXXXX").string();
    if (!openNICanTake(pattern + "/" + alias_name + std::string(suffix_bytes, 'x'))) {
      why = base + " is itself a path OpenNI2 cannot take";
      continue;
    }
    if (::mkdtemp(pattern.data()) == nullptr) {
      why = "cannot create a folder in " + base + ": " + std::strerror(errno);
      continue;
    }
    const fs::path link = fs::path(pattern) / alias_name;
    if (::symlink(absolute.c_str(), link.c_str()) != 0) {
      why = "cannot create a link in " + base + ": " + std::strerror(errno);
      ::rmdir(pattern.c_str());
      continue;
    }
    alias_dir_ = pattern;
    path_ = link.string();
    return;
  }
  throw OutputError(target,
                    "OpenNI2 cannot take this path (it is longer than " +
                        std::to_string(kMaxOpenNIPathBytes) +
                        " bytes or has characters outside printable ASCII), and no short alias "
                        "could be made for it (" +
                        why + "); move or rename it");
}

OpenNIPath::~OpenNIPath() { release(); }

OpenNIPath::OpenNIPath(OpenNIPath&& other) noexcept
    : path_(std::move(other.path_)), alias_dir_(std::move(other.alias_dir_)) {
  other.alias_dir_.clear();
}

OpenNIPath& OpenNIPath::operator=(OpenNIPath&& other) noexcept {
  if (this != &other) {
    release();
    path_ = std::move(other.path_);
    alias_dir_ = std::move(other.alias_dir_);
    other.alias_dir_.clear();
  }
  return *this;
}

void OpenNIPath::release() noexcept {
  if (alias_dir_.empty()) return;
  ::unlink(path_.c_str());
  ::rmdir(alias_dir_.c_str());
  alias_dir_.clear();
}

std::string openNIUri(const std::string& uri, OpenNIPath* alias) {
  if (openNICanTake(uri)) return uri;
  if (isVirtualSensorUri(uri)) {
    const std::string rest = uri.substr(std::string(kVirtualUriPrefix).size());
    const std::size_t query = rest.find('?');
    const std::string source = rest.substr(0, query);
    const std::string options = query == std::string::npos ? "" : rest.substr(query);
    std::error_code ec;
    if (!fs::exists(source, ec)) throw InputError(source, "no such file or folder");
    *alias = OpenNIPath(source, "source", std::string(kVirtualUriPrefix).size() + options.size());
    const std::string aliased = kVirtualUriPrefix + alias->path() + options;
    if (openNICanTake(aliased)) return aliased;
  }
  throw InputError(uri, "OpenNI2 cannot take this device URI (longer than " +
                            std::to_string(kMaxOpenNIPathBytes) +
                            " bytes or with characters outside printable ASCII)");
}

}  // namespace objscan::capture::openni_detail
