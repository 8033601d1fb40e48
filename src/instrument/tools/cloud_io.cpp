#include <fruit_shape_completion/instrument/cloud_io.h>

#include <pcl/PCLPointCloud2.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/io/pcd_io.h>
#include <pcl/common/io.h>
#include <pcl/io/ply_io.h>
#include <pcl/filters/voxel_grid.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <new>
#include <sstream>
#include <stdexcept>

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

std::uint64_t fileSize(const std::string& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  return in ? static_cast<std::uint64_t>(in.tellg()) : 0;
}

// The x, y, z of every point (float or double fields), non-finite ones included (the
// pipeline counts them). PCL's own conversion to PointXYZ takes float fields only.
CloudFile pointsOf(const pcl::PCLPointCloud2& blob, const std::string& path) {
  const pcl::PCLPointField* field[3] = {nullptr, nullptr, nullptr};
  for (const auto& f : blob.fields)
    for (int k = 0; k < 3; ++k)
      if (f.name == std::string(1, static_cast<char>('x' + k))) field[k] = &f;
  for (const auto* f : field) {
    if (f == nullptr) return fail(path, "the cloud has no x, y, z fields");
    const int size = f->datatype == pcl::PCLPointField::FLOAT32 ? 4 : f->datatype == pcl::PCLPointField::FLOAT64 ? 8 : 0;
    if (size == 0) return fail(path, "x, y, z must be float or double fields");
    if (f->offset + size > blob.point_step) return fail(path, "a field lies outside the point");
  }
  const std::size_t n = static_cast<std::size_t>(blob.width) * blob.height;
  if (blob.data.size() < n * blob.point_step) return fail(path, "truncated point data");
  CloudFile out;
  out.points.resize(n);
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      const std::uint8_t* at = &blob.data[i * blob.point_step + field[k]->offset];
      if (field[k]->datatype == pcl::PCLPointField::FLOAT32) {
        float v;
        std::memcpy(&v, at, 4);
        out.points[i][k] = v;
      } else {
        std::memcpy(&out.points[i][k], at, 8);
      }
    }
  return out;
}

// A whole token that is a number (strtod's syntax: nan and inf included).
bool parseNumber(const std::string& token, double* value) {
  char* end = nullptr;
  *value = std::strtod(token.c_str(), &end);
  return end != token.c_str() && *end == '\0';
}

struct PcdHeader {
  std::vector<std::string> fields, types;
  std::vector<std::uint64_t> sizes, counts;
  std::string version, data;
  std::uint64_t width = 1, height = 1, points = 0;
  bool has_width = false, has_points = false;
};

// Reads the header's lines up to DATA; "" or what is wrong with them.
std::string readPcdHeader(std::istream& in, PcdHeader* h) {
  // A value line is numbers to its end: PCL reads "COUNT =2" or "HEIGHT 11VIEWPOINT ..." its own
  // way (a field dropped, a width of zero) and then allocated terabytes.
  auto numbers = [](std::istringstream& ls, std::vector<std::uint64_t>* out) {
    long double v;
    while (ls >> v) {
      if (!(v >= 0 && v <= 1e6)) return false;
      out->push_back(static_cast<std::uint64_t>(v));
    }
    return ls.eof();
  };
  auto rest_empty = [](std::istringstream& ls) { return (ls >> std::ws).eof(); };
  std::string line;
  while (h->data.empty() && std::getline(in, line)) {
    // The header is text; PCL's parser misreads control bytes in it (a NUL inside a key made
    // its reader crash on an otherwise sound file).
    for (unsigned char c : line)
      if ((c < 0x20 && c != '\t' && c != '\r') || c >= 0x7f) return "malformed PCD header: a byte that is not text";
    std::istringstream ls(line);
    std::string key, word;
    ls >> key;
    long double v = 0;
    bool ok = true;
    if (key == "FIELDS") while (ls >> word) h->fields.push_back(word);
    else if (key == "TYPE") while (ls >> word) h->types.push_back(word);
    else if (key == "SIZE") ok = numbers(ls, &h->sizes);
    else if (key == "COUNT") ok = numbers(ls, &h->counts);
    else if (key == "WIDTH" || key == "HEIGHT" || key == "POINTS") {
      ok = (ls >> v) && v >= 0 && v <= 1e12 && rest_empty(ls);
      (key == "WIDTH" ? h->width : key == "HEIGHT" ? h->height : h->points) = ok ? static_cast<std::uint64_t>(v) : 0;
      h->has_points = h->has_points || key == "POINTS";
      h->has_width = h->has_width || key == "WIDTH";
    } else if (key == "DATA") {
      ls >> h->data;
    } else if (key == "VERSION") {
      ls >> h->version;
    } else if (!key.empty() && key[0] != '#' && key != "VIEWPOINT") {
      // PCL ignores what it does not know, and then reads such files wrongly (a misspelt
      // VERSION line made it crash): a version 0.7 header has these keys only.
      return "malformed PCD header: unknown line '" + line.substr(0, 40) + "'";
    }
    if (!ok) return "malformed PCD header: bad " + key + " (counts up to 1e6, sizes up to 1e12)";
  }
  return "";
}

// The header's fields against each other; "" or what is wrong.
std::string checkPcdFields(PcdHeader* h) {
  if (h->data.empty()) return "malformed PCD header: no DATA line";
  if (h->version != "0.7" && h->version != ".7") return "malformed PCD header: VERSION 0.7 expected";
  // PCL's reader trusts these to agree (a compressed file without fields crashes it).
  const std::size_t n = h->fields.size();
  if (n == 0 || h->sizes.size() != n || h->types.size() != n || (!h->counts.empty() && h->counts.size() != n))
    return "malformed PCD header: FIELDS, SIZE, TYPE and COUNT must list the same number of fields";
  for (const char* axis : {"x", "y", "z"})
    if (std::find(h->fields.begin(), h->fields.end(), axis) == h->fields.end()) return "the cloud has no x, y, z fields";
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint64_t size = h->sizes[k];
    if (h->types[k].size() != 1 || std::string("FIU").find(h->types[k][0]) == std::string::npos ||
        (size != 1 && size != 2 && size != 4 && size != 8) || (!h->counts.empty() && h->counts[k] == 0))
      return "malformed PCD header: field '" + h->fields[k] + "' has a bad TYPE, SIZE or COUNT";
  }
  if (!h->has_width) return "malformed PCD header: no WIDTH line";
  if (!h->has_points) h->points = h->width * h->height;
  if (h->points != h->width * h->height) return "malformed PCD header: POINTS differs from WIDTH x HEIGHT";
  return "";
}

// PCL's ascii reader trusts every line to hold the header's values (a line of control bytes
// made it crash): each is checked here, one point per line.
std::string checkPcdAsciiPoints(std::istream& in, std::uint64_t values, std::uint64_t points) {
  std::string line, token;
  std::uint64_t lines = 0;
  double number;
  while (std::getline(in, line)) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    std::istringstream ls(line);
    std::uint64_t n = 0;
    for (; ls >> token; ++n)
      if (!parseNumber(token, &number))
        return "point line " + std::to_string(lines + 1) + " holds something that is not a number";
    if (n != values)
      return "point line " + std::to_string(lines + 1) + " has " + std::to_string(n) + " values, the header " +
             std::to_string(values);
    if (++lines > points) break;
  }
  if (lines != points)
    return "the header promises " + std::to_string(points) + " points, the file holds " + std::to_string(lines);
  return "";
}

// PCL's readers size their buffers from the header (and its point size is 32 bits): the
// header is checked against the file first, so a lying one is refused instead of allocating
// what it claims.
std::string checkPcdHeader(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  PcdHeader h;
  std::string problem = readPcdHeader(in, &h);
  if (problem.empty()) problem = checkPcdFields(&h);
  if (!problem.empty()) return problem;
  std::uint64_t point_step = 0, values = 0;
  for (std::size_t k = 0; k < h.sizes.size(); ++k) {
    const std::uint64_t count = k < h.counts.size() ? h.counts[k] : 1;
    point_step += h.sizes[k] * count;
    values += count;
  }
  if (point_step > 65536) return "malformed PCD header: points of more than 64 KiB";
  const std::uint64_t data_at = static_cast<std::uint64_t>(in.tellg()), size = fileSize(path);
  if (h.data == "ascii") {
    if (h.points > size) return "more points in the header than the file can hold";
    return checkPcdAsciiPoints(in, values, h.points);
  }
  if (h.data == "binary") {
    if (data_at + h.points * point_step > size)
      return "the file is shorter than its header's " + std::to_string(h.points) + " points need";
    return "";
  }
  if (h.data == "binary_compressed") {
    std::uint32_t packed[2] = {0, 0};  // compressed and uncompressed size, then the LZF stream
    if (!in.read(reinterpret_cast<char*>(packed), sizeof(packed))) return "truncated compressed data";
    if (data_at + 8 + packed[0] > size) return "the file is shorter than its compressed size";
    // LZF expands at most ~256 bytes from 3 bytes of back reference.
    if (packed[1] != h.points * point_step || std::uint64_t(packed[1]) > 100 * (std::uint64_t(packed[0]) + 1))
      return "impossible compressed sizes for the header's points";
    return "";
  }
  return "malformed PCD header: unknown DATA '" + h.data + "'";
}

CloudFile readPcd(const std::string& path) {
  const std::string problem = checkPcdHeader(path);
  if (!problem.empty()) return fail(path, problem);
  pcl::PCDReader reader;
  pcl::PCLPointCloud2 blob;
  if (reader.read(path, blob) < 0) return fail(path, "malformed PCD file");
  return pointsOf(blob, path);
}

// "0,5 0,2 0,3": whitespace-separated columns whose numbers hold a comma between digits would
// otherwise be split at the commas and read as other numbers.
bool hasDecimalComma(const std::string& line) {
  std::istringstream ls(line);
  std::string tok;
  int columns = 0;
  bool comma_inside = false;
  while (ls >> tok) {
    ++columns;
    for (std::size_t i = 1; i + 1 < tok.size(); ++i)
      if (tok[i] == ',' && std::isdigit(static_cast<unsigned char>(tok[i - 1])) &&
          std::isdigit(static_cast<unsigned char>(tok[i + 1])))
        comma_inside = true;
  }
  return columns >= 2 && comma_inside;
}

// The vertex count and storage of a PLY header, for the check before PCL reads it; "" if the
// header is usable, else what is wrong with it.
std::string checkPlyHeader(const std::string& path, std::uint64_t* count, bool* binary, std::uint64_t* vertex_bytes,
                           std::uint64_t* header_bytes) {
  std::ifstream in(path, std::ios::binary);
  std::string line, element;
  std::vector<std::string> vertex_properties;
  *count = 0;
  *binary = false;
  *vertex_bytes = 0;
  // A binary vertex's size from its properties' types: PCL allocates count x that before reading.
  auto type_bytes = [](const std::string& t) -> std::uint64_t {
    if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
    if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
    if (t == "double" || t == "float64") return 8;
    return 4;
  };
  while (std::getline(in, line) && line.rfind("end_header", 0) != 0) {
    std::istringstream ls(line);
    std::string word;
    ls >> word;
    if (word == "format") {
      ls >> word;
      *binary = word != "ascii";
    } else if (word == "element") {
      ls >> element;
      if (element == "vertex") {
        long double n = -1;
        if (!(ls >> n) || n < 0 || n > 1e15) return "malformed PLY header: bad vertex count";
        *count = static_cast<std::uint64_t>(n);
      }
    } else if (word == "property" && element == "vertex") {
      std::string type, name;
      ls >> type;
      if (type == "list") return "malformed PLY header: a list property of vertices";
      ls >> name;
      vertex_properties.push_back(name);
      *vertex_bytes += type_bytes(type);
    }
  }
  if (!in) return "malformed PLY header";
  *header_bytes = static_cast<std::uint64_t>(in.tellg());
  auto has = [&](const char* name) {
    return std::find(vertex_properties.begin(), vertex_properties.end(), name) != vertex_properties.end();
  };
  if (!has("x") || !has("y") || !has("z")) return "the cloud has no x, y, z fields";
  // PCL's reader aborts (an assertion) on colour properties other than red, green, blue in a
  // row, optionally followed by alpha.
  for (const char* prefix : {"", "diffuse_"}) {
    const std::string r = std::string(prefix) + "red", g = std::string(prefix) + "green", b = std::string(prefix) + "blue";
    const auto at = std::find(vertex_properties.begin(), vertex_properties.end(), r);
    const bool any = has(r.c_str()) || has(g.c_str()) || has(b.c_str());
    if (any && (at == vertex_properties.end() || vertex_properties.end() - at < 3 || at[1] != g || at[2] != b))
      return "malformed PLY header: colour properties must be " + r + ", " + g + ", " + b + " in a row";
  }
  if (has("alpha")) {
    const auto at = std::find(vertex_properties.begin(), vertex_properties.end(), "alpha");
    if (at - vertex_properties.begin() < 3 || at[-1] != "blue")
      return "malformed PLY header: alpha must follow red, green, blue";
  }
  return "";
}

CloudFile readPly(const std::string& path) {
  std::uint64_t count = 0, vertex_bytes = 0, header_bytes = 0;
  bool binary = false;
  const std::string problem = checkPlyHeader(path, &count, &binary, &vertex_bytes, &header_bytes);
  if (!problem.empty()) return fail(path, problem);
  // A binary vertex takes its properties' bytes, an ascii one at least 6 ("0 0 0\n").
  if (count > fileSize(path) / std::max<std::uint64_t>(1, binary ? vertex_bytes : 6))  // no product to wrap
    return fail(path, "truncated: the header's " + std::to_string(count) + " vertices cannot fit in the file");
  if (!binary) {
    // PCL's ascii reader turns a number it cannot parse into NaN: decimal commas would read as
    // a cloud of NaN points.
    std::ifstream in(path, std::ios::binary);
    in.seekg(static_cast<std::streamoff>(header_bytes));
    std::string line;
    for (int i = 0; i < 64 && std::getline(in, line); ++i)
      if (hasDecimalComma(line))
        return fail(path, "decimal commas are not supported, use '.' ('" + line.substr(0, 80) + "')");
  }
  pcl::PLYReader reader;
  pcl::PCLPointCloud2 blob;
  Eigen::Vector4f origin;
  Eigen::Quaternionf orientation;
  int version = 0;
  if (reader.read(path, blob, origin, orientation, version) < 0) return fail(path, "malformed or truncated PLY file");
  return pointsOf(blob, path);  // which checks the x, y, z fields and the data's length
}


CloudFile readText(const std::string& path) {
  std::ifstream in(path);
  if (!in) return fail(path, "cannot open file");
  CloudFile f;
  std::string line;
  long long line_no = 0;
  int column[3] = {0, 1, 2};  // x, y, z; a header line naming them moves them
  std::size_t columns = 3;    // at least this many per line
  bool first_data = true;
  while (std::getline(in, line)) {
    ++line_no;
    if (line_no == 1 && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);  // a UTF-8 byte-order mark
    const auto first = line.find_first_not_of(" \t\r,");
    if (first == std::string::npos || line[first] == '#') continue;
    if (hasDecimalComma(line)) {
      std::ostringstream os;
      os << "line " << line_no << ": decimal commas are not supported, use '.' ('" << line.substr(0, 80) << "')";
      return fail(path, os.str());
    }
    // Comma-separated, one trimmed token per field (a field may be empty: pandas' index column
    // has no name; a header's may hold blanks: "x (m)"), or separated by blanks.
    std::vector<std::string> tok;
    if (line.find(',') != std::string::npos) {
      std::istringstream ls(line);
      for (std::string t; std::getline(ls, t, ',');) {
        const auto b = t.find_first_not_of(" \t\r"), e = t.find_last_not_of(" \t\r");
        tok.push_back(b == std::string::npos ? std::string() : t.substr(b, e - b + 1));
      }
      if (!tok.empty() && tok.back().empty()) tok.pop_back();  // a trailing comma
    } else {
      std::istringstream ls(line);
      for (std::string t; ls >> t;) tok.push_back(t);
    }
    if (first_data) {
      first_data = false;
      // A header (a spreadsheet's or pandas' export) when one of the first three fields is not a
      // number (more columns may hold words: a label per point); x, y and z are the columns it names.
      double ignored;
      bool numbers = true;
      for (std::size_t c = 0; c < std::min<std::size_t>(3, tok.size()); ++c)
        numbers = numbers && (tok[c].empty() || parseNumber(tok[c], &ignored));
      if (!numbers) {
        int found = 0;
        for (std::size_t c = 0; c < tok.size(); ++c) {
          std::string name = tok[c];
          std::transform(name.begin(), name.end(), name.begin(), [](unsigned char ch) { return std::tolower(ch); });
          name.erase(std::remove(name.begin(), name.end(), '"'), name.end());
          name = name.substr(0, name.find_first_of(" ([\t"));  // "x (m)", "x [m]": the name before its unit
          for (int k = 0; k < 3; ++k)
            if (name == std::string(1, "xyz"[k])) {
              column[k] = static_cast<int>(c);
              found |= 1 << k;
            }
        }
        if (found != 7) {
          std::ostringstream os;
          os << "line " << line_no << ": expected 'x y z' numbers, or a header naming the x, y and z columns, got '"
             << line.substr(0, 80) << "'";
          return fail(path, os.str());
        }
        columns = static_cast<std::size_t>(*std::max_element(column, column + 3)) + 1;
        continue;
      }
    }
    double v[3];
    bool ok = tok.size() >= columns;
    for (int k = 0; ok && k < 3; ++k) ok = parseNumber(tok[static_cast<std::size_t>(column[k])], &v[k]);
    if (!ok) {
      std::ostringstream os;
      os << "line " << line_no << ": expected 'x y z' numbers, got '" << line.substr(0, 80) << "'";
      return fail(path, os.str());
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
  } catch (const std::exception& e) {
    return fail(path, std::string("unreadable: ") + e.what());
  }
}

PointList thinCloud(const PointList& points, double leaf) {
  PointList finite;
  finite.reserve(points.size());
  for (const auto& p : points)
    if (p.allFinite()) finite.push_back(p);
  if (!(leaf > 0.0) || finite.empty()) return finite;
  // PCL's grid returns its input unthinned once its voxel count passes the int range, and it
  // works in single precision: the cloud goes through in blocks of 512 leaves a side, each
  // relative to its own corner, so that georeferenced coordinates keep their millimetres.
  // Blocks are cut on the leaf's grid: the cubes are those of one grid over the whole cloud.
  const double block = 512.0 * leaf;
  constexpr double kFar = 1e15;  // a block index beyond this is no place on a farm
  std::map<std::array<std::int64_t, 3>, pcl::PointCloud<pcl::PointXYZ>> blocks;
  PointList out;
  for (const auto& p : finite) {
    const Eigen::Vector3d cell = (p / block).array().floor();
    if ((cell.array().abs() > kFar).any()) {
      out.push_back(p);
      continue;
    }
    const Eigen::Vector3d q = p - cell * block;
    blocks[{static_cast<std::int64_t>(cell.x()), static_cast<std::int64_t>(cell.y()), static_cast<std::int64_t>(cell.z())}]
        .push_back(pcl::PointXYZ(static_cast<float>(q.x()), static_cast<float>(q.y()), static_cast<float>(q.z())));
  }
  const float l = static_cast<float>(leaf);
  for (auto& [key, part] : blocks) {
    const Eigen::Vector3d corner = Eigen::Vector3d(key[0], key[1], key[2]) * block;
    pcl::PointCloud<pcl::PointXYZ> thinned;
    pcl::VoxelGrid<pcl::PointXYZ> grid;
    grid.setInputCloud(part.makeShared());
    grid.setLeafSize(l, l, l);
    grid.filter(thinned);
    for (const auto& q : thinned) out.push_back(corner + Eigen::Vector3d(q.x, q.y, q.z));
  }
  return out;
}

bool writePly(const std::string& path, const PointList& points,
              const std::vector<std::array<std::uint8_t, 3>>& colors, std::string* error) {
  if (!colors.empty() && colors.size() != points.size()) {
    if (error) *error = path + ": colour count differs from point count";
    return false;
  }
  if (points.empty()) {  // PCL's writer refuses an empty cloud; a view that saw nothing is still a result
    std::ofstream out(path);
    out << "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    if (!out) {
      if (error) *error = path + ": cannot write";
      return false;
    }
    return true;
  }
  pcl::PointCloud<pcl::PointXYZRGB> coloured;
  for (std::size_t i = 0; i < points.size(); ++i) {
    pcl::PointXYZRGB p;
    p.x = static_cast<float>(points[i].x());
    p.y = static_cast<float>(points[i].y());
    p.z = static_cast<float>(points[i].z());
    if (!colors.empty()) {
      p.r = colors[i][0];
      p.g = colors[i][1];
      p.b = colors[i][2];
    }
    coloured.push_back(p);
  }
  int rc = -1;
  try {
    pcl::PLYWriter writer;
    if (colors.empty()) {
      pcl::PointCloud<pcl::PointXYZ> plain;
      pcl::copyPointCloud(coloured, plain);
      rc = writer.write(path, plain, false);
    } else {
      rc = writer.write(path, coloured, false);
    }
  } catch (const std::exception& e) {
    if (error) *error = path + ": " + e.what();
    return false;
  }
  if (rc < 0) {
    if (error) *error = path + ": cannot write";
    return false;
  }
  return true;
}

}  // namespace fruit_shape_completion
