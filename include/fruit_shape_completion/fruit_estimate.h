#pragma once
// One estimated fruit: what the pipeline reports for a cluster of the surface cloud, and what
// shape estimators hand the planner (its evaluation reads center() and volume).
#include <fruit_shape_completion/shared_points.h>
#include <fruit_shape_completion/superellipsoid.h>

#include <limits>
#include <string>

namespace fruit_shape_completion {

struct FruitEstimate {
  int id = -1;         // stable from view to view while it is the same fruit
  int n_points = 0;    // points of the cluster
  Superellipsoid shape;  // the fit (meaningful when converged)
  // The factor its axes were shrunk by for the noise bias (FitParams::noise_bias). The next fit
  // starts from the shape before it, and the refit and axis-bound tests read that shape: they
  // are about the least-squares fit, whose residuals the shrink does not describe.
  double noise_scale = 1.0;
  double volume = 0.0;       // superellipsoid volume [m^3]
  double bbox_volume = 0.0;  // axis-aligned bounding box volume of the cluster's points [m^3]
  // 90 % interval of the true volume (accepted fruits; volume_interval.h) [m^3]
  double volume_lo = 0.0, volume_hi = 0.0;
  // The true centre lies within this distance of center() in 90 % of such fits (accepted
  // fruits; center_uncertainty.h) [m]
  double center_r90 = 0.0;
  // The spread of log(volume) that the fit's residuals and Jacobian alone imply (accepted
  // fruits, else NaN; volume_interval.h logVolumeSpread): large where the points leave the size
  // free.
  double log_volume_spread = std::numeric_limits<double>::quiet_NaN();
  // The share of the fitted surface its points cover (accepted fruits; shape_targets.h
  // seenCoverage), and whether the fit's shortest axis rests on its lower bound: with `views`
  // and the above, what the volume interval is made from.
  double seen_share = std::numeric_limits<double>::quiet_NaN();
  bool size_at_bound = false;
  // The views that saw this fruit, where they are counted (SuperellipsoidEstimator: its sightings
  // log's count, since a reset, at least 1); 0: not counted (a cloud given whole, as fit_cloud's).
  int views = 0;
  Eigen::Vector3d points_centroid = Eigen::Vector3d::Zero();
  Eigen::Vector3d center_prior = Eigen::Vector3d::Zero();  // w
  bool converged = false;
  bool accepted = false;  // converged and plausible: only accepted fruits should be published
  std::string reason;     // why not accepted
  double rms = 0.0;       // RMS radial residual [m]
  int iterations = 0;
  double fit_seconds = 0.0;
  bool refitted = false;  // false: points unchanged since the previous update, fit reused
  // Shared by the estimate's copies (shared_points.h): copying an estimate copies no points.
  SharedPoints missing_surface;  // predicted unseen surface samples (accepted fruits only)
  SharedPoints missing_normals;  // the fitted surface's outward unit normal at each of them
  SharedPoints points;           // the observed points of this fruit (its cluster, or its part)

  Eigen::Vector3d center() const { return shape.t; }
  // The fit's own least-squares solution, before the noise-bias shrink.
  Superellipsoid fittedShape() const {
    Superellipsoid s = shape;
    if (noise_scale > 0.0) {
      s.a /= noise_scale;
      s.b /= noise_scale;
      s.c /= noise_scale;
    }
    return s;
  }
  // A fruit known only by its centre and volume (e.g. the planner's ROI cluster boxes).
  static FruitEstimate ofBox(const Eigen::Vector3d& center, double volume) {
    FruitEstimate f;
    f.shape.t = center;
    f.volume = volume;
    f.accepted = true;
    return f;
  }
};

}  // namespace fruit_shape_completion
