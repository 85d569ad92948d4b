// Light traced from directional lights (the sun) and joined to the probes' paths: two techniques
// beside the probe paths' own, all weighted by the power heuristic.
//
// Why: a sun shining through a window lights a patch of floor, and most of what a room's probes
// receive from the sun comes from that patch, seen directly or through later bounces. A probe's
// paths find the patch by chance (a probe direction or a bounce that happens to land on it), and
// their next-event samples of the sun are wasted wherever it is hidden. Paths traced from the sun
// find the sunlit points by construction.
//
// Light paths. Per directional light and per batch b, n_L of them, rho = n_L / n_b per probe
// sample (n_b the batch's probe samples; below): a direction w_s toward the light
// (uniform in the sun's cone; the direction itself for a delta light) and a point on a disk of
// area A perpendicular to it that covers the scene's bounds, traced into the scene. The first
// hit y_1 is kept only if it lies in the scene's bounds on a side that faces into them (a roof's
// or an outer wall's outside is dropped); the path then bounces on as the probes' paths do
// (cosine-weighted, Russian roulette), to at most maxDepth vertices. Its throughput starts at
// Phi = the light's radiance x its solid angle Omega x A and takes each albedo (and the roulette's
// survival) on.
//
// The five ways to make a path p <- x_1 <- ... <- x_k <- light, k <= maxDepth, with densities
// in a common measure (interior cosine-sampled bounces have equal factors on every side and
// cancel; dividing by the bounce density g = cos_{k-1} cos_k / (pi r^2) from x_{k-1} to x_k):
//   N  the probe path's next-event sample of the light at x_k: p_N (the light's choice at x_k
//      times its solid-angle pdf; the choice alone for a delta light);
//   B  its continuation from x_k hitting the sun's cone: p_B = cos_k / pi (none for a delta);
//   L  a light path's m-th vertex (y_m = x_1, m = k) joined to the probe by a shadow ray:
//      rho a / d_1, a = cos_k(w_s) / (Omega A), d_1 = cos_1 / (4 pi r_1^2) the density at x_1
//      of the probe's uniform direction;
//   C  a probe path's surface vertex x_{k-1} (k >= 2) joined by a shadow ray to the first hit
//      x_k = y_1 of one light path of its batch, picked uniformly among the K kept ones:
//      a n_L / (K g), a's density made K / n_L times denser by picking among kept hits only.
// Each technique's sample counts with its density squared over the sum of the squares, so every
// path is counted once; a technique that cannot make a path (x_k not kept, k = 1 for C) has
// density zero there. L adds to coefficient i, for w = (x_1 - p) / r,
//   w_L Phi prod_{j<m} albedo_j (albedo_m / pi) cos_m / r^2 Y_i(w) / rho
// per light path (a probe's sum is divided by n_b), and C adds to the path's radiance at x_{k-1}
//   w_C beta (albedo_{k-1} / pi) (Phi albedo_k / pi) cos_{k-1} cos_k / r^2 K / n_L.
//
// n_L: a pilot of kPilotPaths paths per light finds the fraction f of first hits kept; n_L =
// lambda n_b with lambda = ceil(kKeptPerSample / f), at most kMaxLambda, so that a probe joins
// about kKeptPerSample light paths per sample of its own whatever the share of the sun's rays that
// enter; but no more than kMaxKeptPaths / (f x batches), so that a bake of millions of samples per
// probe joins fewer per sample (rho < lambda) rather than hold and trace millions of paths. Only
// the kMaxSources brightest directional lights are traced.
//
// The light's share of next-event samples at surfaces is scaled by min(1, kSurfaceShare f)
// (LightSet::ScaleAtSurfaces; at the probe it is left alone). Where little of the sun's beam
// reaches the scene's inside (a window: f of a few percent), C and L carry the sun's light
// almost everywhere and N's samples, weighted near zero, would be wasted; they go to the other
// lights instead. Where the sun lights most of the scene (a courtyard), N keeps its share. The
// constant is measured (docs/performance-history.md).
//
// Deterministic: every light path's numbers come from its own scrambled Sobol stream (seed,
// light, batch), C's choices from a hash of the probe path's sample, and the kept region from the
// scene's bounds alone (never the probe grid, which a shard cuts), so sharding, threads and the
// server give the same bits. Built once per bake for every batch a probe can trace; read-only
// afterwards. Not built with a medium, with estimators other than NEE_MIS, or without a
// directional light whose pilot keeps a first hit.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "light_set.h"
#include "probebake/bake/ray_observer.h"
#include "probebake/math/frame.h"
#include "probebake/math/vec3.h"
#include "probebake/scene/scene.h"
#include "tracer_scene.h"

namespace probebake {

struct TraceCounters;

class DistantLightPaths {
 public:
  // The light paths of batches b < batchSizes.size() (batch b of batchSizes[b] probe samples) of
  // every directional light of *lights (a set built from `scene`), whose share of next-event
  // samples at surfaces it scales as above; or null (and *lights unchanged) when no light is
  // traced. `scene`, `tracer` and *lights outlive the result.
  static std::unique_ptr<DistantLightPaths> Build(const Scene& scene, const TracerScene& tracer,
                                                  LightSet* lights, const BakeSettings& settings,
                                                  std::span<const int64_t> batchSizes);

  // Whether `light` is traced (the others' weights are left alone).
  bool Traces(uint32_t light) const {
    return light < sourceOfLight_.size() && sourceOfLight_[light] >= 0;
  }

  // The sum of the squared densities of L and C above, divided by g and in the units of
  // `light`'s next-event pdf, for the path of batch `batch` whose vertex x (shading normal n,
  // unit, toward the side the path arrived from) receives the light from toLight, whose first
  // vertex has density d1, and whose vertex before x is xPrev (normal nPrev; null when x is the
  // first). Zero when the light is not traced or neither technique can make the path.
  double OtherDensitySquared(uint32_t light, const Vec3d& x, const Vec3d& n, const Vec3d& toLight,
                             double d1, const Vec3d* xPrev, const Vec3d* nPrev,
                             uint32_t batch) const;

  // C at a probe path's surface vertex x (shading normal n toward the side the path arrived
  // from, ray origin spawn) of batch `batch`, whose first vertex has density d1: one kept first
  // hit per traced light, picked by u in [0, 1). Returns what x receives, weighted, per unit of
  // (albedo at x / pi) x the path's throughput. One shadow ray per light that can light x, told
  // to `observer` when not null, played by `roulette` first when its threshold is set (one
  // number u for the joins to every light): roulette on a join's shadow ray (shadow_roulette.h),
  // whose value times `scale` (the path's throughput x albedo / pi, largest channel) is what it
  // adds to the path's radiance.
  struct Roulette {
    double scale = 0, threshold = 0, u = 0;
  };
  Vec3d ConnectVertex(const Vec3d& x, const Vec3d& n, const Vec3f& spawn, uint32_t batch, double u,
                      double d1, const Roulette& roulette, TraceCounters* counters,
                      RayObserver* observer) const;

  // L: adds to `sum` ((order+1)^2 x 3 doubles) batch `batch`'s light paths joined to the probe at
  // p, its shadow rays told to `observer` when not null. Precondition: count is the
  // batchSizes[batch] of Build. threshold > 0: each join whose value is below what a probe sample
  // of radiance `threshold` adds is played by roulette (shadow_roulette.h) with a number from
  // Hash(key, its light's index among the traced ones, its index among that light's vertices).
  struct ProbeRoulette {
    double threshold = 0;
    uint64_t key = 0;
  };
  void ConnectProbe(const Vec3d& p, uint32_t batch, int64_t count, int order,
                    const ProbeRoulette& roulette, std::span<double> sum, TraceCounters* counters,
                    RayObserver* observer) const;

  // For logs and tests: light paths per probe sample of `light` (lambda; 0 when not traced), the
  // pilot's fraction of first hits kept, and the vertices kept over all batches.
  int Lambda(uint32_t light) const;
  double KeptFraction(uint32_t light) const;
  int64_t VertexCount() const;
  // Light paths traced and kept (first hit kept, with a vertex) over all batches of `light`.
  int64_t PathCount(uint32_t light) const;
  int64_t KeptCount(uint32_t light) const;

  static constexpr int kPilotPaths = 4096;
  static constexpr double kKeptPerSample = 0.5;
  static constexpr int kMaxLambda = 64;
  // Kept light paths of one light over all batches, about, at most (n_L is capped per batch):
  // a few hundred bytes each, so at most ~100 MB a light.
  static constexpr int64_t kMaxKeptPaths = int64_t{1} << 18;
  // Directional lights traced, the brightest (irradiance luminance).
  static constexpr size_t kMaxSources = 8;
  // 4 until baker version 22; with the environment guide and the visibility floor of 1/32, 2 cut
  // the demo room's error by 2% (1 and below by 3%, but would scale a sun lighting half of a
  // courtyard, where any scaling costs; docs/performance-history.md).
  static constexpr double kSurfaceShare = 2;

 private:
  struct Source {
    uint32_t light = 0;
    Vec3d toLight;  // unit, the cone's axis
    Framed frame;   // about toLight
    double cosOuter = 1;
    bool delta = true;
    double conePdf = 1;  // 1 / Omega (1 for a delta light)
    Vec3d power;         // Phi: radiance x Omega x A (irradiance x A for a delta light)
    int lambda = 0;
    double keptFraction = 0;  // of the pilot's first hits
  };
  // A kept vertex: where it is, its shading normal (toward the side the light arrived from) and
  // ray origin, what it sends toward a point per cos / r^2 (Phi x the albedos before it x its
  // albedo / pi), and its path's terms: a, p_N and p_B at the first hit, and c = a / g_12 (g_12
  // the density of the bounce from the first hit to the second; 0 on the first hit itself).
  struct Vertex {
    Vec3d x, n;
    Vec3f spawn;
    Vec3d weight;
    double a = 0, pN = 0, pB = 0, c = 0;
  };

  DistantLightPaths(const Scene& scene, const TracerScene& tracer, const LightSet& lights,
                    const BakeSettings& settings);
  // n_L / n_b of (source, batch): light paths per probe sample.
  double Ratio(size_t source, uint32_t batch) const;
  // n_L / K of (source, batch): how much denser the kept first hits are than the light paths.
  double Boost(size_t source, uint32_t batch) const;
  // Whether a first hit at x (normal n toward the light) is kept.
  bool Keeps(const Vec3d& x, const Vec3d& n) const;
  // Traces path `index` of `stream` from light s: whether its first hit is kept, and then, when
  // `out` is not null, its kept vertices appended to *out.
  bool TracePath(const Source& s, uint64_t stream, uint64_t index, std::vector<Vertex>* out) const;

  const Scene& scene_;
  const TracerScene& tracer_;
  const LightSet& lights_;
  const BakeSettings& settings_;
  Vec3d center_, half_;  // the kept region: the scene's bounds
  double radius_ = 0;    // of the disk: the bounds' half diagonal
  double diskArea_ = 0;
  double facingSlack_ = 0;
  std::vector<Source> sources_;
  std::vector<int> sourceOfLight_;          // by light index: into sources_, or -1
  std::vector<std::vector<Vertex>> paths_;  // [source * batches + batch]
  std::vector<int64_t> pathCounts_;         // n_L, likewise
  // The first hits among them, by index into paths_[...], in path order.
  std::vector<std::vector<uint32_t>> firsts_;
  std::vector<int64_t> batchSizes_;
};

}  // namespace probebake
