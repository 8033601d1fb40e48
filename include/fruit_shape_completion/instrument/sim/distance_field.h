#pragma once
// Distances to obstacles on a regular grid (an exact Euclidean distance transform of the cells
// the obstacles occupy), for collision tests of the arm's capsules: against the scene's
// triangles (what the world allows) or against points the planner's map holds (what the
// planner knows).
#include <fruit_shape_completion/instrument/sim/ur5e_kinematics.h>
#include <fruit_shape_completion/types.h>

#include <Eigen/Core>
#include <vector>

namespace fruit_shape_completion {
namespace sim {

class DistanceField {
 public:
  DistanceField() = default;  // no obstacles: everything is free
  // Cells of `resolution` over the obstacles' bounding box grown by `margin`; a sprawling set
  // gets coarser cells (at most 6.4e7).
  static DistanceField ofTriangles(const std::vector<Eigen::Vector3f>& vertices,
                                   const std::vector<Eigen::Vector3i>& triangles, double resolution, double margin);
  static DistanceField ofPoints(const PointList& points, double resolution, double margin);

  // Distance from p to the nearest occupied cell's centre [m]; `margin` beyond the grid.
  double at(const Eigen::Vector3d& p) const;
  // Some point of the capsule's axis nearer an obstacle than its radius, to within about one
  // cell (cell centres stand for the points in them).
  bool hits(const Capsule& c) const;
  double resolution() const { return resolution_; }
  bool empty() const { return distance_.empty(); }

 private:
  void allocate(Eigen::Vector3d lo, Eigen::Vector3d hi, double resolution, double margin);
  void mark(const Eigen::Vector3d& p);
  void transform();
  std::size_t index(int x, int y, int z) const {
    return (static_cast<std::size_t>(z) * size_.y() + y) * size_.x() + x;
  }

  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();
  double resolution_ = 0.01, margin_ = 0.0;
  Eigen::Vector3i size_ = Eigen::Vector3i::Zero();
  std::vector<double> squared_;  // cells^2 while building
  std::vector<float> distance_;  // [m]
};

}  // namespace sim
}  // namespace fruit_shape_completion
