// Relighting (probebake/bake/relight.h) against direct bakes, and the sky transfer's storage
// (docs/volume-format.md, format 4).
//
// Relit against direct: the demo room (its lamp and sun as local lights, its sky through the
// window) baked once with a sky transfer and relit for a sky must match a bake with that sky.
// Per coefficient the tolerance is 4 sigma plus the truncation of the sky at order Ls:
//   - sigma combines the direct bake's reported standard error and a bound on the relit one:
//     std(local + sum_s T_s sky_s) <= se(local) + sum_s |sky_s| se(T_s) (standard deviations
//     are subadditive whatever the correlations);
//   - truncation: the relit value at Ls drops sum_{s > Ls} T_rs sky_s. The bake at Ls = 8 holds
//     T's columns up to 80 (its first (Ls+1)^2 columns are the Ls bake's, bit for bit: the same
//     paths), so the bands Ls+1..8 are measured; beyond 8 the test adds the Cauchy-Schwarz bound
//     |row r| |sky residual beyond 8|, with |row r| over all columns estimated by its visible
//     part (documented as an estimate: the test's one assumption).
// A sky of order <= Ls relights within noise: the mean of z^2 over every probe and coefficient
// (z = difference / combined sigma, sigma an upper bound) is at most 1 + 4 of its standard errors.
#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "bake_test_util.h"
#include "core/src/bake/probe_finish.h"
#include "probebake/bake/relight.h"
#include "probebake/job/job.h"
#include "probebake/job/job_json.h"
#include "probebake/sh/sh_convolution.h"
#include "probebake/sh/sh_projection.h"
#include "probebake/sh/sh_rotation.h"
#include "probebake/volume/vdb_io.h"
#include "probebake/volume/volume_merge.h"

namespace probebake {
namespace {

using namespace probebake::testing;

const std::string kDataDir = PROBEBAKE_TEST_DATA_DIR;

// The demo room over a 4 x 3 x 2 grid (near the window, the lamp and the boxes).
BakeJob DemoJob(int64_t samples, int skyOrder) {
  absl::StatusOr<v1::JobSpec> spec = ReadJobFile(kDataDir + "/demo/demo.json");
  EXPECT_TRUE(spec.ok()) << spec.status();
  v1::Grid* grid = spec->mutable_grid();
  grid->clear_spacing();
  grid->clear_counts();
  for (int c : {4, 3, 2}) grid->add_counts(c);
  v1::BakeSettings* s = spec->mutable_settings();
  s->set_samples_per_probe(samples);
  s->set_batches(kTestBatches);
  if (skyOrder > 0) s->mutable_sky_transfer()->set_order(skyOrder);
  const JobLimits limits;
  absl::StatusOr<BakeJob> job =
      BuildBakeJob(*spec, LocalAssetSource(kDataDir + "/demo", "", limits.maxAssetBytes), limits);
  EXPECT_TRUE(job.ok()) << job.status();
  return *std::move(job);
}

// Z-up lat-long map of w x h from radiance(world direction), at the pixels' centre directions.
template <typename F>
Environment MakeMap(int w, int h, F&& radiance) {
  auto map = std::make_shared<EnvironmentMap>();
  map->width = w, map->height = h;
  map->worldFromMap = Mat3d::FromRows({1, 0, 0}, {0, 0, -1}, {0, 1, 0});
  map->rgb.resize(size_t(w) * h * 3);
  for (int iy = 0; iy < h; ++iy) {
    const double lat = kPi * (0.5 - double(iy) / (h - 1));
    for (int ix = 0; ix < w; ++ix) {
      const double lon = 2 * kPi * (0.5 - double(ix) / (w - 1));
      const Vec3d mapDir{std::sin(lon) * std::cos(lat), std::sin(lat),
                         std::cos(lon) * std::cos(lat)};
      const Vec3d rgb = radiance(map->worldFromMap * mapDir);
      for (int ch = 0; ch < 3; ++ch) map->rgb[3 * (size_t(iy) * w + ix) + ch] = float(rgb[ch]);
    }
  }
  return {Environment::Kind::kMap, {}, map};
}

// A sunset: warm near the horizon, dim blue above, dark ground, and a small bright sun low in the
// west (a disk of 2 degrees radius: sharp at any order the volume holds).
Environment SunsetSky() {
  const Vec3d sun = Normalize(Vec3d{-0.9, 0.2, 0.12});
  return MakeMap(512, 256, [sun](const Vec3d& w) {
    if (w.z < 0) return Vec3d{0.05, 0.04, 0.03};
    const double horizon = std::exp(-6 * w.z);
    Vec3d sky = Vec3d{0.15, 0.2, 0.35} * (1 - horizon) + Vec3d{1.2, 0.55, 0.25} * horizon;
    if (Dot(w, sun) > std::cos(2 * kPi / 180)) sky += Vec3d{400, 260, 120};
    return sky;
  });
}

// A sky of SH order 2 (positive everywhere), as a map.
Environment BandLimitedSky(std::vector<Vec3d>* sh) {
  sh->assign(9, Vec3d{});
  (*sh)[0] = Vec3d{1.0, 0.9, 0.8} * (2 * std::sqrt(kPi));
  (*sh)[2] = {0.6, 0.7, 0.9};    // brighter above (Y2 ~ z)
  (*sh)[3] = {-0.3, -0.2, 0.1};  // toward -x in red
  (*sh)[8] = {0.2, 0.1, 0.05};
  const std::vector<Vec3d> coeffs = *sh;
  return MakeMap(1024, 512, [coeffs](const Vec3d& w) { return ShReconstructRgb(2, coeffs, w); });
}

struct Comparison {
  double worstExcess = 0;  // max over coefficients of (|diff| - 4 sigma - truncation), <= 0 passes
  double meanZ2 = 0;       // over every coefficient and channel
  double maxTruncation = 0, maxSigma = 0;
  int64_t count = 0;
};

// Compares `direct` with `transfer` relit by `skyHigh` (order 8) cut to order `order`.
Comparison Compare(const ProbeVolume& direct, const ProbeVolume& transfer8,
                   const std::vector<Vec3d>& skyHigh, int order, double residualBeyond8,
                   const std::string& what) {
  const int ns = ShCoeffCount(order), n8 = transfer8.SkyCoeffCount();
  const std::vector<Vec3d> sky(skyHigh.begin(), skyHigh.begin() + ns);
  // Relight with the first ns columns only: the Ls = order bake's T.
  const absl::StatusOr<ProbeVolume> relit = Relight(transfer8, sky);
  EXPECT_TRUE(relit.ok()) << relit.status();
  Comparison c;
  for (int64_t p = 0; p < direct.grid.ProbeCount(); ++p) {
    if (!direct.active[p]) continue;
    for (int r = 0; r < direct.CoeffCount(); ++r) {
      for (int ch = 0; ch < 3; ++ch) {
        double sigmaRelit = transfer8.radianceStdError[r][3 * p + ch];
        double measured = 0, rowSq = 0;
        for (int s = 0; s < n8; ++s) {
          const double t = transfer8.skyTransfer[size_t(r * n8 + s)][3 * p + ch];
          rowSq += t * t;
          if (s < ns) {
            sigmaRelit += std::abs(sky[s][ch]) *
                          transfer8.skyTransferStdError[size_t(r * n8 + s)][3 * p + ch];
          } else {
            measured += t * skyHigh[s][ch];
          }
        }
        const double truncation = std::abs(measured) + std::sqrt(rowSq) * residualBeyond8;
        const double sigma = std::hypot(double(direct.radianceStdError[r][3 * p + ch]), sigmaRelit);
        const double diff = relit->radiance[r][3 * p + ch] - direct.radiance[r][3 * p + ch];
        c.worstExcess = std::max(c.worstExcess, std::abs(diff) - 4 * sigma - truncation);
        EXPECT_LE(std::abs(diff), 4 * sigma + truncation)
            << what << " order " << order << ": probe " << p << " coefficient " << r << " channel "
            << ch << " (sigma " << sigma << ", truncation " << truncation << ")";
        if (sigma > 0) c.meanZ2 += (diff / sigma) * (diff / sigma);
        c.maxTruncation = std::max(c.maxTruncation, truncation);
        c.maxSigma = std::max(c.maxSigma, sigma);
        ++c.count;
      }
    }
  }
  c.meanZ2 /= double(c.count);
  std::printf(
      "[measured] relit %s at Ls=%d vs direct: mean z^2 %.3f, max sigma %.3g, max "
      "truncation allowance %.3g\n",
      what.c_str(), order, c.meanZ2, c.maxSigma, c.maxTruncation);
  return c;
}

// Norm of the sky's projection beyond order 8: sqrt(int |sky|^2 - sum_{s <= 80} sky_s^2) per
// channel (the largest), by the map's cells.
double ResidualBeyond8(const Environment& env, const std::vector<Vec3d>& sky8) {
  double worst = 0;
  for (int ch = 0; ch < 3; ++ch) {
    double total = 0;
    if (env.kind == Environment::Kind::kUniform) {
      total = 4 * kPi * env.radiance[ch] * env.radiance[ch];
    } else {
      const EnvironmentMap& m = *env.map;
      // Cells of Imf::LatLongMap rows: z bands between the rows' mid-latitudes.
      for (int iy = 0; iy < m.height; ++iy) {
        const double y0 = std::max(0.0, iy - 0.5), y1 = std::min(double(m.height - 1), iy + 0.5);
        const double z0 = std::sin(kPi * (0.5 - y1 / (m.height - 1)));
        const double z1 = std::sin(kPi * (0.5 - y0 / (m.height - 1)));
        for (int ix = 0; ix < m.width; ++ix) {
          const double x0 = std::max(0.0, ix - 0.5), x1 = std::min(double(m.width - 1), ix + 0.5);
          const double dlon = 2 * kPi * (x1 - x0) / (m.width - 1);
          const double v = m.rgb[3 * (size_t(iy) * m.width + ix) + ch] * m.scale;
          total += v * v * (z1 - z0) * dlon;
        }
      }
    }
    double kept = 0;
    for (const Vec3d& c : sky8) kept += c[ch] * c[ch];
    worst = std::max(worst, std::sqrt(std::max(0.0, total - kept)));
  }
  return worst;
}

class RelightDemo : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { transfer8_ = new ProbeVolume(BakeOrDie(DemoJob(kSamples, 8), 2)); }
  static void TearDownTestSuite() { delete transfer8_; }
  static constexpr int64_t kSamples = 2048;
  static ProbeVolume* transfer8_;

  void CheckSky(const Environment& env, const std::string& what, double maxMeanZ2) {
    BakeJob job = DemoJob(kSamples, 0);
    job.scene.environment = env;
    job.settings.seed = 99;  // independent of the transfer bake
    const ProbeVolume direct = BakeOrDie(job, 2);
    const std::vector<Vec3d> sky8 = ProjectEnvironmentSh(env, 8);
    const double beyond = ResidualBeyond8(env, sky8);
    for (const int order : {2, 4, 8}) {
      const Comparison c = Compare(direct, *transfer8_, sky8, order, beyond, what);
      EXPECT_LE(c.meanZ2, maxMeanZ2) << what << " order " << order;
    }
  }
};
ProbeVolume* RelightDemo::transfer8_ = nullptr;

TEST_F(RelightDemo, TheDemosSkyRotatedMatchesADirectBake) {
  BakeJob demo = DemoJob(16, 0);
  ASSERT_EQ(demo.scene.environment.kind, Environment::Kind::kMap);
  // Rotated by 40 degrees: the map's own rotation for the direct bake, and for the relight the
  // projection of the unrotated map rotated in SH (RotateSkyAboutUp), checked equal here.
  Environment rotated = demo.scene.environment;
  auto map = std::make_shared<EnvironmentMap>(*rotated.map);
  map->worldFromMap = Mat3d::Rotation({0, 0, 1}, 40 * kPi / 180) * map->worldFromMap;
  rotated.map = map;
  const std::vector<Vec3d> turned =
      *RotateSkyAboutUp(ProjectEnvironmentSh(demo.scene.environment, 8), 8, 40);
  const std::vector<Vec3d> direct = ProjectEnvironmentSh(rotated, 8);
  double worst = 0, scale = Length(direct[0]);
  for (size_t i = 0; i < direct.size(); ++i) worst = std::max(worst, Length(turned[i] - direct[i]));
  std::printf(
      "[measured] rotate-then-project vs project-then-rotate: max |diff| %.3g of L00 %.3g\n", worst,
      scale);
  // The map's rotation turns its cells and their quadrature nodes with it: the two agree to the
  // rounding of the SH rotation (about 1e-15 of L00 per band), here bounded by 1e-12.
  EXPECT_LT(worst, 1e-12 * scale);
  CheckSky(rotated, "demo sky rotated 40 deg", 1 + 4 * std::sqrt(2.0 / 24));
}

TEST_F(RelightDemo, ASunsetWithASharpSunMatchesWithinItsTruncation) {
  CheckSky(SunsetSky(), "sunset with a 2-degree sun", 1 + 4 * std::sqrt(2.0 / 24));
}

TEST_F(RelightDemo, AUniformGreySkyMatchesWithinNoise) {
  CheckSky({Environment::Kind::kUniform, {0.5, 0.5, 0.5}, nullptr}, "uniform grey",
           1 + 4 * std::sqrt(2.0 / 24));
}

TEST_F(RelightDemo, ABandLimitedSkyMatchesWithinNoise) {
  // Order 2 <= Ls: no truncation beyond the map's pixelation (1024 x 512 cells).
  std::vector<Vec3d> sh;
  CheckSky(BandLimitedSky(&sh), "band-limited (order 2)", 1 + 4 * std::sqrt(2.0 / 24));
}

TEST_F(RelightDemo, HalfPrecisionCostsFarLessThanTheNoise) {
  // The stored T is rounded to half (2^-11 relative): the relit coefficient moves by at most
  // sum_s |T_rs sky_s| 2^-11, against its noise, at least se(T_r0) |sky_0|. Measured for the
  // sunset (its sun makes the highest columns matter most).
  const ProbeVolume& v = *transfer8_;
  const std::vector<Vec3d> sky = ProjectEnvironmentSh(SunsetSky(), 8);
  const int n8 = v.SkyCoeffCount();
  double worstRatio = 0;
  for (int64_t p = 0; p < v.grid.ProbeCount(); ++p) {
    if (!v.active[p]) continue;
    for (int r = 0; r < v.CoeffCount(); ++r) {
      for (int ch = 0; ch < 3; ++ch) {
        double rounding = 0, noise = 0;
        for (int s = 0; s < n8; ++s) {
          const size_t e = size_t(r * n8 + s);
          rounding += std::abs(v.skyTransfer[e][3 * p + ch] * sky[s][ch]) * 0x1p-11;
          noise = std::max(noise, v.skyTransferStdError[e][3 * p + ch] * std::abs(sky[s][ch]));
        }
        if (noise > 0) worstRatio = std::max(worstRatio, rounding / noise);
      }
    }
  }
  std::printf(
      "[measured] half storage: worst rounding bound / noise of a relit coefficient "
      "%.3g (%lld samples)\n",
      worstRatio, (long long)kSamples);
  EXPECT_LT(worstRatio, 0.25);
}

TEST_F(RelightDemo, RelightingIsDeterministicAndDropsTheTransfer) {
  const std::vector<Vec3d> sky = ProjectEnvironmentSh(SunsetSky(), 2);
  const absl::StatusOr<ProbeVolume> a = Relight(*transfer8_, sky);
  const absl::StatusOr<ProbeVolume> b = Relight(*transfer8_, sky);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->radiance, b->radiance);
  EXPECT_EQ(a->irradiance, b->irradiance);
  EXPECT_EQ(a->skyTransferOrder, 0);
  EXPECT_TRUE(a->skyTransfer.empty());
  // Irradiance regenerated from the relit radiance.
  std::vector<Vec3d> radiance(9), irradiance(9);
  for (int r = 0; r < 9; ++r)
    radiance[r] = {a->radiance[r][0], a->radiance[r][1], a->radiance[r][2]};
  RadianceToIrradianceRgb(2, radiance, irradiance);
  EXPECT_NEAR(a->irradiance[0][0], irradiance[0].x, 1e-5 * std::abs(irradiance[0].x));
  // Bad input is refused, naming what is wrong.
  EXPECT_FALSE(Relight(*transfer8_, std::vector<Vec3d>(5)).ok());
  ProbeVolume none = *transfer8_;
  none.skyTransferOrder = 0;
  none.skyTransfer.clear();
  EXPECT_NE(std::string(Relight(none, sky).status().message()).find("no sky transfer"),
            std::string::npos);
}

std::string TempPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() /
          ("probebake_relight_" + std::to_string(getpid()) + "_" + name))
      .string();
}

TEST(SkyTransferFile, RoundTripsAndMergesBitForBit) {
  BakeJob job = DemoJob(256, 2);
  const ProbeVolume whole = BakeOrDie(job, 2);
  const std::string path = TempPath("whole.vdb");
  ASSERT_TRUE(WriteProbeVolume(path, whole, VolumeMetadataFor(job)).ok());
  absl::StatusOr<ProbeVolumeFile> read = ReadProbeVolume(path);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->format, kProbeVolumeFormat4);
  EXPECT_EQ(read->volume.skyTransferOrder, 2);
  EXPECT_EQ(read->rawMetadata["sky_transfer_precision"], "half");
  // The bake rounds T to half, so the half file holds it exactly.
  EXPECT_EQ(read->volume.skyTransfer, whole.skyTransfer);
  EXPECT_EQ(read->volume.radiance, whole.radiance);
  const auto bytes = std::filesystem::file_size(path);
  int64_t probes = 0;
  for (uint8_t a : whole.active) probes += a;
  // Sharded: the two halves along x bake and merge to the whole file's bits.
  std::vector<VolumePart> parts;
  for (int half = 0; half < 2; ++half) {
    BakeJob part = job;
    part.grid.counts[0] = 2;
    part.grid.origin.x += 2 * half * job.grid.spacing.x;
    const std::string partPath = TempPath("part" + std::to_string(half) + ".vdb");
    ASSERT_TRUE(WriteProbeVolume(partPath, BakeOrDie(part, 1), VolumeMetadataFor(part)).ok());
    absl::StatusOr<ProbeVolumeFile> f = ReadProbeVolume(partPath);
    ASSERT_TRUE(f.ok()) << f.status();
    parts.push_back({partPath, *std::move(f)});
    std::filesystem::remove(partPath);
  }
  absl::StatusOr<ProbeVolumeFile> merged = MergeProbeVolumes(std::move(parts));
  ASSERT_TRUE(merged.ok()) << merged.status();
  EXPECT_EQ(merged->volume.skyTransfer, read->volume.skyTransfer);
  EXPECT_EQ(merged->volume.radiance, read->volume.radiance);
  // Without T the file is format 3 as before.
  const std::string plainPath = TempPath("plain.vdb");
  BakeJob plain = DemoJob(64, 0);
  ASSERT_TRUE(WriteProbeVolume(plainPath, BakeOrDie(plain, 2), VolumeMetadataFor(plain)).ok());
  EXPECT_EQ(ReadProbeVolume(plainPath)->format, kProbeVolumeFormat);
  const auto plainBytes = std::filesystem::file_size(plainPath);
  std::printf(
      "[measured] file bytes per probe (L=2, Ls=2, %lld probes): %.0f with T, %.0f "
      "without\n",
      (long long)probes, double(bytes) / double(probes), double(plainBytes) / double(probes));
  std::filesystem::remove(path);
  std::filesystem::remove(plainPath);
}

}  // namespace
}  // namespace probebake
