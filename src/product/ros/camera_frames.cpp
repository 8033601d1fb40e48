#include <fruit_shape_completion/ros/camera_frames.h>

#include <fruit_shape_completion/fruit_sightings.h>

#include <algorithm>
#include <chrono>

#include <cmath>
#include <cstring>
#include <limits>

namespace fruit_shape_completion {
namespace ros_io {

bool fromOrganizedCloud(const sensor_msgs::PointCloud2& msg, OrganizedFrame* frame, std::string* error) {
  if (msg.height <= 1) {
    *error = "the camera cloud is not organized (height " + std::to_string(msg.height) +
             "): give the camera driver's cloud (depth_image_proc point_cloud_xyzrgb), not a filtered one";
    return false;
  }
  if (msg.is_bigendian) {
    *error = "big-endian clouds are not supported";
    return false;
  }
  int offsets[4] = {-1, -1, -1, -1};  // x, y, z, rgb
  for (const auto& f : msg.fields) {
    const int k = f.name == "x" ? 0 : f.name == "y" ? 1 : f.name == "z" ? 2 : (f.name == "rgb" || f.name == "rgba") ? 3 : -1;
    if (k < 0) continue;
    const bool type_ok = k < 3 ? f.datatype == sensor_msgs::PointField::FLOAT32
                               : (f.datatype == sensor_msgs::PointField::FLOAT32 || f.datatype == sensor_msgs::PointField::UINT32);
    if (!type_ok || f.count != 1 || std::uint64_t(f.offset) + 4 > msg.point_step) {
      *error = "the camera cloud's field '" + f.name + "' is not a single " + (k < 3 ? "float32" : "packed float32/uint32") +
               " inside the point step";
      return false;
    }
    offsets[k] = static_cast<int>(f.offset);
  }
  for (int k = 0; k < 4; ++k)
    if (offsets[k] < 0) {
      *error = k < 3 ? "the camera cloud has no x, y, z fields" : "the camera cloud has no rgb field (the red test needs colours)";
      return false;
    }
  if (std::uint64_t(msg.row_step) < std::uint64_t(msg.width) * msg.point_step ||
      std::uint64_t(msg.data.size()) < std::uint64_t(msg.row_step) * msg.height) {
    *error = "the camera cloud's data is shorter than its width, height and steps say";
    return false;
  }
  frame->width = static_cast<int>(msg.width);
  frame->height = static_cast<int>(msg.height);
  if (msg.width > 100000 || msg.height > 100000 || frame->pixels() > 50000000u) {
    *error = "a camera cloud of " + std::to_string(msg.width) + " x " + std::to_string(msg.height) + " is beyond any camera";
    return false;
  }
  frame->xyz.resize(3 * frame->pixels());
  frame->rgb.resize(3 * frame->pixels());
  for (std::uint32_t v = 0; v < msg.height; ++v)
    for (std::uint32_t u = 0; u < msg.width; ++u) {
      const std::uint8_t* point = &msg.data[std::size_t(v) * msg.row_step + std::size_t(u) * msg.point_step];
      const std::size_t px = std::size_t(v) * msg.width + u;
      for (int k = 0; k < 3; ++k) std::memcpy(&frame->xyz[3 * px + k], point + offsets[k], 4);
      std::uint32_t rgb;
      std::memcpy(&rgb, point + offsets[3], 4);  // PCL's packing: 0x00RRGGBB
      frame->rgb[3 * px] = static_cast<std::uint8_t>(rgb >> 16);
      frame->rgb[3 * px + 1] = static_cast<std::uint8_t>(rgb >> 8);
      frame->rgb[3 * px + 2] = static_cast<std::uint8_t>(rgb);
    }
  return true;
}

sensor_msgs::PointCloud2 toOrganizedCloud(const OrganizedFrame& frame, const std::string& frame_id, const ros::Time& stamp) {
  sensor_msgs::PointCloud2 msg;
  msg.header.frame_id = frame_id;
  msg.header.stamp = stamp;
  msg.height = static_cast<std::uint32_t>(frame.height);
  msg.width = static_cast<std::uint32_t>(frame.width);
  const char* names[4] = {"x", "y", "z", "rgb"};
  const std::uint32_t offsets[4] = {0, 4, 8, 16};
  for (int k = 0; k < 4; ++k) {
    sensor_msgs::PointField f;
    f.name = names[k];
    f.offset = offsets[k];
    f.datatype = sensor_msgs::PointField::FLOAT32;
    f.count = 1;
    msg.fields.push_back(f);
  }
  msg.is_bigendian = false;
  msg.point_step = 32;
  msg.row_step = msg.point_step * msg.width;
  msg.is_dense = false;
  msg.data.assign(std::size_t(msg.row_step) * msg.height, 0);
  for (std::size_t px = 0; px < frame.pixels() && 3 * px + 2 < frame.xyz.size() && 3 * px + 2 < frame.rgb.size(); ++px) {
    std::uint8_t* point = &msg.data[px * msg.point_step];
    std::memcpy(point, &frame.xyz[3 * px], 12);
    const std::uint32_t rgb = (std::uint32_t(frame.rgb[3 * px]) << 16) | (std::uint32_t(frame.rgb[3 * px + 1]) << 8) |
                              frame.rgb[3 * px + 2];
    std::memcpy(point + 16, &rgb, 4);
  }
  return msg;
}

CameraFrameBuffer::Push CameraFrameBuffer::push(const sensor_msgs::PointCloud2ConstPtr& cloud) {
  if (cloud->data.size() > max_bytes_) return Push::kTooLarge;
  std::lock_guard<std::mutex> lock(mutex_);
  Push result = Push::kStored;
  if (cloud->header.stamp < newest_) {
    frames_.clear();
    result = Push::kClockJumpedBack;
  }
  newest_ = cloud->header.stamp;
  frames_.push_back(cloud);
  while (frames_.size() > max_frames_ || bytesLocked() > max_bytes_) {
    frames_.pop_front();
    ++evicted_;
  }
  pushed_.notify_all();
  return result;
}

sensor_msgs::PointCloud2ConstPtr CameraFrameBuffer::take(const ros::Time& stamp, double tolerance, double wait) {
  std::unique_lock<std::mutex> lock(mutex_);
  // The nearest frame that has arrived, at once: waiting for the view's own frame when an older
  // one pairs would hold the planner's callback (a soak measured 36 ms a view). Only when none
  // pairs yet does it wait, for a frame at or after the view's stamp.
  sensor_msgs::PointCloud2ConstPtr frame = takeLocked(stamp, tolerance);
  if (frame || !(wait > 0.0) || !(newest_ < stamp)) return frame;
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(std::min(wait, 10.0));
  pushed_.wait_until(lock, until, [&] { return !(newest_ < stamp); });
  return takeLocked(stamp, tolerance);
}

sensor_msgs::PointCloud2ConstPtr CameraFrameBuffer::takeLocked(const ros::Time& stamp, double tolerance) {
  std::size_t best = frames_.size();
  double best_gap = tolerance;
  for (std::size_t i = 0; i < frames_.size(); ++i) {
    // In seconds, not as a ros::Duration: that throws for stamps 68 years apart (a corrupt stamp).
    const double gap = std::abs(frames_[i]->header.stamp.toSec() - stamp.toSec());
    if (gap <= best_gap) {
      best_gap = gap;
      best = i;
    }
  }
  if (best == frames_.size()) return nullptr;
  sensor_msgs::PointCloud2ConstPtr frame = frames_[best];
  frames_.erase(frames_.begin(), frames_.begin() + static_cast<long>(best) + 1);
  return frame;
}

void CameraFrameBuffer::clear() {
  std::lock_guard<std::mutex> lock(mutex_);
  frames_.clear();
  evicted_ = 0;
  newest_ = ros::Time();
  pushed_.notify_all();
}

std::size_t CameraFrameBuffer::size() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return frames_.size();
}

std::size_t CameraFrameBuffer::evicted() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return evicted_;
}

std::size_t CameraFrameBuffer::bytesLocked() const {
  std::size_t bytes = 0;
  for (const auto& f : frames_) bytes += f->data.size();
  return bytes;
}

CameraRest::Frame CameraRest::observe(const Eigen::Isometry3d& camera_pose, double stamp) {
  if (!camera_pose.matrix().allFinite() || !std::isfinite(stamp)) {
    resting_ = false;
    return Frame::kMoving;
  }
  const bool gap = stamp - last_stamp_ > kHold;  // frames not seen meanwhile: the arm may have moved
  last_stamp_ = stamp;
  if (!resting_ || gap || !posesWithin(camera_pose, rest_pose_, kMove, kTurn) || stamp < rest_since_) {
    rest_pose_ = camera_pose;
    rest_since_ = stamp;
    resting_ = true;
    decided_ = false;
    return Frame::kMoving;
  }
  if (decided_) return Frame::kTaken;
  if (stamp - rest_since_ < kHold) return Frame::kSettling;
  decided_ = true;
  return have_planner_pose_ && FruitSightingLog::samePose(camera_pose, planner_pose_) ? Frame::kPlannersPose
                                                                                       : Frame::kTake;
}

void CameraRest::plannerViewAt(const Eigen::Isometry3d& sensor_pose) {
  have_planner_pose_ = sensor_pose.matrix().allFinite();
  if (have_planner_pose_) planner_pose_ = sensor_pose;
  resting_ = false;
}

void CameraRest::reset() {
  resting_ = false;
  decided_ = false;
  have_planner_pose_ = false;
}

}  // namespace ros_io
}  // namespace fruit_shape_completion
