#pragma once

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <string>

namespace objscan {

/// A file name's extension with its dot, in lower case (".PCD" -> ".pcd"; "" for none): how the
/// commands tell a file's format from its name.
inline std::string lowercaseExtension(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

}  // namespace objscan
