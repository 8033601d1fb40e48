// fit_stress: the fit's tails on many random fruits, as the pipeline (clustering, normals,
// centre prior, fit, splits) meets them in a TSDF surface cloud: superellipsoids and
// pepper-like bodies with 3 or 4 lobes, tapered, tilted, elongated, with a stem dent, 4-12 cm;
// seen by one to four views covering a quarter to all of the surface; depth noise 0.5-3 mm,
// blurred outlines (points at a view's rim dragged away from the camera, as the paper's 3 x 3
// depth blur does), 0-5 % outliers, and sometimes a touching neighbour. Per coverage bin: mean,
// 5th percentile and worst volume accuracy, centre error, fit time.
// Each view is a camera 0.3-0.5 m away (the planner's sensor range) that sees what faces it and
// is not hidden by the fruit itself (a z-buffer; a touching neighbour is scanned by its own
// camera and hides nothing), its share cut by a leaf's straight edge: a silhouette in front of
// the centre, as a camera sees a fruit. --views cap instead cuts each view's share as a cap
// around its direction, whose rim passes through the centre (the suite's first view model; over
// a quarter or half of the surface its fits err smaller than cameras'): the same
// fruits, views, noise levels, blur, strays and neighbours; the noise itself, the neighbour's
// side and the strays are drawn anew.
//   fit_stress [--fruits N] [--seed S] [--json FILE] [--views camera|cap] [--max-fit-points N]
//              [--stall-tolerance T] [--function-tolerance T] [--refit-tolerance T]
#include <fruit_shape_completion/fruit_shape_pipeline.h>
#include <fruit_shape_completion/instrument/sim/synthetic_fruit.h>
#include <fruit_shape_completion/neighbour_grid.h>

#include "command_line.h"
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <optional>
#include <unordered_map>
#include <unordered_set>

using namespace fruit_shape_completion;

namespace {

struct View {
  Eigen::Vector3d dir;  // from the fruit's centre toward the camera
  double cap;           // share of the surface the view sees (a cap around dir; with camera views, at most)
};

struct Case {
  int index = 0;
  std::string kind;  // superellipsoid, pepper
  SyntheticFruit fruit;
  double diameter = 0, volume = 0;
  std::vector<View> views;
  double noise = 0, blur = 0, outliers = 0;
  bool neighbour = false;
};

struct Outcome {
  double coverage = 0;  // share of the surface directions some view saw
  double accuracy = 0, center_mm = 0, fit_ms = 0;
  double prior_mm = 0;      // the matched fit's centre prior's distance from the true centre
  // ... and how far the prior and the fit's centre lie toward the camera (along the mean of the
  // views' directions): a half-seen fit's volume error follows its centre's depth error.
  double prior_toward_mm = 0, fit_toward_mm = 0;
  double fit_coverage = 0;  // the matched fit's own seen share (FruitEstimate::seen_share)
  double ratio = 0;         // true volume / fitted volume
  double rms = 0;           // the matched fit's RMS radial residual [m]
  double min_axis = 0;      // the matched fit's shortest semi-axis [m]
  double max_axis = 0;      // ... and its longest
  double e1 = 0, e2 = 0;    // ... and its exponents
  bool inside = false;      // the true volume lies in the fit's 90 % interval
  bool center_inside = false;  // the true centre lies within the fit's 90 % centre radius
  double center_r90_mm = 0;
  double half_width = 0;    // the interval's half-width relative to the fitted volume
  double log_volume_spread = 0;  // the matched fit's (volume_interval.h)
  bool found = false;
};

// The tool's own draws (not the library's), in a defined order: the same cases on any version
// of the package it is built against.
Eigen::Matrix3d drawRotation(std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  double q[4];
  for (double& v : q) v = g(rng);
  return Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
}

Superellipsoid drawSuperellipsoid(std::mt19937& rng, double radius, const Eigen::Matrix3d& rot) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Superellipsoid s;
  const double aspect = 1.4;
  double axes[3];
  for (double& a : axes) a = radius * std::pow(aspect, 2.0 * u(rng) - 1.0);
  s.a = axes[0], s.b = axes[1], s.c = axes[2];
  s.e1 = 0.4 + 0.45 * u(rng);
  s.e2 = 0.4 + 0.45 * u(rng);
  s.t = Eigen::Vector3d(0, 0, 0.5);
  const Eigen::Vector3d ypr = rot.eulerAngles(2, 1, 0);
  s.rpy = Eigen::Vector3d(ypr[2], ypr[1], ypr[0]);
  return s;
}

Case randomCase(int index, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Case c;
  c.index = index;
  const Eigen::Matrix3d rot = drawRotation(rng);
  const double radius = 0.02 + 0.04 * u(rng);  // 4-12 cm across
  if (u(rng) < 0.4) {
    c.kind = "superellipsoid";
    c.fruit = SyntheticFruit::fromSuperellipsoid(drawSuperellipsoid(rng, radius, rot));
  } else {
    c.kind = "pepper";
    const int lobes = u(rng) < 0.5 ? 3 : 4;
    const double elongation = 0.8 + 0.6 * u(rng);  // half height against radius
    const double lobe_depth = 0.04 + 0.14 * u(rng);
    const double taper = 0.3 * u(rng);
    c.fruit = SyntheticFruit::pepper(radius, radius * elongation, lobes, lobe_depth, taper, Eigen::Vector3d(0, 0, 0.5), rot);
  }
  c.volume = c.fruit.volume(60000);
  c.diameter = 2.0 * radius;
  // One to four views; their caps from a quarter to all of the surface, spread by up to 120 deg.
  const int n_views = 1 + static_cast<int>(4 * u(rng)) % 4;
  const Eigen::Matrix3d first = drawRotation(rng);
  const double spread = M_PI * 2.0 / 3.0 * u(rng);
  for (int v = 0; v < n_views; ++v) {
    const double angle = v == 0 ? 0.0 : spread * u(rng);
    const Eigen::Vector3d axis = drawRotation(rng).col(0);
    const Eigen::Vector3d dir = Eigen::AngleAxisd(angle, axis) * first.col(2);
    const double cap = u(rng) < 0.1 ? 1.0 : 0.25 + 0.3 * u(rng);
    c.views.push_back({dir.normalized(), cap});
  }
  c.noise = 0.0005 + 0.0025 * u(rng);
  c.blur = u(rng) < 0.5 ? 0.002 + 0.006 * u(rng) : 0.0;
  c.outliers = 0.05 * u(rng);
  c.neighbour = u(rng) < 0.2;
  return c;
}

// Outward unit normals of the fruit's surface at `dirs` (directions of its own frame, as
// surfacePoint takes them; `surface` holds surfacePoint of each), by central differences across
// the sphere of directions.
std::vector<Eigen::Vector3d> outwardNormals(const SyntheticFruit& fruit, const PointList& dirs,
                                            const PointList& surface) {
  std::vector<Eigen::Vector3d> normals;
  normals.reserve(dirs.size());
  const double h = 1e-3;
  for (std::size_t i = 0; i < dirs.size(); ++i) {
    const Eigen::Vector3d& u = dirs[i];
    const Eigen::Vector3d t1 = u.unitOrthogonal(), t2 = u.cross(t1);
    const Eigen::Vector3d a = fruit.surfacePoint((u + h * t1).normalized()) - fruit.surfacePoint((u - h * t1).normalized());
    const Eigen::Vector3d b = fruit.surfacePoint((u + h * t2).normalized()) - fruit.surfacePoint((u - h * t2).normalized());
    Eigen::Vector3d n = a.cross(b).normalized();
    if (n.dot(surface[i] - fruit.center) < 0.0) n = -n;
    normals.push_back(n);
  }
  return normals;
}

// How each surface sample faces a camera view: the cosine between its normal and the ray to the
// camera where the camera sees it (0 at the outline), -1 where it does not. A sample is seen if
// it faces the camera and no other part of the fruit that faces it lies nearer in its pixel (the
// tolerance grows with the tilt: a tilted patch spans depth across one pixel). A leaf's straight
// edge across the image then keeps `view.cap` of the whole surface at most. A view of all the
// surface (cap 1) sees everything, as in cap mode.
std::vector<double> cameraMargins(const PointList& surface, const std::vector<Eigen::Vector3d>& normals,
                                  const SyntheticFruit& fruit, const View& view, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> margin(surface.size(), view.cap >= 1.0 ? 1.0 : -1.0);
  if (view.cap >= 1.0) return margin;
  const Eigen::Vector3d dir = view.dir.normalized();
  const Eigen::Vector3d cam = fruit.center + (0.3 + 0.2 * u(rng)) * dir;
  const double edge_angle = 2.0 * M_PI * u(rng);
  const Eigen::Vector3d e1 = dir.unitOrthogonal(), e2 = dir.cross(e1);
  const double pixel = 0.0025 / (fruit.center - cam).dot(-dir);  // about 2.5 mm wide at the fruit
  struct Px {
    double x, y, depth, facing;
  };
  std::vector<Px> px(surface.size());
  std::unordered_map<std::uint64_t, double> nearest;
  auto key = [&](const Px& q) {
    const auto ix = static_cast<std::int64_t>(std::floor(q.x / pixel)) + (1 << 20);
    const auto iy = static_cast<std::int64_t>(std::floor(q.y / pixel)) + (1 << 20);
    return (static_cast<std::uint64_t>(ix) << 32) | static_cast<std::uint64_t>(iy);
  };
  for (std::size_t i = 0; i < surface.size(); ++i) {
    const Eigen::Vector3d rel = surface[i] - cam;
    const double depth = rel.dot(-dir);
    px[i] = {rel.dot(e1) / depth, rel.dot(e2) / depth, depth, normals[i].dot(-rel.normalized())};
    if (px[i].facing <= 0.0) continue;
    auto [it, fresh] = nearest.emplace(key(px[i]), depth);
    if (!fresh) it->second = std::min(it->second, depth);
  }
  std::vector<std::size_t> visible;
  for (std::size_t i = 0; i < surface.size(); ++i) {
    if (px[i].facing <= 0.0) continue;
    const double tilt = std::min(5.0, std::sqrt(1.0 - px[i].facing * px[i].facing) / px[i].facing);  // tan, capped
    if (px[i].depth <= nearest[key(px[i])] + 0.002 + pixel * px[i].depth * tilt) visible.push_back(i);
  }
  std::vector<double> along(visible.size());
  for (std::size_t k = 0; k < visible.size(); ++k)
    along[k] = std::cos(edge_angle) * px[visible[k]].x + std::sin(edge_angle) * px[visible[k]].y;
  const std::size_t keep = std::min(visible.size(), static_cast<std::size_t>(view.cap * surface.size()));
  if (keep == 0) return margin;
  std::vector<double> sorted = along;
  std::nth_element(sorted.begin(), sorted.begin() + (keep - 1), sorted.end());
  const double edge = sorted[keep - 1];
  for (std::size_t k = 0; k < visible.size(); ++k)
    if (along[k] <= edge) margin[visible[k]] = px[visible[k]].facing;
  return margin;
}

// The TSDF-like surface cloud of `fruit` seen by `views`: voxel centres, noisy, rims blurred.
PointList scan(const SyntheticFruit& fruit, const std::vector<View>& views, double noise, double blur,
               std::mt19937& rng, double* coverage, std::optional<std::uint32_t> camera_seed = std::nullopt) {
  const double voxel = 0.004;
  std::normal_distribution<double> g(0.0, noise);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const PointList dirs = fibonacciSphere(40000);
  PointList surface;
  surface.reserve(dirs.size());
  for (const auto& d : dirs) surface.push_back(fruit.surfacePoint(d));
  std::vector<std::vector<double>> camera;
  if (camera_seed) {
    const std::vector<Eigen::Vector3d> normals = outwardNormals(fruit, dirs, surface);
    for (std::size_t v = 0; v < views.size(); ++v)
      camera.push_back(cameraMargins(surface, normals, fruit, views[v], *camera_seed + static_cast<std::uint32_t>(v)));
  }
  std::unordered_set<std::uint64_t> cells;
  PointList out;
  int seen = 0;
  for (std::size_t i = 0; i < dirs.size(); ++i) {
    const Eigen::Vector3d& p = surface[i];
    const Eigen::Vector3d radial = (p - fruit.center).normalized();
    double best_margin = -1.0;  // how far inside its cap the best view sees it (0: at the rim)
    const View* by = nullptr;
    for (std::size_t v = 0; v < views.size(); ++v) {
      const double margin = camera.empty() ? radial.dot(views[v].dir) - (1.0 - 2.0 * views[v].cap) : camera[v][i];
      if (margin >= 0.0 && margin > best_margin) best_margin = margin, by = &views[v];
    }
    if (!by) continue;
    ++seen;
    Eigen::Vector3d q = p;
    if (blur > 0.0 && by->cap < 1.0 && best_margin < 0.15) q -= blur * (1.0 - best_margin / 0.15) * u(rng) * by->dir;
    const Eigen::Vector3i cell = (q / voxel).array().floor().cast<int>();
    const std::uint64_t key = (std::uint64_t(cell.x() + 1000000) << 42) ^ (std::uint64_t(cell.y() + 1000000) << 21) ^
                              std::uint64_t(cell.z() + 1000000);
    if (!cells.insert(key).second) continue;
    q = (cell.cast<double>().array() + 0.5) * voxel;
    out.push_back(q + Eigen::Vector3d{g(rng), g(rng), g(rng)});
  }
  *coverage = static_cast<double>(seen) / dirs.size();
  return out;
}

// The case's cloud: its own surface, a touching neighbour's if it has one, and strays.
PointList caseCloud(const Case& c, std::mt19937& rng, std::optional<std::uint32_t> camera_seed, double* coverage) {
  PointList cloud = scan(c.fruit, c.views, c.noise, c.blur, rng, coverage, camera_seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const std::size_t own = cloud.size();
  if (c.neighbour) {  // a touching fruit beside it, seen from the first view's side
    const Eigen::Vector3d side = c.views[0].dir.cross(drawRotation(rng).col(0)).normalized();
    Superellipsoid other = Superellipsoid::sphere(0.5 * c.diameter * (0.8 + 0.3 * (u(rng) + 1.0) / 2.0), Eigen::Vector3d::Zero());
    const double reach = c.fruit.radius(c.fruit.rotation.transpose() * side) + other.a;
    other.t = c.fruit.center + side * reach;
    double ignored = 0;
    const PointList more = scan(SyntheticFruit::fromSuperellipsoid(other), {{c.views[0].dir, 0.5}}, c.noise, c.blur, rng,
                                &ignored, camera_seed ? std::optional<std::uint32_t>(*camera_seed + 17) : std::nullopt);
    cloud.insert(cloud.end(), more.begin(), more.end());
  }
  const int n_out = static_cast<int>(c.outliers * own);
  for (int i = 0; i < n_out; ++i)  // stray surface points within 3 cm of the fruit's outline
    cloud.push_back(c.fruit.center + (0.5 * c.diameter + 0.03) * Eigen::Vector3d{u(rng), u(rng), u(rng)});
  return cloud;
}

Outcome run(const Case& c, const PipelineParams& params, std::mt19937& rng, const std::string& dump,
            std::optional<std::uint32_t> camera_seed) {
  Outcome o;
  PointList cloud = caseCloud(c, rng, std::nullopt, &o.coverage);
  if (camera_seed) {
    // The cap cloud above still drew from the suite's generator, so that the cases after this
    // one are those of cap mode; the camera cloud draws its noise, its neighbour's side and its
    // strays from its own.
    std::mt19937 own(*camera_seed + 7919u);
    cloud = caseCloud(c, own, camera_seed, &o.coverage);
  }
  if (!dump.empty()) {
    std::ofstream f(dump);
    for (const auto& p : cloud) f << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
  }
  FruitShapePipeline pipeline(params);
  const auto start = std::chrono::steady_clock::now();
  const std::vector<FruitEstimate> fruits = pipeline.update(cloud);
  o.fit_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  const Eigen::Vector3d truth_center = c.fruit.centroid(60000);
  double best = 0.03;  // matched within 3 cm; otherwise the fruit is lost (accuracy 0)
  for (const auto& f : fruits) {
    if (!f.accepted) continue;
    const double d = (f.center() - truth_center).norm();
    if (d < best) {
      best = d;
      o.found = true;
      o.accuracy = 1.0 - std::abs(f.volume - c.volume) / c.volume;
      o.center_mm = 1000.0 * d;
      o.prior_mm = 1000.0 * (f.center_prior - truth_center).norm();
      Eigen::Vector3d look = Eigen::Vector3d::Zero();
      for (const auto& v : c.views) look += v.dir;
      look.normalize();
      o.prior_toward_mm = 1000.0 * (f.center_prior - truth_center).dot(look);
      o.fit_toward_mm = 1000.0 * (f.center() - truth_center).dot(look);
      o.fit_coverage = f.seen_share;
      o.ratio = c.volume / f.volume;
      o.rms = f.rms;
      const Superellipsoid fitted = f.fittedShape();  // as the pipeline tests the axis bound
      o.min_axis = std::min({fitted.a, fitted.b, fitted.c});
      o.max_axis = std::max({fitted.a, fitted.b, fitted.c});
      o.e1 = f.shape.e1;
      o.e2 = f.shape.e2;
      o.inside = c.volume >= f.volume_lo && c.volume <= f.volume_hi;
      o.center_inside = d <= f.center_r90;
      o.center_r90_mm = 1000.0 * f.center_r90;
      o.half_width = 0.5 * (f.volume_hi - f.volume_lo) / f.volume;
      o.log_volume_spread = f.log_volume_spread;
    }
  }
  return o;
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(std::floor(q * (v.size() - 1)))];
}

}  // namespace

int main(int argc, char** argv) {
  int n = 600;
  unsigned seed = 1;
  std::string json_out;
  PipelineParams params;
  CLI::App app("The fit's tails on random fruits through the whole pipeline, per coverage bin.", "fit_stress");
  app.add_option("--fruits", n, "random fruits")->check(CLI::Range(1, 100000))->capture_default_str();
  app.add_option("--seed", seed, "seed of the draw")->capture_default_str();
  app.add_option("--json", json_out, "write every fruit and the bins as JSON");
  app.add_option("--max-fit-points", params.fit.max_points, "the fit's max_fit_points (0: all)")->capture_default_str();
  app.add_option("--stall-tolerance", params.fit.stall_tolerance, "the fit's fit_stall_tolerance")->capture_default_str();
  app.add_option("--function-tolerance", params.fit.function_tolerance, "the fit's fit_function_tolerance")
      ->capture_default_str();
  app.add_option("--refit-tolerance", params.refit_tolerance, "the pipeline's refit_tolerance")->capture_default_str();
  app.add_option("--alpha", params.fit.alpha, "the fit's centre prior weight (fit_alpha)")->capture_default_str();
  app.add_option("--noise-bias", params.fit.noise_bias, "the fit's noise-bias weight (fit_noise_bias)")->capture_default_str();
  app.add_option("--size-prior", params.fit.size_prior, "the fit's pull toward smaller shapes (fit_size_prior) [m^2]")->capture_default_str();
  app.add_option("--gamma", params.fit.gamma, "the fit's axis similarity weight (fit_gamma)")->capture_default_str();
  app.add_option("--min-axis", params.fit.min_axis, "the fit's lower semi-axis bound (min_axis) [m]")->capture_default_str();
  app.add_option("--max-e", params.fit.max_e, "the fit's upper exponent bound (max_e)")->capture_default_str();
  app.add_option("--normal-edge-offset", params.normals.max_edge_offset,
                 "normals of points whose neighbourhood mean lies this share of the radius off them are dropped (0: off)")
      ->capture_default_str();
  app.add_option("--center-lambda", params.center_lambda, "the centre prior's pull toward the cluster mean")
      ->capture_default_str();
  app.add_option("--center-rim-margin", params.center_rim_margin,
                 "the centre prior at most this far [m] behind the deepest seen points (negative: no limit)")
      ->capture_default_str();
  std::string view_model = "camera";
  app.add_option("--views", view_model,
                 "camera: cameras 0.3-0.5 m away cut by a leaf's edge; cap: caps around the view directions (see the header)")
      ->check(CLI::IsMember({"camera", "cap"}))
      ->capture_default_str();
  int dump_index = -1;
  std::string dump_file;
  app.add_option("--dump-index", dump_index, "write this case's cloud (x y z per line) to --dump-file");
  app.add_option("--dump-file", dump_file, "where --dump-index's cloud goes");
  if (const int done = parseCommandLine(app, argc, argv); done >= 0) return done;
  const bool camera_views = view_model == "camera";
  try {
    params.validate();
  } catch (const std::invalid_argument& e) {
    std::cerr << "fit_stress: " << e.what() << "\n";
    return 2;
  }
  std::mt19937 rng(seed);
  struct Row {
    Case c;
    Outcome o;
  };
  std::vector<Row> rows;
  for (int i = 0; i < n; ++i) {
    Case c = randomCase(i, rng);
    // Each case's cameras draw from their own seed, so that the cases stay those of cap mode.
    const auto camera_seed = camera_views ? std::optional<std::uint32_t>(1000003u * (seed + 1) + 101u * static_cast<std::uint32_t>(i))
                                          : std::nullopt;
    Outcome o = run(c, params, rng, i == dump_index ? dump_file : std::string(), camera_seed);
    rows.push_back({std::move(c), o});
  }
  const std::vector<std::pair<double, double>> bins = {{0.0, 0.35}, {0.35, 0.6}, {0.6, 0.85}, {0.85, 1.01}};
  const char* names[] = {"quarter (< 0.35)", "half (0.35-0.6)", "three quarters (0.6-0.85)", "full (>= 0.85)"};
  nlohmann::json out = {{"seed", seed}, {"view_model", view_model}, {"fruits", nlohmann::json::array()}, {"bins", nlohmann::json::array()}};
  auto shares = [](const Case& c) {
    std::vector<double> v;
    for (const auto& view : c.views) v.push_back(view.cap);
    return v;
  };
  for (const auto& r : rows)
    out["fruits"].push_back({{"index", r.c.index}, {"kind", r.c.kind}, {"diameter_m", r.c.diameter}, {"volume_m3", r.c.volume},
                             {"views", r.c.views.size()}, {"view_shares", shares(r.c)}, {"coverage", r.o.coverage},
                             {"noise_m", r.c.noise},
                             {"blur_m", r.c.blur}, {"outliers", r.c.outliers}, {"neighbour", r.c.neighbour},
                             {"found", r.o.found}, {"volume_accuracy", r.o.accuracy}, {"center_error_mm", r.o.center_mm},
                             {"center_prior_error_mm", r.o.prior_mm},
                             {"prior_toward_mm", r.o.prior_toward_mm}, {"fit_toward_mm", r.o.fit_toward_mm},
                             {"pipeline_ms", r.o.fit_ms}, {"fit_coverage", r.o.fit_coverage},
                             {"true_over_fitted_volume", r.o.ratio}, {"rms_m", r.o.rms}, {"fit_min_axis_m", r.o.min_axis},
                             {"fit_max_axis_m", r.o.max_axis}, {"fit_e1", r.o.e1}, {"fit_e2", r.o.e2},
                             {"inside_ci90", r.o.inside}, {"ci90_relative_half_width", r.o.half_width},
                             {"center_inside_r90", r.o.center_inside}, {"center_r90_mm", r.o.center_r90_mm},
                             {"log_volume_spread", r.o.log_volume_spread}});
  std::printf("%-26s %-14s %5s %8s %8s %8s %10s %10s %9s %8s %8s %8s %8s\n", "coverage", "kind", "n", "mean", "p5", "worst",
              "centre mm", "centre p95", "ms (med)", "in ci90", "ci90 hw", "in r90", "r90 mm");
  for (std::size_t b = 0; b < bins.size(); ++b)
    for (const std::string kind : {"all", "superellipsoid", "pepper"}) {
      std::vector<double> acc, err, ms, hw, r90;
      int inside = 0, center_inside = 0;
      for (const auto& r : rows)
        if (r.o.coverage >= bins[b].first && r.o.coverage < bins[b].second && (kind == "all" || r.c.kind == kind)) {
          acc.push_back(r.o.accuracy);
          if (r.o.found) err.push_back(r.o.center_mm);
          ms.push_back(r.o.fit_ms);
          inside += r.o.inside ? 1 : 0;
          center_inside += r.o.center_inside ? 1 : 0;
          if (r.o.found) {
            hw.push_back(r.o.half_width);
            r90.push_back(r.o.center_r90_mm);
          }
        }
      if (acc.empty()) continue;
      double mean = 0, mean_err = 0;
      for (double a : acc) mean += a / acc.size();
      for (double e : err) mean_err += e / std::max<std::size_t>(1, err.size());
      const double p5 = quantile(acc, 0.05), worst = quantile(acc, 0.0), p95 = quantile(err, 0.95), med = quantile(ms, 0.5);
      const double in_ci = static_cast<double>(inside) / acc.size(), med_hw = quantile(hw, 0.5);
      const double in_r90 = static_cast<double>(center_inside) / acc.size(), med_r90 = quantile(r90, 0.5);
      std::printf("%-26s %-14s %5zu %8.3f %8.3f %8.3f %10.2f %10.2f %9.2f %8.3f %8.3f %8.3f %8.1f\n", names[b], kind.c_str(),
                  acc.size(), mean, p5, worst, mean_err, p95, med, in_ci, med_hw, in_r90, med_r90);
      out["bins"].push_back({{"bin", names[b]}, {"kind", kind}, {"n", acc.size()}, {"mean_accuracy", mean},
                             {"p5_accuracy", p5}, {"worst_accuracy", worst}, {"mean_center_mm", mean_err},
                             {"p95_center_mm", p95}, {"median_ms", med}, {"ci90_coverage", in_ci},
                             {"ci90_median_relative_half_width", med_hw}, {"center_r90_coverage", in_r90},
                             {"center_r90_median_mm", med_r90}});
    }
  if (!json_out.empty()) {
    std::ofstream f(json_out);
    f << out.dump(1) << "\n";
    if (!f) {
      std::cerr << "fit_stress: cannot write " << json_out << "\n";
      return 1;
    }
  }
  return 0;
}
