#pragma once
// The red colour thresholder that cuts fruit pixels out of a colour image (as the paper's
// pipeline does before the TSDF map), and the clouds made from depth + mask.
#include <fruit_shape_completion/instrument/sim/analytic_depth_camera.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace fruit_shape_completion {
namespace sim {

// The red test. kHsv: hue within max_hue_deg of 0 (red), enough saturation and brightness.
// kUpstream: pointcloud_roi's test, the product's HsiRedTest (hsi_red_test.h).
struct RedThreshold {
  enum class Test { kHsv, kUpstream };
  Test test = Test::kHsv;
  double max_hue_deg = 20.0;
  double min_saturation = 0.5;
  double min_value = 0.12;  // 0..1
  bool isRed(std::uint8_t r, std::uint8_t g, std::uint8_t b) const;
};

// "red", "yellow" or "other", from a material colour.
std::string colorClass(const std::array<std::uint8_t, 3>& rgb);

// One byte per pixel: 1 where the pixel is red.
std::vector<std::uint8_t> redMask(const std::vector<std::uint8_t>& rgb, int width, int height,
                                  const RedThreshold& threshold = RedThreshold());

}  // namespace sim
}  // namespace fruit_shape_completion
