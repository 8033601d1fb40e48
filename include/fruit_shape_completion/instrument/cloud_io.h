#pragma once
// Point cloud files: PCD (via PCL), PLY (ascii or binary, vertex x y z) and plain text
// (`x y z` per line, extra columns ignored, '#' comments). Errors come back as text naming the
// file and the problem; nothing throws.
#include <fruit_shape_completion/types.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace fruit_shape_completion {

struct CloudFile {
  PointList points;   // as read, non-finite points included (the pipeline counts and skips them)
  std::string error;  // empty on success
  bool ok() const { return error.empty(); }
};

// The format is chosen by extension: .pcd, .ply, anything else is text.
CloudFile readPointCloud(const std::string& path);

// One point per occupied cube of side `leaf` [m] (the centroid of its points; PCL's voxel
// grid, one grid over the whole cloud however large or far from the origin): a raw camera
// cloud thinned toward the spacing the map's surface has. Non-finite points are dropped;
// leaf <= 0 returns the finite points as they are.
PointList thinCloud(const PointList& points, double leaf);

// ASCII PLY; `colors` empty or one RGB per point.
bool writePly(const std::string& path, const PointList& points,
              const std::vector<std::array<std::uint8_t, 3>>& colors, std::string* error);

}  // namespace fruit_shape_completion
