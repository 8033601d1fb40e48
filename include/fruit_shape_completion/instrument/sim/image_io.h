#pragma once
// PNG output of camera images (libpng): 8-bit RGB, 8-bit grey, 16-bit grey (depth in mm).
// TGA input of mesh textures (the plant models' format).
#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace fruit_shape_completion {
namespace sim {

// channels 1 or 3; bit_depth 8 (data as bytes) or 16 (data as native uint16 values).
bool writePng(const std::string& path, int width, int height, int channels, int bit_depth,
              const void* data, std::string* error);

struct RgbaImage {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgba;  // 4 bytes per pixel, top row first
  bool has_alpha = false;          // the file carried an alpha channel
  // Nearest texel at texture coordinates (u, v), wrapped into [0, 1); v = 0 is the bottom row,
  // as in COLLADA/OpenGL.
  std::array<std::uint8_t, 4> texel(double u, double v) const;
};

// Truecolour (24/32 bit) or greyscale (8 bit) TGA, uncompressed or run-length encoded, either
// row order. On failure returns false and sets *error to the file and the problem.
bool readTga(const std::string& path, RgbaImage* image, std::string* error);

}  // namespace sim
}  // namespace fruit_shape_completion
