// Fruits from one update to the next: which previous fruit a cluster is (the 1 cm cells their
// points share), whether that fruit's fit still explains it, and the ids of the fruits fitted
// now (FruitShapePipeline; the rest of the pipeline is in fruit_shape_pipeline.cpp).
#include <fruit_shape_completion/fruit_shape_pipeline.h>
#include <fruit_shape_completion/grid_cell.h>

#include <algorithm>

namespace fruit_shape_completion {

namespace {
constexpr double kTrackCell = 0.01;  // cell size for matching clusters between updates
}  // namespace

std::unordered_set<std::uint64_t> FruitShapePipeline::occupiedCells(const PointList& points) {
  std::unordered_set<std::uint64_t> cells;
  cells.reserve(points.size());
  for (const auto& p : points)
    cells.insert(packCellKey(cellOf(p, 1.0 / kTrackCell)));
  return cells;
}

int FruitShapePipeline::bestOverlap(const std::unordered_set<std::uint64_t>& cells) const {
  int best = -1;
  std::size_t best_n = 0;
  for (std::size_t k = 0; k < tracks_.size(); ++k) {
    std::size_t n = 0;
    for (auto cell : cells) n += tracks_[k].cells.count(cell);
    if (n > best_n) {
      best_n = n;
      best = static_cast<int>(k);
    }
  }
  return best;
}

int FruitShapePipeline::stillExplainedBy(const PointList& points, const std::unordered_set<std::uint64_t>& cells,
                                         const std::vector<char>& reused) const {
  // Exactly one previous fruit may share cells with the cluster (not a merge, not a split).
  int only = -1;
  for (std::size_t k = 0; k < tracks_.size(); ++k) {
    bool shares = false;
    for (auto cell : tracks_[k].cells)
      if (cells.count(cell)) {
        shares = true;
        break;
      }
    if (!shares) continue;
    if (only >= 0 || reused[k]) return -1;
    only = static_cast<int>(k);
  }
  if (only < 0) return -1;
  return stillFits(tracks_[only].estimate, tracks_[only].fitted_points, points) ? only : -1;
}

bool FruitShapePipeline::stillFits(const FruitEstimate& fit, std::size_t fitted_points, const PointList& points) const {
  const double tolerance = 1.0 + params_.refit_tolerance;
  return fit.accepted && static_cast<double>(points.size()) <= tolerance * static_cast<double>(fitted_points) &&
         rmsRadialDistance(points, fit.fittedShape()) <= tolerance * std::max(fit.rms, 0.001);
}

void FruitShapePipeline::assignIds(std::vector<Track>* fitted, std::vector<char>* reused_tracks) {
  // Largest overlap first, one to one; the rest get new ids.
  std::vector<Track>& pending = *fitted;
  std::vector<char>& reused = *reused_tracks;
  struct Pair {
    std::size_t overlap;
    int fruit, track;
  };
  std::vector<Pair> pairs;
  for (std::size_t f = 0; f < pending.size(); ++f)
    for (std::size_t k = 0; k < tracks_.size(); ++k) {
      if (reused[k]) continue;
      std::size_t n = 0;
      for (auto cell : pending[f].cells) n += tracks_[k].cells.count(cell);
      if (n > 0) pairs.push_back({n, static_cast<int>(f), static_cast<int>(k)});
    }
  std::sort(pairs.begin(), pairs.end(), [](const Pair& l, const Pair& r) {
    return l.overlap != r.overlap ? l.overlap > r.overlap : (l.fruit != r.fruit ? l.fruit < r.fruit : l.track < r.track);
  });
  std::vector<int> id(pending.size(), -1);
  for (const auto& p : pairs) {
    if (id[p.fruit] >= 0 || reused[p.track]) continue;
    id[p.fruit] = tracks_[p.track].estimate.id;
    reused[p.track] = 1;
  }
  for (std::size_t f = 0; f < pending.size(); ++f) pending[f].estimate.id = id[f] >= 0 ? id[f] : next_id_++;
}

}  // namespace fruit_shape_completion
