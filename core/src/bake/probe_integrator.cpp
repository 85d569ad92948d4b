#include "probe_integrator.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <type_traits>
#include <vector>

#include "power_heuristic.h"
#include "probebake/base/check.h"
#include "probebake/math/frame.h"
#include "probebake/sampling/hash.h"
#include "probebake/sampling/sampler.h"
#include "probebake/sampling/spherical_fibonacci.h"
#include "probebake/sampling/warps.h"
#include "probebake/sh/sh_basis.h"
#include "probebake/volume/visibility_map.h"
#include "ray_offset.h"
#include "shadow_roulette.h"
#include "surface_material.h"

namespace probebake {
namespace {

constexpr double kInvPi = std::numbers::inv_pi;
constexpr double kInf = std::numeric_limits<double>::infinity();

// Whether a sampler draws the probe's directions and light points from rotated spherical
// Fibonacci sets.
template <typename S>
inline constexpr bool kRotatedSetsAtProbe = std::is_same_v<S, SobolSampler>;

// Dimension sets drawn at the probe (direction, light choice, light point) and at each
// scattering vertex (VertexNumbers).
constexpr uint64_t kProbeSets = 3, kVertexSets = 4;

// The streams of the numbers that pick a sunlit point to join a vertex to, that play a shadow
// ray's roulette, and of a probe's pilot paths.
constexpr uint64_t kConnectTag = 0x636f6e6e656374;     // "connect"
constexpr uint64_t kRouletteTag = 0x726f756c65747465;  // "roulette"
constexpr uint64_t kPilotTag = 0x70696c6f74;           // "pilot"

// A ray's slot when there is no such ray, and when a shadow ray needs no tracing (visible).
constexpr uint16_t kNoRay = 0xFFFF, kVisible = 0xFFFE;

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

// transfer[(r ns + s) 3 + c] += Y_r(wp) weight Y_s(wSky) beta[c], ns = (skyOrder+1)^2: one
// escaped path's term of the sky transfer (probe_integrator.h).
void ProjectTransfer(int order, const Vec3d& wp, double weight, int skyOrder, const Vec3d& wSky,
                     const Vec3d& beta, std::span<double> transfer) {
  double yProbe[kMaxShCoeffCount], ySky[kMaxShCoeffCount];
  EvalShBasis(order, wp, yProbe);
  EvalShBasis(skyOrder, wSky, ySky);
  const int n = ShCoeffCount(order), ns = ShCoeffCount(skyOrder);
  double* t = transfer.data();
  for (int r = 0; r < n; ++r) {
    const double wr = yProbe[r] * weight;
    for (int k = 0; k < ns; ++k, t += 3) {
      const double w = wr * ySky[k];
      t[0] += w * beta.x;
      t[1] += w * beta.y;
      t[2] += w * beta.z;
    }
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

// Packets want rays that are neighbours on the sphere; the probe's directions in sample order
// are spread over the whole sphere on purpose. So the rays from the probe are put in packets in
// the order of a counting sort by cell: the probe directions by their cell of 2^kCellBits bands of
// z by 2^kCellBits steps of azimuth (DirectionCell), along a Morton curve; the shadow rays by light
// and by a coarser cell of their direction in the octahedral map of the sphere.
template <int kCellBits>
[[gnu::always_inline]] inline uint32_t CellIndex(double x) {  // x in [0, 1]
  return std::min(uint32_t(x * (1 << kCellBits)), (1u << kCellBits) - 1);
}

// The cell (*cx, *cy) of d's octahedral map onto [0, 1]^2 (2^kCellBits cells a side).
template <int kCellBits>
[[gnu::always_inline]] inline void OctahedralCell(const Vec3d& d, uint32_t* cx, uint32_t* cy) {
  const double inv = 1 / (std::fabs(d.x) + std::fabs(d.y) + std::fabs(d.z));
  double ox = d.x * inv, oy = d.y * inv;
  if (d.z < 0) {
    const double fx = (1 - std::fabs(oy)) * (ox < 0 ? -1 : 1);
    oy = (1 - std::fabs(ox)) * (oy < 0 ? -1 : 1);
    ox = fx;
  }
  *cx = CellIndex<kCellBits>(0.5 * (ox + 1));
  *cy = CellIndex<kCellBits>(0.5 * (oy + 1));
}

// d's cell in (z, azimuth): equal-height bands of z (equal areas) by equal steps of the "diamond
// angle", a monotone stand-in for the azimuth in [0, 4) without atan2. The probe's directions are
// spherical Fibonacci sets, whose points climb z along a spiral; packets from these cells took
// fewer Embree traversal steps than packets from octahedral cells (docs/performance-history.md).
// The cells are part of the baker's bits: Embree's answer for a ray can differ in its last bits
// with the rays that share its packet (seen in a mesh of 140k triangles, not in small ones), and
// the packing depends on the probe's samples alone, never on threads or sharding.
template <int kCellBits>
[[gnu::always_inline]] inline uint16_t DirectionCell(const Vec3d& d) {
  const double ax = std::fabs(d.x), ay = std::fabs(d.y), sum = ax + ay;
  double diamond = 0;
  if (sum > 0) {
    const double t = ay / sum;  // 0 on the x axis, 1 on the y axis
    if (d.y >= 0) {
      diamond = d.x >= 0 ? t : 2 - t;
    } else {
      diamond = d.x < 0 ? 2 + t : 4 - t;
    }
  }
  return uint16_t(MortonInterleave(CellIndex<kCellBits>(0.5 * (1 - d.z)),
                                   CellIndex<kCellBits>(0.25 * diamond)));
}

template <int kCellBits>
[[gnu::always_inline]] inline uint16_t ShadowCell(const Vec3d& d, uint32_t light) {
  // Cells of 2^(kCellBits - 1) squared per group of lights.
  constexpr int kHalf = kCellBits - 1;
  constexpr uint32_t kLightGroups = 4;  // 4 x 2^(2 kHalf) = 2^(2 kCellBits) buckets
  uint32_t cx, cy;
  OctahedralCell<kHalf>(d, &cx, &cy);
  return uint16_t(((light % kLightGroups) << (2 * kHalf)) | MortonInterleave(cx, cy));
}

// The observer's record of a ray cast from `origin` along dir up to tMax.
ObservedRay Observed(RayKind kind, const Vec3f& origin, const Vec3d& dir, double tMax) {
  ObservedRay r;
  r.origin = origin;
  r.dir = Vec3f(dir);
  r.tfar = TracerScene::EmbreeTFar(tMax);
  r.kind = kind;
  return r;
}

// Tells `observer` of the n closest-hit rays just cast by IntersectRays (out of line: the tracing
// itself only tests the observer pointer).
[[gnu::noinline, gnu::cold]] void ReportIntersections(RayObserver* observer, RayKind kind,
                                                      bool packed, std::span<const Vec3f> origins,
                                                      const Vec3d* dirs, int n,
                                                      const SurfaceHit* hits, const bool* found) {
  constexpr int kPacket = TracerScene::kPacketWidth;
  const bool shared = origins.size() == 1;
  ObservedRay rays[kPacket];
  for (int k = 0; k < n; k += packed ? kPacket : 1) {
    const int m = packed ? std::min(kPacket, n - k) : 1;
    for (int lane = 0; lane < m; ++lane) {
      const int i = k + lane;
      ObservedRay& r = rays[lane];
      r = Observed(kind, origins[shared ? 0 : size_t(i)], dirs[i], kInf);
      r.packed = packed;
      r.coherent = packed && shared;
      r.lanes = uint8_t(m);
      r.lane = uint8_t(lane);
      r.hit = found[i];
      r.tHit = found[i] ? float(hits[i].t) : 0.0f;
    }
    observer->OnRays({rays, size_t(m)});
  }
}

// The shadow rays of one wave, or of a group's light samples at the probe. Ray r's `key` is its
// packet bucket, or a marker (kNoRay, kVisible) when it is not traced; once traced, slot[r] is
// its place in the packets (or its marker) and occluded[slot[r]] its answer.
template <int kWidth>
struct ShadowRays {
  int count = 0;
  Vec3f origin[kWidth];  // [0] alone when the rays share an origin
  Vec3d dir[kWidth];
  double tMax[kWidth];
  uint16_t key[kWidth];
  uint16_t slot[kWidth];
  bool occluded[kWidth];  // by slot
  // The traced rays by slot, for the packets (kept here: arrays of vectors are zeroed when made).
  Vec3f sortedOrigin[kWidth];
  Vec3d sortedDir[kWidth];
  double sortedTMax[kWidth];

  // Whether ray r's light sample reaches its origin, ignoring a medium.
  bool Reaches(int r) const {
    const uint16_t k = slot[r];
    return k < kVisible ? !occluded[k] : k == kVisible;
  }
};

template <int kWidth>
[[gnu::noinline, gnu::cold]] void ReportShadowRays(RayObserver* observer, int traced,
                                                   bool sharedOrigin,
                                                   const ShadowRays<kWidth>& rays);

// Traces rays->count shadow rays: as packets of rays sorted by key (keys below `buckets`), or,
// in groups of one, the one ray alone. sharedOrigin: every ray starts at origin[0]. Tells
// `observer` (when not null) of the rays once traced.
template <int kWidth>
void TraceShadowRays(const TracerScene& tracer, int buckets, bool sharedOrigin,
                     ShadowRays<kWidth>* rays, RayObserver* observer) {
  if constexpr (kWidth == 1) {
    if (rays->count == 0) return;
    rays->slot[0] = rays->key[0] < buckets ? 0 : rays->key[0];
    if (rays->slot[0] == 0)
      rays->occluded[0] = tracer.Occluded(rays->origin[0], rays->dir[0], rays->tMax[0]);
    if (observer) ReportShadowRays(observer, rays->slot[0] == 0 ? 1 : 0, sharedOrigin, *rays);
  } else {
    static_assert(kWidth <= kVisible, "slots never meet the markers");
    const int traced = SortSlots(rays->key, rays->count, buckets, rays->slot);
    for (int r = 0; r < rays->count; ++r) {
      const uint16_t k = rays->slot[r];
      if (k == kNoRay || k == kVisible) continue;
      if (!sharedOrigin) rays->sortedOrigin[k] = rays->origin[r];
      rays->sortedDir[k] = rays->dir[r];
      rays->sortedTMax[k] = rays->tMax[r];
    }
    constexpr int kPacket = TracerScene::kPacketWidth;
    for (int k = 0; k < traced; k += kPacket) {
      const size_t m = size_t(std::min(kPacket, traced - k));
      tracer.OccludedPacket(sharedOrigin ? std::span<const Vec3f>(rays->origin, 1)
                                         : std::span<const Vec3f>(rays->sortedOrigin + k, m),
                            std::span<const Vec3d>(rays->sortedDir + k, m), rays->sortedTMax + k,
                            rays->occluded + k);
    }
    if (observer) ReportShadowRays(observer, traced, sharedOrigin, *rays);
  }
}

// The shadow rays TraceShadowRays traced (`traced` of them, by slot: alone for groups of one, in
// packets otherwise), then those it counted as visible without tracing.
template <int kWidth>
void ReportShadowRays(RayObserver* observer, int traced, bool sharedOrigin,
                      const ShadowRays<kWidth>& rays) {
  constexpr int kPacket = TracerScene::kPacketWidth;
  constexpr bool kPacked = kWidth > 1;
  ObservedRay batch[kPacket];
  for (int k = 0; k < traced; k += kPacket) {
    const int m = std::min(kPacket, traced - k);
    for (int lane = 0; lane < m; ++lane) {
      const int i = k + lane;
      const Vec3f& origin = (sharedOrigin || !kPacked) ? rays.origin[0] : rays.sortedOrigin[i];
      ObservedRay& r = batch[lane];
      r = kPacked ? Observed(RayKind::kShadow, origin, rays.sortedDir[i], rays.sortedTMax[i])
                  : Observed(RayKind::kShadow, origin, rays.dir[0], rays.tMax[0]);
      r.packed = kPacked;
      r.coherent = kPacked && sharedOrigin;
      r.lanes = uint8_t(m);
      r.lane = uint8_t(lane);
      r.hit = rays.occluded[i];
    }
    observer->OnRays({batch, size_t(m)});
  }
  for (int r = 0; r < rays.count; ++r) {
    if (rays.key[r] != kVisible) continue;
    ObservedRay v =
        Observed(RayKind::kShadow, rays.origin[sharedOrigin ? 0 : r], rays.dir[r], rays.tMax[r]);
    v.cast = false;
    observer->OnRays({&v, 1});
  }
}

// found[k], hits[k] (left alone on a miss) of the rays from origins[k] (or origins[0] for all)
// along dirs[k], k < n: as packets in this order, or, in groups of one, the one ray alone.
// Tells `observer` (when not null) of the rays once traced, as rays of `kind`.
template <int kWidth>
[[gnu::always_inline]] inline void IntersectRays(const TracerScene& tracer,
                                                 std::span<const Vec3f> origins, const Vec3d* dirs,
                                                 int n, SurfaceHit* hits, bool* found, RayKind kind,
                                                 RayObserver* observer) {
  if constexpr (kWidth == 1) {
    if (n > 0) found[0] = tracer.Intersect(origins[0], dirs[0], kInf, &hits[0]);
  } else {
    constexpr int kPacket = TracerScene::kPacketWidth;
    const bool shared = origins.size() == 1;
    for (int k = 0; k < n; k += kPacket) {
      const size_t m = size_t(std::min(kPacket, n - k));
      tracer.IntersectPacket(shared ? origins : origins.subspan(size_t(k), m),
                             std::span<const Vec3d>(dirs + k, m), hits + k, found + k);
    }
  }
  if (observer) ReportIntersections(observer, kind, kWidth > 1, origins, dirs, n, hits, found);
}

// A path between two waves.
struct PathState {
  Vec3d radiance;  // gathered so far
  Vec3d beta;      // the throughput of its ray in flight
  Vec3d wi;        // that ray's direction, drawn with pdf pdfDir
  double pdfDir = 0;
  Vec3f origin;  // that ray's origin, kept with a medium only (where the segment starts)
  // The vertex the ray leaves: its point, its shading normal (none at the probe and in a
  // medium) and the sum of its light importance.
  Vec3d pPrev, nPrev;
  bool hasNormal = false;
  double total = 0;
  // The surface vertex before that one (for light tracing's weights), when there is one.
  Vec3d pBefore, nBefore;
  bool hasBefore = false;
  // The distance to the surface the path's first ray (from the probe) hit; +inf on a miss.
  double firstHit = 0;
  // That hit's density as the probe's uniform direction drew it, per unit area (cos / (4 pi
  // t^2)); 0 on a miss.
  double d1 = 0;
  // With sky transfer: whether the path escaped the scene, with which throughput and direction.
  bool escaped = false;
  Vec3d skyBeta, skyDir;
};

// Right after a restart, draw(numbers) draws from `numbers` as it would from the sampler: a
// Sobol sampler's next kSobolChunk sets computed at once (GetChunk) and read set by set, as its
// own calls would read them, or the sampler itself.
template <typename S, typename Draw>
[[gnu::always_inline]] inline void DrawFromChunk(S& sampler, Draw&& draw) {
  if constexpr (std::is_same_v<S, SobolSampler>) {
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
    draw(chunk);
  } else {
    draw(sampler);
  }
}

// A position in the samples of several batches run one after the other: sample `index` of
// work[batch] (empty batches are skipped).
struct SampleCursor {
  explicit SampleCursor(std::span<const ProbeIntegrator::BatchWork> w) : work(w) { Skip(); }
  void Next() {
    ++index;
    Skip();
  }
  void Skip() {
    while (batch < work.size() && index >= work[batch].count) ++batch, index = 0;
  }
  std::span<const ProbeIntegrator::BatchWork> work;
  size_t batch = 0;
  int64_t index = 0;
};

}  // namespace

// The random numbers of one scattering vertex, in the order they are drawn.
struct ProbeIntegrator::VertexNumbers {
  double select = 0;  // light choice
  Vec2d light;        // light point
  Vec2d next;         // continuation direction
  double roulette = 0;
};

// A scattering vertex once shaded, before its rays are traced.
struct ProbeIntegrator::Vertex {
  Vec3d x;           // in the medium: where it lies (a surface vertex lies at its hit)
  Vec3d n;           // on a surface: the shading normal, toward the side the path came from
  Vec3f spawn;       // the origin of its rays
  double total = 0;  // the sum of its light importance
  // Its light sample, when one was drawn that can reach it: neeBase tr neeScale is its
  // contribution, tr what reaches the vertex along the shadow ray (ProbeIntegrator::Arrived).
  bool lightSampled = false;
  LightSample ls;
  Vec3d neeBase;
  double neeScale = 0;
  // Whether the path goes on (not absorbed or stopped by roulette), along wi (pdf pdfDir).
  bool continues = false;
  Vec3d wi;
  double pdfDir = 0;
};

// The probe of a call: its point, the origin of its rays and its light importance.
struct ProbeIntegrator::Probe {
  Vec3d p;
  Vec3f origin;
  std::span<const double> importance;
  double total = 0;
  double pdf = UniformSpherePdf();  // of the path's first direction
  bool lightSample = false;         // a light is sampled at the probe
  uint64_t key = 0;                 // ProbeSite::key
  uint32_t firstBatch = 0;          // of the call
  double rouletteRadiance = 0;      // the shadow rays' roulette threshold; 0: none
};

// Up to kWidth samples traced together: started at the probe together, then wave by wave. "By
// sample": index j of the group's sample j; "by slot": the ray's place in the wave's packets
// (the same for groups of one).
template <int kWidth>
struct ProbeIntegrator::Group {
  int n = 0;
  uint32_t batch[kWidth];  // by sample: its batch (index into the samplers) ...
  int64_t index[kWidth];   // ... and its index there
  Vec3d wi[kWidth];        // by sample: the probe direction
  // The light samples at the probe: by sample, with their shadow rays by sample (key kNoRay when
  // none was drawn).
  LightSample light[kWidth];
  ShadowRays<kWidth> probeShadow;
  PathState path[kWidth];  // by sample
  // By sample, without a medium: the random numbers of the vertex its ray in flight will find,
  // and of the one after it when they were drawn together (one Sobol chunk holds two vertices'
  // sets).
  VertexNumbers vertex[kWidth];
  VertexNumbers after[kWidth];
  // The wave's paths by slot of their ray in flight, and that ray's hit (valid when found).
  uint16_t active[kWidth];
  bool found[kWidth];
  SurfaceHit hit[kWidth];
  // The next wave's paths and rays, in the order of this one (and the first rays, sorted).
  uint16_t next[kWidth];
  Vec3f nextOrigin[kWidth];
  Vec3d nextDir[kWidth];
  // The wave's shadow rays, each with its path and its light sample's neeBase and neeScale.
  ShadowRays<kWidth> shadow;
  uint16_t shadowPath[kWidth];
  Vec3d neeBase[kWidth];
  double neeScale[kWidth];
  // The light importance (LightSet::ImportanceSize() entries each) at the probe, and by sample at
  // the vertices of odd and even depth.
  std::vector<double> probeImportance;
  std::vector<double> importance[2];
  // Told of the call's rays (ray_observer.h); null: nobody is.
  RayObserver* observer = nullptr;
};

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
  static_assert(2 * kVertexSets == kSobolChunk);
  DrawFromChunk(sampler, [&](auto& numbers) {
    *a = DrawVertexNumbers(numbers);
    *b = DrawVertexNumbers(numbers);
  });
}

ProbeIntegrator::ProbeIntegrator(const Scene& scene, const TracerScene& tracer,
                                 const LightSet& lights, const BakeSettings& settings, bool packets)
    : scene_(scene),
      tracer_(tracer),
      lights_(lights),
      settings_(settings),
      packets_(packets),
      skyOrder_(settings.skyTransferOrder) {
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

template <bool kMedium>
[[gnu::always_inline]] inline Vec3d ProbeIntegrator::Arrived(bool occluded, const Vec3f& origin,
                                                             const Vec3d& dir, double tMax) const {
  if (occluded) return {};
  if constexpr (kMedium) return medium_->Transmittance(Vec3d(origin), dir, std::max(tMax, 0.0));
  return {1, 1, 1};
}

Vec3d ProbeIntegrator::ShadowTransmittance(const Vec3f& origin, const LightSample& s,
                                           TraceCounters* counters) const {
  ++counters->rays;  // counted whether traced or not, as the driver counts its shadow rays
  ++counters->shadowRays;
  Vec3d dir;
  double tMax;
  const bool occluded = ShadowRay(origin, s, &dir, &tMax) && tracer_.Occluded(origin, dir, tMax);
  return medium_ ? Arrived<true>(occluded, origin, dir, tMax)
                 : Arrived<false>(occluded, origin, dir, tMax);
}

bool ProbeIntegrator::TraceBatch(const Vec3d& p, uint64_t probeKey, uint32_t batch, int64_t count,
                                 std::span<double> sum, SharedCounters* shared,
                                 const std::atomic<bool>* cancel) const {
  const BatchWork work{count, sum};
  return TraceBatches(p, probeKey, batch, {&work, 1}, shared, cancel);
}

bool ProbeIntegrator::TraceBatches(const Vec3d& p, uint64_t probeKey, uint32_t firstBatch,
                                   std::span<const BatchWork> work, SharedCounters* shared,
                                   const std::atomic<bool>* cancel, double rouletteRadiance) const {
  return Dispatch(p, probeKey, firstBatch, work, shared, cancel, {rouletteRadiance, true});
}

double ProbeIntegrator::RouletteRadiance(const Vec3d& p, uint64_t probeKey, int64_t samples,
                                         SharedCounters* shared) const {
  const int64_t count = std::min(kPilotSamples, samples / kPilotDivisor);
  if (!settings_.shadowRoulette || !lightSampling_ || count < kMinPilotSamples) return 0;
  std::vector<double> sum(3 * size_t(ShCoeffCount(settings_.shOrder)));
  // A stream of its own (another key), joined to batch 0's light paths without the probe's joins
  // to them: a rough estimate, which is all a threshold needs (any one keeps the bake unbiased).
  const BatchWork work{count, sum};
  SharedCounters pilot;
  Dispatch(p, Hash(probeKey, kPilotTag), 0, {&work, 1}, &pilot, nullptr, {0, false});
  // Its rays are the bake's work; its paths are no sample of the probe's.
  if (shared) shared->Add({.rays = pilot.rays.load(), .shadowRays = pilot.shadowRays.load()});
  // The mean over the sphere of radiance sum_i c_i Y_i is c_0 Y_0.
  const Vec3d c0(sum[0], sum[1], sum[2]);
  return kRouletteShare * MaxComponent(c0) / double(count) * kShY00;
}

bool ProbeIntegrator::Dispatch(const Vec3d& p, uint64_t probeKey, uint32_t firstBatch,
                               std::span<const BatchWork> work, SharedCounters* shared,
                               const std::atomic<bool>* cancel, const CallOptions& options) const {
  int64_t count = 0;
  for (const BatchWork& w : work) count += w.count;
  const bool sobol = settings_.sampler == SamplerKind::kSobol;
  const auto run = [&]<bool kMedium, int kWidth>() {
    return sobol ? TraceGroups<kMedium, kWidth, SobolSampler>(p, probeKey, firstBatch, work, shared,
                                                              cancel, options)
                 : TraceGroups<kMedium, kWidth, IndependentSampler>(p, probeKey, firstBatch, work,
                                                                    shared, cancel, options);
  };
  // A medium's paths draw their numbers one after the other from their batch's sampler
  // (TraceWaves), which only a group of one leaves to them.
  if (medium_) return run.template operator()<true, 1>();
  if (packets_ && count >= kMinPacketSamples) return run.template operator()<false, kChunk>();
  return run.template operator()<false, 1>();
}

template <bool kMedium, int kWidth, typename S>
bool ProbeIntegrator::TraceGroups(const Vec3d& p, uint64_t probeKey, uint32_t firstBatch,
                                  std::span<const BatchWork> work, SharedCounters* shared,
                                  const std::atomic<bool>* cancel,
                                  const CallOptions& options) const {
  static_assert(kWidth == 1 || (!kMedium && kWidth == kChunk));
  TraceCounters local;
  std::vector<S> samplers;
  samplers.reserve(work.size());
  int64_t count = 0;  // samples of all the batches, traced as one run
  // Sobol: each batch's probe directions and probe light points, interleaved in one rotated
  // spherical Fibonacci set of twice its samples.
  std::vector<RotatedSphericalFibonacci> atProbe;
  if constexpr (kRotatedSetsAtProbe<S>) atProbe.reserve(work.size());
  for (size_t k = 0; k < work.size(); ++k) {
    const uint64_t stream = Hash(probeKey, uint64_t(firstBatch + k));
    samplers.emplace_back(settings_.seed, stream);
    if constexpr (kRotatedSetsAtProbe<S>)
      atProbe.emplace_back(2 * uint64_t(work[k].count), settings_.seed, stream);
    count += work[k].count;
  }
  // One group per thread, kept: a large one zeroed anew for every call costs a bake a visible
  // share of its time.
  thread_local std::unique_ptr<Group<kWidth>> buffer;
  if (!buffer) buffer = std::make_unique<Group<kWidth>>();
  Group<kWidth>& group = *buffer;
  const size_t size = lights_.ImportanceSize();
  group.probeImportance.resize(size);
  for (std::vector<double>& v : group.importance) v.resize(kWidth * size);

  Probe probe;
  probe.p = p;
  probe.origin = Vec3f(p);
  probe.total = lights_.Importance(p, nullptr, /*includeDelta=*/false, group.probeImportance);
  probe.importance = group.probeImportance;
  probe.lightSample = lightSampling_ && probe.total > 0;
  probe.key = probeKey;
  probe.firstBatch = firstBatch;
  probe.rouletteRadiance = options.rouletteRadiance;

  group.observer =
      observer_ && observer_->BeginCall(probeKey, firstBatch, count) ? observer_ : nullptr;
  SampleCursor cursor(work);
  for (int64_t c = 0; c < count; c += kWidth) {
    if ((c & 255) == 0) {  // kWidth divides 256
      if (shared) shared->Add(local);
      local = {};
      if (cancel && cancel->load(std::memory_order_relaxed)) {
        if (observer_) observer_->EndCall();
        return false;
      }
    }
    group.n = int(std::min<int64_t>(kWidth, count - c));
    for (int j = 0; j < group.n; ++j, cursor.Next()) {
      group.batch[j] = uint32_t(cursor.batch);
      group.index[j] = cursor.index;
    }
    StartAtProbe<kMedium>(probe, std::span<S>(samplers), atProbe, &group, &local);
    TraceWaves<kMedium>(probe, std::span<S>(samplers), &group, &local);
    AddToSums<kMedium>(probe, group, work);
    local.samples += group.n;
  }
  if (lightPaths_ && options.connectProbe) {
    for (size_t k = 0; k < work.size(); ++k) {
      if (work[k].count == 0) continue;
      const DistantLightPaths::ProbeRoulette roulette{
          options.rouletteRadiance, Hash(probeKey, uint64_t(firstBatch + k), kRouletteTag)};
      lightPaths_->ConnectProbe(p, firstBatch + uint32_t(k), work[k].count, settings_.shOrder,
                                roulette, work[k].sum, &local, group.observer);
    }
  }
  if (shared) shared->Add(local);
  if (observer_) observer_->EndCall();
  return true;
}

template <bool kMedium, int kWidth, typename S>
void ProbeIntegrator::StartAtProbe(const Probe& probe, std::span<S> samplers,
                                   std::span<const RotatedSphericalFibonacci> atProbe,
                                   Group<kWidth>* g, TraceCounters* counters) const {
  // Sort keys for the packets (groups of one have no use for them). Zeroed only because GCC
  // cannot see that the loop below sets the n entries SortSlots reads.
  uint16_t hitCell[kWidth] = {};
  ShadowRays<kWidth>& shadow = g->probeShadow;
  shadow.origin[0] = probe.origin;
  shadow.count = g->n;
  for (int j = 0; j < g->n; ++j) {
    S& sampler = samplers[g->batch[j]];
    sampler.StartSample(uint64_t(g->index[j]));
    Vec2d uDirection, uLight;
    double uSelect;
    const auto drawAtProbe = [&](auto& numbers) {
      uDirection = numbers.Get2D();
      uSelect = numbers.Get1D();
      uLight = numbers.Get2D();
    };
    if constexpr (kMedium) {
      // The path goes on drawing from the sampler where the probe's numbers end.
      drawAtProbe(sampler);
    } else {
      // With the first vertex's numbers: one Sobol chunk.
      static_assert(kProbeSets + kVertexSets <= kSobolChunk);
      DrawFromChunk(sampler, [&](auto& numbers) {
        drawAtProbe(numbers);
        g->vertex[j] = DrawVertexNumbers(numbers);
      });
      if (lightSampling_) lights_.Prefetch(g->vertex[j].light);
    }
    if constexpr (kRotatedSetsAtProbe<S>) {
      // The sampler's direction and light point sets are left unused.
      const RotatedSphericalFibonacci& set = atProbe[g->batch[j]];
      const uint64_t i = uint64_t(g->index[j]);
      g->wi[j] = set.Point(2 * i);
      uLight = InvertUniformSphereSample(set.Point(2 * i + 1));
    } else {
      g->wi[j] = SampleUniformSphere(uDirection);
    }
    if constexpr (kWidth > 1) hitCell[j] = DirectionCell<kCellBits>(g->wi[j]);
    PathState& s = g->path[j];
    s.radiance = {};
    s.beta = {1, 1, 1};
    s.wi = g->wi[j];
    s.pdfDir = probe.pdf;
    if constexpr (kMedium) s.origin = probe.origin;
    s.pPrev = probe.p;
    s.hasNormal = false;
    s.hasBefore = false;
    s.total = probe.total;
    s.escaped = false;

    shadow.key[j] = kNoRay;
    if (!probe.lightSample) continue;
    LightSample& ls = g->light[j];
    if (!lights_.Sample(probe.p, nullptr, probe.importance, probe.total, uSelect, uLight, &ls))
      continue;
    ++counters->rays;  // counted whether traced or not
    ++counters->shadowRays;
    shadow.key[j] = ShadowRay(probe.origin, ls, &shadow.dir[j], &shadow.tMax[j])
                        ? (kWidth > 1 ? ShadowCell<kCellBits>(shadow.dir[j], ls.light) : 0)
                        : kVisible;
  }

  // The first rays, by slot: neighbouring slots hold neighbouring directions, whose hits are
  // neighbours too, and so are the rays from them.
  uint16_t slot[kWidth];
  if constexpr (kWidth > 1) {
    SortSlots(hitCell, g->n, kChunk, slot);
  } else {
    slot[0] = 0;
  }
  for (int j = 0; j < g->n; ++j) {
    g->nextDir[slot[j]] = g->wi[j];
    g->active[slot[j]] = uint16_t(j);
  }
  IntersectRays<kWidth>(tracer_, {&probe.origin, 1}, g->nextDir, g->n, g->hit, g->found,
                        RayKind::kProbe, g->observer);
  counters->rays += g->n;
  if (probe.lightSample)
    TraceShadowRays(tracer_, kChunk, /*sharedOrigin=*/true, &shadow, g->observer);
}

template <bool kMedium, int kWidth, typename S>
void ProbeIntegrator::TraceWaves(const Probe& probe, std::span<S> samplers, Group<kWidth>* g,
                                 TraceCounters* counters) const {
  const size_t size = lights_.ImportanceSize();
  constexpr int kShadowGroups = 4;  // shadow rays go in packets by light % kShadowGroups
  uint16_t* next = g->next;
  Vec3f* nextOrigin = g->nextOrigin;
  Vec3d* nextDir = g->nextDir;
  ShadowRays<kWidth>& shadow = g->shadow;
  // One for all vertices: ShadeSurface and ShadeMedium write every field that is read after
  // them, and a fresh one would be zeroed for every vertex.
  Vertex v;
  for (int bounce = 1, count = g->n; count > 0; ++bounce) {
    double* importanceHere = g->importance[bounce & 1].data();
    const double* importanceBefore = g->importance[(bounce - 1) & 1].data();
    int nextRays = 0;
    shadow.count = 0;
    for (int k = 0; k < count; ++k) {
      const int j = g->active[k];
      PathState& s = g->path[j];
      const SurfaceHit& hit = g->hit[k];
      // The vertex's light importance, written by its shading.
      const auto here = [&] { return std::span<double>(importanceHere + j * size, size); };
      if (bounce == 1) {
        s.firstHit = g->found[k] ? hit.t : kInf;
        if (lightPaths_)
          s.d1 = g->found[k] && hit.t > 0
                     ? std::fabs(Dot(s.wi, hit.ng)) * probe.pdf / (hit.t * hit.t)
                     : 0.0;
      }
      bool scattered = false;
      VertexNumbers drawn;  // with a medium: the vertex's numbers, drawn once it is found
      const VertexNumbers* u = kMedium ? &drawn : &g->vertex[j];
      if constexpr (kMedium) {
        // The segment may end in the medium before the surface it found.
        S& sampler = samplers[g->batch[j]];  // the path's alone (a group of one)
        const double uChannel = sampler.Get1D();
        const double uDistance = sampler.Get1D();
        const MediumSample ms =
            medium_->Sample(Vec3d(s.origin), s.wi, g->found[k] ? hit.t : kInf, uChannel, uDistance);
        s.beta *= ms.weight;
        if (ms.scattered) {
          const Vec3d x = Vec3d(s.origin) + s.wi * ms.t;
          drawn = DrawVertexNumbers(sampler);
          if (bounce > settings_.maxDepth || MaxComponent(s.beta) <= 0) continue;
          ShadeMedium(x, s.wi, *u, bounce, here(), &s.beta, &v);
          scattered = true;
        } else if (MaxComponent(s.beta) <= 0) {
          continue;
        }
      }
      if (!scattered) {
        if (skyOrder_ > 0 && !g->found[k]) {
          s.escaped = true;
          s.skyBeta = s.beta;
          s.skyDir = s.wi;
        }
        const std::span<const double> before =
            bounce == 1 ? probe.importance
                        : std::span<const double>(importanceBefore + j * size, size);
        Vec3d albedoHere;  // a varying albedo's value at the hit, when Arrive reads one
        const LightPathContext context{s.d1,
                                       s.hasNormal ? &s.pPrev : nullptr,
                                       s.hasNormal ? &s.nPrev : nullptr,
                                       s.hasBefore ? &s.pBefore : nullptr,
                                       s.hasBefore ? &s.nBefore : nullptr,
                                       probe.firstBatch + g->batch[j]};
        const Vec3d* albedo =
            Arrive(g->found[k], hit, bounce, s.pPrev, s.hasNormal ? &s.nPrev : nullptr, before,
                   s.total, s.wi, s.pdfDir, context, s.beta, &s.radiance, &albedoHere);
        if (!albedo) continue;
        if constexpr (kMedium) drawn = DrawVertexNumbers(samplers[g->batch[j]]);
        if (MaxComponent(*albedo) <= 0) continue;
        const Vec3d betaIn = s.beta;
        ShadeSurface(hit, s.wi, *albedo, *u, bounce, context, here(), &s.beta, &v);
        if (lightPaths_ && bounce < settings_.maxDepth) {
          // Joined to a sunlit point (distant_light_paths.h), with a number of its own.
          const uint64_t key = Hash(probe.key, uint64_t(probe.firstBatch + g->batch[j]),
                                    uint64_t(g->index[j]), uint64_t(bounce), kConnectTag);
          const DistantLightPaths::Roulette roulette{MaxComponent(betaIn * *albedo) * kInvPi,
                                                     probe.rouletteRadiance,
                                                     U32ToUnit(uint32_t(key))};
          const Vec3d e = lightPaths_->ConnectVertex(
              hit.p, v.n, v.spawn, probe.firstBatch + g->batch[j], U32ToUnit(uint32_t(key >> 32)),
              s.d1, roulette, counters, g->observer);
          if (MaxComponent(e) > 0) s.radiance += betaIn * *albedo * e * kInvPi;
        }
      }

      // What the light sample adds when its shadow ray arrives.
      const double nee = v.lightSampled ? MaxComponent(v.neeBase) * v.neeScale : 0;
      if (v.lightSampled && nee < probe.rouletteRadiance) {
        // Roulette on a weak light sample (shadow_roulette.h), with a number of its own (hashed
        // for the weak ones alone).
        const uint64_t key = Hash(probe.key, uint64_t(probe.firstBatch + g->batch[j]),
                                  uint64_t(g->index[j]), uint64_t(bounce), kRouletteTag);
        const double w =
            ShadowRouletteWeight(nee, probe.rouletteRadiance, U32ToUnit(uint32_t(key >> 32)));
        v.lightSampled = w > 0;
        v.neeScale *= w;
      }
      if (v.lightSampled) {
        const int r = shadow.count++;
        ++counters->rays;  // counted whether traced or not
        ++counters->shadowRays;
        shadow.origin[r] = v.spawn;
        shadow.key[r] = ShadowRay(v.spawn, v.ls, &shadow.dir[r], &shadow.tMax[r])
                            ? uint16_t(v.ls.light % kShadowGroups)
                            : kVisible;
        g->shadowPath[r] = uint16_t(j);
        g->neeBase[r] = v.neeBase;
        g->neeScale[r] = v.neeScale;
      }
      if (!v.continues) continue;
      s.wi = v.wi;
      s.pdfDir = v.pdfDir;
      if constexpr (kMedium) s.origin = v.spawn;
      if (lightPaths_) {  // read by light tracing's weights alone
        s.pBefore = s.pPrev;
        s.nBefore = s.nPrev;
        s.hasBefore = s.hasNormal;
      }
      s.pPrev = scattered ? v.x : hit.p;
      s.nPrev = v.n;
      s.hasNormal = !scattered;
      s.total = v.total;
      if constexpr (!kMedium) {
        // The next vertex's numbers: vertex d's sets start at kProbeSets + (d - 1) kVertexSets,
        // and a sampler restarted at an even vertex's computes that vertex's sets and the next
        // one's together (kSobolChunk = 2 kVertexSets), so they are drawn together. Restarted,
        // as the group's paths share their batch's sampler. Its light tables load while the
        // rays are traced.
        static_assert(kSobolChunk == 2 * kVertexSets);
        if ((bounce + 1) % 2 == 0) {
          S& sampler = samplers[g->batch[j]];
          sampler.StartSample(uint64_t(g->index[j]), kProbeSets + uint64_t(bounce) * kVertexSets);
          DrawTwoVertices(sampler, &g->vertex[j], &g->after[j]);
        } else {
          g->vertex[j] = g->after[j];
        }
        if (lightSampling_) lights_.Prefetch(g->vertex[j].light);
      }
      nextOrigin[nextRays] = v.spawn;
      nextDir[nextRays] = v.wi;
      next[nextRays++] = uint16_t(j);
    }

    // Each light sample's contribution is added after its vertex's emission and before the next
    // vertex's, as the path meets them.
    TraceShadowRays(tracer_, kShadowGroups, /*sharedOrigin=*/false, &shadow, g->observer);
    for (int r = 0; r < shadow.count; ++r) {
      const Vec3d tr =
          Arrived<kMedium>(!shadow.Reaches(r), shadow.origin[r], shadow.dir[r], shadow.tMax[r]);
      if (MaxComponent(tr) > 0)
        g->path[g->shadowPath[r]].radiance += g->neeBase[r] * tr * g->neeScale[r];
    }
    // The next wave, in the order of this one: neighbouring rays start from neighbouring points.
    // The hits just read are overwritten only now.
    IntersectRays<kWidth>(tracer_, std::span<const Vec3f>(nextOrigin, size_t(nextRays)), nextDir,
                          nextRays, g->hit, g->found, RayKind::kBounce, g->observer);
    counters->rays += nextRays;
    std::copy(next, next + nextRays, g->active);
    count = nextRays;
  }
}

template <bool kMedium, int kWidth>
void ProbeIntegrator::AddToSums(const Probe& probe, const Group<kWidth>& g,
                                std::span<const BatchWork> work) const {
  const int order = settings_.shOrder;
  const ShadowRays<kWidth>& shadow = g.probeShadow;
  for (int j = 0; j < g.n; ++j) {
    const std::span<double> sum = work[g.batch[j]].sum;
    // The light sample first, then the path.
    if (probe.lightSample && shadow.slot[j] != kNoRay) {
      const LightSample& ls = g.light[j];  // read in place: a copy would be zeroed first
      const Vec3d tr =
          Arrived<kMedium>(!shadow.Reaches(j), probe.origin, shadow.dir[j], shadow.tMax[j]);
      if (MaxComponent(tr) > 0) {
        const double wOverPdf = mis_ ? PowerHeuristicOverPdf(ls.pdf, probe.pdf) : 1 / ls.pdf;
        Project(order, ls.wi, ls.radiance * tr * wOverPdf, sum);
      }
    }
    const Vec3d& radiance = g.path[j].radiance;
    if (MaxComponent(radiance) > 0) Project(order, g.wi[j], radiance / probe.pdf, sum);
    const PathState& path = g.path[j];
    const std::span<double> transfer = work[g.batch[j]].transfer;
    if (!transfer.empty() && path.escaped && MaxComponent(path.skyBeta) > 0)
      ProjectTransfer(order, g.wi[j], 1 / probe.pdf, skyOrder_, path.skyDir, path.skyBeta,
                      transfer);
    const std::span<double> moments = work[g.batch[j]].moments;
    if (!moments.empty()) {
      const double s = InverseDistance(g.path[j].firstHit, work[g.batch[j]].maxDistance);
      double* m = &moments[3 * size_t(VisibilityTexel(g.wi[j]))];
      m[0] += s;
      m[1] += s * s;
      m[2] += 1;
    }
  }
}

[[gnu::always_inline]] inline const Vec3d* ProbeIntegrator::Arrive(
    bool found, const SurfaceHit& hit, int bounce, const Vec3d& pPrev, const Vec3d* nPrev,
    std::span<const double> importancePrev, double totalPrev, const Vec3d& wi, double pdfDir,
    const LightPathContext& context, const Vec3d& beta, Vec3d* radiance, Vec3d* albedoHere) const {
  if (!found) {
    if (countEmission_) {
      lights_.ForEachEscaped(pPrev, nPrev, importancePrev, totalPrev, wi, [&](const LightHit& h) {
        double w = 1.0;
        if (lightPaths_ && nPrev && lightPaths_->Traces(h.light)) {
          // A sun's cone found from a surface: light tracing makes the same path too.
          const double other =
              lightPaths_->OtherDensitySquared(h.light, pPrev, *nPrev, wi, context.d1,
                                               context.xBefore, context.nBefore, context.batch);
          w = pdfDir * pdfDir / (pdfDir * pdfDir + h.pdf * h.pdf + other);
        } else if (mis_) {
          w = PowerHeuristic(pdfDir, h.pdf);
        }
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
  const TriangleMesh& mesh = scene_.meshes[hit.index];
  const Material& material = scene_.materials[mesh.material];
  if (!material.AlbedoVaries()) return &material.albedo;
  *albedoHere = AlbedoAt(material, mesh, hit.prim, hit.u, hit.v);
  return albedoHere;
}

[[gnu::always_inline]] inline void ProbeIntegrator::ShadeSurface(
    const SurfaceHit& hit, const Vec3d& wi, const Vec3d& albedo, const VertexNumbers& u, int bounce,
    const LightPathContext& context, std::span<double> importance, Vec3d* beta, Vertex* v) const {
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
      if (lightPaths_ && lightPaths_->Traces(v->ls.light)) {
        // A directional light: light tracing makes the same path too (distant_light_paths.h).
        const double other =
            lightPaths_->OtherDensitySquared(v->ls.light, hit.p, v->n, v->ls.wi, context.d1,
                                             context.xPrev, context.nPrev, context.batch);
        const double pdf = v->ls.pdf, bsdf = v->ls.delta ? 0.0 : pdfBsdf;
        v->neeScale = pdfBsdf * pdf / (pdf * pdf + bsdf * bsdf + other);
      } else {
        v->neeScale = pdfBsdf * ((mis_ && !v->ls.delta) ? PowerHeuristicOverPdf(v->ls.pdf, pdfBsdf)
                                                        : 1 / v->ls.pdf);
      }
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

[[gnu::always_inline]] inline void ProbeIntegrator::ShadeMedium(const Vec3d& x, const Vec3d& wi,
                                                                const VertexNumbers& u, int bounce,
                                                                std::span<double> importance,
                                                                Vec3d* beta, Vertex* v) const {
  v->x = x;
  v->spawn = Vec3f(x);
  const double g = medium_->g();
  v->total = lights_.Importance(x, nullptr, /*includeDelta=*/true, importance);
  v->lightSampled = false;
  if (lightSampling_ && v->total > 0 &&
      lights_.Sample(x, nullptr, importance, v->total, u.select, u.light, &v->ls)) {
    // Light propagating along -ls.wi leaves along -wi: cos theta = Dot(ls.wi, wi).
    const double phase = HenyeyGreensteinPdf(Dot(v->ls.wi, wi), g);
    const double w = (mis_ && !v->ls.delta) ? PowerHeuristic(v->ls.pdf, phase) : 1.0;
    v->lightSampled = true;
    v->neeBase = *beta * v->ls.radiance;
    v->neeScale = phase * w / v->ls.pdf;
  }

  v->continues = false;
  // Sample where the light came from: its propagation direction dIn is HG-distributed about the
  // outgoing one, -wi (the phase function is symmetric in the two).
  const Vec3d local = SampleHenyeyGreenstein(u.next, g);
  const Vec3d dIn = Framed::FromZ(-wi).FromLocal(local);
  v->pdfDir = HenyeyGreensteinPdf(local.z, g);  // phase / pdf = 1: beta is unchanged
  if (settings_.russianRoulette && bounce >= settings_.rrMinDepth) {
    const double survive = std::min(1.0, MaxComponent(*beta));
    if (u.roulette >= survive) return;
    *beta = *beta / survive;
  }
  v->wi = Normalize(-dIn);
  v->continues = true;
}

}  // namespace probebake
