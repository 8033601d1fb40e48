#include <fruit_shape_completion/hsi_red_test.h>
#include <fruit_shape_completion/instrument/sim/fruit_mask.h>

#include <algorithm>
#include <cmath>

namespace fruit_shape_completion {
namespace sim {

namespace {
void toHsv(double r, double g, double b, double* h, double* s, double* v) {
  const double mx = std::max({r, g, b}), mn = std::min({r, g, b}), d = mx - mn;
  *v = mx;
  *s = mx > 0 ? d / mx : 0.0;
  if (d <= 0) {
    *h = 0;
    return;
  }
  double hue;
  if (mx == r) hue = std::fmod((g - b) / d, 6.0);
  else if (mx == g) hue = (b - r) / d + 2.0;
  else hue = (r - g) / d + 4.0;
  hue *= 60.0;
  *h = hue < 0 ? hue + 360.0 : hue;
}
}  // namespace

bool RedThreshold::isRed(std::uint8_t r, std::uint8_t g, std::uint8_t b) const {
  if (test == Test::kUpstream) return HsiRedTest().isRed(r, g, b);
  if (r <= g || r <= b) return false;  // red is the largest channel of every red hue
  double h, s, v;
  toHsv(r / 255.0, g / 255.0, b / 255.0, &h, &s, &v);
  return (h <= max_hue_deg || h >= 360.0 - max_hue_deg) && s >= min_saturation && v >= min_value;
}

std::string colorClass(const std::array<std::uint8_t, 3>& rgb) {
  if (RedThreshold().isRed(rgb[0], rgb[1], rgb[2])) return "red";
  double h, s, v;
  toHsv(rgb[0] / 255.0, rgb[1] / 255.0, rgb[2] / 255.0, &h, &s, &v);
  if (h >= 40 && h <= 70 && s >= 0.4) return "yellow";
  return "other";
}

std::vector<std::uint8_t> redMask(const std::vector<std::uint8_t>& rgb, int width, int height,
                                  const RedThreshold& threshold) {
  std::vector<std::uint8_t> mask(static_cast<std::size_t>(width) * height, 0);
  for (std::size_t i = 0; i < mask.size() && 3 * i + 2 < rgb.size(); ++i)
    mask[i] = threshold.isRed(rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]) ? 1 : 0;
  return mask;
}

}  // namespace sim
}  // namespace fruit_shape_completion
