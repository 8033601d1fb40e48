#pragma once
// Pixels at depth discontinuities of an organized depth image. A blurred depth image (and a
// real sensor's flying pixels) gives the pixels along an object's outline depths between the
// object and what lies behind it; kept in a fruit mask, those points hang off the fruit like a
// skirt and glue neighbouring fruits into one cluster.
#include <cstdint>
#include <vector>

namespace fruit_shape_completion {

struct DepthEdgeParams {
  // A pixel is an edge if some 8-neighbour's depth differs by more than absolute + relative * z.
  // Far above the sensor noise and what a surface at 80 degrees incidence gives between pixels.
  double absolute = 0.01;  // [m]
  double relative = 0.02;
};

// One byte per pixel, 1 at an edge; pixels without depth (NaN) are never edges and never make one.
std::vector<std::uint8_t> depthEdges(const std::vector<float>& depth, int width, int height,
                                     const DepthEdgeParams& params = DepthEdgeParams());

}  // namespace fruit_shape_completion
