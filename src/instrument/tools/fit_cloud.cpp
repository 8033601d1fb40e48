// fit_cloud: fits one superellipsoid per fruit to a fruit surface cloud file.
//   fit_cloud --input FILE [--json] [--surface-out FILE.ply] [--voxel LEAF] [--center-rim-margin M]
#include <fruit_shape_completion/instrument/cloud_io.h>
#include <fruit_shape_completion/fruit_shape_pipeline.h>

#include "command_line.h"

#include <algorithm>
#include <chrono>
#include <iostream>
#include <sstream>
#include <stdexcept>

#include "fruit_text.h"

using namespace fruit_shape_completion;

int main(int argc, char** argv) {
  std::string input, surface_out;
  bool json = false;
  CLI::App app("Fits one superellipsoid per fruit to a fruit surface cloud file.", "fit_cloud");
  app.add_option("--input", input, "FILE: .pcd, .ply, or text with 'x y z' per line (metres, one frame)")
      ->required();
  app.add_flag("--json", json, "one JSON object on stdout (logs on stderr)");
  app.add_option("--surface-out", surface_out,
                 "PLY of the fitted surfaces: observed part green, predicted unseen part red (accepted fruits only)");
  double voxel = 0.0;
  app.add_option("--voxel", voxel, "[m] thin the cloud to one point per cube of this side first (0: as given)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  double scale = 1.0;
  app.add_option("--scale", scale, "multiply every coordinate by this first (0.001: a cloud in millimetres)")
      ->check(CLI::Range(1e-6, 1e6))
      ->capture_default_str();
  PipelineParams params;
  app.add_option("--center-rim-margin", params.center_rim_margin,
                 "the centre prior at most this far [m] behind the deepest seen points (negative: no limit)")
      ->capture_default_str();
  if (const int done = parseCommandLine(app, argc, argv); done >= 0) return done;
  try {
    params.validate();
  } catch (const std::invalid_argument& e) {
    std::cerr << "fit_cloud: " << e.what() << "\n";
    return 2;
  }

  const auto start = std::chrono::steady_clock::now();
  CloudFile cloud = readPointCloud(input);
  if (!cloud.ok()) {
    std::cerr << "fit_cloud: " << cloud.error << "\n";
    return 1;
  }
  std::cerr << "fit_cloud: read " << cloud.points.size() << " points from " << input << "\n";
  if (scale != 1.0)
    for (auto& p : cloud.points) p *= scale;
  if (cloud.points.size() > 2000000 && voxel == 0.0)
    std::cerr << "fit_cloud: warning: " << cloud.points.size()
              << " points; a fruit surface needs no more than one per 3 mm (--voxel 0.003)\n";
  // Thinning drops the non-finite points before the pipeline could count them: counted here.
  const int non_finite_before = voxel > 0.0 ? static_cast<int>(std::count_if(cloud.points.begin(), cloud.points.end(),
                                                                               [](const auto& p) { return !p.allFinite(); }))
                                            : 0;
  const PointList thinned = voxel > 0.0 ? thinCloud(cloud.points, voxel) : PointList();
  FruitShapePipeline pipeline(params);
  const auto& fruits = pipeline.update(voxel > 0.0 ? thinned : cloud.points);
  const auto& st = pipeline.lastStats();
  const int non_finite = st.non_finite_points + non_finite_before;
  const double total_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();

  std::cerr << "fit_cloud: " << cloud.points.size() << " points";
  if (non_finite > 0) std::cerr << " (" << non_finite << " NaN/Inf skipped)";
  if (voxel > 0.0) std::cerr << ", thinned to " << thinned.size() << " at " << 1000.0 * voxel << " mm";
  std::cerr << ", " << st.clusters << " clusters, " << st.accepted << " accepted fits\n";
  std::vector<std::string> warnings;
  const int finite = static_cast<int>(cloud.points.size()) - non_finite;
  if (finite == 0)
    warnings.push_back("the cloud has no finite points, nothing to fit");
  else if (st.clusters == 0 && st.left_out.oversized == 0 && st.left_out.undersized == 0) {
    std::ostringstream os;
    os << "no cluster of " << pipeline.params().clustering.min_size << ".." << pipeline.params().clustering.max_size
       << " points within " << pipeline.params().clustering.tolerance << " m; nothing to fit";
    warnings.push_back(os.str());
  }
  if (st.left_out.undersized > 0) {
    warnings.push_back(std::to_string(st.left_out.undersized_points) + (voxel > 0.0 ? " thinned" : "") +
                       " point(s) in " + std::to_string(st.left_out.undersized) + " cluster(s) of fewer than " +
                       std::to_string(pipeline.params().clustering.min_size) +
                       " points not fitted (stray points, or fruits seen too little)");
    // Nearly every point alone in its cluster over an extent no fruit cloud has in metres: a
    // cloud given in millimetres or centimetres (not one thinned coarser than the tolerance).
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
    for (const auto& p : cloud.points)
      if (p.allFinite()) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    const double tolerance = pipeline.params().clustering.tolerance;
    if (st.left_out.undersized_points > 0.9 * (voxel > 0.0 ? static_cast<int>(thinned.size()) : finite) &&
        st.left_out.undersized > st.left_out.undersized_points / 3 && voxel < tolerance && finite > 0 &&
        (hi - lo).maxCoeff() > 5.0) {
      std::ostringstream os;
      os << "hardly two points lie within " << tolerance << " m of each other, over " << (hi - lo).maxCoeff()
         << " units: is the cloud in millimetres or centimetres? fit_cloud reads metres (--scale 0.001 or 0.01)";
      warnings.push_back(os.str());
    }
  }
  if (st.left_out.oversized > 0)
    warnings.push_back(std::to_string(st.left_out.oversized) + " cluster(s) of more than " +
                       std::to_string(pipeline.params().clustering.max_size) + " points not fitted (" +
                       (voxel > 0.0 ? "still too dense at this --voxel, or fruits and leaves grown into one: a larger --voxel"
                                    : "a cloud far denser than a 4 mm map: thin it, e.g. --voxel 0.003") +
                       ")");
  for (const auto& w : warnings) std::cerr << "fit_cloud: warning: " << w << "\n";
  for (const auto& f : fruits)
    if (!f.accepted) std::cerr << "fit_cloud: fruit " << f.id << " rejected: " << f.reason << "\n";

  if (!surface_out.empty()) {
    PointList pts;
    std::vector<std::array<std::uint8_t, 3>> colors;
    const int samples = pipeline.params().missing.samples;
    for (const auto& f : fruits) {
      if (!f.accepted) continue;
      // Same sampling as the missing-surface prediction, so red points are exactly those targets.
      for (const auto& p : f.shape.sampleSurface(samples)) {
        bool missing = false;
        for (const auto& m : f.missing_surface) missing = missing || (m - p).squaredNorm() < 1e-16;
        pts.push_back(p);
        colors.push_back(missing ? std::array<std::uint8_t, 3>{230, 30, 30}
                                 : std::array<std::uint8_t, 3>{40, 200, 60});
      }
    }
    std::string err;
    if (!writePly(surface_out, pts, colors, &err)) {
      std::cerr << "fit_cloud: " << err << "\n";
      return 1;
    }
  }

  if (json) {
    nlohmann::json out = {{"fruits", nlohmann::json::array()},
                          {"units", {{"center", "m"}, {"a, b, c", "m"}, {"rpy", "rad"}, {"volume", "m^3"}}},
                          {"input_points", cloud.points.size()},
                          {"non_finite_points", non_finite},
                          {"clusters", st.clusters},
                          {"left_out", {{"undersized", st.left_out.undersized},
                                        {"undersized_points", st.left_out.undersized_points},
                                        {"oversized", st.left_out.oversized}}},
                          {"accepted", st.accepted},
                          {"warnings", warnings},
                          {"total_ms", total_ms}};
    for (const auto& f : fruits) out["fruits"].push_back(fruitJson(f));
    std::cout << out.dump() << "\n";
  } else {
    printFruitTable(std::cout, fruits);
    std::cout << "total " << total_ms << " ms\n";
  }
  return 0;
}
