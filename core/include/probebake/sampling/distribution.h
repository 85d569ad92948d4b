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
// Sampling is O(1) expected: a guide table of n buckets narrows the binary search. Each CDF
// value is stored beside the guide entry of the same index, so where the CDF is near linear the
// guide lookup and the CDF values it leads to share a cache line: a 2048 x 1024 environment map's
// table is tens of MiB, read at random, and each separate array was one more cache miss.
//
// PiecewiseConstant2D(weights, rows, cols): a row-major table (weights[row * cols + col]), for
// environment maps. u.y picks the row from the marginal (row sums), u.x the column from that row's
// conditional; the remapped u is the position inside the chosen cell: the continuous point is
// ((col + uRemapped.x) / cols, (row + uRemapped.y) / rows), whose density per unit area of
// [0,1]^2 is pmf * rows * cols. All-zero tables are uniform as above. Weights are per cell: for
// a latitude-longitude map the caller folds the cells' sin(theta) solid-angle factor into them.
// All rows live in one array (no per-row allocation to chase), each cell's entry carrying the
// caller's 3-float payload (the texel's RGB) beside its CDF value. Both classes are immutable after
// construction; const methods may be called from any thread.
#pragma once

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

namespace detail {
// cdf_i and the guide entry g_i of one index, side by side (one array of n + 1 of them).
struct CdfEntry {
  double cdf;
  uint32_t guide;  // first i with Bucket(cdf_{i+1}) >= b, for b = this entry's index
};
// The same with three floats of the caller's data about index i (PiecewiseConstant2D's payload).
struct CdfPayloadEntry {
  double cdf;
  uint32_t guide;
  float payload[3];
};
// Fills n + 1 entries from n weights as DiscreteDistribution documents; returns the compensated
// total of the weights. Entry: CdfEntry or CdfPayloadEntry.
template <typename Entry>
double BuildCdf(std::span<const double> weights, Entry* entries);
template <typename Entry>
DiscreteSample SampleCdf(const Entry* entries, int64_t n, double u);
template <typename Entry>
double InvertCdf(const Entry* entries, int64_t index, double uRemapped);
}  // namespace detail

class DiscreteDistribution {
 public:
  explicit DiscreteDistribution(std::span<const double> weights);

  int64_t Size() const { return static_cast<int64_t>(entries_.size()) - 1; }
  // Compensated sum of the weights; 0 exactly when all weights are 0.
  double Total() const { return total_; }

  DiscreteSample Sample(double u) const { return detail::SampleCdf(entries_.data(), Size(), u); }
  // Precondition: 0 <= index < Size().
  double Pmf(int64_t index) const { return entries_[index + 1].cdf - entries_[index].cdf; }
  // The u in [0, 1) that Sample maps to (index, uRemapped); uRemapped in [0, 1).
  // Precondition: Pmf(index) > 0.
  double Invert(int64_t index, double uRemapped) const {
    return detail::InvertCdf(entries_.data(), index, uRemapped);
  }

 private:
  std::vector<detail::CdfEntry> entries_;  // n + 1; entries_[0].cdf = 0, entries_[n].cdf = 1
  double total_ = 0;
};

struct PiecewiseConstant2DSample {
  int64_t row = 0, col = 0;
  double pmf = 0;   // probability of the cell (row, col), > 0
  Vec2d uRemapped;  // position inside the cell: x along columns, y along rows, in [0, 1)^2
  const float* payload = nullptr;  // the cell's 3 payload floats
};

class PiecewiseConstant2D {
 public:
  // Preconditions (checked): rows, cols >= 1, weights.size() == rows * cols, and `payload`
  // empty (zeros) or 3 floats per cell in the same order: data the caller needs with each sample
  // (an environment map's texel RGB), stored in the cell's CDF entry so that a sample or a Pmf
  // lookup finds it in the cache line it has loaded anyway.
  PiecewiseConstant2D(std::span<const double> weights, int64_t rows, int64_t cols,
                      std::span<const float> payload = {});

  int64_t Rows() const { return rows_; }
  int64_t Cols() const { return cols_; }
  // Compensated sum of all weights; 0 exactly when all are 0 (then sampling is uniform).
  double Total() const { return marginal_.Total(); }

  PiecewiseConstant2DSample Sample(Vec2d u) const;
  double Pmf(int64_t row, int64_t col) const {
    const detail::CdfPayloadEntry* e = Row(row);
    return marginal_.Pmf(row) * (e[col + 1].cdf - e[col].cdf);
  }
  // The 3 payload floats of cell (row, col).
  const float* Payload(int64_t row, int64_t col) const { return Row(row)[col].payload; }
  // The u that Sample maps to (row, col, uRemapped). Precondition: Pmf(row, col) > 0.
  Vec2d Invert(int64_t row, int64_t col, Vec2d uRemapped) const;

 private:
  const detail::CdfPayloadEntry* Row(int64_t row) const {
    return conditional_.data() + row * (cols_ + 1);
  }

  int64_t rows_, cols_;
  std::vector<detail::CdfPayloadEntry> conditional_;  // per row, cols + 1 entries
  DiscreteDistribution marginal_;                     // over rows, from the rows' totals
};

}  // namespace probebake
