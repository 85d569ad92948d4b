#include "probebake/sampling/distribution.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "probebake/base/check.h"
#include "probebake/sampling/warps.h"

namespace probebake {
namespace {

// The guide bucket of u in [0, 1) among n.
int64_t Bucket(double u, int64_t n) {
  return std::min(static_cast<int64_t>(u * static_cast<double>(n)), n - 1);
}

}  // namespace

namespace detail {

template <typename Entry>
double BuildCdf(std::span<const double> weights, Entry* entries) {
  const size_t n = weights.size();
  PB_CHECK_GT(n, size_t{0});
  PB_CHECK_LT(n, size_t{std::numeric_limits<uint32_t>::max()});
  const auto cdf = [entries](size_t i) -> double& { return entries[i].cdf; };

  // Prefix sums with Neumaier's compensation: prefix[i] = sum + comp carries the rounding error of
  // every addition, so a 1e-6 weight added after a 1e9 one still counts (plain summation would
  // round it to a multiple of ulp(1e9) ~ 1.2e-7).
  cdf(0) = 0;
  double sum = 0, comp = 0;
  for (size_t i = 0; i < n; ++i) {
    const double w = weights[i];
    PB_CHECK(std::isfinite(w) && w >= 0);
    const double t = sum + w;
    comp += std::abs(sum) >= std::abs(w) ? (sum - t) + w : (w - t) + sum;
    sum = t;
    cdf(i + 1) = sum + comp;
  }
  const double total = cdf(n);

  if (total == 0) {
    // All weights zero: uniform, as documented.
    for (size_t i = 0; i <= n; ++i) cdf(i) = static_cast<double>(i) / static_cast<double>(n);
  } else {
    for (size_t i = 1; i < n; ++i) cdf(i) /= total;
    cdf(n) = 1;
    // Rounding can close the interval of a tiny positive weight (or, with compensation, make an
    // entry step back by an ulp). Forward pass: zero weights get zero width, positive weights at
    // least one ulp. Backward pass: pull the top back to 1 without closing any positive interval.
    for (size_t i = 0; i < n; ++i) {
      cdf(i + 1) = weights[i] > 0 ? std::max(cdf(i + 1), std::nextafter(cdf(i), 2.0)) : cdf(i);
    }
    cdf(n) = 1;
    for (size_t i = n - 1; i >= 1; --i) {
      const double bound = weights[i] > 0 ? std::nextafter(cdf(i + 1), 0.0) : cdf(i + 1);
      cdf(i) = std::min(cdf(i), bound);
    }
  }
  for (size_t i = 0; i < n; ++i) {
    PB_CHECK((weights[i] > 0 || total == 0) ? cdf(i + 1) > cdf(i) : cdf(i + 1) == cdf(i));
  }
  PB_CHECK_EQ(cdf(0), 0.0);
  PB_CHECK_EQ(cdf(n), 1.0);

  // Guide table over n buckets of [0, 1): a u in bucket b is found in [guide_b, guide_{b+1}].
  // Bucket() is monotone in its argument, which is all the search bounds rely on.
  size_t i = 0;
  for (size_t b = 0; b < n; ++b) {
    while (i + 1 < n && Bucket(cdf(i + 1), static_cast<int64_t>(n)) < static_cast<int64_t>(b)) ++i;
    entries[b].guide = static_cast<uint32_t>(i);
  }
  entries[n].guide = static_cast<uint32_t>(n - 1);
  return total;
}

template <typename Entry>
DiscreteSample SampleCdf(const Entry* entries, int64_t n, double u) {
  PB_DCHECK(u >= 0 && u < 1);
  const int64_t b = Bucket(u, n);
  // Smallest i in [guide_b, guide_{b+1}] with cdf_{i+1} > u; then cdf_i <= u.
  const std::span<const Entry> range(entries + entries[b].guide + 1,
                                     entries + entries[b + 1].guide + 2);
  const int64_t i =
      std::ranges::upper_bound(range, u, {}, &Entry::cdf) - range.begin() + entries[b].guide;
  PB_DCHECK(i >= 0 && i < n && entries[i].cdf <= u && u < entries[i + 1].cdf);
  const double pmf = entries[i + 1].cdf - entries[i].cdf;
  return {i, pmf, std::min((u - entries[i].cdf) / pmf, kOneMinusEpsilon)};
}

template <typename Entry>
double InvertCdf(const Entry* entries, int64_t index, double uRemapped) {
  const double lo = entries[index].cdf, hi = entries[index + 1].cdf;
  PB_DCHECK(hi > lo);
  // Stay below hi so that Sample(Invert(i, v)) selects i again.
  return std::clamp(lo + uRemapped * (hi - lo), lo, std::nextafter(hi, 0.0));
}

template double BuildCdf(std::span<const double>, CdfEntry*);
template double BuildCdf(std::span<const double>, CdfPayloadEntry*);
template DiscreteSample SampleCdf(const CdfEntry*, int64_t, double);
template DiscreteSample SampleCdf(const CdfPayloadEntry*, int64_t, double);
template double InvertCdf(const CdfEntry*, int64_t, double);
template double InvertCdf(const CdfPayloadEntry*, int64_t, double);

}  // namespace detail

DiscreteDistribution::DiscreteDistribution(std::span<const double> weights)
    : entries_(weights.size() + 1) {
  total_ = detail::BuildCdf(weights, entries_.data());
}

namespace {

// Builds every row's entries into `conditional` (rows x (cols + 1)), payload included; returns
// the rows' totals.
std::vector<double> BuildRows(std::span<const double> weights, int64_t rows, int64_t cols,
                              std::span<const float> payload,
                              std::vector<detail::CdfPayloadEntry>& conditional) {
  PB_CHECK_GE(rows, 1);
  PB_CHECK_GE(cols, 1);
  PB_CHECK_EQ(weights.size(), static_cast<size_t>(rows * cols));
  PB_CHECK(payload.empty() || payload.size() == 3 * weights.size());
  conditional.assign(static_cast<size_t>(rows * (cols + 1)), detail::CdfPayloadEntry{});
  std::vector<double> totals(static_cast<size_t>(rows));
  for (int64_t r = 0; r < rows; ++r) {
    detail::CdfPayloadEntry* row = conditional.data() + r * (cols + 1);
    totals[r] = detail::BuildCdf(weights.subspan(r * cols, cols), row);
    if (payload.empty()) continue;
    for (int64_t c = 0; c < cols; ++c) {
      for (int k = 0; k < 3; ++k) row[c].payload[k] = payload[3 * (r * cols + c) + k];
    }
  }
  return totals;
}

}  // namespace

PiecewiseConstant2D::PiecewiseConstant2D(std::span<const double> weights, int64_t rows,
                                         int64_t cols, std::span<const float> payload)
    : rows_(rows), cols_(cols), marginal_(BuildRows(weights, rows, cols, payload, conditional_)) {}

PiecewiseConstant2DSample PiecewiseConstant2D::Sample(Vec2d u) const {
  const DiscreteSample r = marginal_.Sample(u.y);
  const detail::CdfPayloadEntry* row = Row(r.index);
  const DiscreteSample c = detail::SampleCdf(row, cols_, u.x);
  return {r.index, c.index, r.pmf * c.pmf, {c.uRemapped, r.uRemapped}, row[c.index].payload};
}

Vec2d PiecewiseConstant2D::Invert(int64_t row, int64_t col, Vec2d uRemapped) const {
  return {detail::InvertCdf(Row(row), col, uRemapped.x), marginal_.Invert(row, uRemapped.y)};
}

}  // namespace probebake
