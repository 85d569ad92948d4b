// Veach's power heuristic with exponent 2 (Veach 1997, ch. 9), the MIS weight of every vertex's two
// techniques: w_a = p_a^2 / (p_a^2 + p_b^2) for a sample of technique a (pdf p_a) where technique
// b would have drawn it with pdf p_b; p_a, p_b >= 0, either may be +inf (not both 0, not both
// inf: the weight is undefined there, and NaN comes back).
//
// Against the balance heuristic p_a / (p_a + p_b) it moves weight to whichever technique is the
// likelier there, so less of the estimate rides on the other's rare samples (uniform directions
// that happen to hit a small light), a discontinuous integrand that Sobol points stratify poorly;
// on a small bright light it needs several times less time to equal error
// (docs/performance-history.md).
//
// One division where p_a^2 is normal and p_a^2 + p_b^2 finite: these divisions sit on each path
// vertex's dependency chain. Where the squares underflow or overflow, the form
// 1 / (1 + (p_b / p_a)^2), which neither does (p_a = 0 gives 0, p_a = inf 1).
#pragma once

#include <algorithm>
#include <limits>

namespace probebake {

namespace detail {
// Whether p_a^2 / d, d = p_a^2 + p_b^2, keeps a double's precision: p_a^2 normal (not underflowed,
// so d is normal too; a subnormal p_b^2 beside it errs by an ulp of d) and d finite.
[[gnu::always_inline]] inline bool SquaresInRange(double squareA, double d) {
  return squareA >= std::numeric_limits<double>::min() && d <= std::numeric_limits<double>::max();
}
}  // namespace detail

// w_a, in [0, 1].
[[gnu::always_inline]] inline double PowerHeuristic(double pdfA, double pdfB) {
  const double a2 = pdfA * pdfA, d = a2 + pdfB * pdfB;
  if (detail::SquaresInRange(a2, d)) [[likely]]
    return a2 / d;
  const double r = pdfB / pdfA;
  return 1 / (1 + r * r);
}

// w_a / p_a, a sample's weight over its pdf: p_a / (p_a^2 + p_b^2), one division for the two
// (p_a = inf gives 0). Precondition: p_a > 0.
[[gnu::always_inline]] inline double PowerHeuristicOverPdf(double pdfA, double pdfB) {
  const double a2 = pdfA * pdfA, d = a2 + pdfB * pdfB;
  if (detail::SquaresInRange(a2, d)) [[likely]]
    return pdfA / d;
  // An infinite pdf on either side gives 0 (w_a / inf, or w_a = 0); the rest is scaled by the
  // larger pdf, so that the square sum lies in [1, 2].
  if (pdfA == std::numeric_limits<double>::infinity() ||
      pdfB == std::numeric_limits<double>::infinity())
    return 0;
  const double scale = std::max(pdfA, pdfB), a = pdfA / scale, b = pdfB / scale;
  return a / (a * a + b * b) / scale;
}

}  // namespace probebake
