// Irradiance grids (docs/spherical-harmonics.md): the stored irradiance is the stored radiance
// convolved with the clamped cosine (Â_l per band) and then windowed as requested; radiance is
// never windowed.
#include <gtest/gtest.h>

#include <cmath>

#include "bake_test_util.h"
#include "probebake/sh/sh_convolution.h"
#include "probebake/sh/sh_window.h"
#include "probebake/sh/sphere_quadrature.h"

namespace probebake {
namespace {

using namespace probebake::testing;

// Probes around a small bright sphere light: its L2 irradiance rings negative on the far side.
BakeJob RingingScene(ShWindow window) {
  BakeJob job = MakeJob(2, 1024, {-1, 0, 0});
  job.grid.counts[0] = 3;
  job.settings.irradiance = true;
  job.settings.window = window;
  job.settings.windowWidth = 2.5;
  job.scene.environment = {Environment::Kind::kUniform, {0.01, 0.01, 0.01}, nullptr};
  job.scene.lights.push_back(SphereLight{{0, 0, 2}, 0.05, {500, 400, 300}});
  job.scene.lights.push_back(PointLight{{3, 0, 0}, {0.02, 0.02, 0.02}});
  return job;
}

double BandFactor(ShWindow window, int l, double width, int order) {
  switch (window) {
    case ShWindow::kHanning:
      return HanningWindowFactor(l, width);
    case ShWindow::kLanczos:
      return LanczosWindowFactor(l, order);
    default:
      return 1;
  }
}

TEST(Irradiance, IsTheConvolvedRadianceTimesTheWindow) {
  for (ShWindow window : {ShWindow::kNone, ShWindow::kHanning, ShWindow::kLanczos}) {
    const BakeJob job = RingingScene(window);
    const ProbeVolume v = BakeOrDie(job);
    ASSERT_EQ(v.irradiance.size(), v.radiance.size());
    for (int64_t p = 0; p < 3; ++p)
      for (int l = 0; l <= 2; ++l)
        for (int m = -l; m <= l; ++m)
          for (int ch = 0; ch < 3; ++ch) {
            const int c = ShIndex(l, m);
            const double expected =
                IrradianceBandFactor(l) * BandFactor(window, l, 2.5, 2) * v.radiance[c][3 * p + ch];
            // Both are float roundings of double values computed from the same double radiance:
            // a few float ulps apart.
            EXPECT_NEAR(v.irradiance[c][3 * p + ch], expected, 4e-7 * (std::abs(expected) + 1e-3))
                << "window " << int(window) << " probe " << p << " coefficient " << c;
          }
  }
  EXPECT_EQ(BakeOrDie(RingingScene(ShWindow::kNone)).window, "NONE");
  EXPECT_EQ(BakeOrDie(RingingScene(ShWindow::kHanning)).window, "HANNING(width=2.5)");
}

double MinIrradiance(const ProbeVolume& v, int64_t p, int ch) {
  // Dense deterministic directions (a product rule's nodes serve as a fine sphere grid).
  double lowest = 1e300;
  std::vector<double> y(9);
  for (const auto& node : SphereProductQuadrature(64, 128)) {
    EvalShBasis(2, node.direction, y.data());
    double e = 0;
    for (int c = 0; c < 9; ++c) e += y[c] * v.irradiance[c][3 * p + ch];
    lowest = std::min(lowest, e);
  }
  return lowest;
}

TEST(Irradiance, AutoWindowMakesRingingIrradianceNonNegativeAndLeavesTheRest) {
  const ProbeVolume none = BakeOrDie(RingingScene(ShWindow::kNone));
  const ProbeVolume autoV = BakeOrDie(RingingScene(ShWindow::kAuto));
  int windowed = 0;
  for (int64_t p = 0; p < 3; ++p) {
    bool ringing = false;
    for (int ch = 0; ch < 3; ++ch) ringing = ringing || MinIrradiance(none, p, ch) < 0;
    if (ringing) {
      ++windowed;
      EXPECT_GT(autoV.autoWindowT[p], 0.0f) << p;
      // Non-negative up to the float storage of the coefficients (relative to L00's term).
      for (int ch = 0; ch < 3; ++ch)
        EXPECT_GE(MinIrradiance(autoV, p, ch), -1e-6 * autoV.irradiance[0][3 * p + ch]) << p;
    } else {
      EXPECT_EQ(autoV.autoWindowT[p], 0.0f) << p;
      for (int c = 0; c < 9; ++c)
        for (int ch = 0; ch < 3; ++ch)
          EXPECT_EQ(autoV.irradiance[c][3 * p + ch], none.irradiance[c][3 * p + ch]);
    }
    // Radiance is never windowed.
    for (int c = 0; c < 9; ++c) EXPECT_EQ(autoV.radiance[c][3 * p], none.radiance[c][3 * p]);
  }
  EXPECT_GT(windowed, 0) << "the scene was meant to ring";
  EXPECT_NE(autoV.window.find("AUTO(heat"), std::string::npos) << autoV.window;
  EXPECT_NE(autoV.window.find(std::to_string(windowed) + " of 3 probes windowed"),
            std::string::npos)
      << autoV.window;
}

}  // namespace
}  // namespace probebake
