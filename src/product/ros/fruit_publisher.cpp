#include <fruit_shape_completion/ros/fruit_publisher.h>
#include <fruit_shape_completion/ros/upstream_messages.h>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl_conversions/pcl_conversions.h>
#include <visualization_msgs/MarkerArray.h>

#include <boost/make_shared.hpp>
#include <cmath>
#include <functional>
#include <mutex>
#include <cstring>
#include <type_traits>
#include <sstream>

namespace fruit_shape_completion {
namespace ros_io {

sensor_msgs::PointCloud2 toCloud(const PointList& points, const std::string& frame, const ros::Time& stamp,
                                 const std::vector<std::array<std::uint8_t, 3>>& colors) {
  sensor_msgs::PointCloud2 msg;
  auto fill = [&](auto& cloud) {
    cloud.reserve(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
      typename std::decay_t<decltype(cloud)>::PointType p;
      p.x = static_cast<float>(points[i].x());
      p.y = static_cast<float>(points[i].y());
      p.z = static_cast<float>(points[i].z());
      if constexpr (std::is_same_v<decltype(p), pcl::PointXYZRGB>) {
        p.r = colors[i][0];
        p.g = colors[i][1];
        p.b = colors[i][2];
      }
      cloud.push_back(p);
    }
    pcl::toROSMsg(cloud, msg);
  };
  if (!colors.empty() && colors.size() == points.size()) {
    pcl::PointCloud<pcl::PointXYZRGB> cloud;
    fill(cloud);
  } else {
    pcl::PointCloud<pcl::PointXYZ> cloud;
    fill(cloud);
  }
  msg.header.frame_id = frame;
  msg.header.stamp = stamp;
  return msg;
}

namespace {

// PCL's conversion trusts the header: a message whose sizes lie is refused here first.
bool checkXyzCloud(const sensor_msgs::PointCloud2& msg, std::string* error) {
  // Exactly one float32 each: a repeated name or a count of 3 would leave a coordinate PCL
  // does not match at 0, and the points would be mapped flattened onto a plane.
  int x = 0, y = 0, z = 0;
  for (const auto& f : msg.fields)
    if (f.name == "x" || f.name == "y" || f.name == "z") {
      if (f.datatype != sensor_msgs::PointField::FLOAT32 || f.count != 1 ||
          std::uint64_t(f.offset) + 4 > msg.point_step) {
        *error = "cloud field '" + f.name + "' is not one float32 inside the point step";
        return false;
      }
      ++(f.name == "x" ? x : f.name == "y" ? y : z);
    }
  if (x != 1 || y != 1 || z != 1) {
    *error = "cloud must have one x, one y and one z field (has " + std::to_string(x) + ", " + std::to_string(y) +
             ", " + std::to_string(z) + ")";
    return false;
  }
  if (msg.is_bigendian) {
    *error = "big-endian clouds are not supported";
    return false;
  }
  // 64-bit products: a lying header must not wrap around and pass the size check.
  if (std::uint64_t(msg.row_step) < std::uint64_t(msg.width) * msg.point_step ||
      std::uint64_t(msg.data.size()) < std::uint64_t(msg.row_step) * msg.height) {
    *error = "cloud data is shorter than its width, height and steps say";
    return false;
  }
  return true;
}

}  // namespace

bool fromCloud(const sensor_msgs::PointCloud2& msg, PointList* points, std::size_t* non_finite, std::string* error) {
  points->clear();
  *non_finite = 0;
  if (!checkXyzCloud(msg, error)) return false;
  if (std::uint64_t(msg.width) * msg.height == 0) return true;  // PCL's conversion indexes point 0
  pcl::PointCloud<pcl::PointXYZ> cloud;
  pcl::fromROSMsg(msg, cloud);
  points->reserve(cloud.size());
  for (const auto& p : cloud) {
    const Eigen::Vector3d q(p.x, p.y, p.z);
    if (q.allFinite()) points->push_back(q);
    else ++*non_finite;
  }
  return true;
}

bool fromRoiCloud(const sensor_msgs::PointCloud2& msg, const std::vector<std::int32_t>& indices, PointList* all,
                  PointList* selected, std::size_t* bad_indices, std::string* error) {
  all->clear();
  selected->clear();
  *bad_indices = 0;
  if (!checkXyzCloud(msg, error)) return false;
  if (std::uint64_t(msg.width) * msg.height == 0) {  // PCL's conversion indexes point 0
    *bad_indices = indices.size();
    return true;
  }
  pcl::PointCloud<pcl::PointXYZ> cloud;
  pcl::fromROSMsg(msg, cloud);
  all->reserve(cloud.size());
  for (const auto& p : cloud)
    if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) all->emplace_back(p.x, p.y, p.z);
  selected->reserve(indices.size());
  for (const std::int32_t i : indices) {
    if (i < 0 || static_cast<std::size_t>(i) >= cloud.size()) {
      ++*bad_indices;
      continue;
    }
    const auto& p = cloud[static_cast<std::size_t>(i)];
    if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) selected->emplace_back(p.x, p.y, p.z);
    else ++*bad_indices;
  }
  return true;
}

namespace {

std::array<std::uint8_t, 3> fruitColor(int id) {
  static const std::array<std::uint8_t, 3> palette[8] = {{{230, 25, 75}},  {{60, 180, 75}},  {{255, 225, 25}},
                                                         {{0, 130, 200}},  {{245, 130, 48}}, {{145, 30, 180}},
                                                         {{70, 240, 240}}, {{240, 50, 230}}};
  return palette[(id % 8 + 8) % 8];
}

// The fitted surface as triangles on a latitude/longitude grid of directions.
void surfaceTriangles(const Superellipsoid& se, std::vector<geometry_msgs::Point>* out) {
  const int nt = 16, np = 24;
  std::vector<Eigen::Vector3d> grid((nt + 1) * np);
  for (int i = 0; i <= nt; ++i)
    for (int j = 0; j < np; ++j) {
      const double th = M_PI * i / nt, ph = 2 * M_PI * j / np;
      const Eigen::Vector3d u(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th));
      grid[i * np + j] = se.toWorld(se.surfacePointLocal(u));
    }
  auto add = [out](const Eigen::Vector3d& p) {
    geometry_msgs::Point q;
    q.x = p.x();
    q.y = p.y();
    q.z = p.z();
    out->push_back(q);
  };
  for (int i = 0; i < nt; ++i)
    for (int j = 0; j < np; ++j) {
      const int k = (j + 1) % np;
      add(grid[i * np + j]);
      add(grid[(i + 1) * np + j]);
      add(grid[(i + 1) * np + k]);
      add(grid[i * np + j]);
      add(grid[(i + 1) * np + k]);
      add(grid[i * np + k]);
    }
}

visualization_msgs::MarkerArray fruitMarkers(const std::vector<FruitEstimate>& fruits, const std::string& frame,
                                             const ros::Time& stamp) {
  visualization_msgs::MarkerArray markers;
  visualization_msgs::Marker clear;
  clear.action = visualization_msgs::Marker::DELETEALL;
  markers.markers.push_back(clear);
  for (const auto& f : fruits) {
    if (!f.accepted) continue;
    const Superellipsoid& s = f.shape;
    const auto color = fruitColor(f.id);
    auto marker = [&](const char* ns, int type) {
      visualization_msgs::Marker m;
      m.header.frame_id = frame;
      m.header.stamp = stamp;
      m.ns = ns;
      m.id = f.id;
      m.type = type;
      m.action = visualization_msgs::Marker::ADD;
      m.pose.orientation.w = 1.0;
      return m;
    };
    visualization_msgs::Marker mesh = marker("superellipsoid", visualization_msgs::Marker::TRIANGLE_LIST);
    mesh.scale.x = mesh.scale.y = mesh.scale.z = 1.0;
    mesh.color.r = color[0] / 255.f;
    mesh.color.g = color[1] / 255.f;
    mesh.color.b = color[2] / 255.f;
    mesh.color.a = 0.6f;
    surfaceTriangles(s, &mesh.points);
    markers.markers.push_back(mesh);
    visualization_msgs::Marker label = marker("label", visualization_msgs::Marker::TEXT_VIEW_FACING);
    label.pose.position.x = s.t.x();
    label.pose.position.y = s.t.y();
    label.pose.position.z = s.t.z() + std::max({s.a, s.b, s.c}) + 0.02;
    label.scale.z = 0.02;
    label.color.r = label.color.g = label.color.b = label.color.a = 1.0f;
    std::ostringstream os;
    os << "#" << f.id << " " << static_cast<int>(std::round(f.volume * 1e6));
    if (f.volume_hi > f.volume_lo) os << " +- " << static_cast<int>(std::round(0.5 * (f.volume_hi - f.volume_lo) * 1e6));
    os << " cm3";
    label.text = os.str();
    markers.markers.push_back(label);
  }
  return markers;
}

// Every fruit's points, coloured per fruit (rejected fits' too: they show what was not fitted).
sensor_msgs::PointCloud2 clusterCloud(const std::vector<FruitEstimate>& fruits, const std::string& frame,
                                      const ros::Time& stamp) {
  PointList points;
  std::vector<std::array<std::uint8_t, 3>> colors;
  for (const auto& f : fruits) {
    const auto color = fruitColor(f.id);
    points.insert(points.end(), f.points.begin(), f.points.end());
    colors.insert(colors.end(), f.points.size(), color);
  }
  return toCloud(points, frame, stamp, colors);
}

sensor_msgs::PointCloud2 missingCloud(const std::vector<FruitEstimate>& fruits, const std::string& frame,
                                      const ros::Time& stamp) {
  PointList missing;
  for (const auto& f : fruits)
    if (f.accepted) missing.insert(missing.end(), f.missing_surface.begin(), f.missing_surface.end());
  return toCloud(missing, frame, stamp);
}

}  // namespace

struct FruitPublisher::Visuals {
  enum Topic { kMarkers, kClusters, kMissing, kSurface, kTopics };
  struct State {
    std::vector<FruitEstimate> fruits;  // their points are shared, not copied
    SurfaceBlocks surface;
    ros::Time stamp;
  };
  std::string frame;
  std::array<ros::Publisher, kTopics> topics;

  // publish() on the estimator's thread, connect callbacks on the spinner's. Never held while a
  // message is built or sent (a latched topic serialises the message in publish: megabytes on a
  // row), since a reset waits for publish().
  std::mutex mutex;
  std::array<std::mutex, kTopics> sending;  // one sender per topic at a time, so none overtakes;
                                            // held only by try_lock, so nobody waits for a send
  std::shared_ptr<const State> state = std::make_shared<const State>();
  std::array<bool, kTopics> stale{};  // the latest state is not yet published on this topic
  std::size_t built = 0, failed = 0;  // messages sent; builds or sends that failed

  // The topic's message from `s`, and how to send it.
  std::function<void()> build(int topic, const State& s) const {
    const ros::Publisher& pub = topics[topic];
    switch (topic) {
      case kMarkers: {
        auto m = boost::make_shared<visualization_msgs::MarkerArray>(fruitMarkers(s.fruits, frame, s.stamp));
        return [pub, m] { pub.publish(m); };
      }
      case kClusters: {
        auto m = boost::make_shared<sensor_msgs::PointCloud2>(clusterCloud(s.fruits, frame, s.stamp));
        return [pub, m] { pub.publish(m); };
      }
      case kMissing: {
        auto m = boost::make_shared<sensor_msgs::PointCloud2>(missingCloud(s.fruits, frame, s.stamp));
        return [pub, m] { pub.publish(m); };
      }
      default: {
        auto m = boost::make_shared<sensor_msgs::PointCloud2>(toCloud(s.surface.cloud(), frame, s.stamp));
        return [pub, m] { pub.publish(m); };
      }
    }
  }

  // Publishes the latest state on `topic` if it is not yet: built outside the lock, sent only if
  // no newer state came meanwhile (then built again from that). One sender per topic: a caller
  // that finds another sending leaves it the newer state (it looks again when done) instead of
  // waiting for it. A build or send that fails (out of memory on a large map) leaves the topic
  // stale for the next update or subscriber to retry.
  void bringUpToDate(int topic) {
    for (int round = 0; round < 8; ++round) {
      std::shared_ptr<const State> s;
      {
        std::lock_guard<std::mutex> lock(mutex);
        if (!stale[topic]) return;
        s = state;
      }
      std::function<void()> send;
      try {
        send = build(topic, *s);
      } catch (const std::exception& e) {
        warnFailed(topic, e.what(), s);
        return;
      }
      const std::unique_lock<std::mutex> one_sender(sending[topic], std::try_to_lock);
      if (!one_sender.owns_lock()) return;
      {
        std::lock_guard<std::mutex> lock(mutex);
        if (s != state) continue;
        if (!stale[topic]) return;  // another caller sent this state already
        stale[topic] = false;
      }
      try {
        send();
      } catch (const std::exception& e) {
        warnFailed(topic, e.what(), s);
        return;
      }
      std::lock_guard<std::mutex> lock(mutex);
      ++built;
    }
  }
  void warnFailed(int topic, const char* what, const std::shared_ptr<const State>& s) {
    std::size_t n = 0;
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (s == state) stale[topic] = true;
      n = ++failed;
    }
    ROS_WARN_THROTTLE(10.0, "%s not published: %s (%zu failed so far; the next update tries again)",
                      topics[topic].getTopic().c_str(), what, n);
  }
};

FruitPublisher::FruitPublisher(ros::NodeHandle& nh, const std::string& map_frame, const std::string& superellipsoids_topic)
    : visuals_(std::make_shared<Visuals>()) {
  visuals_->frame = map_frame;
  superellipsoids_ = nh.advertise<superellipsoid_msgs::SuperellipsoidArray>(superellipsoids_topic, 1, true);
  const std::weak_ptr<Visuals> weak = visuals_;
  auto advertise = [&](auto message, const char* name, int topic) {
    // Queued on the node's callback queue, so it never runs inside publish(); the weak pointer
    // lets a callback that outlives this publisher do nothing.
    auto on_connect = [weak, topic](const ros::SingleSubscriberPublisher&) {
      if (const std::shared_ptr<Visuals> v = weak.lock()) v->bringUpToDate(topic);
    };
    visuals_->topics[topic] =
        nh.advertise<decltype(message)>(name, 1, on_connect, ros::SubscriberStatusCallback(), ros::VoidConstPtr(), true);
  };
  advertise(visualization_msgs::MarkerArray(), "fruit_markers", Visuals::kMarkers);
  advertise(sensor_msgs::PointCloud2(), "clusters", Visuals::kClusters);
  advertise(sensor_msgs::PointCloud2(), "missing_surface", Visuals::kMissing);
  advertise(sensor_msgs::PointCloud2(), "tsdf_surface", Visuals::kSurface);
}

void FruitPublisher::publish(std::vector<FruitEstimate> fruits, SurfaceBlocks surface, const ros::Time& stamp) {
  superellipsoid_msgs::SuperellipsoidArray arr;
  arr.header.frame_id = visuals_->frame;
  arr.header.stamp = stamp;
  for (const auto& f : fruits) {
    if (!f.accepted) continue;
    const Superellipsoid& s = f.shape;
    superellipsoid_msgs::Superellipsoid m;
    m.header = arr.header;
    m.id = static_cast<std::uint32_t>(std::max(f.id, 0));
    m.object_tracking = true;
    m.a = s.a;
    m.b = s.b;
    m.c = s.c;
    m.e1 = s.e1;
    m.e2 = s.e2;
    m.tx = s.t.x();
    m.ty = s.t.y();
    m.tz = s.t.z();
    constexpr double kDegrees = 180.0 / M_PI;  // the upstream message's unit
    m.roll = s.rpy.x() * kDegrees;
    m.pitch = s.rpy.y() * kDegrees;
    m.yaw = s.rpy.z() * kDegrees;
    m.volume = f.volume;
    arr.superellipsoids.push_back(m);
  }
  superellipsoids_.publish(arr);

  Visuals& v = *visuals_;
  {
    auto state = std::make_shared<Visuals::State>();
    state->fruits = std::move(fruits);
    state->surface = std::move(surface);
    state->stamp = stamp;
    std::lock_guard<std::mutex> lock(v.mutex);
    v.state = std::move(state);
    v.stale.fill(true);
  }
}

void FruitPublisher::sendVisuals() {
  Visuals& v = *visuals_;
  for (int t = 0; t < Visuals::kTopics; ++t)
    if (v.topics[t].getNumSubscribers() > 0) v.bringUpToDate(t);
}

void FruitPublisher::publish(std::vector<FruitEstimate> fruits, PointList surface, const ros::Time& stamp) {
  SurfaceBlocks blocks;
  if (!surface.empty()) blocks.blocks.push_back({GridCell::Zero(), SharedPoints(std::move(surface))});
  publish(std::move(fruits), std::move(blocks), stamp);
}

std::size_t FruitPublisher::visualsBuilt() const {
  std::lock_guard<std::mutex> lock(visuals_->mutex);
  return visuals_->built;
}

}  // namespace ros_io
}  // namespace fruit_shape_completion
