#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace objscan::capture {

/// One node (stream) of an OpenNI2 `.oni` recording, as its records describe it.
struct OniStreamSummary {
  std::uint32_t node_id = 0;
  std::string node_name;  ///< as recorded: "Depth", "Image", "IR"
  std::string type;       ///< "depth", "color", "ir", "device", "audio", or "node type N"
  /// Four characters packed little-endian, first character in the low byte: 'NONE', '16zT',
  /// 'JPEG', ... (see oniCodecName()).
  std::uint32_t codec_id = 0;
  /// The frame count the NodeAdded record declares. The recorder writes 0xFFFFFFFF ("unknown",
  /// held here as none) and rewrites the record in place with the real count when the stream is
  /// detached at a clean stop.
  std::optional<std::uint32_t> declared_frames;
  std::size_t data_records = 0;  ///< NewData records (frames) found
  bool data_begun = false;       ///< a NodeDataBegin record was seen: recording of frames started
  bool removed = false;          ///< a NodeRemoved record was seen: the stream was detached
  bool has_seek_table = false;   ///< a SeekTable record was seen (written at detach)
  int width = 0;                 ///< from the xnMapOutputMode property, 0 when absent
  int height = 0;
};

/// What inspectOniFile() found in a recording's container structure (no frame is decoded).
struct OniFileSummary {
  std::vector<OniStreamSummary> streams;
  /// An end record is present, every frame stream was removed with a seek table, and nothing is
  /// wrong (problem is empty).
  bool finished = false;
  std::uint64_t bytes = 0;  ///< file size when inspected
  /// Where the end record ends (0 without one). OpenNI2's recorder on Linux leaves as many zero
  /// bytes after it (XnLib's truncate adds the offset twice); nothing reads them.
  std::uint64_t records_end = 0;
  /// The node id of the stream whose frame comes first in the file (none without frames).
  /// Replay starts that stream first: OpenNI2's player drops frames of streams not yet started.
  std::optional<std::uint32_t> first_frame_node;
  /// Empty when the structure is sound and finished; otherwise one sentence such as
  /// "was not finished: the recording stopped without a clean close (no end record)".
  std::string problem;
};

/// Walks every record of an OpenNI2 recording without OpenNI, checking each header and size
/// against the bytes actually in the file (no size field is trusted, and nothing larger than the
/// bytes left is allocated; frame payloads are skipped, never read).
///
/// Throws InputError naming the file for: a missing file or a directory; a file that is not an
/// OpenNI recording ("not an OpenNI recording (no NI10 header)") or of a format version OpenNI 2
/// does not play; corruption (a bad record magic, an unknown record type, a size no OpenNI record
/// can have, records for streams that were never added, a seek table that disagrees with its
/// stream). Without `tolerate_unfinished` it also throws for a file that is cut off ("truncated at
/// byte 123456 inside frame 17 of the depth stream (the file is 1.2 MB; was it copied
/// completely?)"), one whose recorder never closed it ("was not finished: ..."), and one whose
/// declared frame count disagrees with its frames ("declares 50 depth frames but holds 48").
///
/// With `tolerate_unfinished` those three are returned in `problem` (finished = false) with the
/// streams as far as their records are complete, so a recording that is still being written can
/// be watched. The file size is taken once, when the file is opened.
OniFileSummary inspectOniFile(const std::filesystem::path& file, bool tolerate_unfinished = false);

/// "16z with tables (lossless)", "JPEG (lossy)", "uncompressed", ..., or "codec 'ABCD'".
std::string oniCodecName(std::uint32_t codec_id);

/// For `objscan info`: one line per stream ("depth 320x240, 300 frames, 16z with tables
/// (lossless)"), then "problem: ..." when there is one. Every line ends with '\n'.
std::string describe(const OniFileSummary& summary);

}  // namespace objscan::capture
