#pragma once
// PNG output of camera images (libpng): 8-bit RGB, 8-bit grey, 16-bit grey (depth in mm).
#include <cstdint>
#include <string>
#include <vector>

namespace fruit_shape_completion {
namespace sim {

// channels 1 or 3; bit_depth 8 (data as bytes) or 16 (data as native uint16 values).
bool writePng(const std::string& path, int width, int height, int channels, int bit_depth,
              const void* data, std::string* error);

}  // namespace sim
}  // namespace fruit_shape_completion
