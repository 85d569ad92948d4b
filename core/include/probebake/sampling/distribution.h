// Sampling an index in proportion to non-negative weights (light selection, environment-map
// texels), with the continuous u remapped for reuse.
//
// DiscreteDistribution(weights): index i is chosen with probability Pmf(i), the width of its
// interval [cdf_i, cdf_{i+1}) in [0, 1). Contract:
//   - Pmf(i) is exactly the probability with which Sample selects i for u uniform in [0, 1): the
//     same double is returned by Sample and Pmf, so f(i) / pmf estimators and MIS weights agree.
//   - Pmf(i) approximates w_i / sum(w) to a few ulp(1) ~ 1e-16 absolute: the CDF is built in
//     double from compensated (Neumaier) prefix sums, so small weights next to huge ones (HDR suns:
//     1e-6 beside 1e9) are not absorbed by the running sum. Relative accuracy is therefore about
//     1e-16 / Pmf(i); with 32-bit sampler values, indices with Pmf < 2^-32 are reached only by
//     rare, coarse u and should not be expected to show their frequency in a finite run.
//   - Every index with a positive weight has Pmf > 0 (its interval is widened to at least one ulp
//     if rounding would close it); every index with zero weight has Pmf == 0 and is never sampled.
//   - All weights zero: the distribution is uniform (Pmf = 1/n) and Total() == 0, so callers can
//     tell the case apart (e.g. skip a black environment).
//   - Preconditions (checked, they are bugs, not user input): n >= 1, n < 2^32, weights finite
//     and >= 0, u in [0, 1).
// Sampling is O(1) expected: a guide table of n buckets narrows the binary search.
//
// PiecewiseConstant2D(weights, rows, cols): a row-major table (weights[row * cols + col]), for
// environment maps. u.y picks the row from the marginal (row sums), u.x the column from that row's
// conditional; the remapped u is the position inside the chosen cell: the continuous point is
// ((col + uRemapped.x) / cols, (row + uRemapped.y) / rows), whose density per unit area of
// [0,1]^2 is pmf * rows * cols. All-zero tables are uniform as above. Weights are per cell: for
// a latitude-longitude map the caller folds the cells' sin(theta) solid-angle factor into them.
// Both classes are immutable after construction; const methods may be called from any thread.
#pragma once

#include <algorithm>
#include <cstdint>
#include <span>
#include <vector>

#include "probebake/math/vec3.h"

namespace probebake {

struct DiscreteSample {
  int64_t index = 0;
  double pmf = 0;        // probability of `index`, > 0
  double uRemapped = 0;  // (u - cdf_index) / pmf, uniform in [0, 1) given index
};

class DiscreteDistribution {
 public:
  explicit DiscreteDistribution(std::span<const double> weights);

  int64_t Size() const { return size_; }
  // Compensated sum of the weights; 0 exactly when all weights are 0.
  double Total() const { return total_; }

  DiscreteSample Sample(double u) const;
  // A hint, for tables too large for the cache: starts loading the guide entry and the CDF values
  // Sample(u) will read if the CDF is near linear there, and returns that guess of its index.
  int64_t Prefetch(double u) const {
    const int64_t b = Bucket(u);
    __builtin_prefetch(guide_.data() + b);
    __builtin_prefetch(cdf_.data() + b);
    return b;
  }
  // Precondition: 0 <= index < Size().
  double Pmf(int64_t index) const { return cdf_[index + 1] - cdf_[index]; }
  // The u in [0, 1) that Sample maps to (index, uRemapped); uRemapped in [0, 1).
  // Precondition: Pmf(index) > 0.
  double Invert(int64_t index, double uRemapped) const;

 private:
  // Guide ranges up to this long are searched by counting over a fixed window of half or all of
  // this many CDF entries (not a loop over the range, whose exit mispredicts), longer ones
  // binary-searched.
  static constexpr int kLinearSearchMax = 8;
  int64_t size_ = 0;             // n
  std::vector<double> cdf_;      // cdf_[0] = 0 ... cdf_[n] = 1, then kLinearSearchMax entries of 2
  std::vector<uint32_t> guide_;  // guide_[b]: first i with Bucket(cdf_[i + 1]) >= b; n + 1 entries
  double total_ = 0;

  int64_t Bucket(double u) const {
    const int64_t n = Size();
    return std::min(static_cast<int64_t>(u * static_cast<double>(n)), n - 1);
  }
};

struct PiecewiseConstant2DSample {
  int64_t row = 0, col = 0;
  double pmf = 0;   // probability of the cell (row, col), > 0
  Vec2d uRemapped;  // position inside the cell: x along columns, y along rows, in [0, 1)^2
};

class PiecewiseConstant2D {
 public:
  // Preconditions (checked): rows, cols >= 1 and weights.size() == rows * cols.
  PiecewiseConstant2D(std::span<const double> weights, int64_t rows, int64_t cols);

  int64_t Rows() const { return rows_; }
  int64_t Cols() const { return cols_; }
  // Compensated sum of all weights; 0 exactly when all are 0 (then sampling is uniform).
  double Total() const { return marginal_.Total(); }

  PiecewiseConstant2DSample Sample(Vec2d u) const;
  // Sample's two steps, for callers that may stop after the row: r = SampleRow(u.y), then
  // c = SampleColumn(r.index, u.x) give Sample(u) = {r.index, c.index, r.pmf * c.pmf,
  // {c.uRemapped, r.uRemapped}}, the same bits.
  DiscreteSample SampleRow(double uy) const { return marginal_.Sample(uy); }
  DiscreteSample SampleColumn(int64_t row, double ux) const { return conditional_[row].Sample(ux); }
  // A hint (DiscreteDistribution::Prefetch): picks the row Sample(u) picks and starts loading
  // what it will read in that row; returns the row and a guess of the column.
  void Prefetch(Vec2d u, int64_t* row, int64_t* colGuess) const {
    *row = marginal_.Sample(u.y).index;
    *colGuess = conditional_[*row].Prefetch(u.x);
  }
  double Pmf(int64_t row, int64_t col) const {
    return marginal_.Pmf(row) * conditional_[row].Pmf(col);
  }
  // The u that Sample maps to (row, col, uRemapped). Precondition: Pmf(row, col) > 0.
  Vec2d Invert(int64_t row, int64_t col, Vec2d uRemapped) const;

 private:
  int64_t rows_, cols_;
  std::vector<DiscreteDistribution> conditional_;  // one per row
  DiscreteDistribution marginal_;                  // over rows, from the rows' totals
};

}  // namespace probebake
