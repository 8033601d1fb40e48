#pragma once
// Pixels at depth discontinuities of an organized depth image. A blurred depth image (and a
// real sensor's flying pixels) gives the pixels along an object's outline depths between the
// object and what lies behind it; kept in a fruit mask, those points hang off the fruit like a
// skirt and glue neighbouring fruits into one cluster.
#include <cstddef>
#include <cstdint>
#include <vector>

namespace fruit_shape_completion {

struct DepthEdgeParams {
  // A pixel is an edge if some 8-neighbour's depth differs by more than absolute + relative * z.
  // Far above the sensor noise and what a surface at 80 degrees incidence gives between pixels.
  double absolute = 0.01;  // [m]
  double relative = 0.02;
  void validate() const;  // throws std::invalid_argument
};

// One byte per pixel, 1 at an edge; pixels without depth (NaN) are never edges and never make one.
std::vector<std::uint8_t> depthEdges(const std::vector<float>& depth, int width, int height,
                                     const DepthEdgeParams& params = DepthEdgeParams());

// The same test on the pixels of `mask` only (non-zero entries), which are set to 0 where they
// are edges; returns how many were. The depth of pixel i is depth[i * stride] (stride 3 reads
// z out of an organized xyz frame). Testing only the masked pixels keeps a frame whose fruit
// covers a tenth of the image at a tenth of the work.
std::size_t clearDepthEdges(const float* depth, std::size_t stride, int width, int height,
                            std::vector<std::uint8_t>* mask, const DepthEdgeParams& params = DepthEdgeParams());

}  // namespace fruit_shape_completion
