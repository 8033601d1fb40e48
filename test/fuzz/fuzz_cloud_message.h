#pragma once
// Builds a sensor_msgs/PointCloud2 from fuzzer bytes, field by field as a publisher could send
// it: layout numbers that may disagree with each other and with the data, any field names,
// types and offsets, then the rest as the data. Consumes what it reads from `in`.
#include <sensor_msgs/PointCloud2.h>

#include <cstdint>
#include <cstring>
#include <string>

namespace fuzz {

class Bytes {
 public:
  Bytes(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}
  template <typename T>
  T take() {
    T v{};
    const std::size_t n = std::min(sizeof(T), size_ - at_);
    std::memcpy(&v, data_ + at_, n);
    at_ += n;
    return v;
  }
  std::size_t left() const { return size_ - at_; }
  const std::uint8_t* rest() const { return data_ + at_; }
  void skip(std::size_t n) { at_ += std::min(n, left()); }

 private:
  const std::uint8_t* data_;
  std::size_t size_, at_ = 0;
};

inline sensor_msgs::PointCloud2 takeCloud(Bytes& in) {
  static const char* const kNames[] = {"x", "y", "z", "rgb", "rgba", "intensity", "", "X"};
  sensor_msgs::PointCloud2 msg;
  msg.header.frame_id = (in.take<std::uint8_t>() & 1) ? "world" : "camera";
  msg.height = in.take<std::uint8_t>() % 8;  // small: an organized cloud of a few rows
  msg.width = in.take<std::uint16_t>() % 512;
  msg.point_step = in.take<std::uint8_t>();
  msg.row_step = in.take<std::uint16_t>();
  msg.is_bigendian = in.take<std::uint8_t>() & 1;
  msg.is_dense = in.take<std::uint8_t>() & 1;
  const int fields = in.take<std::uint8_t>() % 7;
  for (int i = 0; i < fields; ++i) {
    sensor_msgs::PointField f;
    f.name = kNames[in.take<std::uint8_t>() % 8];
    f.offset = in.take<std::uint8_t>();
    f.datatype = in.take<std::uint8_t>() % 10;  // 1..8 are valid, 0 and 9 are not
    f.count = in.take<std::uint8_t>() % 3;
    msg.fields.push_back(f);
  }
  const std::size_t n = std::min<std::size_t>(in.left(), in.take<std::uint16_t>());
  msg.data.assign(in.rest(), in.rest() + std::min(n, in.left()));
  in.skip(n);
  return msg;
}

}  // namespace fuzz
