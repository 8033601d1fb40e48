#include <fruit_shape_completion/fruit_sightings.h>
#include <fruit_shape_completion/volume_interval.h>

#include <algorithm>
#include <string>
#include <cmath>
#include <cstring>

namespace fruit_shape_completion {

FruitSightingLog::FruitSightingLog(std::size_t kept_views, std::size_t points_per_view)
    : kept_views_(std::max<std::size_t>(1, kept_views)), points_per_view_(std::max<std::size_t>(1, points_per_view)) {}

bool posesWithin(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double move, double turn) {
  return a.matrix().allFinite() && b.matrix().allFinite() && (a.translation() - b.translation()).norm() < move &&
         Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle() < turn;
}

void FruitSightingLog::addView(double time, const PointList& fruit_points, const Eigen::Isometry3d& sensor_pose) {
  const bool finite = sensor_pose.matrix().allFinite();
  const bool same_pose = pose_ > 0 && pose_start_valid_ && samePose(sensor_pose, pose_start_);
  if (!same_pose) {
    ++pose_;
    pose_start_valid_ = finite;  // a pose that is not finite is never the same as another
    if (finite) pose_start_ = sensor_pose;
  }
  const std::size_t n = fruit_points.size(), keep = std::min(n, points_per_view_);
  PointList points;
  points.reserve(keep);
  for (std::size_t i = 0; i < keep; ++i) {
    const Point& p = fruit_points[i * n / keep];
    if (p.allFinite()) points.push_back(p);
  }
  if (points.empty()) return;  // nothing a fruit could be matched with
  // The frames of one pose wait as one entry: upstream's frames at a pose would otherwise fill
  // the log, and the fruit a later fit finds first would lose the poses that saw it.
  auto widen = [](View* v, const Point& p) {
    v->lo = v->lo.cwiseMin(p);
    v->hi = v->hi.cwiseMax(p);
  };
  if (same_pose && !pending_.empty() && pending_.back().pose == pose_) {
    View* v = &pending_.back();
    v->last_time = std::max(v->last_time, time);
    for (std::size_t i = 0; i < points.size() && v->points.size() < points_per_view_; ++i) {
      v->points.push_back(points[i]);
      widen(v, points[i]);
    }
  } else {
    pending_.push_back(View{time, time, pose_, std::move(points)});
    View* v = &pending_.back();
    v->lo = v->hi = v->points.front();
    for (const auto& p : v->points) widen(v, p);
  }
  // Fits may fall behind the views: the oldest unmatched views go first.
  while (pending_.size() > kept_views_) pending_.pop_front();
}

namespace {

constexpr char kCarriedMagic[8] = {'F', 'S', 'C', 'V', 'I', 'E', 'W', '1'};
constexpr std::size_t kCarriedRecordBytes = 3 * 8 + 4 + 2 * 8;

}  // namespace

void appendCarriedSightings(const std::vector<CarriedSightings>& carried, std::string* bytes) {
  auto put = [bytes](const void* p, std::size_t n) { bytes->append(static_cast<const char*>(p), n); };
  const std::uint64_t count = carried.size();
  put(kCarriedMagic, 8);
  put(&count, 8);
  for (const auto& c : carried) {
    const double xyz[3] = {c.center.x(), c.center.y(), c.center.z()};
    const std::int32_t views = c.seen.views;
    put(xyz, sizeof(xyz));
    put(&views, 4);
    put(&c.seen.first_seen, 8);
    put(&c.seen.last_seen, 8);
  }
}

bool readCarriedSightings(const std::string& bytes, std::vector<CarriedSightings>* carried, std::string* error) {
  carried->clear();
  if (bytes.empty()) return true;  // a map saved without them
  std::size_t at = 0;
  auto get = [&](void* p, std::size_t n) {
    if (bytes.size() - at < n) return false;
    std::memcpy(p, bytes.data() + at, n);
    at += n;
    return true;
  };
  char magic[8];
  std::uint64_t count = 0;
  if (!get(magic, 8) || std::memcmp(magic, kCarriedMagic, 8) != 0 || !get(&count, 8)) {
    *error = "the bytes after the map are not the fruits' view counts";
    return false;
  }
  if (count != (bytes.size() - at) / kCarriedRecordBytes || (bytes.size() - at) % kCarriedRecordBytes != 0) {
    *error = "the fruits' view counts are truncated or followed by other bytes";
    return false;
  }
  std::vector<CarriedSightings> out(count);
  for (auto& c : out) {
    double xyz[3];
    std::int32_t views = 0;
    get(xyz, sizeof(xyz));
    get(&views, 4);
    get(&c.seen.first_seen, 8);
    get(&c.seen.last_seen, 8);
    c.center = Eigen::Vector3d(xyz[0], xyz[1], xyz[2]);
    c.seen.views = views;
    auto stamp = [](double t) { return std::isnan(t) || std::isfinite(t); };  // NaN: never seen
    if (!c.center.allFinite() || views <= 0 || views > kMaxCarriedViews || !stamp(c.seen.first_seen) ||
        !stamp(c.seen.last_seen)) {
      *error = "a fruit's view count record holds a centre or stamp that is not finite, or a count outside 1.." +
               std::to_string(kMaxCarriedViews);
      return false;
    }
  }
  *carried = std::move(out);
  return true;
}

bool FruitSightingLog::saw(const View& view, const FruitEstimate& fruit) {
  const double reach = std::max({fruit.shape.a, fruit.shape.b, fruit.shape.c}) + 0.01;
  if (view.points.empty() || !fruit.shape.t.allFinite() ||
      ((fruit.shape.t.array() + reach) < view.lo.array()).any() || ((fruit.shape.t.array() - reach) > view.hi.array()).any())
    return false;
  int near = 0;
  for (const auto& p : view.points) {
    if ((p - fruit.shape.t).squaredNorm() > reach * reach) continue;
    const double d = fruit.shape.radialDistance(p);
    if (std::isfinite(d) && std::abs(d) <= 0.01 && ++near >= 3) return true;
  }
  return false;
}

void FruitSightingLog::record(const View& view, int fruit_id, FruitSightings* s) {
  std::uint64_t& last = last_pose_[fruit_id];
  if (last != view.pose) ++s->views;  // views of one pose are consecutive
  last = view.pose;
  if (!(s->first_seen <= view.time)) s->first_seen = view.time;  // NaN compares false
  if (!(s->last_seen >= view.last_time)) s->last_seen = view.last_time;
}

void FruitSightingLog::claimCarried(const std::vector<const FruitEstimate*>& fresh) {
  // Nearest pairs first over all new fruits, so that a fragment fitted first does not take the
  // record of the fruit beside it.
  struct Pair {
    double distance;
    std::size_t fruit, record;
  };
  std::vector<Pair> pairs;
  for (std::size_t i = 0; i < fresh.size(); ++i)
    for (std::size_t r = 0; r < unclaimed_.size(); ++r) {
      const double d = (unclaimed_[r].center - fresh[i]->shape.t).norm();
      if (d <= kCarryRadius) pairs.push_back({d, i, r});
    }
  std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) { return a.distance < b.distance; });
  std::vector<char> fruit_done(fresh.size(), 0), record_done(unclaimed_.size(), 0);
  for (const Pair& p : pairs) {
    if (fruit_done[p.fruit] || record_done[p.record]) continue;
    fruit_done[p.fruit] = record_done[p.record] = 1;
    sightings_[fresh[p.fruit]->id] = unclaimed_[p.record].seen;
  }
  std::size_t kept = 0;
  for (std::size_t r = 0; r < unclaimed_.size(); ++r)
    if (!record_done[r]) unclaimed_[kept++] = unclaimed_[r];
  unclaimed_.resize(kept);
}

void FruitSightingLog::update(const std::vector<FruitEstimate>& fruits, const std::vector<FruitEstimate>& not_accepted) {
  alive_.clear();
  for (const auto* list : {&fruits, &not_accepted})
    for (const auto& f : *list) alive_.insert(f.id);
  // New fruits (no counts yet), before a loaded map's records give some of them counts.
  std::vector<char> is_new(fruits.size(), 0);
  std::vector<const FruitEstimate*> fresh;
  for (std::size_t i = 0; i < fruits.size(); ++i) {
    const FruitEstimate& f = fruits[i];
    if (!f.accepted || sightings_.count(f.id)) continue;
    is_new[i] = 1;
    if (f.shape.t.allFinite()) fresh.push_back(&f);
  }
  if (!unclaimed_.empty() && !fresh.empty()) claimCarried(fresh);
  for (std::size_t i = 0; i < fruits.size(); ++i) {
    const FruitEstimate& f = fruits[i];
    if (!f.accepted) continue;
    if (f.shape.t.allFinite()) centers_[f.id] = f.shape.t;
    FruitSightings& s = sightings_[f.id];
    if (is_new[i])  // the views that found it may already be matched
      for (const auto& v : kept_)
        if (saw(v, f)) record(v, f.id, &s);
    for (const auto& v : pending_)
      if (saw(v, f)) record(v, f.id, &s);
  }
  for (auto& v : pending_) kept_.push_back(std::move(v));
  pending_.clear();
  while (kept_.size() > kept_views_) kept_.pop_front();
}

void FruitSightingLog::countViews(std::vector<FruitEstimate>* fruits) const {
  for (auto& f : *fruits) {
    if (!f.accepted) continue;
    const auto it = sightings_.find(f.id);
    f.views = std::max(1, it == sightings_.end() ? 0 : it->second.views);
    const VolumeInterval ci = volumeInterval90(f);
    f.volume_lo = ci.lo;
    f.volume_hi = ci.hi;
  }
}

void FruitSightingLog::carryOver(std::vector<CarriedSightings> carried) {
  clear();
  unclaimed_ = std::move(carried);
}

std::vector<CarriedSightings> FruitSightingLog::carried() const {
  std::vector<CarriedSightings> out = unclaimed_;
  for (const auto& [id, seen] : sightings_) {
    const auto c = centers_.find(id);
    if (seen.views > 0 && c != centers_.end() && alive_.count(id)) out.push_back(CarriedSightings{c->second, seen});
  }
  return out;
}

void FruitSightingLog::clear() {
  unclaimed_.clear();
  centers_.clear();
  alive_.clear();
  pending_.clear();
  kept_.clear();
  sightings_.clear();
  last_pose_.clear();
  pose_ = 0;
  pose_start_valid_ = false;
}

}  // namespace fruit_shape_completion
