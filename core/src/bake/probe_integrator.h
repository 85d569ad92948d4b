// The per-probe estimator: SH projection of incoming radiance by path tracing.
//
// For a probe at p the target is c_i = ∫ L(p, ω) Y_i(ω) dω per RGB channel. Each sample combines
// two techniques at the probe, as at every later path vertex:
//   - direction sampling: ω uniform on the sphere (the probe's "BSDF" is the SH measurement, its
//     pdf 1/4π), a path traced from p gives L(p, ω); contribution L Y(ω) / pdf;
//   - light sampling (NEE): a light chosen and sampled at p, one shadow ray; contribution
//     Le Y(ω_l) / pdf_l.
// With Estimator::kNeeMis both are weighted by the power heuristic w_a = p_a^2 / (p_a^2 + p_b^2)
// (one sample per technique), so emission found by either is counted exactly once. Along the
// path: Lambertian vertices with cosine-weighted continuation, NEE with the same MIS, Russian
// roulette after rrMinDepth bounces (survival = max throughput channel, capped at 1), and at most
// maxDepth scattering vertices (light reflected more than maxDepth times is not counted; emitters
// seen directly are always counted). Delta lights at the probe are not sampled here: the bake
// projects them exactly (bake.cpp).
//
// With a medium (medium.h), every ray segment may end in a scattering event inside it: such a
// vertex counts toward maxDepth like a surface, is shaded by the Henyey-Greenstein phase function
// (light sampling and phase sampling combined by the same MIS), and shadow rays and escaping rays
// carry the medium's transmittance. Scenes without a medium run a separate instantiation that has
// none of this.
//
// Random dimensions per sample, always consumed in this order so each dimension keeps one meaning
// across samples (what quasi-Monte Carlo stratification needs): probe direction (2D), light
// choice (1D), light point (2D); then per path segment, with a medium only: channel (1D) and
// distance (1D); then per scattering vertex: light choice (1D), light point (2D), continuation
// (2D), roulette (1D). Without a medium a vertex's numbers are drawn before the ray that finds it
// is traced (LightSet::Prefetch), and left unused when there is no vertex: the order is the same.
//
// With the Sobol sampler the probe's two 2D sets are replaced (and left unused, so that the others
// keep their places): batch b of n samples takes a spherical Fibonacci set of 2n points turned by
// a uniformly random rotation of its own (spherical_fibonacci.h); sample j's direction is point
// 2j, and its light point is point 2j + 1 mapped to the square by the inverse of the uniform
// sphere map. The probe's integrand is a function on the sphere, smooth wherever the light is
// (a sky, a large emitter, indirect light), and such a set integrates it far better than a 2D
// net warped onto the sphere: under a uniform sky 256 samples in 4 batches give each coefficient
// to order 8 within a few 1e-3 of c0, where scrambled Sobol nets left errors of several percent.
// The two techniques take alternate points of one set, so where they sample alike (a uniform sky:
// both uniform over the sphere, each weighted 1/2 by MIS) their sum is the 2n-point rule. A
// light sampled by its own warp (an environment map by its cells, an area light by solid angle)
// receives the points of a well-spread set, not of a net in its own square, and gains less. Each
// point is uniform over the sphere, so every batch is unbiased, and independent rotations keep
// the batches independent: their spread is an honest standard error (probe_finish.h).
//
// Sky transfer (settings.skyTransferOrder = Ls > 0): the environment is not one of the lights
// (LightSet built without it), so no light sample and no escaping ray finds it, and the radiance
// sums hold the local lights alone. Instead a path whose ray escapes the scene in direction w
// with throughput beta (the product of the albedos, roulette and transmittance since the probe)
// adds, for a probe direction wp drawn with pdf p,
//   T[r][s] += Y_r(wp) / p * beta * Y_s(w)    (r < (L+1)^2, s < (Ls+1)^2, per RGB channel),
// which estimates T[r][s] = integral over wp of Y_r(wp) times the radiance at the probe from wp
// under a sky of radiance Y_s: the path is the same one that a bake with that sky would trace,
// and the escape is what direction sampling alone would count of it (weight 1, no MIS: there is
// no sky to sample yet). So sum_s T[r][s] sky_s is, sample by sample, an unbiased estimate of
// what a bake under the sky sum_s sky_s Y_s would add to coefficient r, with the BSDF-sampling
// estimator in place of NEE + MIS for the sky. Local lights keep NEE + MIS along the same paths.
// Escapes past maxDepth count, as the environment's emission does in an ordinary bake.
//
// Shadow-ray roulette (shadow_roulette.h): a path's light sample or join to a sunlit point whose
// contribution, known before its shadow ray is traced, is below a threshold T is traced with
// probability contribution / T and weighted by the inverse. T is kRouletteShare of the probe's
// mean radiance, read from a pilot of a few paths of its own before its batches (RouletteRadiance),
// so it is the same for every batch, thread and shard; the probe's own light samples are always
// traced. The joins of light paths to the probe (DistantLightPaths::ConnectProbe) play the same
// roulette, a join counting as a probe sample of radiance value / 4 pi.
//
// One driver traces every sample, as waves: a group of samples starts together at the probe
// (each path's first ray, each probe light sample's shadow ray), and wave d then shades every
// path's vertex d and traces its rays (its light sample's shadow ray, its continuation). A
// call of at least kMinPacketSamples samples without a medium puts kChunk samples in a group and
// traces each wave's rays as Embree packets: the rays from the probe sorted by direction, so that
// rays that share an origin and nearly a direction share most of their BVH traversal, and each
// later wave in the order of the wave before, so that a packet's rays start from neighbouring
// points. Otherwise a group is a single sample, a wave is one path, and its rays are traced one
// at a time. Only the grouping of rays into packets differs between the two; each sample's random
// numbers, rays and the order of its sum do not.
#pragma once

#include <atomic>
#include <cstdint>
#include <optional>
#include <span>

#include "distant_light_paths.h"
#include "light_set.h"
#include "medium.h"
#include "probebake/bake/ray_observer.h"
#include "probebake/math/vec3.h"
#include "probebake/sampling/spherical_fibonacci.h"
#include "probebake/scene/scene.h"
#include "tracer_scene.h"

namespace probebake {

struct TraceCounters {
  int64_t rays = 0;
  int64_t samples = 0;
  // Of `rays`, the shadow rays (the others: one first ray per sample, and the paths'
  // continuation rays).
  int64_t shadowRays = 0;
};

// Bake-wide totals that progress reports read while workers run.
struct SharedCounters {
  std::atomic<int64_t> rays{0};
  std::atomic<int64_t> samples{0};
  std::atomic<int64_t> shadowRays{0};
  void Add(const TraceCounters& c) {
    rays.fetch_add(c.rays, std::memory_order_relaxed);
    samples.fetch_add(c.samples, std::memory_order_relaxed);
    shadowRays.fetch_add(c.shadowRays, std::memory_order_relaxed);
  }
};

class ProbeIntegrator {
 public:
  // packets false: every sample is traced alone, ray by ray, whatever the call's size: the
  // reference that tests hold the packets' bookkeeping (sorted rays, shared samplers) against.
  // The results agree to float rounding of the hits.
  ProbeIntegrator(const Scene& scene, const TracerScene& tracer, const LightSet& lights,
                  const BakeSettings& settings, bool packets = true);

  // Adds to `sum` ((shOrder+1)^2 x 3 doubles, coefficient-major RGB) the contributions of samples
  // [0, count) of the random stream (seed, Hash(probeKey, batch)) for the probe at local position
  // p (probeKey: ProbeSite::key, probe_site.h).
  // Adds the work done to `shared` every few hundred samples. Returns false if `cancel` was
  // raised (the partial sum is then meaningless).
  bool TraceBatch(const Vec3d& p, uint64_t probeKey, uint32_t batch, int64_t count,
                  std::span<double> sum, SharedCounters* shared,
                  const std::atomic<bool>* cancel) const;

  // One batch of TraceBatches: its sample count and the sum its samples add to; and, when not
  // empty, the visibility moments its probe rays add to (probebake/volume/visibility_map.h):
  // per texel the sum of inverse first-hit distances (InverseDistance(t, maxDistance): a miss
  // or a hit beyond maxDistance counting as 0), of their squares, and the ray count, in sample
  // order.
  // With sky transfer, `transfer` is the batch's T sum ((shOrder+1)^2 x (Ls+1)^2 x 3 doubles,
  // row-major by probe coefficient, then sky coefficient, then RGB); empty otherwise.
  struct BatchWork {
    int64_t count = 0;
    std::span<double> sum;
    std::span<double> moments = {};
    double maxDistance = 0;
    std::span<double> transfer = {};
  };
  // TraceBatch for batches firstBatch + k, k < work.size(), with work[k]'s count and sum: the
  // same sums as one TraceBatch call each. Traced together, small batches' rays from the probe
  // share packets: batches of kSamplesPerCall samples together make the most of them.
  // rouletteRadiance > 0: the shadow rays of the paths' light samples and joins are played by
  // Russian roulette against it (shadow_roulette.h): RouletteRadiance's value for the probe.
  static constexpr int kSamplesPerCall = 256;
  bool TraceBatches(const Vec3d& p, uint64_t probeKey, uint32_t firstBatch,
                    std::span<const BatchWork> work, SharedCounters* shared,
                    const std::atomic<bool>* cancel, double rouletteRadiance = 0) const;

  // The roulette threshold of the shadow rays for the probe at p (key probeKey) that bakes up to
  // `samples` samples: kRouletteShare x the mean radiance that a pilot of min(kPilotSamples,
  // samples / kPilotDivisor) paths of its own finds there (their numbers apart from the bake's,
  // so every batch stays independent of it), with no roulette. 0 (none) when fewer than
  // kMinPilotSamples would be traced, or with light sampling off. Adds its rays to *shared (when
  // not null), and no samples: its paths are not the probe's.
  static constexpr double kRouletteShare = 0.2;
  static constexpr int64_t kPilotSamples = 16, kPilotDivisor = 128, kMinPilotSamples = 4;
  double RouletteRadiance(const Vec3d& p, uint64_t probeKey, int64_t samples,
                          SharedCounters* shared) const;

  // Reports the rays of TraceBatches calls to `observer` (ray_observer.h); null: none (the
  // default). Not thread-safe against running calls: set before tracing.
  void SetRayObserver(RayObserver* observer) { observer_ = observer; }

  // Joins `paths` (distant_light_paths.h: built for this integrator's scene, lights and settings,
  // with the bake's batch sizes) to every probe's batches, and weighs the directional lights'
  // next-event and direction samples against them. Null (the default): no light tracing. Not
  // thread-safe against running calls: set before tracing.
  void SetLightPaths(const DistantLightPaths* paths) { lightPaths_ = paths; }

  // Fraction of the sampled light's radiance that reaches `origin`: 0 when occluded, else the
  // medium's transmittance (1 without a medium).
  Vec3d ShadowTransmittance(const Vec3f& origin, const LightSample& s,
                            TraceCounters* counters) const;

 private:
  // The parts of the driver, defined in probe_integrator.cpp: a scattering vertex's random
  // numbers, the vertex once shaded, the probe of a call, and a group of samples traced together.
  struct VertexNumbers;
  struct Vertex;
  struct Probe;
  template <int kWidth>
  struct Group;

  // Samples per group when a call traces packets: one direction cell each at the probe (a
  // 2^kCellBits square grid), and slots that fit 16 bits beside their markers. Calls of fewer
  // than kMinPacketSamples samples are too spread over the sphere to pay for the sort.
  static constexpr int kCellBits = 4;
  static constexpr int kChunk = kSamplesPerCall;
  static_assert(kChunk == 1 << (2 * kCellBits), "one direction cell per sample");
  static constexpr int kMinPacketSamples = 128;

  // The numbers of one scattering vertex, in the order they are drawn.
  template <typename S>
  static VertexNumbers DrawVertexNumbers(S& sampler);
  // Two vertices' numbers, *a's then *b's, as two DrawVertexNumbers calls right after a restart
  // (one Sobol chunk, taken at once).
  template <typename S>
  static void DrawTwoVertices(S& sampler, VertexNumbers* a, VertexNumbers* b);

  // A call's options beyond its batches: the roulette threshold, and whether the probe is
  // joined to the light paths (not in a pilot, whose samples are no batch of theirs).
  struct CallOptions {
    double rouletteRadiance = 0;
    bool connectProbe = true;
  };
  // TraceBatches with `options`: the call in TraceGroups' instantiation for its size and scene.
  bool Dispatch(const Vec3d& p, uint64_t probeKey, uint32_t firstBatch,
                std::span<const BatchWork> work, SharedCounters* shared,
                const std::atomic<bool>* cancel, const CallOptions& options) const;
  // The whole call with groups of kWidth samples (kChunk: packets; 1: one path at a time).
  template <bool kMedium, int kWidth, typename S>
  bool TraceGroups(const Vec3d& p, uint64_t probeKey, uint32_t firstBatch,
                   std::span<const BatchWork> work, SharedCounters* shared,
                   const std::atomic<bool>* cancel, const CallOptions& options) const;
  // Draws the random numbers of the group's samples at the probe (and, without a medium, at
  // their first vertex), samples the lights there and traces the rays from the probe.
  template <bool kMedium, int kWidth, typename S>
  void StartAtProbe(const Probe& probe, std::span<S> samplers,
                    std::span<const RotatedSphericalFibonacci> atProbe, Group<kWidth>* group,
                    TraceCounters* counters) const;
  // Traces the group's paths on from the probe's hits, one wave per vertex depth, until every
  // path has ended; leaves each path's radiance in the group.
  template <bool kMedium, int kWidth, typename S>
  void TraceWaves(const Probe& probe, std::span<S> samplers, Group<kWidth>* group,
                  TraceCounters* counters) const;
  // Adds each sample's two contributions at the probe to its batch's sum, in sample order.
  template <bool kMedium, int kWidth>
  void AddToSums(const Probe& probe, const Group<kWidth>& group,
                 std::span<const BatchWork> work) const;

  // The emission that the ray from pPrev (normal nPrev, light importance importancePrev summing
  // to totalPrev) along wi, drawn with pdf pdfDir, finds at `hit` or, when not found, beyond the
  // scene, times beta and its MIS weight, added to *radiance. Returns the albedo of the diffuse
  // vertex the path continues from, or nullptr when it ends there (no hit, a light's surface, or
  // bounce past maxDepth): the material's constant albedo, or, where it varies over the surface,
  // its value at the hit written to *albedoHere.
  // What the weights against light tracing (distant_light_paths.h) need of a path: the density
  // of its first vertex as the probe's direction drew it (per unit area: cos / (4 pi r^2)), the
  // surface vertex the ray in flight left (null when it left the probe) and the one before that.
  struct LightPathContext {
    double d1 = 0;
    const Vec3d *xPrev = nullptr, *nPrev = nullptr;
    const Vec3d *xBefore = nullptr, *nBefore = nullptr;
    uint32_t batch = 0;  // the path's batch (of the whole probe, not of the call)
  };
  const Vec3d* Arrive(bool found, const SurfaceHit& hit, int bounce, const Vec3d& pPrev,
                      const Vec3d* nPrev, std::span<const double> importancePrev, double totalPrev,
                      const Vec3d& wi, double pdfDir, const LightPathContext& context,
                      const Vec3d& beta, Vec3d* radiance, Vec3d* albedoHere) const;
  // Shades the diffuse vertex (albedo > 0) at `hit`, reached along wi, as vertex `bounce` with the
  // numbers u: its light sample, continuation and roulette. `importance` gets its light
  // importance; *beta becomes the continuation's throughput. context as for Arrive, for the
  // path that arrived here.
  void ShadeSurface(const SurfaceHit& hit, const Vec3d& wi, const Vec3d& albedo,
                    const VertexNumbers& u, int bounce, const LightPathContext& context,
                    std::span<double> importance, Vec3d* beta, Vertex* v) const;
  // Shades the scattering event at x in the medium, reached along wi, as ShadeSurface does a
  // surface: the phase function in place of the BSDF.
  void ShadeMedium(const Vec3d& x, const Vec3d& wi, const VertexNumbers& u, int bounce,
                   std::span<double> importance, Vec3d* beta, Vertex* v) const;
  // The shadow ray from `origin` to the sampled light point: false when none is needed (the
  // point lies within float error of the origin: visible).
  bool ShadowRay(const Vec3f& origin, const LightSample& s, Vec3d* dir, double* tMax) const;
  // What reaches the end of the shadow ray from `origin` along dir (up to tMax) of a light
  // sample: 0 when `occluded`, else the medium's transmittance (1 without one).
  template <bool kMedium>
  Vec3d Arrived(bool occluded, const Vec3f& origin, const Vec3d& dir, double tMax) const;

  const Scene& scene_;
  const TracerScene& tracer_;
  const LightSet& lights_;
  const BakeSettings& settings_;
  std::optional<HomogeneousMedium> medium_;
  bool lightSampling_;  // NEE on
  bool countEmission_;  // direction-sampled rays count the emission they hit
  bool mis_;            // weight the two by the power heuristic
  bool packets_;        // trace calls large enough for them as packets
  RayObserver* observer_ = nullptr;
  const DistantLightPaths* lightPaths_ = nullptr;
  int skyOrder_;  // Ls of the sky transfer; 0: off
};

}  // namespace probebake
