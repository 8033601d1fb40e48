// soak_driver: drives a planner host (fruit_mapping_node) over ROS as a robot does, only harder,
// for ~duration seconds (scripts/ros_soak.sh):
//  - organized 640x480 camera clouds at ~camera_hz on /camera/depth/points, tf map -> camera at
//    each frame's stamp; a share of the frames gets no tf and another a tf one second stale;
//  - pointcloud_roi's PointcloudWithRoi at ~view_hz on /detect_roi/results, each paired with the
//    frame of its stamp (the planner's views);
//  - every ~service_period seconds clear_map, save_map or load_map (in turn) from its own thread.
// It samples the host's resident memory and writes ~out_csv (time, rss); at the end it prints
// one JSON line with the RSS figures, the service results and the host's last diagnostics.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <fruit_shape_completion/FilePath.h>
#include <fruit_shape_completion/instrument/planner/pointcloud_roi.h>
#include <fruit_shape_completion/ros/camera_frames.h>
#include <fruit_shape_completion/ros/fruit_publisher.h>
#include <fruit_shape_completion/ros/upstream_messages.h>
#include <fruit_shape_completion/instrument/sim/fruit_truth.h>
#include <fruit_shape_completion/instrument/sim/procedural_scene.h>
#include <fruit_shape_completion/instrument/sim/rgbd_renderer.h>

#include <ros/ros.h>
#include <std_srvs/Empty.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/transform_broadcaster.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <dirent.h>
#include <fstream>
#include <map>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <unistd.h>

using namespace fruit_shape_completion;

namespace {

struct Frame {
  sensor_msgs::PointCloud2 cloud;  // camera frame, stamp set when sent
  pointcloud_roi_msgs::PointcloudWithRoi roi;
  geometry_msgs::Transform pose;
};

// The pid of the first process whose command line contains `name` (0 if none).
int findPid(const std::string& name) {
  DIR* dir = opendir("/proc");
  if (!dir) return 0;
  int found = 0;
  while (dirent* e = readdir(dir)) {
    const int pid = std::atoi(e->d_name);
    if (pid <= 0 || pid == getpid()) continue;
    std::ifstream in("/proc/" + std::to_string(pid) + "/cmdline");
    std::string cmd((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (cmd.find(name) != std::string::npos && cmd.find("soak_driver") == std::string::npos) {
      found = pid;
      break;
    }
  }
  closedir(dir);
  return found;
}

double rssMb(int pid) {
  std::ifstream statm("/proc/" + std::to_string(pid) + "/statm");
  long pages = 0, resident = 0;
  if (!(statm >> pages >> resident)) return -1.0;
  return static_cast<double>(resident) * static_cast<double>(sysconf(_SC_PAGESIZE)) / (1024.0 * 1024.0);
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "soak_driver");
  ros::NodeHandle nh, pnh("~");
  double duration = 600, camera_hz = 30, view_hz = 10, service_period = 4, missing_tf = 0.05, stale_tf = 0.05;
  std::string host = "fruit_mapping_node", estimator_ns = "/fruit_mapping_node/superellipsoid", out_csv = "soak_ros.csv";
  std::string map_frame = "world";
  pnh.param("duration", duration, duration);
  pnh.param("camera_hz", camera_hz, camera_hz);
  pnh.param("view_hz", view_hz, view_hz);
  pnh.param("service_period", service_period, service_period);
  pnh.param("missing_tf", missing_tf, missing_tf);
  pnh.param("stale_tf", stale_tf, stale_tf);
  pnh.param("host", host, host);
  pnh.param("estimator_ns", estimator_ns, estimator_ns);
  pnh.param("out_csv", out_csv, out_csv);

  // A dozen views of a procedural plant row, rendered once, sent in a loop.
  sim::Scene scene;
  std::string err;
  if (!sim::loadSceneSpec("procedural:3", &scene, &err)) {
    ROS_FATAL("%s", err.c_str());
    return 1;
  }
  std::vector<int> triangle_fruit;
  const auto fruits = sim::computeFruitTruth(scene, &triangle_fruit);
  const sim::RgbdRenderer renderer(scene, triangle_fruit);
  std::vector<Frame> frames;
  sim::RedThreshold red_test;
  red_test.test = sim::RedThreshold::Test::kUpstream;
  for (std::size_t k = 0; k < 12 && !fruits.empty(); ++k) {
    const Eigen::Vector3d target = fruits[k % fruits.size()].center;
    const double a = 0.7 * static_cast<double>(k);
    const PinholeCamera cam = PinholeCamera::lookingAt(target + Eigen::Vector3d(0.35 * std::cos(a), 0.35 * std::sin(a), 0.1), target);
    sim::DepthNoise noise;
    noise.model = sim::DepthNoise::Model::kPaper;
    noise.seed = static_cast<unsigned>(k);
    const sim::RgbdFrame f = renderer.render(cam, noise, 2);
    Frame out;
    out.cloud = ros_io::toOrganizedCloud(sim::organizedFrame(f), "camera", ros::Time());
    const planner::RoiCloud roi = planner::pointcloudRoi(f, 0.01, red_test);
    out.roi.cloud = ros_io::toCloud(roi.points, map_frame, ros::Time(), roi.colours);
    out.roi.roi_indices = roi.roi_indices;
    out.pose = tf2::eigenToTransform(sim::cameraPose(cam)).transform;
    out.roi.transform = out.pose;
    frames.push_back(std::move(out));
  }
  ros::Publisher camera_pub = nh.advertise<sensor_msgs::PointCloud2>("/camera/depth/points", 4);
  ros::Publisher roi_pub = nh.advertise<pointcloud_roi_msgs::PointcloudWithRoi>(ros_io::kUpstreamRoiTopic, 4);
  tf2_ros::TransformBroadcaster tf;
  std::mutex diag_mutex;
  std::map<std::string, std::string> diag;
  ros::Subscriber diag_sub = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 10, [&](const diagnostic_msgs::DiagnosticArrayConstPtr& m) {
        for (const auto& s : m->status) {
          if (s.name.find(host) == std::string::npos || s.name.find("shape estimator") == std::string::npos) continue;
          std::lock_guard<std::mutex> lock(diag_mutex);
          diag.clear();
          diag["level"] = std::to_string(static_cast<int>(s.level));
          diag["message"] = s.message;
          for (const auto& kv : s.values) diag[kv.key] = kv.value;
        }
      });
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(10.0);
  while (ros::ok() && ros::WallTime::now() < until && (camera_pub.getNumSubscribers() == 0 || roi_pub.getNumSubscribers() == 0))
    ros::WallDuration(0.05).sleep();
  const int pid = findPid(host);
  if (pid == 0) ROS_WARN("soak_driver: no process '%s' found: no memory figures", host.c_str());

  std::atomic<bool> done{false};
  std::atomic<int> service_ok{0}, service_failed{0}, service_unreachable{0};
  // The services race with the views from their own thread, as an operator's calls would.
  std::thread services([&] {
    const std::string path = "/tmp/fsc_ros_soak_" + std::to_string(getpid()) + ".tsdf";
    for (int k = 0; !done; ++k) {
      for (int i = 0; i < 20 * service_period && !done; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
      if (done) break;
      bool reached = false, ok = false;
      if (k % 3 == 0) {
        fruit_shape_completion::FilePath srv;
        srv.request.file_path = path;
        reached = ros::service::call(estimator_ns + "/save_map", srv);
        ok = srv.response.success;
      } else if (k % 3 == 1) {
        fruit_shape_completion::FilePath srv;
        srv.request.file_path = path;
        reached = ros::service::call(estimator_ns + "/load_map", srv);
        ok = srv.response.success;
      } else {
        std_srvs::Empty srv;
        reached = ros::service::call(estimator_ns + "/clear_map", srv);
        ok = reached;
      }
      (!reached ? service_unreachable : ok ? service_ok : service_failed)++;
    }
    std::remove(path.c_str());
  });

  std::ofstream csv(out_csv);
  csv << "t_s,rss_mb\n";
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const ros::WallTime start = ros::WallTime::now();
  const double frame_dt = 1.0 / camera_hz;
  const int frames_per_view = std::max(1, static_cast<int>(std::lround(camera_hz / view_hz)));
  std::size_t sent = 0, views = 0, no_tf = 0, stale = 0;
  std::vector<double> rss;
  double next_sample = 0.0;
  while (ros::ok() && (ros::WallTime::now() - start).toSec() < duration) {
    const ros::WallTime tick = ros::WallTime::now();
    const Frame& f = frames[sent % frames.size()];
    const ros::Time stamp = ros::Time::now();
    const double r = u(rng);
    if (r >= missing_tf) {
      geometry_msgs::TransformStamped t;
      t.transform = f.pose;
      t.header.frame_id = map_frame;
      t.child_frame_id = "camera";
      t.header.stamp = r < missing_tf + stale_tf ? stamp - ros::Duration(1.0) : stamp;
      stale += r < missing_tf + stale_tf;
      tf.sendTransform(t);
    } else {
      ++no_tf;
    }
    sensor_msgs::PointCloud2 cloud = f.cloud;
    cloud.header.stamp = stamp;
    camera_pub.publish(cloud);
    if (sent % static_cast<std::size_t>(frames_per_view) == 0) {
      pointcloud_roi_msgs::PointcloudWithRoi roi = f.roi;
      roi.cloud.header.stamp = stamp;
      roi_pub.publish(roi);
      ++views;
    }
    ++sent;
    const double t = (ros::WallTime::now() - start).toSec();
    if (t >= next_sample && pid > 0) {
      rss.push_back(rssMb(pid));
      csv << t << ',' << rss.back() << '\n';
      next_sample += 5.0;
    }
    const double spent = (ros::WallTime::now() - tick).toSec();
    if (spent < frame_dt) ros::WallDuration(frame_dt - spent).sleep();
  }
  done = true;
  services.join();
  ros::WallDuration(2.5).sleep();  // one more diagnostics message after the last view
  const double elapsed = (ros::WallTime::now() - start).toSec();
  // RSS growth over the second half (after warm-up): last sample against the half-way one.
  double half = -1, last = -1, peak = 0;
  if (!rss.empty()) {
    half = rss[rss.size() / 2];
    last = rss.back();
    for (double x : rss) peak = std::max(peak, x);
  }
  std::printf("{\"seconds\": %.0f, \"camera_frames_sent\": %zu, \"camera_hz\": %.1f, \"views_sent\": %zu, "
              "\"frames_without_tf\": %zu, \"frames_with_stale_tf\": %zu, \"services_ok\": %d, \"services_failed\": %d, "
              "\"services_unreachable\": %d, \"rss_mb_half\": %.1f, \"rss_mb_last\": %.1f, \"rss_mb_peak\": %.1f, "
              "\"rss_growth_second_half\": %.4f, \"host_alive\": %s, \"diagnostics\": {",
              elapsed, sent, static_cast<double>(sent) / elapsed, views, no_tf, stale, service_ok.load(),
              service_failed.load(), service_unreachable.load(), half, last, peak,
              half > 0 ? (last - half) / half : 0.0, pid > 0 && rssMb(pid) > 0 ? "true" : "false");
  {
    std::lock_guard<std::mutex> lock(diag_mutex);
    bool first = true;
    for (const auto& kv : diag) {
      std::printf("%s\"%s\": \"%s\"", first ? "" : ", ", kv.first.c_str(), kv.second.c_str());
      first = false;
    }
  }
  std::printf("}}\n");
  std::fflush(stdout);
  return 0;
}
