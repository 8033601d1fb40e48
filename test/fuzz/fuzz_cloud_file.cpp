// libFuzzer target: the point-cloud reader (PCD in all encodings, PLY ascii and binary, text).
// The first byte picks the format; the rest is the file.
#include "fuzz_input_file.h"

#include <fruit_shape_completion/instrument/cloud_io.h>

#include <cmath>
#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  static const char* kExtensions[] = {"pcd", "ply", "xyz"};
  const std::string path = fuzz::writeInput(data + 1, size - 1, std::string("cloud.") + kExtensions[data[0] % 3]);
  const auto file = fruit_shape_completion::readPointCloud(path);
  // A reader's promise: an error, or points (non-finite ones allowed, the pipeline counts them).
  if (!file.error.empty() && !file.points.empty()) std::abort();
  return 0;
}
