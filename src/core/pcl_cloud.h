#pragma once
// The core's Eigen point lists as PCL clouds. Private to the core's sources: PCL headers stay
// out of the public ones (they compile slowly).
#include <fruit_shape_completion/types.h>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <vector>

namespace fruit_shape_completion {

using PclCloud = pcl::PointCloud<pcl::PointXYZ>;

// The finite points of `points`; index[k] is the position in `points` of cloud point k.
inline PclCloud::Ptr toPclCloud(const PointList& points, std::vector<int>* index = nullptr) {
  PclCloud::Ptr cloud(new PclCloud);
  cloud->reserve(points.size());
  if (index != nullptr) index->clear();
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) continue;
    const Eigen::Vector3f p = points[i].cast<float>();
    if (!p.allFinite()) continue;  // beyond float range
    cloud->push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
    if (index != nullptr) index->push_back(static_cast<int>(i));
  }
  return cloud;
}

}  // namespace fruit_shape_completion
