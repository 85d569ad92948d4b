// Square root usable in constant expressions, for the SH modules' compile-time tables.
#pragma once

namespace probebake::sh_internal {

// Newton's iteration from above decreases monotonically to within one ulp of sqrt(a); the loop
// stops when it no longer decreases. a <= 0 gives 0.
constexpr double ConstexprSqrt(double a) {
  if (a <= 0) return 0;
  double x = a > 1 ? a : 1;
  for (;;) {
    const double next = 0.5 * (x + a / x);
    if (next >= x) return x;
    x = next;
  }
}

}  // namespace probebake::sh_internal
