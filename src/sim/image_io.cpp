#include <fruit_shape_completion/sim/image_io.h>

#include <png.h>

#include <cstdio>
#include <vector>

namespace fruit_shape_completion {
namespace sim {

bool writePng(const std::string& path, int width, int height, int channels, int bit_depth,
              const void* data, std::string* error) {
  auto fail = [&](const std::string& what) {
    if (error) *error = path + ": " + what;
    return false;
  };
  if ((channels != 1 && channels != 3) || (bit_depth != 8 && bit_depth != 16) || width <= 0 || height <= 0)
    return fail("unsupported image format");
  FILE* fp = std::fopen(path.c_str(), "wb");
  if (!fp) return fail("cannot open for writing");
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!png || !info || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    std::fclose(fp);
    return fail("PNG encoding failed");
  }
  png_init_io(png, fp);
  png_set_IHDR(png, info, width, height, bit_depth, channels == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_GRAY,
               PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  if (bit_depth == 16) png_set_swap(png);  // PNG stores big-endian; our data is native (little) endian
  const std::size_t row_bytes = static_cast<std::size_t>(width) * channels * (bit_depth / 8);
  const auto* bytes = static_cast<const png_byte*>(data);
  for (int y = 0; y < height; ++y) png_write_row(png, const_cast<png_bytep>(bytes + y * row_bytes));
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return std::fclose(fp) == 0 ? true : fail("write error");
}

}  // namespace sim
}  // namespace fruit_shape_completion
