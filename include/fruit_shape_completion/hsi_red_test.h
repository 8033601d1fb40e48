#pragma once
// pointcloud_roi's red test (RedClusterFilter): PCL's packed HSI of a colour, fruit unless
// hue < -20 or hue > 35 (1/128 half-turns), saturation < 30 or intensity < 30 (0-255). The
// arithmetic follows pcl::PackedHSIComparison step for step (float hue components, truncated
// hue), so a pixel is fruit here exactly when the upstream filter keeps it.
#include <cstdint>

namespace fruit_shape_completion {

struct HsiRedTest {
  int min_hue = -20, max_hue = 35;
  int min_saturation = 30, min_intensity = 30;
  bool isRed(std::uint8_t r, std::uint8_t g, std::uint8_t b) const;
};

}  // namespace fruit_shape_completion
