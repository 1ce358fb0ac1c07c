#include "objscan/core/organized_cloud.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>

#include <liblzf/lzf.h>

#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"

namespace objscan {

std::size_t OrganizedCloud::validCount() const {
  std::size_t n = 0;
  for (std::size_t i = 0; i < points_C.size(); ++i) n += valid(i);
  return n;
}

namespace {

namespace fs = std::filesystem;

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
/// More points than any camera gives: a header asking for more is corrupt, not a cloud.
constexpr std::size_t kMaxPoints = std::size_t{1} << 27;

struct PcdField {
  std::string name;
  std::size_t size = 4;
  char type = 'F';
  std::size_t count = 1;
  std::size_t offset = 0;  ///< within a point, bytes (binary); the first value's index (ascii)
};

struct PcdHeader {
  std::vector<PcdField> fields;
  std::size_t width = 0, height = 0, points = 0;
  std::string data;
  std::size_t point_bytes = 0;  ///< sum of size * count
  std::size_t values = 0;       ///< sum of count
};

/// Splits a header line into its words.
std::vector<std::string> words(const std::string& line) {
  std::istringstream in(line);
  return {std::istream_iterator<std::string>(in), std::istream_iterator<std::string>()};
}

std::size_t parseCount(const fs::path& path, const std::string& key, const std::string& word) {
  std::size_t used = 0;
  unsigned long long v = 0;
  try {
    v = std::stoull(word, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != word.size() || word.empty() || word[0] == '-' || v > kMaxPoints) {
    throw InputError(path, key + " holds \"" + word + "\", not a count this reader accepts");
  }
  return static_cast<std::size_t>(v);
}

/// Parses the header up to and including its DATA line; `pos` is left at the first data byte.
PcdHeader parseHeader(const fs::path& path, const std::string& bytes, std::size_t& pos) {
  PcdHeader h;
  std::vector<std::string> sizes, types, counts;
  bool have_width = false, have_height = false, have_points = false;
  while (h.data.empty()) {
    if (pos >= bytes.size()) {
      throw InputError(path, "the PCD header ends before its DATA line (truncated, or not a PCD)");
    }
    std::size_t end = bytes.find('\n', pos);
    if (end == std::string::npos) end = bytes.size();
    std::string line = bytes.substr(pos, end - pos);
    pos = std::min(end + 1, bytes.size());
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::vector<std::string> w = words(line);
    if (w.empty() || w[0][0] == '#') continue;
    const std::string& key = w[0];
    const std::vector<std::string> rest(w.begin() + 1, w.end());
    if (key == "VERSION" || key == "VIEWPOINT") {
      continue;
    } else if (key == "FIELDS" || key == "COLUMNS") {
      for (const std::string& name : rest) h.fields.push_back({name});
    } else if (key == "SIZE") {
      sizes = rest;
    } else if (key == "TYPE") {
      types = rest;
    } else if (key == "COUNT") {
      counts = rest;
    } else if (key == "WIDTH" && rest.size() == 1) {
      h.width = parseCount(path, key, rest[0]);
      have_width = true;
    } else if (key == "HEIGHT" && rest.size() == 1) {
      h.height = parseCount(path, key, rest[0]);
      have_height = true;
    } else if (key == "POINTS" && rest.size() == 1) {
      h.points = parseCount(path, key, rest[0]);
      have_points = true;
    } else if (key == "DATA" && rest.size() == 1) {
      h.data = rest[0];
      if (h.data != "ascii" && h.data != "binary" && h.data != "binary_compressed") {
        throw InputError(
            path, "DATA " + h.data + " is not a PCD encoding (ascii, binary, binary_compressed)");
      }
    } else {
      throw InputError(path,
                       "the PCD header line \"" + line.substr(0, 60) + "\" is not understood");
    }
  }
  if (h.fields.empty()) throw InputError(path, "the PCD header has no FIELDS");
  if (sizes.size() != h.fields.size() || types.size() != h.fields.size() ||
      (!counts.empty() && counts.size() != h.fields.size())) {
    throw InputError(path, "the PCD header's SIZE, TYPE and COUNT do not have one entry per field");
  }
  if (!have_width) throw InputError(path, "the PCD header has no WIDTH");
  if (!have_height) h.height = 1;  // v0.5 files may leave it out
  if (!have_points) h.points = h.width * h.height;
  if (h.width == 0 || h.height == 0 || h.points != h.width * h.height || h.points > kMaxPoints) {
    throw InputError(path, "the PCD header's WIDTH x HEIGHT (" + std::to_string(h.width) + " x " +
                               std::to_string(h.height) + ") does not match POINTS " +
                               std::to_string(h.points));
  }
  for (std::size_t i = 0; i < h.fields.size(); ++i) {
    PcdField& f = h.fields[i];
    f.size = parseCount(path, "SIZE", sizes[i]);
    f.count = counts.empty() ? 1 : parseCount(path, "COUNT", counts[i]);
    if (types[i].size() != 1 || std::string("FIU").find(types[i][0]) == std::string::npos) {
      throw InputError(path, "field " + f.name + " has TYPE " + types[i] + " (not F, I or U)");
    }
    f.type = types[i][0];
    const bool size_ok = f.type == 'F' ? (f.size == 4 || f.size == 8)
                                       : (f.size == 1 || f.size == 2 || f.size == 4 || f.size == 8);
    if (!size_ok || f.count == 0 || f.count > 1024) {
      throw InputError(path, "field " + f.name + " has SIZE " + sizes[i] + " and TYPE " + types[i] +
                                 " with COUNT " + std::to_string(f.count) +
                                 ", which no PCD writer produces");
    }
    f.offset = h.point_bytes;
    h.point_bytes += f.size * f.count;
    h.values += f.count;
  }
  return h;
}

const PcdField* findField(const PcdHeader& h, const char* name) {
  for (const PcdField& f : h.fields) {
    if (f.name == name) return &f;
  }
  return nullptr;
}

/// A value of `field` stored at `at` (binary), as a double (F) or its integer bits (I, U).
double binaryValue(const PcdField& f, const char* at) {
  if (f.type == 'F') {
    if (f.size == 4) {
      float v;
      std::memcpy(&v, at, 4);
      return v;
    }
    double v;
    std::memcpy(&v, at, 8);
    return v;
  }
  std::uint64_t bits = 0;
  std::memcpy(&bits, at, f.size);  // little-endian, as PCL writes
  if (f.type == 'I' && f.size < 8 && (bits >> (8 * f.size - 1)) & 1u) {
    bits |= ~std::uint64_t{0} << (8 * f.size);  // sign-extend
  }
  return f.type == 'I' ? static_cast<double>(static_cast<std::int64_t>(bits))
                       : static_cast<double>(bits);
}

/// The fields the cloud needs, located, with the checks on their types.
struct Layout {
  const PcdField *x = nullptr, *y = nullptr, *z = nullptr, *rgb = nullptr, *label = nullptr;
};

Layout layoutOf(const fs::path& path, const PcdHeader& h) {
  Layout l{findField(h, "x"), findField(h, "y"), findField(h, "z"), findField(h, "rgba"),
           findField(h, "label")};
  if (!l.rgb) l.rgb = findField(h, "rgb");
  if (!l.x || !l.y || !l.z) throw InputError(path, "the PCD has no x y z fields");
  for (const PcdField* f : {l.x, l.y, l.z}) {
    if (f->type != 'F') {
      throw InputError(path, "field " + f->name + " has TYPE " + f->type + ", not F (float)");
    }
  }
  if (l.rgb && l.rgb->size != 4) {
    throw InputError(path, "field " + l.rgb->name + " has SIZE " + std::to_string(l.rgb->size) +
                               ", not 4 (packed 8-bit colour)");
  }
  if (l.label && (l.label->type == 'F' || l.label->size > 4)) {
    throw InputError(path, "field label has TYPE " + std::string(1, l.label->type) + " SIZE " +
                               std::to_string(l.label->size) +
                               ": a label must be an integer of at most 4 bytes");
  }
  return l;
}

/// Colour of packed bits 0x00RRGGBB (rgb) or 0xAARRGGBB (rgba).
Rgb8 unpackColour(std::uint32_t bits) {
  return Rgb8(static_cast<std::uint8_t>(bits >> 16), static_cast<std::uint8_t>(bits >> 8),
              static_cast<std::uint8_t>(bits));
}

/// The bits of a 4-byte colour value as stored: a float's bits (TYPE F, PCL's rgb) or the integer.
std::uint32_t colourBits(const char* at) {
  std::uint32_t bits;
  std::memcpy(&bits, at, 4);
  return bits;
}

OrganizedCloud emptyCloud(const PcdHeader& h, const Layout& l) {
  OrganizedCloud c;
  c.width = static_cast<int>(h.width);
  c.height = static_cast<int>(h.height);
  c.points_C.assign(h.points, Eigen::Vector3f::Constant(kNaN));
  if (l.rgb) c.colors.assign(h.points, Rgb8::Zero());
  if (l.label) c.labels.assign(h.points, 0);
  return c;
}

/// A point is kept when its coordinates are finite floats; NaN (no reading) and infinities leave
/// it missing. A finite value past float's range cannot come from a float field: corrupt.
void setPoint(const fs::path& path, OrganizedCloud& c, std::size_t i, double x, double y,
              double z) {
  if (!(std::isfinite(x) && std::isfinite(y) && std::isfinite(z))) return;
  constexpr double kMax = std::numeric_limits<float>::max();
  if (std::fabs(x) > kMax || std::fabs(y) > kMax || std::fabs(z) > kMax) {
    throw InputError(path, "point " + std::to_string(i) + " has a coordinate past float's range");
  }
  c.points_C[i] = Eigen::Vector3d(x, y, z).cast<float>();
}

std::uint32_t labelValue(const fs::path& path, double v, std::size_t point) {
  if (!(v >= 0 && v <= std::numeric_limits<std::uint32_t>::max())) {  // NaN too
    throw InputError(path,
                     "point " + std::to_string(point) + " has a label outside 0 .. 4294967295");
  }
  return static_cast<std::uint32_t>(v);
}

/// Binary data: array of structures (stride point_bytes), or with `soa`, one array per field (the
/// decompressed binary_compressed layout).
OrganizedCloud decodeBinary(const fs::path& path, const PcdHeader& h, const Layout& l,
                            const char* data, bool soa) {
  OrganizedCloud c = emptyCloud(h, l);
  const auto at = [&](const PcdField& f, std::size_t i) {
    return soa ? data + f.offset * h.points + i * f.size * f.count
               : data + i * h.point_bytes + f.offset;
  };
  for (std::size_t i = 0; i < h.points; ++i) {
    setPoint(path, c, i, binaryValue(*l.x, at(*l.x, i)), binaryValue(*l.y, at(*l.y, i)),
             binaryValue(*l.z, at(*l.z, i)));
    if (l.rgb) c.colors[i] = unpackColour(colourBits(at(*l.rgb, i)));
    if (l.label) c.labels[i] = labelValue(path, binaryValue(*l.label, at(*l.label, i)), i);
  }
  return c;
}

OrganizedCloud decodeAscii(const fs::path& path, const PcdHeader& h, const Layout& l,
                           const std::string& bytes, std::size_t pos) {
  OrganizedCloud c = emptyCloud(h, l);
  std::vector<std::size_t> first(h.fields.size());  // each field's first value in a line
  for (std::size_t k = 0, v = 0; k < h.fields.size(); v += h.fields[k].count, ++k) first[k] = v;
  const auto index = [&](const PcdField* f) {
    return first[static_cast<std::size_t>(f - h.fields.data())];
  };
  std::vector<std::string> tokens;
  std::size_t i = 0;
  while (i < h.points) {
    if (pos >= bytes.size()) {
      throw InputError(path, "the PCD is truncated: " + std::to_string(i) + " of " +
                                 std::to_string(h.points) + " points");
    }
    std::size_t end = bytes.find('\n', pos);
    if (end == std::string::npos) end = bytes.size();
    tokens = words(bytes.substr(pos, end - pos));
    pos = end + 1;
    if (tokens.empty()) continue;
    if (tokens.size() != h.values) {
      throw InputError(path, "point " + std::to_string(i) + " has " +
                                 std::to_string(tokens.size()) + " values, the header says " +
                                 std::to_string(h.values));
    }
    const auto number = [&](std::size_t k) {
      const std::string& t = tokens[k];
      char* stop = nullptr;
      const double v = std::strtod(t.c_str(), &stop);
      if (stop != t.c_str() + t.size()) {
        throw InputError(path, "point " + std::to_string(i) + " holds \"" + t.substr(0, 30) +
                                   "\", not a number");
      }
      return v;
    };
    setPoint(path, c, i, number(index(l.x)), number(index(l.y)), number(index(l.z)));
    if (l.rgb) {
      const double v = number(index(l.rgb));
      // The packed colour must fit its 32-bit field: a value outside it names no colour (and
      // converting it would be undefined).
      const bool fits = l.rgb->type == 'F' ? !(std::fabs(v) > std::numeric_limits<float>::max()) ||
                                                 std::isinf(v)
                        : l.rgb->type == 'I' ? v >= -2147483648.0 && v <= 2147483647.0
                                             : v >= 0.0 && v <= 4294967295.0;
      if (!fits) {
        throw InputError(path, "point " + std::to_string(i) + "'s rgb " + tokens[index(l.rgb)].substr(0, 30) +
                                   " does not fit its 32-bit field");
      }
      const std::uint32_t bits =
          l.rgb->type == 'F'   ? std::bit_cast<std::uint32_t>(static_cast<float>(v))
          : l.rgb->type == 'I' ? static_cast<std::uint32_t>(static_cast<std::int32_t>(v))
                               : static_cast<std::uint32_t>(v);
      c.colors[i] = unpackColour(bits);
    }
    if (l.label) {
      const double v = number(index(l.label));
      if (v != std::floor(v)) {
        throw InputError(path, "point " + std::to_string(i) + "'s label is not an integer");
      }
      c.labels[i] = labelValue(path, v, i);
    }
    ++i;
  }
  return c;
}

}  // namespace

OrganizedCloud readPcd(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in || fs::is_directory(path)) {
    throw InputError(path, fs::exists(path) ? "cannot be read as a file" : "no such file");
  }
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (bytes.empty()) throw InputError(path, "the file is empty");
  std::size_t pos = 0;
  const PcdHeader h = parseHeader(path, bytes, pos);
  const Layout l = layoutOf(path, h);
  const std::size_t available = bytes.size() - pos;
  if (h.data == "ascii") {
    // Each value takes a character and, but for the last, a separator: a count the data cannot
    // hold is refused before the cloud is allocated for it.
    if ((available + 1) / 2 / std::max<std::size_t>(h.values, 1) < h.points) {
      throw InputError(path, "the PCD is truncated: its ascii data (" + std::to_string(available) +
                                 " bytes) cannot hold the " + std::to_string(h.points) +
                                 " points its header declares");
    }
    return decodeAscii(path, h, l, bytes, pos);
  }
  const std::size_t expected = h.points * h.point_bytes;
  if (h.data == "binary") {
    if (available < expected) {
      throw InputError(path, "the PCD is truncated: its binary data holds " +
                                 std::to_string(available) + " of " + std::to_string(expected) +
                                 " bytes");
    }
    return decodeBinary(path, h, l, bytes.data() + pos, false);
  }
  std::uint32_t sizes[2];
  if (available < sizeof sizes) throw InputError(path, "the PCD is truncated after its header");
  std::memcpy(sizes, bytes.data() + pos, sizeof sizes);
  const std::size_t compressed = sizes[0], uncompressed = sizes[1];
  if (uncompressed != expected) {
    throw InputError(path, "the compressed PCD says it holds " + std::to_string(uncompressed) +
                               " bytes, its header " + std::to_string(expected));
  }
  if (available - sizeof sizes < compressed) {
    throw InputError(path, "the PCD is truncated: its compressed data holds " +
                               std::to_string(available - sizeof sizes) + " of " +
                               std::to_string(compressed) + " bytes");
  }
  // LZF expands 3 bytes into 264 at most (its longest back reference): a larger claim is not
  // LZF data, and is refused before the buffer is allocated for it.
  constexpr std::size_t kLzfMaxExpansion = 88;
  if (uncompressed > compressed * kLzfMaxExpansion + 8) {
    throw InputError(path, "the PCD's compressed data is corrupt (" + std::to_string(compressed) +
                               " bytes of LZF cannot hold " + std::to_string(uncompressed) + ")");
  }
  std::string raw(expected, '\0');
  const unsigned int got =
      expected == 0
          ? 0
          : lzf_decompress(bytes.data() + pos + sizeof sizes, static_cast<unsigned int>(compressed),
                           raw.data(), static_cast<unsigned int>(expected));
  if (got != expected) {
    throw InputError(path, "the PCD's compressed data is corrupt (it does not decompress to " +
                               std::to_string(expected) + " bytes)");
  }
  return decodeBinary(path, h, l, raw.data(), true);
}

void writePcd(const fs::path& path, const OrganizedCloud& cloud) {
  const std::size_t n = cloud.points_C.size();
  static_assert(std::endian::native == std::endian::little, "PCD binary data is little-endian");
  if (cloud.width <= 0 || cloud.height <= 0 ||
      n != static_cast<std::size_t>(cloud.width) * static_cast<std::size_t>(cloud.height)) {
    throw std::invalid_argument("writePcd: the cloud's points do not fill its WIDTH x HEIGHT");
  }
  if (n > kMaxPoints) {
    throw std::invalid_argument("writePcd: more points than a PCD file readPcd reads may hold");
  }
  if ((!cloud.colors.empty() && cloud.colors.size() != n) ||
      (!cloud.labels.empty() && cloud.labels.size() != n)) {
    throw std::invalid_argument("writePcd: one colour and one label per point are needed");
  }
  const bool colours = !cloud.colors.empty(), labels = !cloud.labels.empty();
  // Every field is 4 bytes, one value: x y z as floats, then rgb and label as unsigned integers.
  std::string fields = "x y z", sizes = "4 4 4", types = "F F F", counts = "1 1 1";
  const auto addField = [&](const char* name) {
    fields += std::string(" ") + name;
    sizes += " 4";
    types += " U";
    counts += " 1";
  };
  if (colours) addField("rgb");
  if (labels) addField("label");
  std::ostringstream header;
  header << "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS " << fields
         << "\nSIZE " << sizes << "\nTYPE " << types << "\nCOUNT " << counts << "\nWIDTH "
         << cloud.width << "\nHEIGHT " << cloud.height << "\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << n
         << "\nDATA binary\n";
  std::string bytes = header.str();
  const std::size_t point_size = 4 * (3 + std::size_t{colours} + std::size_t{labels});
  std::size_t at = bytes.size();
  bytes.resize(at + n * point_size);
  const auto put = [&](const void* value) {
    std::memcpy(bytes.data() + at, value, 4);
    at += 4;
  };
  for (std::size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) put(&cloud.points_C[i][k]);
    if (colours) {
      const Rgb8& c = cloud.colors[i];
      const std::uint32_t packed = std::uint32_t{c.x()} << 16 | std::uint32_t{c.y()} << 8 | c.z();
      put(&packed);
    }
    if (labels) put(&cloud.labels[i]);
  }
  writeFileAtomically(path, bytes);
}

OrganizedCloud cloudOfFrame(const RgbdFrame& frame) {
  frame.validate();
  const Intrinsics& k = frame.intrinsics;
  OrganizedCloud c;
  c.width = frame.depth_m.cols;
  c.height = frame.depth_m.rows;
  c.points_C.assign(static_cast<std::size_t>(c.width) * c.height, Eigen::Vector3f::Constant(kNaN));
  if (!frame.color_rgb.empty()) c.colors.assign(c.points_C.size(), Rgb8::Zero());
  for (int v = 0; v < c.height; ++v) {
    const float* depth = frame.depth_m.ptr<float>(v);
    for (int u = 0; u < c.width; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * c.width + u;
      const float z = depth[u];
      if (std::isfinite(z) && z > 0.0f) {
        c.points_C[i] = Eigen::Vector3f(static_cast<float>((u - k.cx_px) / k.fx_px) * z,
                                        static_cast<float>((v - k.cy_px) / k.fy_px) * z, z);
      }
      if (!c.colors.empty()) {
        const cv::Vec3b rgb = frame.color_rgb.at<cv::Vec3b>(v, u);
        c.colors[i] = Rgb8(rgb[0], rgb[1], rgb[2]);
      }
    }
  }
  return c;
}

OrganizedCloud placeOnPixelGrid(const OrganizedCloud& cloud, const Intrinsics& k) {
  k.validate();
  OrganizedCloud out;
  out.width = k.width_px;
  out.height = k.height_px;
  out.points_C.assign(static_cast<std::size_t>(k.width_px) * k.height_px,
                      Eigen::Vector3f::Constant(kNaN));
  if (!cloud.colors.empty()) out.colors.assign(out.points_C.size(), Rgb8::Zero());
  if (!cloud.labels.empty()) out.labels.assign(out.points_C.size(), 0);
  for (std::size_t i = 0; i < cloud.points_C.size(); ++i) {
    const Eigen::Vector3f& p = cloud.points_C[i];
    if (!cloud.valid(i) || !(p.z() > 0.0f)) continue;
    const double u = k.fx_px * p.x() / p.z() + k.cx_px, v = k.fy_px * p.y() / p.z() + k.cy_px;
    const long iu = std::lround(u), iv = std::lround(v);
    if (iu < 0 || iv < 0 || iu >= k.width_px || iv >= k.height_px) continue;
    const std::size_t j = static_cast<std::size_t>(iv) * k.width_px + static_cast<std::size_t>(iu);
    if (out.valid(j) && out.points_C[j].z() <= p.z()) continue;
    out.points_C[j] = p;
    if (!cloud.colors.empty()) out.colors[j] = cloud.colors[i];
    if (!cloud.labels.empty()) out.labels[j] = cloud.labels[i];
  }
  return out;
}

namespace {

/// The spacing and offset of values that lie on a grid a + step * n (integers n), from their
/// sorted distinct values: the step is the most common gap between neighbours (gaps over several
/// steps are multiples of it), refined by least squares over all values. Nothing when the values
/// do not sit on one grid within a tenth of a step.
std::optional<std::pair<double, double>> gridOf(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  // Distinct values, merging those closer than float rounding of a ratio.
  std::vector<double> distinct;
  for (double v : values) {
    if (distinct.empty() || v - distinct.back() > 1e-6 * std::max(1.0, std::abs(v))) {
      distinct.push_back(v);
    }
  }
  if (distinct.size() < 16) return std::nullopt;
  std::vector<double> gaps;
  for (std::size_t i = 1; i < distinct.size(); ++i) gaps.push_back(distinct[i] - distinct[i - 1]);
  std::nth_element(gaps.begin(), gaps.begin() + gaps.size() / 4, gaps.end());
  const double step0 = gaps[gaps.size() / 4];
  if (!(step0 > 0.0)) return std::nullopt;
  // Each value's grid index from the first; least squares for step and offset.
  double sn = 0, sv = 0, snn = 0, snv = 0;
  std::vector<double> n(distinct.size());
  for (std::size_t i = 0; i < distinct.size(); ++i) {
    n[i] = std::round((distinct[i] - distinct[0]) / step0);
    sn += n[i];
    sv += distinct[i];
    snn += n[i] * n[i];
    snv += n[i] * distinct[i];
  }
  const double m = static_cast<double>(distinct.size());
  const double det = m * snn - sn * sn;
  if (!(det > 0.0)) return std::nullopt;
  const double step = (m * snv - sn * sv) / det, offset = (sv - step * sn) / m;
  for (std::size_t i = 0; i < distinct.size(); ++i) {
    if (std::abs(offset + step * n[i] - distinct[i]) > 0.1 * step) return std::nullopt;
  }
  return std::make_pair(step, offset);
}

}  // namespace

std::optional<Intrinsics> fitPinhole(const OrganizedCloud& cloud) {
  std::vector<double> xs, ys;
  for (std::size_t i = 0; i < cloud.points_C.size(); ++i) {
    const Eigen::Vector3f& p = cloud.points_C[i];
    if (!cloud.valid(i) || !(p.z() > 0.0f)) continue;
    xs.push_back(static_cast<double>(p.x()) / p.z());
    ys.push_back(static_cast<double>(p.y()) / p.z());
  }
  const auto gx = gridOf(xs), gy = gridOf(ys);
  if (!gx || !gy) return std::nullopt;
  // x / z = (u - cx) / fx and the grid offset + step n give fx = 1 / step and u = n + cx + fx
  // offset: the image is taken as the smallest that holds every point and the principal point
  // (n = -offset / step), its first column the smallest n.
  Intrinsics k;
  k.fx_px = 1.0 / gx->first;
  k.fy_px = 1.0 / gy->first;
  const auto span = [](const std::vector<double>& v, double step, double offset) {
    const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
    const long centre = std::lround(-offset / step);
    return std::make_pair(std::min(centre, std::lround((*lo - offset) / step)),
                          std::max(centre, std::lround((*hi - offset) / step)));
  };
  const auto [u0, u1] = span(xs, gx->first, gx->second);
  const auto [v0, v1] = span(ys, gy->first, gy->second);
  k.width_px = static_cast<int>(std::min(u1 - u0 + 1, 16385L));
  k.height_px = static_cast<int>(std::min(v1 - v0 + 1, 16385L));
  if (k.width_px < 2 || k.height_px < 2 || k.width_px > 16384 || k.height_px > 16384) {
    return std::nullopt;
  }
  k.cx_px = std::clamp(-gx->second * k.fx_px - static_cast<double>(u0), 0.0,
                       static_cast<double>(k.width_px - 1));
  k.cy_px = std::clamp(-gy->second * k.fy_px - static_cast<double>(v0), 0.0,
                       static_cast<double>(k.height_px - 1));
  return k;
}

void OrganizedMeshConfig::validate() const {
  if (!(max_view_angle_deg > 0.0f && max_view_angle_deg < 90.0f)) {
    throw std::invalid_argument("the organized mesh's max_view_angle_deg must lie in (0, 90)");
  }
  if (!(noise_steps >= 0.0f) || !std::isfinite(noise_steps)) {
    throw std::invalid_argument("the organized mesh's noise_steps must be a number >= 0");
  }
}

TriangleMesh meshOrganized(const OrganizedCloud& cloud, const OrganizedMeshConfig& config,
                           std::vector<std::int32_t>* pixel_of_vertex) {
  config.validate();
  if (!cloud.organized()) {
    throw std::invalid_argument(
        "the cloud is not organized (one row): put it on its pixel grid first");
  }
  const std::size_t w = static_cast<std::size_t>(cloud.width);
  const std::size_t h = static_cast<std::size_t>(cloud.height);
  TriangleMesh mesh;
  std::vector<std::int32_t> vertex(w * h, -1);
  if (pixel_of_vertex) pixel_of_vertex->clear();
  for (std::size_t i = 0; i < w * h; ++i) {
    if (!cloud.valid(i) || !(cloud.points_C[i].z() > 0.0f)) continue;
    vertex[i] = static_cast<std::int32_t>(mesh.positions.size());
    mesh.positions.push_back(cloud.points_C[i]);
    if (!cloud.colors.empty()) mesh.colors.push_back(cloud.colors[i]);
    if (!cloud.labels.empty()) mesh.labels.push_back(objectIdOfLabel(cloud.labels[i]));
    if (pixel_of_vertex) pixel_of_vertex->push_back(static_cast<std::int32_t>(i));
  }
  const float tan_max = std::tan(config.max_view_angle_deg * static_cast<float>(M_PI) / 180.0f);
  // Whether pixels a and b (neighbours, both with readings) are joined: the depth step against the
  // lateral distance between their rays at that depth.
  const auto joined = [&](std::size_t a, std::size_t b) {
    const Eigen::Vector3f& p = cloud.points_C[a];
    const Eigen::Vector3f& q = cloud.points_C[b];
    const float z = 0.5f * (p.z() + q.z());
    const float lateral = (p.head<2>() / p.z() - q.head<2>() / q.z()).norm() * z;
    const float allowed = std::max(tan_max * lateral, config.noise_steps * 2.85e-3f * z * z);
    return std::abs(p.z() - q.z()) <= allowed;
  };
  const auto add = [&](std::size_t a, std::size_t b, std::size_t c) {
    if (vertex[a] < 0 || vertex[b] < 0 || vertex[c] < 0) return;
    if (!joined(a, b) || !joined(b, c) || !joined(c, a)) return;
    // a, b, c run clockwise in the image (u right, v down), counter-clockwise seen from the
    // camera: the normal faces it.
    mesh.triangles.emplace_back(vertex[a], vertex[b], vertex[c]);
  };
  for (std::size_t v = 0; v + 1 < h; ++v) {
    for (std::size_t u = 0; u + 1 < w; ++u) {
      const std::size_t p00 = v * w + u, p01 = p00 + 1, p10 = p00 + w, p11 = p10 + 1;
      // The shorter diagonal (in depth) splits the block; with a pixel missing, the other three.
      const auto depth_gap = [&](std::size_t a, std::size_t b) {
        return vertex[a] >= 0 && vertex[b] >= 0
                   ? std::abs(cloud.points_C[a].z() - cloud.points_C[b].z())
                   : std::numeric_limits<float>::infinity();
      };
      if (depth_gap(p00, p11) <= depth_gap(p01, p10)) {
        add(p00, p10, p11);
        add(p00, p11, p01);
      } else {
        add(p00, p10, p01);
        add(p01, p10, p11);
      }
    }
  }
  mesh.computeNormals();
  return mesh;
}

std::int32_t objectIdOfLabel(std::uint32_t label, bool merge_parts) {
  if (label < 10) return 0;
  const std::uint32_t id = merge_parts ? label / 10 : label;
  // Beyond int32 (a corrupt label): the largest id, which ground truth then refuses by name.
  return static_cast<std::int32_t>(std::min<std::uint32_t>(id, INT32_MAX));
}

}  // namespace objscan
