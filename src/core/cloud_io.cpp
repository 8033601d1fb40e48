#include <fruit_shape_completion/cloud_io.h>

#include <algorithm>
#include <cstring>
#include <cstdint>
#include <fstream>
#include <new>
#include <stdexcept>
#include <sstream>

namespace fruit_shape_completion {

namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

std::string extensionOf(const std::string& path) {
  const auto dot = path.find_last_of('.');
  const auto slash = path.find_last_of('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  return lower(path.substr(dot + 1));
}

CloudFile fail(const std::string& path, const std::string& what) {
  CloudFile f;
  f.error = path + ": " + what;
  return f;
}

// One scalar field of a binary record (PLY vertex property or PCD field).
struct ScalarField {
  std::string name;
  int size = 0;     // bytes
  char kind = 'f';  // 'f' float, 'i' signed, 'u' unsigned
};

double decodeScalar(const unsigned char* b, const ScalarField& f, bool big_endian) {
  unsigned char buf[8] = {0};
  for (int i = 0; i < f.size; ++i) buf[i] = big_endian ? b[f.size - 1 - i] : b[i];
  if (f.kind == 'f') {
    if (f.size == 4) { float v; std::memcpy(&v, buf, 4); return v; }
    double v; std::memcpy(&v, buf, 8); return v;
  }
  if (f.kind == 'i') {
    switch (f.size) {
      case 1: { std::int8_t v; std::memcpy(&v, buf, 1); return v; }
      case 2: { std::int16_t v; std::memcpy(&v, buf, 2); return v; }
      case 4: { std::int32_t v; std::memcpy(&v, buf, 4); return v; }
      default: { std::int64_t v; std::memcpy(&v, buf, 8); return static_cast<double>(v); }
    }
  }
  switch (f.size) {
    case 1: return buf[0];
    case 2: { std::uint16_t v; std::memcpy(&v, buf, 2); return v; }
    case 4: { std::uint32_t v; std::memcpy(&v, buf, 4); return v; }
    default: { std::uint64_t v; std::memcpy(&v, buf, 8); return static_cast<double>(v); }
  }
}

// LZF decompression (the codec of PCD's binary_compressed). False on corrupt input.
bool lzfDecompress(const unsigned char* in, size_t in_len, unsigned char* out, size_t out_len) {
  size_t ip = 0, op = 0;
  while (ip < in_len) {
    const unsigned ctrl = in[ip++];
    if (ctrl < 32) {  // literal run
      const size_t len = ctrl + 1;
      if (ip + len > in_len || op + len > out_len) return false;
      std::memcpy(out + op, in + ip, len);
      ip += len;
      op += len;
    } else {  // back reference
      size_t len = ctrl >> 5;
      if (len == 7) {
        if (ip >= in_len) return false;
        len += in[ip++];
      }
      if (ip >= in_len) return false;
      const size_t back = ((ctrl & 0x1f) << 8) + in[ip++] + 1;
      len += 2;
      if (back > op || op + len > out_len) return false;
      for (size_t k = 0; k < len; ++k, ++op) out[op] = out[op - back];
    }
  }
  return op == out_len;
}

CloudFile readPcd(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail(path, "cannot open file");
  std::vector<ScalarField> fields;
  std::vector<int> counts, sizes;
  std::vector<char> types;
  long long points = -1, width = -1, height = 1;
  std::string data, line;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ls(line);
    std::string key, v;
    ls >> key;
    if (key == "FIELDS") {
      while (ls >> v) fields.push_back({v, 0, 'f'});
    } else if (key == "SIZE") {
      int n;
      while (ls >> n) sizes.push_back(n);
    } else if (key == "TYPE") {
      while (ls >> v) types.push_back(v.empty() ? '?' : v[0]);
    } else if (key == "COUNT") {
      int n;
      while (ls >> n) counts.push_back(n);
    } else if (key == "WIDTH") {
      ls >> width;
    } else if (key == "HEIGHT") {
      ls >> height;
    } else if (key == "POINTS") {
      ls >> points;
    } else if (key == "DATA") {
      ls >> data;
      break;
    } else if (key != "VERSION" && key != "VIEWPOINT") {
      return fail(path, "malformed PCD header: unknown line '" + line.substr(0, 60) + "'");
    }
  }
  if (data.empty()) return fail(path, "malformed PCD header: no DATA line");
  if (fields.empty()) return fail(path, "malformed PCD header: no FIELDS");
  if (counts.empty()) counts.assign(fields.size(), 1);
  if (sizes.size() != fields.size() || types.size() != fields.size() || counts.size() != fields.size())
    return fail(path, "malformed PCD header: FIELDS, SIZE, TYPE and COUNT differ in length");
  // Header numbers are untrusted: bound them before they size anything.
  constexpr long long kMaxPoints = 1LL << 32;
  if (width < -1 || height < 0 || width > kMaxPoints || height > kMaxPoints)
    return fail(path, "malformed PCD header: bad WIDTH or HEIGHT");
  if (points < 0 && width >= 0) {
    if (height != 0 && width > kMaxPoints / height)
      return fail(path, "malformed PCD header: implausible WIDTH x HEIGHT");
    points = width * height;
  }
  if (points < 0) return fail(path, "malformed PCD header: no POINTS or WIDTH");
  if (points > kMaxPoints) return fail(path, "malformed PCD header: implausible POINTS " + std::to_string(points));
  for (int c : counts)
    if (c > (1 << 16)) return fail(path, "malformed PCD header: implausible COUNT " + std::to_string(c));
  int ix = -1, iy = -1, iz = -1;
  size_t record = 0;
  std::vector<size_t> offset(fields.size());
  std::vector<size_t> token(fields.size());
  size_t tokens = 0;
  for (size_t i = 0; i < fields.size(); ++i) {
    ScalarField& f = fields[i];
    f.size = sizes[i];
    f.kind = types[i] == 'F' ? 'f' : types[i] == 'I' ? 'i' : types[i] == 'U' ? 'u' : '?';
    const bool ok_size = f.kind == 'f' ? (f.size == 4 || f.size == 8)
                                       : (f.size == 1 || f.size == 2 || f.size == 4 || f.size == 8);
    if (f.kind == '?' || !ok_size || counts[i] < 1)
      return fail(path, "malformed PCD header: bad SIZE/TYPE/COUNT for field '" + f.name + "'");
    offset[i] = record;
    token[i] = tokens;
    record += static_cast<size_t>(f.size) * counts[i];
    tokens += counts[i];
    if (record > (1u << 20)) return fail(path, "malformed PCD header: a point of more than 1 MiB");
    if (f.name == "x") ix = static_cast<int>(i);
    if (f.name == "y") iy = static_cast<int>(i);
    if (f.name == "z") iz = static_cast<int>(i);
  }
  if (ix < 0 || iy < 0 || iz < 0) return fail(path, "PCD file has no x, y, z fields");

  // Bytes left after the header, to refuse sizes the file cannot hold before allocating them.
  const std::streampos data_start = in.tellg();
  in.seekg(0, std::ios::end);
  const std::uint64_t remaining = data_start < 0 ? 0 : static_cast<std::uint64_t>(in.tellg() - data_start);
  in.seekg(data_start);

  CloudFile f;
  if (data == "ascii") {
    std::vector<double> vals(tokens);
    for (long long p = 0; p < points; ++p) {
      for (size_t k = 0; k < tokens; ++k) {
        std::string tok;
        char* end = nullptr;
        if (!(in >> tok) || (vals[k] = std::strtod(tok.c_str(), &end), *end != '\0')) {
          std::ostringstream os;
          os << "truncated or malformed PCD data at point " << p << " of " << points;
          return fail(path, os.str());
        }
      }
      f.points.emplace_back(vals[token[ix]], vals[token[iy]], vals[token[iz]]);
    }
  } else if (data == "binary") {
    if (static_cast<std::uint64_t>(record) * static_cast<std::uint64_t>(points) > remaining) {
      std::ostringstream os;
      os << "truncated PCD data: the header says " << points << " points of " << record << " bytes, the file holds "
         << remaining << " bytes";
      return fail(path, os.str());
    }
    f.points.reserve(static_cast<size_t>(points));
    std::vector<unsigned char> buf(record);
    for (long long p = 0; p < points; ++p) {
      if (!in.read(reinterpret_cast<char*>(buf.data()), record)) {
        std::ostringstream os;
        os << "truncated PCD data at point " << p << " of " << points;
        return fail(path, os.str());
      }
      f.points.emplace_back(decodeScalar(&buf[offset[ix]], fields[ix], false),
                            decodeScalar(&buf[offset[iy]], fields[iy], false),
                            decodeScalar(&buf[offset[iz]], fields[iz], false));
    }
  } else if (data == "binary_compressed") {
    std::uint32_t sizes_hdr[2];
    if (!in.read(reinterpret_cast<char*>(sizes_hdr), sizeof(sizes_hdr)))
      return fail(path, "truncated PCD compressed data header");
    const std::uint64_t expected = static_cast<std::uint64_t>(record) * points;
    if (sizes_hdr[1] != expected)
      return fail(path, "malformed PCD: compressed payload size does not match the header");
    if (sizes_hdr[0] > remaining - std::min<std::uint64_t>(remaining, sizeof(sizes_hdr)))
      return fail(path, "truncated PCD compressed data: the file is shorter than its compressed size");
    // LZF expands at most ~90x (a 3-byte back reference copies up to 264 bytes).
    if (sizes_hdr[1] > 100ull * sizes_hdr[0] + 64)
      return fail(path, "malformed PCD: uncompressed size impossible for its compressed size");
    std::vector<unsigned char> packed(sizes_hdr[0]), raw(sizes_hdr[1]);
    if (!in.read(reinterpret_cast<char*>(packed.data()), packed.size()))
      return fail(path, "truncated PCD compressed data");
    if (!lzfDecompress(packed.data(), packed.size(), raw.data(), raw.size()))
      return fail(path, "corrupt PCD compressed data");
    // Decompressed data is stored field by field: all x, then all y, ...
    auto at = [&](int fi, long long p) {
      return &raw[offset[fi] * points + static_cast<size_t>(p) * sizes[fi] * counts[fi]];
    };
    for (long long p = 0; p < points; ++p)
      f.points.emplace_back(decodeScalar(at(ix, p), fields[ix], false),
                            decodeScalar(at(iy, p), fields[iy], false),
                            decodeScalar(at(iz, p), fields[iz], false));
  } else {
    return fail(path, "malformed PCD header: unknown DATA '" + data + "'");
  }
  return f;
}

bool plyType(const std::string& t, ScalarField& p) {
  static const struct { const char* name; int size; char kind; } types[] = {
      {"char", 1, 'i'},   {"int8", 1, 'i'},    {"uchar", 1, 'u'},   {"uint8", 1, 'u'},
      {"short", 2, 'i'},  {"int16", 2, 'i'},   {"ushort", 2, 'u'},  {"uint16", 2, 'u'},
      {"int", 4, 'i'},    {"int32", 4, 'i'},   {"uint", 4, 'u'},    {"uint32", 4, 'u'},
      {"float", 4, 'f'},  {"float32", 4, 'f'}, {"double", 8, 'f'},  {"float64", 8, 'f'}};
  for (const auto& ty : types)
    if (t == ty.name) {
      p.size = ty.size;
      p.kind = ty.kind;
      return true;
    }
  return false;
}

CloudFile readPly(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail(path, "cannot open file");
  std::string line;
  if (!std::getline(in, line) || line.rfind("ply", 0) != 0) return fail(path, "not a PLY file (no 'ply' magic)");
  std::string format;
  long long n_vertices = -1;
  bool in_vertex = false, seen_other_element = false;
  std::vector<ScalarField> props;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream ls(line);
    std::string word;
    ls >> word;
    if (word == "end_header") break;
    if (word == "format") {
      ls >> format;
    } else if (word == "element") {
      std::string name;
      long long count = -1;
      ls >> name >> count;
      in_vertex = name == "vertex";
      if (in_vertex) {
        if (seen_other_element) return fail(path, "unsupported PLY: 'vertex' is not the first element");
        if (count < 0) return fail(path, "malformed PLY header: bad vertex count");
        n_vertices = count;
      } else {
        seen_other_element = true;
      }
    } else if (word == "property" && in_vertex) {
      std::string type, name;
      ls >> type;
      if (type == "list") return fail(path, "unsupported PLY: list property in the vertex element");
      ls >> name;
      ScalarField p;
      if (!plyType(type, p)) return fail(path, "malformed PLY header: unknown property type '" + type + "'");
      p.name = name;
      props.push_back(p);
    }
  }
  if (line != "end_header") return fail(path, "malformed PLY header: no end_header");
  if (n_vertices < 0) return fail(path, "malformed PLY header: no vertex element");
  int ix = -1, iy = -1, iz = -1;
  size_t stride = 0;
  for (size_t i = 0; i < props.size(); ++i) {
    if (props[i].name == "x") ix = static_cast<int>(i);
    if (props[i].name == "y") iy = static_cast<int>(i);
    if (props[i].name == "z") iz = static_cast<int>(i);
    stride += props[i].size;
  }
  if (ix < 0 || iy < 0 || iz < 0) return fail(path, "PLY vertices have no x, y, z properties");

  CloudFile f;
  if (format == "ascii") {
    std::vector<double> values(props.size());
    for (long long v = 0; v < n_vertices; ++v) {
      for (auto& val : values)
        if (!(in >> val)) {
          std::ostringstream os;
          os << "truncated or malformed PLY data at vertex " << v << " of " << n_vertices;
          return fail(path, os.str());
        }
      f.points.emplace_back(values[ix], values[iy], values[iz]);
    }
  } else if (format == "binary_little_endian" || format == "binary_big_endian") {
    const bool big = format == "binary_big_endian";
    std::vector<unsigned char> buf(stride);
    std::vector<size_t> offset(props.size(), 0);
    for (size_t i = 1; i < props.size(); ++i) offset[i] = offset[i - 1] + props[i - 1].size;
    for (long long v = 0; v < n_vertices; ++v) {
      if (!in.read(reinterpret_cast<char*>(buf.data()), stride)) {
        std::ostringstream os;
        os << "truncated PLY data at vertex " << v << " of " << n_vertices;
        return fail(path, os.str());
      }
      f.points.emplace_back(decodeScalar(&buf[offset[ix]], props[ix], big),
                            decodeScalar(&buf[offset[iy]], props[iy], big),
                            decodeScalar(&buf[offset[iz]], props[iz], big));
    }
  } else {
    return fail(path, "malformed PLY header: unknown format '" + format + "'");
  }
  return f;
}

CloudFile readText(const std::string& path) {
  std::ifstream in(path);
  if (!in) return fail(path, "cannot open file");
  CloudFile f;
  std::string line;
  long long line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const auto first = line.find_first_not_of(" \t\r,");
    if (first == std::string::npos || line[first] == '#') continue;
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream ls(line);
    std::string tok[3];
    double v[3];
    for (int k = 0; k < 3; ++k) {
      char* end = nullptr;
      if (!(ls >> tok[k]) || (v[k] = std::strtod(tok[k].c_str(), &end), *end != '\0')) {
        std::ostringstream os;
        os << "line " << line_no << ": expected 'x y z' numbers, got '" << line.substr(0, 80) << "'";
        return fail(path, os.str());
      }
    }
    f.points.emplace_back(v[0], v[1], v[2]);
  }
  if (in.bad()) return fail(path, "read error");
  return f;
}

}  // namespace

CloudFile readPointCloud(const std::string& path) {
  {
    std::ifstream probe(path);
    if (!probe) return fail(path, "cannot open file");
  }
  const std::string ext = extensionOf(path);
  try {
    if (ext == "pcd") return readPcd(path);
    if (ext == "ply") return readPly(path);
    return readText(path);
  } catch (const std::bad_alloc&) {
    return fail(path, "out of memory while reading (is the file's header plausible?)");
  } catch (const std::length_error&) {
    return fail(path, "the file's sizes are beyond what can be allocated");
  }
}

bool writePly(const std::string& path, const PointList& points,
              const std::vector<std::array<std::uint8_t, 3>>& colors, std::string* error) {
  const bool with_color = !colors.empty();
  if (with_color && colors.size() != points.size()) {
    if (error) *error = path + ": " + "colour count differs from point count";
    return false;
  }
  std::ofstream out(path);
  if (!out) {
    if (error) *error = path + ": cannot open for writing";
    return false;
  }
  out << "ply\nformat ascii 1.0\nelement vertex " << points.size()
      << "\nproperty float x\nproperty float y\nproperty float z\n";
  if (with_color) out << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  out << "end_header\n";
  for (size_t i = 0; i < points.size(); ++i) {
    out << static_cast<float>(points[i].x()) << ' ' << static_cast<float>(points[i].y()) << ' '
        << static_cast<float>(points[i].z());
    if (with_color)
      out << ' ' << int(colors[i][0]) << ' ' << int(colors[i][1]) << ' ' << int(colors[i][2]);
    out << '\n';
  }
  if (!out) {
    if (error) *error = path + ": write error";
    return false;
  }
  return true;
}

}  // namespace fruit_shape_completion
