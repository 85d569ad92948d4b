#include "environment_guide.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <optional>

#include "environment_light.h"
#include "light_sample.h"
#include "probe_integrator.h"
#include "probebake/sampling/sampler.h"
#include "probebake/sampling/warps.h"
#include "tracer_scene.h"

namespace probebake {
namespace {

// The stream key of the guide's rays: fixed, so the guide depends on the scene alone.
constexpr uint64_t kGuideKey = 0x656e766775696465;  // "envguide"

// The inner boundaries of the phi bins of a half turn, as unit vectors (cos a, sin a),
// a = k 2 pi / kPhiBins for k = 1 .. kPhiBins / 2 - 1.
constexpr int kHalfTurnBins = EnvironmentGuide::kPhiBins / 2;
const std::array<Vec2d, kHalfTurnBins - 1> kPhiBoundaries = [] {
  std::array<Vec2d, kHalfTurnBins - 1> out;
  for (int k = 1; k < kHalfTurnBins; ++k) {
    const double a = k * 2 * std::numbers::pi / EnvironmentGuide::kPhiBins;
    out[size_t(k - 1)] = {std::cos(a), std::sin(a)};
  }
  return out;
}();

// The phi bin of (x, y): floor((phi + pi) / (2 pi / kPhiBins)), phi its angle in [-pi, pi), by
// comparisons instead of an arc tangent. In either half turn, phi >= a exactly when the cross
// product of (cos a, sin a) and (x, y) is >= 0; the lower half is turned by pi first.
int PhiBin(double x, double y) {
  const bool upper = y >= 0;
  const double u = upper ? x : -x, v = upper ? y : -y;
  int count = 0;
  for (const Vec2d& c : kPhiBoundaries) count += c.x * v - c.y * u >= 0;
  return (upper ? kHalfTurnBins : 0) + count;
}

// One arrived training ray: its bin, f / q (q the density it was drawn from), q, and the
// environment's own density p_e of its direction.
struct Arrived {
  int bin;
  double weight, q, pdf;
};

// Rows of bins (bands of z) within one of row z: a ray of row z counts in 3 x that many bins once
// spread.
int RowsAround(int z) {
  return 1 + (z > 0) + (z < EnvironmentGuide::kZBins - 1);
}

// The histogram with kNeighbourWeight of each bin's weight added to each of its 8 neighbours in
// (z, phi), phi wrapping round.
std::vector<double> Spread(const std::vector<double>& histogram) {
  constexpr int kZ = EnvironmentGuide::kZBins, kPhi = EnvironmentGuide::kPhiBins;
  std::vector<double> out(histogram.size(), 0.0);
  for (int z = 0; z < kZ; ++z)
    for (int phi = 0; phi < kPhi; ++phi) {
      const double h = histogram[size_t(z * kPhi + phi)];
      if (!(h > 0)) continue;
      for (int dz = std::max(0, z - 1); dz <= std::min(kZ - 1, z + 1); ++dz)
        for (int dp = -1; dp <= 1; ++dp)
          out[size_t(dz * kPhi + (phi + dp + kPhi) % kPhi)] +=
              dz == z && dp == 0 ? h : EnvironmentGuide::kNeighbourWeight * h;
    }
  return out;
}

// The alpha of kAlphas whose estimated second moment of f / p is least, over a cell's arrived
// rays whose weights, spread, are `spread` (total `sum`): E_q[f^2 / (q p_alpha)], p_alpha =
// alpha p_g + (1 - alpha) p_e, each ray scored against the guide without it (its weight taken
// out of its bin and of the total). Ties go to the smaller alpha.
double ChooseAlpha(const std::vector<Arrived>& arrived, const std::vector<double>& spread,
                   double sum) {
  constexpr double kBinSolidAngle = 4 * std::numbers::pi / EnvironmentGuide::kBins;
  constexpr size_t kCandidates = EnvironmentGuide::kAlphas.size();
  double moment[kCandidates] = {};
  for (const Arrived& r : arrived) {
    const int rows = RowsAround(r.bin / EnvironmentGuide::kPhiBins);
    const double rest = sum - r.weight * (1 + EnvironmentGuide::kNeighbourWeight * (3 * rows - 1));
    const double guided =
        rest > 0 ? std::max(0.0, spread[size_t(r.bin)] - r.weight) / (rest * kBinSolidAngle) : 0.0;
    // f^2 / (q p_alpha) with f = weight x q.
    for (size_t k = 0; k < kCandidates; ++k) {
      const double alpha = EnvironmentGuide::kAlphas[k];
      moment[k] += r.weight * r.weight * r.q / (alpha * guided + (1 - alpha) * r.pdf);
    }
  }
  size_t best = 0;
  for (size_t k = 1; k < kCandidates; ++k)
    if (moment[k] < moment[best]) best = k;
  return EnvironmentGuide::kAlphas[best];
}

// A direction uniform in solid angle in bin `bin`: z and phi uniform over its ranges.
Vec3d DirectionInBin(int bin, double uz, double uPhi) {
  const int zBin = bin / EnvironmentGuide::kPhiBins;
  const int phiBin = bin % EnvironmentGuide::kPhiBins;
  const double z = std::clamp(-1 + (zBin + uz) * (2.0 / EnvironmentGuide::kZBins), -1.0, 1.0);
  const double phi =
      -std::numbers::pi + (phiBin + uPhi) * (2 * std::numbers::pi / EnvironmentGuide::kPhiBins);
  const double r = std::sqrt(std::max(0.0, 1 - z * z));
  return {r * std::cos(phi), r * std::sin(phi), z};
}

// What one cell's rays found: the arrived ones, their weights per bin and in all, and the
// environment's light they would have brought unoccluded (f / q had nothing blocked them).
struct CellRays {
  std::vector<Arrived> arrived;
  std::vector<double> histogram = std::vector<double>(EnvironmentGuide::kBins);
  double sum = 0, emitted = 0;
  int64_t traced = 0;
  bool open = false;  // most of the environment's light arrives: not guided
};

// The weights per bin of the rays of the cells around `cell` (itself and its neighbours, 3 x 3 x 3
// at most) into *histogram, and when `arrived` is not null those rays; returns their sum.
double Around(const CellGrid& grid, const std::vector<CellRays>& cells, int64_t cell,
              std::vector<double>* histogram, std::vector<Arrived>* arrived = nullptr) {
  std::fill(histogram->begin(), histogram->end(), 0.0);
  if (arrived) arrived->clear();
  const int64_t nx = grid.dims[0], ny = grid.dims[1], nz = grid.dims[2];
  const int64_t ix = cell % nx, iy = cell / nx % ny, iz = cell / (nx * ny);
  double sum = 0;
  for (int64_t z = std::max<int64_t>(0, iz - 1); z <= std::min(nz - 1, iz + 1); ++z)
    for (int64_t y = std::max<int64_t>(0, iy - 1); y <= std::min(ny - 1, iy + 1); ++y)
      for (int64_t x = std::max<int64_t>(0, ix - 1); x <= std::min(nx - 1, ix + 1); ++x) {
        const CellRays& n = cells[size_t((z * ny + y) * nx + x)];
        for (int b = 0; b < EnvironmentGuide::kBins; ++b)
          (*histogram)[size_t(b)] += n.histogram[size_t(b)];
        sum += n.sum;
        if (arrived) arrived->insert(arrived->end(), n.arrived.begin(), n.arrived.end());
      }
  return sum;
}

// Traces rays [begin, end) of cell `cell` into *t: sampled as the environment samples, or with
// `first` half from it (the first pass's histogram around the cell). Stops, marking the cell open,
// at ray kPilotRaysPerCell when kOpenFraction of the light has arrived.
void TraceCell(const CellGrid& grid, int64_t cell, int begin, int end,
               const DiscreteDistribution* first, const EnvironmentGuide::Trace& trace,
               CellRays* t) {
  IndependentSampler sampler(kGuideKey, uint64_t(cell));
  for (int r = begin; r < end; ++r) {
    if (r == EnvironmentGuide::kPilotRaysPerCell &&
        t->sum >= EnvironmentGuide::kOpenFraction * t->emitted) {
      t->open = true;
      return;
    }
    sampler.StartSample(uint64_t(r));
    const Vec2d a = sampler.Get2D();
    const Vec2d b = sampler.Get2D();
    const Vec2d c = sampler.Get2D();
    const Vec3d x = grid.Point(cell, {a.x, a.y, b.x});
    EnvironmentGuide::Ray ray;
    double q;
    if (!first) {
      ray = trace(x, nullptr, c);
      q = ray.pdf;
      if (!(q > 0)) continue;
    } else {
      // Half from the first pass's histogram, half from the environment.
      if (c.x < 0.5) {
        const DiscreteSample bin = first->Sample(std::min(2 * c.x, kOneMinusEpsilon));
        const Vec3d wi = DirectionInBin(int(bin.index), bin.uRemapped, c.y);
        ray = trace(x, &wi, c);
      } else {
        ray = trace(x, nullptr, {std::min(2 * c.x - 1, kOneMinusEpsilon), c.y});
        if (!(ray.pdf > 0)) continue;
      }
      q = 0.5 * first->Pmf(EnvironmentGuide::Bin(ray.wi)) *
              EnvironmentGuide::kInverseBinSolidAngle +
          0.5 * ray.pdf;
    }
    ++t->traced;
    t->emitted += ray.emitted / q;
    if (!(ray.arrived > 0)) continue;
    const Arrived hit{EnvironmentGuide::Bin(ray.wi), ray.arrived / q, q, ray.pdf};
    t->arrived.push_back(hit);
    t->histogram[size_t(hit.bin)] += hit.weight;
    t->sum += hit.weight;
  }
}

// Cell `cell`'s guide: its alpha (0: none) and, when positive, its bins' weights in *histogram:
// from its own rays, or when fewer than kMinArrived of them arrived, those of the cells around it.
double CellGuide(const CellGrid& grid, const std::vector<CellRays>& cells, int64_t cell,
                 std::vector<double>* histogram) {
  const CellRays& own = cells[size_t(cell)];
  if (own.open) return 0;
  std::vector<Arrived> around;
  const std::vector<Arrived>* arrived = &own.arrived;
  if (own.arrived.size() >= size_t(EnvironmentGuide::kMinArrived)) {
    *histogram = own.histogram;
  } else {
    histogram->resize(EnvironmentGuide::kBins);
    Around(grid, cells, cell, histogram, &around);
    arrived = &around;
  }
  if (arrived->size() < size_t(EnvironmentGuide::kMinArrived)) return 0;
  *histogram = Spread(*histogram);
  double sum = 0;
  for (double h : *histogram) sum += h;
  return ChooseAlpha(*arrived, *histogram, sum);
}

}  // namespace

int EnvironmentGuide::Bin(const Vec3d& wi) {
  const int z = std::clamp(int((wi.z + 1) * (0.5 * kZBins)), 0, kZBins - 1);
  return z * kPhiBins + PhiBin(wi.x, wi.y);
}

Vec3d EnvironmentGuide::Sample(int32_t cell, const Vec2d& u) const {
  const DiscreteSample bin = bins_[size_t(cell)].Sample(u.x);
  return DirectionInBin(int(bin.index), bin.uRemapped, u.y);
}

int64_t EnvironmentGuide::GuidedCells() const {
  return std::count_if(alpha_.begin(), alpha_.end(), [](float a) { return a > 0; });
}

EnvironmentGuide EnvironmentGuide::Build(const Vec3d& lo, const Vec3d& hi, const Trace& trace) {
  EnvironmentGuide g;
  g.grid_ = CellGrid::Over(lo, hi, kRayBudget / kRaysPerCell);
  const CellGrid& grid = g.grid_;
  if (grid.Empty()) return g;
  const int64_t cellCount = grid.Count();

  // The pilot: where the environment reaches most of the box, there is nothing to guide.
  {
    IndependentSampler sampler(kGuideKey, uint64_t(cellCount));
    double emitted = 0, arrived = 0;
    for (int r = 0; r < kPilotRays; ++r) {
      sampler.StartSample(uint64_t(r));
      const Vec2d a = sampler.Get2D();
      const Vec2d b = sampler.Get2D();
      const Vec3d x = grid.Point(0, {a.x * grid.dims[0], a.y * grid.dims[1], b.x * grid.dims[2]});
      const Ray ray = trace(x, nullptr, {b.y, sampler.Get1D()});
      if (!(ray.pdf > 0)) continue;
      ++g.rays_;
      emitted += ray.emitted / ray.pdf;
      arrived += ray.arrived / ray.pdf;
    }
    g.openFraction_ = emitted > 0 ? arrived / emitted : 0;
    if (arrived >= kOpenFraction * emitted) return g;
  }

  // Two passes over the cells: the environment's own samples, then half of the rest drawn from
  // what the first pass found around each cell.
  std::vector<CellRays> cells(static_cast<size_t>(cellCount));
  std::vector<std::optional<DiscreteDistribution>> first(static_cast<size_t>(cellCount));
  const auto forEachCell = [&](auto&& f) {
    tbb::parallel_for(tbb::blocked_range<int64_t>(0, cellCount, 4),
                      [&](const tbb::blocked_range<int64_t>& range) {
                        for (int64_t c = range.begin(); c != range.end(); ++c) f(c);
                      });
  };
  forEachCell([&](int64_t c) {
    TraceCell(grid, c, 0, kFirstStageRays, nullptr, trace, &cells[size_t(c)]);
  });
  std::vector<double> around(kBins);
  for (int64_t c = 0; c < cellCount; ++c) {
    if (cells[size_t(c)].open) continue;
    if (Around(grid, cells, c, &around) > 0) first[size_t(c)].emplace(around);
  }
  forEachCell([&](int64_t c) {
    if (cells[size_t(c)].open) return;
    TraceCell(grid, c, kFirstStageRays, kRaysPerCell,
              first[size_t(c)] ? &*first[size_t(c)] : nullptr, trace, &cells[size_t(c)]);
  });

  g.alpha_.assign(size_t(cellCount), 0.0f);
  const double one = 1;
  g.bins_.assign(size_t(cellCount), DiscreteDistribution(std::span<const double>(&one, 1)));
  forEachCell([&](int64_t c) {
    std::vector<double> histogram;
    const double alpha = CellGuide(grid, cells, c, &histogram);
    if (!(alpha > 0)) return;
    g.alpha_[size_t(c)] = float(alpha);
    g.bins_[size_t(c)] = DiscreteDistribution(histogram);
  });
  for (const CellRays& cell : cells) g.rays_ += cell.traced;
  return g;
}

EnvironmentGuide EnvironmentGuide::Build(const TracerScene& tracer,
                                         const EnvironmentLight& environment,
                                         const ProbeIntegrator& integrator) {
  return Build(
      tracer.boundsMin(), tracer.boundsMax(), [&](const Vec3d& x, const Vec3d* wi, const Vec2d& u) {
        Ray ray;
        LightSample s;
        if (wi) {
          s.wi = *wi;
          s.radiance = environment.RadianceAndPdf(s.wi, nullptr, &s.pdf);
        } else {
          s.radiance = environment.Sample(u, nullptr, &s.wi, &s.pdf);
        }
        ray.wi = s.wi;
        ray.pdf = s.pdf;
        if (!(MaxComponent(s.radiance) > 0)) return ray;
        s.distance = std::numeric_limits<double>::infinity();
        TraceCounters unused;  // Build counts the rays
        ray.emitted = Luminance(s.radiance);
        ray.arrived = Luminance(s.radiance * integrator.ShadowTransmittance(Vec3f(x), s, &unused));
        return ray;
      });
}

}  // namespace probebake
