#include "fruit_report.h"

#include <cmath>
#include <cstdio>
#include <sstream>

namespace fruit_shape_completion {

std::string jsonNumber(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.9g", v);
  return buf;
}

std::string jsonString(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof(buf), "\\u%04x", c);
          out += buf;
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

namespace {
std::string vec3(const Eigen::Vector3d& v) {
  return "[" + jsonNumber(v.x()) + ", " + jsonNumber(v.y()) + ", " + jsonNumber(v.z()) + "]";
}
}  // namespace

std::string fruitJson(const FruitEstimate& f) {
  const Superellipsoid& s = f.shape;
  std::ostringstream os;
  os << "{\"id\": " << f.id << ", \"n_points\": " << f.n_points
     << ", \"center\": " << vec3(s.t) << ", \"a\": " << jsonNumber(s.a)
     << ", \"b\": " << jsonNumber(s.b) << ", \"c\": " << jsonNumber(s.c)
     << ", \"e1\": " << jsonNumber(s.e1) << ", \"e2\": " << jsonNumber(s.e2)
     << ", \"rpy\": " << vec3(s.rpy) << ", \"volume_m3\": " << jsonNumber(f.volume)
     << ", \"bbox_volume_m3\": " << jsonNumber(f.bbox_volume)
     << ", \"converged\": " << (f.converged ? "true" : "false")
     << ", \"accepted\": " << (f.accepted ? "true" : "false")
     << ", \"rejected_reason\": " << (f.accepted ? "null" : jsonString(f.reason))
     << ", \"rms_m\": " << jsonNumber(f.rms) << ", \"iterations\": " << f.iterations
     << ", \"fit_ms\": " << jsonNumber(f.fit_seconds * 1000.0)
     << ", \"missing_surface_points\": " << f.missing_surface.size() << "}";
  return os.str();
}

void printFruitTable(std::ostream& os, const std::vector<FruitEstimate>& fruits) {
  char line[256];
  std::snprintf(line, sizeof(line), "%4s %7s %28s %7s %7s %7s %5s %5s %9s %9s %7s %7s %s\n", "id",
                "points", "centre [m]", "a[cm]", "b[cm]", "c[cm]", "e1", "e2", "V[cm3]",
                "bbox[cm3]", "rms[mm]", "fit[ms]", "status");
  os << line;
  for (const auto& f : fruits) {
    const Superellipsoid& s = f.shape;
    std::snprintf(line, sizeof(line),
                  "%4d %7d (%8.4f,%8.4f,%8.4f) %7.2f %7.2f %7.2f %5.2f %5.2f %9.1f %9.1f %7.2f %7.1f %s\n",
                  f.id, f.n_points, s.t.x(), s.t.y(), s.t.z(), s.a * 100, s.b * 100, s.c * 100,
                  s.e1, s.e2, f.volume * 1e6, f.bbox_volume * 1e6, f.rms * 1000,
                  f.fit_seconds * 1000, f.accepted ? "ok" : ("rejected: " + f.reason).c_str());
    os << line;
  }
}

}  // namespace fruit_shape_completion
