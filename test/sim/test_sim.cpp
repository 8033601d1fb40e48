#include <fruit_shape_completion/instrument/sim/fruit_mask.h>
#include <fruit_shape_completion/instrument/sim/fruit_truth.h>
#include <fruit_shape_completion/instrument/sim/image_io.h>
#include <fruit_shape_completion/instrument/sim/procedural_scene.h>
#include <fruit_shape_completion/instrument/sim/rgbd_renderer.h>
#include <fruit_shape_completion/fruit_shape_pipeline.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <stdexcept>
#include <filesystem>
#include <fstream>
#include <sys/stat.h>
#include <unistd.h>

using namespace fruit_shape_completion;
using namespace fruit_shape_completion::sim;

namespace {

std::string sharedData() {
  const char* env = std::getenv("FSC_SHARED_DATA");
  return env ? env : "../shared/data";
}

bool exists(const std::string& p) { return std::ifstream(p).good(); }

// Appends an axis-aligned box (12 triangles, outward winding) to a scene.
void addBox(Scene& s, const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, int material, bool open_top = false) {
  const int b = static_cast<int>(s.vertices.size());
  for (int i = 0; i < 8; ++i)
    s.vertices.emplace_back(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(), i & 4 ? hi.z() : lo.z());
  const int faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (int f = 0; f < 6; ++f) {
    if (open_top && f == 1) continue;  // z = hi face
    s.triangles.emplace_back(b + faces[f][0], b + faces[f][1], b + faces[f][2]);
    s.triangles.emplace_back(b + faces[f][0], b + faces[f][2], b + faces[f][3]);
    s.triangle_material.push_back(material);
    s.triangle_material.push_back(material);
    s.triangle_plant.push_back(0);
    s.triangle_plant.push_back(0);
  }
}

Scene toyScene() {
  Scene s;
  s.materials = {{"fruit", {{200, 20, 10}}, true}, {"ground", {{90, 90, 90}}, false}};
  addBox(s, Eigen::Vector3f(-0.05f, 0.45f, 0.2f), Eigen::Vector3f(0.05f, 0.55f, 0.3f), 0);
  const int b = static_cast<int>(s.vertices.size());  // ground plane z = 0
  s.vertices.emplace_back(-5.f, -5.f, 0.f);
  s.vertices.emplace_back(5.f, -5.f, 0.f);
  s.vertices.emplace_back(5.f, 5.f, 0.f);
  s.vertices.emplace_back(-5.f, 5.f, 0.f);
  s.triangles.emplace_back(b, b + 1, b + 2);
  s.triangles.emplace_back(b, b + 2, b + 3);
  s.triangle_material.insert(s.triangle_material.end(), {1, 1});
  s.triangle_plant.insert(s.triangle_plant.end(), {0, 0});
  return s;
}

// Exact first hit of a ray with the toy scene (box slabs, then the plane).
double analyticHit(const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  double best = std::numeric_limits<double>::infinity();
  const Eigen::Vector3d lo(-0.05, 0.45, 0.2), hi(0.05, 0.55, 0.3);
  double t0 = 0, t1 = best;
  bool hit = true;
  for (int k = 0; k < 3 && hit; ++k) {
    if (std::abs(d[k]) < 1e-15) {
      hit = o[k] >= lo[k] && o[k] <= hi[k];
      continue;
    }
    double a = (lo[k] - o[k]) / d[k], b = (hi[k] - o[k]) / d[k];
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
    hit = t0 <= t1;
  }
  if (hit) best = t0;
  if (d.z() < 0) best = std::min(best, -o.z() / d.z());
  return best;
}

struct MaskScore {
  double precision, recall;
  int on_leaf_or_stem, on_yellow, red_pixels;
};

MaskScore scoreMask(const Scene& scene, const RgbdFrame& frame, const RedThreshold& test = RedThreshold()) {
  const std::vector<std::uint8_t> mask = redMask(frame.rgb, frame.width, frame.height, test);
  MaskScore s{0, 0, 0, 0, 0};
  int tp = 0, fp = 0, fn = 0;
  for (std::size_t i = 0; i < mask.size(); ++i) {
    const int m = frame.material[i];
    const bool red_fruit = m >= 0 && scene.materials[m].fruit && colorClass(scene.materials[m].rgb) == "red";
    const bool yellow = m >= 0 && scene.materials[m].fruit && colorClass(scene.materials[m].rgb) == "yellow";
    s.red_pixels += red_fruit;
    if (mask[i] && red_fruit) ++tp;
    if (mask[i] && !red_fruit) ++fp;
    if (!mask[i] && red_fruit) ++fn;
    if (mask[i] && m >= 0 && !scene.materials[m].fruit) ++s.on_leaf_or_stem;
    if (mask[i] && yellow) ++s.on_yellow;
  }
  s.precision = tp + fp ? static_cast<double>(tp) / (tp + fp) : 1.0;
  s.recall = tp + fn ? static_cast<double>(tp) / (tp + fn) : 1.0;
  return s;
}

}  // namespace

TEST(RgbdRenderer, DepthOfAToySceneMatchesTheAnalyticHits) {
  const Scene scene = toyScene();
  const RgbdRenderer renderer(scene, {});
  DepthNoise off;
  off.enabled = false;
  const PinholeCamera cam = PinholeCamera::lookingAt(Eigen::Vector3d(0.1, 0.0, 0.6), Eigen::Vector3d(0, 0.5, 0.2), 160, 120);
  const RgbdFrame frame = renderer.render(cam, off);
  int compared = 0, box = 0;
  double worst = 0;
  for (int v = 0; v < frame.height; ++v)
    for (int u = 0; u < frame.width; ++u) {
      const Eigen::Vector3d d = cam.rayDirection(u, v);
      const double t = analyticHit(cam.position, d);
      const float z = frame.depth[v * frame.width + u];
      if (!std::isfinite(t) || t > cam.max_range) {
        EXPECT_FALSE(std::isfinite(z));
        continue;
      }
      ASSERT_TRUE(std::isfinite(z)) << u << "," << v;
      worst = std::max(worst, std::abs(z - t * d.dot(cam.rotation.col(2))));
      ++compared;
      box += frame.material[v * frame.width + u] == 0;
    }
  EXPECT_GT(compared, 10000);
  EXPECT_GT(box, 200);
  EXPECT_LT(worst, 2e-5);  // float precision of the ray tracer
}

TEST(RgbdRenderer, NoiseGrowsWithDistanceAsModelled) {
  const Scene scene = toyScene();
  const RgbdRenderer renderer(scene, {});
  // Looking straight down at the ground from 1.2 m: sigma = 0.0012 + 0.0019 * 0.8^2 = 2.4 mm.
  PinholeCamera cam = PinholeCamera::lookingAt(Eigen::Vector3d(1, -1, 1.2), Eigen::Vector3d(1, -1, 0), 80, 60);
  DepthNoise noise;
  const RgbdFrame noisy = renderer.render(cam, noise);
  noise.enabled = false;
  const RgbdFrame exact = renderer.render(cam, noise);
  double sum2 = 0;
  int n = 0;
  for (std::size_t i = 0; i < exact.depth.size(); ++i)
    if (std::isfinite(noisy.depth[i])) {
      sum2 += std::pow(noisy.depth[i] - exact.depth[i], 2);
      ++n;
    }
  ASSERT_GT(n, 4000);
  const double sigma = std::sqrt(sum2 / n), expected = 0.0012 + 0.0019 * 0.64;
  EXPECT_NEAR(sigma, expected, 0.15 * expected);
  // Reproducible, and the same with any thread count.
  DepthNoise again;
  EXPECT_EQ(renderer.render(cam, again, 1).depth, noisy.depth);
}

TEST(RgbdRenderer, PaperNoiseIsStructuredAndBlursEdgesIntoMixedDepths) {
  const Scene scene = toyScene();
  const RgbdRenderer renderer(scene, {});
  // The ground from 1.2 m: Gaussian 1 mm + 0.3 % (4.6 mm) on top of sinusoids of up to 4.5 mm
  // and 0.9 % (11 mm): far above the independent model's 2.4 mm.
  const PinholeCamera ground = PinholeCamera::lookingAt(Eigen::Vector3d(1, -1, 1.2), Eigen::Vector3d(1, -1, 0), 320, 240);
  DepthNoise paper;
  paper.model = DepthNoise::Model::kPaper;
  DepthNoise none;
  none.enabled = false;
  const RgbdFrame noisy = renderer.render(ground, paper), exact = renderer.render(ground, none);
  double sum2 = 0;
  int n = 0;
  for (std::size_t i = 0; i < exact.depth.size(); ++i)
    if (std::isfinite(noisy.depth[i]) && std::isfinite(exact.depth[i])) {
      sum2 += std::pow(noisy.depth[i] - exact.depth[i], 2);
      ++n;
    }
  ASSERT_GT(n, 70000);
  const double rms = std::sqrt(sum2 / n);
  EXPECT_GT(rms, 0.005);
  EXPECT_LT(rms, 0.014);
  EXPECT_EQ(renderer.render(ground, paper, 1).depth, noisy.depth);  // reproducible, any thread count

  // The box top (0.9 m) over the ground (1.2 m), without the Gaussian part: next to the edge the
  // blur mixes the two depths; away from it a pixel keeps its surface (within the sinusoids).
  paper.paper_sigma_base = paper.paper_sigma_rel = 0.0;
  const PinholeCamera above = PinholeCamera::lookingAt(Eigen::Vector3d(0, 0.5, 1.2), Eigen::Vector3d(0, 0.5, 0), 160, 120);
  const RgbdFrame blurred = renderer.render(above, paper), sharp = renderer.render(above, none);
  int mixed = 0, edge = 0;
  for (int v = 1; v + 1 < sharp.height; ++v)
    for (int u = 1; u + 1 < sharp.width; ++u) {
      const std::size_t px = static_cast<std::size_t>(v) * sharp.width + u;
      float lo = sharp.depth[px], hi = sharp.depth[px];
      for (int dv = -1; dv <= 1; ++dv)
        for (int du = -1; du <= 1; ++du) {
          const float z = sharp.depth[static_cast<std::size_t>(v + dv) * sharp.width + u + du];
          lo = std::min(lo, z);
          hi = std::max(hi, z);
        }
      if (hi - lo < 0.2f) {
        EXPECT_NEAR(blurred.depth[px], sharp.depth[px], 0.0025 + 0.009 * sharp.depth[px]);
        continue;
      }
      ++edge;
      EXPECT_GT(blurred.depth[px], lo - 0.016f);
      EXPECT_LT(blurred.depth[px], hi + 0.016f);
      mixed += std::abs(blurred.depth[px] - sharp.depth[px]) > 0.03f;  // moved toward the other surface
    }
  EXPECT_GT(edge, 50);
  EXPECT_GT(mixed, edge / 2);
}

TEST(FruitMask, UpstreamHsiTestAsPointcloudRoiApplies) {
  RedThreshold upstream;
  upstream.test = RedThreshold::Test::kUpstream;
  // The scenario files' colours: red fruit in, yellow fruit and leaves out; the brown stems
  // (hue 27) pass too, as they would upstream: false positives of the paper's pipeline.
  EXPECT_TRUE(upstream.isRed(176, 22, 14));
  EXPECT_TRUE(upstream.isRed(150, 18, 12));
  EXPECT_FALSE(upstream.isRed(162, 154, 35));  // hue 40 > 35
  EXPECT_FALSE(upstream.isRed(46, 104, 32));
  EXPECT_TRUE(upstream.isRed(92, 74, 44));
  EXPECT_FALSE(RedThreshold().isRed(92, 74, 44));
  // A red fruit in shadow falls below intensity 30: the upstream test misses it, the HSV one not.
  EXPECT_FALSE(upstream.isRed(62, 8, 5));
  EXPECT_TRUE(RedThreshold().isRed(62, 8, 5));
  // Hue just inside and outside its bounds (units of 1/128 half-turn): magenta-red and orange.
  EXPECT_TRUE(upstream.isRed(200, 40, 60));
  EXPECT_FALSE(upstream.isRed(200, 20, 140));
  EXPECT_FALSE(upstream.isRed(40, 40, 40));  // grey: no saturation
}

TEST(FruitTruth, ClosedOpenAndDoubleSidedBoxesHaveExactVolumes) {
  for (int variant = 0; variant < 3; ++variant) {
    Scene s = toyScene();
    s.vertices.clear();
    s.triangles.clear();
    s.triangle_material.clear();
    s.triangle_plant.clear();
    addBox(s, Eigen::Vector3f(0.1f, 0.2f, 0.3f), Eigen::Vector3f(0.2f, 0.25f, 0.34f), 0, variant == 1);
    if (variant == 2) {  // every face also as a back face, as the capsicum COLLADA meshes have
      const std::size_t n = s.triangles.size();
      for (std::size_t t = 0; t < n; ++t) {
        s.triangles.emplace_back(s.triangles[t][0], s.triangles[t][2], s.triangles[t][1]);
        s.triangle_material.push_back(0);
        s.triangle_plant.push_back(0);
      }
    }
    const auto fruits = computeFruitTruth(s);
    ASSERT_EQ(fruits.size(), 1u) << "variant " << variant;
    // Exact for the corners as stored (floats).
    const Eigen::Vector3d lo = Eigen::Vector3f(0.1f, 0.2f, 0.3f).cast<double>();
    const Eigen::Vector3d hi = Eigen::Vector3f(0.2f, 0.25f, 0.34f).cast<double>();
    EXPECT_NEAR(fruits[0].volume, (hi - lo).prod(), 1e-15) << "variant " << variant;
    EXPECT_LT((fruits[0].center - 0.5 * (lo + hi)).norm(), 1e-12) << "variant " << variant;
    EXPECT_EQ(fruits[0].boundary_edges, variant == 1 ? 4 : 0);
  }
}

TEST(SharedScenes, ScenarioOneHasFourteenRedFruitsOfRealisticSize) {
  const std::string path = sharedData() + "/scenes/scenario1_world14.yaml";
  if (!exists(path)) GTEST_SKIP() << "needs ../shared/data (set FSC_SHARED_DATA): " << path << " not found";
  Scene scene;
  std::string err;
  ASSERT_TRUE(loadScene(path, &scene, &err)) << err;
  std::vector<int> triangle_fruit;
  const auto fruits = computeFruitTruth(scene, &triangle_fruit);
  ASSERT_EQ(fruits.size(), 14u);
  for (const auto& f : fruits) {
    EXPECT_EQ(f.color, "red");
    EXPECT_GE(f.volume, 85e-6);
    EXPECT_LE(f.volume, 265e-6);  // the largest is 263.5 cm^3 ("about 85 to 260" in the data README)
    EXPECT_NEAR(f.se_volume, f.volume, 0.06 * f.volume);
    EXPECT_GT(f.boundary_edges, 0);  // the stem hole was there and got closed
  }
  // The fruit-only ground-truth mesh gives the same fruits for the first plant.
  std::vector<Eigen::Vector3f> v;
  std::vector<Eigen::Vector3i> t;
  std::vector<int> m;
  ASSERT_TRUE(appendMeshTo(scene.plants[0].fruit_truth, scene.plants[0].position, scene.plants[0].yaw, scene, &v, &t, &m, &err)) << err;
  const auto only = computeFruitTruth(scene, v, t, m, std::vector<int>(t.size(), 0), nullptr);
  ASSERT_EQ(only.size(), 7u);
  for (const auto& f : only) {
    double best = 1;
    for (const auto& g : fruits) best = std::min(best, (g.center - f.center).norm());
    EXPECT_LT(best, 1e-4);
  }

  // The thresholder against the renderer's own labels, noise off.
  const RgbdRenderer renderer(scene, triangle_fruit);
  DepthNoise off;
  off.enabled = false;
  const RgbdFrame frame = renderer.render(PinholeCamera::lookingAt(scene.camera_start_position, scene.camera_start_look_at), off);
  const MaskScore s = scoreMask(scene, frame);
  EXPECT_GT(s.red_pixels, 5000);
  EXPECT_GT(s.precision, 0.98);
  EXPECT_GT(s.recall, 0.98);
  EXPECT_EQ(s.on_leaf_or_stem, 0);
  std::printf("[ report   ] scenario 1 mask: precision %.4f recall %.4f over %d red fruit pixels\n", s.precision, s.recall, s.red_pixels);

  // As Gazebo draws it: every material textured, leaves cut by their alpha, the upstream HSI test.
  ASSERT_EQ(scene.uvs.size(), scene.vertices.size());
  for (const auto& mat : scene.materials) {
    if (mat.name == "VG07frt0") continue;  // the yellow fruit: no plant of scenario 1 has it
    ASSERT_TRUE(mat.texture) << mat.name;
  }
  Shading textured;
  textured.textures = true;
  const RgbdRenderer gazebo(scene, triangle_fruit, textured);
  const RgbdFrame tf = gazebo.render(PinholeCamera::lookingAt(scene.camera_start_position, scene.camera_start_look_at), off);
  RedThreshold upstream;
  upstream.test = RedThreshold::Test::kUpstream;
  const MaskScore ts = scoreMask(scene, tf, upstream);
  EXPECT_GT(ts.red_pixels, 5000);
  EXPECT_GT(ts.precision, 0.97);
  EXPECT_GT(ts.recall, 0.9);
  // The cut-away leaf margins let the camera see past them: fewer surface pixels than untextured.
  int flat_hits = 0, cut_hits = 0;
  for (std::size_t i = 0; i < tf.material.size(); ++i) {
    flat_hits += frame.material[i] >= 0;
    cut_hits += tf.material[i] >= 0;
  }
  EXPECT_LT(cut_hits, flat_hits);
  std::printf("[ report   ] scenario 1 textured, upstream red test: precision %.4f recall %.4f; %d of %d surface pixels "
              "left after the alpha cut\n", ts.precision, ts.recall, cut_hits, flat_hits);
}

TEST(SharedScenes, TheLowestRealPepperSeenFromBelowFitsWithinAFifthWithTheRimLimit) {
  // The plant's lowest, largest fruit (251 cm^3, blocky) alone, seen slightly from below by one
  // camera with the paper's depth noise and blur, every depth pixel given to the pipeline as
  // fit_cloud gives a user's cloud. The normals along its steep sides meet far behind what the
  // camera saw, and a fit that follows that prior comes out 1.4-1.8x too large; the centre
  // prior held to the deepest seen points (center_rim_margin, 3 mm by default) keeps it
  // within 20 %.
  const std::string given = sharedData() + "/plants/VG07_6_fruitonly.dae";
  if (!exists(given)) GTEST_SKIP() << "needs ../shared/data (set FSC_SHARED_DATA): " << given << " not found";
  const std::string mesh = std::filesystem::absolute(given).string();  // the scene file lives elsewhere
  char dir_template[] = "/tmp/fsc_pepper_XXXXXX";
  ASSERT_NE(mkdtemp(dir_template), nullptr);
  const std::string yaml = std::string(dir_template) + "/plant.yaml";
  std::ofstream(yaml) << "name: fruit_only\nplants:\n  - {mesh: " << mesh << ", position: [0, 0, 0], yaw: 0.0}\n"
                      << "materials:\n  VG07frt1: {rgb: [176, 22, 14], fruit: true}\n"
                      << "  VG07frt2: {rgb: [150, 18, 12], fruit: true}\n";
  Scene plant;
  std::string err;
  const bool loaded = loadScene(yaml, &plant, &err);
  std::remove(yaml.c_str());
  rmdir(dir_template);
  ASSERT_TRUE(loaded) << err;
  std::vector<int> triangle_fruit;
  const auto fruits = computeFruitTruth(plant, &triangle_fruit);
  ASSERT_EQ(fruits.size(), 7u);
  int lowest = 0;
  for (const auto& f : fruits)
    if (f.center.z() < fruits[lowest].center.z()) lowest = f.id;
  const FruitTruth& truth = fruits[lowest];
  Scene alone = plant;  // the other fruits would hide parts of it
  alone.triangles.clear();
  alone.triangle_material.clear();
  alone.triangle_plant.clear();
  std::vector<int> alone_fruit;
  for (std::size_t t = 0; t < plant.triangles.size(); ++t)
    if (triangle_fruit[t] == lowest) {
      alone.triangles.push_back(plant.triangles[t]);
      alone.triangle_material.push_back(plant.triangle_material[t]);
      alone.triangle_plant.push_back(plant.triangle_plant[t]);
      alone_fruit.push_back(lowest);
    }
  const RgbdRenderer renderer(alone, alone_fruit);
  PipelineParams limited, free_prior;
  limited.center_rim_margin = 0.003;
  free_prior.center_rim_margin = -1.0;
  // Azimuths around the fruit, 15 deg below it, 0.3-0.5 m away.
  double worst_limited = 1.0, worst_free = 1.0;
  for (const auto& [azimuth, distance] : {std::pair{2.36, 0.5}, {0.27, 0.3}, {-0.74, 0.4}}) {
    const Eigen::Vector3d view(std::cos(azimuth) * std::cos(-0.26), std::sin(azimuth) * std::cos(-0.26), std::sin(-0.26));
    DepthNoise noise;
    noise.model = DepthNoise::Model::kPaper;
    noise.seed = 7;
    const RgbdFrame frame = renderer.render(PinholeCamera::lookingAt(truth.center + distance * view, truth.center), noise);
    const PointList points = cloudsFromFrame(frame, std::vector<std::uint8_t>(frame.depth.size(), 0)).full;
    ASSERT_GT(points.size(), 1000u);
    auto accuracy = [&](const PipelineParams& params) {
      FruitShapePipeline pipeline(params);
      double best = 0.0;
      for (const auto& f : pipeline.update(points))
        if (f.accepted && (f.shape.t - truth.center).norm() < 0.03)
          best = std::max(best, 1.0 - std::abs(f.volume - truth.volume) / truth.volume);
      return best;
    };
    const double held = accuracy(limited), free = accuracy(free_prior);
    std::printf("[ report   ] lowest pepper from azimuth %.2f, %.1f m: volume accuracy %.3f (%.3f with the prior free)\n",
                azimuth, distance, held, free);
    worst_limited = std::min(worst_limited, held);
    worst_free = std::min(worst_free, free);
  }
  EXPECT_GT(worst_limited, 0.8);
  // The case this guards: without the limit it is fitted far too large (should the default path
  // ever fit it, the limit's test needs a harder case).
  EXPECT_LT(worst_free, 0.7);
}

TEST(ImageIo, TgaRunLengthAndPlainBothRowOrders) {
  const std::string dir = ::testing::TempDir();
  // 3 x 2, 32 bit, bottom row first, run-length: a run of 3 red, then 3 raw pixels.
  const std::vector<unsigned char> rle = {0, 0, 10, 0, 0, 0, 0, 0, 0, 0, 0, 0, 3, 0, 2, 0, 32, 8,
                                          0x82, 0, 0, 255, 255,                             // 3 x red (BGRA)
                                          0x02, 255, 0, 0, 255, 0, 255, 0, 0, 1, 2, 3, 128};  // blue, green (a 0), (3,2,1)
  std::ofstream(dir + "/fsc.tga", std::ios::binary).write(reinterpret_cast<const char*>(rle.data()), rle.size());
  RgbaImage img;
  std::string err;
  ASSERT_TRUE(readTga(dir + "/fsc.tga", &img, &err)) << err;
  ASSERT_EQ(img.width, 3);
  ASSERT_EQ(img.height, 2);
  EXPECT_TRUE(img.has_alpha);
  // The file's first row is the bottom one (v = 0).
  EXPECT_EQ(img.texel(0.1, 0.2), (std::array<std::uint8_t, 4>{{255, 0, 0, 255}}));
  EXPECT_EQ(img.texel(0.1, 0.7), (std::array<std::uint8_t, 4>{{0, 0, 255, 255}}));
  EXPECT_EQ(img.texel(0.5, 0.7), (std::array<std::uint8_t, 4>{{0, 255, 0, 0}}));
  EXPECT_EQ(img.texel(0.9, 1.7), (std::array<std::uint8_t, 4>{{3, 2, 1, 128}}));  // wrapped
  // 1 x 2, 24 bit, plain, top row first.
  const std::vector<unsigned char> plain = {0, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 2, 0, 24, 0x20, 10, 20, 30, 40, 50, 60};
  std::ofstream(dir + "/fsc2.tga", std::ios::binary).write(reinterpret_cast<const char*>(plain.data()), plain.size());
  ASSERT_TRUE(readTga(dir + "/fsc2.tga", &img, &err)) << err;
  EXPECT_FALSE(img.has_alpha);
  EXPECT_EQ(img.texel(0.5, 0.9), (std::array<std::uint8_t, 4>{{30, 20, 10, 255}}));
  // Broken files: a clear message, no image.
  auto broken = [&](std::vector<unsigned char> bytes, const std::string& expect) {
    std::ofstream(dir + "/fsc3.tga", std::ios::binary | std::ios::trunc).write(reinterpret_cast<const char*>(bytes.data()), bytes.size());
    err.clear();
    EXPECT_FALSE(readTga(dir + "/fsc3.tga", &img, &err));
    EXPECT_NE(err.find(expect), std::string::npos) << err;
  };
  broken(std::vector<unsigned char>(rle.begin(), rle.end() - 3), "truncated");
  std::vector<unsigned char> overrun = rle;
  overrun[18] = 0x86;  // a run of 7 in a 6-pixel image
  broken(overrun, "past the image");
  std::vector<unsigned char> mapped = plain;
  mapped[1] = 1;
  broken(mapped, "unsupported TGA type");
  std::vector<unsigned char> huge = plain;
  huge[12] = huge[13] = 0xff;
  broken(huge, "1-16384");
  std::vector<unsigned char> claims = plain;  // 16000 x 16000 in a 24-byte file: refused before allocating
  claims[12] = claims[14] = 0x80;
  claims[13] = claims[15] = 0x3e;
  broken(claims, "truncated");
  claims[2] = 10;  // run-length: 256 M pixels cannot come from 6 bytes of packets
  broken(claims, "truncated");
  broken({1, 2, 3}, "header");
  EXPECT_FALSE(readTga(dir + "/missing.tga", &img, &err));
}

TEST(RgbdRenderer, TexturesAlphaCutAndOneLightAsGazeboDrawsThem) {
  // A 1 m square at y = 1 facing the camera (at the origin, looking along +y); its texture is
  // transparent on the left half (u < 0.5) and red on the right.
  Scene s;
  s.materials.resize(1);
  s.materials[0].name = "leaf";
  s.materials[0].rgb = {{0, 255, 0}};
  auto tex = std::make_shared<RgbaImage>();
  tex->width = 2;
  tex->height = 1;
  tex->has_alpha = true;
  tex->rgba = {0, 0, 0, 0, 200, 100, 50, 255};
  s.materials[0].texture = tex;
  s.vertices = {{-0.5f, 1.f, -0.5f}, {0.5f, 1.f, -0.5f}, {0.5f, 1.f, 0.5f}, {-0.5f, 1.f, 0.5f}};
  s.uvs = {{0.f, 0.f}, {1.f, 0.f}, {1.f, 1.f}, {0.f, 1.f}};
  s.triangles = {{0, 1, 2}, {0, 2, 3}};
  s.triangle_material = {0, 0};
  s.triangle_plant = {0, 0};
  Shading shading;
  shading.textures = true;
  shading.light_direction = Eigen::Vector3d(0, 1, -1);  // hits the square's face at 45 degrees
  const RgbdRenderer renderer(s, {}, shading);
  DepthNoise off;
  off.enabled = false;
  const PinholeCamera cam = PinholeCamera::lookingAt(Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 1, 0));
  const RgbdFrame f = renderer.render(cam, off);
  const int v = cam.height / 2;
  const std::size_t left = static_cast<std::size_t>(v) * cam.width + cam.width / 2 - 40;
  const std::size_t right = static_cast<std::size_t>(v) * cam.width + cam.width / 2 + 40;
  EXPECT_EQ(f.material[left], -1);  // cut away: the ray went through
  EXPECT_TRUE(std::isnan(f.depth[left]));
  EXPECT_EQ(renderer.castRay(Eigen::Vector3d::Zero(), cam.rayDirection(cam.width / 2 - 40, v), 5.0),
            std::numeric_limits<double>::infinity());
  ASSERT_EQ(f.material[right], 0);
  EXPECT_NEAR(f.depth[right], 1.0, 1e-4);
  const double shade = std::min(1.0, 0.4 + 0.8 * std::sqrt(0.5));  // ambient + diffuse cos 45
  EXPECT_NEAR(f.rgb[3 * right], 200 * shade, 1.0);
  EXPECT_NEAR(f.rgb[3 * right + 1], 100 * shade, 1.0);
  EXPECT_NEAR(f.rgb[3 * right + 2], 50 * shade, 1.0);
  // The same square untextured: flat colour, whole square solid.
  const RgbdRenderer flat(s, {});
  const RgbdFrame g = flat.render(cam, off);
  EXPECT_EQ(g.material[left], 0);
  EXPECT_EQ(g.rgb[3 * left], 0);
  EXPECT_GT(g.rgb[3 * left + 1], 200);
}

TEST(ProceduralScene, ReproduciblePepperShapedAndYellowStaysOutOfTheMask) {
  Scene a, b;
  std::string err;
  ASSERT_TRUE(loadSceneSpec("procedural:7", &a, &err)) << err;
  ASSERT_TRUE(loadSceneSpec("procedural:7", &b, &err)) << err;
  ASSERT_EQ(a.triangles.size(), b.triangles.size());
  EXPECT_EQ(a.vertices, b.vertices);
  std::vector<int> triangle_fruit;
  const auto fruits = computeFruitTruth(a, &triangle_fruit);
  ASSERT_GE(fruits.size(), 12u);
  int yellow = 0;
  for (const auto& f : fruits) {
    EXPECT_GE(f.volume, 55e-6);
    EXPECT_LE(f.volume, 255e-6);
    yellow += f.color == "yellow";
  }
  EXPECT_GE(yellow, 1);
  const RgbdRenderer renderer(a, triangle_fruit);
  DepthNoise off;
  off.enabled = false;
  const RgbdFrame frame = renderer.render(PinholeCamera::lookingAt(a.camera_start_position, a.camera_start_look_at), off);
  const MaskScore s = scoreMask(a, frame);
  EXPECT_GT(s.precision, 0.98);
  EXPECT_GT(s.recall, 0.98);
  EXPECT_EQ(s.on_leaf_or_stem, 0);
  EXPECT_EQ(s.on_yellow, 0);
  // Leaves really occlude: some fruit pixels of the unoccluded fruits are hidden.
  int fruit_pixels = 0;
  for (int id : frame.fruit) fruit_pixels += id >= 0;
  EXPECT_GT(fruit_pixels, 1000);

  // Written out and loaded back: the same fruits.
  const std::string dir = "/tmp/fsc_scene_" + std::to_string(::getpid());
  ASSERT_TRUE(writeSceneFiles(a, dir, &err)) << err;
  Scene c;
  ASSERT_TRUE(loadScene(dir + "/scene.yaml", &c, &err)) << err;
  const auto again = computeFruitTruth(c);
  ASSERT_EQ(again.size(), fruits.size());
  for (std::size_t i = 0; i < fruits.size(); ++i) {
    EXPECT_NEAR(again[i].volume, fruits[i].volume, 1e-3 * fruits[i].volume);
    EXPECT_LT((again[i].center - fruits[i].center).norm(), 1e-4);
  }
  std::system(("rm -rf " + dir).c_str());
}

TEST(SceneFiles, BadFilesGiveAClearErrorNamingFileAndProblem) {
  const std::string dir = "/tmp/fsc_bad_" + std::to_string(::getpid());
  ::mkdir(dir.c_str(), 0755);
  Scene s;
  std::string err;
  std::ofstream(dir + "/missing_mesh.yaml") << "name: x\nmaterials: {leaf: {rgb: [1, 2, 3]}}\nplants:\n  - {mesh: nowhere.dae, position: [0, 0, 0]}\n";
  EXPECT_FALSE(loadScene(dir + "/missing_mesh.yaml", &s, &err));
  EXPECT_NE(err.find("nowhere.dae"), std::string::npos) << err;
  EXPECT_NE(err.find("not found"), std::string::npos) << err;

  std::ofstream(dir + "/m.obj") << "mtllib m.mtl\nusemtl mystery\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  std::ofstream(dir + "/m.mtl") << "newmtl mystery\nKd 1 0 0\n";
  std::ofstream(dir + "/unknown_material.yaml") << "materials: {leaf: {rgb: [1, 2, 3]}}\nplants:\n  - {mesh: m.obj, position: [0, 0, 0]}\n";
  EXPECT_FALSE(loadScene(dir + "/unknown_material.yaml", &s, &err));
  EXPECT_NE(err.find("mystery"), std::string::npos) << err;
  EXPECT_NE(err.find("m.obj"), std::string::npos) << err;

  std::ofstream(dir + "/broken.yaml") << "plants: [ {mesh: a.dae, position: [0, 0\n";
  EXPECT_FALSE(loadScene(dir + "/broken.yaml", &s, &err));
  EXPECT_NE(err.find("broken.yaml"), std::string::npos) << err;
  EXPECT_NE(err.find("malformed"), std::string::npos) << err;

  std::ofstream(dir + "/bad_values.yaml") << "materials: {leaf: {rgb: [1, 2, 300]}}\nplants: []\n";
  EXPECT_FALSE(loadScene(dir + "/bad_values.yaml", &s, &err));
  EXPECT_NE(err.find("0-255"), std::string::npos) << err;

  EXPECT_FALSE(loadScene(dir + "/does_not_exist.yaml", &s, &err));
  EXPECT_NE(err.find("not found"), std::string::npos) << err;
  EXPECT_FALSE(loadSceneSpec("procedural:abc", &s, &err));
  EXPECT_NE(err.find("seed"), std::string::npos) << err;

  // Extreme or non-finite coordinates never reach the ray tracer (Embree aborts on 1e20).
  std::ofstream(dir + "/leaf.obj") << "mtllib leaf.mtl\nusemtl leaf\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  std::ofstream(dir + "/leaf.mtl") << "newmtl leaf\nKd 0 1 0\n";
  const std::string head = "materials: {leaf: {rgb: [1, 2, 3]}}\nplants:\n  - {mesh: leaf.obj, ";
  const std::vector<std::pair<std::string, std::string>> extreme = {
      {"position: [1e20, 0, 0]}\n", "beyond 1e4 m"},
      {"position: [0, .nan, 0]}\n", "not finite"},
      {"position: [0, 0, 0], yaw: .nan}\n", "yaw"},
      {"position: [0, 0, 0], yaw: .inf}\n", "yaw"},
      {"position: [0, 0, 0]}\nworkspace: {box_min: [0, 0, 0], box_max: [1, 1, 1e30]}\n", "beyond 1e4 m"},
      {"position: [0, 0, 0]}\nworkspace: {box_min: [0, 0, 0], box_max: [1, 1, 1], reach_center: [0, 0, 0], reach_radius: .inf}\n",
       "reach_radius"},
      {"position: [0, 0, 0]}\ncamera_start: {position: [0, 0, -1e9], look_at: [0, 0, 0]}\n", "beyond 1e4 m"},
      {"position: [9999.5, 0, 0], yaw: 0}\n", "vertex lies beyond 1e4 m"},  // the mesh reaches 10000.5
  };
  for (const auto& [tail, expected] : extreme) {
    std::ofstream(dir + "/extreme.yaml") << head << tail;
    EXPECT_FALSE(loadScene(dir + "/extreme.yaml", &s, &err)) << tail;
    EXPECT_NE(err.find(expected), std::string::npos) << tail << " -> " << err;
    EXPECT_TRUE(err.find("extreme.yaml") != std::string::npos || err.find("leaf.obj") != std::string::npos) << err;
  }
  std::system(("rm -rf " + dir).c_str());
}

TEST(RgbdRenderer, ExtremeScenesAndCamerasAreRefusedNotPassedToEmbree) {
  Scene scene;
  scene.name = "toy";
  scene.materials.push_back(SceneMaterial{});
  scene.vertices = {Eigen::Vector3f(0, 0, 1), Eigen::Vector3f(1, 0, 1), Eigen::Vector3f(0, 1, 1)};
  scene.triangles = {Eigen::Vector3i(0, 1, 2)};
  scene.triangle_material = {0};
  scene.triangle_plant = {0};
  Scene far = scene;
  far.vertices[1] = Eigen::Vector3f(1e20f, 0, 1);
  EXPECT_THROW(RgbdRenderer(far, {}), std::invalid_argument);
  Scene nan = scene;
  nan.vertices[2].y() = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(RgbdRenderer(nan, {}), std::invalid_argument);
  Scene bad_index = scene;
  bad_index.triangles[0] = Eigen::Vector3i(0, 1, 3);
  EXPECT_THROW(RgbdRenderer(bad_index, {}), std::invalid_argument);

  const RgbdRenderer renderer(scene, {});
  PinholeCamera cam = PinholeCamera::lookingAt(Eigen::Vector3d(0.2, 0.2, 0), Eigen::Vector3d(0.2, 0.2, 1));
  cam.width = 64;
  cam.height = 48;
  EXPECT_NO_THROW(renderer.render(cam));
  PinholeCamera far_cam = cam;
  far_cam.position = Eigen::Vector3d(1e20, 0, 0);
  EXPECT_THROW(renderer.render(far_cam), std::invalid_argument);
  PinholeCamera nan_cam = cam;
  nan_cam.rotation(0, 0) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(renderer.render(nan_cam), std::invalid_argument);
  EXPECT_TRUE(std::isinf(renderer.castRay(Eigen::Vector3d(1e20, 0, 0), Eigen::Vector3d(0, 0, 1), 10.0)));
  EXPECT_TRUE(std::isinf(renderer.castRay(Eigen::Vector3d(0.2, 0.2, 0), Eigen::Vector3d::Constant(NAN), 10.0)));
  EXPECT_NEAR(renderer.castRay(Eigen::Vector3d(0.2, 0.2, 0), Eigen::Vector3d(0, 0, 1), 10.0), 1.0, 1e-5);
  EXPECT_FALSE(renderer.isClear(Eigen::Vector3d(0.2, 0.2, 0.9), 0.2));
}
