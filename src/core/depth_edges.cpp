#include <fruit_shape_completion/depth_edges.h>

#include <cmath>

namespace fruit_shape_completion {

std::vector<std::uint8_t> depthEdges(const std::vector<float>& depth, int width, int height,
                                     const DepthEdgeParams& params) {
  std::vector<std::uint8_t> edge(depth.size(), 0);
  if (width <= 0 || height <= 0 || depth.size() != static_cast<std::size_t>(width) * height) return edge;
  for (int v = 0; v < height; ++v)
    for (int u = 0; u < width; ++u) {
      const std::size_t px = static_cast<std::size_t>(v) * width + u;
      const float z = depth[px];
      if (!std::isfinite(z)) continue;
      const double limit = params.absolute + params.relative * z;
      for (int dv = -1; dv <= 1 && !edge[px]; ++dv)
        for (int du = -1; du <= 1; ++du) {
          const int uu = u + du, vv = v + dv;
          if (uu < 0 || vv < 0 || uu >= width || vv >= height) continue;
          const float n = depth[static_cast<std::size_t>(vv) * width + uu];
          if (std::isfinite(n) && std::abs(n - z) > limit) {
            edge[px] = 1;
            break;
          }
        }
    }
  return edge;
}

}  // namespace fruit_shape_completion
