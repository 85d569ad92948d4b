#include "probebake/sampling/distribution.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "probebake/base/check.h"
#include "probebake/sampling/warps.h"

namespace probebake {

DiscreteDistribution::DiscreteDistribution(std::span<const double> weights) {
  const size_t n = weights.size();
  PB_CHECK_GT(n, size_t{0});
  PB_CHECK_LT(n, size_t{std::numeric_limits<uint32_t>::max()});

  // Prefix sums with Neumaier's compensation: prefix[i] = sum + comp carries the rounding error of
  // every addition, so a 1e-6 weight added after a 1e9 one still counts (plain summation would
  // round it to a multiple of ulp(1e9) ~ 1.2e-7).
  size_ = static_cast<int64_t>(n);
  cdf_.resize(n + 1);
  cdf_[0] = 0;
  double sum = 0, comp = 0;
  for (size_t i = 0; i < n; ++i) {
    const double w = weights[i];
    PB_CHECK(std::isfinite(w) && w >= 0);
    const double t = sum + w;
    comp += std::abs(sum) >= std::abs(w) ? (sum - t) + w : (w - t) + sum;
    sum = t;
    cdf_[i + 1] = sum + comp;
  }
  total_ = cdf_[n];

  if (total_ == 0) {
    // All weights zero: uniform, as documented.
    for (size_t i = 0; i <= n; ++i) cdf_[i] = static_cast<double>(i) / static_cast<double>(n);
  } else {
    for (size_t i = 1; i < n; ++i) cdf_[i] /= total_;
    cdf_[n] = 1;
    // Rounding can close the interval of a tiny positive weight (or, with compensation, make an
    // entry step back by an ulp). Forward pass: zero weights get zero width, positive weights at
    // least one ulp. Backward pass: pull the top back to 1 without closing any positive interval.
    for (size_t i = 0; i < n; ++i) {
      cdf_[i + 1] = weights[i] > 0 ? std::max(cdf_[i + 1], std::nextafter(cdf_[i], 2.0)) : cdf_[i];
    }
    cdf_[n] = 1;
    for (size_t i = n - 1; i >= 1; --i) {
      const double bound = weights[i] > 0 ? std::nextafter(cdf_[i + 1], 0.0) : cdf_[i + 1];
      cdf_[i] = std::min(cdf_[i], bound);
    }
  }
  for (size_t i = 0; i < n; ++i) {
    PB_CHECK((weights[i] > 0 || total_ == 0) ? cdf_[i + 1] > cdf_[i] : cdf_[i + 1] == cdf_[i]);
  }
  PB_CHECK_EQ(cdf_[0], 0.0);
  PB_CHECK_EQ(cdf_[n], 1.0);

  // Guide table over n buckets of [0, 1): a u in bucket b is found in [guide_[b], guide_[b+1]].
  // Bucket() is monotone in its argument, which is all the search bounds rely on.
  guide_.resize(n + 1);
  size_t i = 0;
  for (size_t b = 0; b < n; ++b) {
    while (i + 1 < n && Bucket(cdf_[i + 1]) < static_cast<int64_t>(b)) ++i;
    guide_[b] = static_cast<uint32_t>(i);
  }
  guide_[n] = static_cast<uint32_t>(n - 1);
  // Above every u, so a search window that runs past cdf_[n] counts none of them.
  cdf_.resize(n + 1 + kLinearSearchMax, 2.0);
}

DiscreteSample DiscreteDistribution::Sample(double u) const {
  PB_DCHECK(u >= 0 && u < 1);
  const int64_t b = Bucket(u);
  // Smallest i in [guide_[b], guide_[b+1]] with cdf_[i + 1] > u; then cdf_[i] <= u. The CDF
  // is monotone, so i - guide_[b] counts the entries of the range at or below u: counted without
  // branches over short ranges, where a binary search's few branches mispredict half the time,
  // searched over long ones. The count runs over a fixed window from lo + 1 (4 or 8 entries): its
  // entries past hi lie beyond i + 1, above u (the padding too), and add nothing, so i is that of
  // a count to hi, without the loop exit that mispredicted with the range's length
  // (probebake_sampling_bench; the timings are in docs/performance-history.md).
  const int64_t lo = guide_[b], hi = guide_[b + 1];
  int64_t i;
  if (hi - lo <= kLinearSearchMax) {
    const double* window = cdf_.data() + lo + 1;
    int64_t below = 0;
    if (hi - lo <= kLinearSearchMax / 2) {
      for (int k = 0; k < kLinearSearchMax / 2; ++k) below += window[k] <= u;
    } else {
      for (int k = 0; k < kLinearSearchMax; ++k) below += window[k] <= u;
    }
    i = lo + below;
  } else {
    i = (std::upper_bound(cdf_.data() + lo + 1, cdf_.data() + hi + 2, u) - cdf_.data()) - 1;
  }
  PB_DCHECK(i >= 0 && i < Size() && cdf_[i] <= u && u < cdf_[i + 1]);
  const double pmf = cdf_[i + 1] - cdf_[i];
  return {i, pmf, std::min((u - cdf_[i]) / pmf, kOneMinusEpsilon)};
}

double DiscreteDistribution::Invert(int64_t index, double uRemapped) const {
  const double lo = cdf_[index], hi = cdf_[index + 1];
  PB_DCHECK(hi > lo);
  // Stay below hi so that Sample(Invert(i, v)) selects i again.
  return std::clamp(lo + uRemapped * (hi - lo), lo, std::nextafter(hi, 0.0));
}

namespace {

std::vector<DiscreteDistribution> BuildRows(std::span<const double> weights, int64_t rows,
                                            int64_t cols) {
  PB_CHECK_GE(rows, 1);
  PB_CHECK_GE(cols, 1);
  PB_CHECK_EQ(weights.size(), static_cast<size_t>(rows * cols));
  std::vector<DiscreteDistribution> result;
  result.reserve(rows);
  for (int64_t r = 0; r < rows; ++r) result.emplace_back(weights.subspan(r * cols, cols));
  return result;
}

std::vector<double> RowTotals(const std::vector<DiscreteDistribution>& rows) {
  std::vector<double> totals(rows.size());
  for (size_t r = 0; r < rows.size(); ++r) totals[r] = rows[r].Total();
  return totals;
}

}  // namespace

PiecewiseConstant2D::PiecewiseConstant2D(std::span<const double> weights, int64_t rows,
                                         int64_t cols)
    : rows_(rows),
      cols_(cols),
      conditional_(BuildRows(weights, rows, cols)),
      marginal_(RowTotals(conditional_)) {}

PiecewiseConstant2DSample PiecewiseConstant2D::Sample(Vec2d u) const {
  const DiscreteSample r = SampleRow(u.y);
  const DiscreteSample c = SampleColumn(r.index, u.x);
  return {r.index, c.index, r.pmf * c.pmf, {c.uRemapped, r.uRemapped}};
}

Vec2d PiecewiseConstant2D::Invert(int64_t row, int64_t col, Vec2d uRemapped) const {
  return {conditional_[row].Invert(col, uRemapped.x), marginal_.Invert(row, uRemapped.y)};
}

}  // namespace probebake
