#include "objscan/capture/oni_container.h"

#include <algorithm>
#include <cerrno>
#include <compare>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <initializer_list>
#include <string_view>
#include <system_error>
#include <tuple>

#include "objscan/core/error.h"

namespace objscan::capture {
namespace fs = std::filesystem;

namespace {

// The container format, as OpenNI2 writes it (Source/Core/OniDataRecords.h) and plays it
// (Source/Drivers/OniFile/DataRecords.h, PlayerNode.cpp). Integers are little-endian, structs
// packed.
//
// File header, 24 bytes: "NI10"; version u8 major, u8 minor, u16 maintenance, u32 build;
// u64 maximum time stamp; u32 maximum node id.
constexpr std::uint64_t kFileHeaderBytes = 24;
constexpr char kFileMagic[4] = {'N', 'I', '1', '0'};

// Record header: u32 magic "NIR\0", u32 record type, u32 node id, u32 fields size (this header
// included), u32 payload size, undo record position (u64 from format 1.0.1.0 on, u32 before).
// The record's fields follow the header; its payload (frame data, seek table) follows the fields.
constexpr std::uint32_t kRecordMagic = 0x0052494E;
constexpr std::uint64_t kRecordHeaderBytes = 28;
constexpr std::uint64_t kRecordHeaderBytesOld32 = 24;

// Seek table entries: u64 time stamp, u32 configuration id, u64 (u32 before 1.0.1.0) position.
constexpr std::uint64_t kSeekEntryBytes = 20;
constexpr std::uint64_t kSeekEntryBytesOld32 = 16;

// OpenNI's player reads each record into a buffer this large (PlayerNode::RECORD_MAX_SIZE: a
// NewData header with an 80-character name, plus 1600 x 1200 x 3 bytes of data) and refuses, or
// overruns, anything larger; no record the recorder writes for a playable file is larger.
constexpr std::uint64_t kPlayerRecordMaxBytes = 28 + 81 + 8 + 4 + 1600ull * 1200 * 3;

// The recorder writes "unknown" until the stream is detached at a clean stop.
constexpr std::uint32_t kUnknownFrameCount = 0xFFFFFFFF;

enum RecordType : std::uint32_t {
  kNodeAdded_1_0_0_4 = 0x02,  // name, node type, codec
  kIntProperty = 0x03,        // property name, u32 size, value (all in the fields)
  kRealProperty = 0x04,
  kStringProperty = 0x05,
  kGeneralProperty = 0x06,
  kNodeRemoved = 0x07,    // header only; undo position = the NodeAdded record's position
  kNodeDataBegin = 0x08,  // u32 frame count, u64 maximum time stamp
  kNodeStateReady = 0x09,
  kNewData = 0x0A,  // u64 time stamp, u32 frame number; the frame is the payload
  kEnd = 0x0B,
  kNodeAdded_1_0_0_5 = 0x0C,  // + u32 frame count, u64 min and max time stamp
  kNodeAdded = 0x0D,          // + seek table position
  kSeekTable = 0x0E,          // payload: (frames + 1) seek entries, the first one empty
};

// XnProductionNodeType values that NodeAdded records carry.
std::string nodeTypeName(std::uint32_t type) {
  switch (type) {
    case 1:
      return "device";
    case 2:
      return "depth";
    case 3:
      return "color";
    case 4:
      return "audio";
    case 5:
      return "ir";
    default:
      return "node type " + std::to_string(type);
  }
}

/// Depth, image and IR nodes carry frames (PlayerNode::IsTypeGenerator).
bool isFrameStream(const OniStreamSummary& s) {
  return s.type == "depth" || s.type == "color" || s.type == "ir";
}

std::string cat(std::initializer_list<std::string_view> parts) {
  std::string out;
  for (std::string_view p : parts) out.append(p);
  return out;
}

std::string bytesText(std::uint64_t bytes) {
  char buf[64];
  if (bytes >= (1u << 30)) {
    std::snprintf(buf, sizeof buf, "%.1f GB", static_cast<double>(bytes) / (1 << 30));
  } else if (bytes >= (1u << 20)) {
    std::snprintf(buf, sizeof buf, "%.1f MB", static_cast<double>(bytes) / (1 << 20));
  } else if (bytes >= (1u << 10)) {
    std::snprintf(buf, sizeof buf, "%.1f KB", static_cast<double>(bytes) / (1 << 10));
  } else {
    std::snprintf(buf, sizeof buf, "%llu bytes", static_cast<unsigned long long>(bytes));
  }
  return buf;
}

std::uint32_t u32At(const std::uint8_t* p) {
  return std::uint32_t{p[0]} | std::uint32_t{p[1]} << 8 | std::uint32_t{p[2]} << 16 |
         std::uint32_t{p[3]} << 24;
}

std::uint64_t u64At(const std::uint8_t* p) {
  return std::uint64_t{u32At(p)} | std::uint64_t{u32At(p + 4)} << 32;
}

/// Thrown inside the walk for a record whose fields end before what they must hold.
struct FieldsTooShort {};

/// Reads the fields of one record, never past their end.
class FieldReader {
 public:
  explicit FieldReader(const std::vector<std::uint8_t>& bytes) : bytes_(bytes) {}
  std::uint32_t u32() { return u32At(take(4)); }
  std::uint64_t u64() { return u64At(take(8)); }
  /// u32 size (terminating NUL included), then the characters.
  std::string string() {
    const std::uint32_t size = u32();
    const auto* p = reinterpret_cast<const char*>(take(size));
    return std::string(p, std::find(p, p + size, '\0'));
  }
  const std::uint8_t* take(std::uint64_t n) {
    if (n > bytes_.size() - at_) throw FieldsTooShort{};
    const std::uint8_t* p = bytes_.data() + at_;
    at_ += n;
    return p;
  }

 private:
  const std::vector<std::uint8_t>& bytes_;
  std::size_t at_ = 0;
};

struct RecordHeader {
  std::uint64_t pos = 0;
  std::uint32_t type = 0;
  std::uint32_t node = 0;
  std::uint32_t fields_size = 0;  ///< header included
  std::uint32_t payload_size = 0;
  std::uint64_t undo_pos = 0;
};

/// Per-stream bookkeeping beyond what the summary reports.
struct StreamState {
  std::uint32_t added_by = 0;           ///< the NodeAdded record type
  std::uint64_t seek_table_points = 0;  ///< seek table position the NodeAdded record declares
  std::uint64_t seek_table_at = 0;      ///< where a seek table record was found
};

class OniWalker {
 public:
  OniWalker(const fs::path& file, bool tolerate) : file_(file), tolerate_(tolerate) {}

  OniFileSummary run() {
    open();
    if (!readFileHeader()) return summary_;
    if (!walkRecords()) return summary_;
    checkWholeFile();
    summary_.finished = summary_.problem.empty();
    return summary_;
  }

 private:
  // ---- Reporting ----------------------------------------------------------------------------

  [[noreturn]] void fail(const std::string& problem) const { throw InputError(file_, problem); }

  [[noreturn]] void corrupt(std::uint64_t pos, const std::string& what) const {
    fail(cat({"corrupt at byte ", std::to_string(pos), ": ", what}));
  }

  /// A file that may be fine but is not (yet) complete: thrown, or kept as the problem when the
  /// caller tolerates unfinished files. The first problem found is the one reported.
  void incomplete(const std::string& problem) {
    if (!tolerate_) fail(problem);
    if (summary_.problem.empty()) summary_.problem = problem;
  }

  void truncated(const std::string& where) {
    incomplete(cat({"truncated at byte ", std::to_string(size_), " ", where, " (the file is ",
                    bytesText(size_), "; was it copied completely?)"}));
  }

  // ---- Reading ------------------------------------------------------------------------------

  void open() {
    std::error_code ec;
    const fs::file_status status = fs::status(file_, ec);
    if (status.type() == fs::file_type::not_found) fail("does not exist");
    if (ec) fail(cat({"cannot be accessed: ", ec.message()}));
    if (status.type() == fs::file_type::directory) {
      fail("is a directory, not an OpenNI recording (.oni file)");
    }
    if (status.type() != fs::file_type::regular) fail("is not a regular file");
    in_.open(file_, std::ios::binary);
    if (!in_) fail(cat({"cannot be opened: ", std::strerror(errno)}));
    in_.seekg(0, std::ios::end);
    const std::streamoff end = in_.tellg();
    if (end < 0) fail("cannot be read: its size is unknown");
    size_ = static_cast<std::uint64_t>(end);
    summary_.bytes = size_;
  }

  /// Reads n bytes at pos; the caller has checked pos + n <= size_.
  void readAt(std::uint64_t pos, void* dst, std::uint64_t n) {
    in_.clear();
    in_.seekg(static_cast<std::streamoff>(pos));
    in_.read(static_cast<char*>(dst), static_cast<std::streamsize>(n));
    if (static_cast<std::uint64_t>(in_.gcount()) != n) {
      fail(cat({"cannot be read at byte ", std::to_string(pos), " (did it shrink while read?)"}));
    }
  }

  bool readFileHeader() {
    std::uint8_t h[kFileHeaderBytes] = {};
    const std::uint64_t have = std::min<std::uint64_t>(size_, kFileHeaderBytes);
    readAt(0, h, have);
    // Compares as many of the four magic bytes as the file holds.
    if (std::memcmp(h, kFileMagic, std::min<std::uint64_t>(have, 4)) != 0) {
      fail("not an OpenNI recording (no NI10 header)");
    }
    if (have < 4) {
      // Empty, or the first bytes of "NI10": nothing to say it is a recording, unless the caller
      // is watching one being created.
      if (!tolerate_) {
        fail(have == 0 ? "is empty, not an OpenNI recording (no NI10 header)"
                       : "not an OpenNI recording (no NI10 header)");
      }
      incomplete("holds no NI10 header yet (the recording has not started writing)");
      return false;
    }
    if (have < kFileHeaderBytes) {
      truncated("inside the NI10 file header");
      return false;
    }
    const unsigned major = h[4], minor = h[5];
    const unsigned maintenance = h[6] | h[7] << 8;
    const std::uint32_t build = u32At(h + 8);
    const auto version = [&](unsigned a, unsigned b, unsigned c, std::uint32_t d) {
      return std::make_tuple(major, minor, maintenance, build) <=> std::make_tuple(a, b, c, d);
    };
    // PlayerNode plays 1.0.0.4 (OpenNI 1.x) to 1.0.1.0 (what OpenNI 2 writes); files before
    // 1.0.1.0 use 32-bit record positions.
    if (version(1, 0, 0, 4) < 0 || version(1, 0, 1, 0) > 0) {
      fail(cat({"is an OpenNI recording of format version ", std::to_string(major), ".",
                std::to_string(minor), ".", std::to_string(maintenance), ".", std::to_string(build),
                ", which OpenNI 2 does not play (it plays 1.0.0.4 to 1.0.1.0)"}));
    }
    old32_ = version(1, 0, 1, 0) < 0;
    max_time_stamp_ = u64At(h + 12);
    max_node_id_ = u32At(h + 20);
    return true;
  }

  // ---- Records ------------------------------------------------------------------------------

  /// Index into summary_.streams of the latest stream added with this node id, or -1.
  int findStream(std::uint32_t node) const {
    for (int i = static_cast<int>(summary_.streams.size()) - 1; i >= 0; --i) {
      if (summary_.streams[i].node_id == node) return i;
    }
    return -1;
  }

  std::string streamLabel(int i) const {
    const OniStreamSummary& s = summary_.streams[i];
    for (int j = 0; j < static_cast<int>(summary_.streams.size()); ++j) {
      if (j != i && summary_.streams[j].type == s.type) {
        return cat({"the ", s.type, " stream (node ", std::to_string(s.node_id), ")"});
      }
    }
    return cat({"the ", s.type, " stream"});
  }

  static bool isNodeAdded(std::uint32_t type) {
    return type == kNodeAdded || type == kNodeAdded_1_0_0_5 || type == kNodeAdded_1_0_0_4;
  }

  /// What a record is, for messages: "frame 17 of the depth stream". Corrupt when the record
  /// belongs to a stream that no record added, or that was removed already.
  std::string describeRecord(const RecordHeader& h) const {
    if (isNodeAdded(h.type)) return cat({"the record adding stream ", std::to_string(h.node)});
    if (h.type == kEnd) return "the end record";
    const int i = findStream(h.node);
    std::string kind;
    switch (h.type) {
      case kIntProperty:
      case kRealProperty:
      case kStringProperty:
      case kGeneralProperty:
        kind = "a property record";
        break;
      case kNodeRemoved:
        kind = "the node-removed record";
        break;
      case kNodeDataBegin:
        kind = "the data-begin record";
        break;
      case kNodeStateReady:
        kind = "the state-ready record";
        break;
      case kNewData:
        kind = "a frame record";
        break;
      case kSeekTable:
        kind = "the seek table";
        break;
    }
    if (i < 0) {
      corrupt(h.pos,
              cat({kind, " for stream ", std::to_string(h.node), ", which no record added"}));
    }
    if (summary_.streams[i].removed && h.type != kSeekTable) {
      corrupt(h.pos, cat({kind, " for ", streamLabel(i), " after it was removed"}));
    }
    if (h.type == kNewData) {
      return cat(
          {"frame ", std::to_string(summary_.streams[i].data_records + 1), " of ", streamLabel(i)});
    }
    return cat({kind, " of ", streamLabel(i)});
  }

  /// Returns false when the walk stopped at a truncation that is tolerated.
  bool walkRecords() {
    const std::uint64_t header_bytes = old32_ ? kRecordHeaderBytesOld32 : kRecordHeaderBytes;
    std::uint64_t pos = kFileHeaderBytes;
    std::vector<std::uint8_t> fields;
    while (pos < size_) {
      const std::uint64_t left = size_ - pos;
      if (left < header_bytes) {
        truncated(records_ == 0 ? std::string("inside the first record's header")
                                : cat({"inside the record header after ", last_record_}));
        return false;
      }
      std::uint8_t raw[kRecordHeaderBytes] = {};
      readAt(pos, raw, header_bytes);
      RecordHeader h;
      h.pos = pos;
      h.type = u32At(raw + 4);
      h.node = u32At(raw + 8);
      h.fields_size = u32At(raw + 12);
      h.payload_size = u32At(raw + 16);
      h.undo_pos = old32_ ? u32At(raw + 20) : u64At(raw + 20);
      if (u32At(raw) != kRecordMagic) {
        corrupt(pos, records_ == 0
                         ? std::string("bad record magic (expected \"NIR\")")
                         : cat({"bad record magic (expected \"NIR\") after ", last_record_}));
      }
      if (h.type < kNodeAdded_1_0_0_4 || h.type > kSeekTable) {
        corrupt(pos, cat({"unknown record type ", std::to_string(h.type)}));
      }
      if (h.fields_size < header_bytes) {
        corrupt(pos, cat({"record fields size ", std::to_string(h.fields_size),
                          " is smaller than the record header"}));
      }
      const std::string what = describeRecord(h);
      const std::uint64_t total = std::uint64_t{h.fields_size} + h.payload_size;
      if (total > kPlayerRecordMaxBytes) {
        corrupt(pos, cat({what, " claims ", bytesText(total),
                          ", more than OpenNI's player accepts in one record (",
                          bytesText(kPlayerRecordMaxBytes), ")"}));
      }
      if (h.undo_pos >= pos) {
        corrupt(pos, cat({what, " refers back to byte ", std::to_string(h.undo_pos),
                          ", which is not before it"}));
      }
      if (total > left) {
        truncated(cat({"inside ", what}));
        return false;
      }
      fields.resize(h.fields_size - header_bytes);
      readAt(pos + header_bytes, fields.data(), fields.size());
      try {
        handleRecord(h, fields, what);
      } catch (const FieldsTooShort&) {
        corrupt(pos, cat({what, " ends inside its fields"}));
      }
      ++records_;
      last_record_ = what;
      pos += total;
      if (h.type == kEnd) {
        end_seen_ = true;
        summary_.records_end = pos;
        break;  // the recorder truncates the file after its end record; the player stops there
      }
    }
    return true;
  }

  void handleRecord(const RecordHeader& h, const std::vector<std::uint8_t>& fields,
                    const std::string& what) {
    FieldReader f(fields);
    if (isNodeAdded(h.type)) {
      const int existing = findStream(h.node);
      if (existing >= 0 && !summary_.streams[existing].removed) {
        corrupt(h.pos, cat({"stream ", std::to_string(h.node), " is added a second time"}));
      }
      OniStreamSummary s;
      StreamState state;
      state.added_by = h.type;
      s.node_id = h.node;
      s.node_name = f.string();
      s.type = nodeTypeName(f.u32());
      s.codec_id = f.u32();
      if (h.type != kNodeAdded_1_0_0_4) {
        const std::uint32_t frames = f.u32();
        if (frames != kUnknownFrameCount) s.declared_frames = frames;
        f.u64();  // minimum time stamp
        f.u64();  // maximum time stamp
      }
      if (h.type == kNodeAdded) state.seek_table_points = old32_ ? f.u32() : f.u64();
      summary_.streams.push_back(std::move(s));
      states_.push_back(state);
      return;
    }
    if (h.type == kEnd) return;
    const int i = findStream(h.node);  // describeRecord() made sure there is one
    OniStreamSummary& s = summary_.streams[i];
    StreamState& state = states_[i];
    switch (h.type) {
      case kIntProperty:
      case kRealProperty:
      case kStringProperty:
      case kGeneralProperty: {
        const std::string name = f.string();
        const std::uint32_t size = f.u32();
        const std::uint8_t* value = f.take(size);
        // VideoModeData / XnMapOutputMode: u32 width, u32 height, u32 fps.
        if (name == "xnMapOutputMode" && size >= 8) {
          s.width = static_cast<int>(u32At(value));
          s.height = static_cast<int>(u32At(value + 4));
        }
        break;
      }
      case kNodeRemoved:
        s.removed = true;
        break;
      case kNodeDataBegin: {
        const std::uint32_t frames = f.u32();
        f.u64();  // maximum time stamp
        // Files before 1.0.0.5 declared the frame count here rather than in NodeAdded.
        if (state.added_by == kNodeAdded_1_0_0_4 && frames != kUnknownFrameCount) {
          s.declared_frames = frames;
        }
        s.data_begun = true;
        break;
      }
      case kNodeStateReady:
        break;
      case kNewData: {
        const std::uint64_t time_stamp = f.u64();
        f.u32();  // frame number
        if (time_stamp > max_time_stamp_) {
          corrupt(h.pos, cat({what,
                              " is stamped after the file header's maximum time stamp "
                              "(OpenNI's player rejects it)"}));
        }
        if (!summary_.first_frame_node) summary_.first_frame_node = s.node_id;
        ++s.data_records;
        break;
      }
      case kSeekTable: {
        const std::uint64_t entry = old32_ ? kSeekEntryBytesOld32 : kSeekEntryBytes;
        if (s.declared_frames &&
            h.payload_size != (std::uint64_t{*s.declared_frames} + 1) * entry) {
          corrupt(h.pos, cat({what, " holds ", std::to_string(h.payload_size / entry),
                              " entries, but the stream declares ",
                              std::to_string(*s.declared_frames), " frames (OpenNI expects ",
                              std::to_string(*s.declared_frames + 1ull), ")"}));
        }
        s.has_seek_table = true;
        state.seek_table_at = h.pos;
        break;
      }
    }
  }

  /// Checks that need every record: run only when the walk reached the end of the file or the
  /// end record.
  void checkWholeFile() {
    for (std::size_t i = 0; i < summary_.streams.size(); ++i) {
      const OniStreamSummary& s = summary_.streams[i];
      const StreamState& state = states_[i];
      // The player follows NodeAdded's seek table position when the stream declares frames.
      // A position at or past the end of a file without an end record is a cut-off copy, which
      // the end-record check below reports.
      if (state.seek_table_points != 0 && s.declared_frames.value_or(0) > 0 &&
          state.seek_table_points != state.seek_table_at) {
        if (end_seen_ || state.seek_table_points < size_) {
          fail(cat({"corrupt: ", streamLabel(static_cast<int>(i)),
                    " declares its seek table at byte ", std::to_string(state.seek_table_points),
                    ", but there is none there"}));
        }
      }
    }
    const bool closed_once = [&] {
      for (const OniStreamSummary& s : summary_.streams) {
        if (s.declared_frames) return true;
      }
      return false;
    }();
    if (!end_seen_) {
      if (records_ == 0) {
        truncated("right after the NI10 file header: it holds no records");
      } else if (closed_once) {
        // NodeAdded records are rewritten with the frame count only when the recording is
        // closed, so this file was complete once: a copy that was cut at a record boundary.
        truncated(cat({"after ", last_record_, ", before the end record"}));
      } else {
        std::string frames;
        for (std::size_t i = 0; i < summary_.streams.size(); ++i) {
          const OniStreamSummary& s = summary_.streams[i];
          if (!isFrameStream(s)) continue;
          frames.append(frames.empty() ? "" : ", ");
          frames.append(cat({std::to_string(s.data_records), " ", s.type}));
        }
        incomplete(
            cat({"was not finished: the recording stopped without a clean close (no end "
                 "record",
                 frames.empty() ? "" : "; frames so far: ", frames, ")"}));
      }
      return;
    }
    bool any_data = false;
    for (std::size_t i = 0; i < summary_.streams.size(); ++i) {
      const OniStreamSummary& s = summary_.streams[i];
      any_data = any_data || s.data_begun;
      // The header's maximum node id is patched when the recorder closes the file; the player
      // sizes its node table from it and rejects larger ids.
      if (s.node_id > max_node_id_) {
        fail(cat({"corrupt: ", streamLabel(static_cast<int>(i)), " has node id ",
                  std::to_string(s.node_id), ", above the file header's maximum ",
                  std::to_string(max_node_id_)}));
      }
    }
    if (!any_data) {
      fail("holds no frames: no stream began recording data (OpenNI's player refuses such files)");
    }
    for (std::size_t i = 0; i < summary_.streams.size(); ++i) {
      const OniStreamSummary& s = summary_.streams[i];
      if (!isFrameStream(s)) continue;
      const std::string label = streamLabel(static_cast<int>(i));
      if (!s.removed || (states_[i].added_by == kNodeAdded && !s.has_seek_table)) {
        incomplete(cat({"was not finished: ", label, " was not closed (no ",
                        s.removed ? "seek table" : "node-removed record", ")"}));
      }
    }
    for (std::size_t i = 0; i < summary_.streams.size(); ++i) {
      const OniStreamSummary& s = summary_.streams[i];
      if (s.declared_frames && *s.declared_frames != s.data_records) {
        incomplete(cat({"declares ", std::to_string(*s.declared_frames), " ", s.type,
                        " frames but holds ", std::to_string(s.data_records)}));
      }
    }
  }

  fs::path file_;
  bool tolerate_;
  std::ifstream in_;
  std::uint64_t size_ = 0;
  bool old32_ = false;
  std::uint64_t max_time_stamp_ = 0;
  std::uint32_t max_node_id_ = 0;
  OniFileSummary summary_;
  std::vector<StreamState> states_;  ///< parallel to summary_.streams
  std::size_t records_ = 0;
  std::string last_record_;  ///< description of the last complete record
  bool end_seen_ = false;
};

}  // namespace

OniFileSummary inspectOniFile(const fs::path& file, bool tolerate_unfinished) {
  return OniWalker(file, tolerate_unfinished).run();
}

std::string oniCodecName(std::uint32_t codec_id) {
  char c[4];
  for (int i = 0; i < 4; ++i) c[i] = static_cast<char>((codec_id >> (8 * i)) & 0xFF);
  const std::string_view fourcc(c, 4);
  if (codec_id == 0) return "no codec";
  if (fourcc == "NONE") return "uncompressed";
  if (fourcc == "16zT") return "16z with tables (lossless)";
  if (fourcc == "16zP") return "16z (lossless)";
  if (fourcc == "Im8z") return "8z (lossless)";
  if (fourcc == "JPEG") return "JPEG (lossy)";
  for (char ch : fourcc) {
    if (ch < 0x20 || ch > 0x7E) {
      char buf[32];
      std::snprintf(buf, sizeof buf, "codec 0x%08x", static_cast<unsigned>(codec_id));
      return buf;
    }
  }
  return cat({"codec '", fourcc, "'"});
}

std::string describe(const OniFileSummary& summary) {
  std::string out;
  for (const OniStreamSummary& s : summary.streams) {
    out.append(s.type);
    if (!isFrameStream(s)) {
      out.append(cat({" (node ", std::to_string(s.node_id), ")\n"}));
      continue;
    }
    if (s.width > 0 && s.height > 0) {
      out.append(cat({" ", std::to_string(s.width), "x", std::to_string(s.height)}));
    }
    out.append(
        cat({", ", std::to_string(s.data_records), s.data_records == 1 ? " frame" : " frames", ", ",
             oniCodecName(s.codec_id), "\n"}));
  }
  if (!summary.problem.empty()) out.append(cat({"problem: ", summary.problem, "\n"}));
  return out;
}

}  // namespace objscan::capture
