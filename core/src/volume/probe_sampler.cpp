#include "probebake/volume/probe_sampler.h"

#include <algorithm>
#include <cmath>

#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sh_convolution.h"
#include "probebake/volume/visibility_map.h"

namespace probebake {
namespace {

// DDGI's crushing: weights below kCrush fall toward 0 as w^3 / kCrush^2. DDGI also floors
// weights at 1e-6, which makes a point hidden from every probe the plain blend of all 8: the
// whole leak again, for the points next to a thin wall whose probes are all uncertain. Here the
// floor is kMinWeight, far below any weight Chebyshev gives a probe that sees the point, so the
// probes least hidden still win.
constexpr double kCrush = 0.2;
constexpr double kMinWeight = 1e-30;

double Square(double x) {
  return x * x;
}

// A corner of the cell around the sampled point x: whether its probe holds light, where it was
// baked, its trilinear weight and how well it sees x (Chebyshev, 1 without visibility).
struct Corner {
  bool usable = false;
  int64_t probe = 0;
  Vec3d position;
  double trilinear = 0, seen = 1;
};

// The cell's connectivity at x (probe_sampler.h): connected[i] in [0, 1] for each corner, left
// at 1 where no corner weighs in.
void Connectivity(const ProbeVolume& volume, const Vec3d& x, const Corner (&corners)[8],
                  double (&connected)[8]) {
  // Each probe's moments toward each neighbour along the cell's edges, read once: the edge's
  // visibility and the wall's place along it both come from them.
  struct Toward {
    bool known = false;  // some ray went that way (and the neighbour is not at the probe)
    double mean = 0, variance = 0, length = 0;
  };
  Toward toward[8][3];
  for (int i = 0; i < 8; ++i) {
    for (int a = 0; a < 3; ++a) {
      const int j = i ^ (1 << a);
      if (!corners[i].usable || !corners[j].usable) continue;
      Toward& t = toward[i][a];
      const Vec3d along = corners[j].position - corners[i].position;
      t.length = Length(along);
      t.known = t.length > 0 &&
                VisibilityMoments(volume, corners[i].probe, along / t.length, &t.mean, &t.variance);
    }
  }
  const auto sees = [&](int i, int a) {
    const Toward& t = toward[i][a];
    return t.known ? ChebyshevVisibility(t.mean, t.variance, t.length) : 1.0;
  };
  // Each edge as open as its two probes see each other; b[i][j] the bottleneck over paths of
  // edges from corner i to corner j.
  double edge[8][3] = {}, b[8][8] = {};
  for (int i = 0; i < 8; ++i) {
    b[i][i] = 1;
    for (int a = 0; a < 3; ++a) {
      const int j = i ^ (1 << a);
      if (!corners[i].usable || !corners[j].usable) continue;
      edge[i][a] = std::min(sees(i, a), sees(j, a));
      b[i][j] = edge[i][a];
    }
  }
  for (int m = 0; m < 8; ++m)
    for (int i = 0; i < 8; ++i)
      for (int j = 0; j < 8; ++j) b[i][j] = std::max(b[i][j], std::min(b[i][m], b[m][j]));
  // claim[i]: whether x lies on probe i's side of what blocks its edges. Along each edge, x's
  // distance from the probe is compared with the first surface the probe saw that way (head-on,
  // where its moments are sharp): nearer claims x, beyond does not, within kRamp of the edge's
  // length in between; an open edge does not count, a blocked one in full.
  constexpr double kRamp = 0.01;
  double claim[8];
  for (int i = 0; i < 8; ++i) {
    claim[i] = 1;
    for (int a = 0; a < 3; ++a) {
      const Toward& t = toward[i][a];
      if (!t.known || !(t.mean > 0)) continue;
      const Vec3d along = corners[i ^ (1 << a)].position - corners[i].position;
      const double beyond = Dot(x - corners[i].position, along) / t.length - 1 / t.mean;
      const double step = std::clamp(0.5 - beyond / (kRamp * t.length), 0.0, 1.0);
      claim[i] *= 1 - (1 - edge[i][a]) * (1 - step);
    }
  }
  // A probe's support: the claims of the probes weighing in, as far as they are connected to it;
  // where no probe claims x (x inside what blocks the edges), how well they see it instead.
  double support[8] = {}, most = 0;
  for (const bool bySight : {false, true}) {
    for (int i = 0; i < 8; ++i) {
      support[i] = 0;
      for (int j = 0; j < 8; ++j)
        if (corners[j].usable && corners[j].trilinear > 0)
          support[i] += (bySight ? corners[j].seen : claim[j]) * b[i][j];
      if (corners[i].usable && corners[i].trilinear > 0) most = std::max(most, support[i]);
    }
    if (most > 0) break;
  }
  if (!(most > 0)) return;
  for (int i = 0; i < 8; ++i) {
    const double r2 = Square(support[i] / most), r4 = r2 * r2;
    connected[i] = r4 * r4;
  }
}

}  // namespace

ProbeSampler::ProbeSampler(const ProbeVolume& volume, ProbeSamplerOptions options)
    : volume_(volume), options_(options) {
  const Vec3d& s = volume.grid.spacing;
  bias_ = options.normalBias * std::min({s.x, s.y, s.z});
  bandFactor_.assign(size_t(volume.CoeffCount()), 1.0);
  if (volume.irradiance.empty()) {
    for (int l = 0; l <= volume.shOrder; ++l)
      for (int m = -l; m <= l; ++m) bandFactor_[size_t(ShIndex(l, m))] = IrradianceBandFactor(l);
  }
}

ProbeSample ProbeSampler::Sample(const Vec3d& position, const Vec3d& normal) const {
  const ProbeGrid& grid = volume_.grid;
  const int coeffs = volume_.CoeffCount();
  const Vec3d n = Normalize(normal);
  const Vec3d biased = position + n * bias_;

  int base[3];
  double alpha[3];
  for (int a = 0; a < 3; ++a) {
    const int count = grid.counts[a];
    const double f =
        std::clamp((position[a] - grid.origin[a]) / grid.spacing[a], 0.0, double(count - 1));
    base[a] = std::min(int(std::floor(f)), std::max(count - 2, 0));
    alpha[a] = count > 1 ? f - base[a] : 0.0;
  }

  Corner corners[8];
  const bool visibility = options_.visibility && !volume_.visibility.empty();
  for (int k = 0; k < 8; ++k) {
    int c[3];
    double trilinear = 1;
    for (int a = 0; a < 3; ++a) {
      const int bit = (k >> a) & 1;
      c[a] = std::min(base[a] + bit, grid.counts[a] - 1);
      trilinear *= bit ? alpha[a] : 1 - alpha[a];
    }
    const int64_t p = grid.LinearIndex(c[0], c[1], c[2]);
    const bool filled = !volume_.filled.empty() && volume_.filled[size_t(p)] > 0.5f;
    if (!volume_.active[size_t(p)] || !(volume_.validity[size_t(p)] >= 0.5f || filled)) continue;
    Corner& corner = corners[k];
    corner.usable = true;
    corner.probe = p;
    corner.trilinear = trilinear;
    corner.position = grid.Position(c[0], c[1], c[2]);
    if (!volume_.offset.empty()) {
      const float* o = &volume_.offset[3 * size_t(p)];
      corner.position += Vec3d(o[0], o[1], o[2]);
    }
    if (visibility && trilinear > 0)
      corner.seen = std::min(ProbeVisibility(volume_, p, corner.position, biased),
                             ProbeVisibility(volume_, p, corner.position, position));
  }
  double connected[8] = {1, 1, 1, 1, 1, 1, 1, 1};
  if (visibility && options_.connectivity) Connectivity(volume_, position, corners, connected);

  ProbeSample out;
  out.radianceSh.assign(size_t(coeffs), Vec3d{0, 0, 0});
  std::vector<Vec3d> blended(size_t(coeffs), Vec3d{0, 0, 0});
  double total = 0;
  for (int k = 0; k < 8; ++k) {
    const Corner& corner = corners[k];
    if (!corner.usable || corner.trilinear <= 0) continue;
    const int64_t p = corner.probe;
    double w = 1;
    if (options_.backfaceWeight) {
      const Vec3d toProbe = corner.position - position;
      const double len = Length(toProbe);
      const double cosine = len > 0 ? Dot(toProbe / len, n) : 1.0;
      const double h = (cosine + 1) / 2;
      w *= h * h + 0.2;
    }
    if (visibility) {
      w *= std::min(corner.seen, connected[k]);
      w = std::max(w, kMinWeight);
      if (w < kCrush) w *= w * w / (kCrush * kCrush);
    }
    w *= corner.trilinear;
    total += w;
    ++out.probes;
    for (int i = 0; i < coeffs; ++i) {
      const float* r = &volume_.radiance[size_t(i)][3 * size_t(p)];
      out.radianceSh[size_t(i)] += Vec3d(r[0], r[1], r[2]) * w;
      const float* e =
          volume_.irradiance.empty() ? r : &volume_.irradiance[size_t(i)][3 * size_t(p)];
      blended[size_t(i)] += Vec3d(e[0], e[1], e[2]) * (w * bandFactor_[size_t(i)]);
    }
  }
  out.irradiance = {0, 0, 0};
  if (total <= 0) return out;
  std::vector<double> y(static_cast<size_t>(coeffs));
  EvalShBasis<double>(volume_.shOrder, n, y.data());
  for (int i = 0; i < coeffs; ++i) {
    out.radianceSh[size_t(i)] = out.radianceSh[size_t(i)] / total;
    out.irradiance += blended[size_t(i)] * (y[size_t(i)] / total);
  }
  return out;
}

}  // namespace probebake
