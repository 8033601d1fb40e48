#pragma once
// Basic point types shared by the core library. Plain Eigen: no PCL in widely included headers.
#include <Eigen/Core>
#include <vector>

namespace fruit_shape_completion {

using Point = Eigen::Vector3d;
using PointList = std::vector<Point>;

// No input coordinate may exceed this [m]: a crop row is metres long, and beyond it a
// coordinate is a unit or transform error that would overflow map keys or the ray tracer.
constexpr double kMaxCoordinate = 1e4;

}  // namespace fruit_shape_completion
