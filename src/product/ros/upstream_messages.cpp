#include <fruit_shape_completion/ros/upstream_messages.h>

#include <ros/advertise_options.h>
#include <ros/subscribe_options.h>

namespace fruit_shape_completion {
namespace ros_io {

namespace {

void replaceAll(std::string* text, const std::string& from, const std::string& to) {
  for (std::size_t at = text->find(from); at != std::string::npos; at = text->find(from, at + to.size()))
    text->replace(at, from.size(), to);
}

}  // namespace

std::string upstreamSuperellipsoidArrayDefinition() {
  std::string text = ros::message_traits::definition<fruit_shape_completion::SuperellipsoidArray>();
  replaceAll(&text, "MSG: fruit_shape_completion/SuperellipsoidFit", "MSG: superellipsoid_msgs/Superellipsoid");
  replaceAll(&text, "SuperellipsoidFit[] superellipsoids", "Superellipsoid[] superellipsoids");
  return text;
}

std::string upstreamPointcloudWithRoiDefinition() {
  return ros::message_traits::definition<fruit_shape_completion::PointcloudWithRoi>();
}

ros::Publisher advertiseUpstreamSuperellipsoids(ros::NodeHandle& nh, const std::string& topic, bool latch) {
  ros::AdvertiseOptions options;
  options.init<fruit_shape_completion::SuperellipsoidArray>(topic, 1);
  options.datatype = kUpstreamSuperellipsoidArrayType;
  options.message_definition = upstreamSuperellipsoidArrayDefinition();
  options.latch = latch;
  return nh.advertise(options);
}

ros::Publisher advertiseUpstreamPointcloudWithRoi(ros::NodeHandle& nh, const std::string& topic, std::uint32_t queue_size) {
  ros::AdvertiseOptions options;
  options.init<fruit_shape_completion::PointcloudWithRoi>(topic, queue_size);
  options.datatype = kUpstreamPointcloudWithRoiType;
  options.message_definition = upstreamPointcloudWithRoiDefinition();
  return nh.advertise(options);
}

ros::Subscriber subscribeUpstreamPointcloudWithRoi(
    ros::NodeHandle& nh, const std::string& topic, std::uint32_t queue_size,
    const boost::function<void(const fruit_shape_completion::PointcloudWithRoiConstPtr&)>& callback) {
  ros::SubscribeOptions options;
  options.init<fruit_shape_completion::PointcloudWithRoi>(topic, queue_size, callback);
  options.datatype = kUpstreamPointcloudWithRoiType;
  return nh.subscribe(options);
}

}  // namespace ros_io
}  // namespace fruit_shape_completion
