// libFuzzer target: the plugin's PointCloud2 readers (fromCloud for fruit clouds, fromOrganizedCloud
// for the camera) on clouds whose steps, offsets, types and data size disagree, then the fruit
// input stage on whatever organized frame was accepted. Each must refuse with a message or give
// points it can use; nothing may read outside the data.
#include "fuzz_cloud_message.h"

#include <fruit_shape_completion/fruit_input_stage.h>
#include <fruit_shape_completion/ros/camera_frames.h>
#include <fruit_shape_completion/ros/fruit_publisher.h>

#include <cmath>
#include <cstdlib>

using namespace fruit_shape_completion;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fuzz::Bytes in(data, size);
  const sensor_msgs::PointCloud2 msg = fuzz::takeCloud(in);
  PointList points;
  std::size_t non_finite = 0;
  std::string error;
  if (ros_io::fromCloud(msg, &points, &non_finite, &error)) {
    for (const auto& p : points)
      if (!p.allFinite()) std::abort();  // non-finite points are skipped and counted
  } else if (error.empty()) {
    std::abort();  // a refusal says why
  }
  OrganizedFrame frame;
  error.clear();
  if (!ros_io::fromOrganizedCloud(msg, &frame, &error)) {
    if (error.empty()) std::abort();
    return 0;
  }
  if (frame.xyz.size() != 3 * static_cast<std::size_t>(frame.width) * frame.height) std::abort();
  const FruitInputStage stage{FruitInputParams()};
  const FruitInput out = stage.processFrame(frame, Eigen::Isometry3d::Identity(), nullptr);
  for (const auto& p : out.fruit)
    if (!p.allFinite()) std::abort();
  return 0;
}
