#include "parallel_parts.h"
#include <fruit_shape_completion/instrument/sim/image_io.h>
#include <fruit_shape_completion/instrument/sim/rgbd_renderer.h>

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

namespace fruit_shape_completion {
namespace sim {

struct RgbdRenderer::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::vector<int> triangle_material;
  std::vector<int> triangle_fruit;
  std::vector<std::array<std::uint8_t, 3>> colors;
  Shading shading;
  bool textured = false;  // textures on and the scene has texture coordinates
  std::vector<Eigen::Vector3i> triangles;
  std::vector<Eigen::Vector2f> uvs;
  std::vector<std::shared_ptr<const RgbaImage>> textures;  // per material, or null
  std::vector<char> alpha_cut;                             // per material

  Eigen::Vector2f uvAt(unsigned prim, float u, float v) const {
    const Eigen::Vector3i& t = triangles[prim];
    return (1.0f - u - v) * uvs[static_cast<std::size_t>(t[0])] + u * uvs[static_cast<std::size_t>(t[1])] +
           v * uvs[static_cast<std::size_t>(t[2])];
  }
};

namespace {

// The paper's structured depth noise on a noise-free depth image (NaN: no depth). The sinusoids'
// amplitudes are the paper's; their periods (in pixels) and per-frame phases are this
// simulator's choice, since the paper does not give them. The blur averages only valid
// neighbours: a pixel keeps its validity, and next to a depth edge takes a mixed depth.
void applyPaperDepthNoise(RgbdFrame* frame, const DepthNoise& noise) {
  const int w = frame->width, h = frame->height;
  std::mt19937 rng(noise.seed * 2654435761u + 17u);
  std::uniform_real_distribution<double> phase(0.0, 2.0 * M_PI);
  const double p[5] = {phase(rng), phase(rng), phase(rng), phase(rng), phase(rng)};
  std::vector<float>& depth = frame->depth;
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      float& z = depth[static_cast<std::size_t>(v) * w + u];
      if (std::isnan(z)) continue;
      const double add = 0.002 * std::sin(2.0 * M_PI * u / 97.0 + p[0]) + 0.0015 * std::sin(2.0 * M_PI * v / 61.0 + p[1]) +
                         0.001 * std::sin(2.0 * M_PI * (u + v) / 23.0 + p[2]);
      const double mul = 1.0 + 0.002 * std::sin(2.0 * M_PI * u / 41.0 + p[3]) + 0.007 * std::sin(2.0 * M_PI * v / 149.0 + p[4]);
      z = static_cast<float>(z * mul + add);
    }
  std::vector<float> blurred(depth.size(), std::numeric_limits<float>::quiet_NaN());
  static const double kKernel[3] = {0.25, 0.5, 0.25};
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      const std::size_t px = static_cast<std::size_t>(v) * w + u;
      if (std::isnan(depth[px])) continue;
      double sum = 0.0, weight = 0.0;
      for (int dv = -1; dv <= 1; ++dv)
        for (int du = -1; du <= 1; ++du) {
          const int uu = u + du, vv = v + dv;
          if (uu < 0 || vv < 0 || uu >= w || vv >= h) continue;
          const float z = depth[static_cast<std::size_t>(vv) * w + uu];
          if (std::isnan(z)) continue;
          const double k = kKernel[du + 1] * kKernel[dv + 1];
          sum += k * z;
          weight += k;
        }
      blurred[px] = static_cast<float>(sum / weight);
    }
  std::normal_distribution<double> gauss(0.0, 1.0);
  const double min_z = frame->camera.min_range, max_z = frame->camera.max_range;
  for (std::size_t px = 0; px < blurred.size(); ++px) {
    float& z = blurred[px];
    if (std::isnan(z)) continue;
    z = static_cast<float>(z + (noise.paper_sigma_base + noise.paper_sigma_rel * z) * gauss(rng));
    if (z < min_z || z > max_z) z = std::numeric_limits<float>::quiet_NaN();
  }
  depth.swap(blurred);
}

// Embree's hit filter: hits on a leaf where its texture is transparent do not count.
void alphaCut(const RTCFilterFunctionNArguments* args) {
  const auto* impl = static_cast<const RgbdRenderer::Impl*>(args->geometryUserPtr);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    const unsigned prim = RTCHitN_primID(args->hit, args->N, i);
    const int mat = impl->triangle_material[prim];
    if (!impl->alpha_cut[static_cast<std::size_t>(mat)]) continue;
    const Eigen::Vector2f uv = impl->uvAt(prim, RTCHitN_u(args->hit, args->N, i), RTCHitN_v(args->hit, args->N, i));
    if (impl->textures[static_cast<std::size_t>(mat)]->texel(uv.x(), uv.y())[3] < 128) args->valid[i] = 0;
  }
}

}  // namespace

RgbdRenderer::RgbdRenderer(const Scene& scene, std::vector<int> triangle_fruit, const Shading& shading) : impl_(new Impl) {
  // Embree aborts the process on extreme coordinates: refuse them here with a message.
  for (const auto& v : scene.vertices)
    if (!v.allFinite() || v.cwiseAbs().maxCoeff() > kMaxCoordinate)
      throw std::invalid_argument("scene '" + scene.name + "' has a vertex that is not finite or lies beyond 1e4 m");
  for (const auto& t : scene.triangles)
    if ((t.array() < 0).any() || (t.array() >= static_cast<int>(scene.vertices.size())).any())
      throw std::invalid_argument("scene '" + scene.name + "' has a triangle with a vertex index out of range");
  if (scene.triangle_material.size() != scene.triangles.size())
    throw std::invalid_argument("scene '" + scene.name + "': one material per triangle needed");
  for (int m : scene.triangle_material)
    if (m < 0 || m >= static_cast<int>(scene.materials.size()))
      throw std::invalid_argument("scene '" + scene.name + "' has a triangle with an unknown material");
  impl_->shading = shading;
  if (!(shading.light_direction.allFinite() && shading.light_direction.norm() > 0.0))
    throw std::invalid_argument("the light direction must be a finite, non-zero vector");
  if (!(std::isfinite(shading.ambient) && shading.ambient >= 0.0 && std::isfinite(shading.diffuse) && shading.diffuse >= 0.0))
    throw std::invalid_argument("ambient and diffuse light must be finite and >= 0");
  impl_->triangle_material = scene.triangle_material;
  impl_->textured = shading.textures && scene.uvs.size() == scene.vertices.size() && !scene.vertices.empty();
  if (impl_->textured) {
    impl_->triangles = scene.triangles;
    impl_->uvs = scene.uvs;
    for (const auto& m : scene.materials) {
      impl_->textures.push_back(m.texture);
      impl_->alpha_cut.push_back(m.texture && m.texture->has_alpha);
    }
  }
  const bool any_cut = std::find(impl_->alpha_cut.begin(), impl_->alpha_cut.end(), 1) != impl_->alpha_cut.end();
  impl_->device = rtcNewDevice("threads=1");
  if (impl_->device == nullptr) throw std::runtime_error("embree: cannot create a device");
  impl_->scene = rtcNewScene(impl_->device);
  rtcSetSceneBuildQuality(impl_->scene, RTC_BUILD_QUALITY_HIGH);
  if (!scene.triangles.empty()) {
    RTCGeometry geom = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          3 * sizeof(float), scene.vertices.size()));
    for (std::size_t i = 0; i < scene.vertices.size(); ++i)
      for (int k = 0; k < 3; ++k) v[3 * i + k] = scene.vertices[i][k];
    auto* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                               3 * sizeof(unsigned), scene.triangles.size()));
    for (std::size_t i = 0; i < scene.triangles.size(); ++i)
      for (int k = 0; k < 3; ++k) idx[3 * i + k] = static_cast<unsigned>(scene.triangles[i][k]);
    if (any_cut) {
      rtcSetGeometryUserData(geom, impl_.get());
      rtcSetGeometryIntersectFilterFunction(geom, alphaCut);
      rtcSetGeometryOccludedFilterFunction(geom, alphaCut);
    }
    rtcCommitGeometry(geom);
    rtcAttachGeometry(impl_->scene, geom);
    rtcReleaseGeometry(geom);
  }
  rtcCommitScene(impl_->scene);
  impl_->triangle_fruit = std::move(triangle_fruit);
  impl_->triangle_fruit.resize(scene.triangles.size(), -1);
  for (const auto& m : scene.materials) impl_->colors.push_back(m.rgb);
}

RgbdRenderer::~RgbdRenderer() {
  if (impl_->scene) rtcReleaseScene(impl_->scene);
  if (impl_->device) rtcReleaseDevice(impl_->device);
}

RgbdFrame RgbdRenderer::render(const PinholeCamera& cam, const DepthNoise& noise, int threads) const {
  if (!cam.position.allFinite() || !cam.rotation.allFinite() || cam.position.cwiseAbs().maxCoeff() > kMaxCoordinate)
    throw std::invalid_argument("camera pose is not finite or lies beyond 1e4 m; nothing rendered");
  if (cam.width <= 0 || cam.height <= 0 || cam.width > 16384 || cam.height > 16384 || !(cam.hfov_rad > 0.0 && cam.hfov_rad < M_PI))
    throw std::invalid_argument("camera image size must be 1-16384 pixels and its field of view 0-180 degrees");
  RgbdFrame frame;
  frame.camera = cam;
  frame.width = cam.width;
  frame.height = cam.height;
  const std::size_t n = static_cast<std::size_t>(cam.width) * cam.height;
  frame.rgb.assign(3 * n, 0);
  frame.depth.assign(n, std::numeric_limits<float>::quiet_NaN());
  frame.material.assign(n, -1);
  frame.fruit.assign(n, -1);
  const Eigen::Vector3d axis = cam.rotation.col(2);
  const double cos_max = std::cos(noise.max_incidence_deg * M_PI / 180.0);
  const std::array<std::uint8_t, 3> background = {{180, 190, 200}};

  // Shades one pixel from its hit (t = range along the unit ray d), or the background.
  const Eigen::Vector3d to_light = -impl_->shading.light_direction.normalized();
  auto shadePixel = [&](int u, int v, const Eigen::Vector3d& d, bool hit, float t, unsigned prim, float bu, float bv,
                        const Eigen::Vector3d& ng, std::mt19937& rng, std::normal_distribution<double>& gauss) {
    const std::size_t px = static_cast<std::size_t>(v) * cam.width + u;
    std::uint8_t* out = &frame.rgb[3 * px];
    if (!hit) {
      std::copy(background.begin(), background.end(), out);
      return;
    }
    const int mat = impl_->triangle_material[prim];
    frame.material[px] = mat;
    frame.fruit[px] = impl_->triangle_fruit[prim];
    const Eigen::Vector3d n = ng.normalized();
    const double cos_inc = std::abs(n.dot(d));
    if (impl_->shading.textures) {
      // Lit from the side the camera sees: leaves are drawn on both faces.
      const Eigen::Vector3d facing = n.dot(d) > 0.0 ? Eigen::Vector3d(-n) : n;
      const double shade = std::min(1.0, impl_->shading.ambient + impl_->shading.diffuse * std::max(0.0, facing.dot(to_light)));
      std::array<std::uint8_t, 3> base = impl_->colors[mat];
      if (impl_->textured && impl_->textures[static_cast<std::size_t>(mat)]) {
        const Eigen::Vector2f uv = impl_->uvAt(prim, bu, bv);
        const auto texel = impl_->textures[static_cast<std::size_t>(mat)]->texel(uv.x(), uv.y());
        base = {{texel[0], texel[1], texel[2]}};
      }
      for (int k = 0; k < 3; ++k) out[k] = static_cast<std::uint8_t>(base[k] * shade + 0.5);
    } else {
      const double shade = 0.35 + 0.65 * cos_inc;  // light at the camera
      for (int k = 0; k < 3; ++k)
        out[k] = static_cast<std::uint8_t>(std::min(255.0, impl_->colors[mat][k] * shade + 0.5));
    }
    if (t < cam.min_range || t > cam.max_range) return;
    double z = t * d.dot(axis);
    if (noise.enabled && noise.model == DepthNoise::Model::kIndependent) {
      if (cos_inc < cos_max) return;
      z += (noise.base + noise.quad * (z - noise.ref) * (z - noise.ref)) * gauss(rng);
    }
    frame.depth[px] = static_cast<float>(z);
  };

  // Packets of 4 x 4 pixels (coherent primary rays trace faster together); tile rows are
  // interleaved over the threads. Noise is seeded per tile row: the same frame for any thread count.
  const int tiles_x = (cam.width + 3) / 4, tiles_y = (cam.height + 3) / 4;
  auto work = [&](int first_tile_row) {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    alignas(64) RTCRayHit16 rh;
    alignas(64) int valid[16];
    Eigen::Vector3d dirs[16];
    for (int ty = first_tile_row; ty < tiles_y; ty += std::max(1, threads)) {
      std::mt19937 rng(noise.seed * 7919u + static_cast<unsigned>(ty));
      std::normal_distribution<double> gauss(0.0, 1.0);
      for (int tx = 0; tx < tiles_x; ++tx) {
        for (int i = 0; i < 16; ++i) {
          const int u = 4 * tx + (i & 3), v = 4 * ty + (i >> 2);
          valid[i] = (u < cam.width && v < cam.height) ? -1 : 0;
          const Eigen::Vector3d d = valid[i] ? cam.rayDirection(u, v) : Eigen::Vector3d::UnitZ();
          dirs[i] = d;
          rh.ray.org_x[i] = static_cast<float>(cam.position.x());
          rh.ray.org_y[i] = static_cast<float>(cam.position.y());
          rh.ray.org_z[i] = static_cast<float>(cam.position.z());
          rh.ray.dir_x[i] = static_cast<float>(d.x());
          rh.ray.dir_y[i] = static_cast<float>(d.y());
          rh.ray.dir_z[i] = static_cast<float>(d.z());
          rh.ray.tnear[i] = 0.0f;
          rh.ray.tfar[i] = std::numeric_limits<float>::infinity();
          rh.ray.time[i] = 0.0f;
          rh.ray.mask[i] = ~0u;
          rh.ray.id[i] = static_cast<unsigned>(i);
          rh.ray.flags[i] = 0;
          rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
          rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
        }
        rtcIntersect16(valid, impl_->scene, &ctx, &rh);
        for (int i = 0; i < 16; ++i) {
          if (!valid[i]) continue;
          shadePixel(4 * tx + (i & 3), 4 * ty + (i >> 2), dirs[i], rh.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID,
                     rh.ray.tfar[i], rh.hit.primID[i], rh.hit.u[i], rh.hit.v[i],
                     Eigen::Vector3d(rh.hit.Ng_x[i], rh.hit.Ng_y[i], rh.hit.Ng_z[i]), rng, gauss);
        }
      }
    }
  };
  runParts(static_cast<std::size_t>(std::max(1, threads)), [&](std::size_t i) { work(static_cast<int>(i)); });
  if (noise.enabled && noise.model == DepthNoise::Model::kPaper) applyPaperDepthNoise(&frame, noise);
  return frame;
}

double RgbdRenderer::castRay(const Eigen::Vector3d& o, const Eigen::Vector3d& dir, double max_range) const {
  // Never hand Embree a ray it may abort on; such a ray sees nothing.
  if (!o.allFinite() || !dir.allFinite() || !(dir.norm() > 0.0) || o.cwiseAbs().maxCoeff() > kMaxCoordinate ||
      std::isnan(max_range))
    return std::numeric_limits<double>::infinity();
  const Eigen::Vector3d d = dir.normalized();
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh;
  rh.ray.org_x = static_cast<float>(o.x());
  rh.ray.org_y = static_cast<float>(o.y());
  rh.ray.org_z = static_cast<float>(o.z());
  rh.ray.dir_x = static_cast<float>(d.x());
  rh.ray.dir_y = static_cast<float>(d.y());
  rh.ray.dir_z = static_cast<float>(d.z());
  rh.ray.tnear = 0.0f;
  rh.ray.tfar = static_cast<float>(max_range);
  rh.ray.time = 0.0f;
  rh.ray.mask = ~0u;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene, &ctx, &rh);
  return rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? std::numeric_limits<double>::infinity() : rh.ray.tfar;
}

bool RgbdRenderer::isClear(const Eigen::Vector3d& p, double radius) const {
  for (int x = -1; x <= 1; ++x)
    for (int y = -1; y <= 1; ++y)
      for (int z = -1; z <= 1; ++z)
        if ((x || y || z) && std::isfinite(castRay(p, Eigen::Vector3d(x, y, z), radius))) return false;
  return true;
}

FrameClouds cloudsFromFrame(const RgbdFrame& frame, const std::vector<std::uint8_t>& mask,
                            std::vector<std::size_t>* full_pixels) {
  if (full_pixels) full_pixels->clear();
  FrameClouds clouds;
  clouds.full.reserve(frame.depth.size());
  const PinholeCamera& cam = frame.camera;
  const double f = cam.focalLength();
  for (int v = 0; v < frame.height; ++v)
    for (int u = 0; u < frame.width; ++u) {
      const std::size_t px = static_cast<std::size_t>(v) * frame.width + u;
      const double z = frame.depth[px];
      if (!std::isfinite(z)) continue;
      const Eigen::Vector3d p = cam.position + cam.rotation * cam.pixelPoint(u, v, z, f);
      clouds.full.push_back(p);
      if (full_pixels) full_pixels->push_back(px);
      if (px < mask.size() && mask[px]) clouds.fruit.push_back(p);
    }
  return clouds;
}

OrganizedFrame organizedFrame(const RgbdFrame& frame) {
  OrganizedFrame out;
  out.width = frame.width;
  out.height = frame.height;
  out.rgb = frame.rgb;
  out.xyz.assign(3 * out.pixels(), std::numeric_limits<float>::quiet_NaN());
  const PinholeCamera& cam = frame.camera;
  // depth_image_proc: x = (u - cx) z / fx with the principal point at the image centre, between
  // the two middle pixels (cloudsFromFrame's pixel centres).
  const double f = cam.focalLength();
  for (int v = 0; v < frame.height; ++v)
    for (int u = 0; u < frame.width; ++u) {
      const std::size_t px = static_cast<std::size_t>(v) * frame.width + u;
      const double z = frame.depth[px];
      if (!std::isfinite(z)) continue;
      const Eigen::Vector3d c = cam.pixelPoint(u, v, z, f);
      for (int k = 0; k < 3; ++k) out.xyz[3 * px + k] = static_cast<float>(c[k]);
    }
  return out;
}

Eigen::Isometry3d cameraPose(const PinholeCamera& camera) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = camera.rotation;
  pose.translation() = camera.position;
  return pose;
}

}  // namespace sim
}  // namespace fruit_shape_completion
