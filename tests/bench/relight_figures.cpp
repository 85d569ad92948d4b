// The figures of relightable volumes (README "Relighting", docs/performance-history.md): bake
// time with and without a sky transfer, file bytes per probe, relight time per million probes,
// and the error of a relit volume against the order Ls of the sky for a soft sky and a sharp sun.
// Short runs (about two minutes on 2 cores): probebake_relight_figures [THREADS [errors]].
// Prints one line per figure.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include <unistd.h>

#include "probebake/bake/bake.h"
#include "probebake/bake/relight.h"
#include "probebake/base/log.h"
#include "probebake/job/job.h"
#include "probebake/job/job_json.h"
#include "probebake/math/mat3.h"
#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sh_convolution.h"
#include "probebake/volume/vdb_io.h"

namespace probebake {
namespace {

constexpr double kPi = std::numbers::pi;
const std::string kDataDir = PROBEBAKE_TEST_DATA_DIR;

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// The demo room; counts {0,0,0}: its own 0.5 spacing (1124 probes). noLights: the sky alone.
BakeJob DemoJob(int64_t samples, int skyOrder, std::array<int, 3> counts, bool noLights) {
  absl::StatusOr<v1::JobSpec> spec = ReadJobFile(kDataDir + "/demo/demo.json");
  if (!spec.ok()) std::abort();
  if (counts[0] > 0) {
    spec->mutable_grid()->clear_spacing();
    spec->mutable_grid()->clear_counts();
    for (int c : counts) spec->mutable_grid()->add_counts(c);
  }
  if (noLights) spec->mutable_scene()->clear_lights();
  v1::BakeSettings* s = spec->mutable_settings();
  s->set_samples_per_probe(samples);
  if (skyOrder > 0) s->mutable_sky_transfer()->set_order(skyOrder);
  const JobLimits limits;
  absl::StatusOr<BakeJob> job =
      BuildBakeJob(*spec, LocalAssetSource(kDataDir + "/demo", "", limits.maxAssetBytes), limits);
  if (!job.ok()) {
    std::fprintf(stderr, "%s\n", std::string(job.status().message()).c_str());
    std::abort();
  }
  return *std::move(job);
}

ProbeVolume BakeOrDie(const BakeJob& job, int threads, double* seconds = nullptr) {
  BakeOptions options;
  options.threads = threads;
  const auto start = std::chrono::steady_clock::now();
  absl::StatusOr<ProbeVolume> v = Bake(job, options);
  if (!v.ok()) std::abort();
  if (seconds) *seconds = Seconds(start);
  return *std::move(v);
}

// A Z-up map: soft blue sky, warm horizon, dark ground, and a sun of 0.53 degrees (the real
// sun's) toward `sun`, of radiance `sunRadiance` (0: none).
// horizonBelow: the lower hemisphere holds the horizon's colour instead of a dark ground (the
// sky then has no edge at the horizon; the ground hides that half from probes above it anyway).
Environment Sky(const Vec3d& sun, double sunRadiance, bool horizonBelow = false) {
  auto map = std::make_shared<EnvironmentMap>();
  const int w = 2048, h = 1024;
  map->width = w, map->height = h;
  map->worldFromMap = Mat3d::FromRows({1, 0, 0}, {0, 0, -1}, {0, 1, 0});
  map->rgb.resize(size_t(w) * h * 3);
  const double cosSun = std::cos(0.53 / 2 * kPi / 180);
  for (int iy = 0; iy < h; ++iy) {
    const double lat = kPi * (0.5 - double(iy) / (h - 1));
    for (int ix = 0; ix < w; ++ix) {
      const double lon = 2 * kPi * (0.5 - double(ix) / (w - 1));
      const Vec3d d = map->worldFromMap * Vec3d{std::sin(lon) * std::cos(lat), std::sin(lat),
                                                std::cos(lon) * std::cos(lat)};
      Vec3d rgb = horizonBelow ? Vec3d{1.0, 0.8, 0.6} : Vec3d{0.05, 0.04, 0.03};
      if (d.z >= 0) {
        const double horizon = std::exp(-4 * d.z);
        rgb = Vec3d{0.3, 0.45, 0.8} * (1 - horizon) + Vec3d{1.0, 0.8, 0.6} * horizon;
        if (sunRadiance > 0 && Dot(d, sun) > cosSun) rgb += Vec3d{1, 0.9, 0.8} * sunRadiance;
      }
      for (int ch = 0; ch < 3; ++ch) map->rgb[3 * (size_t(iy) * w + ix) + ch] = float(rgb[ch]);
    }
  }
  return {Environment::Kind::kMap, {}, map};
}

// Mean over the active probes of the relative L2 error of the irradiance over the sphere of
// normals (luminance; sum_i A_l^2 dE_i^2 / sum_i A_l^2 E_i^2 by orthonormality).
double IrradianceError(const ProbeVolume& got, const ProbeVolume& want) {
  double sum = 0;
  int64_t n = 0;
  for (int64_t p = 0; p < want.grid.ProbeCount(); ++p) {
    if (!want.active[p]) continue;
    double err = 0, norm = 0;
    for (int l = 0, i = 0; l <= want.shOrder; ++l) {
      const double a = IrradianceBandFactor(l);
      for (int m = -l; m <= l; ++m, ++i) {
        const auto lum = [&](const ProbeVolume& v) {
          return Luminance(
              Vec3d(v.radiance[i][3 * p], v.radiance[i][3 * p + 1], v.radiance[i][3 * p + 2]));
        };
        err += a * a * (lum(got) - lum(want)) * (lum(got) - lum(want));
        norm += a * a * lum(want) * lum(want);
      }
    }
    sum += std::sqrt(err / norm);
    ++n;
  }
  return sum / double(n);
}

int64_t Active(const ProbeVolume& v) {
  int64_t n = 0;
  for (uint8_t a : v.active) n += a;
  return n;
}

void BakeTimesAndBytes(int threads) {
  const std::string dir = std::filesystem::temp_directory_path() /
                          ("probebake_relight_figures_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  for (const int samples : {512}) {
    double base = 0;
    for (const int order : {0, 2, 4}) {
      const BakeJob job = DemoJob(samples, order, {0, 0, 0}, false);
      double seconds = 0;
      const ProbeVolume v = BakeOrDie(job, threads, &seconds);
      const std::string path = dir + "/demo" + std::to_string(order) + ".vdb";
      if (!WriteProbeVolume(path, v, VolumeMetadataFor(job)).ok()) std::abort();
      const double bytes = double(std::filesystem::file_size(path)) / double(Active(v));
      if (order == 0) base = seconds;
      std::printf(
          "bake demo room (%lld probes, %d spp, L=2, irradiance, %d threads) Ls=%d: "
          "%.2f s (x%.2f), %.1f Mrays/s, file %.0f bytes/probe\n",
          (long long)Active(v), samples, threads, order, seconds, seconds / base,
          double(v.stats.rays) / seconds * 1e-6, bytes);
    }
  }
  // A denser grid (spacing 0.25) for the bytes, where the per-grid overhead is amortised.
  for (const int order : {0, 2, 4}) {
    const BakeJob job = DemoJob(8, order, {32, 24, 12}, false);
    const ProbeVolume v = BakeOrDie(job, threads);
    const std::string path = dir + "/dense" + std::to_string(order) + ".vdb";
    if (!WriteProbeVolume(path, v, VolumeMetadataFor(job)).ok()) std::abort();
    std::printf("file bytes per probe, %lld probes, L=2 with irradiance, Ls=%d: %.0f\n",
                (long long)Active(v), order,
                double(std::filesystem::file_size(path)) / double(Active(v)));
  }
  std::filesystem::remove_all(dir);
}

void RelightTimes() {
  // A synthetic volume of 100^2 x 10 probes, all active (the timing does not depend on values).
  for (const int skyOrder : {2, 4}) {
    ProbeVolume v;
    v.grid.spacing = {1, 1, 1};
    v.grid.counts[0] = 100, v.grid.counts[1] = 100, v.grid.counts[2] = 10;
    const int64_t n = v.grid.ProbeCount();
    v.shOrder = 2;
    v.skyTransferOrder = skyOrder;
    v.active.assign(size_t(n), 1);
    v.validity.assign(size_t(n), 1.0f);
    v.stdError = v.stdErrorL0 = v.sampleCount = v.validity;
    v.radiance.assign(9, std::vector<float>(3 * size_t(n), 0.1f));
    v.irradiance = v.radiance;
    v.skyTransfer.assign(size_t(9 * v.SkyCoeffCount()), std::vector<float>(3 * size_t(n), 0.01f));
    const std::vector<Vec3d> sky(size_t(v.SkyCoeffCount()), Vec3d{1, 1, 1});
    const auto start = std::chrono::steady_clock::now();
    const absl::StatusOr<ProbeVolume> relit = Relight(v, sky);
    const double seconds = Seconds(start);
    if (!relit.ok()) std::abort();
    std::printf(
        "relight L=2 with irradiance, Ls=%d: %.3f s for %lld probes = %.2f s per million "
        "probes\n",
        skyOrder, seconds, (long long)n, seconds / double(n) * 1e6);
  }
}

// Outdoors: a grey ground (albedo 0.3, 40 x 40) with the demo's boxes scaled up as buildings,
// 4 x 4 x 2 probes around them.
BakeJob OutdoorJob(int64_t samples, int skyOrder) {
  BakeJob job;
  job.scene.materials.push_back({"ground", {0.3, 0.3, 0.3}, {}});
  job.scene.materials.push_back({"wall", {0.6, 0.5, 0.4}, {}});
  TriangleMesh ground;
  ground.name = "ground";
  ground.positions = {{-20, -20, 0}, {20, -20, 0}, {20, 20, 0}, {-20, 20, 0}};
  ground.indices = {0, 1, 2, 0, 2, 3};
  job.scene.meshes.push_back(ground);
  for (const auto& [lo, hi] : {std::pair{Vec3d{-3, -1, 0}, Vec3d{-1, 3, 4}},
                               std::pair{Vec3d{1, -3, 0}, Vec3d{4, -1, 2}}}) {
    TriangleMesh box;
    box.name = "building";
    box.material = 1;
    for (int k = 0; k < 8; ++k)
      box.positions.push_back(
          {(k & 1) ? hi.x : lo.x, (k & 2) ? hi.y : lo.y, (k & 4) ? hi.z : lo.z});
    box.indices = {0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4,
                   2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5};
    job.scene.meshes.push_back(box);
  }
  job.grid.origin = {-3.5, -3.5, 0.5};
  job.grid.spacing = {2.2, 2.2, 1.5};
  job.grid.counts[0] = job.grid.counts[1] = 4;
  job.grid.counts[2] = 2;
  job.settings.shOrder = 2;
  job.settings.samplesPerProbe = samples;
  job.settings.maxDepth = 6;
  job.settings.skyTransferOrder = skyOrder;
  return job;
}

void ErrorAgainstOrder(int threads) {
  const int64_t samples = 16384;
  // The sun shines through the window onto the floor.
  const Vec3d sun = Normalize(Vec3d{0.2, 0.8, 0.55});
  // A sun of radiance 2e4 on a 0.53-degree disk: about 1.3 of irradiance against the sky's ~2.
  const Environment skies[4] = {Sky(sun, 0), Sky(sun, 2e4), Sky(sun, 0, true), Sky(sun, 2e4, true)};
  const char* names[4] = {"soft sky (no sun)", "sky + sharp 0.53-degree sun",
                          "soft sky, horizon colour below",
                          "sky + sharp sun, horizon colour below"};
  for (const bool outdoor : {true, false}) {
    const BakeJob transferJob =
        outdoor ? OutdoorJob(samples, 8) : DemoJob(samples, 8, {4, 3, 2}, true);
    double seconds = 0;
    const ProbeVolume transfer = BakeOrDie(transferJob, threads, &seconds);
    for (int k = 0; k < 4; ++k) {
      BakeJob direct = transferJob;
      direct.settings.skyTransferOrder = 0;
      direct.scene.environment = skies[k];
      direct.settings.seed = 7;
      const ProbeVolume reference = BakeOrDie(direct, threads);
      direct.settings.seed = 8;
      const double noise = IrradianceError(BakeOrDie(direct, threads), reference);
      const std::vector<Vec3d> sky8 = ProjectEnvironmentSh(skies[k], 8);
      std::printf(
          "error vs Ls, %s, %s (%lld probes, %lld spp): noise floor (two direct bakes) "
          "%.4f;",
          outdoor ? "outdoors" : "demo room, sky only", names[k], (long long)Active(reference),
          (long long)samples, noise);
      for (const int order : {1, 2, 3, 4, 6, 8}) {
        const std::vector<Vec3d> sky(sky8.begin(), sky8.begin() + ShCoeffCount(order));
        const absl::StatusOr<ProbeVolume> relit = Relight(transfer, sky);
        if (!relit.ok()) std::abort();
        std::printf(" Ls=%d %.4f", order, IrradianceError(*relit, reference));
      }
      std::printf("\n");
    }
  }
}

}  // namespace
}  // namespace probebake

int main(int argc, char** argv) {
  const int threads = argc > 1 ? std::atoi(argv[1]) : 2;
  const std::string only = argc > 2 ? argv[2] : "";  // "errors": the error figures alone
  probebake::Logger("bake")->set_level(spdlog::level::warn);
  probebake::Logger("job")->set_level(spdlog::level::warn);
  if (only != "errors") {
    probebake::BakeTimesAndBytes(threads);
    probebake::RelightTimes();
  }
  probebake::ErrorAgainstOrder(threads);
  return 0;
}
