#include <fruit_shape_completion/SuperellipsoidArray.h>
#include <fruit_shape_completion/ros/fruit_publisher.h>

#include <sensor_msgs/point_cloud2_iterator.h>
#include <visualization_msgs/MarkerArray.h>

#include <cmath>
#include <cstring>
#include <sstream>

namespace fruit_shape_completion {
namespace ros_io {

sensor_msgs::PointCloud2 toCloud(const PointList& points, const std::string& frame, const ros::Time& stamp,
                                 const std::vector<std::array<std::uint8_t, 3>>& colors) {
  sensor_msgs::PointCloud2 msg;
  msg.header.frame_id = frame;
  msg.header.stamp = stamp;
  sensor_msgs::PointCloud2Modifier mod(msg);
  const bool rgb = !colors.empty() && colors.size() == points.size();
  if (rgb)
    mod.setPointCloud2FieldsByString(2, "xyz", "rgb");
  else
    mod.setPointCloud2FieldsByString(1, "xyz");
  mod.resize(points.size());
  sensor_msgs::PointCloud2Iterator<float> x(msg, "x"), y(msg, "y"), z(msg, "z");
  for (std::size_t i = 0; i < points.size(); ++i, ++x, ++y, ++z) {
    *x = static_cast<float>(points[i].x());
    *y = static_cast<float>(points[i].y());
    *z = static_cast<float>(points[i].z());
  }
  if (rgb) {
    sensor_msgs::PointCloud2Iterator<std::uint8_t> r(msg, "r"), g(msg, "g"), b(msg, "b");
    for (std::size_t i = 0; i < points.size(); ++i, ++r, ++g, ++b) {
      *r = colors[i][0];
      *g = colors[i][1];
      *b = colors[i][2];
    }
  }
  return msg;
}

bool fromCloud(const sensor_msgs::PointCloud2& msg, PointList* points, std::size_t* non_finite, std::string* error) {
  points->clear();
  *non_finite = 0;
  std::int64_t off[3] = {-1, -1, -1};
  int type[3] = {0, 0, 0};
  const char* names[3] = {"x", "y", "z"};
  for (const auto& f : msg.fields)
    for (int k = 0; k < 3; ++k)
      if (f.name == names[k]) {
        off[k] = f.offset;
        type[k] = f.datatype;
      }
  for (int k = 0; k < 3; ++k) {
    if (off[k] < 0) {
      *error = "cloud has no x, y, z fields";
      return false;
    }
    if (type[k] != sensor_msgs::PointField::FLOAT32 && type[k] != sensor_msgs::PointField::FLOAT64) {
      *error = "cloud x, y, z fields are not float32/float64";
      return false;
    }
  }
  if (msg.is_bigendian) {
    *error = "big-endian clouds are not supported";
    return false;
  }
  // 64-bit products: a lying header must not wrap around and pass the size check.
  const std::uint64_t n = static_cast<std::uint64_t>(msg.width) * msg.height;
  if (msg.point_step == 0 || static_cast<std::uint64_t>(msg.row_step) < static_cast<std::uint64_t>(msg.width) * msg.point_step ||
      static_cast<std::uint64_t>(msg.data.size()) < static_cast<std::uint64_t>(msg.row_step) * msg.height) {
    *error = "cloud data is shorter than its width, height and steps say";
    return false;
  }
  for (int k = 0; k < 3; ++k)
    if (static_cast<std::uint64_t>(off[k]) + (type[k] == sensor_msgs::PointField::FLOAT64 ? 8u : 4u) > msg.point_step) {
      *error = "cloud fields lie outside the point step";
      return false;
    }
  points->reserve(n);
  for (std::uint32_t row = 0; row < msg.height; ++row)
    for (std::uint32_t col = 0; col < msg.width; ++col) {
      const std::uint8_t* p = &msg.data[static_cast<std::size_t>(row) * msg.row_step + static_cast<std::size_t>(col) * msg.point_step];
      double v[3];
      for (int k = 0; k < 3; ++k) {
        if (type[k] == sensor_msgs::PointField::FLOAT32) {
          float f;
          std::memcpy(&f, p + off[k], 4);
          v[k] = f;
        } else {
          std::memcpy(&v[k], p + off[k], 8);
        }
      }
      const Eigen::Vector3d q(v[0], v[1], v[2]);
      if (q.allFinite()) points->push_back(q);
      else ++*non_finite;
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

}  // namespace

FruitPublisher::FruitPublisher(ros::NodeHandle& nh, const std::string& map_frame) : frame_(map_frame) {
  superellipsoids_ = nh.advertise<fruit_shape_completion::SuperellipsoidArray>("superellipsoids", 1, true);
  markers_ = nh.advertise<visualization_msgs::MarkerArray>("fruit_markers", 1, true);
  clusters_ = nh.advertise<sensor_msgs::PointCloud2>("clusters", 1, true);
  missing_ = nh.advertise<sensor_msgs::PointCloud2>("missing_surface", 1, true);
  surface_ = nh.advertise<sensor_msgs::PointCloud2>("tsdf_surface", 1, true);
}

void FruitPublisher::publish(const std::vector<FruitEstimate>& fruits, const PointList& surface, const ros::Time& stamp) {
  fruit_shape_completion::SuperellipsoidArray arr;
  arr.header.frame_id = frame_;
  arr.header.stamp = stamp;
  visualization_msgs::MarkerArray markers;
  visualization_msgs::Marker clear;
  clear.action = visualization_msgs::Marker::DELETEALL;
  markers.markers.push_back(clear);
  PointList cluster_points, missing;
  std::vector<std::array<std::uint8_t, 3>> cluster_colors;
  for (const auto& f : fruits) {
    const auto color = fruitColor(f.id);
    for (const auto& p : f.points) {
      cluster_points.push_back(p);
      cluster_colors.push_back(color);
    }
    if (!f.accepted) continue;
    const Superellipsoid& s = f.shape;
    fruit_shape_completion::SuperellipsoidFit m;
    m.id = f.id;
    m.a = s.a;
    m.b = s.b;
    m.c = s.c;
    m.e1 = s.e1;
    m.e2 = s.e2;
    m.tx = s.t.x();
    m.ty = s.t.y();
    m.tz = s.t.z();
    m.roll = s.rpy.x();
    m.pitch = s.rpy.y();
    m.yaw = s.rpy.z();
    m.volume = f.volume;
    arr.superellipsoids.push_back(m);
    missing.insert(missing.end(), f.missing_surface.begin(), f.missing_surface.end());

    auto marker = [&](const char* ns, int type) {
      visualization_msgs::Marker m;
      m.header = arr.header;
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
    os << "#" << f.id << " " << static_cast<int>(std::round(f.volume * 1e6)) << " cm3";
    label.text = os.str();
    markers.markers.push_back(label);
  }
  superellipsoids_.publish(arr);
  markers_.publish(markers);
  clusters_.publish(toCloud(cluster_points, frame_, stamp, cluster_colors));
  missing_.publish(toCloud(missing, frame_, stamp));
  surface_.publish(toCloud(surface, frame_, stamp));
}

}  // namespace ros_io
}  // namespace fruit_shape_completion
