// The grower's fruit report (fruit_report.h), the views that saw each fruit
// (fruit_sightings.h) and the clean-up of a killed save's temporaries (atomic_file.h).
#include <fruit_shape_completion/atomic_file.h>
#include <fruit_shape_completion/fruit_report.h>
#include <fruit_shape_completion/fruit_sightings.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

using namespace fruit_shape_completion;
namespace fs = std::filesystem;

namespace {

FruitEstimate fruit(int id, const Eigen::Vector3d& c, double r, bool accepted = true) {
  FruitEstimate f;
  f.id = id;
  f.shape = Superellipsoid::sphere(r, c);
  f.volume = f.shape.volume();
  f.accepted = accepted;
  f.n_points = 100 + id;
  f.volume_lo = 0.9 * f.volume;
  f.volume_hi = 1.2 * f.volume;
  f.center_r90 = 0.001 * id;
  return f;
}

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

struct TempDir {
  fs::path path;
  TempDir() {
    char tmpl[] = "/tmp/fruit_report_testXXXXXX";
    path = mkdtemp(tmpl);
  }
  ~TempDir() { fs::remove_all(path); }
};

}  // namespace

TEST(FruitReport, CsvAndJsonHoldOneRowPerAcceptedFruitThatReadsBack) {
  TempDir dir;
  const std::vector<FruitEstimate> fruits = {fruit(3, {0.1, 0.2, 0.5}, 0.04), fruit(5, {-0.3, 0.0, 0.7}, 0.03, false),
                                             fruit(7, {0.4, -0.1, 0.6}, 0.035)};
  std::map<int, FruitSightings> seen;
  seen[3] = {4, 1.5, 9.25};
  std::string error;
  const std::string csv = (dir.path / "fruits.csv").string();
  ASSERT_TRUE(writeFruitReport(csv, fruits, seen, &error)) << error;
  std::istringstream lines(slurp(csv));
  std::string header, row3, row7, extra;
  std::getline(lines, header);
  std::getline(lines, row3);
  std::getline(lines, row7);
  EXPECT_FALSE(std::getline(lines, extra)) << "a row for the rejected fruit: " << extra;
  EXPECT_EQ(header.rfind("id,x,y,z,volume_m3,a,b,c,e1,e2,roll,pitch,yaw,points,views,first_seen,last_seen", 0), 0u);
  std::vector<std::string> cells;
  std::istringstream r3(row3);
  for (std::string cell; std::getline(r3, cell, ',');) cells.push_back(cell);
  ASSERT_EQ(cells.size(), fruitReportColumns().size());
  EXPECT_EQ(cells[0], "3");
  EXPECT_NEAR(std::stod(cells[1]), 0.1, 1e-9);
  EXPECT_NEAR(std::stod(cells[4]), fruits[0].volume, 1e-12);
  EXPECT_EQ(cells[13], "103");
  EXPECT_EQ(cells[14], "4");
  EXPECT_NEAR(std::stod(cells[15]), 1.5, 1e-9);
  EXPECT_NEAR(std::stod(cells[16]), 9.25, 1e-9);
  EXPECT_NEAR(std::stod(cells[17]), 0.9 * fruits[0].volume, 1e-12);  // the 90 % volume interval
  EXPECT_NEAR(std::stod(cells[18]), 1.2 * fruits[0].volume, 1e-12);
  EXPECT_NEAR(std::stod(cells[19]), 0.003, 1e-12);  // the 90 % centre radius
  // A fruit no view was matched to: 0 views, no stamps (empty cells).
  EXPECT_NE(row7.find(",0,,"), std::string::npos) << row7;
  // A fruit whose own views were counted reports the count its interval was made from, even
  // where the log (read at another moment) has counted one more since.
  std::vector<FruitEstimate> counted = fruits;
  counted[0].views = 3;
  ASSERT_TRUE(writeFruitReport(csv, counted, seen, &error)) << error;
  std::istringstream again(slurp(csv));
  std::getline(again, header);
  std::getline(again, row3);
  std::vector<std::string> recounted;
  std::istringstream r3b(row3);
  for (std::string cell; std::getline(r3b, cell, ',');) recounted.push_back(cell);
  ASSERT_EQ(recounted.size(), fruitReportColumns().size());
  EXPECT_EQ(recounted[14], "3");

  const std::string json = (dir.path / "fruits.json").string();
  ASSERT_TRUE(writeFruitReport(json, fruits, seen, &error)) << error;
  const auto j = nlohmann::json::parse(slurp(json));
  ASSERT_EQ(j["fruits"].size(), 2u);
  EXPECT_EQ(j["fruits"][0]["id"], 3);
  EXPECT_NEAR(j["fruits"][1]["volume_m3"].get<double>(), fruits[2].volume, 1e-12);
  EXPECT_TRUE(j["fruits"][1]["first_seen"].is_null());
  EXPECT_NEAR(j["fruits"][1]["center_r90_m"].get<double>(), 0.007, 1e-12);
  // A robot's stamps (seconds since 1970, 1.7e9) keep their milliseconds and more, not 10 s.
  std::map<int, FruitSightings> stamped;
  stamped[3] = {2, 1732550404.125, 1732550419.875};
  ASSERT_TRUE(writeFruitReport(json, fruits, stamped, &error)) << error;
  const auto js = nlohmann::json::parse(slurp(json));
  EXPECT_NEAR(js["fruits"][0]["first_seen"].get<double>(), 1732550404.125, 1e-6);
  EXPECT_NEAR(js["fruits"][0]["last_seen"].get<double>(), 1732550419.875, 1e-6);

  EXPECT_FALSE(writeFruitReport((dir.path / "fruits.txt").string(), fruits, seen, &error));
  EXPECT_NE(error.find(".csv or .json"), std::string::npos) << error;
  EXPECT_FALSE(writeFruitReport("/nonexistent-dir/fruits.csv", fruits, seen, &error));
}

TEST(FruitSightings, ViewsCountForTheFruitsTheirPointsFellOnIncludingViewsBeforeTheFirstFit) {
  const FruitEstimate a = fruit(1, {0, 0, 0.5}, 0.04), b = fruit(2, {0.3, 0, 0.5}, 0.04);
  auto pointsOn = [](const FruitEstimate& f, int n) {
    PointList out;
    for (const auto& p : f.shape.sampleSurface(n)) out.push_back(p);
    return out;
  };
  auto at = [](double x) {  // a camera pose of its own per view
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.translation() = Eigen::Vector3d(x, 0, 0);
    return pose;
  };
  FruitSightingLog log(8, 64);
  log.addView(1.0, pointsOn(a, 100), at(0.1));  // before any fit
  log.update({a});
  log.addView(2.0, pointsOn(b, 100), at(0.2));  // b seen; b is fitted only at the next update
  log.addView(3.0, pointsOn(a, 2), at(0.3));    // two points: not enough to count
  log.update({a, b});
  log.addView(4.0, pointsOn(a, 100), at(0.4));
  PointList both = pointsOn(a, 50);
  for (const auto& p : pointsOn(b, 50)) both.push_back(p);
  log.addView(5.0, both, at(0.5));
  log.update({a, b});
  const auto s = log.sightings();
  ASSERT_EQ(s.count(1), 1u);
  ASSERT_EQ(s.count(2), 1u);
  EXPECT_EQ(s.at(1).views, 3);
  EXPECT_DOUBLE_EQ(s.at(1).first_seen, 1.0);
  EXPECT_DOUBLE_EQ(s.at(1).last_seen, 5.0);
  EXPECT_EQ(s.at(2).views, 2);
  EXPECT_DOUBLE_EQ(s.at(2).first_seen, 2.0);
  EXPECT_DOUBLE_EQ(s.at(2).last_seen, 5.0);
  log.clear();
  EXPECT_TRUE(log.sightings().empty());
}

// Upstream inserts every frame while the arm stands still: frames from one pose are one view, so
// the volume interval does not narrow for a fruit seen from one place.
TEST(FruitSightings, FramesFromOneCameraPoseCountAsOneView) {
  const FruitEstimate a = fruit(1, {0, 0, 0.5}, 0.04);
  const PointList seen = a.shape.sampleSurface(100);
  auto pose = [](double x, double yaw_deg) {
    Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
    p.translation() = Eigen::Vector3d(x, 0, 0);
    p.linear() = Eigen::AngleAxisd(yaw_deg * M_PI / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    return p;
  };
  FruitSightingLog log(16, 64);
  for (int k = 0; k < 5; ++k) log.addView(k, seen, pose(0.0, 0.0));  // standing still
  log.update({a});
  EXPECT_EQ(log.sightings().at(1).views, 1);
  log.addView(5, seen, pose(0.001, 0.5));  // jitter of one pose
  log.update({a});
  EXPECT_EQ(log.sightings().at(1).views, 1);
  log.addView(6, seen, pose(0.03, 0.0));   // moved 3 cm: another view
  log.addView(7, seen, pose(0.03, 0.0));
  log.update({a});
  EXPECT_EQ(log.sightings().at(1).views, 2);
  log.addView(8, seen, pose(0.03, 8.0));   // turned 8 degrees in place: another view
  log.update({a});
  EXPECT_EQ(log.sightings().at(1).views, 3);
  // Creeping 1.5 cm per frame: measured from where the view began, every second frame is new.
  for (int k = 1; k <= 4; ++k) log.addView(8 + k, seen, pose(0.03 + 0.015 * k, 8.0));
  log.update({a});
  EXPECT_EQ(log.sightings().at(1).views, 5);
  // A pose that is not finite is never the same pose.
  Eigen::Isometry3d bad = pose(0.09, 8.0);
  bad.translation().x() = std::numeric_limits<double>::quiet_NaN();
  log.addView(13, seen, bad);
  log.addView(14, seen, bad);
  log.update({a});
  EXPECT_EQ(log.sightings().at(1).views, 7);
  EXPECT_DOUBLE_EQ(log.sightings().at(1).last_seen, 14.0);
  // After a pose that was not finite, the next frame where the last finite view stood is new.
  log.addView(15, seen, pose(0.09, 8.0));
  log.update({a});
  EXPECT_EQ(log.sightings().at(1).views, 8);

  // A fruit fitted only later finds the poses that saw it, its frames on both sides of an update
  // one view; a log that keeps four entries keeps four poses however many frames each sent.
  const FruitEstimate b = fruit(2, {0.3, 0, 0.5}, 0.04);
  const PointList seen_b = b.shape.sampleSurface(100);
  FruitSightingLog small(4, 64);
  for (int p = 0; p < 3; ++p)
    for (int k = 0; k < 10; ++k) small.addView(20 + p + 0.01 * k, seen_b, pose(0.1 * p, 0.0));
  small.update({a});  // b not fitted yet: its frames wait as kept views
  for (int k = 0; k < 5; ++k) small.addView(23 + 0.01 * k, seen_b, pose(0.2, 0.0));  // still the third pose
  small.addView(24, PointList(), pose(0.5, 0.0));  // a frame without fruit points: nothing to match
  small.update({a, b});
  ASSERT_EQ(small.sightings().count(2), 1u);
  EXPECT_EQ(small.sightings().at(2).views, 3);
  EXPECT_DOUBLE_EQ(small.sightings().at(2).first_seen, 20.0);
  EXPECT_DOUBLE_EQ(small.sightings().at(2).last_seen, 23.04);
}

// A saved map keeps its fruits' counts: after a load each fruit fitted near a saved centre
// starts from the nearest record (each used once), one farther than kCarryRadius from all from
// nothing; records round-trip through their bytes and bad bytes are refused with a message.
TEST(FruitSightings, ALoadedMapsFruitsStartFromTheNearestSavedCounts) {
  FruitSightings five, two;
  five.views = 5;
  five.first_seen = 1.0;
  five.last_seen = 9.0;
  two.views = 2;
  two.first_seen = 3.0;
  two.last_seen = 4.0;
  const std::vector<CarriedSightings> saved = {{Eigen::Vector3d(0, 0, 0.5), five}, {Eigen::Vector3d(0.3, 0, 0.5), two}};
  std::string bytes = "map bytes";
  const std::size_t map_size = bytes.size();
  appendCarriedSightings(saved, &bytes);
  std::vector<CarriedSightings> read;
  std::string error;
  ASSERT_TRUE(readCarriedSightings(bytes.substr(map_size), &read, &error)) << error;
  ASSERT_EQ(read.size(), 2u);
  EXPECT_EQ(read[1].center, saved[1].center);
  EXPECT_EQ(read[1].seen.views, 2);
  EXPECT_DOUBLE_EQ(read[0].seen.last_seen, 9.0);
  EXPECT_TRUE(readCarriedSightings("", &read, &error));
  EXPECT_TRUE(read.empty());
  EXPECT_FALSE(readCarriedSightings(bytes.substr(map_size, bytes.size() - map_size - 3), &read, &error));
  EXPECT_NE(error.find("truncated"), std::string::npos) << error;
  EXPECT_FALSE(readCarriedSightings("not counts at all", &read, &error));

  FruitSightingLog log(8, 64);
  log.carryOver(saved);
  // Refitted 6 mm off the first centre, and one 2.5 cm from the second: only the first claims.
  const FruitEstimate a = fruit(7, {0.006, 0, 0.5}, 0.04), far = fruit(8, {0.3, 0.025, 0.5}, 0.04);
  log.addView(20.0, a.shape.sampleSurface(100), Eigen::Isometry3d::Identity());
  log.update({a, far});
  EXPECT_EQ(log.sightings().at(7).views, 6);
  EXPECT_DOUBLE_EQ(log.sightings().at(7).first_seen, 1.0);
  EXPECT_DOUBLE_EQ(log.sightings().at(7).last_seen, 20.0);
  EXPECT_EQ(log.sightings().at(8).views, 0);
  // Saved again: fruit 7's counts and the record no fruit claimed; still so when fruit 7 was
  // not accepted in the last update (a leaf grown into its cluster): its counts stay.
  for (const bool accepted : {true, false}) {
    FruitEstimate a_now = a;
    a_now.accepted = accepted;
    if (accepted) log.update({a_now, far});
    else log.update({far}, {a_now});
    const std::vector<CarriedSightings> again = log.carried();
    int views = 0, at_a = 0;
    for (const auto& c : again) {
      views += c.seen.views;
      at_a += (c.center - a.shape.t).norm() < 1e-9 ? 1 : 0;
    }
    EXPECT_EQ(views, 6 + 2);
    EXPECT_EQ(at_a, 1);
  }
  // An id the last update no longer had (a fragment merged into its fruit) is not saved.
  log.update({far});
  int saved_views = 0;
  for (const auto& c : log.carried()) saved_views += c.seen.views;
  EXPECT_EQ(saved_views, 2);  // the unclaimed record only
  // A fragment fitted beside a fruit does not take the fruit's record: nearest pairs first.
  FruitSightingLog pairs(8, 64);
  pairs.carryOver({{Eigen::Vector3d(0, 0, 0.5), five}});
  const FruitEstimate fragment = fruit(1, {0.015, 0, 0.5}, 0.02), whole = fruit(2, {0.002, 0, 0.5}, 0.04);
  pairs.update({fragment, whole});
  EXPECT_EQ(pairs.sightings().at(2).views, 5);
  EXPECT_EQ(pairs.sightings().at(1).views, 0);
  log.clear();
  EXPECT_TRUE(log.carried().empty());
  // A count a saved map could not hold is refused, not carried into the log.
  std::string hostile;
  FruitSightings huge = five;
  huge.views = kMaxCarriedViews + 1;
  appendCarriedSightings({{Eigen::Vector3d(0, 0, 0.5), huge}}, &hostile);
  EXPECT_FALSE(readCarriedSightings(hostile, &read, &error));
}

TEST(AtomicFile, AKilledSavesTemporaryIsRemovedOnceOldAndOthersAreLeftAlone) {
  TempDir dir;
  const std::string target = (dir.path / "map.tsdf").string();
  std::string error;
  ASSERT_TRUE(writeFileAtomically(target, "old", &error)) << error;
  const fs::path stale = target + ".tmpAb12Cd", fresh = target + ".tmpZz99Yy", other = dir.path / "map.tsdf.bak",
                 other_target = dir.path / "other.tsdf.tmpAb12Cd";
  for (const auto& p : {stale, fresh, other, other_target}) std::ofstream(p) << "partial";
  fs::last_write_time(stale, fs::file_time_type::clock::now() - std::chrono::minutes(5));
  fs::last_write_time(other_target, fs::file_time_type::clock::now() - std::chrono::minutes(5));
  const std::vector<std::string> removed = removeStaleTemporaries(target);
  ASSERT_EQ(removed.size(), 1u);
  EXPECT_EQ(removed[0], stale.string());
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_TRUE(fs::exists(fresh));  // a write that may still be running
  EXPECT_TRUE(fs::exists(other));
  EXPECT_TRUE(fs::exists(other_target));
  EXPECT_EQ(slurp(target), "old");
  EXPECT_EQ(removeStaleTemporaries(target, 0.0).size(), 1u);  // the fresh one, once old enough
  EXPECT_TRUE(removeStaleTemporaries((dir.path / "missing" / "x.tsdf").string()).empty());
}
