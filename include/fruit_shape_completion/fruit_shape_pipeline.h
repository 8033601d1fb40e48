#pragma once
// Surface cloud in, one superellipsoid per fruit out; called after every view.
//
// Fruits keep their id while they are the same fruit (matched to the previous update's by
// shared occupied 1 cm cells); a cluster whose points did not change is not refitted; a changed
// one starts from its previous fit. A cluster no single superellipsoid fits (touching fruits)
// is split into parts that each fit.
#include <fruit_shape_completion/euclidean_clustering.h>
#include <fruit_shape_completion/fruit_estimate.h>
#include <fruit_shape_completion/missing_surface.h>
#include <fruit_shape_completion/parallel_jobs.h>
#include <fruit_shape_completion/superellipsoid_fit.h>
#include <fruit_shape_completion/surface_blocks.h>
#include <fruit_shape_completion/surface_normals.h>

#include <atomic>
#include <cstdint>
#include <optional>
#include <string>
#include <unordered_set>
#include <vector>

namespace fruit_shape_completion {

struct PipelineParams {
  ClusteringParams clustering;
  NormalParams normals;
  double center_lambda = 2.5;  // pull of the centre prior toward the cluster mean
  // The centre prior lies at most this far [m] behind the deepest seen points, along the way
  // the normals face, where the normal lines scatter (limitToSeenDepth); negative: no limit.
  // Blocky and lobed fruits seen from one side have lines that meet far behind them; a patch
  // seen through a gap in the leaves (its rim a cut in front of the centre) is fitted smaller.
  double center_rim_margin = 0.003;
  // A cluster that no superellipsoid fits is split in two up to this depth (touching fruits).
  int max_split_depth = 2;
  // A cluster whose split only cuts one fruit into overlapping parts is that fruit, fitted
  // whole and accepted up to this RMS radial residual (fit.max_rms decides when to try a split).
  double one_fruit_max_rms = 0.009;
  // An accepted fit above this RMS is split too if that explains its points far better (two
  // small touching fruits fit one superellipsoid within fit.max_rms).
  double split_rms = 0.004;
  // A changed cluster that one accepted fruit covered before keeps that fit, unrefitted, while
  // the fit still explains it: the RMS radial residual of its points under the old fit at most
  // (1 + refit_tolerance) times the old one (1 mm at least), and at most refit_tolerance more
  // points. A view that only re-observes a fruit then costs no fit. Touching fruits split
  // before are split again along their previous fits, each part kept or refitted the same way.
  // 0: refit every change, and split from scratch.
  double refit_tolerance = 0.1;
  // The changed clusters of an update are fitted on up to this many threads (1: in the
  // caller's). The fruits are the same whatever the number.
  int threads = 2;
  FitParams fit;
  MissingSurfaceParams missing;
  // Throws std::invalid_argument naming the first bad value.
  void validate() const;
};

struct PipelineStats {
  int input_points = 0;
  int non_finite_points = 0;  // skipped
  int clusters = 0;  // examined this update (around the changed blocks when only those were re-clustered)
  ClustersLeftOut left_out;  // formed this update, not fitted for their size (outside clustering's min..max_size)
  bool local = false;  // only the clusters around the changed blocks were formed again
  int cluster_passes = 0;  // local: clusterings of the gathered blocks while the region grew
  int fitted = 0;  // fits run this update (others reused)
  int kept = 0;    // changed clusters whose previous fit still explained them (not refitted)
  int splits = 0;  // clusters split into several fruits
  int accepted = 0;
  double seconds = 0.0;          // all of it; of which
  double cluster_seconds = 0.0;  // Euclidean clustering
  double prior_seconds = 0.0;    // normals and centre priors of the clusters fitted
  double fit_seconds = 0.0;      // the superellipsoid fits (the solver)
  double missing_seconds = 0.0;  // predicted unseen surfaces

  // Adds the counts and times a fit job made (fitted, kept, splits, prior, fit and missing
  // seconds) to these.
  void addJob(const PipelineStats& job);
};

class FruitShapePipeline {
 public:
  explicit FruitShapePipeline(const PipelineParams& params = PipelineParams());

  // Processes a new surface cloud (the whole current fruit surface, not a delta) and returns
  // all fruits, accepted or not, largest cluster first. If `cancel` becomes true it returns
  // between two clusters with the previous update's fruits and tracks unchanged.
  const std::vector<FruitEstimate>& update(const PointList& surface_cloud, const std::atomic<bool>* cancel = nullptr);
  // The same surface by blocks (which changed, surface_blocks.h): clusters are formed again
  // only around the changed blocks, as far as they reach, and every other fruit is carried over
  // as it was; the fruits are those of a whole update (the same clusters; ids and order may
  // differ). The first update, and one after new settings, clusters it all.
  const std::vector<FruitEstimate>& update(const SurfaceBlocks& surface, const std::atomic<bool>* cancel = nullptr);

  const std::vector<FruitEstimate>& fruits() const { return fruits_; }
  // The last update's fruits, moved out (fruits() is empty until the next update): saves a
  // host that keeps its own copy a second copy of every fruit's points.
  std::vector<FruitEstimate> takeFruits() { return std::move(fruits_); }
  const PipelineStats& lastStats() const { return stats_; }
  const PipelineParams& params() const { return params_; }
  // From the next update on; throws std::invalid_argument (nothing changed) for bad values.
  void setParams(const PipelineParams& params) {
    params.validate();
    params_ = params;
    local_ready_ = false;  // other clusters: the next update forms them all again
  }
  void reset();

 private:
  struct Track {
    FruitEstimate estimate;
    std::uint64_t cluster_signature = 0;  // order-independent hash of its cluster's points
    std::size_t cluster_points = 0;
    std::size_t fitted_points = 0;  // of the points its fit was made on (kept fits do not grow it)
    std::unordered_set<std::uint64_t> cells;  // occupied 1 cm cells of this fruit's points
    std::size_t split_points = 0;  // a part of a split: its cluster's size when the split was decided
    std::vector<GridCell> blocks;  // the surface blocks its points lie in (local updates)
    std::size_t rough_checked_points = 0;  // its rough fit was tried split at this cluster size and stayed whole
  };
  using Parts = std::vector<std::pair<PointList, FruitEstimate>>;
  // A split decision (made, or refused for a rough fit) is revisited once its cluster has grown
  // by this share: more of the fruit seen may tell otherwise.
  static constexpr double kRecheckGrowth = 0.25;
  // Splitting as before, a point farther than this many fit.max_rms from every earlier fruit's
  // fit belongs to none of them.
  static constexpr double kLeftOverRms = 2.5;

  // The fit functions below may run on several threads at once (one cluster, or one half of a
  // split, each): they read tracks_ and params_ and count into their own `stats`.
  // The points' surface normals (estimateNormals, oriented toward their centroid).
  std::vector<Eigen::Vector3d> normalsOf(const PointList& points, PipelineStats* stats) const;
  // One fit of a cluster (or part) with its points' normals.
  FruitEstimate estimateCluster(const PointList& points, const std::vector<Eigen::Vector3d>& normals, int id,
                                const Track* previous, PipelineStats* stats) const;
  // A changed cluster's fruits: split as before, or fitted (and split if it must be), each
  // with its unseen surface.
  std::vector<Track> fitChangedCluster(const PointList& points, const std::unordered_set<std::uint64_t>& cells,
                                       const std::vector<char>& reused, PipelineStats* stats) const;
  // The cluster as one fruit, or, if no superellipsoid fits it, split into parts that fit.
  // `cells`: the points' occupied 1 cm cells if the caller has them.
  // `fitted_whole`: the cluster's whole fit if the caller has it.
  // `split_rough`: an accepted fit above split_rms is tried split too (small touching fruits
  // fitted as one); the parts of a split are not (one cut separates such a pair).
  Parts estimateWithSplit(const PointList& points, const std::vector<Eigen::Vector3d>& normals, int depth,
                          PipelineStats* stats, const std::unordered_set<std::uint64_t>* cells = nullptr,
                          const FruitEstimate* fitted_whole = nullptr, bool split_rough = false) const;
  // A changed cluster that holds at least half of each of two or more accepted earlier fruits
  // (the parts of one split, or fruits of their own it has grown together): its points go to
  // the fruit whose fit explains them better, and each keeps its fit (see refit_tolerance), is
  // refitted from it, or keeps it if the refit fails; points far from every fit, and those of a
  // fruit left with fewer than clustering.min_size, are clustered and fitted on their own; fits
  // that interpenetrate are one fruit, fitted together. Fruits just grown together, or the parts
  // of a split once the cluster has grown by a quarter since, are first fitted whole and kept
  // whole if that fits within split_rms (a merge). Empty if the cluster is not such a one (or
  // holds a fruit already taken): the full split runs then.
  // The cluster's normals and whole fit, if computed on the way, go to `normals` and `whole`.
  std::vector<Track> splitAsBefore(const PointList& points, const std::unordered_set<std::uint64_t>& cells,
                                   const std::vector<char>& reused, std::vector<Eigen::Vector3d>* normals,
                                   std::optional<FruitEstimate>* whole, PipelineStats* stats) const;
  // Whether `fit`, made on `fitted_points` points, still explains `points` (refit_tolerance).
  bool stillFits(const FruitEstimate& fit, std::size_t fitted_points, const PointList& points) const;
  // `fit` for the cluster (part) `points`, described anew.
  static FruitEstimate keptEstimate(const FruitEstimate& fit, const PointList& points);
  // The predicted unseen surface of an accepted fruit (none otherwise).
  void predictMissing(FruitEstimate* estimate, PipelineStats* stats) const;
  int bestOverlap(const std::unordered_set<std::uint64_t>& cells) const;
  // Fitted fruits inherit the id of the unreused previous fruit they share most 1 cm cells with
  // (marking it reused); the others get new ids.
  void assignIds(std::vector<Track>* fitted, std::vector<char>* reused);
  // The occupied 1 cm cells of the points (how clusters are matched between updates).
  static std::unordered_set<std::uint64_t> occupiedCells(const PointList& points);
  // The previous fruit the changed cluster's points still fit (see refit_tolerance), or -1.
  int stillExplainedBy(const PointList& points, const std::unordered_set<std::uint64_t>& cells,
                       const std::vector<char>& reused) const;

  // Either surface: `cloud`, or `blocks` (then `cloud` only if the caller already has it).
  const std::vector<FruitEstimate>& run(const PointList* cloud, const SurfaceBlocks* blocks,
                                        const std::atomic<bool>* cancel);
  // The clusters around the changed blocks, as far as they reach (indices into *sub, the
  // finite points gathered from the blocks around them; size filtered, largest first); moves
  // the tracks they do not reach to `untouched`.
  std::vector<std::vector<int>> localClusters(const SurfaceBlocks& blocks, PointList* sub, std::vector<Track>* untouched);

  PipelineParams params_;
  bool local_ready_ = false;     // the tracks know their blocks, of this block size
  double local_block_size_ = 0.0;
  std::vector<GridCell> pending_changed_;  // changed blocks of updates that were cancelled
  std::vector<Track> tracks_;
  std::vector<FruitEstimate> fruits_;
  PipelineStats stats_;
  int next_id_ = 0;
  // The fit threads of the running update, which a split's halves may borrow (null outside it).
  ThreadBudget* budget_ = nullptr;
};

}  // namespace fruit_shape_completion
