#include <fruit_shape_completion/depth_edges.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace fruit_shape_completion {

namespace {

bool isEdge(const float* depth, std::size_t stride, int width, int height, int u, int v, const DepthEdgeParams& params) {
  const float z = depth[(static_cast<std::size_t>(v) * width + u) * stride];
  if (!std::isfinite(z)) return false;
  const double limit = params.absolute + params.relative * z;
  for (int vv = std::max(0, v - 1); vv <= std::min(height - 1, v + 1); ++vv)
    for (int uu = std::max(0, u - 1); uu <= std::min(width - 1, u + 1); ++uu) {
      const float n = depth[(static_cast<std::size_t>(vv) * width + uu) * stride];
      if (std::isfinite(n) && std::abs(n - z) > limit) return true;
    }
  return false;
}

}  // namespace

void DepthEdgeParams::validate() const {
  if (!(absolute >= 0.0 && std::isfinite(absolute))) throw std::invalid_argument("depth edge absolute must be >= 0");
  if (!(relative >= 0.0 && std::isfinite(relative))) throw std::invalid_argument("depth edge relative must be >= 0");
}

std::vector<std::uint8_t> depthEdges(const std::vector<float>& depth, int width, int height,
                                     const DepthEdgeParams& params) {
  std::vector<std::uint8_t> edge(depth.size(), 0);
  if (width <= 0 || height <= 0 || depth.size() != static_cast<std::size_t>(width) * height) return edge;
  for (int v = 0; v < height; ++v)
    for (int u = 0; u < width; ++u)
      edge[static_cast<std::size_t>(v) * width + u] = isEdge(depth.data(), 1, width, height, u, v, params) ? 1 : 0;
  return edge;
}

std::size_t clearDepthEdges(const float* depth, std::size_t stride, int width, int height,
                            std::vector<std::uint8_t>* mask, const DepthEdgeParams& params) {
  if (width <= 0 || height <= 0 || mask->size() != static_cast<std::size_t>(width) * height) return 0;
  std::size_t cleared = 0;
  for (int v = 0; v < height; ++v)
    for (int u = 0; u < width; ++u) {
      std::uint8_t& m = (*mask)[static_cast<std::size_t>(v) * width + u];
      if (m && isEdge(depth, stride, width, height, u, v, params)) {
        m = 0;
        ++cleared;
      }
    }
  return cleared;
}

}  // namespace fruit_shape_completion
