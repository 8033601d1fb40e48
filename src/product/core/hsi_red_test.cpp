#include <fruit_shape_completion/hsi_red_test.h>

#include <algorithm>
#include <cmath>

namespace fruit_shape_completion {

bool HsiRedTest::brightAndSaturated(std::uint8_t r, std::uint8_t g, std::uint8_t b) const {
  // The integer tests first: most pixels (dark, grey) fail them without an atan2.
  const int intensity = (r + g + b) / 3;
  if (intensity < min_intensity) return false;
  const int lowest = std::min(r, std::min(g, b));
  const int saturation = intensity == 0 ? 0 : 255 - lowest * 255 / intensity;
  return saturation >= min_saturation;
}

bool HsiRedTest::hueInBand(int twice_r_minus_g_b, int g_minus_b) const {
  const float hx = static_cast<float>(twice_r_minus_g_b) / 4.0f;
  const float hy = static_cast<float>(g_minus_b) * 111.0f / 255.0f;
  // hx <= 0 puts the hue at a quarter turn or beyond, outside any band narrower than that; but
  // a grey pixel (hx = hy = 0) has atan2's hue 0, as in PCL.
  if (!(hx > 0.0f) && !(hx == 0.0f && hy == 0.0f) && min_hue > -64 && max_hue < 64) return false;
  const double h = std::atan2(hy, hx) * 128.0f / M_PI;
  const int hue = h >= 128.0 ? -128 : static_cast<int>(h);  // PCL's int8 cast wraps +128 to -128
  return hue >= min_hue && hue <= max_hue;
}

TabulatedRedTest::TabulatedRedTest(const HsiRedTest& test) : test_(test), hue_bits_((1021 * 511 + 63) / 64, 0) {
  for (int i = 0; i < 1021; ++i)
    for (int j = 0; j < 511; ++j)
      if (test_.hueInBand(i - 510, j - 255)) {
        const std::uint32_t k = static_cast<std::uint32_t>(i * 511 + j);
        hue_bits_[k >> 6] |= std::uint64_t(1) << (k & 63);
      }
}

}  // namespace fruit_shape_completion
