// PLY reading and writing.
//
// Written by hand rather than taken from a library: Debian 12 packages no stand-alone PLY library
// (tinyply, happly, rply, miniply are absent), and bench/ply_read_bench measured the readers that
// ship inside bigger packages on a 400k-face mesh (README, "Benchmarks"): PCL's PLYReader is 6-16x
// slower than this file, VTK's reader (through PCL) 4-13x slower and crashes or silently accepts
// truncated files, Open3D's rply-based reader 1.6-4.5x slower and would pull the whole Open3D
// runtime into core. PCL and Open3D also accept an ASCII file cut inside its last number, reading
// a different value. What this file adds is strictness: every count is checked against the bytes
// that are there before anything is allocated, a value must be followed by a separator, and every
// failure names the element, row and property.

#include "objscan/core/ply_io.h"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <type_traits>

#include "objscan/core/byte_writing.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"

namespace objscan {
namespace fs = std::filesystem;

const char* toString(PlyFormat format) {
  switch (format) {
    case PlyFormat::kAscii:
      return "ascii";
    case PlyFormat::kBinaryLittleEndian:
      return "binary_little_endian";
    case PlyFormat::kBinaryBigEndian:
      return "binary_big_endian";
  }
  return "?";
}

namespace {

// ---------------------------------------------------------------------------------------------
// Types and header

enum class Type : std::uint8_t {
  kInt8,
  kUint8,
  kInt16,
  kUint16,
  kInt32,
  kUint32,
  kFloat32,
  kFloat64
};

bool parseType(std::string_view name, Type& type) {
  struct Entry {
    std::string_view name;
    Type type;
  };
  static constexpr Entry kTypes[] = {
      {"char", Type::kInt8},       {"int8", Type::kInt8},       {"uchar", Type::kUint8},
      {"uint8", Type::kUint8},     {"short", Type::kInt16},     {"int16", Type::kInt16},
      {"ushort", Type::kUint16},   {"uint16", Type::kUint16},   {"int", Type::kInt32},
      {"int32", Type::kInt32},     {"uint", Type::kUint32},     {"uint32", Type::kUint32},
      {"float", Type::kFloat32},   {"float32", Type::kFloat32}, {"double", Type::kFloat64},
      {"float64", Type::kFloat64},
  };
  for (const Entry& e : kTypes) {
    if (e.name == name) {
      type = e.type;
      return true;
    }
  }
  return false;
}

std::size_t sizeOf(Type t) {
  switch (t) {
    case Type::kInt8:
    case Type::kUint8:
      return 1;
    case Type::kInt16:
    case Type::kUint16:
      return 2;
    case Type::kInt32:
    case Type::kUint32:
    case Type::kFloat32:
      return 4;
    case Type::kFloat64:
      return 8;
  }
  return 0;
}

bool isInteger(Type t) { return t != Type::kFloat32 && t != Type::kFloat64; }

/// Where a property's values go.
enum class Slot : std::uint8_t {
  kIgnore,
  kX,
  kY,
  kZ,
  kNx,
  kNy,
  kNz,
  kRed,
  kGreen,
  kBlue,
  kLabel,
  kQuality,
  kIgnoreFlag,
  kIndices
};

struct Prop {
  std::string name;
  Type type = Type::kFloat32;
  bool list = false;
  Type count_type = Type::kUint8;
  Slot slot = Slot::kIgnore;
};

struct Elem {
  std::string name;
  std::size_t count = 0;
  std::vector<Prop> props;
};

struct ParsedHeader {
  PlyFormat format = PlyFormat::kAscii;
  std::vector<Elem> elements;
  std::vector<std::string> comments;
  std::size_t body_offset = 0;
};

/// An input problem found while parsing; turned into an InputError with the path by readPly.
struct ParseError {
  std::string what;
};

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r'))
    s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r'))
    s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> words(std::string_view s) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && (s[i] == ' ' || s[i] == '\t')) ++i;
    const std::size_t start = i;
    while (i < s.size() && s[i] != ' ' && s[i] != '\t') ++i;
    if (i > start) out.push_back(s.substr(start, i - start));
  }
  return out;
}

ParsedHeader parseHeader(std::string_view bytes) {
  if (bytes.size() < 4 || bytes.substr(0, 3) != "ply" || (bytes[3] != '\n' && bytes[3] != '\r')) {
    throw ParseError{"not a PLY file (it does not start with the line 'ply')"};
  }
  ParsedHeader header;
  bool have_format = false;
  std::size_t pos = 0;
  int line_no = 0;
  while (true) {
    const std::size_t eol = bytes.find('\n', pos);
    if (eol == std::string_view::npos) {
      throw ParseError{"the header has no 'end_header' line (file truncated, or not a PLY file)"};
    }
    const std::string_view line = trim(bytes.substr(pos, eol - pos));
    pos = eol + 1;
    ++line_no;
    const std::string where = "header line " + std::to_string(line_no) + ": ";
    if (line_no == 1) continue;  // "ply"
    const std::vector<std::string_view> w = words(line);
    if (w.empty()) continue;
    const std::string_view key = w[0];
    if (key == "end_header") {
      if (w.size() != 1) throw ParseError{where + "unexpected text after 'end_header'"};
      if (!have_format) throw ParseError{where + "no 'format' line before end_header"};
      for (const Elem& e : header.elements) {
        if (e.props.empty() && e.count > 0) {
          throw ParseError{"element '" + e.name + "' declares " + std::to_string(e.count) +
                           " rows but no properties"};
        }
      }
      header.body_offset = pos;
      return header;
    }
    if (key == "comment" || key == "obj_info") {
      const std::size_t start = line.find(key) + key.size();
      header.comments.emplace_back(trim(line.substr(start)));
    } else if (key == "format") {
      if (have_format) throw ParseError{where + "a second 'format' line"};
      if (w.size() != 3)
        throw ParseError{where +
                         "expected 'format <ascii|binary_little_endian|binary_big_endian> 1.0'"};
      if (w[1] == "ascii") {
        header.format = PlyFormat::kAscii;
      } else if (w[1] == "binary_little_endian") {
        header.format = PlyFormat::kBinaryLittleEndian;
      } else if (w[1] == "binary_big_endian") {
        header.format = PlyFormat::kBinaryBigEndian;
      } else {
        throw ParseError{where + "unknown format '" + std::string(w[1]) + "'"};
      }
      if (w[2] != "1.0" && w[2] != "1")
        throw ParseError{where + "unsupported PLY version '" + std::string(w[2]) + "'"};
      have_format = true;
    } else if (key == "element") {
      std::uint64_t count = 0;
      if (w.size() != 3 ||
          std::from_chars(w[2].data(), w[2].data() + w[2].size(), count).ec != std::errc() ||
          std::from_chars(w[2].data(), w[2].data() + w[2].size(), count).ptr !=
              w[2].data() + w[2].size()) {
        throw ParseError{where + "expected 'element <name> <count>' with a non-negative count"};
      }
      header.elements.push_back(Elem{std::string(w[1]), static_cast<std::size_t>(count), {}});
    } else if (key == "property") {
      if (header.elements.empty()) throw ParseError{where + "property before any element"};
      Prop prop;
      if (w.size() == 5 && w[1] == "list") {
        prop.list = true;
        if (!parseType(w[2], prop.count_type) || !isInteger(prop.count_type)) {
          throw ParseError{where + "list count type '" + std::string(w[2]) +
                           "' must be an integer type"};
        }
        if (!parseType(w[3], prop.type))
          throw ParseError{where + "unknown type '" + std::string(w[3]) + "'"};
        prop.name = std::string(w[4]);
      } else if (w.size() == 3) {
        if (!parseType(w[1], prop.type))
          throw ParseError{where + "unknown type '" + std::string(w[1]) + "'"};
        prop.name = std::string(w[2]);
      } else {
        throw ParseError{
            where +
            "expected 'property <type> <name>' or 'property list <count type> <type> <name>'"};
      }
      header.elements.back().props.push_back(std::move(prop));
    } else {
      throw ParseError{where + "unknown keyword '" + std::string(key) + "'"};
    }
  }
}

/// Decides which properties the mesh takes and checks the ones it needs are there.
void assignSlots(ParsedHeader& header, PlyReadReport& report) {
  struct Named {
    std::string_view name;
    Slot slot;
  };
  static constexpr Named kVertexSlots[] = {
      {"x", Slot::kX},
      {"y", Slot::kY},
      {"z", Slot::kZ},
      {"nx", Slot::kNx},
      {"ny", Slot::kNy},
      {"nz", Slot::kNz},
      {"red", Slot::kRed},
      {"green", Slot::kGreen},
      {"blue", Slot::kBlue},
      {"diffuse_red", Slot::kRed},
      {"diffuse_green", Slot::kGreen},
      {"diffuse_blue", Slot::kBlue},
      {"object_id", Slot::kLabel},
      {"label", Slot::kLabel},
      {"quality", Slot::kQuality},
      {"ignore", Slot::kIgnoreFlag},
  };
  bool have_vertex = false;
  for (Elem& e : header.elements) {
    if (e.name == "vertex") {
      if (have_vertex) throw ParseError{"the header declares two 'vertex' elements"};
      have_vertex = true;
      const auto has = [&](std::string_view name) {
        return std::any_of(e.props.begin(), e.props.end(),
                           [&](const Prop& p) { return !p.list && p.name == name; });
      };
      if (has("label") && has("object_id")) {
        throw ParseError{
            "the vertex element has both 'label' and 'object_id', and both would be the object "
            "ids: remove or rename one of them"};
      }
      bool seen[16] = {};
      for (Prop& p : e.props) {
        for (const Named& n : kVertexSlots) {
          if (p.name == n.name && !p.list && !seen[static_cast<int>(n.slot)]) {
            p.slot = n.slot;
            seen[static_cast<int>(n.slot)] = true;
          }
        }
      }
      if (!seen[static_cast<int>(Slot::kX)] || !seen[static_cast<int>(Slot::kY)] ||
          !seen[static_cast<int>(Slot::kZ)]) {
        throw ParseError{"the vertex element lacks one of the properties x, y, z"};
      }
      for (const Prop& p : e.props) {
        if ((p.slot == Slot::kLabel || p.slot == Slot::kIgnoreFlag) && !isInteger(p.type)) {
          throw ParseError{"vertex property '" + p.name + "' must have an integer type"};
        }
      }
      // Normals and colours are taken only when all three components are there.
      const bool normals = seen[static_cast<int>(Slot::kNx)] && seen[static_cast<int>(Slot::kNy)] &&
                           seen[static_cast<int>(Slot::kNz)];
      const bool colors = seen[static_cast<int>(Slot::kRed)] &&
                          seen[static_cast<int>(Slot::kGreen)] &&
                          seen[static_cast<int>(Slot::kBlue)];
      for (Prop& p : e.props) {
        const bool is_normal = p.slot == Slot::kNx || p.slot == Slot::kNy || p.slot == Slot::kNz;
        const bool is_color =
            p.slot == Slot::kRed || p.slot == Slot::kGreen || p.slot == Slot::kBlue;
        if ((is_normal && !normals) || (is_color && !colors)) p.slot = Slot::kIgnore;
        if (p.slot == Slot::kIgnore) report.ignored.push_back("vertex." + p.name);
      }
    } else if (e.name == "face") {
      bool have_indices = false;
      for (Prop& p : e.props) {
        if (!have_indices && p.list && (p.name == "vertex_indices" || p.name == "vertex_index")) {
          if (!isInteger(p.type))
            throw ParseError{"face property '" + p.name + "' must hold integers"};
          p.slot = Slot::kIndices;
          have_indices = true;
        } else {
          report.ignored.push_back("face." + p.name);
        }
      }
      if (!have_indices && e.count > 0) {
        throw ParseError{"the face element has no 'vertex_indices' list"};
      }
    } else {
      report.ignored.push_back(e.name);
    }
  }
  if (!have_vertex) throw ParseError{"the header declares no 'vertex' element"};
}

/// The fewest body bytes the declared elements can take, to reject impossible counts before
/// allocating. ASCII: every value is at least one character plus a separator.
double minimumBodyBytes(const ParsedHeader& header) {
  double total = 0.0;
  for (const Elem& e : header.elements) {
    double row = 0.0;
    for (const Prop& p : e.props) {
      // A list may be empty here: a face of fewer than 3 indices is named as such when read.
      if (header.format == PlyFormat::kAscii) {
        row += 2.0;  // a character and a separator
      } else {
        row += static_cast<double>(sizeOf(p.list ? p.count_type : p.type));
      }
    }
    total += row * static_cast<double>(e.count);
  }
  // The last ASCII value may end the file without a separator (readPly warns).
  return header.format == PlyFormat::kAscii && total > 0.0 ? total - 1.0 : total;
}

// ---------------------------------------------------------------------------------------------
// Value sources: ASCII tokens, binary of either byte order.

bool isSpace(char c) { return c == ' ' || c == '\n' || c == '\r' || c == '\t'; }

std::string typeName(Type t) {
  static constexpr const char* kNames[] = {"char", "uchar", "short", "ushort",
                                           "int",  "uint",  "float", "double"};
  return kNames[static_cast<int>(t)];
}

/// Checks an integer read as int64 fits the declared integer type.
void checkRange(std::int64_t v, Type t) {
  struct Range {
    std::int64_t lo, hi;
  };
  // Indexed by Type, integer types only.
  static constexpr Range kRanges[] = {{INT8_MIN, INT8_MAX},   {0, UINT8_MAX},
                                      {INT16_MIN, INT16_MAX}, {0, UINT16_MAX},
                                      {INT32_MIN, INT32_MAX}, {0, UINT32_MAX}};
  if (!isInteger(t)) return;
  const Range r = kRanges[static_cast<int>(t)];
  if (v < r.lo || v > r.hi) {
    throw ParseError{"value " + std::to_string(v) + " does not fit type " + typeName(t)};
  }
}

class AsciiSource {
 public:
  AsciiSource(const char* begin, const char* end, int first_line)
      : p_(begin), end_(end), line_(first_line) {}

  double scalar(Type t) {
    const std::string_view tok = token();
    if (isInteger(t)) return static_cast<double>(integerValue(tok, t));
    if (t == Type::kFloat32) {
      float v = 0.0f;
      parseNumber(tok, v);
      return v;
    }
    double v = 0.0;
    parseNumber(tok, v);
    return v;
  }

  std::int64_t integer(Type t) {
    if (!isInteger(t)) throw ParseError{"expected an integer type"};
    return integerValue(token(), t);
  }

  /// Whether `values` more values could still be in the file: each takes at least a character
  /// and a separator. Checked before anything is sized by a count read from the file.
  bool canHold(std::uint64_t values, Type) const {
    return values <= (static_cast<std::uint64_t>(end_ - p_) + 1) / 2;
  }

  /// Bytes after the last element other than whitespace (readPly warns and ignores them).
  std::size_t trailing() {
    while (p_ != end_ && isSpace(*p_)) ++p_;
    return static_cast<std::size_t>(end_ - p_);
  }

  /// The file's last value when the file ends right after it, without a line break (MeshLab and
  /// Open3D accept that; readPly warns, since a file cut inside that value reads the same).
  const std::optional<std::string>& unterminated() const { return unterminated_; }

  std::string position() const { return "line " + std::to_string(line_); }

 private:
  std::string_view token() {
    while (p_ != end_ && isSpace(*p_)) {
      if (*p_ == '\n') ++line_;
      ++p_;
    }
    if (p_ == end_) throw ParseError{"the file ends early (truncated?)"};
    const char* start = p_;
    while (p_ != end_ && !isSpace(*p_)) ++p_;
    const std::string_view tok(start, static_cast<std::size_t>(p_ - start));
    if (p_ == end_) unterminated_ = std::string(tok.substr(0, 40));
    return tok;
  }

  template <class T>
  void parseNumber(std::string_view tok, T& v) {
    const char* b = tok.data();
    const char* e = b + tok.size();
    if (*b == '+' && e - b > 1 && b[1] != '-' && b[1] != '+') ++b;  // from_chars takes no '+'
    const auto [ptr, ec] = std::from_chars(b, e, v);
    if (ptr != e || (ec != std::errc() && ec != std::errc::result_out_of_range)) {
      throw ParseError{"'" + std::string(tok.substr(0, 40)) + "' is not a number"};
    }
    if (ec == std::errc::result_out_of_range) {
      throw ParseError{"'" + std::string(tok.substr(0, 40)) + "' is out of range"};
    }
  }

  std::int64_t integerValue(std::string_view tok, Type t) {
    std::int64_t v = 0;
    parseNumber(tok, v);
    checkRange(v, t);
    return v;
  }

  const char* p_;
  const char* end_;
  int line_;
  std::optional<std::string> unterminated_;
};

template <bool kSwap>
class BinarySource {
 public:
  BinarySource(const char* begin, const char* end) : begin_(begin), p_(begin), end_(end) {}

  double scalar(Type t) {
    if (t == Type::kFloat32) return get<float>();
    if (t == Type::kFloat64) return get<double>();
    return static_cast<double>(integer(t));
  }

  std::int64_t integer(Type t) {
    switch (t) {
      case Type::kInt8:
        return get<std::int8_t>();
      case Type::kUint8:
        return get<std::uint8_t>();
      case Type::kInt16:
        return get<std::int16_t>();
      case Type::kUint16:
        return get<std::uint16_t>();
      case Type::kInt32:
        return get<std::int32_t>();
      case Type::kUint32:
        return get<std::uint32_t>();
      default:
        throw ParseError{"expected an integer type"};
    }
  }

  void skip(std::size_t bytes) {
    if (static_cast<std::size_t>(end_ - p_) < bytes)
      throw ParseError{"the file ends early (truncated?)"};
    p_ += bytes;
  }

  bool canHold(std::uint64_t values, Type t) const {
    return values <= static_cast<std::uint64_t>(end_ - p_) / sizeOf(t);
  }

  /// Bytes after the last element (readPly warns and ignores them).
  std::size_t trailing() const { return static_cast<std::size_t>(end_ - p_); }

  std::string position() const { return "byte " + std::to_string(p_ - begin_) + " of the data"; }

 private:
  template <class T>
  T get() {
    if (static_cast<std::size_t>(end_ - p_) < sizeof(T))
      throw ParseError{"the file ends early (truncated?)"};
    T v;
    if constexpr (kSwap && sizeof(T) > 1) {
      char tmp[sizeof(T)];
      std::reverse_copy(p_, p_ + sizeof(T), tmp);
      std::memcpy(&v, tmp, sizeof(T));
    } else {
      std::memcpy(&v, p_, sizeof(T));
    }
    p_ += sizeof(T);
    return v;
  }

  const char* begin_;
  const char* p_;
  const char* end_;
};

// ---------------------------------------------------------------------------------------------
// Body

/// Colours: uchar as is, ushort scaled from 0..65535, floating point from 0..1; values outside
/// the range are clamped.
std::uint8_t colorByte(double v, Type t) {
  if (std::isnan(v)) throw ParseError{"a colour value is NaN"};
  if (t == Type::kFloat32 || t == Type::kFloat64) v *= 255.0;
  if (t == Type::kUint16) v /= 257.0;
  return static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0, 255.0)));
}

template <class Source>
void readBody(Source& in, const ParsedHeader& header, TriangleMesh& mesh, PlyReadReport& report) {
  std::size_t vertex_count = 0;
  for (const Elem& e : header.elements) {
    if (e.name == "vertex") vertex_count = e.count;
  }
  std::vector<std::int64_t> polygon;
  for (const Elem& e : header.elements) {
    const bool is_vertex = e.name == "vertex";
    const bool is_face = e.name == "face";
    bool normals = false, colors = false, labels = false, weights = false, ignore = false;
    for (const Prop& p : e.props) {
      normals |= p.slot == Slot::kNx;
      colors |= p.slot == Slot::kRed;
      labels |= p.slot == Slot::kLabel;
      weights |= p.slot == Slot::kQuality;
      ignore |= p.slot == Slot::kIgnoreFlag;
    }
    if (is_vertex) {
      mesh.positions.resize(e.count);
      if (normals) mesh.normals.resize(e.count);
      if (colors) mesh.colors.resize(e.count);
      if (labels) mesh.labels.resize(e.count);
      if (weights) mesh.weights.resize(e.count);
      if (ignore) mesh.ignore.resize(e.count);
    }
    if (is_face) mesh.triangles.reserve(e.count);

    // A skipped element with fixed-size rows is stepped over in one go.
    if constexpr (!std::is_same_v<Source, AsciiSource>) {
      if (!is_vertex && !is_face &&
          std::none_of(e.props.begin(), e.props.end(), [](const Prop& p) { return p.list; })) {
        std::size_t row = 0;
        for (const Prop& p : e.props) row += sizeOf(p.type);
        try {
          in.skip(row * e.count);
        } catch (const ParseError& err) {
          throw ParseError{err.what + " in element '" + e.name + "'"};
        }
        continue;
      }
    }

    std::size_t row = 0;
    std::size_t prop_index = 0;
    try {
      for (row = 0; row < e.count; ++row) {
        for (prop_index = 0; prop_index < e.props.size(); ++prop_index) {
          const Prop& p = e.props[prop_index];
          if (p.list) {
            const std::int64_t n = in.integer(p.count_type);
            if (n < 0) throw ParseError{"negative list length " + std::to_string(n)};
            if (!in.canHold(static_cast<std::uint64_t>(n), p.type)) {
              throw ParseError{
                  "list length " + std::to_string(n) +
                  " is more than the rest of the file can hold (truncated or corrupt?)"};
            }
            if (p.slot != Slot::kIndices) {
              for (std::int64_t k = 0; k < n; ++k) in.scalar(p.type);
              continue;
            }
            if (n < 3) {
              throw ParseError{"a face needs at least 3 vertex indices, this one has " +
                               std::to_string(n)};
            }
            polygon.resize(static_cast<std::size_t>(n));
            for (std::int64_t k = 0; k < n; ++k) {
              const std::int64_t v = in.integer(p.type);
              if (v < 0 || static_cast<std::uint64_t>(v) >= vertex_count) {
                throw ParseError{"it refers to vertex " + std::to_string(v) +
                                 ", but the file has " + std::to_string(vertex_count) +
                                 " vertices"};
              }
              polygon[static_cast<std::size_t>(k)] = v;
            }
            ++report.faces;
            for (std::size_t k = 1; k + 1 < polygon.size(); ++k) {
              const Eigen::Vector3i tri(static_cast<int>(polygon[0]), static_cast<int>(polygon[k]),
                                        static_cast<int>(polygon[k + 1]));
              if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) {
                ++report.degenerate_dropped;
              } else {
                mesh.triangles.push_back(tri);
              }
            }
            continue;
          }
          const double v = in.scalar(p.type);
          switch (p.slot) {
            case Slot::kX:
              mesh.positions[row].x() = static_cast<float>(v);
              break;
            case Slot::kY:
              mesh.positions[row].y() = static_cast<float>(v);
              break;
            case Slot::kZ:
              mesh.positions[row].z() = static_cast<float>(v);
              break;
            case Slot::kNx:
              mesh.normals[row].x() = static_cast<float>(v);
              break;
            case Slot::kNy:
              mesh.normals[row].y() = static_cast<float>(v);
              break;
            case Slot::kNz:
              mesh.normals[row].z() = static_cast<float>(v);
              break;
            case Slot::kRed:
              mesh.colors[row][0] = colorByte(v, p.type);
              break;
            case Slot::kGreen:
              mesh.colors[row][1] = colorByte(v, p.type);
              break;
            case Slot::kBlue:
              mesh.colors[row][2] = colorByte(v, p.type);
              break;
            case Slot::kLabel:
              if (v < INT32_MIN || v > INT32_MAX) {
                throw ParseError{p.name + " " + std::to_string(v) + " does not fit a 32-bit int"};
              }
              mesh.labels[row] = static_cast<std::int32_t>(v);
              break;
            case Slot::kQuality:
              mesh.weights[row] = static_cast<float>(v);  // checked by dropUnusableWeights
              break;
            case Slot::kIgnoreFlag:
              mesh.ignore[row] = v != 0.0 ? 1 : 0;
              break;
            case Slot::kIgnore:
            case Slot::kIndices:
              break;
          }
        }
      }
    } catch (const ParseError& err) {
      const std::string prop =
          prop_index < e.props.size() ? ", property '" + e.props[prop_index].name + "'" : "";
      throw ParseError{e.name + " " + std::to_string(row) + " of " + std::to_string(e.count) +
                       prop + " (" + in.position() + "): " + err.what};
    }
  }
  report.trailing_bytes = in.trailing();
}

/// `quality` is a fusion weight in the files objscan writes, but any scalar in others (MeshLab
/// keeps curvature, distances or ambient occlusion there, negative too): values that cannot be a
/// weight (NaN, infinite, negative) make the property ignored, with a warning, not the file
/// refused.
void dropUnusableWeights(const fs::path& path, TriangleMesh& mesh, PlyReadReport& report) {
  const auto bad = std::find_if(mesh.weights.begin(), mesh.weights.end(),
                                [](float w) { return !(std::isfinite(w) && w >= 0.0f); });
  if (bad == mesh.weights.end()) return;
  log::warning(path.string() +
               ": vertex property 'quality' ignored: objscan reads it as the fusion weight, a "
               "finite number >= 0, and vertex " +
               std::to_string(bad - mesh.weights.begin()) + " has " + std::to_string(*bad));
  mesh.weights.clear();
  report.ignored.push_back("vertex.quality");
}

PlyHeader publicHeader(const ParsedHeader& parsed) {
  PlyHeader h;
  h.format = parsed.format;
  h.comments = parsed.comments;
  for (const Elem& e : parsed.elements) {
    PlyHeader::Element pe{e.name, e.count, {}};
    for (const Prop& p : e.props) {
      pe.properties.push_back(
          {p.name, typeName(p.type), p.list ? typeName(p.count_type) : std::string()});
    }
    h.elements.push_back(std::move(pe));
  }
  return h;
}

// ---------------------------------------------------------------------------------------------
// Writing

using byte_writing::putBinary;
using byte_writing::putText;

}  // namespace

TriangleMesh readPly(const fs::path& path, PlyReadReport* report_out) {
  const std::string bytes = readWholeFile(path);
  if (bytes.empty()) throw InputError(path, "the file is empty");

  PlyReadReport report;
  report.file_bytes = bytes.size();
  TriangleMesh mesh;
  try {
    ParsedHeader header = parseHeader(bytes);
    assignSlots(header, report);
    const std::size_t body_bytes = bytes.size() - header.body_offset;
    const double needed = minimumBodyBytes(header);
    if (needed > static_cast<double>(body_bytes)) {
      std::string counts;
      for (const Elem& e : header.elements) {
        counts += (counts.empty() ? "" : ", ") + std::to_string(e.count) + " '" + e.name + "'";
      }
      throw ParseError{"truncated: the header announces " + counts + " elements (at least " +
                       std::to_string(static_cast<std::uint64_t>(needed)) +
                       " bytes of data), but only " + std::to_string(body_bytes) +
                       " bytes follow the header"};
    }
    report.header = publicHeader(header);

    const char* begin = bytes.data() + header.body_offset;
    const char* end = bytes.data() + bytes.size();
    const bool host_little = std::endian::native == std::endian::little;
    if (header.format == PlyFormat::kAscii) {
      const int header_lines = static_cast<int>(std::count(bytes.data(), begin, '\n'));
      AsciiSource in(begin, end, header_lines + 1);
      readBody(in, header, mesh, report);
      report.unterminated_last_value = in.unterminated();
    } else if ((header.format == PlyFormat::kBinaryLittleEndian) == host_little) {
      BinarySource<false> in(begin, end);
      readBody(in, header, mesh, report);
    } else {
      BinarySource<true> in(begin, end);
      readBody(in, header, mesh, report);
    }
  } catch (const ParseError& e) {
    throw InputError(path, e.what);
  }
  dropUnusableWeights(path, mesh, report);

  try {
    mesh.validate();
  } catch (const std::invalid_argument& e) {
    throw InputError(path, e.what());
  }
  if (report.unterminated_last_value) {
    log::warning(path.string() + ": the file does not end with a line break; its last value '" +
                 *report.unterminated_last_value +
                 "' was read as complete (a file cut short inside it would read the same)");
  }
  if (report.trailing_bytes > 0) {
    log::warning(path.string() + ": " + std::to_string(report.trailing_bytes) +
                 (report.trailing_bytes == 1 ? " byte" : " bytes") +
                 " after the last element ignored (do the header's counts match the data?)");
  }
  if (report.degenerate_dropped > 0) {
    log::warning(path.string() + ": dropped " + std::to_string(report.degenerate_dropped) +
                 " degenerate triangle(s) that repeat a vertex");
  }
  if (report_out) *report_out = std::move(report);
  return mesh;
}

std::string encodePly(const TriangleMesh& mesh, PlyFormat format) {
  mesh.validate();
  const bool normals = mesh.hasNormals();
  const bool colors = mesh.hasColors();
  const bool labels = mesh.hasLabels();
  const bool weights = mesh.hasWeights();
  const bool ignore = mesh.hasIgnore();

  std::string out;
  out += "ply\nformat ";
  out += toString(format);
  out += " 1.0\ncomment written by objscan\n";
  out += "element vertex " + std::to_string(mesh.positions.size()) + "\n";
  out += "property float x\nproperty float y\nproperty float z\n";
  if (normals) out += "property float nx\nproperty float ny\nproperty float nz\n";
  if (colors) out += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  if (labels) out += "property int object_id\n";
  if (weights) out += "property float quality\n";
  if (ignore) out += "property uchar ignore\n";
  out += "element face " + std::to_string(mesh.triangles.size()) + "\n";
  out += "property list uchar int vertex_indices\nend_header\n";

  const std::size_t n = mesh.positions.size();
  if (format == PlyFormat::kAscii) {
    out.reserve(out.size() + n * (normals ? 80 : 40) + mesh.triangles.size() * 24);
    for (std::size_t i = 0; i < n; ++i) {
      const auto& p = mesh.positions[i];
      putText(out, p.x());
      out += ' ';
      putText(out, p.y());
      out += ' ';
      putText(out, p.z());
      if (normals) {
        const auto& nm = mesh.normals[i];
        out += ' ';
        putText(out, nm.x());
        out += ' ';
        putText(out, nm.y());
        out += ' ';
        putText(out, nm.z());
      }
      if (colors) {
        const auto& c = mesh.colors[i];
        for (int k = 0; k < 3; ++k) {
          out += ' ';
          putText(out, static_cast<int>(c[k]));
        }
      }
      if (labels) {
        out += ' ';
        putText(out, mesh.labels[i]);
      }
      if (weights) {
        out += ' ';
        putText(out, mesh.weights[i]);
      }
      if (ignore) {
        out += ' ';
        putText(out, static_cast<int>(mesh.ignore[i]));
      }
      out += '\n';
    }
    for (const auto& t : mesh.triangles) {
      out += '3';
      for (int k = 0; k < 3; ++k) {
        out += ' ';
        putText(out, t[k]);
      }
      out += '\n';
    }
  } else {
    const bool swap =
        (format == PlyFormat::kBinaryLittleEndian) != (std::endian::native == std::endian::little);
    out.reserve(out.size() +
                n * (12 + (normals ? 12 : 0) + (colors ? 3 : 0) + (labels ? 4 : 0) +
                     (weights ? 4 : 0) + (ignore ? 1 : 0)) +
                mesh.triangles.size() * 13);
    for (std::size_t i = 0; i < n; ++i) {
      for (int k = 0; k < 3; ++k) putBinary(out, mesh.positions[i][k], swap);
      if (normals)
        for (int k = 0; k < 3; ++k) putBinary(out, mesh.normals[i][k], swap);
      if (colors) out.append(reinterpret_cast<const char*>(mesh.colors[i].data()), 3);
      if (labels) putBinary(out, mesh.labels[i], swap);
      if (weights) putBinary(out, mesh.weights[i], swap);
      if (ignore) out += static_cast<char>(mesh.ignore[i]);
    }
    for (const auto& t : mesh.triangles) {
      out += static_cast<char>(3);
      for (int k = 0; k < 3; ++k) putBinary(out, static_cast<std::int32_t>(t[k]), swap);
    }
  }
  return out;
}

void writePly(const fs::path& path, const TriangleMesh& mesh, PlyFormat format) {
  writeFileAtomically(path, encodePly(mesh, format));
}

}  // namespace objscan
