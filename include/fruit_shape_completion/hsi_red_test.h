#pragma once
// pointcloud_roi's red test (RedClusterFilter): PCL's packed HSI of a colour, fruit unless
// hue < -20 or hue > 35 (1/128 half-turns), saturation < 30 or intensity < 30 (0-255). The
// arithmetic follows pcl::PackedHSIComparison step for step (float hue components, truncated
// hue), so a pixel is fruit here exactly when the upstream filter keeps it.
#include <cstdint>
#include <vector>

namespace fruit_shape_completion {

struct HsiRedTest {
  int min_hue = -20, max_hue = 35;
  int min_saturation = 30, min_intensity = 30;
  bool isRed(std::uint8_t r, std::uint8_t g, std::uint8_t b) const {
    return brightAndSaturated(r, g, b) && hueInBand(2 * r - g - b, g - b);
  }
  bool brightAndSaturated(std::uint8_t r, std::uint8_t g, std::uint8_t b) const;
  // The hue depends on the colour through 2r - g - b and g - b only.
  bool hueInBand(int twice_r_minus_g_b, int g_minus_b) const;
};

// The same test with the hue band tabulated over (2r - g - b, g - b): one bit each, 64 KiB
// built once, and no atan2 per pixel (it was a third of a camera frame's input stage).
class TabulatedRedTest {
 public:
  explicit TabulatedRedTest(const HsiRedTest& test = HsiRedTest());
  bool isRed(std::uint8_t r, std::uint8_t g, std::uint8_t b) const {
    if (!test_.brightAndSaturated(r, g, b)) return false;
    const std::uint32_t i = static_cast<std::uint32_t>((2 * r - g - b + 510) * 511 + (g - b + 255));
    return (hue_bits_[i >> 6] >> (i & 63)) & 1u;
  }
  const HsiRedTest& test() const { return test_; }

 private:
  HsiRedTest test_;
  std::vector<std::uint64_t> hue_bits_;
};

}  // namespace fruit_shape_completion
