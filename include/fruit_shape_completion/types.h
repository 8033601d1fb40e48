#pragma once
// Basic point types shared by the core library. Plain Eigen: no PCL in widely included headers.
#include <Eigen/Core>
#include <vector>

namespace fruit_shape_completion {

using Point = Eigen::Vector3d;
using PointList = std::vector<Point>;

}  // namespace fruit_shape_completion
