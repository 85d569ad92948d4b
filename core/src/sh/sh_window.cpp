#include "probebake/sh/sh_window.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <sstream>
#include <vector>

#include "probebake/base/check.h"
#include "probebake/math/frame.h"
#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sh_convolution.h"

namespace probebake {

double HanningWindowFactor(int l, double width) {
  PB_CHECK_GE(l, 0);
  PB_CHECK(width > 0);  // also rejects NaN; +inf is "no window"
  if (l > width) return 0;
  return 0.5 * (1 + std::cos(std::numbers::pi * l / width));
}

double LanczosWindowFactor(int l, int order) {
  PB_CHECK_GE(l, 0);
  PB_CHECK_GE(order, 0);
  if (l == 0) return 1;
  const double x = std::numbers::pi * l / (order + 1);
  return std::sin(x) / x;
}

double HeatWindowFactor(int l, double t) {
  PB_CHECK_GE(l, 0);
  PB_CHECK(t >= 0);  // also rejects NaN
  if (l == 0) return 1;
  return std::exp(-t * l * (l + 1));
}

double ShBandWindow::Factor(int l, int order) const {
  switch (kind) {
    case ShBandWindowKind::kNone:
      return 1;
    case ShBandWindowKind::kHanning:
      return HanningWindowFactor(l, parameter);
    case ShBandWindowKind::kLanczos:
      return LanczosWindowFactor(l, order);
    case ShBandWindowKind::kHeat:
      return HeatWindowFactor(l, parameter);
  }
  PB_CHECK(false);
  return 0;
}

std::string ShBandWindow::ToString() const {
  std::ostringstream os;
  os.precision(17);
  switch (kind) {
    case ShBandWindowKind::kNone:
      return "NONE";
    case ShBandWindowKind::kHanning:
      os << "HANNING(width=" << parameter << ")";
      break;
    case ShBandWindowKind::kLanczos:
      return "LANCZOS";
    case ShBandWindowKind::kHeat:
      os << "HEAT(t=" << parameter << ")";
      break;
  }
  return os.str();
}

std::ostream& operator<<(std::ostream& os, const ShBandWindow& window) {
  return os << window.ToString();
}

std::ostream& operator<<(std::ostream& os, const AutoWindowResult& result) {
  return os << "AutoWindowResult{" << result.window
            << (result.nonNegative ? "" : ", cannot be made non-negative") << "}";
}

namespace {

template <typename V>
void ApplyWindow(const ShBandWindow& window, int order, std::span<V> coeffs) {
  PB_CHECK(order >= 0 && order <= kMaxShOrder);
  PB_CHECK_GE(coeffs.size(), static_cast<size_t>(ShCoeffCount(order)));
  if (window.kind == ShBandWindowKind::kNone) return;
  for (int l = 0; l <= order; ++l) {
    const double w = window.Factor(l, order);
    for (int i = l * l; i < (l + 1) * (l + 1); ++i) coeffs[i] = coeffs[i] * w;
  }
}

}  // namespace

void ApplyShWindow(const ShBandWindow& window, int order, std::span<double> coeffs) {
  ApplyWindow(window, order, coeffs);
}

void ApplyShWindowRgb(const ShBandWindow& window, int order, std::span<Vec3d> coeffs) {
  ApplyWindow(window, order, coeffs);
}

// ---------------------------------------------------------------------------------------------
// Auto window.

namespace {

constexpr double kPi = std::numbers::pi;
constexpr int kMaxBands = kMaxShOrder + 1;
constexpr double kInf = std::numeric_limits<double>::infinity();

// The irradiance bands of an order: l <= order with Â_l != 0 (0, 1, 2, 4, 6, 8, ...).
struct Bands {
  int count = 0;
  int l[kMaxBands] = {};
  double factor[kMaxBands] = {};  // Â_l

  explicit Bands(int order) {
    for (int l_ = 0; l_ <= order; ++l_) {
      const double a = IrradianceBandFactor(l_);
      if (a != 0) {
        l[count] = l_;
        factor[count] = a;
        ++count;
      }
    }
  }
  // s_j = exp(-t l_j (l_j + 1)), the heat window of each band.
  void Heat(double t, double* s) const {
    for (int j = 0; j < count; ++j) s[j] = HeatWindowFactor(l[j], t);
  }
};

// Per channel: the constant term c = Â_0 L_00 Y_00 and each band's amplitude bound
// a_j = |Â_l| |L_l| sqrt((2l+1)/(4π)) >= max_ω |Σ_m Â_l L_lm Y_lm(ω)| (addition theorem and
// Cauchy–Schwarz). E_t >= c - Σ_{j>=1} s_j a_j everywhere: a sufficient test for non-negativity.
struct ChannelBounds {
  double c[3] = {};
  double a[3][kMaxBands] = {};
};

ChannelBounds MakeBounds(const Bands& bands, std::span<const Vec3d> radiance) {
  ChannelBounds b;
  for (int ch = 0; ch < 3; ++ch) {
    b.c[ch] = bands.factor[0] * radiance[0][ch] * kShY00;
    for (int j = 1; j < bands.count; ++j) {
      const int l = bands.l[j];
      double norm2 = 0;
      for (int i = l * l; i < (l + 1) * (l + 1); ++i) norm2 += radiance[i][ch] * radiance[i][ch];
      b.a[ch][j] = std::abs(bands.factor[j]) * std::sqrt(norm2 * (2 * l + 1) / (4 * kPi));
    }
  }
  return b;
}

// The smallest t for which the sufficient test holds in every channel, using
// Σ_j s_j a_j <= exp(-2t) Σ_j a_j: t = ln(Σ a / c) / 2. Requires c > 0 where Σ a > 0.
double CertifiedUpperT(const Bands& bands, const ChannelBounds& b) {
  double t = 0;
  for (int ch = 0; ch < 3; ++ch) {
    double sum = 0;
    for (int j = 1; j < bands.count; ++j) sum += b.a[ch][j];
    if (sum > b.c[ch]) t = std::max(t, 0.5 * std::log(sum / b.c[ch]));
  }
  // One ulp-scale nudge so rounding in exp() cannot leave the bound a hair short.
  return t * (1 + 1e-12) + 1e-300;
}

bool SufficientTestPasses(const Bands& bands, const ChannelBounds& b, double t) {
  double s[kMaxBands];
  bands.Heat(t, s);
  for (int ch = 0; ch < 3; ++ch) {
    double sum = 0;
    for (int j = 1; j < bands.count; ++j) sum += s[j] * b.a[ch][j];
    if (b.c[ch] - sum < 0) return false;
  }
  return true;
}

// ---- Orders <= 3: exact minimum of a quadratic form on the sphere. ----

// Eigen-decomposition of a symmetric 3x3 matrix by cyclic Jacobi rotations: a = q diag(w) qᵀ,
// the columns of q the eigenvectors. Converges quadratically; 10 sweeps are far more than needed.
void SymmetricEigen3(double a[3][3], double w[3], double q[3][3]) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) q[i][j] = i == j ? 1 : 0;
  for (int sweep = 0; sweep < 10; ++sweep) {
    const double off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    if (off == 0) break;
    for (int p = 0; p < 2; ++p) {
      for (int r = p + 1; r < 3; ++r) {
        if (a[p][r] == 0) continue;
        const double theta = (a[r][r] - a[p][p]) / (2 * a[p][r]);
        const double t = std::copysign(1.0, theta) / (std::abs(theta) + std::hypot(theta, 1.0));
        const double c = 1 / std::sqrt(t * t + 1), s = t * c;
        for (int k = 0; k < 3; ++k) {  // a <- Jᵀ a J
          const double akp = a[k][p], akr = a[k][r];
          a[k][p] = c * akp - s * akr;
          a[k][r] = s * akp + c * akr;
        }
        for (int k = 0; k < 3; ++k) {
          const double apk = a[p][k], ark = a[r][k];
          a[p][k] = c * apk - s * ark;
          a[r][k] = s * apk + c * ark;
        }
        for (int k = 0; k < 3; ++k) {
          const double qkp = q[k][p], qkr = q[k][r];
          q[k][p] = c * qkp - s * qkr;
          q[k][r] = s * qkp + c * qkr;
        }
      }
    }
  }
  for (int i = 0; i < 3; ++i) w[i] = a[i][i];
}

// E(ω) = c + b·ω + ωᵀAω on the unit sphere, A symmetric, stored in A's eigenbasis.
class QuadraticOnSphere {
 public:
  // e: irradiance coefficients of one channel, order <= 3 (band 3 has Â_3 = 0 and is ignored).
  QuadraticOnSphere(int order, const double* e) {
    constexpr double k1 = 0.48860251190291992159;   // sqrt(3/(4π))
    constexpr double k2a = 1.0925484305920790705;   // sqrt(15/(4π))
    constexpr double k20 = 0.31539156525252000603;  // sqrt(5/(16π))
    constexpr double k22 = 0.54627421529603953527;  // sqrt(15/(16π))
    c_ = kShY00 * e[0];
    double b[3] = {0, 0, 0};
    double a[3][3] = {};
    if (order >= 1) {
      b[0] = -k1 * e[3];
      b[1] = -k1 * e[1];
      b[2] = k1 * e[2];
    }
    if (order >= 2) {
      // Band 2 with 3z² - 1 = 2z² - x² - y² on the sphere: a traceless quadratic form.
      a[0][1] = a[1][0] = 0.5 * k2a * e[4];
      a[1][2] = a[2][1] = -0.5 * k2a * e[5];
      a[0][2] = a[2][0] = -0.5 * k2a * e[7];
      a[0][0] = -k20 * e[6] + k22 * e[8];
      a[1][1] = -k20 * e[6] - k22 * e[8];
      a[2][2] = 2 * k20 * e[6];
    }
    double w[3], q[3][3];
    SymmetricEigen3(a, w, q);
    int idx[3] = {0, 1, 2};
    std::sort(idx, idx + 3, [&](int i, int j) { return w[i] < w[j]; });
    for (int k = 0; k < 3; ++k) {
      lambda_[k] = w[idx[k]];
      beta_[k] = q[0][idx[k]] * b[0] + q[1][idx[k]] * b[1] + q[2][idx[k]] * b[2];
    }
  }

  // min over |x| = 1 of c + s1 b·x + s2 xᵀAx (s1, s2 >= 0): the dual value
  // g(μ) = μ - Σ β_i² / (4(d_i - μ)) (d = s2 λ, β scaled by s1) is a lower bound for every
  // μ < d_min and equals the minimum at its maximiser, the root of the secular equation
  // Σ β_i² / (4(d_i - μ)²) = 1, found by safeguarded Newton in δ = d_min - μ.
  double Min(double s1, double s2) const {
    double d[3], beta[3];
    double beta2 = 0;
    for (int k = 0; k < 3; ++k) {
      d[k] = s2 * lambda_[k];
      beta[k] = s1 * beta_[k];
      beta2 += beta[k] * beta[k];
    }
    if (beta2 == 0) return c_ + d[0];
    auto dual = [&](double delta) {  // g at μ = d_min - δ
      double g = d[0] - delta;
      for (int k = 0; k < 3; ++k) {
        if (beta[k] != 0) g -= beta[k] * beta[k] / (4 * (d[k] - d[0] + delta));
      }
      return g;
    };
    // Hard case: no weight on the lowest eigenvalue(s) and the secular sum at δ = 0 <= 1.
    double phi0 = 0;
    bool finite = true;
    for (int k = 0; k < 3; ++k) {
      if (beta[k] == 0) continue;
      const double gap = d[k] - d[0];
      if (gap <= 0) {
        finite = false;
        break;
      }
      phi0 += beta[k] * beta[k] / (4 * gap * gap);
    }
    if (finite && phi0 <= 1) return c_ + dual(0);
    // Bracket: φ(hi) <= 1 since every term <= β_k² / (4δ²); φ(lo) >= 1 from the k = 0 term
    // alone. ψ(δ) = 1/sqrt(φ(δ)) - 1 is concave and increasing (Moré–Sorensen), so Newton from
    // the left end climbs to the root monotonically; that matters when β_0 is rounding noise on
    // a problem that is exactly the hard case (a single light: b along A's top eigenvector).
    double lo = 0.5 * std::abs(beta[0]), hi = 0.5 * std::sqrt(beta2);
    double delta = lo > 0 ? lo : (finite ? 0 : hi);
    for (int iter = 0; iter < 100; ++iter) {
      // Newton on ψ, bisecting when a step leaves the bracket.
      double phi = 0, dphi = 0;
      for (int k = 0; k < 3; ++k) {
        if (beta[k] == 0) continue;
        const double den = d[k] - d[0] + delta;
        const double t = beta[k] * beta[k] / (4 * den * den);
        phi += t;
        dphi -= 2 * t / den;
      }
      if (phi > 1) {
        lo = delta;
      } else {
        hi = delta;
      }
      const double psi = 1 / std::sqrt(phi) - 1;
      const double dpsi = -0.5 * dphi / (phi * std::sqrt(phi));
      const double step = psi / dpsi;
      if (std::abs(step) <= 4e-16 * delta) break;  // converged to rounding
      double next = delta - step;
      if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
      if (hi - lo <= 4e-16 * hi) break;
      delta = next;
    }
    return c_ + dual(std::max(delta, std::numeric_limits<double>::min()));
  }

 private:
  double c_ = 0;
  double lambda_[3] = {};  // ascending
  double beta_[3] = {};
};

// The smallest t with m(t) >= 0, given m(lo) < 0 <= m(hi) and m non-decreasing (the minimum
// principle): Brent's method (inverse quadratic interpolation and secant steps, bisection when
// they stall), until the bracket is narrower than 1e-10 t. Returns the bracket's feasible end.
// R. P. Brent, "Algorithms for Minimization without Derivatives", 1973, ch. 4.
template <typename MinFn>
double SmallestNonNegativeT(double lo, double mlo, double hi, double mhi, MinFn&& m) {
  // b: the latest estimate; c: the other end of the bracket; a: the previous b.
  double a = lo, fa = mlo, b = hi, fb = mhi, c = a, fc = fa;
  double d = b - a, e = d;
  for (int iter = 0; iter < 200; ++iter) {
    if ((fb >= 0) == (fc >= 0)) {  // keep b and c on opposite sides of the root
      c = a, fc = fa;
      d = e = b - a;
    }
    if (std::abs(fc) < std::abs(fb)) {  // b the better estimate
      a = b, b = c, c = a;
      fa = fb, fb = fc, fc = fa;
    }
    const double tol = 0.25e-10 * std::max(std::abs(b), std::abs(c));
    const double half = 0.5 * (c - b);
    if (std::abs(half) <= tol || fb == 0) break;
    if (std::abs(e) >= tol && std::abs(fa) > std::abs(fb)) {
      double p, q;
      const double sb = fb / fa;
      if (a == c) {  // secant
        p = 2 * half * sb;
        q = 1 - sb;
      } else {  // inverse quadratic interpolation
        const double qa = fa / fc, r = fb / fc;
        p = sb * (2 * half * qa * (qa - r) - (b - a) * (r - 1));
        q = (qa - 1) * (r - 1) * (sb - 1);
      }
      if (p > 0) {
        q = -q;
      } else {
        p = -p;
      }
      if (2 * p < std::min(3 * half * q - std::abs(tol * q), std::abs(e * q))) {
        e = d;
        d = p / q;
      } else {
        d = e = half;
      }
    } else {
      d = e = half;
    }
    a = b, fa = fb;
    b += std::abs(d) > tol ? d : (half > 0 ? tol : -tol);
    fb = m(b);
  }
  // The root lies between b and c (within the tolerance); return the side with m >= 0.
  if (fb >= 0 && (fc < 0 || b <= c)) return b;
  return fc >= 0 ? c : b;
}

AutoWindowResult AutoWindowQuadratic(int order, std::span<const Vec3d> radiance, const Bands& bands,
                                     const ChannelBounds& bounds) {
  std::vector<QuadraticOnSphere> quads;
  for (int ch = 0; ch < 3; ++ch) {
    double e[16] = {};
    for (int l = 0; l <= order; ++l)
      for (int i = l * l; i < (l + 1) * (l + 1); ++i)
        e[i] = IrradianceBandFactor(l) * radiance[i][ch];
    quads.emplace_back(order, e);
  }
  auto minimum = [&](double t) {
    const double s1 = HeatWindowFactor(1, t), s2 = HeatWindowFactor(2, t);
    double m = kInf;
    for (const QuadraticOnSphere& q : quads) m = std::min(m, q.Min(s1, s2));
    return m;
  };
  const double m0 = minimum(0);
  if (m0 >= 0) return {ShBandWindow::Heat(0), true};
  const double hi = CertifiedUpperT(bands, bounds);
  return {ShBandWindow::Heat(SmallestNonNegativeT(0, m0, hi, std::max(0.0, minimum(hi)), minimum)),
          true};
}

// ---- Orders >= 4: grid, bisection, Newton refinement. ----

// A deterministic near-uniform grid: rows at θ_i = (i + 1/2) π / rows, each with enough
// points for an arc spacing <= `spacing`, alternate rows offset by half a step. Every direction
// is within `spacing` of a grid point (covering radius <= spacing/sqrt(2) up to curvature), and
// each point knows its neighbours within 1.6 spacing.
struct Grid {
  double spacing = 0;
  std::vector<Vec3d> dirs;
  std::vector<std::vector<int>> neighbors;
};

Grid MakeGrid(int bandLimit) {
  Grid g;
  const int rows = 2 * bandLimit + 2;
  g.spacing = kPi / rows;
  for (int i = 0; i < rows; ++i) {
    const double theta = (i + 0.5) * g.spacing;
    const int n = std::max(3, static_cast<int>(std::ceil(2 * kPi * std::sin(theta) / g.spacing)));
    for (int j = 0; j < n; ++j) {
      const double phi = (j + 0.5 * (i % 2)) * 2 * kPi / n;
      g.dirs.push_back(
          {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)});
    }
  }
  const double cosRadius = std::cos(1.6 * g.spacing);
  g.neighbors.resize(g.dirs.size());
  for (size_t p = 0; p < g.dirs.size(); ++p)
    for (size_t q = 0; q < g.dirs.size(); ++q)
      if (p != q && Dot(g.dirs[p], g.dirs[q]) > cosRadius) g.neighbors[p].push_back(q);
  return g;
}

const Grid& GridFor(int bandLimit) {
  static const Grid g4 = MakeGrid(4), g6 = MakeGrid(6), g8 = MakeGrid(8);
  static_assert(kMaxShOrder <= 9, "add grids for higher irradiance bands");
  return bandLimit <= 4 ? g4 : (bandLimit <= 6 ? g6 : g8);
}

class NumericAutoWindow {
 public:
  NumericAutoWindow(int order, std::span<const Vec3d> radiance, const Bands& bands,
                    const ChannelBounds& bounds)
      : order_(order), bands_(bands), bounds_(bounds), grid_(GridFor(bands.l[bands.count - 1])) {
    // Irradiance coefficients Â_l L_lm, channel by channel, contiguous for the band sums.
    for (int ch = 0; ch < 3; ++ch) {
      for (int l = 0; l <= order; ++l)
        for (int i = l * l; i < (l + 1) * (l + 1); ++i)
          irradiance_[ch][i] = IrradianceBandFactor(l) * radiance[i][ch];
    }
    for (int ch = 0; ch < 3; ++ch) {
      points_[ch].dirs.reserve(grid_.dirs.size() + 64);
      points_[ch].values.reserve((grid_.dirs.size() + 64) * bands_.count);
      for (int j = 0; j < bands_.count; ++j) active_[ch].v[j].reserve(grid_.dirs.size() + 64);
    }
    for (const Vec3d& d : grid_.dirs) AddPointAllChannels(d);
    gridSize_ = grid_.dirs.size();
  }

  double Solve() {
    std::vector<Refined> negative;
    // At t = 0 a negative grid value already settles it; otherwise refine to decide.
    if (PointSetMin(0) >= 0 && RefinedMin(0, &negative) >= 0) return 0;
    double lo = 0;
    const double certified = CertifiedUpperT(bands_, bounds_);
    auto pointSetMin = [&](double t) { return PointSetMin(t); };
    for (int round = 0; round < 8; ++round) {
      for (const Refined& r : negative) AddPoint(r.channel, r.dir);
      negative.clear();
      const double t = SmallestNonNegativeT(lo, PointSetMin(lo), certified,
                                            std::max(0.0, PointSetMin(certified)), pointSetMin);
      if (RefinedMin(t, &negative) >= 0) return t;
      lo = t;
    }
    return certified;  // unreachable in practice; always safe
  }

 private:
  struct Refined {
    int channel;
    Vec3d dir;
    double value;
  };

  // Per-band irradiance values of channel ch at dir.
  void BandValues(int ch, const Vec3d& dir, double* v) const {
    double y[kMaxShCoeffCount];
    EvalShBasis(order_, dir, y);
    for (int j = 0; j < bands_.count; ++j) {
      const int l = bands_.l[j];
      double sum = 0;
      for (int i = l * l; i < (l + 1) * (l + 1); ++i) sum += irradiance_[ch][i] * y[i];
      v[j] = sum;
    }
  }

  double Value(int ch, const Vec3d& dir, const double* s) const {
    double v[kMaxBands];
    BandValues(ch, dir, v);
    double sum = 0;
    for (int j = 0; j < bands_.count; ++j) sum += s[j] * v[j];
    return sum;
  }

  void AddPoint(int ch, const Vec3d& dir) {
    points_[ch].dirs.push_back(dir);
    const size_t base = points_[ch].values.size();
    points_[ch].values.resize(base + bands_.count);
    BandValues(ch, dir, &points_[ch].values[base]);
    for (int j = 0; j < bands_.count; ++j) active_[ch].v[j].push_back(points_[ch].values[base + j]);
  }

  // The same point for every channel, with one basis evaluation.
  void AddPointAllChannels(const Vec3d& dir) {
    double y[kMaxShCoeffCount];
    EvalShBasis(order_, dir, y);
    for (int ch = 0; ch < 3; ++ch) {
      points_[ch].dirs.push_back(dir);
      for (int j = 0; j < bands_.count; ++j) {
        const int l = bands_.l[j];
        double sum = 0;
        for (int i = l * l; i < (l + 1) * (l + 1); ++i) sum += irradiance_[ch][i] * y[i];
        points_[ch].values.push_back(sum);
        active_[ch].v[j].push_back(sum);
      }
    }
  }

  double PointValue(int ch, size_t p, const double* s) const {
    const double* v = &points_[ch].values[p * bands_.count];
    double sum = 0;
    for (int j = 0; j < bands_.count; ++j) sum += s[j] * v[j];
    return sum;
  }

  // Minimum over the (active) point set at t. A negative result makes t a lower end of every
  // later search, so points that provably stay non-negative above t are dropped then: for
  // t' >= t, s_j(t') <= s_j(t) and a point's value is >= v_0 - Σ_{j>=1} s_j(t) |v_j|. Dropped
  // points are >= 0 wherever they could matter, so the sign of the result is unaffected. The
  // active values are stored band by band and compacted, so these loops vectorise.
  double PointSetMin(double t) {
    double s[kMaxBands];
    bands_.Heat(t, s);
    double m = kInf;
    for (int ch = 0; ch < 3; ++ch) {
      ActiveSet& a = active_[ch];
      const size_t n = a.v[0].size();
      scratch_.assign(n, 0.0);
      double* f = scratch_.data();
      for (int j = 0; j < bands_.count; ++j) {
        const double sj = s[j];
        const double* v = a.v[j].data();
        for (size_t p = 0; p < n; ++p) f[p] += sj * v[p];
      }
      for (size_t p = 0; p < n; ++p) m = std::min(m, f[p]);
    }
    if (m < 0) {
      for (int ch = 0; ch < 3; ++ch) {
        ActiveSet& a = active_[ch];
        const size_t n = a.v[0].size();
        scratch_.assign(a.v[0].begin(), a.v[0].end());
        double* bound = scratch_.data();
        for (int j = 1; j < bands_.count; ++j) {
          const double sj = s[j];
          const double* v = a.v[j].data();
          for (size_t p = 0; p < n; ++p) bound[p] -= sj * std::abs(v[p]);
        }
        size_t kept = 0;
        for (size_t p = 0; p < n; ++p) {
          if (bound[p] >= 0) continue;
          for (int j = 0; j < bands_.count; ++j) a.v[j][kept] = a.v[j][p];
          ++kept;
        }
        for (int j = 0; j < bands_.count; ++j) a.v[j].resize(kept);
      }
    }
    return m;
  }

  // Minimum of channel ch's windowed irradiance near `start`, by Newton's method on the sphere
  // with finite-difference derivatives in a tangent frame (step 1e-4 rad: gradient errors
  // ~1e-8 relative, so the minimiser is located to ~1e-8 rad and its value, being stationary,
  // to ~1e-16 relative), each step limited to the grid spacing and halved until it descends.
  Refined Refine(int ch, Vec3d start, const double* s) const {
    constexpr double h = 1e-4;
    Vec3d w = start;
    double f = Value(ch, w, s);
    for (int iter = 0; iter < 30; ++iter) {
      const Framed frame = Framed::FromZ(w);
      auto at = [&](double u, double v) {
        return Value(ch, Normalize(w + frame.s * u + frame.t * v), s);
      };
      const double fpu = at(h, 0), fmu = at(-h, 0), fpv = at(0, h), fmv = at(0, -h);
      const double fpp = at(h, h);
      const double gu = (fpu - fmu) / (2 * h), gv = (fpv - fmv) / (2 * h);
      const double huu = (fpu - 2 * f + fmu) / (h * h), hvv = (fpv - 2 * f + fmv) / (h * h);
      const double huv = (fpp - fpu - fpv + f) / (h * h);  // O(h) accurate: enough for a step
      const double det = huu * hvv - huv * huv;
      double su, sv;
      if (huu > 0 && det > 0) {
        su = -(hvv * gu - huv * gv) / det;
        sv = -(huu * gv - huv * gu) / det;
      } else {  // not convex here: steepest descent, scaled to the grid spacing
        const double gn = std::hypot(gu, gv);
        if (gn == 0) break;
        su = -gu / gn * grid_.spacing;
        sv = -gv / gn * grid_.spacing;
      }
      const double len = std::hypot(su, sv);
      if (len > grid_.spacing) {
        su *= grid_.spacing / len;
        sv *= grid_.spacing / len;
      }
      bool moved = false;
      for (int halving = 0; halving < 30; ++halving) {
        const Vec3d next = Normalize(w + frame.s * su + frame.t * sv);
        const double fn = Value(ch, next, s);
        if (fn < f) {
          w = next;
          f = fn;
          moved = true;
          break;
        }
        su *= 0.5;
        sv *= 0.5;
      }
      if (!moved || std::hypot(su, sv) < 1e-9) break;
    }
    return {ch, w, f};
  }

  // The minimum over all channels of the refined minima at t. Candidates per channel: grid
  // points that are no higher than their neighbours and lower than the Bernstein bound
  // (spacing²/2) Σ_j s_j l_j² a_j (a minimum below zero lies within `spacing` of some grid point
  // whose value exceeds it by at most that much: the restriction to a great circle is a
  // trigonometric polynomial of degree l per band with |f''| <= l² max|f|), plus every point
  // added earlier. Negative refined minima are returned through `negative`.
  double RefinedMin(double t, std::vector<Refined>* negative) const {
    double s[kMaxBands];
    bands_.Heat(t, s);
    double overall = kInf;
    for (int ch = 0; ch < 3; ++ch) {
      double slack = 0;
      for (int j = 1; j < bands_.count; ++j)
        slack += s[j] * bands_.l[j] * bands_.l[j] * bounds_.a[ch][j];
      slack *= 0.5 * grid_.spacing * grid_.spacing;
      const size_t n = points_[ch].dirs.size();
      std::vector<double> f(n);
      for (size_t p = 0; p < n; ++p) f[p] = PointValue(ch, p, s);
      std::vector<std::pair<double, size_t>> candidates;
      for (size_t p = 0; p < n; ++p) {
        if (f[p] >= slack) continue;
        bool localMin = true;
        if (p < gridSize_) {
          for (int q : grid_.neighbors[p]) {
            if (f[q] < f[p]) {
              localMin = false;
              break;
            }
          }
        }
        if (localMin) candidates.emplace_back(f[p], p);
      }
      std::sort(candidates.begin(), candidates.end());
      if (candidates.size() > kMaxCandidates) candidates.resize(kMaxCandidates);
      for (const auto& [value, p] : candidates) {
        const Refined r = Refine(ch, points_[ch].dirs[p], s);
        overall = std::min(overall, r.value);
        if (r.value < 0) negative->push_back(r);
      }
    }
    return overall;
  }

  static constexpr size_t kMaxCandidates = 24;

  struct Points {
    std::vector<Vec3d> dirs;
    std::vector<double> values;  // bands_.count per point
  };

  int order_;
  double irradiance_[3][kMaxShCoeffCount] = {};
  const Bands& bands_;
  const ChannelBounds& bounds_;
  const Grid& grid_;
  struct ActiveSet {
    std::vector<double> v[kMaxBands];  // band j values of the points not yet proven >= 0
  };

  size_t gridSize_ = 0;
  Points points_[3];
  ActiveSet active_[3];
  std::vector<double> scratch_;
};

}  // namespace

AutoWindowResult FindAutoShWindow(int order, std::span<const Vec3d> radiance) {
  PB_CHECK(order >= 0 && order <= kMaxShOrder);
  PB_CHECK_GE(radiance.size(), static_cast<size_t>(ShCoeffCount(order)));
  const Bands bands(order);
  const ChannelBounds bounds = MakeBounds(bands, radiance);
  if (SufficientTestPasses(bands, bounds, 0)) return {ShBandWindow::Heat(0), true};
  // As t grows the irradiance tends to its constant term c: a channel with c < 0 cannot be
  // fixed, and one with c = 0 and other bands is non-negative only in the limit t = +inf.
  for (int ch = 0; ch < 3; ++ch) {
    double sum = 0;
    for (int j = 1; j < bands.count; ++j) sum += bounds.a[ch][j];
    if (bounds.c[ch] < 0) return {ShBandWindow::Heat(kInf), false};
    if (bounds.c[ch] == 0 && sum > 0) return {ShBandWindow::Heat(kInf), true};
  }
  if (order <= 3) return AutoWindowQuadratic(order, radiance, bands, bounds);
  return {ShBandWindow::Heat(NumericAutoWindow(order, radiance, bands, bounds).Solve()), true};
}

}  // namespace probebake
