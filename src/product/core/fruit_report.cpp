#include <fruit_shape_completion/fruit_report.h>

#include <fruit_shape_completion/atomic_file.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace fruit_shape_completion {

namespace {

bool endsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// The shortest text that reads back as the same double (a stamp of 1.7e9 s keeps its
// fraction; a fixed digit count either rounds it or prints 0.03 as 0.029999999999999999);
// NaN (never seen) as an empty CSV cell or JSON null.
std::string number(double v, bool json) {
  if (!std::isfinite(v)) return json ? "null" : "";
  char buf[64];
  const auto end = std::to_chars(buf, buf + sizeof(buf), v).ptr;
  return std::string(buf, end);
}

}  // namespace

const std::vector<std::string>& fruitReportColumns() {
  static const std::vector<std::string> columns = {"id", "x", "y", "z", "volume_m3", "a", "b", "c", "e1", "e2",
                                                   "roll", "pitch", "yaw", "points", "views", "first_seen",
                                                   "last_seen", "volume_ci90_lo_m3", "volume_ci90_hi_m3",
                                                   "center_r90_m"};
  return columns;
}

bool writeFruitReport(const std::string& path, const std::vector<FruitEstimate>& fruits,
                      const std::map<int, FruitSightings>& sightings, std::string* error) {
  const bool json = endsWith(path, ".json");
  if (!json && !endsWith(path, ".csv")) {
    if (error) *error = path + ": the file name must end in .csv or .json";
    return false;
  }
  std::ostringstream out;
  const auto& columns = fruitReportColumns();
  if (json) {
    out << "{\"fruits\": [";
  } else {
    for (std::size_t i = 0; i < columns.size(); ++i) out << (i ? "," : "") << columns[i];
    out << '\n';
  }
  bool first = true;
  for (const auto& f : fruits) {
    if (!f.accepted) continue;
    const auto it = sightings.find(f.id);
    const FruitSightings seen = it == sightings.end() ? FruitSightings() : it->second;
    const Superellipsoid& s = f.shape;
    const double deg = 180.0 / M_PI;  // as superellipsoid_msgs/Superellipsoid
    const std::vector<std::string> values = {
        std::to_string(f.id), number(s.t.x(), json), number(s.t.y(), json), number(s.t.z(), json),
        number(f.volume, json), number(s.a, json), number(s.b, json), number(s.c, json), number(s.e1, json),
        number(s.e2, json), number(s.rpy.x() * deg, json), number(s.rpy.y() * deg, json), number(s.rpy.z() * deg, json),
        std::to_string(f.n_points), std::to_string(f.views > 0 ? f.views : seen.views), number(seen.first_seen, json),
        number(seen.last_seen, json), number(f.volume_lo, json), number(f.volume_hi, json),
        number(f.center_r90, json)};
    if (json) {
      out << (first ? "" : ",") << "\n  {";
      for (std::size_t i = 0; i < columns.size(); ++i) out << (i ? ", " : "") << '"' << columns[i] << "\": " << values[i];
      out << '}';
    } else {
      for (std::size_t i = 0; i < values.size(); ++i) out << (i ? "," : "") << values[i];
      out << '\n';
    }
    first = false;
  }
  if (json) out << (first ? "" : "\n") << "]}\n";
  return writeFileAtomically(path, out.str(), error);
}

}  // namespace fruit_shape_completion
