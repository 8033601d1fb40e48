#pragma once
// Which predicted, unseen fruit surface becomes the planner's extra ROI targets. The planner
// draws its targets uniformly from one pool with its own ROI contours, so what is handed over
// decides where its views go: fruits already measured well hand over nothing, every other
// fruit the same number of points however large it is, and each point sits a little outside
// the predicted surface, so that a ray to it ends in the space a camera must see.
#include <fruit_shape_completion/fruit_estimate.h>

#include <cstddef>
#include <vector>

namespace fruit_shape_completion {

struct ShapeTargetParams {
  // A fruit whose fitted surface is seen over at least this share of its samples (no observed
  // point within the missing-surface threshold elsewhere) hands over no targets. 1: all hand over.
  double settled_coverage = 1.0;
  int per_fruit = 0;        // at most this many targets per fruit, spread over its unseen part; 0: all
  double offset = 0.05;     // [m] along the surface's outward normal
  // Hand over each target's outward normal, so that the planner views it from the side it
  // faces; false: zero directions (any side).
  bool view_side = true;
  // What a view gains in the planner's utility per fruit surface it would newly see
  // (shape_view_gain.h): seeing a whole fruit's worth of predicted surface adds view_gain. 0:
  // nothing, the planner's own utility alone.
  double view_gain = 1.0;
  double view_fov_deg = 60.0;    // the cone a view sees (full angle): the camera's narrower FOV
  double view_max_range = 1.0;   // [m] predicted surface farther than this is not counted
  // [m] A view whose camera would stand this close to a cell the planner's map holds occupied
  // gains nothing from predicted surface: the plant goes on beyond what the map has seen, and
  // moves to views in among it run into the unseen part. 0: no such check.
  double view_clearance = 0.15;
  // Its upper bound: the check visits every map cell within it, once per sampled view.
  static constexpr double kMaxViewClearance = 0.5;
  void validate() const;    // throws std::invalid_argument naming the first bad value
};

// Targets with the direction to view each from: the predicted surface's outward normal there
// (unit vectors, one per point), or no directions at all (any side).
struct ShapeTargets {
  PointList points, directions;
  // Per target, what seeing it adds to a view's utility (view_gain x the share of its fruit's
  // surface it stands for); empty: no view gain. The cone a view sees them in.
  std::vector<double> gains;
  double view_cos_half_angle = 1.0, view_max_range = 0.0;
  double view_clearance = 0.0;  // [m] ShapeTargetParams::view_clearance
};

// The fitted surface's outward unit normal at its point s.
Eigen::Vector3d outwardNormal(const Superellipsoid& shape, const Point& s);

// The share of a fruit's surface samples that were seen (1 - missing / samples).
double seenCoverage(const FruitEstimate& fruit, int surface_samples);
// ... of `missing_samples` not seen among `surface_samples`.
double seenCoverage(std::size_t missing_samples, int surface_samples);

// The targets of the accepted fruits (missing_surface computed from `surface_samples` samples).
ShapeTargets selectShapeTargets(const std::vector<FruitEstimate>& fruits, int surface_samples,
                             const ShapeTargetParams& params);

}  // namespace fruit_shape_completion
