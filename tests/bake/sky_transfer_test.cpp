// Sky transfer bakes (settings.skyTransfer, core/src/bake/probe_integrator.h) against closed forms:
// T[r][s] is the radiance coefficient r that a sky of radiance Y_s adds at the probe.
//   - in vacuum T is the identity (T00 exactly, the rest within the bake's standard errors);
//   - over an infinite black ground T is the hemisphere mask's product integrals
//     H[r][s] = int_{z > 0} Y_r Y_s dw, computed here by a quadrature exact for them;
//   - over a ground of albedo rho the ground adds rho E_s / pi over the lower hemisphere, E_s the
//     irradiance Y_s gives a horizontal surface: interreflection coloured by albedo;
//   - inside a sphere of albedo rho with a cap cut out (a "furnace" open to the sky) the wall's
//     radiance is the geometric series rho f sum_k (rho (1 - f))^k per bounce k < maxDepth, f the
//     opening's share of the sphere.
// Tolerances: kSigmas reported standard errors (bake_test_util.h) plus the half-precision
// rounding of stored T (2^-11 relative, and 2^-25 absolute for subnormals).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "bake_test_util.h"
#include "probebake/job/job_json.h"
#include "probebake/job/limits.h"
#include "probebake/job/validate.h"
#include "probebake/sh/sh_convolution.h"

namespace probebake {
namespace {

using namespace probebake::testing;

// T[r][s] channel ch of probe p.
double T(const ProbeVolume& v, int64_t p, int r, int s, int ch) {
  return v.skyTransfer[size_t(r * v.SkyCoeffCount() + s)][3 * p + ch];
}
double TStdError(const ProbeVolume& v, int64_t p, int r, int s, int ch) {
  return v.skyTransferStdError[size_t(r * v.SkyCoeffCount() + s)][3 * p + ch];
}

// Half-precision storage: half an ulp of 11 significant bits, or of the subnormal spacing 2^-24.
double HalfRounding(double x) {
  return std::max(0x1p-11 * std::abs(x), 0x1p-25);
}

// int over the directions with z in [z0, z1] of f(w) dw, by Gauss-Legendre in z (n nodes) and the
// trapezoid rule in azimuth (m nodes): exact for products of SH up to order (m - 1) / 2 in
// azimuth and polynomials of degree 2n - 1 in z (products of two SH of equal |m| are such).
template <typename F>
double IntegrateBand(double z0, double z1, F&& f, int n = 24, int m = 64) {
  const QuadratureRule1D rule = GaussLegendreRule(n);
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    const double z = z0 + 0.5 * (rule.nodes[i] + 1) * (z1 - z0);
    const double wz = 0.5 * rule.weights[i] * (z1 - z0);
    const double r = std::sqrt(std::max(0.0, 1 - z * z));
    for (int k = 0; k < m; ++k) {
      const double phi = 2 * kPi * (k + 0.5) / m;
      sum += wz * (2 * kPi / m) * f(Vec3d{r * std::cos(phi), r * std::sin(phi), z});
    }
  }
  return sum;
}

// H[r][s] = int over z in [z0, z1] of Y_r Y_s.
std::vector<double> MaskProducts(int order, int skyOrder, double z0, double z1) {
  const int n = ShCoeffCount(order), ns = ShCoeffCount(skyOrder);
  std::vector<double> h(size_t(n * ns));
  for (int r = 0; r < n; ++r) {
    for (int s = 0; s < ns; ++s) {
      h[size_t(r * ns + s)] = IntegrateBand(z0, z1, [&](const Vec3d& w) {
        double y[kMaxShCoeffCount];
        EvalShBasis(std::max(order, skyOrder), w, y);
        return y[r] * y[s];
      });
    }
  }
  return h;
}

// Expects T of probe p to be expected[r ns + s] (times scale[ch]) within kSigmas standard errors
// plus the half rounding and extraAbs; prints the worst deviation in standard errors.
void ExpectTransfer(const ProbeVolume& v, int64_t p, const std::vector<double>& expected,
                    const Vec3d& scale, const std::string& what, double extraAbs = 0) {
  const int n = v.CoeffCount(), ns = v.SkyCoeffCount();
  ASSERT_EQ(expected.size(), size_t(n * ns)) << what;
  ASSERT_EQ(v.skyTransferStdError.size(), size_t(n * ns)) << what;
  double worst = 0, worstError = 0;
  for (int r = 0; r < n; ++r) {
    for (int s = 0; s < ns; ++s) {
      for (int ch = 0; ch < 3; ++ch) {
        const double exact = expected[size_t(r * ns + s)] * scale[ch];
        const double got = T(v, p, r, s, ch);
        const double se = TStdError(v, p, r, s, ch);
        const double allowance = HalfRounding(exact) + extraAbs;
        const double error = std::abs(got - exact);
        worstError = std::max(worstError, error);
        if (se > 0) worst = std::max(worst, std::max(0.0, error - allowance) / se);
        EXPECT_NEAR(got, exact, kSigmas * se + allowance)
            << what << ": T[" << r << "][" << s << "] channel " << ch << " (std error " << se
            << ")";
      }
    }
  }
  std::printf(
      "[measured] %s: %d x %d x 3 entries, max |error| %.3g, max (|error| - allowance) / "
      "std error %.2f\n",
      what.c_str(), n, ns, worstError, worst);
}

BakeJob TransferJob(int order, int skyOrder, int64_t samples, Vec3d p = {}) {
  BakeJob job = MakeJob(order, samples, p);
  job.settings.skyTransferOrder = skyOrder;
  return job;
}

TEST(SkyTransferSettings, OrderIsValidatedNamingTheField) {
  const auto error = [](const std::string& settings) {
    const std::string json = R"({"scene": {}, "grid": {"min": [0,0,0], "max": [0,0,0],
      "counts": [1,1,1]}, "settings": )" +
                             settings + "}";
    absl::StatusOr<v1::JobSpec> spec = ParseJobJson(json);
    EXPECT_TRUE(spec.ok()) << spec.status();
    return std::string(ValidateJobSpec(*spec, JobLimits{}).message());
  };
  EXPECT_EQ(error(R"({"skyTransfer": {"order": 2}})"), "");
  EXPECT_EQ(error(R"({"skyTransfer": {"order": 0}})"), "");
  EXPECT_NE(error(R"({"skyTransfer": {"order": 9}})").find("settings.skyTransfer.order"),
            std::string::npos);
  EXPECT_NE(error(R"({"skyTransfer": {"order": -1}})").find("settings.skyTransfer.order"),
            std::string::npos);
  // Adaptive sampling, given or from a preset, measures the local lights alone: refused.
  EXPECT_NE(error(R"({"skyTransfer": {"order": 2}, "targetRelError": 0.05})")
                .find("settings.skyTransfer.order"),
            std::string::npos);
  EXPECT_NE(error(R"({"skyTransfer": {"order": 2}, "quality": "PREVIEW"})").find("preset"),
            std::string::npos);
  EXPECT_EQ(error(R"({"skyTransfer": {"order": 2}, "quality": "PREVIEW", "targetRelError": 0})"),
            "");
}

TEST(SkyTransfer, VacuumIsTheIdentity) {
  // T[r][s] = int Y_r Y_s = delta_rs. T00 is exact whatever the directions: each sample adds
  // Y0^2 / (1 / 4 pi) = 1, so the mean is 1 to rounding, stored exactly in half. Every other entry
  // is a quadrature of Y_r Y_s over the probe's point sets, within its standard errors.
  for (const auto& [order, skyOrder] : {std::pair{2, 2}, std::pair{3, 1}, std::pair{1, 3}}) {
    const ProbeVolume v = BakeOrDie(TransferJob(order, skyOrder, 4096));
    ASSERT_EQ(v.skyTransferOrder, skyOrder);
    for (int ch = 0; ch < 3; ++ch) EXPECT_EQ(T(v, 0, 0, 0, ch), 1.0f);
    std::vector<double> identity(size_t(v.CoeffCount() * v.SkyCoeffCount()), 0.0);
    for (int r = 0; r < std::min(v.CoeffCount(), v.SkyCoeffCount()); ++r)
      identity[size_t(r * v.SkyCoeffCount() + r)] = 1;
    ExpectTransfer(v, 0, identity, {1, 1, 1},
                   "vacuum L=" + std::to_string(order) + " Ls=" + std::to_string(skyOrder));
    // Nothing local: the radiance grids are black.
    for (const auto& plane : v.radiance) EXPECT_EQ(plane[0], 0.0f);
  }
}

// A square of half-size 1e6 at z = 0 under a probe at height 1: the directions it fails to cover
// lie within 1e-6 rad of the horizon, solid angle < 2 pi 1e-6, so an entry errs by at most
// 2 pi 1e-6 max|Y_r Y_s| (< 1e-4 for order 4).
constexpr double kGroundHalfSize = 1e6;
constexpr double kGroundMissed = 2 * kPi * 1e-6 * 2;

void AddGround(Scene* scene, uint32_t material) {
  const double s = kGroundHalfSize;
  AddQuad(scene, {-s, -s, 0}, {s, -s, 0}, {s, s, 0}, {-s, s, 0}, material);
}

TEST(SkyTransfer, BlackGroundIsTheHemisphereMask) {
  BakeJob job = TransferJob(3, 3, 8192, {0, 0, 1});
  AddGround(&job.scene, AddMaterial(&job.scene, {0, 0, 0}));
  const ProbeVolume v = BakeOrDie(job);
  ExpectTransfer(v, 0, MaskProducts(3, 3, 0, 1), {1, 1, 1}, "black ground", kGroundMissed);
}

TEST(SkyTransfer, ColouredGroundReflectsTheSkyByItsAlbedo) {
  // Under the sky Y_s the ground (unoccluded, infinite) receives E_s = int_{z>0} Y_s z dw and
  // sends rho E_s / pi up, uniform: the probe sees it over the lower hemisphere, adding
  // rho E_s / pi int_{z<0} Y_r to H[r][s].
  const Vec3d rho{0.8, 0.5, 0.2};
  BakeJob job = TransferJob(2, 2, 8192, {0, 0, 1});
  AddGround(&job.scene, AddMaterial(&job.scene, rho));
  const ProbeVolume v = BakeOrDie(job);
  const int n = v.CoeffCount(), ns = v.SkyCoeffCount();
  const std::vector<double> upper = MaskProducts(2, 2, 0, 1);
  for (int ch = 0; ch < 3; ++ch) {
    std::vector<double> expected(upper);
    for (int r = 0; r < n; ++r) {
      const double below = IntegrateBand(-1, 0, [&](const Vec3d& w) {
        double y[kMaxShCoeffCount];
        EvalShBasis(2, w, y);
        return y[r];
      });
      for (int s = 0; s < ns; ++s) {
        const double e = IntegrateBand(0, 1, [&](const Vec3d& w) {
          double y[kMaxShCoeffCount];
          EvalShBasis(2, w, y);
          return y[s] * w.z;
        });
        expected[size_t(r * ns + s)] += rho[ch] * e / kPi * below;
      }
    }
    const int64_t p = 0;
    double worst = 0;
    for (int r = 0; r < n; ++r) {
      for (int s = 0; s < ns; ++s) {
        const double exact = expected[size_t(r * ns + s)];
        const double se = TStdError(v, p, r, s, ch);
        const double tol = kSigmas * se + HalfRounding(exact) + kGroundMissed;
        EXPECT_NEAR(T(v, p, r, s, ch), exact, tol) << "T[" << r << "][" << s << "] ch " << ch;
        if (se > 0) worst = std::max(worst, std::abs(T(v, p, r, s, ch) - exact) / se);
      }
    }
    std::printf(
        "[measured] coloured ground, channel %d (albedo %.1f): max |error| / std error "
        "%.2f\n",
        ch, rho[ch], worst);
  }
}

// Inside a sphere of radius 1 about the origin with the cap z > cosAlpha cut out, open to the sky.
// Every point of a sphere sees any region of it with the form factor of its area share, so under
// a uniform sky of radiance 1 the wall's radiance is uniform: B = rho (f + (1 - f) B), the series
// rho f sum_k (rho (1 - f))^k over k bounces, f = (1 - cosAlpha) / 2 the opening's share.
// The sphere is a mesh of rings x segments quads; its departure from the sphere is an error of
// the order of its relative area deficit, which the test adds to its tolerance.
struct OpenSphere {
  double cosAlpha = 0.5;
  int rings = 96, segments = 192;

  double OpeningShare() const { return (1 - cosAlpha) / 2; }
  void Add(Scene* scene, uint32_t material, double* areaDeficit) const {
    TriangleMesh m;
    m.name = "open sphere";
    const double theta0 = std::acos(cosAlpha);
    for (int i = 0; i <= rings; ++i) {
      const double theta = theta0 + (kPi - theta0) * i / rings;
      for (int j = 0; j < segments; ++j) {
        const double phi = 2 * kPi * j / segments;
        m.positions.push_back(
            {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)});
      }
    }
    double area = 0;
    for (int i = 0; i < rings; ++i) {
      for (int j = 0; j < segments; ++j) {
        const uint32_t a = uint32_t(i * segments + j),
                       b = uint32_t(i * segments + (j + 1) % segments);
        const uint32_t c = b + uint32_t(segments), d = a + uint32_t(segments);
        // Front faces toward the centre.
        m.indices.insert(m.indices.end(), {a, b, c, a, c, d});
        area +=
            0.5 * Length(Cross(m.positions[b] - m.positions[a], m.positions[c] - m.positions[a]));
        area +=
            0.5 * Length(Cross(m.positions[c] - m.positions[a], m.positions[d] - m.positions[a]));
      }
    }
    *areaDeficit = 1 - area / (2 * kPi * (1 + cosAlpha));
    m.material = material;
    scene->meshes.push_back(std::move(m));
  }
  // The wall's radiance under a sky of radiance 1 with at most `depth` bounces.
  double WallRadiance(double rho, int depth) const {
    const double f = OpeningShare();
    double sum = 0, term = rho * f;
    for (int k = 0; k < depth; ++k, term *= rho * (1 - f)) sum += term;
    return sum;
  }
};

TEST(SkyTransfer, OpenFurnaceSumsTheBouncesGeometrically) {
  const Vec3d rho{0.9, 0.6, 0.3};
  const OpenSphere sphere;
  for (const int depth : {1, 2, 4, 16}) {
    BakeJob job = TransferJob(2, 1, 16384);
    job.settings.maxDepth = depth;
    double deficit = 0;
    sphere.Add(&job.scene, AddMaterial(&job.scene, rho), &deficit);
    const ProbeVolume v = BakeOrDie(job);
    // Column 0 (a uniform sky of radiance Y0): Y0 (opening cap + B (whole sphere - cap)).
    const std::vector<double> cap = CapProjection(2, {0, 0, 1}, sphere.cosAlpha);
    const double y0 = 0.5 / std::sqrt(kPi);
    for (int ch = 0; ch < 3; ++ch) {
      const double b = sphere.WallRadiance(rho[ch], depth);
      for (int r = 0; r < v.CoeffCount(); ++r) {
        const double whole = r == 0 ? 2 * std::sqrt(kPi) : 0.0;
        const double exact = y0 * (cap[r] + b * (whole - cap[r]));
        const double se = TStdError(v, 0, r, 0, ch);
        // The mesh's wall: its share of what the wall sends errs by about its area deficit.
        const double geometry = 2 * deficit * y0 * b * 2 * std::sqrt(kPi);
        EXPECT_NEAR(T(v, 0, r, 0, ch), exact, kSigmas * se + HalfRounding(exact) + geometry)
            << "maxDepth " << depth << " T[" << r << "][0] channel " << ch;
        if (r == 0)
          std::printf(
              "[measured] open furnace rho %.1f maxDepth %d: T00 %.6f exact %.6f "
              "(std error %.2g, mesh allowance %.2g)\n",
              rho[ch], depth, T(v, 0, 0, 0, ch), exact, se, geometry);
      }
    }
  }
}

TEST(SkyTransfer, RadianceHoldsTheLocalLightsOnly) {
  // With transfer on, the environment is left out of the radiance: the radiance planes are those
  // of the same bake without an environment, bit for bit (same lights, same random numbers).
  BakeJob job = TransferJob(2, 2, 1024, {0, 0, 1});
  job.grid.counts[0] = 2;
  AddGround(&job.scene, AddMaterial(&job.scene, {0.5, 0.5, 0.5}));
  job.scene.lights.push_back(PointLight{{0.3, 0.2, 2}, {5, 4, 3}});
  job.scene.lights.push_back(RectLight{{-1, -1, 3}, {1, 0, 0}, {0, 1, 0}, {2, 2, 2}, true});
  BakeJob dark = job;
  dark.settings.skyTransferOrder = 0;
  job.scene.environment = {Environment::Kind::kUniform, {0.3, 0.4, 0.5}, nullptr};
  const ProbeVolume withSky = BakeOrDie(job);
  const ProbeVolume withoutSky = BakeOrDie(dark);
  ASSERT_EQ(withSky.radiance.size(), withoutSky.radiance.size());
  for (size_t c = 0; c < withSky.radiance.size(); ++c)
    EXPECT_EQ(withSky.radiance[c], withoutSky.radiance[c]) << "coefficient " << c;
  EXPECT_EQ(withSky.stdError, withoutSky.stdError);
  EXPECT_TRUE(withoutSky.skyTransfer.empty());
}

TEST(SkyTransfer, SameBitsWhateverThreadsAndSharding) {
  BakeJob job = TransferJob(2, 2, 512, {0, 0, 0.5});
  job.grid.counts[0] = 3;
  job.grid.counts[1] = 2;
  AddGround(&job.scene, AddMaterial(&job.scene, {0.7, 0.5, 0.3}));
  AddBox(&job.scene, {1, -1, 0}, {1.5, 2, 2}, AddMaterial(&job.scene, {0.4, 0.6, 0.8}), false);
  const ProbeVolume one = BakeOrDie(job, 1);
  const ProbeVolume two = BakeOrDie(job, 2);
  EXPECT_EQ(one.skyTransfer, two.skyTransfer);
  // A sub-grid (the last two columns) bakes its probes as the whole grid does.
  BakeJob part = job;
  part.grid.origin.x += job.grid.spacing.x;
  part.grid.counts[0] = 2;
  const ProbeVolume sub = BakeOrDie(part, 2);
  for (size_t e = 0; e < one.skyTransfer.size(); ++e) {
    for (int j = 0; j < 2; ++j) {
      for (int i = 0; i < 2; ++i) {
        const int64_t whole = one.grid.LinearIndex(i + 1, j, 0),
                      mine = sub.grid.LinearIndex(i, j, 0);
        for (int ch = 0; ch < 3; ++ch)
          ASSERT_EQ(one.skyTransfer[e][3 * whole + ch], sub.skyTransfer[e][3 * mine + ch])
              << "entry " << e;
      }
    }
  }
}

}  // namespace
}  // namespace probebake
