#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <string_view>

namespace objscan {

/// Writes `bytes` to `path` so that `path` is either left as it was or holds all of `bytes`, never
/// a partial file: the data goes to a temporary file in the same directory, is flushed to disk
/// (fsync), and is renamed over `path`. Throws OutputError naming the path on any failure, after
/// removing the temporary file.
void writeFileAtomically(const std::filesystem::path& path, std::string_view bytes);

/// Writes `bytes` to a new file `path` in a staging folder (freshPartialFolder), which is moved
/// into place whole (swapInFolder): the file needs no temporary name, rename and folder flush of
/// its own, only its data flushed (fsync). A discovery's objects/ holds a thousand files, and
/// writeFileAtomically's four steps a file took 1 s of system calls there. Throws OutputError
/// naming the path when it exists already or cannot be written, after removing what was written.
void writeStagedFile(const std::filesystem::path& path, std::string_view bytes);

/// Makes the names of the files written into the staging folder `folder` durable (one fsync of
/// the folder), before it is renamed into place. Best effort, as a rename's flush: some file
/// systems refuse fsync on folders.
void makeStagedFolderDurable(const std::filesystem::path& folder);

/// Removes from `folder` (not its subfolders) the temporary files writeFileAtomically leaves when
/// its process is killed mid-write: names exactly of its form, "NAME.tmp-PID-N", whose process PID
/// no longer runs. Returns how many it removed. Only for a folder this process holds
/// (OutputFolderLock): on a folder shared between hosts a live writer elsewhere looks dead here.
std::size_t removeStaleTemporaries(const std::filesystem::path& folder);

/// Whether a file can be created in `folder`: creates a probe file there (unnamed where the file
/// system allows, else named as writeFileAtomically's temporaries and removed), since permissions
/// alone do not say it (root, read-only mounts, virtual file systems). Returns 0, or the errno of
/// the failed creation.
int probeWritableFolder(const std::filesystem::path& folder);

/// A name next to `path` that no other writer picks, of the form removeStaleTemporaries clears
/// ("NAME.tmp-PID-N"): for a file that is made complete under it and then linked or renamed into
/// place.
std::filesystem::path temporarySibling(const std::filesystem::path& path);

/// Reads a whole regular file into memory. Throws InputError when the path is missing, is a
/// directory or another non-regular file (a device such as /dev/zero, a FIFO, a socket: never
/// opened, so one cannot block or stream without end), is larger than `max_bytes` (the size is
/// looked at before anything is read, so a huge or sparse file costs no memory), or cannot be
/// read. An empty file is returned as "".
std::string readWholeFile(const std::filesystem::path& path,
                          std::uintmax_t max_bytes = std::numeric_limits<std::uintmax_t>::max());

}  // namespace objscan
