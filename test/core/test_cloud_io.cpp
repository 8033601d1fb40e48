#include <fruit_shape_completion/instrument/cloud_io.h>
#include <fruit_shape_completion/instrument/sim/synthetic_fruit.h>
#include <gtest/gtest.h>

#include <random>
#include <nlohmann/json.hpp>

#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>

using namespace fruit_shape_completion;

namespace {

std::string tempPath(const std::string& name) {
  const char* dir = std::getenv("TMPDIR");
  return std::string(dir ? dir : "/tmp") + "/fsc_test_" + std::to_string(::getpid()) + "_" + name;
}

void writeFile(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

struct CommandResult {
  int status;
  std::string out;
};

CommandResult run(const std::string& cmd) {
  CommandResult r{-1, ""};
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof(buf), p)) > 0) r.out.append(buf, n);
  const int st = pclose(p);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

std::string fitCloudExe() {
  const char* dir = std::getenv("FSC_BIN_DIR");
  return std::string(dir ? dir : ".") + "/fit_cloud";
}

}  // namespace

TEST(CloudIo, PlyRoundTripWithColours) {
  const PointList pts = {Eigen::Vector3d(0.1, 0.2, 0.3), Eigen::Vector3d(-1, 2.5, 1e-3)};
  const std::string path = tempPath("rt.ply");
  std::string err;
  ASSERT_TRUE(writePly(path, pts, {{1, 2, 3}, {4, 5, 6}}, &err)) << err;
  const CloudFile f = readPointCloud(path);
  ASSERT_TRUE(f.ok()) << f.error;
  ASSERT_EQ(f.points.size(), 2u);
  for (int i = 0; i < 2; ++i) EXPECT_LT((f.points[i] - pts[i]).norm(), 1e-6);
  std::remove(path.c_str());
}

TEST(CloudIo, BinaryPlyWithDoublesAndExtraProperties) {
  const std::string path = tempPath("bin.ply");
  std::string data =
      "ply\nformat binary_little_endian 1.0\ncomment test\nelement vertex 2\n"
      "property uchar flag\nproperty double x\nproperty double y\nproperty double z\n"
      "property float intensity\nelement face 0\nproperty list uchar int vertex_indices\n"
      "end_header\n";
  for (int v = 0; v < 2; ++v) {
    const unsigned char flag = 7;
    const double xyz[3] = {1.0 + v, 2.0, -3.0};
    const float intensity = 0.5f;
    data.append(reinterpret_cast<const char*>(&flag), 1);
    data.append(reinterpret_cast<const char*>(xyz), sizeof(xyz));
    data.append(reinterpret_cast<const char*>(&intensity), 4);
  }
  writeFile(path, data);
  const CloudFile f = readPointCloud(path);
  ASSERT_TRUE(f.ok()) << f.error;
  ASSERT_EQ(f.points.size(), 2u);
  EXPECT_EQ(f.points[1], Eigen::Vector3d(2, 2, -3));
  // Truncated data: a clear error naming the vertex.
  writeFile(path, data.substr(0, data.size() - 5));
  const CloudFile g = readPointCloud(path);
  EXPECT_FALSE(g.ok());
  EXPECT_NE(g.error.find("truncated"), std::string::npos) << g.error;
  std::remove(path.c_str());
}

TEST(CloudIo, TextWithExtraColumnsCommentsAndNaN) {
  const std::string path = tempPath("pts.txt");
  writeFile(path, "# x y z r g b\n0.1 0.2 0.3 255 0 0\n\n1,2,3\nnan 0 0\n");
  const CloudFile f = readPointCloud(path);
  ASSERT_TRUE(f.ok()) << f.error;
  ASSERT_EQ(f.points.size(), 3u);
  EXPECT_EQ(f.points[1], Eigen::Vector3d(1, 2, 3));
  EXPECT_FALSE(f.points[2].allFinite());
  writeFile(path, "0.1 0.2 0.3\n0.1 oops 0.3\n");
  const CloudFile g = readPointCloud(path);
  EXPECT_FALSE(g.ok());
  EXPECT_NE(g.error.find("line 2"), std::string::npos) << g.error;
  // Decimal commas would split into other numbers: refused, naming the line; a comma list is fine.
  writeFile(path, "0.1, 0.2, 0.3\n0,5 0,2 0,3\n");
  const CloudFile comma = readPointCloud(path);
  EXPECT_FALSE(comma.ok());
  EXPECT_NE(comma.error.find("line 2"), std::string::npos) << comma.error;
  EXPECT_NE(comma.error.find("decimal comma"), std::string::npos) << comma.error;
  // A spreadsheet's export: a byte-order mark and a header naming the columns; pandas' unnamed
  // index column first. x, y and z are read where the header names them.
  writeFile(path, "\xEF\xBB\xBFid,Z,y,X\n7,0.3,0.2,0.1\n8,3,2,1\n");
  const CloudFile named = readPointCloud(path);
  ASSERT_TRUE(named.ok()) << named.error;
  ASSERT_EQ(named.points.size(), 2u);
  EXPECT_EQ(named.points[0], Eigen::Vector3d(0.1, 0.2, 0.3));
  // `text` read whole, its first point (0.1, 0.2, 0.3).
  const auto readsFirstPoint = [&](const std::string& text) {
    writeFile(path, text);
    const CloudFile f = readPointCloud(path);
    ASSERT_TRUE(f.ok()) << text << ": " << f.error;
    EXPECT_EQ(f.points.at(0), Eigen::Vector3d(0.1, 0.2, 0.3)) << text;
  };
  readsFirstPoint(",x,y,z\n0,0.1,0.2,0.3\n");
  writeFile(path, "x y w\n0.1 0.2 0.3\n");
  const CloudFile no_z = readPointCloud(path);
  EXPECT_FALSE(no_z.ok());
  EXPECT_NE(no_z.error.find("naming the x, y and z"), std::string::npos) << no_z.error;
  // Units after the names, and a label per point in a column the header names too.
  readsFirstPoint("Point ID,x (m),y (m),z (m),label\n1,0.1,0.2,0.3,leaf\n");
  // Without a header, words after x, y and z are extra columns, as before.
  readsFirstPoint("0.1 0.2 0.3 leaf\n");
  std::remove(path.c_str());
  // A NaN row in an ASCII PLY is kept as a non-finite point (counted downstream), not fatal.
  const std::string ply = tempPath("nan.ply");
  writeFile(ply, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                 "end_header\n0.1 0.2 0.3\nnan nan nan\n1 2 3\n");
  const CloudFile h = readPointCloud(ply);
  ASSERT_TRUE(h.ok()) << h.error;
  ASSERT_EQ(h.points.size(), 3u);
  EXPECT_FALSE(h.points[1].allFinite());
  EXPECT_LT((h.points[2] - Eigen::Vector3d(1, 2, 3)).norm(), 1e-6);
  std::remove(ply.c_str());
}

TEST(CloudIo, PcdAsciiAndMalformedFiles) {
  const std::string path = tempPath("c.pcd");
  writeFile(path,
            "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\n"
            "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA ascii\n0.5 0.25 1\n-1 0 2\n");
  const CloudFile f = readPointCloud(path);
  ASSERT_TRUE(f.ok()) << f.error;
  ASSERT_EQ(f.points.size(), 2u);
  EXPECT_EQ(f.points[0], Eigen::Vector3d(0.5, 0.25, 1));
  writeFile(path, "this is not a pcd file\n");
  const CloudFile junk = readPointCloud(path);
  EXPECT_FALSE(junk.ok());
  EXPECT_NE(junk.error.find("malformed PCD"), std::string::npos) << junk.error;
  std::remove(path.c_str());
  const CloudFile missing = readPointCloud(tempPath("does_not_exist.ply"));
  EXPECT_FALSE(missing.ok());
  EXPECT_NE(missing.error.find("cannot open"), std::string::npos);
  const std::string bad_ply = tempPath("bad.ply");
  writeFile(bad_ply, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1\n2\n3\n");
  const CloudFile nxyz = readPointCloud(bad_ply);
  EXPECT_FALSE(nxyz.ok());
  EXPECT_NE(nxyz.error.find("x, y, z"), std::string::npos) << nxyz.error;
  // Found by fuzz_cloud_file: a lone colour property made PCL's reader abort on an assertion.
  writeFile(bad_ply, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                     "property uchar blue\nend_header\n0.1 0.2 0.3 20\n");
  const CloudFile lone_blue = readPointCloud(bad_ply);
  EXPECT_FALSE(lone_blue.ok());
  EXPECT_NE(lone_blue.error.find("colour"), std::string::npos) << lone_blue.error;
  // A small binary file whose header promises a million vertices of ten doubles: PCL would
  // allocate 80 MB for it before finding the data short; refused from its size first.
  std::string wide = "ply\nformat binary_little_endian 1.0\nelement vertex 1000000\n";
  for (const char* name : {"x", "y", "z", "a", "b", "c", "d", "e", "f", "g"}) wide += std::string("property double ") + name + "\n";
  writeFile(bad_ply, wide + "end_header\n" + std::string(4000000, '\0'));
  const CloudFile short_binary = readPointCloud(bad_ply);
  EXPECT_FALSE(short_binary.ok());
  EXPECT_NE(short_binary.error.find("cannot fit in the file"), std::string::npos) << short_binary.error;
  // A vertex of 21 845 bytes times a count chosen to wrap 64 bits to less than the file.
  std::string wrap = "ply\nformat binary_little_endian 1.0\nelement vertex 844437815230468\nproperty float x\n"
                     "property float y\nproperty float z\n";
  for (int k = 3; k < 5461; ++k) wrap += "property float p" + std::to_string(k) + "\n";
  writeFile(bad_ply, wrap + "property uchar q\nend_header\n" + std::string(30000, '\0'));
  const CloudFile wrapped = readPointCloud(bad_ply);
  EXPECT_FALSE(wrapped.ok());
  EXPECT_NE(wrapped.error.find("cannot fit in the file"), std::string::npos) << wrapped.error;
  // PCL's ascii reader makes NaN of what it cannot parse: decimal commas are named instead.
  writeFile(bad_ply, "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
                     "end_header\n0,1 0,2 0,3\n0,2 0,2 0,3\n");
  const CloudFile commas = readPointCloud(bad_ply);
  EXPECT_FALSE(commas.ok());
  EXPECT_NE(commas.error.find("decimal commas"), std::string::npos) << commas.error;
  std::remove(bad_ply.c_str());
}

TEST(CloudIo, PcdBinaryAndBinaryCompressed) {
  const std::string path = tempPath("b.pcd");
  const std::string header =
      "VERSION .7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\nWIDTH 3\n"
      "HEIGHT 1\nPOINTS 3\n";
  const float xyz[3][3] = {{0.1f, 0.2f, 0.3f}, {1.f, 2.f, 3.f}, {-1.f, -2.f, -3.f}};
  std::string binary = header + "DATA binary\n";
  for (const auto& p : xyz) {
    binary.append(reinterpret_cast<const char*>(p), 12);
    binary.append(4, '\0');
  }
  writeFile(path, binary);
  CloudFile f = readPointCloud(path);
  ASSERT_TRUE(f.ok()) << f.error;
  ASSERT_EQ(f.points.size(), 3u);
  EXPECT_LT((f.points[1] - Eigen::Vector3d(1, 2, 3)).norm(), 1e-6);
  // binary_compressed: field-major payload, LZF-coded. Literal runs only: a valid LZF stream.
  std::string raw;
  for (int k = 0; k < 3; ++k)
    for (const auto& p : xyz) raw.append(reinterpret_cast<const char*>(&p[k]), 4);
  raw.append(12, '\0');  // rgb
  std::string lzf;
  for (size_t i = 0; i < raw.size(); i += 32) {
    const size_t n = std::min<size_t>(32, raw.size() - i);
    lzf.push_back(static_cast<char>(n - 1));
    lzf.append(raw, i, n);
  }
  const std::uint32_t sizes[2] = {static_cast<std::uint32_t>(lzf.size()),
                                  static_cast<std::uint32_t>(raw.size())};
  writeFile(path, header + "DATA binary_compressed\n" +
                      std::string(reinterpret_cast<const char*>(sizes), 8) + lzf);
  f = readPointCloud(path);
  ASSERT_TRUE(f.ok()) << f.error;
  ASSERT_EQ(f.points.size(), 3u);
  EXPECT_LT((f.points[2] - Eigen::Vector3d(-1, -2, -3)).norm(), 1e-6);
  // A corrupt payload is refused, not read past its end.
  writeFile(path, header + "DATA binary_compressed\n" +
                      std::string(reinterpret_cast<const char*>(sizes), 8) + lzf.substr(0, 20));
  f = readPointCloud(path);
  EXPECT_FALSE(f.ok());
  // Lying headers: sizes the file cannot hold are refused before anything is allocated for them.
  const std::string lying[] = {
      "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 4000000000\nHEIGHT 1\nPOINTS 4000000000\nDATA binary\n",
      "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 2000000000\nPOINTS 1\nDATA binary\n",
      "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 3\nHEIGHT -2\nDATA binary\n",
      "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 99999999999999\nDATA ascii\n1 2 3\n",
      "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 4294967296\nHEIGHT 4294967296\nDATA binary\n",
      "FIELDS x y z a b c\nSIZE 4 4 4 8 8 8\nTYPE F F F F F F\nCOUNT 1 1 1 65536 65536 65536\nPOINTS 1\nDATA binary\n",
      // Found by fuzz_cloud_file: no FIELDS line (misspelt) before compressed data crashed PCL.
      "F0IELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\nWIDTH 3\nPOINTS 3\nDATA binary_compressed\n"
      "\x32\0\0\0\x30\0\0\0",
      "FIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 1\nDATA binary\n",
      // Also found by fuzz_cloud_file: header lines and control bytes among ascii points.
      "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nPOINTS 2\nDATA ascii\nTYPE F F F\n"
      "COUNT \x18\x18\x18 1 2 0.3\n",
      // A misspelt VERSION line; control bytes inside a key.
      "# .PCD v0.7V\nERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\n"
      "POINTS 1\nDATA ascii\n0.1 0.2 0.3\n",
      std::string("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nPOI\0\0\0\xf1NTS 1\nDATA binary\n", 68),
      "FIELDS x y z\nSIZE 4 4 3\nTYPE F F F\nWIDTH 1\nDATA binary\n",
      "FIELDS a b c\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA binary\n",
      // Found by fuzz_cloud_file (fifteenth session): value lines that are not numbers to their
      // end; PCL dropped the field and allocated terabytes.
      "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT =2 1 1 1\nWIDTH 0\n"
      "HEIGHT 11VIEWPOINT 1 POINTS 4\nDATA binary\n",
      "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1 2\nDATA binary\n",
  };
  for (const auto& text : lying) {
    writeFile(path, text + std::string(64, '\0'));
    f = readPointCloud(path);
    EXPECT_FALSE(f.ok()) << text;
    EXPECT_FALSE(f.error.empty());
  }
  // Refused by the header check, before PCL could ask for its allocation.
  writeFile(path, "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT =2 1 1 1\nWIDTH 0\n"
                  "HEIGHT 11VIEWPOINT 1 POINTS 4\nDATA binary\n" + std::string(64, '\0'));
  f = readPointCloud(path);
  EXPECT_NE(f.error.find("malformed PCD header: bad COUNT"), std::string::npos) << f.error;
  // An uncompressed size LZF cannot reach from its compressed size (12 MB from 20 bytes).
  {
    const std::string h3 = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1000000\nPOINTS 1000000\n";
    const std::uint32_t ratio[2] = {20u, 12000000u};
    writeFile(path, h3 + "DATA binary_compressed\n" + std::string(reinterpret_cast<const char*>(ratio), 8) +
                        std::string(20, '\0'));
    f = readPointCloud(path);
    EXPECT_FALSE(f.ok());
    EXPECT_NE(f.error.find("impossible"), std::string::npos) << f.error;
  }
  // A compressed size larger than the file.
  const std::uint32_t big[2] = {0xfffffff0u, static_cast<std::uint32_t>(raw.size())};
  writeFile(path, header + "DATA binary_compressed\n" + std::string(reinterpret_cast<const char*>(big), 8) + lzf);
  f = readPointCloud(path);
  EXPECT_FALSE(f.ok());
  EXPECT_NE(f.error.find("shorter"), std::string::npos) << f.error;
  std::remove(path.c_str());
}

TEST(FitCloudTool, JsonOutputMatchesTheFruitInTheFile) {
  std::mt19937 rng(12);
  const Superellipsoid truth = randomSuperellipsoid(rng, Eigen::Vector3d(0.1, 0.4, 0.6));
  ScanParams scan;
  scan.visible_fraction = 0.7;
  PointList pts = scanFruit(SyntheticFruit::fromSuperellipsoid(truth), scan);
  pts.emplace_back(std::numeric_limits<double>::quiet_NaN(), 0, 0);
  for (int i = 0; i < 3; ++i) pts.emplace_back(1.0, 1.0, 1.0 + 0.004 * i);  // a speck: not a fruit, counted
  const std::string input = tempPath("fruit.txt");
  {
    std::ofstream out(input);
    out.precision(9);
    for (const auto& p : pts) out << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
  }
  const std::string surface = tempPath("surface.ply");
  const CommandResult r =
      run(fitCloudExe() + " --input " + input + " --json --surface-out " + surface + " 2>/dev/null");
  ASSERT_EQ(r.status, 0) << r.out;
  // One fruit, and its volume is the truth's within 5 %.
  const nlohmann::json out = nlohmann::json::parse(r.out);
  ASSERT_EQ(out.at("fruits").size(), 1u) << r.out;
  const nlohmann::json& fruit = out["fruits"][0];
  EXPECT_NEAR(fruit.at("volume_m3").get<double>(), truth.volume(), 0.05 * truth.volume()) << r.out;
  EXPECT_EQ(out.at("non_finite_points").get<int>(), 1) << r.out;
  EXPECT_TRUE(fruit.at("converged").get<bool>()) << r.out;
  EXPECT_TRUE(fruit.at("rejected_reason").is_null()) << r.out;
  const CommandResult log = run(fitCloudExe() + " --input " + input + " --json 2>&1 >/dev/null");
  EXPECT_NE(log.out.find("3 point(s) in 1 cluster(s) of fewer than 100 points not fitted"), std::string::npos)
      << log.out;
  // Its 90 % volume interval holds the true volume, its 90 % centre radius the true centre.
  EXPECT_LE(fruit.at("volume_ci90_m3").at(0).get<double>(), truth.volume()) << r.out;
  EXPECT_GE(fruit.at("volume_ci90_m3").at(1).get<double>(), truth.volume()) << r.out;
  const auto c = fruit.at("center").get<std::vector<double>>();
  EXPECT_LE((Eigen::Vector3d(c[0], c[1], c[2]) - truth.t).norm(), fruit.at("center_r90_m").get<double>()) << r.out;
  // The surface file holds the 300 samples of the fit, on the true surface.
  const CloudFile s = readPointCloud(surface);
  ASSERT_TRUE(s.ok()) << s.error;
  ASSERT_EQ(s.points.size(), 300u);
  for (const auto& p : s.points) EXPECT_LT(truth.radialDistance(p), 0.004);
  std::remove(input.c_str());
  std::remove(surface.c_str());
}

// --voxel thins clouds that PCL's single-precision grid would not: a clump far from the origin
// (georeferenced coordinates) keeps its place to within a leaf, and a cloud spanning more
// voxels than an int counts (PCL then returns it unthinned) is thinned in slabs.
TEST(FitCloudTool, ThinningWorksFarFromTheOriginAndOverLargeExtents) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(0.0, 0.0025);
  const Eigen::Vector3d far_away(312345.678, 5678901.234, 101.5);
  PointList clump;
  for (int i = 0; i < 1000; ++i) clump.push_back(far_away + Eigen::Vector3d(u(rng), u(rng), u(rng)));
  PointList thinned = thinCloud(clump, 0.003);
  ASSERT_GE(thinned.size(), 1u);
  EXPECT_LE(thinned.size(), 8u);
  for (const auto& p : thinned) EXPECT_LT((p - far_away).norm(), 0.006) << p.transpose();
  // 12 x 12 x 3 m at 3 mm: 1.6e10 voxels. Two clumps at opposite corners, and a NaN.
  PointList wide;
  for (int i = 0; i < 1000; ++i) {
    wide.push_back(Eigen::Vector3d(u(rng), u(rng), u(rng)));
    wide.push_back(Eigen::Vector3d(12.0, 12.0, 3.0) + Eigen::Vector3d(u(rng), u(rng), u(rng)));
  }
  wide.push_back(Eigen::Vector3d(std::nan(""), 0, 0));
  thinned = thinCloud(wide, 0.003);
  EXPECT_GE(thinned.size(), 2u);
  EXPECT_LE(thinned.size(), 16u);
  for (const auto& p : thinned) EXPECT_TRUE(p.norm() < 0.01 || (p - Eigen::Vector3d(12, 12, 3)).norm() < 0.01) << p.transpose();
  // Coordinates no farm has stay as they are (no block index for them), the rest is thinned.
  thinned = thinCloud({Eigen::Vector3d(1e300, 0, 0), Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.0001, 0, 0)}, 0.003);
  EXPECT_EQ(thinned.size(), 2u);
}

TEST(FitCloudTool, ADenseRawViewIsTooLargeAClusterUnlessThinned) {
  // A camera's raw view of an 8 cm fruit 0.3 m away: about 0.7 mm between points, more than a
  // cluster may hold (cluster_max_size 10 000). fit_cloud says so and fits nothing; thinned to
  // 3 mm (--voxel) it fits the fruit. A NaN point is counted either way.
  const Superellipsoid truth = Superellipsoid::sphere(0.04, Eigen::Vector3d(0.0, 0.0, 0.3));
  std::ostringstream text;
  int n = 0;
  for (double x = -0.04; x <= 0.04; x += 0.0006)
    for (double y = -0.04; y <= 0.04; y += 0.0006)
      if (x * x + y * y < 0.04 * 0.04) {
        text << x << ' ' << y << ' ' << 0.3 - std::sqrt(0.04 * 0.04 - x * x - y * y) << '\n';
        ++n;
      }
  text << "nan 0 0\n";
  ASSERT_GT(n, 10000);
  const std::string input = tempPath("dense_view.txt");
  writeFile(input, text.str());
  CommandResult r = run(fitCloudExe() + " --input " + input + " --json 2>&1 >/dev/null");
  EXPECT_EQ(r.status, 0);
  EXPECT_NE(r.out.find("1 cluster(s) of more than 10000 points not fitted"), std::string::npos) << r.out;
  r = run(fitCloudExe() + " --input " + input + " --json 2>/dev/null");
  EXPECT_EQ(nlohmann::json::parse(r.out).at("fruits").size(), 0u) << r.out;
  r = run(fitCloudExe() + " --input " + input + " --json --voxel 0.003 2>/dev/null");
  ASSERT_EQ(r.status, 0) << r.out;
  const nlohmann::json out = nlohmann::json::parse(r.out);
  ASSERT_EQ(out.at("fruits").size(), 1u) << r.out;
  EXPECT_TRUE(out["fruits"][0].at("accepted").get<bool>()) << r.out;
  EXPECT_NEAR(out["fruits"][0].at("volume_m3").get<double>(), truth.volume(), 0.25 * truth.volume()) << r.out;
  EXPECT_EQ(out.at("non_finite_points").get<int>(), 1) << r.out;
  std::remove(input.c_str());
}

// A fruit cloud in millimetres: every point is alone within the clustering's 1 cm, nothing is
// fitted, and the tool asks about the unit; --scale 0.001 reads it as metres.
TEST(FitCloudTool, AMillimetreCloudIsNamedAndScaleReadsIt) {
  const Superellipsoid truth = Superellipsoid::sphere(0.04, Eigen::Vector3d(0.3, 0.1, 0.5));
  std::ostringstream text;
  for (const auto& p : truth.sampleSurface(4000))
    if (p.z() < 0.5) text << 1000.0 * p.x() << ' ' << 1000.0 * p.y() << ' ' << 1000.0 * p.z() << '\n';
  const std::string input = tempPath("millimetres.txt");
  writeFile(input, text.str());
  CommandResult r = run(fitCloudExe() + " --input " + input + " --json 2>/dev/null");
  ASSERT_EQ(r.status, 0) << r.out;
  nlohmann::json out = nlohmann::json::parse(r.out);
  EXPECT_EQ(out.at("accepted").get<int>(), 0);
  EXPECT_NE(out.at("warnings").dump().find("millimetres"), std::string::npos) << r.out;
  r = run(fitCloudExe() + " --input " + input + " --json --scale 0.001 2>/dev/null");
  ASSERT_EQ(r.status, 0) << r.out;
  out = nlohmann::json::parse(r.out);
  ASSERT_EQ(out.at("accepted").get<int>(), 1) << r.out;
  EXPECT_NEAR(out["fruits"][0].at("volume_m3").get<double>(), truth.volume(), 0.1 * truth.volume()) << r.out;
  EXPECT_EQ(out.at("warnings").size(), 0u) << r.out;
  EXPECT_EQ(out.at("units").at("center").get<std::string>(), "m");
  std::remove(input.c_str());
}

TEST(FitCloudTool, BadFilesAndArgumentsFailWithAMessage) {
  const std::string exe = fitCloudExe();
  CommandResult r = run(exe + " --input /nonexistent/cloud.pcd 2>&1");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.out.find("cannot open"), std::string::npos) << r.out;
  r = run(exe + " --input " + tempPath("any.pcd") + " --bogus 2>&1");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.out.find("--bogus"), std::string::npos) << r.out;
  r = run(exe + " 2>&1");  // --input missing
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.out.find("--input"), std::string::npos) << r.out;
  r = run(exe + " --help 2>&1");
  EXPECT_EQ(r.status, 0);
  EXPECT_NE(r.out.find("--surface-out"), std::string::npos) << r.out;
  const std::string empty = tempPath("empty.txt");
  writeFile(empty, "");
  r = run(exe + " --input " + empty + " --json 2>/dev/null");
  EXPECT_EQ(r.status, 0);
  EXPECT_TRUE(nlohmann::json::parse(r.out).at("fruits").empty()) << r.out;
  std::remove(empty.c_str());
}

// A mistyped value never runs with a silently read number: the tool names the option, says what
// is wrong and exits with 2 (run_trials, as a new user would mistype it).
TEST(ToolCommandLines, BadValuesNameTheOptionAndFail) {
  const char* dir = std::getenv("FSC_BIN_DIR");
  const std::string exe = std::string(dir ? dir : ".") + "/run_trials --scene procedural:1 --trials 1 ";
  const std::pair<std::string, std::string> cases[] = {
      {"--duration 2x", "--duration"},  {"--jobs 1O", "--jobs"},           {"--duration -5", "--duration"},
      {"--trials 0", "--trials"},       {"--input rgb", "--input"},       {"--frobnicate", "--frobnicate"},
      {"--profile Paper", "--profile"}, {"--input-outliers 5,1", "--input-outliers"}};
  for (const auto& [args, option] : cases) {
    const CommandResult r = run(exe + args + " 2>&1");
    EXPECT_EQ(r.status, 2) << args << ": " << r.out;
    EXPECT_NE(r.out.find(option), std::string::npos) << args << ": " << r.out;
  }
  const CommandResult help = run(std::string(dir ? dir : ".") + "/run_trials --help 2>&1");
  EXPECT_EQ(help.status, 0);
  EXPECT_NE(help.out.find("--velocity-scaling"), std::string::npos) << help.out;
}
