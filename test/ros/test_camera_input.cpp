// The camera input without a ROS master: one simulated frame through the simulator loop's path
// (the renderer's organized frame straight into the estimator) and through the plugin's ROS path
// (a depth_image_proc-style PointCloud2, read back by the plugin's conversion) gives the same
// fruit cloud and the same map; the frame buffer pairs views with frames; malformed clouds are
// refused with a message.
#include <fruit_shape_completion/host/superellipsoid_estimator.h>
#include <fruit_shape_completion/ros/camera_frames.h>
#include <fruit_shape_completion/ros/fruit_publisher.h>
#include <fruit_shape_completion/instrument/sim/fruit_truth.h>
#include <fruit_shape_completion/instrument/sim/procedural_scene.h>
#include <fruit_shape_completion/instrument/sim/rgbd_renderer.h>
#include <fruit_shape_completion/tsdf_surface.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cstring>
#include <limits>
#include <thread>

using namespace fruit_shape_completion;

namespace {

struct RenderedFrame {
  sim::RgbdFrame frame;
  Eigen::Isometry3d pose;
  RenderedFrame() {
    sim::Scene scene;
    std::string err;
    EXPECT_TRUE(sim::loadSceneSpec("procedural:3", &scene, &err)) << err;
    std::vector<int> triangle_fruit;
    const auto fruits = sim::computeFruitTruth(scene, &triangle_fruit);
    const sim::RgbdRenderer renderer(scene, triangle_fruit);
    // Look at the first red fruit from 35 cm, with the paper's blurred noise.
    Eigen::Vector3d target = fruits.front().center;
    for (const auto& f : fruits)
      if (f.color == "red") target = f.center;
    sim::DepthNoise noise;
    noise.model = sim::DepthNoise::Model::kPaper;
    frame = renderer.render(PinholeCamera::lookingAt(target + Eigen::Vector3d(0.2, -0.25, 0.1), target), noise, 2);
    pose = sim::cameraPose(frame.camera);
  }
};

sensor_msgs::PointCloud2ConstPtr cloudAt(double stamp) {
  sensor_msgs::PointCloud2Ptr c(new sensor_msgs::PointCloud2);
  c->header.stamp = ros::Time(stamp);
  c->height = 2;
  c->width = 2;
  c->data.resize(1000);
  return c;
}

}  // namespace

TEST(CameraInput, SimulatorLoopAndPluginRosPathGiveTheSameFruitCloudAndMap) {
  const RenderedFrame r;
  const OrganizedFrame direct = sim::organizedFrame(r.frame);
  OrganizedFrame via_ros;
  std::string error;
  ASSERT_TRUE(ros_io::fromOrganizedCloud(ros_io::toOrganizedCloud(direct, "camera", ros::Time(1.0)), &via_ros, &error)) << error;
  const FruitInputStage stage;
  const FruitInput a = stage.processFrame(direct, r.pose), b = stage.processFrame(via_ros, r.pose);
  ASSERT_GT(a.fruit.size(), 500u) << "the view shows no fruit";
  ASSERT_EQ(a.fruit.size(), b.fruit.size());
  for (std::size_t i = 0; i < a.fruit.size(); ++i) ASSERT_EQ(a.fruit[i], b.fruit[i]) << "point " << i;
  // And the estimators fed each way hold the same map.
  host::SuperellipsoidEstimator e1, e2;
  const PointList none;
  host::ViewData v1{none, none, r.pose, 1.0, host::ViewSource::kCameraFrame}, v2 = v1;
  v1.camera_frame = &direct;
  v2.camera_frame = &via_ros;
  e1.insertView(v1);
  e2.insertView(v2);
  e1.update();
  e2.update();
  EXPECT_EQ(e1.surface(), e2.surface());
  EXPECT_EQ(e1.status().input.camera_frames, 1u);
  EXPECT_EQ(e1.status().input.depth_edge_points, a.depth_edges);
  EXPECT_GT(a.depth_edges, 0u);  // the blurred outlines were there to drop
}

TEST(CameraInput, MalformedCameraCloudsAreRefusedWithAMessage) {
  const RenderedFrame r;
  const sensor_msgs::PointCloud2 good = ros_io::toOrganizedCloud(sim::organizedFrame(r.frame), "camera", ros::Time(1.0));
  OrganizedFrame out;
  std::string error;
  auto refused = [&](const sensor_msgs::PointCloud2& msg, const std::string& words) {
    error.clear();
    return !ros_io::fromOrganizedCloud(msg, &out, &error) && error.find(words) != std::string::npos;
  };
  sensor_msgs::PointCloud2 flat = good;
  flat.width *= flat.height;
  flat.height = 1;
  EXPECT_TRUE(refused(flat, "not organized")) << error;
  sensor_msgs::PointCloud2 no_rgb = good;
  no_rgb.fields.pop_back();
  EXPECT_TRUE(refused(no_rgb, "rgb")) << error;
  sensor_msgs::PointCloud2 short_data = good;
  short_data.data.resize(good.data.size() / 2);
  EXPECT_TRUE(refused(short_data, "shorter")) << error;
  sensor_msgs::PointCloud2 lying_step = good;
  lying_step.row_step = 0xFFFFFFFFu;
  EXPECT_TRUE(refused(lying_step, "shorter")) << error;
  sensor_msgs::PointCloud2 double_x = good;
  double_x.fields[0].datatype = sensor_msgs::PointField::FLOAT64;
  EXPECT_TRUE(refused(double_x, "float32")) << error;
  sensor_msgs::PointCloud2 outside = good;
  outside.fields[3].offset = good.point_step;
  EXPECT_TRUE(refused(outside, "inside the point step")) << error;
  sensor_msgs::PointCloud2 big_endian = good;
  big_endian.is_bigendian = true;
  EXPECT_TRUE(refused(big_endian, "big-endian")) << error;
  // A uint32 rgb field (some drivers) reads the same colours.
  sensor_msgs::PointCloud2 uint_rgb = good;
  uint_rgb.fields[3].datatype = sensor_msgs::PointField::UINT32;
  OrganizedFrame a, b;
  ASSERT_TRUE(ros_io::fromOrganizedCloud(good, &a, &error));
  ASSERT_TRUE(ros_io::fromOrganizedCloud(uint_rgb, &b, &error));
  EXPECT_EQ(a.rgb, b.rgb);
  EXPECT_EQ(std::memcmp(a.xyz.data(), b.xyz.data(), 4 * a.xyz.size()), 0);
}

TEST(CameraFrameBuffer, PairsTheNearestFrameWithinTheToleranceAndStaysBounded) {
  ros_io::CameraFrameBuffer buffer(4, 1 << 20);
  for (double t : {1.0, 1.033, 1.066, 1.1}) EXPECT_EQ(buffer.push(cloudAt(t)), ros_io::CameraFrameBuffer::Push::kStored);
  EXPECT_EQ(buffer.take(ros::Time(2.0), 0.05), nullptr);  // too far from any
  const auto f = buffer.take(ros::Time(1.07), 0.05);
  ASSERT_NE(f, nullptr);
  EXPECT_DOUBLE_EQ(f->header.stamp.toSec(), 1.066);
  EXPECT_EQ(buffer.size(), 1u);  // it and the older frames are gone
  // Bounded by count (and bytes): the oldest go first, counted.
  for (double t : {1.2, 1.3, 1.4, 1.5, 1.6}) buffer.push(cloudAt(t));
  EXPECT_EQ(buffer.size(), 4u);
  EXPECT_EQ(buffer.evicted(), 2u);
  ros_io::CameraFrameBuffer small(100, 2500);
  for (double t : {1.0, 2.0, 3.0}) small.push(cloudAt(t));
  EXPECT_EQ(small.size(), 2u);  // 1000 bytes each, 2500 allowed
  sensor_msgs::PointCloud2Ptr huge(new sensor_msgs::PointCloud2(*cloudAt(4.0)));
  huge->data.resize(5000);
  EXPECT_EQ(small.push(huge), ros_io::CameraFrameBuffer::Push::kTooLarge);
  // A bag that loops: time goes back, the buffer starts again with the new frame.
  EXPECT_EQ(buffer.push(cloudAt(0.5)), ros_io::CameraFrameBuffer::Push::kClockJumpedBack);
  EXPECT_EQ(buffer.size(), 1u);
  EXPECT_NE(buffer.take(ros::Time(0.5), 0.0), nullptr);
  // A corrupt stamp 136 years on: ros::Time's own difference would throw; it pairs with nothing.
  sensor_msgs::PointCloud2Ptr far(new sensor_msgs::PointCloud2(*cloudAt(1.0)));
  far->header.stamp = ros::Time(0xFFFFFFF0u, 0);
  buffer.push(far);
  EXPECT_EQ(buffer.take(ros::Time(1.0), 0.05), nullptr);
  // A reset clears the frames and restarts the count of evicted ones.
  EXPECT_EQ(buffer.evicted(), 2u);
  buffer.clear();
  EXPECT_EQ(buffer.size(), 0u);
  EXPECT_EQ(buffer.evicted(), 0u);
}

// A view made from a frame (pointcloud_roi's output) can arrive before the frame itself: the
// buffer waits briefly for it, and does not wait once a newer frame shows none will pair.
TEST(CameraFrameBuffer, WaitsBrieflyForAFrameThatHasNotArrivedYet) {
  ros_io::CameraFrameBuffer buffer(4, 1 << 20);
  buffer.push(cloudAt(1.0));
  std::thread camera([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
    buffer.push(cloudAt(2.0));
  });
  const auto f = buffer.take(ros::Time(2.0), 0.01, 2.0);
  camera.join();
  ASSERT_NE(f, nullptr);
  EXPECT_DOUBLE_EQ(f->header.stamp.toSec(), 2.0);
  // A newer frame is there already: no frame within the tolerance returns at once, no wait.
  buffer.push(cloudAt(3.0));
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(buffer.take(ros::Time(2.5), 0.01, 5.0), nullptr);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 1.0);
  // Without a wait, a missing frame is missing.
  EXPECT_EQ(buffer.take(ros::Time(4.0), 0.01), nullptr);
  // An older frame within the tolerance pairs at once, without waiting for the view's own
  // (the planner's callback must not wait while one pairs).
  buffer.push(cloudAt(4.967));
  const auto t0 = std::chrono::steady_clock::now();
  const auto previous = buffer.take(ros::Time(5.0), 0.05, 5.0);
  ASSERT_NE(previous, nullptr);
  EXPECT_DOUBLE_EQ(previous->header.stamp.toSec(), 4.967);
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 1.0);
}

// A detector with nothing to report publishes an empty cloud (width 0): no points, indices into
// it counted as bad, and no read of point 0 of an empty buffer (found by fuzz_camera_cloud).
TEST(CloudReaders, EmptyCloudsGiveNoPointsAndCountTheirIndices) {
  sensor_msgs::PointCloud2 empty = ros_io::toCloud(PointList(), "camera", ros::Time(1.0));
  ASSERT_EQ(empty.width * empty.height, 0u);
  PointList points, all, fruit;
  std::size_t non_finite = 7, bad = 0;
  std::string error;
  EXPECT_TRUE(ros_io::fromCloud(empty, &points, &non_finite, &error)) << error;
  EXPECT_TRUE(points.empty());
  EXPECT_EQ(non_finite, 0u);
  EXPECT_TRUE(ros_io::fromRoiCloud(empty, {0, 3, -1}, &all, &fruit, &bad, &error)) << error;
  EXPECT_TRUE(all.empty() && fruit.empty());
  EXPECT_EQ(bad, 3u);
  // Eight rows of nothing: the same.
  empty.height = 8;
  EXPECT_TRUE(ros_io::fromCloud(empty, &points, &non_finite, &error)) << error;
  EXPECT_TRUE(points.empty());
}

// Without a planner, one frame per rest: held 0.3 s within 1 cm and 0.01 rad of where the rest
// began, with no gap in the frames seen, not frame to frame; not where the planner's last view
// stood; a cleared map may be mapped again.
TEST(CameraRest, OneFramePerRestHeldLongEnoughAndNotThePlannersPose) {
  using ros_io::CameraRest;
  auto at = [](double x) {
    Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
    p.translation() = Eigen::Vector3d(x, 0, 0.5);
    return p;
  };
  CameraRest rest;
  // Frames every 0.1 s at one place from t0; what the frame at t0 + 0.35 s made of it.
  auto held = [&](double x, double t0) {
    EXPECT_EQ(rest.observe(at(x), t0), CameraRest::Frame::kMoving);
    EXPECT_EQ(rest.observe(at(x), t0 + 0.1), CameraRest::Frame::kSettling);  // still frames, no rest yet
    EXPECT_EQ(rest.observe(at(x), t0 + 0.2), CameraRest::Frame::kSettling);
    return rest.observe(at(x), t0 + 0.35);
  };
  EXPECT_EQ(held(0.0, 1.0), CameraRest::Frame::kTake);
  EXPECT_EQ(rest.observe(at(0.0), 1.5), CameraRest::Frame::kTaken);
  EXPECT_EQ(rest.observe(at(0.0), 1.7), CameraRest::Frame::kTaken);
  // Frames missed for longer than the hold (the planner's time, tf missing): a rest starts over.
  EXPECT_EQ(rest.observe(at(0.0), 9.0), CameraRest::Frame::kMoving);
  EXPECT_EQ(rest.observe(at(0.0), 9.2), CameraRest::Frame::kSettling);
  // Creeping 5 mm per frame (15 cm/s at 30 Hz): each frame still beside the last, never a rest.
  int taken = 0;
  for (int k = 1; k <= 60; ++k)
    taken += rest.observe(at(0.005 * k), 9.2 + k / 30.0) == CameraRest::Frame::kTake ? 1 : 0;
  EXPECT_EQ(taken, 0);
  // Where the planner's last view stood: decided, not taken; elsewhere taken.
  rest.plannerViewAt(at(1.0));
  EXPECT_EQ(held(1.005, 20.0), CameraRest::Frame::kPlannersPose);
  EXPECT_EQ(rest.observe(at(1.005), 20.45), CameraRest::Frame::kTaken);
  EXPECT_EQ(held(1.2, 21.0), CameraRest::Frame::kTake);
  // A planner view ends the rest in progress: the frames after it settle anew.
  EXPECT_EQ(rest.observe(at(1.4), 22.0), CameraRest::Frame::kMoving);
  EXPECT_EQ(rest.observe(at(1.4), 22.2), CameraRest::Frame::kSettling);
  rest.plannerViewAt(at(3.0));
  EXPECT_EQ(rest.observe(at(1.4), 22.35), CameraRest::Frame::kMoving);
  // After a reset (the map cleared) the planner's pose and a rest already taken are mapped again.
  rest.plannerViewAt(at(2.0));
  EXPECT_EQ(held(2.0, 30.0), CameraRest::Frame::kPlannersPose);
  rest.reset();
  EXPECT_EQ(held(2.0, 31.0), CameraRest::Frame::kTake);
  rest.reset();
  EXPECT_EQ(rest.observe(at(2.0), 31.45), CameraRest::Frame::kMoving);
  // A bag that loops (stamps back in time) and a pose that is not finite start over.
  EXPECT_EQ(held(2.0, 2.0), CameraRest::Frame::kTake);
  Eigen::Isometry3d bad = at(2.0);
  bad.translation().x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(rest.observe(bad, 3.0), CameraRest::Frame::kMoving);
  EXPECT_EQ(rest.observe(at(2.0), 3.1), CameraRest::Frame::kMoving);
}
