#pragma once

// Internal to capture/: paths that OpenNI2 can take.
//
// OpenNI2 2.2 keeps a device's URI in a fixed 256-byte field and mishandles bytes outside
// printable ASCII: a recording or a virtual sensor's folder whose path holds "ü" crashes it
// (SIGSEGV inside libOpenNI2 while the file device announces itself), and a path of 256 bytes or
// more is refused only after OpenNI2 has tried it. objscan hands OpenNI2 such a path through an
// alias: a symbolic link with a plain name in a fresh private folder under the temporary
// directory, removed again when the alias goes.

#include <filesystem>
#include <string>

namespace objscan::capture::openni_detail {

/// Whether OpenNI2 takes `path` as it is: printable ASCII only (0x20-0x7e) and at most
/// kMaxOpenNIPathBytes bytes.
bool openNICanTake(const std::string& path);
inline constexpr std::size_t kMaxOpenNIPathBytes = 200;

/// A path to give OpenNI2 for an existing file or folder `target`: `target` itself when
/// openNICanTake() it (with `suffix_bytes` more for a file name OpenNI2 adds inside a folder),
/// else a symbolic link "<tmp>/objscan-openni-XXXXXX/<alias_name>" to its absolute path, removed
/// (with its folder) by the destructor. Throws OutputError naming `target` when no such link can
/// be made.
class OpenNIPath {
 public:
  OpenNIPath() = default;
  OpenNIPath(const std::filesystem::path& target, const std::string& alias_name,
             std::size_t suffix_bytes = 0);
  ~OpenNIPath();
  OpenNIPath(OpenNIPath&& other) noexcept;
  OpenNIPath& operator=(OpenNIPath&& other) noexcept;
  OpenNIPath(const OpenNIPath&) = delete;
  OpenNIPath& operator=(const OpenNIPath&) = delete;

  /// What OpenNI2 gets.
  const std::string& path() const { return path_; }
  bool aliased() const { return !alias_dir_.empty(); }

 private:
  void release() noexcept;
  std::string path_;
  std::filesystem::path alias_dir_;  ///< empty when `path_` is the target itself
};

}  // namespace objscan::capture::openni_detail

namespace objscan::capture::openni_detail {

/// The device URI to give OpenNI2 for `uri`: `uri` itself, or for a virtual sensor whose source
/// is a path OpenNI2 cannot take, the same URI with the source replaced by an alias held in
/// `*alias`. Throws InputError naming `uri` for any other URI OpenNI2 cannot take.
std::string openNIUri(const std::string& uri, OpenNIPath* alias);

}  // namespace objscan::capture::openni_detail
