// Someone else's planner: the README's snippet, compiled as written, runs one view of a fruit
// through the plugin (loaded by name through pluginlib) and must give targets off its hidden side.
#include <pointcloud_roi_msgs/PointcloudWithRoi.h>
#include <ros/ros.h>

#include <cmath>
#include <cstring>
#include <iostream>
#include <string>
#include <vector>

#include README_SNIPPET_INCLUDES

namespace {

// One view from the origin of a 4 cm sphere 0.5 m ahead (camera frame = map frame here, z ahead):
// its near cap at 2 mm spacing, as pointcloud_roi would send it, every point a ROI point.
pointcloud_roi_msgs::PointcloudWithRoi oneView() {
  pointcloud_roi_msgs::PointcloudWithRoi msg;
  msg.cloud.header.frame_id = "camera";
  msg.cloud.height = 1;
  msg.cloud.point_step = 12;
  for (const char* name : {"x", "y", "z"}) {
    sensor_msgs::PointField f;
    f.name = name;
    f.offset = static_cast<std::uint32_t>(4 * msg.cloud.fields.size());
    f.datatype = sensor_msgs::PointField::FLOAT32;
    f.count = 1;
    msg.cloud.fields.push_back(f);
  }
  const double r = 0.04, cz = 0.5;
  std::vector<float> xyz;
  for (double x = -r; x <= r; x += 0.002)
    for (double y = -r; y <= r; y += 0.002) {
      const double d2 = r * r - x * x - y * y;
      if (d2 < 0) continue;
      xyz.insert(xyz.end(), {float(x), float(y), float(cz - std::sqrt(d2))});
      msg.roi_indices.push_back(static_cast<std::int32_t>(msg.roi_indices.size()));
    }
  msg.cloud.width = static_cast<std::uint32_t>(msg.roi_indices.size());
  msg.cloud.row_step = msg.cloud.width * msg.cloud.point_step;
  msg.cloud.data.resize(xyz.size() * 4);
  std::memcpy(msg.cloud.data.data(), xyz.data(), msg.cloud.data.size());
  msg.transform.rotation.w = 1.0;  // camera at the map origin
  return msg;
}

void yourPlanner(ros::NodeHandle& private_nh, const std::string& map_frame,
                 const pointcloud_roi_msgs::PointcloudWithRoi& msg, std::vector<octomap::point3d>& targets) {
#include README_SNIPPET_BODY
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "downstream_check");
  ros::NodeHandle private_nh("~");
  XmlRpc::XmlRpcValue list;
  list[0]["name"] = "superellipsoid";
  list[0]["type"] = "fruit_shape_completion/SuperellipsoidEstimator";
  private_nh.setParam("shape_estimators", list);
  std::vector<octomap::point3d> targets;
  try {
    yourPlanner(private_nh, "world", oneView(), targets);
  } catch (const std::exception& e) {
    std::cerr << "downstream_check: " << e.what() << "\n";
    return 1;
  }
  int on_hidden_side = 0;
  for (const auto& p : targets) {
    // Targets sit target_offset (default 5 cm) outside the predicted surface.
    const double off = std::abs(std::sqrt(p.x() * p.x() + p.y() * p.y() + (p.z() - 0.5) * (p.z() - 0.5)) - 0.04 - 0.05);
    on_hidden_side += off < 0.006 && p.z() > 0.49;
  }
  std::cout << "downstream_check: " << targets.size() << " targets, " << on_hidden_side
            << " on the sphere's hidden side\n";
  // The 1 cm views' veil filter drops the cap's rim (incidence beyond 75 degrees), so a single
  // view's fit is looser than with every point: 72 % of the targets lie on the hidden side.
  return targets.size() >= 20 && on_hidden_side >= 0.65 * targets.size() ? 0 : 1;
}
