// libFuzzer target: TsdfMap::load, which must refuse a bad file and leave the map unchanged.
#include "fuzz_input_file.h"

#include <fruit_shape_completion/tsdf_map.h>

#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::writeInput(data, size, "map.tsdf");
  fruit_shape_completion::TsdfMap map;
  std::string error;
  const bool ok = map.load(path, &error);
  if (!ok && error.empty()) std::abort();                      // a refusal always says why
  if (!ok && map.observedVoxelCount() != 0) std::abort();     // and leaves the map as it was
  return 0;
}
