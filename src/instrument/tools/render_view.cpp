// render_view: renders one RGB-D view of a scene and writes what the camera saw.
//   render_view --scene FILE|procedural[:SEED] --camera x,y,z,look_x,look_y,look_z --out DIR
//               [--profile paper|ideal] [--no-noise] [--seed N]
// Paper (default): textured, lit plants, the paper's depth noise, pointcloud_roi's red test;
// ideal: flat colours, i.i.d. depth noise, this simulator's HSV red test.
// DIR gets color.png, depth.png (16-bit, millimetres, 0 = no depth), mask.png (the red
// thresholder: 255 = fruit), labels.png (ground truth: 255 = fruit pixel), fruit_cloud.ply and
// full_cloud.ply (world frame).
#include <fruit_shape_completion/instrument/cloud_io.h>
#include <fruit_shape_completion/instrument/sim/fruit_mask.h>
#include <fruit_shape_completion/instrument/sim/fruit_truth.h>
#include <fruit_shape_completion/instrument/sim/image_io.h>
#include <fruit_shape_completion/instrument/sim/procedural_scene.h>
#include <fruit_shape_completion/instrument/sim/rgbd_renderer.h>

#include <filesystem>

#include <cmath>
#include <cstring>
#include "command_line.h"

#include <iostream>
#include <sstream>

using namespace fruit_shape_completion;
using namespace fruit_shape_completion::sim;

int main(int argc, char** argv) {
  std::string spec, camera_arg, out;
  DepthNoise noise;
  std::string profile = "paper";
  CLI::App app("Renders one RGB-D view of a scene (PNG images, PLY clouds, the fruit mask).", "render_view");
  app.add_option("--scene", spec, "scene file, or procedural[:SEED]")->required();
  app.add_option("--camera", camera_arg, "x,y,z,look_x,look_y,look_z (default: the scene's start view)");
  app.add_option("--out", out, "output directory")->required();
  app.add_option("--profile", profile, "paper (textures, the paper's noise, pointcloud_roi's red test) or ideal")
      ->check(CLI::IsMember({"paper", "ideal"}))->capture_default_str();
  app.add_flag_callback("--no-noise", [&] { noise.enabled = false; }, "noise-free depth");
  app.add_option("--seed", noise.seed, "depth-noise seed");
  if (const int done = parseCommandLine(app, argc, argv); done >= 0) return done;
  const bool paper = profile == "paper";
  Shading shading;
  shading.textures = paper;
  if (paper) noise.model = DepthNoise::Model::kPaper;
  RedThreshold red_test;
  if (paper) red_test.test = RedThreshold::Test::kUpstream;
  Scene scene;
  std::string err;
  if (!loadSceneSpec(spec, &scene, &err)) {
    std::cerr << "render_view: " << err << "\n";
    return 1;
  }
  Eigen::Vector3d pos = scene.camera_start_position, look = scene.camera_start_look_at;
  if (!camera_arg.empty()) {
    std::stringstream ss(camera_arg);
    double v[6];
    char comma;
    bool ok = static_cast<bool>(ss >> v[0]);
    for (int k = 1; k < 6 && ok; ++k) ok = static_cast<bool>(ss >> comma >> v[k]) && comma == ',';
    if (!ok || !(ss >> std::ws).eof()) {
      std::cerr << "render_view: --camera needs six comma-separated numbers x,y,z,look_x,look_y,look_z\n";
      return 2;
    }
    pos = Eigen::Vector3d(v[0], v[1], v[2]);
    look = Eigen::Vector3d(v[3], v[4], v[5]);
  }
  if (!pos.allFinite() || !look.allFinite() || (look - pos).norm() < 1e-6 ||
      std::max(pos.cwiseAbs().maxCoeff(), look.cwiseAbs().maxCoeff()) > kMaxCoordinate) {
    std::cerr << "render_view: the camera position and look-at point must be finite, distinct and within 1e4 m\n";
    return 2;
  }
  std::vector<int> triangle_fruit;
  computeFruitTruth(scene, &triangle_fruit);
  for (const auto& note : scene.notes) std::cerr << "render_view: " << note << "\n";
  const RgbdRenderer renderer(scene, triangle_fruit, shading);
  const RgbdFrame frame = renderer.render(PinholeCamera::lookingAt(pos, look), noise);
  const std::vector<std::uint8_t> mask = redMask(frame.rgb, frame.width, frame.height, red_test);
  const FrameClouds clouds = cloudsFromFrame(frame, mask);

  std::error_code mkdir_error;
  std::filesystem::create_directories(out, mkdir_error);
  const std::size_t n = frame.depth.size();
  std::vector<std::uint16_t> depth_mm(n, 0);
  std::vector<std::uint8_t> mask8(n), labels8(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (std::isfinite(frame.depth[i])) depth_mm[i] = static_cast<std::uint16_t>(std::min(65535.0, std::round(frame.depth[i] * 1000.0)));
    mask8[i] = mask[i] ? 255 : 0;
    labels8[i] = frame.fruit[i] >= 0 ? 255 : 0;
  }
  const bool ok = writePng(out + "/color.png", frame.width, frame.height, 3, 8, frame.rgb.data(), &err) &&
                  writePng(out + "/depth.png", frame.width, frame.height, 1, 16, depth_mm.data(), &err) &&
                  writePng(out + "/mask.png", frame.width, frame.height, 1, 8, mask8.data(), &err) &&
                  writePng(out + "/labels.png", frame.width, frame.height, 1, 8, labels8.data(), &err) &&
                  writePly(out + "/fruit_cloud.ply", clouds.fruit, {}, &err) &&
                  writePly(out + "/full_cloud.ply", clouds.full, {}, &err);
  if (!ok) {
    std::cerr << "render_view: " << err << "\n";
    return 1;
  }
  std::cerr << "render_view: " << clouds.full.size() << " depth pixels, " << clouds.fruit.size()
            << " fruit pixels -> " << out << "\n";
  return 0;
}
