#include <fruit_shape_completion/instrument/sim/image_io.h>

#include <png.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
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

std::array<std::uint8_t, 4> RgbaImage::texel(double u, double v) const {
  if (width <= 0 || height <= 0) return {{0, 0, 0, 0}};
  u -= std::floor(u);
  v -= std::floor(v);
  if (!std::isfinite(u) || !std::isfinite(v)) u = v = 0.0;
  const int x = std::min(width - 1, static_cast<int>(u * width));
  const int y = std::min(height - 1, static_cast<int>((1.0 - v) * height));
  const std::uint8_t* p = &rgba[4 * (static_cast<std::size_t>(y) * width + x)];
  return {{p[0], p[1], p[2], p[3]}};
}

bool readTga(const std::string& path, RgbaImage* image, std::string* error) {
  auto fail = [&](const std::string& what) {
    if (error) *error = path + ": " + what;
    return false;
  };
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail("texture not found or not readable");
  const std::vector<std::uint8_t> file((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (file.size() < 18) return fail("not a TGA file (shorter than its header)");
  const int id_length = file[0], colour_map = file[1], type = file[2];
  const int width = file[12] | file[13] << 8, height = file[14] | file[15] << 8, bpp = file[16], desc = file[17];
  if (colour_map != 0 || !(type == 2 || type == 3 || type == 10 || type == 11))
    return fail("unsupported TGA type " + std::to_string(type) + " (truecolour or grey, plain or RLE only)");
  const bool grey = type == 3 || type == 11, rle = type >= 9;
  if ((grey && bpp != 8) || (!grey && bpp != 24 && bpp != 32))
    return fail("unsupported TGA depth of " + std::to_string(bpp) + " bits");
  if (width == 0 || height == 0 || width > 16384 || height > 16384) return fail("TGA size must be 1-16384 pixels");
  const int bytes = bpp / 8;
  const std::size_t count = static_cast<std::size_t>(width) * height;
  std::size_t at = 18 + static_cast<std::size_t>(id_length);
  // Before allocating: the file must hold the pixels (a run-length packet covers at most 128).
  const std::size_t left = file.size() > at ? file.size() - at : 0;
  if ((!rle && left < count * bytes) || (rle && count > 128 * left)) return fail("TGA pixel data is truncated");
  std::vector<std::uint8_t> raw(count * bytes);
  if (!rle) {
    if (file.size() < at + raw.size()) return fail("TGA pixel data is truncated");
    std::copy(file.begin() + at, file.begin() + at + raw.size(), raw.begin());
  } else {
    for (std::size_t done = 0; done < count;) {
      if (at >= file.size()) return fail("TGA run-length data is truncated");
      const int packet = file[at++];
      const std::size_t n = static_cast<std::size_t>(packet & 0x7f) + 1;
      if (done + n > count) return fail("a TGA run-length packet runs past the image");
      const std::size_t payload = (packet & 0x80) ? bytes : n * bytes;
      if (at + payload > file.size()) return fail("TGA run-length data is truncated");
      for (std::size_t k = 0; k < n; ++k)
        std::copy_n(file.begin() + at + ((packet & 0x80) ? 0 : k * bytes), bytes, raw.begin() + (done + k) * bytes);
      at += payload;
      done += n;
    }
  }
  RgbaImage img;
  img.width = width;
  img.height = height;
  img.has_alpha = bpp == 32;
  img.rgba.resize(4 * count);
  const bool top_first = desc & 0x20, right_first = desc & 0x10;
  for (int row = 0; row < height; ++row)
    for (int col = 0; col < width; ++col) {
      const std::uint8_t* src = &raw[(static_cast<std::size_t>(row) * width + col) * bytes];
      const int y = top_first ? row : height - 1 - row, x = right_first ? width - 1 - col : col;
      std::uint8_t* dst = &img.rgba[4 * (static_cast<std::size_t>(y) * width + x)];
      if (grey) {
        dst[0] = dst[1] = dst[2] = src[0];
        dst[3] = 255;
      } else {  // stored as BGR(A)
        dst[0] = src[2];
        dst[1] = src[1];
        dst[2] = src[0];
        dst[3] = bytes == 4 ? src[3] : 255;
      }
    }
  *image = std::move(img);
  return true;
}

}  // namespace sim
}  // namespace fruit_shape_completion
