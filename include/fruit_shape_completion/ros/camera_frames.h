#pragma once
// The camera's organized clouds for the fruit input stage: reading and writing them as
// depth_image_proc's point_cloud_xyzrgb publishes them (float32 x, y, z and a packed rgb field,
// NaN where there is no return), and a bounded buffer that pairs a planner view with the frame
// the view was made from (the nearest stamp).
#include <fruit_shape_completion/fruit_input_stage.h>

#include <Eigen/Geometry>
#include <ros/time.h>
#include <sensor_msgs/PointCloud2.h>

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <mutex>
#include <string>

namespace fruit_shape_completion {
namespace ros_io {

// False with a message for a cloud that is not organized (height 1), lacks float32 x, y, z or a
// packed rgb/rgba field, is big-endian, or whose steps and data size disagree.
bool fromOrganizedCloud(const sensor_msgs::PointCloud2& msg, OrganizedFrame* frame, std::string* error);
// The frame as depth_image_proc publishes it (32-byte points: x, y, z, pad, rgb as float32).
sensor_msgs::PointCloud2 toOrganizedCloud(const OrganizedFrame& frame, const std::string& frame_id,
                                          const ros::Time& stamp);

// The last camera clouds, bounded by count and bytes; thread-safe. Clouds are kept as received
// (shared, not copied) and converted only when a view takes one.
class CameraFrameBuffer {
 public:
  CameraFrameBuffer(std::size_t max_frames, std::size_t max_bytes) : max_frames_(max_frames), max_bytes_(max_bytes) {}
  enum class Push { kStored, kClockJumpedBack, kTooLarge };
  // kClockJumpedBack: the stamp is older than the newest frame (a bag that loops); the buffer
  // was cleared and holds only this frame. kTooLarge: one frame exceeds max_bytes, not stored.
  Push push(const sensor_msgs::PointCloud2ConstPtr& cloud);
  // The frame nearest `stamp` within `tolerance` (nullptr if none); it and older frames leave
  // the buffer (a view is never paired with an earlier frame after a later one). If none pairs
  // and no frame at or after `stamp` has arrived, waits up to `wait` seconds (wall time) for
  // one: a view derived from a frame can overtake that frame on another connection.
  sensor_msgs::PointCloud2ConstPtr take(const ros::Time& stamp, double tolerance, double wait = 0.0);
  void clear();  // the frames and the evicted count
  std::size_t size() const;
  std::size_t evicted() const;  // frames pushed out by the bounds before any view took them

 private:
  std::size_t bytesLocked() const;
  const std::size_t max_frames_, max_bytes_;
  sensor_msgs::PointCloud2ConstPtr takeLocked(const ros::Time& stamp, double tolerance);
  mutable std::mutex mutex_;
  std::condition_variable pushed_;
  std::deque<sensor_msgs::PointCloud2ConstPtr> frames_;  // oldest first
  std::size_t evicted_ = 0;
  ros::Time newest_;  // the newest stamp pushed, taken frames included
};

// When a camera without a planner has come to rest, so that one frame per rest is mapped (as
// pointcloud_roi's roi_cloud): within kMove and kTurn of where the rest began for kHold of frame
// stamps, with no gap longer than kHold between the frames seen (frame to frame alone, 1 cm in
// 33 ms, an arm moving at up to 30 cm/s read as resting; now under about 3 cm/s does). A rest
// where the planner's last view stood is the planner's: a planner that inserts views only after
// it moves (insert_scan_if_not_moved false) leaves long gaps, and its view already mapped it.
// Not thread-safe.
class CameraRest {
 public:
  static constexpr double kMove = 0.01, kTurn = 0.01;  // [m], [rad]
  static constexpr double kHold = 0.3;                 // [s]
  enum class Frame {
    kMoving,         // a new rest may begin here
    kSettling,       // at rest for less than kHold
    kTake,           // the rest's frame: map it
    kPlannersPose,   // the rest's frame, where the planner's last view stood: not mapped
    kTaken,          // this rest's frame was decided already
  };
  Frame observe(const Eigen::Isometry3d& camera_pose, double stamp);
  // A planner view: the rest in progress is the planner's time, not one to finish later.
  void plannerViewAt(const Eigen::Isometry3d& sensor_pose);
  void reset();  // the map was cleared or replaced: every pose may be mapped again

 private:
  Eigen::Isometry3d rest_pose_ = Eigen::Isometry3d::Identity();
  double rest_since_ = 0.0, last_stamp_ = 0.0;
  bool resting_ = false, decided_ = false;
  Eigen::Isometry3d planner_pose_ = Eigen::Isometry3d::Identity();
  bool have_planner_pose_ = false;
};

}  // namespace ros_io
}  // namespace fruit_shape_completion
