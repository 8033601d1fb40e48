#pragma once
// Which views saw which fruit, for the fruit report and the volume interval (a fruit seen in few
// views keeps their depth errors; volume_interval.h): a view saw a fruit when at least three of
// its fruit points lie within 1 cm of the fruit's fitted surface. Views are matched at the next
// update against that update's fruits; a fruit fitted for the first time is also matched against
// the last `kept_views` views, so that the views that found it count. Memory is bounded: each
// view keeps at most `points_per_view` of its points, and only the last `kept_views` views.
// Frames from one camera pose are one view: upstream's planner inserts every frame while the arm
// stands still (insert_scan_if_not_moved, on by default), and a fruit seen from one place would
// count as seen in many, its interval narrowed as if many views' depth errors averaged out.
// A saved map carries its fruits' counts (CarriedSightings): the map fused those views, and a
// fruit of a loaded map is as pinned down as it was when saved, not as if seen once.
#include <fruit_shape_completion/fruit_report.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <deque>
#include <map>
#include <set>
#include <string>
#include <vector>

namespace fruit_shape_completion {

// Whether two camera poses lie within `move` [m] and `turn` [rad] of each other (false if either
// is not finite).
bool posesWithin(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double move, double turn);

// A fruit's centre and the views that had seen it, kept with a saved map.
struct CarriedSightings {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  FruitSightings seen;
};
// The records as bytes appended after a map file, and read back; false with a message if the
// bytes are not such records (empty bytes: none, true).
void appendCarriedSightings(const std::vector<CarriedSightings>& carried, std::string* bytes);
constexpr int kMaxCarriedViews = 1000000;  // a count above this is no file this package wrote
bool readCarriedSightings(const std::string& bytes, std::vector<CarriedSightings>* carried, std::string* error);

class FruitSightingLog {
 public:
  explicit FruitSightingLog(std::size_t kept_views = 64, std::size_t points_per_view = 256);
  // A frame whose camera lies within kSamePoseMove and kSamePoseTurnDeg of the pose that began
  // the current view belongs to that view.
  static constexpr double kSamePoseMove = 0.02;     // [m]
  static constexpr double kSamePoseTurnDeg = 5.0;
  static bool samePose(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
    return posesWithin(a, b, kSamePoseMove, kSamePoseTurnDeg * M_PI / 180.0);
  }
  void addView(double time, const PointList& fruit_points, const Eigen::Isometry3d& sensor_pose);
  // Matches the waiting views with an update's fruits; `not_accepted` are that update's other
  // fruits: matched to no view, their counts kept for a save (a fruit a leaf grew into).
  void update(const std::vector<FruitEstimate>& fruits, const std::vector<FruitEstimate>& not_accepted = {});
  const std::map<int, FruitSightings>& sightings() const { return sightings_; }
  // Sets each accepted fruit's views from the log and its volume interval from them: a fruit seen
  // in few keeps their depth errors (volume_interval.h). One the log matched no view to (a
  // loaded map's fruit the saved counts did not cover, until a view sees it) reads as seen in one.
  void countViews(std::vector<FruitEstimate>* fruits) const;
  // Clears the log (as clear()) and keeps a loaded map's records: fruits fitted for the first
  // time start from the counts of the records within kCarryRadius of their centres (nearest
  // pairs first, each record used once).
  void carryOver(std::vector<CarriedSightings> carried);
  static constexpr double kCarryRadius = 0.02;  // [m]
  // For a save: the last update's counted fruits (those not accepted in it too) at their last
  // accepted centres, and the records no fruit has claimed yet. Ids the last update no longer
  // had (a fragment merged into its fruit) are left out.
  std::vector<CarriedSightings> carried() const;
  void clear();

 private:
  struct View {
    double time, last_time;  // of its first and last frame
    std::uint64_t pose;      // which camera pose: frames from one share it
    PointList points;
    // Their bounds: a fruit out of reach of the box is skipped without a look at each point
    // (a row holds hundreds of fruits, a view sees a few).
    Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = Eigen::Vector3d::Zero();
  };
  static bool saw(const View& view, const FruitEstimate& fruit);
  void claimCarried(const std::vector<const FruitEstimate*>& fresh);
  void record(const View& view, int fruit_id, FruitSightings* s);
  std::size_t kept_views_, points_per_view_;
  std::uint64_t pose_ = 0;  // the current pose's number; 0: none yet
  Eigen::Isometry3d pose_start_ = Eigen::Isometry3d::Identity();  // where it began
  bool pose_start_valid_ = false;  // false after a pose that was not finite
  std::map<int, std::uint64_t> last_pose_;  // per fruit, the pose it was last counted from
  std::deque<View> pending_, kept_;  // not yet matched; matched (the newest kept_views_)
  std::map<int, FruitSightings> sightings_;
  std::vector<CarriedSightings> unclaimed_;  // a loaded map's records no fruit has claimed
  std::map<int, Eigen::Vector3d> centers_;    // per fruit, its last accepted centre
  std::set<int> alive_;                       // the ids of the last update's fruits
};

}  // namespace fruit_shape_completion
