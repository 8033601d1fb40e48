#include <fruit_shape_completion/missing_surface.h>

#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

namespace fruit_shape_completion {

PointList predictMissingSurface(const Superellipsoid& shape, const PointList& observed,
                                const MissingSurfaceParams& params) {
  PointList missing;
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  for (const auto& p : observed)
    if (p.allFinite()) cloud->push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())));
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
  if (!cloud->empty()) tree.setInputCloud(cloud);
  std::vector<int> nearest(1);
  std::vector<float> d2(1);
  const double t2 = params.threshold * params.threshold;
  for (const auto& s : shape.sampleSurface(params.samples)) {
    if (!s.allFinite()) continue;
    const pcl::PointXYZ q(static_cast<float>(s.x()), static_cast<float>(s.y()), static_cast<float>(s.z()));
    if (cloud->empty() || tree.nearestKSearch(q, 1, nearest, d2) < 1 || d2[0] > t2) missing.push_back(s);
  }
  return missing;
}

}  // namespace fruit_shape_completion
