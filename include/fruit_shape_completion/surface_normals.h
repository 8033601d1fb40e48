#pragma once
// Per-point surface normals from the PCA of each point's neighbourhood.
#include <fruit_shape_completion/types.h>

#include <vector>

namespace fruit_shape_completion {

struct NormalParams {
  double radius = 0.015;  // neighbourhood radius [m]
  int min_neighbours = 5;
  // A neighbourhood that is a line, not a surface (middle / largest eigenvalue below this),
  // gives no normal.
  double min_planarity = 0.05;
  // Normals are computed at no more than this many evenly spread points of a cloud (each
  // still from its full neighbourhood); the rest get none. The centre prior and the shape check
  // need a few hundred normals, not thousands. 0: every point.
  int max_points = 500;
  // A point whose neighbourhood's mean lies more than this share of `radius` from it, across
  // its normal, sits at the edge of what was seen (a silhouette, a leaf's edge): its one-sided
  // neighbourhood tilts the normal toward the seen side, and the normal's line then passes
  // behind the centre. Such points get no normal (a half-disc neighbourhood's mean lies 0.42
  // of the radius off its point). 0: off.
  double max_edge_offset = 0.3;
};

struct SurfaceNormals {
  // One entry per input point; a point without a valid normal (degenerate neighbourhood, or
  // not among the max_points evaluated) gets NaN, so callers drop it on its own instead of
  // discarding the whole cluster.
  std::vector<Eigen::Vector3d> normals;
  int valid = 0;
};

// The moments of a point's neighbourhood (offsets from the point) and the PCA normal they give:
// the one normal computation, also used by the TSDF integrator's neighbourhood pass.
struct NeighbourMoments {
  int count = 0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double outer[6] = {0, 0, 0, 0, 0, 0};  // the symmetric second moments: xx xy xz yy yz zz
  void add(const Eigen::Vector3d& offset) {
    const double x = offset.x(), y = offset.y(), z = offset.z();
    ++count;
    sum += offset;
    outer[0] += x * x;
    outer[1] += x * y;
    outer[2] += x * z;
    outer[3] += y * y;
    outer[4] += y * z;
    outer[5] += z * z;
  }
  // The unit normal, its sign arbitrary; NaN if the neighbourhood is too small or a line.
  Eigen::Vector3d normal(const NormalParams& params) const;
};

// Normals are oriented toward `inside` (e.g. the cluster centroid: for a convex fruit shell
// it lies on the inner side of every tangent plane).
SurfaceNormals estimateNormals(const PointList& points, const NormalParams& params,
                               const Eigen::Vector3d& inside);

}  // namespace fruit_shape_completion
