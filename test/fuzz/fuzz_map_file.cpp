// libFuzzer target: TsdfMap::load, which must refuse a bad file and leave the map unchanged,
// and the fruits' view counts a saved map carries after it (refused with a message or read).
#include "fuzz_input_file.h"

#include <fruit_shape_completion/fruit_sightings.h>
#include <fruit_shape_completion/tsdf_map.h>

#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::writeInput(data, size, "map.tsdf");
  fruit_shape_completion::TsdfMap map;
  std::string error, rest;
  const bool ok = map.load(path, &error, &rest);
  if (!ok && error.empty()) std::abort();                      // a refusal always says why
  if (!ok && map.observedVoxelCount() != 0) std::abort();     // and leaves the map as it was
  if (ok) {
    std::vector<fruit_shape_completion::CarriedSightings> carried;
    std::string why;
    if (!fruit_shape_completion::readCarriedSightings(rest, &carried, &why) && why.empty()) std::abort();
    for (const auto& c : carried)
      if (!c.center.allFinite() || c.seen.views <= 0) std::abort();  // only records the log can use
  }
  return 0;
}
