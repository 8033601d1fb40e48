#pragma once
// What a grower opens at the end of a run: one row per accepted fruit with its position,
// volume, shape (angles in degrees, as superellipsoid_msgs/Superellipsoid has them), how many points and views it rests on and when it was first and last seen,
// as CSV or JSON, written atomically (a kill mid-write leaves the previous file).
#include <fruit_shape_completion/fruit_estimate.h>

#include <limits>
#include <map>
#include <string>
#include <vector>

namespace fruit_shape_completion {

// The views whose fruit points fell on a fruit: how many, and their first and last stamps [s].
struct FruitSightings {
  int views = 0;
  double first_seen = std::numeric_limits<double>::quiet_NaN();
  double last_seen = std::numeric_limits<double>::quiet_NaN();
};

// The CSV header's columns, in order.
const std::vector<std::string>& fruitReportColumns();

// Writes the accepted fruits to `path`: JSON if it ends in ".json", CSV if in ".csv"; anything
// else is refused. `sightings` is keyed by fruit id (a fruit without an entry: 0 views, no
// stamps); a fruit whose own `views` were counted reports those, the count its volume interval
// was made from. False with a message naming the file and the reason.
bool writeFruitReport(const std::string& path, const std::vector<FruitEstimate>& fruits,
                      const std::map<int, FruitSightings>& sightings, std::string* error);

}  // namespace fruit_shape_completion
