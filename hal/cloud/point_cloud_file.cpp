#include "blockmap/hal/cloud/point_cloud_file.hpp"

#include <algorithm>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <iterator>
#include <optional>
#include <sstream>
#include <system_error>

#include "blockmap/hal/files.hpp"

namespace blockmap::hal::cloud {
namespace {

// Coordinates beyond this (m) are kept relative to an origin near the first point.
constexpr double kLargeCoordinateM = 10000.0;

[[noreturn]] void fail(const std::string& what) {
  throw CloudFileError(what);
}

// ---- accumulating points ----

class PointSink {
 public:
  explicit PointSink(PointCloud& cloud) : cloud_(cloud) {}
  void add(double x, double y, double z) {
    if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) {
      ++cloud_.skipped_nonfinite;
      return;
    }
    if (!origin_set_) {
      origin_set_ = true;
      const Eigen::Vector3d first(x, y, z);
      if (first.cwiseAbs().maxCoeff() > kLargeCoordinateM) {
        cloud_.origin_m = (first / 1000.0).array().round() * 1000.0;
      }
    }
    cloud_.points_m.emplace_back((Eigen::Vector3d(x, y, z) - cloud_.origin_m).cast<float>());
  }

 private:
  PointCloud& cloud_;
  bool origin_set_ = false;
};

// ---- text ----

class LineReader {
 public:
  explicit LineReader(std::string_view text) : text_(text) {}
  // The next line without its end; nullopt at the end of the text.
  std::optional<std::string_view> next() {
    if (position_ >= text_.size()) {
      return std::nullopt;
    }
    const std::size_t end = text_.find('\n', position_);
    const std::size_t stop = end == std::string_view::npos ? text_.size() : end;
    std::string_view line = text_.substr(position_, stop - position_);
    position_ = stop + 1;
    ++number_;
    if (!line.empty() && line.back() == '\r') {
      line.remove_suffix(1);
    }
    return line;
  }
  [[nodiscard]] std::size_t line_number() const noexcept { return number_; }
  [[nodiscard]] std::size_t offset() const noexcept { return std::min(position_, text_.size()); }

 private:
  std::string_view text_;
  std::size_t position_ = 0;
  std::size_t number_ = 0;
};

bool is_separator(char c) {
  return c == ' ' || c == '\t' || c == ',';
}

// Splits on spaces, tabs and commas into `out`; returns the count (at most out.size()).
std::size_t split_fields(std::string_view line, std::span<std::string_view> out) {
  std::size_t count = 0;
  std::size_t i = 0;
  while (i < line.size() && count < out.size()) {
    while (i < line.size() && is_separator(line[i])) {
      ++i;
    }
    const std::size_t start = i;
    while (i < line.size() && !is_separator(line[i])) {
      ++i;
    }
    if (i > start) {
      out[count++] = line.substr(start, i - start);
    }
  }
  return count;
}

std::size_t count_fields(std::string_view line) {
  std::size_t count = 0;
  bool in_field = false;
  for (const char c : line) {
    const bool separator = is_separator(c);
    count += (!separator && !in_field) ? 1 : 0;
    in_field = !separator;
  }
  return count;
}

std::optional<double> parse_number(std::string_view field) {
  // from_chars takes "nan" and "inf" too, so those points are skipped and counted, not refused.
  if (!field.empty() && field.front() == '+') {
    field.remove_prefix(1);
  }
  double value = 0.0;
  const auto [end, error] = std::from_chars(field.data(), field.data() + field.size(), value);
  if (error == std::errc::result_out_of_range) {
    return std::numeric_limits<double>::infinity();
  }
  if (error != std::errc() || end != field.data() + field.size()) {
    return std::nullopt;
  }
  return value;
}

std::uint64_t parse_count(std::string_view field, const std::string& what) {
  std::uint64_t value = 0;
  const auto [end, error] = std::from_chars(field.data(), field.data() + field.size(), value);
  if (error != std::errc() || end != field.data() + field.size()) {
    fail(what + ": '" + std::string(field) + "' is not a count");
  }
  return value;
}

std::string line_prefix(std::size_t line) {
  return "line " + std::to_string(line);
}

// ---- binary scalars ----

enum class ScalarType : std::uint8_t { kI8, kU8, kI16, kU16, kI32, kU32, kI64, kU64, kF32, kF64 };

std::size_t scalar_size(ScalarType type) {
  switch (type) {
    case ScalarType::kI8:
    case ScalarType::kU8:
      return 1;
    case ScalarType::kI16:
    case ScalarType::kU16:
      return 2;
    case ScalarType::kI32:
    case ScalarType::kU32:
    case ScalarType::kF32:
      return 4;
    case ScalarType::kI64:
    case ScalarType::kU64:
    case ScalarType::kF64:
      return 8;
  }
  return 1;
}

template <typename T>
T load(const std::uint8_t* bytes, bool big_endian) {
  std::array<std::uint8_t, sizeof(T)> raw{};
  std::memcpy(raw.data(), bytes, sizeof(T));
  if (big_endian == (std::endian::native == std::endian::little)) {
    std::reverse(raw.begin(), raw.end());
  }
  return std::bit_cast<T>(raw);
}

double load_scalar(const std::uint8_t* bytes, ScalarType type, bool big_endian) {
  switch (type) {
    case ScalarType::kI8:
      return static_cast<double>(static_cast<std::int8_t>(bytes[0]));
    case ScalarType::kU8:
      return static_cast<double>(bytes[0]);
    case ScalarType::kI16:
      return static_cast<double>(load<std::int16_t>(bytes, big_endian));
    case ScalarType::kU16:
      return static_cast<double>(load<std::uint16_t>(bytes, big_endian));
    case ScalarType::kI32:
      return static_cast<double>(load<std::int32_t>(bytes, big_endian));
    case ScalarType::kU32:
      return static_cast<double>(load<std::uint32_t>(bytes, big_endian));
    case ScalarType::kI64:
      return static_cast<double>(load<std::int64_t>(bytes, big_endian));
    case ScalarType::kU64:
      return static_cast<double>(load<std::uint64_t>(bytes, big_endian));
    case ScalarType::kF32:
      return static_cast<double>(load<float>(bytes, big_endian));
    case ScalarType::kF64:
      return load<double>(bytes, big_endian);
  }
  return 0.0;
}

// ---- PLY ----

std::optional<ScalarType> ply_type(std::string_view name) {
  if (name == "char" || name == "int8") return ScalarType::kI8;
  if (name == "uchar" || name == "uint8") return ScalarType::kU8;
  if (name == "short" || name == "int16") return ScalarType::kI16;
  if (name == "ushort" || name == "uint16") return ScalarType::kU16;
  if (name == "int" || name == "int32") return ScalarType::kI32;
  if (name == "uint" || name == "uint32") return ScalarType::kU32;
  if (name == "float" || name == "float32") return ScalarType::kF32;
  if (name == "double" || name == "float64") return ScalarType::kF64;
  return std::nullopt;
}

struct PlyProperty {
  std::string name;
  ScalarType type = ScalarType::kF32;
  bool is_list = false;
  ScalarType count_type = ScalarType::kU8;
};

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> properties;
};

enum class PlyEncoding : std::uint8_t { kAscii, kBinaryLittle, kBinaryBig };

struct PlyHeader {
  PlyEncoding encoding = PlyEncoding::kAscii;
  std::vector<PlyElement> elements;
  std::size_t body_offset = 0;
  std::size_t body_line = 0;
};

PlyHeader parse_ply_header(std::string_view text) {
  LineReader lines(text);
  const auto magic = lines.next();
  if (!magic || *magic != "ply") {
    fail("not a PLY file: the first line must be 'ply'");
  }
  PlyHeader header;
  bool have_format = false;
  std::array<std::string_view, 6> fields{};
  while (true) {
    const auto line = lines.next();
    if (!line) {
      fail("PLY header has no 'end_header'");
    }
    const std::string where = "PLY header " + line_prefix(lines.line_number());
    const std::size_t count = split_fields(*line, fields);
    if (count == 0 || fields[0] == "comment" || fields[0] == "obj_info") {
      continue;
    }
    if (fields[0] == "end_header") {
      break;
    }
    if (fields[0] == "format") {
      if (count != 3 || fields[2] != "1.0") {
        fail(where + ": expected 'format <encoding> 1.0'");
      }
      if (fields[1] == "ascii") {
        header.encoding = PlyEncoding::kAscii;
      } else if (fields[1] == "binary_little_endian") {
        header.encoding = PlyEncoding::kBinaryLittle;
      } else if (fields[1] == "binary_big_endian") {
        header.encoding = PlyEncoding::kBinaryBig;
      } else {
        fail(where + ": unknown encoding '" + std::string(fields[1]) + "'");
      }
      have_format = true;
    } else if (fields[0] == "element") {
      if (count != 3) {
        fail(where + ": expected 'element <name> <count>'");
      }
      header.elements.push_back(
          PlyElement{std::string(fields[1]), parse_count(fields[2], where), {}});
    } else if (fields[0] == "property") {
      if (header.elements.empty()) {
        fail(where + ": property before any element");
      }
      PlyProperty property;
      if (count == 5 && fields[1] == "list") {
        const auto count_type = ply_type(fields[2]);
        const auto item_type = ply_type(fields[3]);
        if (!count_type || !item_type || *count_type == ScalarType::kF32 ||
            *count_type == ScalarType::kF64) {
          fail(where + ": bad list property types");
        }
        property = PlyProperty{std::string(fields[4]), *item_type, true, *count_type};
      } else if (count == 3) {
        const auto type = ply_type(fields[1]);
        if (!type) {
          fail(where + ": unknown property type '" + std::string(fields[1]) + "'");
        }
        property = PlyProperty{std::string(fields[2]), *type, false, ScalarType::kU8};
      } else {
        fail(where + ": expected 'property <type> <name>' or 'property list <type> <type> <name>'");
      }
      header.elements.back().properties.push_back(property);
    } else {
      fail(where + ": unknown keyword '" + std::string(fields[0]) + "'");
    }
  }
  if (!have_format) {
    fail("PLY header has no 'format' line");
  }
  header.body_offset = lines.offset();
  header.body_line = lines.line_number();
  return header;
}

struct XyzIndices {
  std::size_t x = 0;
  std::size_t y = 0;
  std::size_t z = 0;
};

XyzIndices find_xyz(const PlyElement& vertex) {
  std::array<std::optional<std::size_t>, 3> found;
  for (std::size_t i = 0; i < vertex.properties.size(); ++i) {
    const PlyProperty& p = vertex.properties[i];
    for (std::size_t axis = 0; axis < 3; ++axis) {
      if (p.name == std::string(1, static_cast<char>('x' + axis))) {
        if (p.is_list) {
          fail("PLY vertex property '" + p.name + "' is a list");
        }
        found[axis] = i;
      }
    }
  }
  if (!found[0] || !found[1] || !found[2]) {
    fail("PLY vertex element lacks an x, y or z property");
  }
  return {*found[0], *found[1], *found[2]};
}

void read_ply_ascii(std::string_view text, const PlyHeader& header, PointSink& sink) {
  LineReader lines(text.substr(header.body_offset));
  std::vector<std::string_view> fields(256);
  for (const PlyElement& element : header.elements) {
    const bool vertex = element.name == "vertex";
    const XyzIndices xyz = vertex ? find_xyz(element) : XyzIndices{};
    for (std::uint64_t i = 0; i < element.count; ++i) {
      auto line = lines.next();
      while (line && count_fields(*line) == 0) {
        line = lines.next();
      }
      const std::size_t number = header.body_line + lines.line_number();
      if (!line) {
        fail("PLY body ends after " + std::to_string(i) + " of " + std::to_string(element.count) +
             " '" + element.name + "' lines (truncated)");
      }
      if (!vertex) {
        continue;
      }
      const std::size_t count = split_fields(*line, fields);
      // Scalars come one field each; lists as a count and that many items.
      std::array<double, 3> values{};
      std::size_t field = 0;
      for (std::size_t p = 0; p < element.properties.size(); ++p) {
        if (field >= count) {
          fail(line_prefix(number) + ": too few values for the vertex properties");
        }
        const auto value = parse_number(fields[field]);
        if (!value) {
          fail(line_prefix(number) + ": '" + std::string(fields[field]) + "' is not a number");
        }
        if (element.properties[p].is_list) {
          field += 1 + static_cast<std::size_t>(std::max(0.0, *value));
          continue;
        }
        for (std::size_t axis = 0; axis < 3; ++axis) {
          const std::size_t index = axis == 0 ? xyz.x : axis == 1 ? xyz.y : xyz.z;
          if (index == p) {
            values[axis] = *value;
          }
        }
        ++field;
      }
      sink.add(values[0], values[1], values[2]);
    }
  }
}

void read_ply_binary(std::span<const std::uint8_t> body, const PlyHeader& header, PointSink& sink,
                     PointCloud& cloud) {
  const bool big = header.encoding == PlyEncoding::kBinaryBig;
  std::size_t at = 0;
  const auto need = [&](std::size_t bytes, const PlyElement& element, std::uint64_t i) {
    if (body.size() - at < bytes) {
      fail("PLY body ends in '" + element.name + "' " + std::to_string(i) + " of " +
           std::to_string(element.count) + " (truncated)");
    }
  };
  for (const PlyElement& element : header.elements) {
    const bool vertex = element.name == "vertex";
    const XyzIndices xyz = vertex ? find_xyz(element) : XyzIndices{};
    const bool all_scalar = std::none_of(element.properties.begin(), element.properties.end(),
                                         [](const PlyProperty& p) { return p.is_list; });
    std::size_t record = 0;
    for (const PlyProperty& p : element.properties) {
      record += p.is_list ? 0 : scalar_size(p.type);
    }
    if (!vertex && all_scalar) {
      if (element.count > (body.size() - at) / std::max<std::size_t>(record, 1)) {
        fail("PLY body ends in '" + element.name + "' (truncated)");
      }
      at += static_cast<std::size_t>(element.count) * record;
      continue;
    }
    if (vertex && all_scalar) {
      cloud.points_m.reserve(static_cast<std::size_t>(std::min<std::uint64_t>(
          element.count, (body.size() - at) / std::max<std::size_t>(record, 1))));
    }
    for (std::uint64_t i = 0; i < element.count; ++i) {
      std::array<double, 3> values{};
      for (std::size_t p = 0; p < element.properties.size(); ++p) {
        const PlyProperty& property = element.properties[p];
        if (property.is_list) {
          need(scalar_size(property.count_type), element, i);
          const double items = load_scalar(body.data() + at, property.count_type, big);
          at += scalar_size(property.count_type);
          if (items < 0) {
            fail("PLY list with a negative count in '" + element.name + "'");
          }
          const std::size_t bytes = static_cast<std::size_t>(items) * scalar_size(property.type);
          need(bytes, element, i);
          at += bytes;
          continue;
        }
        need(scalar_size(property.type), element, i);
        if (vertex) {
          const double value = load_scalar(body.data() + at, property.type, big);
          values[0] = p == xyz.x ? value : values[0];
          values[1] = p == xyz.y ? value : values[1];
          values[2] = p == xyz.z ? value : values[2];
        }
        at += scalar_size(property.type);
      }
      if (vertex) {
        sink.add(values[0], values[1], values[2]);
      }
    }
  }
}

void read_ply(std::span<const std::uint8_t> bytes, PointCloud& cloud) {
  const std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  const PlyHeader header = parse_ply_header(text);
  if (std::none_of(header.elements.begin(), header.elements.end(),
                   [](const PlyElement& e) { return e.name == "vertex"; })) {
    fail("PLY file has no vertex element");
  }
  PointSink sink(cloud);
  switch (header.encoding) {
    case PlyEncoding::kAscii:
      cloud.format = "ply ascii";
      read_ply_ascii(text, header, sink);
      break;
    case PlyEncoding::kBinaryLittle:
    case PlyEncoding::kBinaryBig:
      cloud.format = header.encoding == PlyEncoding::kBinaryBig ? "ply binary_big_endian"
                                                                : "ply binary_little_endian";
      read_ply_binary(bytes.subspan(header.body_offset), header, sink, cloud);
      break;
  }
}

// ---- PCD ----

struct PcdField {
  std::string name;
  std::size_t size = 4;
  char type = 'F';
  std::size_t count = 1;
  std::size_t offset = 0;  // within a binary record
};

ScalarType pcd_scalar(const PcdField& field, const std::string& where) {
  if (field.type == 'F' && field.size == 4) return ScalarType::kF32;
  if (field.type == 'F' && field.size == 8) return ScalarType::kF64;
  if (field.type == 'I' && field.size == 1) return ScalarType::kI8;
  if (field.type == 'I' && field.size == 2) return ScalarType::kI16;
  if (field.type == 'I' && field.size == 4) return ScalarType::kI32;
  if (field.type == 'I' && field.size == 8) return ScalarType::kI64;
  if (field.type == 'U' && field.size == 1) return ScalarType::kU8;
  if (field.type == 'U' && field.size == 2) return ScalarType::kU16;
  if (field.type == 'U' && field.size == 4) return ScalarType::kU32;
  if (field.type == 'U' && field.size == 8) return ScalarType::kU64;
  fail(where + ": field '" + field.name + "' has an unsupported TYPE/SIZE");
}

// LZF (liblzf's format, as PCL writes binary_compressed). Returns false on corrupt input.
bool lzf_decompress(std::span<const std::uint8_t> in, std::span<std::uint8_t> out) {
  std::size_t i = 0;
  std::size_t o = 0;
  while (i < in.size()) {
    const std::size_t control = in[i++];
    if (control < 32) {  // a literal run of control + 1 bytes
      const std::size_t length = control + 1;
      if (i + length > in.size() || o + length > out.size()) {
        return false;
      }
      std::memcpy(out.data() + o, in.data() + i, length);
      i += length;
      o += length;
      continue;
    }
    std::size_t length = control >> 5;  // a back reference
    if (length == 7) {
      if (i >= in.size()) {
        return false;
      }
      length += in[i++];
    }
    if (i >= in.size()) {
      return false;
    }
    const std::size_t distance = ((control & 0x1f) << 8) + in[i++] + 1;
    length += 2;
    if (distance > o || o + length > out.size()) {
      return false;
    }
    for (std::size_t k = 0; k < length; ++k, ++o) {
      out[o] = out[o - distance];
    }
  }
  return o == out.size();
}

void read_pcd(std::span<const std::uint8_t> bytes, PointCloud& cloud) {
  const std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  LineReader lines(text);
  std::vector<PcdField> fields;
  std::uint64_t points = 0;
  std::uint64_t width = 0;
  std::uint64_t height = 1;
  bool have_points = false;
  std::string data;
  std::vector<std::string_view> tokens(1024);
  while (data.empty()) {
    const auto line = lines.next();
    if (!line) {
      fail("PCD header has no DATA line");
    }
    const std::string where = "PCD header " + line_prefix(lines.line_number());
    const std::size_t count = split_fields(*line, tokens);
    if (count == 0 || tokens[0].front() == '#') {
      continue;
    }
    const std::string_view key = tokens[0];
    const auto values = std::span(tokens).subspan(1, count - 1);
    if (key == "VERSION" || key == "VIEWPOINT") {
      continue;
    }
    if (key == "FIELDS") {
      fields.clear();
      for (const std::string_view name : values) {
        fields.push_back(PcdField{std::string(name)});
      }
    } else if (key == "SIZE" || key == "TYPE" || key == "COUNT") {
      if (values.size() != fields.size()) {
        fail(where + ": " + std::string(key) + " must list one value per field");
      }
      for (std::size_t i = 0; i < values.size(); ++i) {
        if (key == "TYPE") {
          if (values[i].size() != 1 ||
              std::string_view("FIU").find(values[i][0]) == std::string_view::npos) {
            fail(where + ": TYPE must be F, I or U");
          }
          fields[i].type = values[i][0];
        } else {
          const std::uint64_t value = parse_count(values[i], where);
          if (value == 0 || value > 1 << 16) {
            fail(where + ": " + std::string(key) + " out of range");
          }
          (key == "SIZE" ? fields[i].size : fields[i].count) = static_cast<std::size_t>(value);
        }
      }
    } else if (key == "WIDTH" || key == "HEIGHT" || key == "POINTS") {
      if (values.size() != 1) {
        fail(where + ": " + std::string(key) + " takes one value");
      }
      const std::uint64_t value = parse_count(values[0], where);
      if (key == "WIDTH") {
        width = value;
      } else if (key == "HEIGHT") {
        height = value;
      } else {
        points = value;
        have_points = true;
      }
    } else if (key == "DATA") {
      if (values.size() != 1) {
        fail(where + ": DATA takes one value");
      }
      data = std::string(values[0]);
    } else {
      fail(where + ": unknown keyword '" + std::string(key) + "'");
    }
  }
  if (lines.line_number() == 0 || fields.empty()) {
    fail("PCD header has no FIELDS");
  }
  if (!have_points) {
    points = width * height;
  }
  std::array<std::optional<std::size_t>, 3> xyz;
  std::size_t record = 0;
  std::size_t values_per_point = 0;
  for (std::size_t i = 0; i < fields.size(); ++i) {
    fields[i].offset = record;
    record += fields[i].size * fields[i].count;
    for (std::size_t axis = 0; axis < 3; ++axis) {
      if (fields[i].name == std::string(1, static_cast<char>('x' + axis))) {
        xyz[axis] = i;
      }
    }
    values_per_point += fields[i].count;
  }
  if (!xyz[0] || !xyz[1] || !xyz[2]) {
    fail("PCD file has no x, y and z fields");
  }
  const std::string where = "PCD";
  const std::array<ScalarType, 3> types = {pcd_scalar(fields[*xyz[0]], where),
                                           pcd_scalar(fields[*xyz[1]], where),
                                           pcd_scalar(fields[*xyz[2]], where)};
  PointSink sink(cloud);
  const std::span<const std::uint8_t> body = bytes.subspan(lines.offset());
  if (data == "ascii") {
    cloud.format = "pcd ascii";
    // The value index of each of x, y, z on a line (fields may have COUNT > 1).
    std::array<std::size_t, 3> column{};
    std::size_t index = 0;
    for (std::size_t i = 0; i < fields.size(); ++i) {
      for (std::size_t axis = 0; axis < 3; ++axis) {
        if (*xyz[axis] == i) {
          column[axis] = index;
        }
      }
      index += fields[i].count;
    }
    const std::size_t header_lines = lines.line_number();
    std::uint64_t read = 0;
    while (read < points) {
      const auto line = lines.next();
      if (!line) {
        fail("PCD body ends after " + std::to_string(read) + " of " + std::to_string(points) +
             " points (truncated)");
      }
      if (count_fields(*line) == 0) {
        continue;
      }
      const std::size_t count = split_fields(*line, tokens);
      if (count < values_per_point) {
        fail(line_prefix(lines.line_number()) + ": expected " + std::to_string(values_per_point) +
             " values, found " + std::to_string(count));
      }
      std::array<double, 3> v{};
      for (std::size_t axis = 0; axis < 3; ++axis) {
        const auto value = parse_number(tokens[column[axis]]);
        if (!value) {
          fail(line_prefix(lines.line_number()) + ": '" + std::string(tokens[column[axis]]) +
               "' is not a number");
        }
        v[axis] = *value;
      }
      sink.add(v[0], v[1], v[2]);
      ++read;
    }
    static_cast<void>(header_lines);
    return;
  }
  if (data == "binary") {
    cloud.format = "pcd binary";
    if (points > body.size() / record) {
      fail("PCD body holds " + std::to_string(body.size() / record) + " of " +
           std::to_string(points) + " points (truncated)");
    }
    cloud.points_m.reserve(static_cast<std::size_t>(points));
    for (std::uint64_t i = 0; i < points; ++i) {
      const std::uint8_t* p = body.data() + static_cast<std::size_t>(i) * record;
      sink.add(load_scalar(p + fields[*xyz[0]].offset, types[0], false),
               load_scalar(p + fields[*xyz[1]].offset, types[1], false),
               load_scalar(p + fields[*xyz[2]].offset, types[2], false));
    }
    return;
  }
  if (data == "binary_compressed") {
    cloud.format = "pcd binary_compressed";
    if (body.size() < 8) {
      fail("PCD binary_compressed body is shorter than its 8-byte size header (truncated)");
    }
    const auto compressed = load<std::uint32_t>(body.data(), false);
    const auto uncompressed = load<std::uint32_t>(body.data() + 4, false);
    if (compressed > body.size() - 8) {
      fail("PCD binary_compressed body holds " + std::to_string(body.size() - 8) + " of " +
           std::to_string(compressed) + " compressed bytes (truncated)");
    }
    if (points > 0 && (uncompressed / record != points || uncompressed % record != 0)) {
      fail("PCD binary_compressed size " + std::to_string(uncompressed) + " does not hold " +
           std::to_string(points) + " points");
    }
    // LZF gives at most 88 bytes for 3 (a back reference of 264 bytes): a size beyond that
    // is a lie the file tells, and is not allocated.
    constexpr std::uint64_t kMaxLzfRatio = 88;
    if (uncompressed > kMaxLzfRatio * std::uint64_t{compressed}) {
      fail("PCD binary_compressed size " + std::to_string(uncompressed) + " cannot come from " +
           std::to_string(compressed) + " compressed bytes (corrupt)");
    }
    std::vector<std::uint8_t> raw(uncompressed);
    if (!lzf_decompress(body.subspan(8, compressed), raw)) {
      fail("PCD binary_compressed data is corrupt (LZF)");
    }
    // Column-major: all values of the first field, then the second's ...
    cloud.points_m.reserve(static_cast<std::size_t>(points));
    for (std::uint64_t i = 0; i < points; ++i) {
      std::array<double, 3> v{};
      for (std::size_t axis = 0; axis < 3; ++axis) {
        const PcdField& f = fields[*xyz[axis]];
        const std::size_t column_start = f.offset * static_cast<std::size_t>(points);
        v[axis] =
            load_scalar(raw.data() + column_start + static_cast<std::size_t>(i) * f.size * f.count,
                        types[axis], false);
      }
      sink.add(v[0], v[1], v[2]);
    }
    return;
  }
  fail("PCD DATA must be ascii, binary or binary_compressed, not '" + data + "'");
}

// ---- XYZ text, 3DTK .3d, KITTI .bin ----

void read_text_xyz(std::span<const std::uint8_t> bytes, PointCloud& cloud, bool uos) {
  const std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  LineReader lines(text);
  PointSink sink(cloud);
  cloud.format = uos ? "3dtk uos" : "xyz";
  std::array<std::string_view, 3> fields{};
  while (const auto line = lines.next()) {
    const std::size_t first = line->find_first_not_of(" \t,");
    if (first == std::string_view::npos || (*line)[first] == '#' || (*line)[first] == '/') {
      continue;  // blank, or a comment
    }
    if (uos && lines.line_number() == 1 && line->find('x') != std::string_view::npos) {
      continue;  // older 3DTK files start with a "360 x 225" grid size
    }
    if (split_fields(*line, fields) < 3) {
      fail(line_prefix(lines.line_number()) + ": expected at least three numbers (x y z)");
    }
    std::array<double, 3> v{};
    for (std::size_t axis = 0; axis < 3; ++axis) {
      const auto value = parse_number(fields[axis]);
      if (!value) {
        fail(line_prefix(lines.line_number()) + ": '" + std::string(fields[axis]) +
             "' is not a number");
      }
      v[axis] = *value;
    }
    if (!uos) {
      sink.add(v[0], v[1], v[2]);
      continue;
    }
    // 3DTK: centimetres, x right, y up, z forward -> metres, x forward, y left, z up.
    const Eigen::Vector3d p(v[2] / 100.0, -v[0] / 100.0, v[1] / 100.0);
    if (p.allFinite() && p.norm() >= kUosNoReturnRangeM) {
      ++cloud.skipped_no_return;
      continue;
    }
    sink.add(p.x(), p.y(), p.z());
  }
}

void read_kitti_bin(std::span<const std::uint8_t> bytes, PointCloud& cloud) {
  constexpr std::size_t kRecord = 16;  // float32 x, y, z, reflectance
  if (bytes.size() % kRecord != 0) {
    fail("KITTI .bin size " + std::to_string(bytes.size()) +
         " is not a whole number of 16-byte points (truncated)");
  }
  cloud.format = "kitti bin";
  PointSink sink(cloud);
  cloud.points_m.reserve(bytes.size() / kRecord);
  for (std::size_t at = 0; at < bytes.size(); at += kRecord) {
    sink.add(static_cast<double>(load<float>(bytes.data() + at, false)),
             static_cast<double>(load<float>(bytes.data() + at + 4, false)),
             static_cast<double>(load<float>(bytes.data() + at + 8, false)));
  }
}

}  // namespace

CloudFormat format_from_path(const std::filesystem::path& path) {
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension == ".ply") return CloudFormat::kPly;
  if (extension == ".pcd") return CloudFormat::kPcd;
  if (extension == ".xyz" || extension == ".txt" || extension == ".asc") return CloudFormat::kXyz;
  if (extension == ".bin") return CloudFormat::kKittiBin;
  if (extension == ".3d") return CloudFormat::kUos3d;
  throw CloudFileError(path.string() + ": unknown point cloud extension '" + extension +
                       "' (expected .ply, .pcd, .xyz, .bin or .3d)");
}

PointCloud parse_point_cloud(std::span<const std::uint8_t> bytes, CloudFormat format) {
  PointCloud cloud;
  switch (format) {
    case CloudFormat::kPly:
      read_ply(bytes, cloud);
      break;
    case CloudFormat::kPcd:
      read_pcd(bytes, cloud);
      break;
    case CloudFormat::kXyz:
      read_text_xyz(bytes, cloud, false);
      break;
    case CloudFormat::kUos3d:
      read_text_xyz(bytes, cloud, true);
      break;
    case CloudFormat::kKittiBin:
      read_kitti_bin(bytes, cloud);
      break;
  }
  return cloud;
}

PointCloud read_point_cloud(const std::filesystem::path& path, std::size_t max_bytes) {
  const CloudFormat format = format_from_path(path);
  std::string bytes;
  try {
    bytes = read_whole_file(path, max_bytes);
  } catch (const FileError& error) {
    throw CloudFileError(error.what());
  }
  try {
    return parse_point_cloud(std::span<const std::uint8_t>(
                                 reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()),
                             format);
  } catch (const CloudFileError& error) {
    throw CloudFileError(path.string() + ": " + error.what());
  }
}

void write_ply(const std::filesystem::path& path, std::span<const Eigen::Vector3f> points_m,
               const Eigen::Vector3d& origin_m) {
  std::ostringstream file(std::ios::binary);
  // Coordinates beyond float's millimetres go in as doubles with the origin added back.
  const bool doubles = origin_m != Eigen::Vector3d::Zero();
  const char* type = doubles ? "double" : "float";
  file << "ply\nformat binary_little_endian 1.0\ncomment written by blockmap\nelement vertex "
       << points_m.size() << "\nproperty " << type << " x\nproperty " << type << " y\nproperty "
       << type << " z\nend_header\n";
  std::vector<std::uint8_t> record(doubles ? 24 : 12);
  const auto put = [&](std::size_t at, auto value) {
    auto raw = std::bit_cast<std::array<std::uint8_t, sizeof(value)>>(value);
    if (std::endian::native == std::endian::big) {
      std::reverse(raw.begin(), raw.end());
    }
    std::memcpy(record.data() + at, raw.data(), raw.size());
  };
  for (const Eigen::Vector3f& p : points_m) {
    for (Eigen::Index axis = 0; axis < 3; ++axis) {
      if (doubles) {
        put(static_cast<std::size_t>(axis) * 8, static_cast<double>(p[axis]) + origin_m[axis]);
      } else {
        put(static_cast<std::size_t>(axis) * 4, p[axis]);
      }
    }
    file.write(reinterpret_cast<const char*>(record.data()),
               static_cast<std::streamsize>(record.size()));
  }
  if (std::string problem = write_whole_file(path, file.view()); !problem.empty()) {
    throw CloudFileError(problem);
  }
}

}  // namespace blockmap::hal::cloud
