#include <fruit_shape_completion/depth_edges.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

using namespace fruit_shape_completion;

TEST(DepthEdges, OutlinesOfANearSquareNotATiltedNoisyPlane) {
  const int w = 60, h = 40;
  std::vector<float> depth(w * h, 1.0f);
  // A square at 0.5 m (columns and rows 20-39 / 10-29), then a 3 x 3 blur that mixes its outline.
  for (int v = 10; v < 30; ++v)
    for (int u = 20; u < 40; ++u) depth[v * w + u] = 0.5f;
  std::vector<float> blurred = depth;
  for (int v = 1; v < h - 1; ++v)
    for (int u = 1; u < w - 1; ++u) {
      double sum = 0;
      for (int dv = -1; dv <= 1; ++dv)
        for (int du = -1; du <= 1; ++du) sum += depth[(v + dv) * w + u + du] / 9.0;
      blurred[v * w + u] = static_cast<float>(sum);
    }
  const auto edges = depthEdges(blurred, w, h);
  // The square's middle and the far background are not edges; its outline ring (mixed) is.
  EXPECT_EQ(edges[20 * w + 30], 0);
  EXPECT_EQ(edges[2 * w + 2], 0);
  EXPECT_EQ(edges[10 * w + 30], 1);  // outermost row of the square
  EXPECT_EQ(edges[9 * w + 30], 1);   // first background row, also mixed
  EXPECT_EQ(edges[12 * w + 30], 0);  // two rows in: neither it nor its neighbours are mixed
  int on_square = 0;
  for (int v = 10; v < 30; ++v)
    for (int u = 20; u < 40; ++u) on_square += edges[v * w + u];
  EXPECT_LE(on_square, 20 * 20 - 16 * 16);  // at most a 2-pixel ring of the square

  // A plane at 75 degrees incidence with 1 mm + 0.3 % noise: no edges.
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<float> tilted(w * h);
  const double pixel = 0.5 * std::tan(40.0 * M_PI / 180.0) / 320;  // a 640-pixel image at 0.5 m
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      const double z = 0.5 + u * pixel * std::tan(75.0 * M_PI / 180.0);
      tilted[v * w + u] = static_cast<float>(z + (0.001 + 0.003 * z) * noise(rng));
    }
  int tilted_edges = 0;
  for (auto e : depthEdges(tilted, w, h)) tilted_edges += e;
  EXPECT_EQ(tilted_edges, 0);

  // No depth next to a pixel: not an edge; malformed sizes: no edges, no crash.
  std::vector<float> holes(w * h, 0.7f);
  for (int u = 0; u < w; ++u) holes[20 * w + u] = std::numeric_limits<float>::quiet_NaN();
  int hole_edges = 0;
  for (auto e : depthEdges(holes, w, h)) hole_edges += e;
  EXPECT_EQ(hole_edges, 0);
  EXPECT_EQ(depthEdges(holes, w + 1, h).size(), holes.size());
  EXPECT_TRUE(depthEdges({}, 0, 0).empty());
}
