#include "fruit_text.h"

#include <cmath>
#include <cstdio>

namespace fruit_shape_completion {

namespace {
nlohmann::json vec3(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
}  // namespace

nlohmann::json fruitJson(const FruitEstimate& f) {
  const Superellipsoid& s = f.shape;
  return {{"id", f.id},
          {"n_points", f.n_points},
          {"center", vec3(s.t)},
          {"a", s.a},
          {"b", s.b},
          {"c", s.c},
          {"e1", s.e1},
          {"e2", s.e2},
          {"rpy", vec3(s.rpy)},
          {"volume_m3", f.volume},
          {"volume_ci90_m3", f.accepted ? nlohmann::json{f.volume_lo, f.volume_hi} : nlohmann::json()},
          // the true centre lies within this distance of "center" in 90 % of such fits
          {"center_r90_m", f.accepted ? nlohmann::json(f.center_r90) : nlohmann::json()},
          // the share of the fitted surface its points cover, which the interval is made from
          {"seen_share", f.accepted ? nlohmann::json(f.seen_share) : nlohmann::json()},
          // how far the points alone pin the size down, which the interval is also made from
          {"log_volume_spread",
           f.accepted && std::isfinite(f.log_volume_spread) ? nlohmann::json(f.log_volume_spread) : nlohmann::json()},
          // the shortest axis rests on min_axis: sized by the bound, not the points (a patch of a
          // larger fruit, or a fruit smaller than the bound); the interval reaches far above
          {"size_at_bound", f.size_at_bound},
          {"bbox_volume_m3", f.bbox_volume},
          {"converged", f.converged},
          {"accepted", f.accepted},
          {"rejected_reason", f.accepted ? nlohmann::json() : nlohmann::json(f.reason)},
          {"rms_m", f.rms},
          {"iterations", f.iterations},
          {"fit_ms", f.fit_seconds * 1000.0},
          {"missing_surface_points", f.missing_surface.size()}};
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
