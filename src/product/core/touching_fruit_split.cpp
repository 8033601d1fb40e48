// Touching fruits: a cluster that no superellipsoid fits is split in two (recursively), and a
// cluster split before is split again along its previous fits (FruitShapePipeline's
// estimateWithSplit and splitAsBefore; the rest of the pipeline is in fruit_shape_pipeline.cpp).
#include <fruit_shape_completion/fruit_shape_pipeline.h>

#include <algorithm>
#include <cmath>
#include <iterator>

namespace fruit_shape_completion {

namespace {

// Two fits are one fruit when they interpenetrate by more than kOverlapShare of the smaller
// one's extent along the line between their centres: touching fruits do not, so a split whose
// parts do has cut a single fruit into pieces (fits of partly seen fruits bulge a little, which
// the margin leaves to touching pairs).
constexpr double kOverlapShare = 0.5;
bool oneFruit(const Superellipsoid& a, const Superellipsoid& b) {
  const Eigen::Vector3d d = b.t - a.t;
  const double ra = a.surfacePointLocal(a.rotation().transpose() * d).norm();
  const double rb = b.surfacePointLocal(b.rotation().transpose() * -d).norm();
  return ra + rb - d.norm() > kOverlapShare * std::min(ra, rb);
}

bool anyTwoOneFruit(const std::vector<const Superellipsoid*>& fits) {
  for (std::size_t i = 0; i < fits.size(); ++i)
    for (std::size_t j = i + 1; j < fits.size(); ++j)
      if (oneFruit(*fits[i], *fits[j])) return true;
  return false;
}

// A split of an accepted fit must lower the RMS radial residual at least this much (relative).
constexpr double kSplitGain = 0.7;
// Overlapping parts are one fruit unless they lower the RMS below this share of the whole's.
constexpr double kOverlapGain = 0.5;
// One shape over two touching fruits, the smaller at least half the larger across, is at least
// 1.5 times as long as it is wide; single fruits fitted roughly (lobes, blurred rims) rarely
// are. A rough fit less elongated than this is not tried split.
constexpr double kPairElongation = 1.4;
double elongation(const Superellipsoid& s) {
  return std::max({s.a, s.b, s.c}) / std::min({s.a, s.b, s.c});
}

}  // namespace

std::vector<FruitShapePipeline::Track> FruitShapePipeline::splitAsBefore(
    const PointList& points, const std::unordered_set<std::uint64_t>& cells, const std::vector<char>& reused,
    std::vector<Eigen::Vector3d>* normals_out, std::optional<FruitEstimate>* whole_out, PipelineStats* stats) const {
  // The accepted previous fruits with at least half their cells in the cluster: the parts of
  // one split, or fruits of their own that the cluster has grown together (a view saw what
  // joins them). A neighbour that merely shares a cell across a gap is another cluster's;
  // rejected ones (leaf pieces, rough fits) do not stop it: their points are left over below.
  std::vector<int> parts;
  for (std::size_t k = 0; k < tracks_.size(); ++k) {
    std::size_t shared = 0;
    for (auto cell : tracks_[k].cells) shared += cells.count(cell);
    if (shared == 0 || 2 * shared < tracks_[k].cells.size()) continue;
    if (reused[k]) return {};
    if (tracks_[k].estimate.accepted) parts.push_back(static_cast<int>(k));
  }
  if (parts.size() < 2) return {};
  const Track& first = tracks_[parts.front()];
  std::size_t same_split = 0;
  for (const auto& t : tracks_)
    same_split += t.estimate.accepted && t.cluster_signature == first.cluster_signature &&
                  t.cluster_points == first.cluster_points;
  bool one_split = first.split_points != 0 && same_split == parts.size();
  for (int k : parts) {
    const Track& t = tracks_[k];
    one_split = one_split && t.split_points == first.split_points && t.cluster_signature == first.cluster_signature &&
                t.cluster_points == first.cluster_points;
  }
  std::vector<Eigen::Vector3d>& normals = *normals_out;  // of the whole cluster, once a fit needs them
  // Once the cluster has grown since the split was decided, or has just grown together, the
  // whole cluster is fitted first, so that a fruit split in error (or seen in two pieces)
  // merges. Without this, fruits grown together went to the full split, which on three or four
  // of them could lose them all.
  const bool recheck = !one_split || static_cast<double>(points.size()) >
                                         (1.0 + kRecheckGrowth) * static_cast<double>(first.split_points);
  if (recheck) {
    normals = normalsOf(points, stats);
    *whole_out = estimateCluster(points, normals, -1, &tracks_[static_cast<std::size_t>(bestOverlap(cells))], stats);
    ++stats->fitted;
    if ((*whole_out)->accepted && (*whole_out)->rms <= params_.split_rms) {
      Track whole;
      whole.estimate = **whole_out;
      whole.fitted_points = points.size();
      whole.cells = cells;
      return {whole};
    }
  }
  // Each point to the part whose fit explains it better; a point far from every fit (a new
  // fruit grown onto them, a leaf) is left over.
  std::vector<Eigen::VectorXd> distance;
  for (int k : parts) distance.push_back(radialDistances(points, tracks_[k].estimate.shape));
  const std::size_t kLeftOver = parts.size();
  std::vector<std::size_t> label(points.size(), 0);
  std::vector<PointList> part_points(parts.size() + 1);
  for (std::size_t i = 0; i < points.size(); ++i) {
    std::size_t& best = label[i];
    for (std::size_t j = 1; j < parts.size(); ++j)
      if (distance[j][static_cast<Eigen::Index>(i)] < distance[best][static_cast<Eigen::Index>(i)]) best = j;
    if (!(distance[best][static_cast<Eigen::Index>(i)] <= kLeftOverRms * params_.fit.max_rms)) best = kLeftOver;
    part_points[best].push_back(points[i]);
  }
  // Each earlier fruit keeps its fit while that explains its points, or is refitted from it. A
  // fruit this view made worse to fit keeps the fit that explained it before: one blurred view
  // must not lose a mapped fruit. One left with fewer points than a cluster needs was a piece of
  // its neighbours' fits: its points are left over.
  auto normalsOfPart = [&](std::size_t j) {
    if (normals.empty()) normals = normalsOf(points, stats);
    std::vector<Eigen::Vector3d> out;
    for (std::size_t i = 0; i < points.size(); ++i)
      if (label[i] == j) out.push_back(normals[i]);
    return out;
  };
  const std::size_t split_points = recheck ? points.size() : first.split_points;
  struct Piece {
    Track track;
    PointList points;
    const Track* previous;  // the earlier fruit it started from, if any
  };
  std::vector<Piece> pieces;
  int kept = 0;
  for (std::size_t j = 0; j < parts.size(); ++j) {
    const Track& previous = tracks_[parts[j]];
    if (static_cast<int>(part_points[j].size()) < params_.clustering.min_size) {
      part_points[kLeftOver].insert(part_points[kLeftOver].end(), part_points[j].begin(), part_points[j].end());
      continue;
    }
    Piece piece{Track(), std::move(part_points[j]), &previous};
    const PointList& pts = piece.points;
    Track& t = piece.track;
    t.split_points = split_points;
    t.cells = occupiedCells(pts);
    FruitEstimate refit;
    const bool still = stillFits(previous.estimate, previous.fitted_points, pts);
    if (!still) {
      refit = estimateCluster(pts, normalsOfPart(j), -1, &previous, stats);
      ++stats->fitted;
    }
    if (!still && refit.accepted) {
      t.estimate = std::move(refit);
      t.fitted_points = pts.size();
    } else {
      t.estimate = keptEstimate(previous.estimate, pts);
      t.fitted_points = previous.fitted_points;
      kept += still ? 1 : 0;
    }
    pieces.push_back(std::move(piece));
  }
  if (pieces.empty()) return {};
  // What is left over is clustered and fitted on its own (a new fruit grown onto them); its
  // accepted fits join the pieces, so that one overlapping an earlier fruit merges with it.
  std::vector<Track> rejected;
  const PointList& rest = part_points[kLeftOver];
  if (static_cast<int>(rest.size()) >= params_.clustering.min_size) {
    for (const auto& idx : euclideanClusters(rest, params_.clustering)) {
      PointList cluster;
      for (int i : idx) cluster.push_back(rest[static_cast<std::size_t>(i)]);
      for (auto& part : estimateWithSplit(cluster, normalsOf(cluster, stats), 0, stats)) {
        Track t;
        t.estimate = std::move(part.second);
        t.fitted_points = part.first.size();
        t.cells = occupiedCells(part.first);
        t.split_points = split_points;
        if (t.estimate.accepted)
          pieces.push_back(Piece{std::move(t), std::move(part.first), nullptr});
        else
          rejected.push_back(std::move(t));
      }
    }
  }
  // Two fits that interpenetrate are one fruit (seen in two pieces before, or split in error):
  // their points are fitted together, or else the larger piece's fit takes them all.
  for (bool merged = true; merged;) {
    merged = false;
    for (std::size_t a = 0; a < pieces.size() && !merged; ++a)
      for (std::size_t b = a + 1; b < pieces.size() && !merged; ++b) {
        if (!oneFruit(pieces[a].track.estimate.shape, pieces[b].track.estimate.shape)) continue;
        const std::size_t keep = pieces[a].points.size() >= pieces[b].points.size() ? a : b;
        const std::size_t gone = keep == a ? b : a;
        Piece& big = pieces[keep];
        big.points.insert(big.points.end(), pieces[gone].points.begin(), pieces[gone].points.end());
        if (big.previous == nullptr) big.previous = pieces[gone].previous;
        Track& t = big.track;
        t.cells = occupiedCells(big.points);
        FruitEstimate both = estimateCluster(big.points, normalsOf(big.points, stats), -1, big.previous, stats);
        ++stats->fitted;
        if (both.accepted) {
          t.estimate = std::move(both);
          t.fitted_points = big.points.size();
        } else {
          t.estimate = keptEstimate(t.estimate, big.points);
        }
        pieces.erase(pieces.begin() + static_cast<std::ptrdiff_t>(gone));
        merged = true;
      }
  }
  std::vector<Track> out;
  for (auto& piece : pieces) out.push_back(std::move(piece.track));
  for (auto& t : rejected) out.push_back(std::move(t));
  if (out.size() == 1) out.front().split_points = 0;  // one fruit: a cluster of its own
  stats->kept += kept;
  stats->splits += out.size() > 1 ? 1 : 0;
  return out;
}

FruitShapePipeline::Parts FruitShapePipeline::estimateWithSplit(const PointList& points,
                                                                const std::vector<Eigen::Vector3d>& normals, int depth,
                                                                PipelineStats* stats,
                                                                const std::unordered_set<std::uint64_t>* cells,
                                                                const FruitEstimate* fitted_whole, bool split_rough) const {
  FruitEstimate whole;
  if (fitted_whole != nullptr) {
    whole = *fitted_whole;
  } else {
    const int warm = bestOverlap(cells ? *cells : occupiedCells(points));
    whole = estimateCluster(points, normals, -1, warm >= 0 ? &tracks_[warm] : nullptr, stats);
    ++stats->fitted;
  }
  Parts out;
  const int min_part = params_.clustering.min_size;
  // Touching fruits end up in one cluster, which no single superellipsoid fits: split it in
  // two (2-means along its main axis, then one reassignment of points to the fit that explains
  // them better) and keep the split if some part fits.
  // A fit that is accepted but explains its points only roughly may be two small touching
  // fruits fitted as one: its split is tried too, and kept only if it explains them far better.
  const bool suspect =
      split_rough && whole.accepted && whole.rms > params_.split_rms && elongation(whole.shape) >= kPairElongation;
  if ((whole.accepted && !suspect) || !whole.converged || depth >= params_.max_split_depth ||
      static_cast<int>(points.size()) < 2 * min_part) {
    out.emplace_back(points, whole);
    return out;
  }
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : points) mean += p / static_cast<double>(points.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : points) cov += (p - mean) * (p - mean).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov / points.size());
  const Eigen::Vector3d axis = es.eigenvectors().col(2) * std::sqrt(std::max(0.0, es.eigenvalues()(2)));
  Eigen::Vector3d c[2] = {mean - axis, mean + axis};
  std::vector<int> label(points.size(), 0);
  for (int it = 0; it < 10; ++it) {
    Eigen::Vector3d sum[2] = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
    int n[2] = {0, 0};
    for (std::size_t i = 0; i < points.size(); ++i) {
      label[i] = (points[i] - c[1]).squaredNorm() < (points[i] - c[0]).squaredNorm();
      sum[label[i]] += points[i];
      ++n[label[i]];
    }
    if (n[0] == 0 || n[1] == 0) break;
    c[0] = sum[0] / n[0];
    c[1] = sum[1] / n[1];
  }
  // The parts keep the whole cluster's normals: computed once, from the fuller neighbourhoods.
  std::vector<Eigen::Vector3d> part_normals[2];
  auto partition = [&](PointList part[2]) {
    for (int k = 0; k < 2; ++k) {
      part[k].clear();
      part_normals[k].clear();
    }
    for (std::size_t i = 0; i < points.size(); ++i) {
      part[label[i]].push_back(points[i]);
      part_normals[label[i]].push_back(normals[i]);
    }
    return static_cast<int>(part[0].size()) >= min_part && static_cast<int>(part[1].size()) >= min_part;
  };
  PointList part[2];
  if (!partition(part)) {
    out.emplace_back(points, whole);
    return out;
  }
  // Each half starts from the previous fruit it overlaps most, if there is one: touching fruits
  // seen before were usually fitted apart before.
  auto previousOf = [&](const PointList& half) -> const Track* {
    const int k = bestOverlap(occupiedCells(half));
    return k >= 0 ? &tracks_[k] : nullptr;
  };
  // The halves are independent: the second may run beside the first on a thread the update's
  // other clusters no longer need.
  FruitEstimate first[2];
  PipelineStats half_stats[2];
  auto fitHalf = [&](int k) {
    first[k] = estimateCluster(part[k], part_normals[k], -1, previousOf(part[k]), &half_stats[k]);
  };
  runPair(budget_, [&]() { fitHalf(0); }, [&]() { fitHalf(1); });
  stats->addJob(half_stats[0]);
  stats->addJob(half_stats[1]);
  stats->fitted += 2;
  const std::size_t half_points[2] = {part[0].size(), part[1].size()};
  if (first[0].converged && first[1].converged) {
    const Eigen::VectorXd d0 = radialDistances(points, first[0].shape);
    const Eigen::VectorXd d1 = radialDistances(points, first[1].shape);
    for (std::size_t i = 0; i < points.size(); ++i) label[i] = d1[i] < d0[i];
    if (!partition(part)) {
      out.emplace_back(points, whole);
      return out;
    }
  }
  Parts sub[2];
  PipelineStats sub_stats[2];
  auto finishHalf = [&](int k) {
    // A half whose trial fit still explains its reassigned points keeps that fit.
    if (params_.refit_tolerance > 0.0 && stillFits(first[k], half_points[k], part[k])) {
      sub[k].emplace_back(part[k], keptEstimate(first[k], part[k]));
      sub[k].back().second.refitted = true;
      return;
    }
    sub[k] = estimateWithSplit(part[k], part_normals[k], depth + 1, &sub_stats[k]);
  };
  runPair(budget_, [&]() { finishHalf(0); }, [&]() { finishHalf(1); });
  Parts parts = std::move(sub[0]);
  parts.insert(parts.end(), std::make_move_iterator(sub[1].begin()), std::make_move_iterator(sub[1].end()));
  stats->addJob(sub_stats[0]);
  stats->addJob(sub_stats[1]);
  double squares = 0.0;
  int accepted = 0;
  std::vector<const Superellipsoid*> fits;
  for (const auto& pe : parts) {
    squares += pe.first.size() * pe.second.rms * pe.second.rms;
    accepted += pe.second.accepted;
    if (pe.second.accepted) fits.push_back(&pe.second.shape);
  }
  const double split_rms = std::sqrt(squares / static_cast<double>(points.size()));
  // Parts that overlap have cut one fruit that fits a superellipsoid only roughly (blurred rims,
  // lobes): it stays whole and is accepted. Unless the parts explain the points several times
  // better: a half-seen neighbour's fit may bulge into its touching fruit.
  if (whole.rms <= params_.one_fruit_max_rms && split_rms > kOverlapGain * whole.rms &&
      anyTwoOneFruit(fits)) {
    whole.accepted = true;
    whole.reason.clear();
    out.emplace_back(points, whole);
    return out;
  }
  // Keep the split if any part fits: of three merged fruits, the two that fit are found even
  // when the third, half seen, fits nothing yet (the unfit parts stay unaccepted). An accepted
  // whole gives way only to parts that all fit, far better.
  if (accepted == 0 || (suspect && (accepted < static_cast<int>(parts.size()) || split_rms > kSplitGain * whole.rms))) {
    out.emplace_back(points, whole);
    return out;
  }
  ++stats->splits;
  return parts;
}

}  // namespace fruit_shape_completion
