#include <fruit_shape_completion/instrument/planner/pointcloud_roi.h>

#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

namespace fruit_shape_completion {
namespace planner {

RoiCloud pointcloudRoi(const sim::RgbdFrame& frame, double leaf, const sim::RedThreshold& red_test) {
  std::vector<std::size_t> pixels;
  const sim::FrameClouds all = sim::cloudsFromFrame(frame, {}, &pixels);
  pcl::PointCloud<pcl::PointXYZRGB>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZRGB>);
  cloud->reserve(all.full.size());
  for (std::size_t i = 0; i < all.full.size(); ++i) {
    const Eigen::Vector3d& p = all.full[i];
    const std::size_t px = pixels[i];
    pcl::PointXYZRGB q;
    q.x = static_cast<float>(p.x()), q.y = static_cast<float>(p.y()), q.z = static_cast<float>(p.z());
    q.r = frame.rgb[3 * px], q.g = frame.rgb[3 * px + 1], q.b = frame.rgb[3 * px + 2];
    cloud->push_back(q);
  }
  pcl::PointCloud<pcl::PointXYZRGB>::Ptr down(new pcl::PointCloud<pcl::PointXYZRGB>);
  pcl::VoxelGrid<pcl::PointXYZRGB> grid;
  grid.setInputCloud(cloud);
  const float l = static_cast<float>(leaf);
  grid.setLeafSize(l, l, l);
  grid.filter(*down);
  RoiCloud out;
  pcl::IndicesPtr red(new pcl::Indices);
  for (std::size_t i = 0; i < down->size(); ++i) {
    const auto& q = (*down)[i];
    out.points.emplace_back(q.x, q.y, q.z);
    out.colours.push_back({q.r, q.g, q.b});
    if (red_test.isRed(q.r, q.g, q.b)) red->push_back(static_cast<pcl::index_t>(i));
  }
  if (red->empty()) return out;
  pcl::StatisticalOutlierRemoval<pcl::PointXYZRGB> sor;  // PCL's defaults: mean_k 1, stddev 0
  sor.setInputCloud(down);
  sor.setIndices(red);
  pcl::Indices kept;
  sor.filter(kept);
  out.roi_indices.assign(kept.begin(), kept.end());
  return out;
}

}  // namespace planner
}  // namespace fruit_shape_completion
