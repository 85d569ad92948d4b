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
// Without a medium, a call of at least kMinPacketSamples samples traces kChunk samples at a time
// as waves of Embree packets: first the rays from the probe (each path's first ray, each probe
// light sample's shadow ray), sorted by direction so that rays that share an origin and nearly a
// direction share most of their BVH traversal; then, wave d for d = 1, 2, ..., the rays of every
// path's vertex d (its light sample's shadow ray and its continuation), in the order of the wave
// before, so that a packet's rays start from neighbouring points. Only the grouping of rays into
// packets changes; each sample's random numbers, rays and the order of the sum do not.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "light_set.h"
#include "medium.h"
#include "probebake/math/vec3.h"
#include "probebake/scene/scene.h"
#include "tracer_scene.h"

namespace probebake {

struct TraceCounters {
  int64_t rays = 0;
  int64_t samples = 0;
};

// Bake-wide totals that progress reports read while workers run.
struct SharedCounters {
  std::atomic<int64_t> rays{0};
  std::atomic<int64_t> samples{0};
  void Add(const TraceCounters& c) {
    rays.fetch_add(c.rays, std::memory_order_relaxed);
    samples.fetch_add(c.samples, std::memory_order_relaxed);
  }
};

class ProbeIntegrator {
 public:
  // probePackets false: every ray is traced alone (tests compare the two ways; the results
  // agree to float rounding of the hits).
  ProbeIntegrator(const Scene& scene, const TracerScene& tracer, const LightSet& lights,
                  const BakeSettings& settings, bool probePackets = true);

  // Adds to `sum` ((shOrder+1)^2 x 3 doubles, coefficient-major RGB) the contributions of samples
  // [0, count) of the random stream (seed, Hash(probeKey, batch)) for the probe at local position
  // p (probeKey: ProbeSite::key, probe_site.h).
  // Adds the work done to `shared` every few hundred samples. Returns false if `cancel` was
  // raised (the partial sum is then meaningless).
  bool TraceBatch(const Vec3d& p, uint64_t probeKey, uint32_t batch, int64_t count,
                  std::span<double> sum, SharedCounters* shared,
                  const std::atomic<bool>* cancel) const;

  // One batch of TraceBatches: its sample count and the sum its samples add to.
  struct BatchWork {
    int64_t count = 0;
    std::span<double> sum;
  };
  // TraceBatch for batches firstBatch + k, k < work.size(), with work[k]'s count and sum: the
  // same sums as one TraceBatch call each. Traced together, small batches' rays from the probe
  // share packets: batches of kSamplesPerCall samples together make the most of them.
  static constexpr int kSamplesPerCall = 256;
  bool TraceBatches(const Vec3d& p, uint64_t probeKey, uint32_t firstBatch,
                    std::span<const BatchWork> work, SharedCounters* shared,
                    const std::atomic<bool>* cancel) const;

  // Fraction of the sampled light's radiance that reaches `origin`: 0 when occluded, else the
  // medium's transmittance (1 without a medium).
  Vec3d ShadowTransmittance(const Vec3f& origin, const LightSample& s,
                            TraceCounters* counters) const;

 private:
  // Rays from the probe are traced as packets kChunk samples at a time (when a call has at least
  // kMinPacketSamples; fewer are too spread over the sphere to pay for the sort).
  static constexpr int kCellBits = 4;
  static constexpr int kChunk = kSamplesPerCall;
  static_assert(kChunk == 1 << (2 * kCellBits), "one direction cell per sample");
  static constexpr int kMinPacketSamples = 128;
  // A sample's ray slot when it has no such ray, and when its shadow ray needed no tracing.
  static constexpr uint16_t kNoRay = 0xFFFF, kVisible = 0xFFFE;
  // Whether the light sample whose shadow ray has `slot` reaches its origin, given the traced
  // rays' `occluded` by slot.
  static bool Reaches(uint16_t slot, const bool* occluded) {
    return slot == kVisible || (slot != kNoRay && !occluded[slot]);
  }
  // Dimension sets drawn at the probe (direction, light choice, light point) and at each
  // scattering vertex (VertexNumbers).
  static constexpr uint64_t kProbeSets = 3, kVertexSets = 4;

  // The random numbers of one scattering vertex, in the order they are drawn.
  struct VertexNumbers {
    double select = 0;  // light choice
    Vec2d light;        // light point
    Vec2d next;         // continuation direction
    double roulette = 0;
  };
  template <typename S>
  static VertexNumbers DrawVertexNumbers(S& sampler);
  // Two vertices' numbers, *a's then *b's, as two DrawVertexNumbers calls right after a restart
  // (one Sobol chunk, taken at once).
  template <typename S>
  static void DrawTwoVertices(S& sampler, VertexNumbers* a, VertexNumbers* b);
  // A diffuse vertex once shaded, before its rays are traced.
  struct SurfaceVertex {
    Vec3d n;           // the shading normal, toward the side the path arrived from
    Vec3f spawn;       // the origin of the vertex's rays
    double total = 0;  // the sum of its light importance
    // Its light sample, when one was drawn that can reach it: neeBase tr neeScale is its
    // contribution, tr the shadow ray's transmittance.
    bool lightSampled = false;
    LightSample ls;
    Vec3d neeBase;
    double neeScale = 0;
    // Whether the path goes on (it is not absorbed or stopped by roulette), along wi (pdf pdfDir).
    bool continues = false;
    Vec3d wi;
    double pdfDir = 0;
  };
  // A path of the waves (TraceWaves) between two of them, by sample.
  struct PathState {
    Vec3d radiance;  // gathered so far
    Vec3d beta;      // the throughput of its ray in flight
    Vec3d wi;        // that ray's direction, drawn with pdf pdfDir
    double pdfDir = 0;
    // The vertex the ray leaves: its point, its shading normal (none at the probe) and the sum of
    // its light importance.
    Vec3d pPrev, nPrev;
    bool hasNormal = false;
    double total = 0;
  };

  // A position in the samples of several batches run one after the other: sample `index` of
  // work[batch] (empty batches are skipped).
  struct SampleCursor {
    explicit SampleCursor(std::span<const BatchWork> w) : work(w) { Skip(); }
    void Next() {
      ++index;
      Skip();
    }
    void Skip() {
      while (batch < work.size() && index >= work[batch].count) ++batch, index = 0;
    }
    std::span<const BatchWork> work;
    size_t batch = 0;
    int64_t index = 0;
  };
  // A chunk's samples traced as waves, ahead of the rest of their work (kMedium false only). "By
  // sample": index j of sample c + j; "by slot": the ray's place in the packets of its wave.
  struct ProbeRays {
    Vec3d wi[kChunk];             // by sample: the probe direction
    uint16_t hitSlot[kChunk];     // by sample
    bool found[kChunk];           // by slot: whether the first ray hit
    SurfaceHit hit[kChunk];       // by slot: the hit, valid when found
    LightSample light[kChunk];    // by sample: the light sample, when shadowSlot is not kNoRay
    uint16_t shadowSlot[kChunk];  // by sample: kNoRay when no light was sampled, or kVisible
    bool occluded[kChunk];        // by slot
    uint32_t batch[kChunk];       // by sample: its batch (index into the samplers) ...
    int64_t index[kChunk];        // ... and its index there
    // By sample: the random numbers of the vertex its ray in flight will find, and of the one
    // after it when they were drawn together (one Sobol chunk holds two vertices' sets).
    VertexNumbers vertex[kChunk];
    VertexNumbers after[kChunk];
    PathState path[kChunk];      // by sample
    bool nextFound[kChunk];      // by slot of the wave's continuation rays
    SurfaceHit nextHit[kChunk];  // by slot: valid when nextFound
    // By sample: the light importance (LightSet::ImportanceSize() entries each) of the vertices
    // of odd and even depth.
    std::vector<double> importance[2];
  };

  template <bool kMedium, typename S>
  bool TraceBatchesWith(const Vec3d& p, uint64_t probeKey, uint32_t firstBatch,
                        std::span<const BatchWork> work, SharedCounters* shared,
                        const std::atomic<bool>* cancel) const;
  // Fills `out` for the n <= kChunk samples from `cursor` on (samplers[k]: batch k's stream) at
  // the probe at p (float origin `origin`, light importance `importance` summing to `total`):
  // draws their random numbers at the probe and at the first vertex (out->vertex), samples the
  // lights as TraceBatchesWith would, and traces the rays.
  template <typename S>
  void TraceProbeRays(const Vec3f& origin, const Vec3d& p, std::span<const double> importance,
                      double total, std::span<S> samplers, SampleCursor cursor, int n,
                      ProbeRays* out, TraceCounters* counters) const;
  // Traces, as waves of packets, the n samples' paths on from the rays from the probe at p (light
  // importance `importance` summing to `total`, direction pdf pdfProbe) that TraceProbeRays
  // traced: wave d shades every path's vertex d as TracePath would and traces its rays, in the
  // order of the wave before, so that a packet's rays start from neighbouring points. Leaves each
  // path's radiance in out->path.
  template <typename S>
  void TraceWaves(const Vec3d& p, std::span<const double> importance, double total, double pdfProbe,
                  std::span<S> samplers, int n, ProbeRays* out, TraceCounters* counters) const;
  // The radiance arriving at `origin` (float; p the probe in double) along wi, drawn with pdf
  // pdfDir: what the path from there gathers, with the sampler at its first vertex's numbers.
  // importancePrev: the light importance at p, summing to totalPrev (overwritten, as is scratch).
  template <bool kMedium, typename S>
  Vec3d TracePath(const Vec3f& origin, const Vec3d& p, const Vec3d& wi, double pdfDir,
                  std::span<double> importancePrev, double totalPrev, std::span<double> scratch,
                  S& sampler, TraceCounters* counters) const;
  // Adds to *radiance the emission that the ray from pPrev (normal nPrev, light importance
  // importancePrev summing to totalPrev) along wi, drawn with pdf pdfDir, finds at `hit` or, when
  // not found, beyond the scene, times beta and its MIS weight. Returns the albedo of the diffuse
  // vertex the path continues from, or nullptr when it ends there (no hit, a light's surface, or
  // bounce past maxDepth).
  const Vec3d* Arrive(bool found, const SurfaceHit& hit, int bounce, const Vec3d& pPrev,
                      const Vec3d* nPrev, std::span<const double> importancePrev, double totalPrev,
                      const Vec3d& wi, double pdfDir, const Vec3d& beta, Vec3d* radiance) const;
  // Shades the diffuse vertex (albedo > 0) at `hit`, reached along wi, as vertex `bounce` with the
  // numbers u: its light sample, continuation and roulette. `importance` gets its light
  // importance; *beta becomes the continuation's throughput.
  void ShadeSurface(const SurfaceHit& hit, const Vec3d& wi, const Vec3d& albedo,
                    const VertexNumbers& u, int bounce, std::span<double> importance, Vec3d* beta,
                    SurfaceVertex* v) const;
  // The shadow ray from `origin` to the sampled light point: false when none is needed (the
  // point lies within float error of the origin: visible).
  bool ShadowRay(const Vec3f& origin, const LightSample& s, Vec3d* dir, double* tMax) const;
  // True when nothing lies between `origin` and the sampled light point; `dir` and `tMax` get
  // the shadow ray actually traced.
  bool Unoccluded(const Vec3f& origin, const LightSample& s, TraceCounters* counters, Vec3d* dir,
                  double* tMax) const;
  template <bool kMedium>
  Vec3d Shadow(const Vec3f& origin, const LightSample& s, TraceCounters* counters) const;

  const Scene& scene_;
  const TracerScene& tracer_;
  const LightSet& lights_;
  const BakeSettings& settings_;
  std::optional<HomogeneousMedium> medium_;
  bool lightSampling_;  // NEE on
  bool countEmission_;  // direction-sampled rays count the emission they hit
  bool mis_;            // weight the two by the power heuristic
  bool probePackets_;   // trace the rays from the probe as packets where they pay
};

}  // namespace probebake
