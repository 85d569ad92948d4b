#include "probe_integrator.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <type_traits>

#include "power_heuristic.h"
#include "probebake/base/check.h"
#include "probebake/math/frame.h"
#include "probebake/sampling/hash.h"
#include "probebake/sampling/sampler.h"
#include "probebake/sampling/warps.h"
#include "probebake/sh/sh_basis.h"
#include "ray_offset.h"

namespace probebake {
namespace {

constexpr double kInvPi = std::numbers::inv_pi;
constexpr double kInf = std::numeric_limits<double>::infinity();

// sum[3 i + c] += Y_i(w) value[c].
void Project(int order, const Vec3d& w, const Vec3d& value, std::span<double> sum) {
  double y[kMaxShCoeffCount];
  EvalShBasis(order, w, y);
  const int n = ShCoeffCount(order);
  for (int i = 0; i < n; ++i) {
    sum[3 * i] += y[i] * value.x;
    sum[3 * i + 1] += y[i] * value.y;
    sum[3 * i + 2] += y[i] * value.z;
  }
}

// The 16-bit x and y interleaved, x in the even places: the cell's index along a Morton (Z-order)
// curve.
uint32_t MortonInterleave(uint32_t x, uint32_t y) {
  const auto spread = [](uint32_t v) {
    v = (v | (v << 8)) & 0x00FF00FFu;
    v = (v | (v << 4)) & 0x0F0F0F0Fu;
    v = (v | (v << 2)) & 0x33333333u;
    v = (v | (v << 1)) & 0x55555555u;
    return v;
  };
  return spread(x) | (spread(y) << 1);
}

// A stable counting sort of n elements by key, for packing rays into packets: slot[i] becomes
// element i's place among the elements whose key is below `buckets`, in the order of their keys
// (ties in the order of i); an element with any other key (a marker) gets that key as its slot.
// Returns the number of elements placed. Precondition: buckets <= 256.
int SortSlots(const uint16_t* keys, int n, int buckets, uint16_t* slot) {
  PB_DCHECK(buckets <= 256);
  int start[257] = {};
  for (int i = 0; i < n; ++i) {
    if (keys[i] < buckets) ++start[keys[i] + 1];
  }
  for (int b = 0; b < buckets; ++b) start[b + 1] += start[b];
  const int placed = start[buckets];
  for (int i = 0; i < n; ++i) slot[i] = keys[i] < buckets ? uint16_t(start[keys[i]]++) : keys[i];
  return placed;
}

}  // namespace

template <typename S>
[[gnu::always_inline]] inline ProbeIntegrator::VertexNumbers ProbeIntegrator::DrawVertexNumbers(
    S& sampler) {
  VertexNumbers v;
  v.select = sampler.Get1D();
  v.light = sampler.Get2D();
  v.next = sampler.Get2D();
  v.roulette = sampler.Get1D();
  return v;
}

template <typename S>
[[gnu::always_inline]] inline void ProbeIntegrator::DrawTwoVertices(S& sampler, VertexNumbers* a,
                                                                    VertexNumbers* b) {
  if constexpr (std::is_same_v<S, SobolSampler>) {
    static_assert(kSobolChunk == 2 * kVertexSets);
    // The chunk read set by set, as the sampler's own calls would, so that DrawVertexNumbers
    // alone says which set holds which number.
    struct ChunkReader {
      const uint32_t *x, *y;
      double Get1D() {
        const double u = U32ToUnit(*x);
        ++x, ++y;  // a Get1D call uses its set's x alone
        return u;
      }
      Vec2d Get2D() {
        const Vec2d u{U32ToUnit(*x), U32ToUnit(*y)};
        ++x, ++y;
        return u;
      }
    } chunk;
    sampler.GetChunk(&chunk.x, &chunk.y);
    *a = DrawVertexNumbers(chunk);
    *b = DrawVertexNumbers(chunk);
  } else {
    *a = DrawVertexNumbers(sampler);
    *b = DrawVertexNumbers(sampler);
  }
}

ProbeIntegrator::ProbeIntegrator(const Scene& scene, const TracerScene& tracer,
                                 const LightSet& lights, const BakeSettings& settings,
                                 bool probePackets)
    : scene_(scene),
      tracer_(tracer),
      lights_(lights),
      settings_(settings),
      probePackets_(probePackets) {
  if (scene.medium) medium_.emplace(*scene.medium, tracer.offset());
  switch (settings.estimator) {
    case Estimator::kNeeMis:
      lightSampling_ = true, countEmission_ = true, mis_ = true;
      break;
    case Estimator::kLightSampling:
      lightSampling_ = true, countEmission_ = false, mis_ = false;
      break;
    case Estimator::kDirectionSampling:
      lightSampling_ = false, countEmission_ = true, mis_ = false;
      break;
  }
}

bool ProbeIntegrator::ShadowRay(const Vec3f& origin, const LightSample& s, Vec3d* dir,
                                double* tMax) const {
  if (!std::isfinite(s.distance)) {
    *dir = s.wi;
    *tMax = kInf;
    return true;
  }
  // Aim from the ray's actual origin (offset off its surface, not the shading point itself) at
  // the sampled point, and stop short of the light's own surface by the float error of the
  // coordinates involved: otherwise grazing shadow rays end beyond the light and hit it.
  const Vec3d o(origin);
  const Vec3d v = s.point - o;
  const double d = Length(v);
  const double maxAbs = std::max({MaxComponent(Abs(o)), MaxComponent(Abs(s.point)), s.vertexScale});
  *tMax = d - FloatSlack(maxAbs);
  *dir = d > 0 ? v * (1 / d) : s.wi;
  return *tMax > 0;
}

bool ProbeIntegrator::Unoccluded(const Vec3f& origin, const LightSample& s, TraceCounters* counters,
                                 Vec3d* dir, double* tMax) const {
  ++counters->rays;
  if (!ShadowRay(origin, s, dir, tMax)) return true;
  return !tracer_.Occluded(origin, *dir, *tMax);
}

template <bool kMedium>
Vec3d ProbeIntegrator::Shadow(const Vec3f& origin, const LightSample& s,
                              TraceCounters* counters) const {
  Vec3d dir;
  double tMax;
  if (!Unoccluded(origin, s, counters, &dir, &tMax)) return {};
  if constexpr (kMedium) return medium_->Transmittance(Vec3d(origin), dir, std::max(tMax, 0.0));
  return {1, 1, 1};
}

Vec3d ProbeIntegrator::ShadowTransmittance(const Vec3f& origin, const LightSample& s,
                                           TraceCounters* counters) const {
  return medium_ ? Shadow<true>(origin, s, counters) : Shadow<false>(origin, s, counters);
}

bool ProbeIntegrator::TraceBatch(const Vec3d& p, uint64_t probeKey, uint32_t batch, int64_t count,
                                 std::span<double> sum, SharedCounters* shared,
                                 const std::atomic<bool>* cancel) const {
  const BatchWork work{count, sum};
  return TraceBatches(p, probeKey, batch, {&work, 1}, shared, cancel);
}

bool ProbeIntegrator::TraceBatches(const Vec3d& p, uint64_t probeKey, uint32_t firstBatch,
                                   std::span<const BatchWork> work, SharedCounters* shared,
                                   const std::atomic<bool>* cancel) const {
  const bool sobol = settings_.sampler == SamplerKind::kSobol;
  if (medium_) {
    return sobol
               ? TraceBatchesWith<true, SobolSampler>(p, probeKey, firstBatch, work, shared, cancel)
               : TraceBatchesWith<true, IndependentSampler>(p, probeKey, firstBatch, work, shared,
                                                            cancel);
  }
  return sobol
             ? TraceBatchesWith<false, SobolSampler>(p, probeKey, firstBatch, work, shared, cancel)
             : TraceBatchesWith<false, IndependentSampler>(p, probeKey, firstBatch, work, shared,
                                                           cancel);
}

template <bool kMedium, typename S>
bool ProbeIntegrator::TraceBatchesWith(const Vec3d& p, uint64_t probeKey, uint32_t firstBatch,
                                       std::span<const BatchWork> work, SharedCounters* shared,
                                       const std::atomic<bool>* cancel) const {
  TraceCounters local;
  const int order = settings_.shOrder;
  const Vec3f origin(p);
  std::vector<S> samplers;
  samplers.reserve(work.size());
  int64_t count = 0;  // samples of all the batches, traced as one run
  for (size_t k = 0; k < work.size(); ++k) {
    samplers.emplace_back(settings_.seed, Hash(probeKey, uint64_t(firstBatch + k)));
    count += work[k].count;
  }
  std::vector<double> importanceProbe(lights_.ImportanceSize()), scratchA(lights_.ImportanceSize()),
      scratchB(lights_.ImportanceSize());
  const double totalProbe = lights_.Importance(p, nullptr, /*includeDelta=*/false, importanceProbe);
  const double pdfProbe = UniformSpherePdf();
  const bool probeLightSample = lightSampling_ && totalProbe > 0;
  // Without a medium, a chunk of samples at a time has its paths traced as waves of packets
  // (TraceWaves) before its sums are added up.
  // One buffer per thread, kept: zeroing it (then 55 KB, now over 100 KB) anew for every call
  // took 0.5% of a bake's CPU samples (perf, memset).
  ProbeRays* probeRays = nullptr;
  if (!kMedium && probePackets_ && count >= kMinPacketSamples) {
    thread_local std::unique_ptr<ProbeRays> buffer;
    if (!buffer) buffer = std::make_unique<ProbeRays>();
    probeRays = buffer.get();
    for (std::vector<double>& v : probeRays->importance)
      v.resize(kChunk * lights_.ImportanceSize());
  }

  const int64_t chunk = probeRays ? kChunk : count;
  SampleCursor cursor(work);
  for (int64_t c = 0; c < count; c += chunk) {
    // int64_t: without packets the chunk is the whole call, up to 2^32 samples.
    const int64_t n = std::min<int64_t>(chunk, count - c);
    if (probeRays) {
      TraceProbeRays(origin, p, importanceProbe, totalProbe, std::span<S>(samplers), cursor, int(n),
                     probeRays, &local);
      TraceWaves(p, importanceProbe, totalProbe, pdfProbe, std::span<S>(samplers), int(n),
                 probeRays, &local);
    }
    for (int64_t j = 0; j < n; ++j, cursor.Next()) {
      if (((c + j) & 255) == 0) {
        if (shared) shared->Add(local);
        local = {};
        if (cancel && cancel->load(std::memory_order_relaxed)) return false;
      }
      S& sampler = samplers[cursor.batch];
      const std::span<double> sum = work[cursor.batch].sum;
      Vec3d wi, radiance;
      Vec2d uLight;
      double uSelect = 0;
      if (probeRays) {
        // TraceProbeRays found this direction from the same numbers, and TraceWaves traced the
        // path.
        wi = probeRays->wi[j];
        radiance = probeRays->path[j].radiance;
      } else {
        sampler.StartSample(uint64_t(cursor.index));
        const Vec2d uDirection = sampler.Get2D();
        uSelect = sampler.Get1D();
        uLight = sampler.Get2D();
        // The path first, the light sample after it: the path's work hides the memory latency
        // of the light sample's tables (a large environment map), loaded from here on. The
        // projections are still added light sample first, so the sum's bits do not change.
        if (probeLightSample) lights_.Prefetch(uLight);
        wi = SampleUniformSphere(uDirection);
        std::copy(importanceProbe.begin(), importanceProbe.end(), scratchA.begin());
        radiance = TracePath<kMedium>(origin, p, wi, pdfProbe, scratchA, totalProbe, scratchB,
                                      sampler, &local);
      }

      if (probeLightSample) {
        const auto add = [&](const LightSample& ls, const Vec3d& tr) {
          if (MaxComponent(tr) <= 0) return;
          const double wOverPdf = mis_ ? PowerHeuristicOverPdf(ls.pdf, pdfProbe) : 1 / ls.pdf;
          Project(order, ls.wi, ls.radiance * tr * wOverPdf, sum);
        };
        if (probeRays) {
          // Read in place: zeroing a local LightSample (rep stos) took 0.8% of a bake (perf).
          const uint16_t slot = probeRays->shadowSlot[j];
          if (Reaches(slot, probeRays->occluded)) add(probeRays->light[j], {1, 1, 1});
        } else {
          LightSample ls;
          if (lights_.Sample(p, nullptr, importanceProbe, totalProbe, uSelect, uLight, &ls))
            add(ls, Shadow<kMedium>(origin, ls, &local));
        }
      }
      if (MaxComponent(radiance) > 0) Project(order, wi, radiance / pdfProbe, sum);
      ++local.samples;
    }
  }
  if (shared) shared->Add(local);
  return true;
}

template <typename S>
void ProbeIntegrator::TraceProbeRays(const Vec3f& origin, const Vec3d& p,
                                     std::span<const double> importance, double total,
                                     std::span<S> samplers, SampleCursor cursor, int n,
                                     ProbeRays* out, TraceCounters* counters) const {
  // Packets want rays that are neighbours on the sphere; Sobol points in index order are spread
  // over the whole sphere on purpose. So the rays are put in packets in the order of a counting
  // sort by cell: the probe directions by their cell of 2^kCellBits x 2^kCellBits in the (z, phi)
  // square they are drawn from (SampleUniformSphere), along a Morton curve (an aligned chunk of
  // Sobol points is a (0, 2 kCellBits, 2)-net: one point in each); the shadow rays by light and
  // by octahedral cell of their direction. The rays' order changes only which rays share a packet,
  // never a result.
  static_assert(kChunk == (1 << (2 * kCellBits)));
  static_assert(kChunk <= kVisible, "slots never meet the markers");
  // shadowCell is a sample's bucket, or kNoRay / kVisible when it has no shadow ray to trace.
  const bool lightSample = lightSampling_ && total > 0;
  // Zeroed only because GCC cannot see that the loop below sets the n entries SortSlots reads.
  uint16_t hitCell[kChunk] = {}, shadowCell[kChunk] = {};
  Vec3d shadowDir[kChunk];
  double shadowTMax[kChunk];
  const auto cellIndex = [](double x) {  // x in [0, 1]
    return std::min(uint32_t(x * (1 << kCellBits)), (1u << kCellBits) - 1);
  };
  for (int j = 0; j < n; ++j, cursor.Next()) {
    S& sampler = samplers[cursor.batch];
    sampler.StartSample(uint64_t(cursor.index));
    out->batch[j] = uint32_t(cursor.batch);
    out->index[j] = cursor.index;
    const Vec2d uDirection = sampler.Get2D();
    const double uSelect = sampler.Get1D();
    const Vec2d uLight = sampler.Get2D();
    out->vertex[j] = DrawVertexNumbers(sampler);
    out->wi[j] = SampleUniformSphere(uDirection);
    hitCell[j] = uint16_t(MortonInterleave(cellIndex(uDirection.x), cellIndex(uDirection.y)));

    shadowCell[j] = kNoRay;
    if (!lightSample) continue;
    LightSample& ls = out->light[j];
    if (!lights_.Sample(p, nullptr, importance, total, uSelect, uLight, &ls)) continue;
    ++counters->rays;  // counted as Unoccluded counts it, traced or not
    if (!ShadowRay(origin, ls, &shadowDir[j], &shadowTMax[j])) {
      shadowCell[j] = kVisible;
      continue;
    }
    // Octahedral map of the direction, then cells of 2^(kCellBits - 1) squared per light.
    const Vec3d& d = shadowDir[j];
    const double l1 = std::fabs(d.x) + std::fabs(d.y) + std::fabs(d.z);
    const double inv = 1 / l1;
    double ox = d.x * inv, oy = d.y * inv;
    if (d.z < 0) {
      const double fx = (1 - std::fabs(oy)) * (ox < 0 ? -1 : 1);
      oy = (1 - std::fabs(ox)) * (oy < 0 ? -1 : 1);
      ox = fx;
    }
    constexpr int kHalf = kCellBits - 1;
    constexpr uint32_t kLightGroups = 4;  // 4 x 2^(2 kHalf) = kChunk buckets
    const uint32_t cx = cellIndex(0.5 * (ox + 1)) >> 1, cy = cellIndex(0.5 * (oy + 1)) >> 1;
    shadowCell[j] = uint16_t(((ls.light % kLightGroups) << (2 * kHalf)) | MortonInterleave(cx, cy));
  }

  SortSlots(hitCell, n, kChunk, out->hitSlot);
  Vec3d sortedDir[kChunk];
  for (int j = 0; j < n; ++j) sortedDir[out->hitSlot[j]] = out->wi[j];
  constexpr int kWidth = TracerScene::kPacketWidth;
  for (int k = 0; k < n; k += kWidth) {
    const int m = std::min(kWidth, n - k);
    tracer_.IntersectPacket({&origin, 1}, std::span<const Vec3d>(sortedDir + k, size_t(m)),
                            out->hit + k, out->found + k);
  }
  counters->rays += n;
  if (!lightSample) return;

  const int rays = SortSlots(shadowCell, n, kChunk, out->shadowSlot);
  double sortedTMax[kChunk];
  for (int j = 0; j < n; ++j) {
    const uint16_t k = out->shadowSlot[j];
    if (k == kNoRay || k == kVisible) continue;
    sortedDir[k] = shadowDir[j];
    sortedTMax[k] = shadowTMax[j];
  }
  for (int k = 0; k < rays; k += kWidth) {
    const int m = std::min(kWidth, rays - k);
    tracer_.OccludedPacket({&origin, 1}, std::span<const Vec3d>(sortedDir + k, size_t(m)),
                           sortedTMax + k, out->occluded + k);
  }
}

template <typename S>
void ProbeIntegrator::TraceWaves(const Vec3d& p, std::span<const double> importance, double total,
                                 double pdfProbe, std::span<S> samplers, int n, ProbeRays* out,
                                 TraceCounters* counters) const {
  const size_t size = lights_.ImportanceSize();
  // The wave's paths by slot of the rays that find their next vertex: the first wave in the probe
  // rays' order (neighbouring slots hold neighbouring directions, whose hits are neighbours too,
  // and so are the rays from them), each later one in the order of the one before.
  uint16_t active[kChunk], next[kChunk];
  for (int j = 0; j < n; ++j) {
    active[out->hitSlot[j]] = uint16_t(j);
    PathState& s = out->path[j];
    s.radiance = {};
    s.beta = {1, 1, 1};
    s.wi = out->wi[j];
    s.pdfDir = pdfProbe;
    s.pPrev = p;
    s.hasNormal = false;
    s.total = total;
  }
  Vec3f shadowOrigin[kChunk], nextOrigin[kChunk], sortedOrigin[kChunk];
  Vec3d shadowDir[kChunk], nextDir[kChunk], sortedDir[kChunk];
  double shadowTMax[kChunk], sortedTMax[kChunk];
  uint16_t shadowGroup[kChunk], shadowSlot[kChunk];
  bool sortedOccluded[kChunk];
  // By shadow ray: its path and its light sample's contribution, neeBase neeScale unless occluded.
  uint16_t shadowPath[kChunk];
  Vec3d neeBase[kChunk];
  double neeScale[kChunk];
  const bool* found = out->found;
  const SurfaceHit* hits = out->hit;
  constexpr int kWidth = TracerScene::kPacketWidth;
  constexpr int kShadowGroups = 4;
  // One for all vertices: ShadeSurface writes every field that is read after it, and zeroing a
  // fresh one (some 200 bytes) for every vertex took 1.5% of the bake's own instructions
  // (callgrind).
  SurfaceVertex v;
  for (int bounce = 1, count = n; count > 0; ++bounce) {
    double* importanceHere = out->importance[bounce & 1].data();
    const double* importanceBefore = out->importance[(bounce - 1) & 1].data();
    int shadowRays = 0, nextRays = 0;
    for (int k = 0; k < count; ++k) {
      const int j = active[k];
      PathState& s = out->path[j];
      const SurfaceHit& hit = hits[k];
      const std::span<const double> before =
          bounce == 1 ? importance : std::span<const double>(importanceBefore + j * size, size);
      const Vec3d* albedo = Arrive(found[k], hit, bounce, s.pPrev, s.hasNormal ? &s.nPrev : nullptr,
                                   before, s.total, s.wi, s.pdfDir, s.beta, &s.radiance);
      if (!albedo || MaxComponent(*albedo) <= 0) continue;
      ShadeSurface(hit, s.wi, *albedo, out->vertex[j], bounce,
                   std::span<double>(importanceHere + j * size, size), &s.beta, &v);
      if (v.lightSampled) {
        ++counters->rays;  // counted as Unoccluded counts it, traced or not
        if (ShadowRay(v.spawn, v.ls, &shadowDir[shadowRays], &shadowTMax[shadowRays])) {
          shadowOrigin[shadowRays] = v.spawn;
          shadowGroup[shadowRays] = uint16_t(v.ls.light % kShadowGroups);
          shadowPath[shadowRays] = uint16_t(j);
          neeBase[shadowRays] = v.neeBase;
          neeScale[shadowRays++] = v.neeScale;
        } else {
          // Added after the vertex's emission and before the next vertex's, as TracePath adds it.
          const Vec3d tr{1, 1, 1};
          s.radiance += v.neeBase * tr * v.neeScale;
        }
      }
      if (!v.continues) continue;
      s.wi = v.wi;
      s.pdfDir = v.pdfDir;
      s.pPrev = hit.p;
      s.nPrev = v.n;
      s.hasNormal = true;
      s.total = v.total;
      // The next vertex's numbers, as TracePath draws them: vertex d's sets start at kProbeSets +
      // (d - 1) kVertexSets, and a sampler restarted at an even vertex's computes that vertex's
      // sets and the next one's together (kSobolChunk = 2 kVertexSets), so they are drawn
      // together. Its light tables load while the rays are traced.
      static_assert(kSobolChunk == 2 * kVertexSets);
      if ((bounce + 1) % 2 == 0) {
        S& sampler = samplers[out->batch[j]];
        sampler.StartSample(uint64_t(out->index[j]), kProbeSets + uint64_t(bounce) * kVertexSets);
        DrawTwoVertices(sampler, &out->vertex[j], &out->after[j]);
      } else {
        out->vertex[j] = out->after[j];
      }
      if (lightSampling_) lights_.Prefetch(out->vertex[j].light);
      nextOrigin[nextRays] = v.spawn;
      nextDir[nextRays] = v.wi;
      next[nextRays++] = uint16_t(j);
    }
    // Packets of shadow rays by light (a stable counting sort of the wave's order): rays from
    // neighbouring points to one light share most of their traversal.
    SortSlots(shadowGroup, shadowRays, kShadowGroups, shadowSlot);
    for (int r = 0; r < shadowRays; ++r) {
      const int k = shadowSlot[r];
      sortedOrigin[k] = shadowOrigin[r];
      sortedDir[k] = shadowDir[r];
      sortedTMax[k] = shadowTMax[r];
    }
    for (int k = 0; k < shadowRays; k += kWidth) {
      const size_t m = size_t(std::min(kWidth, shadowRays - k));
      tracer_.OccludedPacket(std::span<const Vec3f>(sortedOrigin + k, m),
                             std::span<const Vec3d>(sortedDir + k, m), sortedTMax + k,
                             sortedOccluded + k);
    }
    for (int r = 0; r < shadowRays; ++r) {
      if (sortedOccluded[shadowSlot[r]]) continue;
      const Vec3d tr{1, 1, 1};  // as TracePath adds it
      out->path[shadowPath[r]].radiance += neeBase[r] * tr * neeScale[r];
    }
    // The hits just read are overwritten only now.
    for (int k = 0; k < nextRays; k += kWidth) {
      const size_t m = size_t(std::min(kWidth, nextRays - k));
      tracer_.IntersectPacket(std::span<const Vec3f>(nextOrigin + k, m),
                              std::span<const Vec3d>(nextDir + k, m), out->nextHit + k,
                              out->nextFound + k);
    }
    counters->rays += nextRays;
    std::copy(next, next + nextRays, active);
    count = nextRays;
    found = out->nextFound;
    hits = out->nextHit;
  }
}

[[gnu::always_inline]] inline const Vec3d* ProbeIntegrator::Arrive(
    bool found, const SurfaceHit& hit, int bounce, const Vec3d& pPrev, const Vec3d* nPrev,
    std::span<const double> importancePrev, double totalPrev, const Vec3d& wi, double pdfDir,
    const Vec3d& beta, Vec3d* radiance) const {
  if (!found) {
    if (countEmission_) {
      lights_.ForEachEscaped(nPrev, importancePrev, totalPrev, wi, [&](const LightHit& h) {
        const double w = mis_ ? PowerHeuristic(pdfDir, h.pdf) : 1.0;
        *radiance += beta * h.radiance * w;
      });
    }
    return nullptr;
  }
  if (countEmission_ && lights_.MayEmit(hit)) {
    LightHit h;
    if (lights_.EvalSurfaceHit(pPrev, nPrev, importancePrev, totalPrev, wi, hit, &h)) {
      const double w = mis_ ? PowerHeuristic(pdfDir, h.pdf) : 1.0;
      *radiance += beta * h.radiance * w;
    }
  }
  if (hit.kind != SurfaceKind::kMesh) return nullptr;  // area lights' surfaces absorb
  if (bounce > settings_.maxDepth) return nullptr;
  return &scene_.materials[scene_.meshes[hit.index].material].albedo;
}

[[gnu::always_inline]] inline void ProbeIntegrator::ShadeSurface(
    const SurfaceHit& hit, const Vec3d& wi, const Vec3d& albedo, const VertexNumbers& u, int bounce,
    std::span<double> importance, Vec3d* beta, SurfaceVertex* v) const {
  // Shade on the side the ray arrived from; both sides of a mesh reflect.
  v->n = Dot(wi, hit.ng) < 0 ? hit.ng : -hit.ng;
  v->spawn = OffsetRayOrigin(hit.p, v->n, hit.vertexScale);
  // Light importance here serves NEE and the MIS weight of the next hit; the pure
  // direction-sampling estimator needs neither.
  v->total = (lightSampling_ || mis_)
                 ? lights_.Importance(hit.p, &v->n, /*includeDelta=*/true, importance)
                 : 0.0;
  v->lightSampled = false;
  if (lightSampling_ && v->total > 0 &&
      lights_.Sample(hit.p, &v->n, importance, v->total, u.select, u.light, &v->ls)) {
    const double cosTheta = Dot(v->ls.wi, v->n);
    if (cosTheta > 0) {
      // f cos w / pdf = (albedo / pi) cos w / pdf, the albedo in neeBase.
      const double pdfBsdf = cosTheta * kInvPi;
      v->lightSampled = true;
      v->neeBase = *beta * albedo * v->ls.radiance;
      v->neeScale = pdfBsdf * ((mis_ && !v->ls.delta) ? PowerHeuristicOverPdf(v->ls.pdf, pdfBsdf)
                                                      : 1 / v->ls.pdf);
    }
  }

  v->continues = false;
  // f cos / pdf = (albedo / pi) cos / (cos / pi) = albedo, whatever the direction: roulette is
  // decided first, and a path it ends samples no direction (beta is not read once a path ends).
  Vec3d betaNext = *beta * albedo;
  if (settings_.russianRoulette && bounce >= settings_.rrMinDepth) {
    const double survive = std::min(1.0, MaxComponent(betaNext));
    if (u.roulette >= survive) return;
    betaNext = betaNext / survive;
  }
  const Vec3d local = SampleCosineHemisphere(u.next);
  v->pdfDir = CosineHemispherePdf(local.z);
  if (!(v->pdfDir > 0)) return;
  // Unit to a few ulp already (an orthonormal frame, a unit local vector): not normalized again,
  // which took a square root and a division on the vertex's dependency chain.
  v->wi = Framed::FromZ(v->n).FromLocal(local);
  *beta = betaNext;
  v->continues = true;
}

template <bool kMedium, typename S>
Vec3d ProbeIntegrator::TracePath(const Vec3f& originProbe, const Vec3d& p, const Vec3d& wiProbe,
                                 double pdfProbe, std::span<double> importancePrev,
                                 double totalPrev, std::span<double> scratch, S& sampler,
                                 TraceCounters* counters) const {
  Vec3d radiance, beta{1, 1, 1}, wi = wiProbe;
  double pdfDir = pdfProbe;
  Vec3f origin = originProbe;
  Vec3d pPrev = p;
  Vec3d nPrevStorage;
  const Vec3d* nPrev = nullptr;  // the probe and medium vertices have no surface
  for (int bounce = 1;; ++bounce) {
    // Without a medium the vertex's random numbers are drawn before its ray is traced (a path
    // that ends there leaves them unused, and the next sample restarts the sampler), so that the
    // light sample's memory loads while Embree traces.
    VertexNumbers u;
    if constexpr (!kMedium) {
      u = DrawVertexNumbers(sampler);
      if (lightSampling_) lights_.Prefetch(u.light);
    }
    SurfaceHit hit;
    ++counters->rays;
    const bool found = tracer_.Intersect(origin, wi, kInf, &hit);

    if constexpr (kMedium) {
      const double uChannel = sampler.Get1D();
      const double uDistance = sampler.Get1D();
      const MediumSample ms =
          medium_->Sample(Vec3d(origin), wi, found ? hit.t : kInf, uChannel, uDistance);
      beta *= ms.weight;
      if (ms.scattered) {
        const Vec3d x = Vec3d(origin) + wi * ms.t;
        u = DrawVertexNumbers(sampler);
        if (bounce > settings_.maxDepth || MaxComponent(beta) <= 0) break;
        const Vec3f xf(x);
        const double g = medium_->g();
        const double total = lights_.Importance(x, nullptr, /*includeDelta=*/true, scratch);
        if (lightSampling_ && total > 0) {
          LightSample ls;
          if (lights_.Sample(x, nullptr, scratch, total, u.select, u.light, &ls)) {
            // Light propagating along -ls.wi leaves along -wi: cos theta = Dot(ls.wi, wi).
            const double phase = HenyeyGreensteinPdf(Dot(ls.wi, wi), g);
            const Vec3d tr = Shadow<true>(xf, ls, counters);
            if (MaxComponent(tr) > 0) {
              const double w = (mis_ && !ls.delta) ? PowerHeuristic(ls.pdf, phase) : 1.0;
              radiance += beta * ls.radiance * tr * (phase * w / ls.pdf);
            }
          }
        }
        // Sample where the light came from: its propagation direction dIn is HG-distributed about
        // the outgoing one, -wi (the phase function is symmetric in the two).
        const Vec3d local = SampleHenyeyGreenstein(u.next, g);
        const Vec3d dIn = Framed::FromZ(-wi).FromLocal(local);
        pdfDir = HenyeyGreensteinPdf(local.z, g);  // phase / pdf = 1: beta is unchanged
        if (settings_.russianRoulette && bounce >= settings_.rrMinDepth) {
          const double survive = std::min(1.0, MaxComponent(beta));
          if (u.roulette >= survive) break;
          beta = beta / survive;
        }
        wi = Normalize(-dIn);
        origin = xf;
        pPrev = x;
        nPrev = nullptr;
        std::swap(importancePrev, scratch);
        totalPrev = total;
        continue;
      }
      if (MaxComponent(beta) <= 0) break;
    }

    const Vec3d* albedo = Arrive(found, hit, bounce, pPrev, nPrev, importancePrev, totalPrev, wi,
                                 pdfDir, beta, &radiance);
    if (!albedo) break;
    if constexpr (kMedium) u = DrawVertexNumbers(sampler);
    if (MaxComponent(*albedo) <= 0) break;

    SurfaceVertex v;
    ShadeSurface(hit, wi, *albedo, u, bounce, scratch, &beta, &v);
    if (v.lightSampled) {
      const Vec3d tr = Shadow<kMedium>(v.spawn, v.ls, counters);
      if (MaxComponent(tr) > 0) radiance += v.neeBase * tr * v.neeScale;
    }
    if (!v.continues) break;
    wi = v.wi;
    pdfDir = v.pdfDir;
    origin = v.spawn;
    pPrev = hit.p;
    nPrevStorage = v.n;
    nPrev = &nPrevStorage;
    std::swap(importancePrev, scratch);
    totalPrev = v.total;
  }
  return radiance;
}

}  // namespace probebake
