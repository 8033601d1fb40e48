#include <fruit_shape_completion/instrument/sim/distance_field.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace fruit_shape_completion {
namespace sim {

namespace {

constexpr double kFar = 1e20;
// Cell centres stand for the points in them: a capsule axis point and an obstacle point may
// each lie half a cell diagonal from theirs. Half of that slack is added to the radius, so
// contacts are taken to within about one cell (closer ones may be missed, nearer than that
// may be flagged).
constexpr double kHalfDiagonal = 0.8660254037844386;

// Felzenszwalb and Huttenlocher's lower envelope of parabolas, along one grid line.
void transform1d(const std::vector<double>& f, std::vector<double>& d, std::vector<int>& v, std::vector<double>& z) {
  const int n = static_cast<int>(f.size());
  int k = 0;
  v[0] = 0;
  z[0] = -std::numeric_limits<double>::infinity();
  z[1] = std::numeric_limits<double>::infinity();
  auto meet = [&](int q, int p) { return ((f[q] + double(q) * q) - (f[p] + double(p) * p)) / (2.0 * q - 2.0 * p); };
  for (int q = 1; q < n; ++q) {
    double s = meet(q, v[k]);
    while (s <= z[k]) s = meet(q, v[--k]);  // z[0] is -inf: k stays >= 0
    ++k;
    v[k] = q;
    z[k] = s;
    z[k + 1] = std::numeric_limits<double>::infinity();
  }
  k = 0;
  for (int q = 0; q < n; ++q) {
    while (z[k + 1] < q) ++k;
    d[q] = double(q - v[k]) * (q - v[k]) + f[v[k]];
  }
}

}  // namespace

void DistanceField::allocate(Eigen::Vector3d lo, Eigen::Vector3d hi, double resolution, double margin) {
  margin_ = margin;
  lo.array() -= margin;
  hi.array() += margin;
  resolution_ = std::max(resolution, std::cbrt((hi - lo).prod() / 6.4e7));
  origin_ = lo;
  size_ = ((hi - lo) / resolution_).array().ceil().cast<int>() + 1;
  squared_.assign(static_cast<std::size_t>(size_.x()) * size_.y() * size_.z(), kFar);
}

void DistanceField::mark(const Eigen::Vector3d& p) {
  const Eigen::Vector3i g = ((p - origin_) / resolution_).array().floor().cast<int>();
  if ((g.array() < 0).any() || (g.array() >= size_.array()).any()) return;
  squared_[index(g.x(), g.y(), g.z())] = 0.0;
}

void DistanceField::transform() {
  std::vector<double> f, d, z(static_cast<std::size_t>(size_.maxCoeff()) + 1);
  std::vector<int> v(static_cast<std::size_t>(size_.maxCoeff()));
  for (int axis = 0; axis < 3; ++axis) {
    const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
    f.resize(static_cast<std::size_t>(size_[axis]));
    d.resize(f.size());
    for (int i = 0; i < size_[a1]; ++i)
      for (int j = 0; j < size_[a2]; ++j) {
        Eigen::Vector3i c;
        c[a1] = i;
        c[a2] = j;
        for (int k = 0; k < size_[axis]; ++k) {
          c[axis] = k;
          f[static_cast<std::size_t>(k)] = squared_[index(c.x(), c.y(), c.z())];
        }
        transform1d(f, d, v, z);
        for (int k = 0; k < size_[axis]; ++k) {
          c[axis] = k;
          squared_[index(c.x(), c.y(), c.z())] = std::min(d[static_cast<std::size_t>(k)], kFar);
        }
      }
  }
  distance_.resize(squared_.size());
  for (std::size_t i = 0; i < squared_.size(); ++i) distance_[i] = static_cast<float>(std::sqrt(squared_[i]) * resolution_);
  squared_.clear();
  squared_.shrink_to_fit();
}

DistanceField DistanceField::ofTriangles(const std::vector<Eigen::Vector3f>& vertices,
                                         const std::vector<Eigen::Vector3i>& triangles, double resolution, double margin) {
  DistanceField field;
  if (triangles.empty()) return field;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const auto& t : triangles)
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d p = vertices[static_cast<std::size_t>(t[k])].cast<double>();
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
  field.allocate(lo, hi, resolution, margin);
  for (const auto& t : triangles) {
    const Eigen::Vector3d a = vertices[static_cast<std::size_t>(t[0])].cast<double>();
    const Eigen::Vector3d b = vertices[static_cast<std::size_t>(t[1])].cast<double>();
    const Eigen::Vector3d c = vertices[static_cast<std::size_t>(t[2])].cast<double>();
    const double longest = std::max({(b - a).norm(), (c - a).norm(), (c - b).norm()});
    const int steps = std::max(1, static_cast<int>(std::ceil(longest / (0.5 * field.resolution_))));
    for (int i = 0; i <= steps; ++i)
      for (int j = 0; i + j <= steps; ++j) field.mark(a + (b - a) * (double(i) / steps) + (c - a) * (double(j) / steps));
  }
  field.transform();
  return field;
}

DistanceField DistanceField::ofPoints(const PointList& points, double resolution, double margin) {
  DistanceField field;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const auto& p : points)
    if (p.allFinite()) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
  if (!(lo.array() <= hi.array()).all()) return field;
  field.allocate(lo, hi, resolution, margin);
  for (const auto& p : points)
    if (p.allFinite()) field.mark(p);
  field.transform();
  return field;
}

double DistanceField::at(const Eigen::Vector3d& p) const {
  if (distance_.empty()) return std::numeric_limits<double>::infinity();
  const Eigen::Vector3d g = (p - origin_) / resolution_;
  if (!g.allFinite()) return 0.0;
  const Eigen::Vector3i c = g.array().floor().cast<int>();
  if ((c.array() < 0).any() || (c.array() >= size_.array()).any()) return margin_;  // beyond: further than margin
  return distance_[index(c.x(), c.y(), c.z())];
}

bool DistanceField::hits(const Capsule& c) const {
  if (distance_.empty()) return false;
  const double len = (c.b - c.a).norm();
  const int steps = std::max(1, static_cast<int>(std::ceil(len / (0.5 * resolution_))));
  for (int i = 0; i <= steps; ++i)
    if (at(c.a + (c.b - c.a) * (double(i) / steps)) < c.radius + kHalfDiagonal * resolution_) return true;
  return false;
}

}  // namespace sim
}  // namespace fruit_shape_completion
