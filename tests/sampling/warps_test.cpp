#include "probebake/sampling/warps.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "probebake/sampling/sampler.h"
#include "sampling/stats.h"

namespace probebake {
namespace {

using testing::ChiSquareTest;
using testing::GaussLegendre;

constexpr double kPi = std::numbers::pi;
constexpr double kEps = std::numeric_limits<double>::epsilon();  // 2^-52
constexpr double kAlpha = 1e-6;  // significance of every chi-square test in this file
constexpr int kSamples = 1 << 20;

// u values for round trips: the corners and edges of the square plus independent random points.
std::vector<Vec2d> TestPoints(uint64_t stream, int count) {
  const double top = 1 - 0x1p-32;  // largest sampler value
  std::vector<Vec2d> u = {{0, 0},       {0, 0.5}, {0.5, 0}, {top, top},  {0.5, 0.5},
                          {0.25, 0.75}, {top, 0}, {0, top}, {1e-9, 0.3}, {0.7, 1e-9}};
  IndependentSampler s(12345, stream);
  for (int i = 0; i < count; ++i) {
    s.StartSample(i);
    u.push_back(s.Get2D());
  }
  return u;
}

// 1 - cos(theta) of a unit vector without cancellation near +z.
double OneMinusCos(const Vec3d& w) {
  return w.z > 0 ? (w.x * w.x + w.y * w.y) / (1 + w.z) : 1 - w.z;
}

double Azimuth(const Vec3d& w) {
  const double phi = std::atan2(w.y, w.x);
  return phi < 0 ? phi + 2 * kPi : phi;
}

// Unit vector with 1 - cos(theta) = t and azimuth phi.
Vec3d FromTPhi(double t, double phi) {
  const double s = std::sqrt(std::max(0.0, t * (2 - t)));
  return {s * std::cos(phi), s * std::sin(phi), 1 - t};
}

// Integral of pdf(w) dw over the cap t = 1 - cos(theta) in [0, tMax] (dw = dt dphi), by composite
// 8-point Gauss-Legendre on 64 x 16 panels. For the smooth pdfs here the truncation error is at
// the rounding level; the sum of 65536 terms is accurate to ~65536 eps = 1.5e-11, the tolerance.
double IntegrateOverCap(const std::function<double(const Vec3d&)>& pdf, double tMax) {
  double sum = 0;
  for (int i = 0; i < 64; ++i) {
    const auto qt = GaussLegendre(8, tMax * i / 64, tMax * (i + 1) / 64);
    for (int j = 0; j < 16; ++j) {
      const auto qp = GaussLegendre(8, 2 * kPi * j / 16, 2 * kPi * (j + 1) / 16);
      for (int a = 0; a < 8; ++a)
        for (int b = 0; b < 8; ++b) sum += qt.w[a] * qp.w[b] * pdf(FromTPhi(qt.x[a], qp.x[b]));
    }
  }
  return sum;
}
constexpr double kIntegralTolerance = 1.5e-11;

// Chi-square test of a direction warp on an (nT x nPhi) grid in (t = 1 - cos(theta), phi) over
// t in [0, tMax] (equal solid angle cells); expected counts from the pdf by 6 x 6 Gauss-Legendre
// per cell. Samples from the independent sampler (i.i.d., as the test assumes).
void ExpectDirectionsMatchPdf(const std::string& name, const std::function<Vec3d(Vec2d)>& sample,
                              const std::function<double(const Vec3d&)>& pdf, double tMax,
                              int nT = 40, int nPhi = 32) {
  std::vector<double> observed(nT * nPhi, 0), expected(nT * nPhi, 0);
  IndependentSampler s(7, Hash(name.size(), name[0], name.back()));
  int outside = 0;
  for (int i = 0; i < kSamples; ++i) {
    s.StartSample(i);
    const Vec3d w = sample(s.Get2D());
    const double t = OneMinusCos(w);
    const int it = static_cast<int>(t / tMax * nT);
    const int ip = std::min(static_cast<int>(Azimuth(w) / (2 * kPi) * nPhi), nPhi - 1);
    if (!(std::abs(Length(w) - 1) < 1e-14) || it < 0 || it >= nT) {
      ++outside;
      continue;
    }
    observed[it * nPhi + ip] += 1;
  }
  EXPECT_EQ(outside, 0) << name << ": samples outside the domain or not unit length";
  for (int it = 0; it < nT; ++it) {
    const auto qt = GaussLegendre(6, tMax * it / nT, tMax * (it + 1) / nT);
    for (int ip = 0; ip < nPhi; ++ip) {
      const auto qp = GaussLegendre(6, 2 * kPi * ip / nPhi, 2 * kPi * (ip + 1) / nPhi);
      double p = 0;
      for (int a = 0; a < 6; ++a)
        for (int b = 0; b < 6; ++b) p += qt.w[a] * qp.w[b] * pdf(FromTPhi(qt.x[a], qp.x[b]));
      expected[it * nPhi + ip] = p * kSamples;
    }
  }
  const auto r = ChiSquareTest(observed, expected, kAlpha);
  EXPECT_TRUE(r.pass) << name << ": " << r.ToString();
}

// |a - b| for fractions of a turn, allowing wrap-around at 0 == 1.
double AzimuthFractionDistance(double a, double b) {
  const double d = std::abs(a - b);
  return std::min(d, 1 - d);
}

// ---- Uniform sphere and hemisphere.

TEST(Warps, UniformSpherePdfIntegratesToOne) {
  EXPECT_NEAR(IntegrateOverCap([](const Vec3d&) { return UniformSpherePdf(); }, 2), 1,
              kIntegralTolerance);
}

TEST(Warps, UniformSphereMatchesPdf) {
  ExpectDirectionsMatchPdf(
      "sphere", SampleUniformSphere, [](const Vec3d&) { return UniformSpherePdf(); }, 2);
}

// Round-trip tolerances come from a first-order rounding analysis: z = 1 - 2u and u = (1 - z)/2
// each round once (<= eps/2 absolute); phi = 2 pi u, cos/sin (<= 1 ulp in glibc), the products
// with sin(theta) and atan2 change the recovered azimuth fraction by a few eps regardless of
// theta (relative errors of x and y cancel in y/x). 16 eps leaves a 4x margin. The azimuth is
// undefined where sin(theta) == 0 (u.x == 0), so it is not compared there.
constexpr double kRoundTripTolerance = 16 * kEps;

TEST(Warps, UniformSphereInverts) {
  for (const Vec2d& u : TestPoints(1, 100000)) {
    const Vec3d w = SampleUniformSphere(u);
    const Vec2d v = InvertUniformSphereSample(w);
    ASSERT_NEAR(v.x, u.x, kRoundTripTolerance) << u;
    if (w.x != 0 || w.y != 0) {
      ASSERT_LE(AzimuthFractionDistance(v.y, u.y), kRoundTripTolerance) << u;
    }
  }
}

TEST(Warps, UniformHemispherePdfIntegratesToOne) {
  EXPECT_NEAR(IntegrateOverCap([](const Vec3d&) { return UniformHemispherePdf(); }, 1), 1,
              kIntegralTolerance);
}

TEST(Warps, UniformHemisphereMatchesPdf) {
  ExpectDirectionsMatchPdf(
      "hemisphere", SampleUniformHemisphere, [](const Vec3d&) { return UniformHemispherePdf(); },
      1);
}

TEST(Warps, UniformHemisphereInverts) {
  for (const Vec2d& u : TestPoints(2, 100000)) {
    const Vec3d w = SampleUniformHemisphere(u);
    ASSERT_GE(w.z, 0);
    const Vec2d v = InvertUniformHemisphereSample(w);
    ASSERT_NEAR(v.x, u.x, kRoundTripTolerance) << u;
    if (w.x != 0 || w.y != 0) {
      ASSERT_LE(AzimuthFractionDistance(v.y, u.y), kRoundTripTolerance) << u;
    }
  }
}

// ---- Concentric disk and cosine hemisphere.

TEST(Warps, ConcentricDiskMatchesPdf) {
  // Grid in (r^2, phi): equal-area cells (dA = d(r^2)/2 dphi); expected = N pdf area by 4 x 4
  // Gauss-Legendre (exact for the constant pdf, so this also checks the pdf's value).
  constexpr int nR = 32, nPhi = 32;
  std::vector<double> observed(nR * nPhi, 0), expected(nR * nPhi, 0);
  IndependentSampler s(8, 8);
  for (int i = 0; i < kSamples; ++i) {
    s.StartSample(i);
    const Vec2d p = SampleUniformDiskConcentric(s.Get2D());
    const double r2 = p.x * p.x + p.y * p.y;
    ASSERT_LE(r2, 1 + 4 * kEps) << p;
    const int ir = std::min(static_cast<int>(r2 * nR), nR - 1);
    const int ip = std::min(static_cast<int>(Azimuth({p.x, p.y, 0}) / (2 * kPi) * nPhi), nPhi - 1);
    observed[ir * nPhi + ip] += 1;
  }
  double total = 0;
  for (int ir = 0; ir < nR; ++ir) {
    const auto qr = GaussLegendre(4, double(ir) / nR, double(ir + 1) / nR);
    for (int ip = 0; ip < nPhi; ++ip) {
      const auto qp = GaussLegendre(4, 2 * kPi * ip / nPhi, 2 * kPi * (ip + 1) / nPhi);
      double area = 0;
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) area += qr.w[a] * qp.w[b] * 0.5 * UniformDiskPdf();
      expected[ir * nPhi + ip] = area * kSamples;
      total += area;
    }
  }
  EXPECT_NEAR(total, 1, 1e-13);  // pdf integrates to 1; 1024 terms, rounding ~ 1024 eps
  const auto r = ChiSquareTest(observed, expected, kAlpha);
  EXPECT_TRUE(r.pass) << r.ToString();
}

TEST(Warps, ConcentricDiskInverts) {
  // Forward and inverse each take ~10 correctly rounded or 1-ulp operations on O(1) values; the
  // composition is well conditioned (the map is bi-Lipschitz), hence 16 eps.
  for (const Vec2d& u : TestPoints(3, 100000)) {
    const Vec2d v = InvertUniformDiskConcentricSample(SampleUniformDiskConcentric(u));
    ASSERT_NEAR(v.x, u.x, kRoundTripTolerance) << u;
    ASSERT_NEAR(v.y, u.y, kRoundTripTolerance) << u;
  }
}

TEST(Warps, CosineHemispherePdfIntegratesToOne) {
  EXPECT_NEAR(IntegrateOverCap([](const Vec3d& w) { return CosineHemispherePdf(w.z); }, 1), 1,
              kIntegralTolerance);
  EXPECT_EQ(CosineHemispherePdf(-0.5), 0);
}

TEST(Warps, CosineHemisphereMatchesPdf) {
  ExpectDirectionsMatchPdf(
      "cosine", SampleCosineHemisphere, [](const Vec3d& w) { return CosineHemispherePdf(w.z); }, 1);
}

TEST(Warps, CosineHemisphereInverts) {
  for (const Vec2d& u : TestPoints(4, 100000)) {
    const Vec3d w = SampleCosineHemisphere(u);
    ASSERT_NEAR(Length(w), 1, 4 * kEps) << u;
    const Vec2d v = InvertCosineHemisphereSample(w);
    ASSERT_NEAR(v.x, u.x, kRoundTripTolerance) << u;
    ASSERT_NEAR(v.y, u.y, kRoundTripTolerance) << u;
  }
}

// ---- Uniform cone, from a wide cap down to the sun's disk (angular radius 0.2665 deg).

class UniformConeTest : public ::testing::TestWithParam<double> {};

TEST_P(UniformConeTest, PdfIntegratesToOne) {
  const double thetaMax = GetParam();
  const double cosThetaMax = std::cos(thetaMax);
  const double tMax = 2 * std::sin(thetaMax / 2) * std::sin(thetaMax / 2);  // 1 - cos, stable
  EXPECT_NEAR(IntegrateOverCap([&](const Vec3d&) { return UniformConePdf(cosThetaMax); }, tMax), 1,
              kIntegralTolerance + 2.2e-16 / tMax)  // + 2 ulp of cos(thetaMax): libm and rounding
      << "thetaMax = " << thetaMax;
}

TEST_P(UniformConeTest, MatchesPdf) {
  const double thetaMax = GetParam();
  const double cosThetaMax = std::cos(thetaMax);
  // Bin edges use the cap as the sampler sees it (1 - cosThetaMax, exact by Sterbenz for
  // thetaMax <= 60 deg), so bins and samples agree on the boundary.
  const double tMax = 1 - cosThetaMax;
  ExpectDirectionsMatchPdf(
      "cone" + std::to_string(thetaMax), [&](Vec2d u) { return SampleUniformCone(u, cosThetaMax); },
      [&](const Vec3d&) { return UniformConePdf(cosThetaMax); }, tMax);
}

TEST_P(UniformConeTest, Inverts) {
  const double cosThetaMax = std::cos(GetParam());
  for (const Vec2d& u : TestPoints(5, 100000)) {
    const Vec3d w = SampleUniformCone(u, cosThetaMax);
    ASSERT_GE(w.z, cosThetaMax) << u;
    const Vec2d v = InvertUniformConeSample(w, cosThetaMax);
    // t = (x^2 + y^2)/(1 + z) recomputes 1 - cos(theta) to ~6 eps relative (products, sum,
    // division and the rounding of z), so u.x comes back to 6 eps u.x; 16 eps overall.
    ASSERT_NEAR(v.x, u.x, kRoundTripTolerance) << u;
    if (w.x != 0 || w.y != 0) {
      ASSERT_LE(AzimuthFractionDistance(v.y, u.y), kRoundTripTolerance) << u;
    }
  }
}

constexpr double kSunAngularRadius = 0.2665 * std::numbers::pi / 180;
INSTANTIATE_TEST_SUITE_P(Caps, UniformConeTest,
                         ::testing::Values(std::numbers::pi / 3, 0.2, 0.01, kSunAngularRadius,
                                           1e-5));

// The small-cap sampler keeps relative precision: for the sun, 1 - cos(theta) of every sample is
// u.x (1 - cosThetaMax) to a few eps relative (computing sin(theta) as sqrt(1 - z^2) instead
// would leave only ~1e-11 relative in sin^2(theta) and ~1e-6 in 1 - z here).
TEST(Warps, UniformConeSmallCapKeepsRelativePrecision) {
  const double cosThetaMax = std::cos(kSunAngularRadius);
  for (const Vec2d& u : TestPoints(6, 10000)) {
    if (u.x == 0) continue;
    const Vec3d w = SampleUniformCone(u, cosThetaMax);
    const double t = OneMinusCos(w);
    const double expected = u.x * (1 - cosThetaMax);
    ASSERT_NEAR(t / expected, 1, 16 * kEps) << u;
  }
}

// ---- Uniform triangle (barycentrics).

TEST(Warps, UniformTriangleMatchesPdf) {
  // Grid of K x K cells over (b0, b1); cells below the diagonal lie inside the triangle
  // b0 + b1 <= 1 (expected share 2 / K^2 of the samples), cells the diagonal passes through
  // corner to corner have half that, the rest zero. Exact expectations, no quadrature.
  constexpr int K = 32;
  std::vector<double> observed(K * K, 0), expected(K * K, 0);
  for (int i = 0; i < K; ++i)
    for (int j = 0; j < K; ++j)
      expected[i * K + j] =
          kSamples * (i + j < K - 1 ? 2.0 : (i + j == K - 1 ? 1.0 : 0.0)) / (K * K);
  IndependentSampler s(9, 9);
  for (int n = 0; n < kSamples; ++n) {
    s.StartSample(n);
    const auto b = SampleUniformTriangle(s.Get2D());
    ASSERT_GE(b[0], 0);
    ASSERT_GE(b[1], 0);
    ASSERT_GE(b[2], -kEps);
    ASSERT_EQ(b[0] + b[1] + b[2], 1.0);
    observed[std::min(int(b[0] * K), K - 1) * K + std::min(int(b[1] * K), K - 1)] += 1;
  }
  const auto r = ChiSquareTest(observed, expected, kAlpha);
  EXPECT_TRUE(r.pass) << r.ToString();
  // Pdf: 1 / area.
  EXPECT_DOUBLE_EQ(UniformTrianglePdf({0, 0, 0}, {2, 0, 0}, {0, 3, 0}), 1 / 3.0);
  EXPECT_DOUBLE_EQ(UniformTrianglePdf({1, 1, 1}, {1, 2, 1}, {1, 1, 5}), 1 / 2.0);
}

TEST(Warps, UniformTriangleInverts) {
  // b0 = u.x/2 is exact and b1 = u.y - b0 rounds once; the inverse adds them back: <= 2 eps.
  for (const Vec2d& u : TestPoints(7, 100000)) {
    const Vec2d v = InvertUniformTriangleSample(SampleUniformTriangle(u));
    ASSERT_NEAR(v.x, u.x, 4 * kEps) << u;
    ASSERT_NEAR(v.y, u.y, 4 * kEps) << u;
  }
}

// ---- Parallelogram.

TEST(Warps, UniformParallelogramMatchesPdfAndInverts) {
  const Vec3d p0{1, -2, 0.5}, e1{2, 0.5, 0}, e2{0.3, 1, 1.5};
  const Vec3d n = Cross(e1, e2);
  EXPECT_DOUBLE_EQ(UniformParallelogramPdf(e1, e2), 1 / Length(n));
  // Parameters recovered with the cross-product (Cramer) formula, independent of the inverse's
  // normal equations.
  constexpr int K = 32;
  std::vector<double> observed(K * K, 0), expected(K * K, double(kSamples) / (K * K));
  IndependentSampler s(10, 10);
  for (int i = 0; i < kSamples; ++i) {
    s.StartSample(i);
    const Vec3d d = SampleUniformParallelogram(s.Get2D(), p0, e1, e2) - p0;
    const double a = Dot(Cross(d, e2), n) / Dot(n, n), b = Dot(Cross(e1, d), n) / Dot(n, n);
    observed[std::clamp(int(a * K), 0, K - 1) * K + std::clamp(int(b * K), 0, K - 1)] += 1;
  }
  const auto r = ChiSquareTest(observed, expected, kAlpha);
  EXPECT_TRUE(r.pass) << r.ToString();
  // Inverse: the 2x2 normal equations have condition number ~ (|e1||e2| / |e1 x e2|)^2 ~ 2 here;
  // with O(1) coordinates the error is a few tens of eps: 64 eps.
  for (const Vec2d& u : TestPoints(11, 100000)) {
    const Vec2d v =
        InvertUniformParallelogramSample(SampleUniformParallelogram(u, p0, e1, e2), p0, e1, e2);
    ASSERT_NEAR(v.x, u.x, 64 * kEps) << u;
    ASSERT_NEAR(v.y, u.y, 64 * kEps) << u;
  }
}

// ---- Henyey-Greenstein.

TEST(HenyeyGreenstein, IsotropicAtZeroIsExactlyUniformSphere) {
  for (const Vec2d& u : TestPoints(12, 100000)) {
    const Vec3d w = SampleHenyeyGreenstein(u, 0);
    ASSERT_EQ(w, SampleUniformSphere(u)) << u;
    ASSERT_EQ(HenyeyGreensteinPdf(w.z, 0), UniformSpherePdf());
    ASSERT_EQ(InvertHenyeyGreensteinSample(w, 0), InvertUniformSphereSample(w)) << u;
  }
}

// Textbook CDF, P(cos > mu) = (1 - g^2)/(2g) [1/(1 - g) - (1 + g^2 - 2 g mu)^(-1/2)], inverted in
// long double: only used to place bin edges and quadrature panels at equal probability so that
// every bin is well populated; expectations always come from integrating HenyeyGreensteinPdf.
std::vector<double> EqualProbabilityEdges(double g, int k) {
  std::vector<double> edges(k + 1);
  const long double G = g;
  for (int i = 0; i <= k; ++i) {
    const long double U = static_cast<long double>(i) / k;  // P(cos > edge)
    if (i == 0) {
      edges[i] = 1;
      continue;
    }
    if (i == k) {
      edges[i] = -1;
      continue;
    }
    const long double X = 1 / (1 - G) - 2 * G * U / (1 - G * G);  // (1 + g^2 - 2 g mu)^(-1/2)
    edges[i] = static_cast<double>((1 + G * G - 1 / (X * X)) / (2 * G));
  }
  return edges;  // descending from 1 to -1
}

// Probability of cos(theta) in [lo, hi]: integral of 2 pi p(mu) dmu. Far from isotropic the pdf
// behaves like D^(-3/2) with D = 1 + g^2 - 2 g mu, nearly singular just beyond mu = +-1, so plain
// Gauss-Legendre in mu converges slowly on wide tail bins (a 100-bin test showed a 16% error in
// the widest bin). Substituting x = log D (dmu = -D/(2g) dx) turns the integrand into a smooth
// multiple of exp(-x/2), which 16-point Gauss-Legendre integrates to rounding level over the
// whole range of x here (< 16). Nodes are placed in long double; the pdf is evaluated in double.
double HgBinProbability(double g, double lo, double hi) {
  if (std::abs(g) < 0.01) {  // nearly constant pdf: plain quadrature in mu is exact enough
    const auto q = GaussLegendre(16, lo, hi);
    double p = 0;
    for (int i = 0; i < 16; ++i) p += q.w[i] * 2 * kPi * HenyeyGreensteinPdf(q.x[i], g);
    return p;
  }
  const long double G = g;
  const auto logD = [&](long double mu) { return std::log(1 + G * G - 2 * G * mu); };
  const long double x0 = logD(lo), x1 = logD(hi);
  const auto q = GaussLegendre(16, 0, 1);
  long double p = 0;
  for (int i = 0; i < 16; ++i) {
    const long double x = x0 + (x1 - x0) * static_cast<long double>(q.x[i]);
    const long double d = std::exp(x);
    const long double mu = (1 + G * G - d) / (2 * G);
    const long double jacobian = std::abs((x1 - x0) * d / (2 * G));
    p += static_cast<long double>(q.w[i]) * jacobian * 2 * kPi *
         HenyeyGreensteinPdf(static_cast<double>(mu), g);
  }
  return static_cast<double>(p);
}

class HenyeyGreensteinTest : public ::testing::TestWithParam<double> {};

TEST_P(HenyeyGreensteinTest, PdfIntegratesToOne) {
  const double g = GetParam();
  // 400 equal-probability panels integrated as in HgBinProbability: truncation at the rounding
  // level, 6400 terms summing to ~1e-12. On top of that, the pdf is evaluated at mu rounded to
  // double (<= 5.5e-17 absolute near 1); p ~ D^(-3/2) turns that into a relative error up to
  // 1.5 * 2|g| * 5.5e-17 / D, at most 1.65e-16 |g| / (1 - |g|)^2 at the peak (1.6e-10 for
  // g = 0.999). Tolerance: 1e-12 + 2e-16 |g| / (1 - |g|)^2.
  const std::vector<double> edges = EqualProbabilityEdges(g, 400);
  double total = 0;
  for (int i = 0; i < 400; ++i) total += HgBinProbability(g, edges[i + 1], edges[i]);
  const double peakConditioning = std::abs(g) / ((1 - std::abs(g)) * (1 - std::abs(g)));
  EXPECT_NEAR(total, 1, 1e-12 + 2e-16 * peakConditioning) << "g = " << g;
}

TEST_P(HenyeyGreensteinTest, MatchesPdf) {
  const double g = GetParam();
  constexpr int nMu = 100, nPhi = 8;
  const std::vector<double> edges = EqualProbabilityEdges(g, nMu);  // descending
  std::vector<double> observed(nMu * nPhi, 0), expected(nMu * nPhi, 0);
  for (int i = 0; i < nMu; ++i) {
    const double p = HgBinProbability(g, edges[i + 1], edges[i]);
    for (int j = 0; j < nPhi; ++j) expected[i * nPhi + j] = p * kSamples / nPhi;
  }
  IndependentSampler s(13, Hash(static_cast<int64_t>(g * 1000)));
  for (int n = 0; n < kSamples; ++n) {
    s.StartSample(n);
    const Vec3d w = SampleHenyeyGreenstein(s.Get2D(), g);
    ASSERT_TRUE(IsFinite(w));
    ASSERT_NEAR(Length(w), 1, 4 * kEps);
    // Bin i holds cos in [edges[i+1], edges[i]).
    const int i = std::clamp(
        static_cast<int>(std::upper_bound(edges.begin(), edges.end(), w.z, std::greater<double>()) -
                         edges.begin()) -
            1,
        0, nMu - 1);
    const int j = std::min(static_cast<int>(Azimuth(w) / (2 * kPi) * nPhi), nPhi - 1);
    observed[i * nPhi + j] += 1;
  }
  const auto r = ChiSquareTest(observed, expected, kAlpha);
  EXPECT_TRUE(r.pass) << "g = " << g << ": " << r.ToString();
}

// Defining property of HG: E[P_l(cos theta)] = g^l. |P_l| <= 1 bounds the standard deviation of
// the sample mean by 1/sqrt(N); 5 such bounds.
TEST_P(HenyeyGreensteinTest, LegendreMomentsArePowersOfG) {
  const double g = GetParam();
  double m1 = 0, m2 = 0, m3 = 0;
  IndependentSampler s(14, Hash(static_cast<int64_t>(g * 1000)));
  for (int n = 0; n < kSamples; ++n) {
    s.StartSample(n);
    const double mu = SampleHenyeyGreensteinCos(s.Get1D(), g);
    m1 += mu;
    m2 += (3 * mu * mu - 1) / 2;
    m3 += (5 * mu * mu * mu - 3 * mu) / 2;
  }
  const double tolerance = 5 / std::sqrt(double(kSamples));
  EXPECT_NEAR(m1 / kSamples, g, tolerance);
  EXPECT_NEAR(m2 / kSamples, g * g, tolerance);
  EXPECT_NEAR(m3 / kSamples, g * g * g, tolerance);
}

TEST_P(HenyeyGreensteinTest, StableAndMonotoneOverTheWholeUnitInterval) {
  const double g = GetParam();
  double previous = 2;
  for (int i = 0; i <= 1 << 16; ++i) {
    // Uniform grid plus points crowding both ends, where the lobe's peak and tail sit.
    for (double u : {i / 65536.0, 0x1p-32 * i, 1 - 0x1p-32 * (65536 - i)}) {
      if (u >= 1) continue;
      const double mu = SampleHenyeyGreensteinCos(u, g);
      ASSERT_TRUE(mu >= -1 && mu <= 1) << "u = " << u << ", cos = " << mu;
      const double p = HenyeyGreensteinPdf(mu, g);
      ASSERT_TRUE(std::isfinite(p) && p > 0) << "u = " << u << ", pdf = " << p;
    }
    const double mu = SampleHenyeyGreensteinCos(i / 65536.0, g);
    if (i < 65536) {
      ASSERT_LE(mu, previous) << "not monotone at u = " << i / 65536.0;
    }
    previous = mu;
  }
  // u = 0 is the forward direction, to the documented absolute error of cos (<= 12 eps).
  EXPECT_NEAR(SampleHenyeyGreensteinCos(0, g), 1, 12 * kEps);
}

TEST_P(HenyeyGreensteinTest, Inverts) {
  const double g = GetParam();
  for (const Vec2d& u : TestPoints(15, 100000)) {
    const Vec3d w = SampleHenyeyGreenstein(u, g);
    const Vec2d v = InvertHenyeyGreensteinSample(w, g);
    // cos(theta) is computed to a few eps absolute (<= 12 eps, see warps.h); the inverse maps an
    // error d(cos) to du = 2 pi p(cos) d(cos), large at the peak of a sharp lobe (2 pi p ~ 1e6
    // at g = 0.999). Tolerance 32 eps (1 + 2 pi p).
    const double tolerance = 32 * kEps * (1 + 2 * kPi * HenyeyGreensteinPdf(w.z, g));
    ASSERT_NEAR(v.x, u.x, tolerance) << "g = " << g << ", u = " << u;
    if (w.x != 0 || w.y != 0) {
      ASSERT_LE(AzimuthFractionDistance(v.y, u.y), kRoundTripTolerance)
          << "g = " << g << ", u = " << u;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(G, HenyeyGreensteinTest,
                         ::testing::Values(-0.999, -0.9, -0.5, -0.2, 0.1, 0.3, 0.5, 0.9, 0.999));

}  // namespace
}  // namespace probebake
