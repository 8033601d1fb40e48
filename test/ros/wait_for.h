#pragma once
// Spins ROS callbacks until `pred` holds or `seconds` of wall time have passed (the rostests').
#include <ros/ros.h>

namespace fruit_shape_completion {
namespace test {

template <typename Pred>
bool waitFor(Pred pred, double seconds) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(seconds);
  while (ros::ok() && ros::WallTime::now() < end) {
    ros::spinOnce();
    if (pred()) return true;
    ros::WallDuration(0.05).sleep();
  }
  return pred();
}

}  // namespace test
}  // namespace fruit_shape_completion
