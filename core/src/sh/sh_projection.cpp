#include "probebake/sh/sh_projection.h"

#include <algorithm>

namespace probebake {
namespace {

void CheckOrderAndSize(int order, size_t size) {
  PB_CHECK(order >= 0 && order <= kMaxShOrder);
  PB_CHECK_GE(size, static_cast<size_t>(ShCoeffCount(order)));
}

}  // namespace

double ShReconstruct(int order, std::span<const double> coeffs, const Vec3d& dir) {
  CheckOrderAndSize(order, coeffs.size());
  double y[kMaxShCoeffCount];
  EvalShBasis(order, dir, y);
  double sum = 0;
  for (int i = 0; i < ShCoeffCount(order); ++i) sum += coeffs[i] * y[i];
  return sum;
}

Vec3d ShReconstructRgb(int order, std::span<const Vec3d> coeffs, const Vec3d& dir) {
  CheckOrderAndSize(order, coeffs.size());
  double y[kMaxShCoeffCount];
  EvalShBasis(order, dir, y);
  Vec3d sum;
  for (int i = 0; i < ShCoeffCount(order); ++i) sum += coeffs[i] * y[i];
  return sum;
}

double ShDot(int order, std::span<const double> f, std::span<const double> g) {
  CheckOrderAndSize(order, f.size());
  CheckOrderAndSize(order, g.size());
  double sum = 0;
  for (int i = 0; i < ShCoeffCount(order); ++i) sum += f[i] * g[i];
  return sum;
}

Vec3d ShDotRgb(int order, std::span<const Vec3d> f, std::span<const Vec3d> g) {
  CheckOrderAndSize(order, f.size());
  CheckOrderAndSize(order, g.size());
  Vec3d sum;
  for (int i = 0; i < ShCoeffCount(order); ++i) sum += f[i] * g[i];
  return sum;
}

Vec3d ShDotRgb(int order, std::span<const Vec3d> f, std::span<const double> g) {
  CheckOrderAndSize(order, f.size());
  CheckOrderAndSize(order, g.size());
  Vec3d sum;
  for (int i = 0; i < ShCoeffCount(order); ++i) sum += f[i] * g[i];
  return sum;
}

template <typename Value>
ShAccumulatorT<Value>::ShAccumulatorT(int order) : order_(order), coeffs_(ShCoeffCount(order)) {
  PB_CHECK(order >= 0 && order <= kMaxShOrder);
  const size_t n = static_cast<size_t>(coeffs_) * kChannels;
  block_.assign(n, 0.0);
  hi_.assign(n, 0.0);
  lo_.assign(n, 0.0);
}

template <typename Value>
void ShAccumulatorT<Value>::Add(const Vec3d& dir, const Value& x) {
  double y[kMaxShCoeffCount];
  EvalShBasis(order_, dir, y);
  AddBasis(std::span<const double>(y, coeffs_), x);
}

// hi + lo += x with hi + x split exactly into a rounded sum and its error (Knuth's TwoSum,
// valid for any magnitudes; needs strict IEEE evaluation, which the build guarantees).
template <typename Value>
void ShAccumulatorT<Value>::TwoSumInto(double x, double& hi, double& lo) {
  const double s = hi + x;
  const double bp = s - hi;
  const double err = (hi - (s - bp)) + (x - bp);
  hi = s;
  lo += err;
}

template <typename Value>
void ShAccumulatorT<Value>::FoldBlock() {
  for (size_t k = 0; k < block_.size(); ++k) {
    TwoSumInto(block_[k], hi_[k], lo_[k]);
    block_[k] = 0;
  }
}

template <typename Value>
void ShAccumulatorT<Value>::Merge(const ShAccumulatorT& other) {
  PB_CHECK_EQ(order_, other.order_);
  for (size_t k = 0; k < block_.size(); ++k) {
    TwoSumInto(block_[k], hi_[k], lo_[k]);
    block_[k] = 0;
    TwoSumInto(other.block_[k], hi_[k], lo_[k]);
    TwoSumInto(other.hi_[k], hi_[k], lo_[k]);
    TwoSumInto(other.lo_[k], hi_[k], lo_[k]);
  }
  // The open block is empty now; the next fold comes within kBlockSize samples, so no block
  // ever holds more than kBlockSize of them and the error bound stands.
  count_ += other.count_;
}

template <typename Value>
void ShAccumulatorT<Value>::Sum(std::span<Value> out, double scale) const {
  PB_CHECK_GE(out.size(), static_cast<size_t>(coeffs_));
  for (int i = 0; i < coeffs_; ++i) {
    double v[kChannels];
    for (int c = 0; c < kChannels; ++c) {
      const size_t k = static_cast<size_t>(c) * coeffs_ + i;
      double hi = hi_[k], lo = lo_[k];
      TwoSumInto(block_[k], hi, lo);
      v[c] = scale * (hi + lo);
    }
    if constexpr (kChannels == 1) {
      out[i] = v[0];
    } else {
      out[i] = Vec3d{v[0], v[1], v[2]};
    }
  }
}

template <typename Value>
void ShAccumulatorT<Value>::Reset() {
  count_ = 0;
  std::fill(block_.begin(), block_.end(), 0.0);
  std::fill(hi_.begin(), hi_.end(), 0.0);
  std::fill(lo_.begin(), lo_.end(), 0.0);
}

template class ShAccumulatorT<double>;
template class ShAccumulatorT<Vec3d>;

}  // namespace probebake
