#include "bench_raw_embree.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <thread>
#include <variant>

#include "bench_embree_scene.h"
#include "bench_util.h"
#include "core/src/bake/tracer_scene.h"
#include "probebake/base/status.h"
#include "probebake/math/frame.h"
#include "probebake/sampling/hash.h"
#include "probebake/sampling/sampler.h"
#include "probebake/sampling/warps.h"

namespace probebake::bench {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr int kRows = 32, kCols = 64;  // direction cells per probe: z rows x phi columns

struct Ray {
  Vec3f origin, dir;
  float tfar = kInf;
};

void FillRay(const Ray& r, RTCRay* ray) {
  ray->org_x = r.origin.x, ray->org_y = r.origin.y, ray->org_z = r.origin.z;
  ray->tnear = 0;
  ray->dir_x = r.dir.x, ray->dir_y = r.dir.y, ray->dir_z = r.dir.z;
  ray->time = 0;
  ray->tfar = r.tfar;
  ray->mask = 0xFFFFFFFFu;
  ray->id = 0;
  ray->flags = 0;
}

// Traces rays [begin, end) once; returns a checksum so the work cannot be optimised away.
using TraceFn = std::function<uint64_t(const std::vector<Ray>&, size_t, size_t)>;

uint64_t Intersect1(RTCScene scene, const std::vector<Ray>& rays, size_t begin, size_t end) {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  uint64_t sum = 0;
  for (size_t i = begin; i < end; ++i) {
    RTCRayHit rh;
    FillRay(rays[i], &rh.ray);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene, &context, &rh);
    sum += rh.hit.primID;
  }
  return sum;
}

uint64_t Occluded1(RTCScene scene, const std::vector<Ray>& rays, size_t begin, size_t end) {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  uint64_t sum = 0;
  for (size_t i = begin; i < end; ++i) {
    RTCRay ray;
    FillRay(rays[i], &ray);
    rtcOccluded1(scene, &context, &ray);
    sum += ray.tfar < 0 ? 1 : 0;
  }
  return sum;
}

// Lane k of a ray packet (RTCRay4/8/16), set as FillRay sets a single ray.
template <typename RayN>
void FillLane(const Ray& r, int k, RayN* ray) {
  ray->org_x[k] = r.origin.x, ray->org_y[k] = r.origin.y, ray->org_z[k] = r.origin.z;
  ray->tnear[k] = 0;
  ray->dir_x[k] = r.dir.x, ray->dir_y[k] = r.dir.y, ray->dir_z[k] = r.dir.z;
  ray->time[k] = 0;
  ray->tfar[k] = r.tfar;
  ray->mask[k] = 0xFFFFFFFFu;
  ray->id[k] = 0;
  ray->flags[k] = 0;
}

template <int N, typename RayHitN>
void CallIntersect(const int* valid, RTCScene scene, RTCIntersectContext* context, RayHitN* rh) {
  if constexpr (N == 4) rtcIntersect4(valid, scene, context, rh);
  if constexpr (N == 8) rtcIntersect8(valid, scene, context, rh);
  if constexpr (N == 16) rtcIntersect16(valid, scene, context, rh);
}

// Packets of N consecutive rays (begin and end multiples of N).
template <int N, typename RayHitN>
uint64_t IntersectN(RTCScene scene, bool coherent, const std::vector<Ray>& rays, size_t begin,
                    size_t end) {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  context.flags =
      coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
  alignas(64) int valid[N];
  std::fill(valid, valid + N, -1);
  uint64_t sum = 0;
  for (size_t i = begin; i + N <= end; i += N) {
    alignas(64) RayHitN rh;
    for (int k = 0; k < N; ++k) {
      FillLane(rays[i + k], k, &rh.ray);
      rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
      rh.hit.primID[k] = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
    }
    CallIntersect<N>(valid, scene, &context, &rh);
    for (int k = 0; k < N; ++k) sum += rh.hit.primID[k];
  }
  return sum;
}

// Occlusion packets of 8 consecutive rays (begin and end multiples of 8), incoherent.
uint64_t Occluded8(RTCScene scene, const std::vector<Ray>& rays, size_t begin, size_t end) {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  alignas(32) int valid[8];
  std::fill(valid, valid + 8, -1);
  uint64_t sum = 0;
  for (size_t i = begin; i + 8 <= end; i += 8) {
    alignas(32) RTCRay8 ray;
    for (int k = 0; k < 8; ++k) FillLane(rays[i + k], k, &ray);
    rtcOccluded8(valid, scene, &context, &ray);
    for (int k = 0; k < 8; ++k) sum += ray.tfar[k] < 0 ? 1 : 0;
  }
  return sum;
}

std::atomic<uint64_t> g_sink{0};

// Runs `trace` over `rays` split into `threads` slices (aligned to `align` rays), `passes` times.
// Returns {wall seconds, summed thread CPU seconds}.
std::pair<double, double> RunPasses(const TraceFn& trace, const std::vector<Ray>& rays, int threads,
                                    int passes, size_t align) {
  // One slice runs on the calling thread: a thread of its own would be placed on another CPU
  // than the bake it is compared with (bench_util.h, CpuPin).
  if (threads == 1) {
    const size_t end = rays.size() / align * align;
    const double w0 = WallSeconds(), c0 = ThreadCpuSeconds();
    uint64_t sum = 0;
    for (int p = 0; p < passes; ++p) sum += trace(rays, 0, end);
    const double cpu = ThreadCpuSeconds() - c0, wall = WallSeconds() - w0;
    g_sink.fetch_add(sum, std::memory_order_relaxed);
    return {wall, cpu};
  }
  std::vector<double> cpu(threads, 0);
  std::vector<std::thread> workers;
  std::atomic<int> ready{0};
  std::atomic<bool> go{false};
  const size_t blocks = rays.size() / align;
  double start = 0;
  for (int t = 0; t < threads; ++t) {
    workers.emplace_back([&, t] {
      const size_t begin = blocks * t / threads * align, end = blocks * (t + 1) / threads * align;
      ready.fetch_add(1);
      while (!go.load(std::memory_order_acquire)) std::this_thread::yield();
      const double c0 = ThreadCpuSeconds();
      uint64_t sum = 0;
      for (int p = 0; p < passes; ++p) sum += trace(rays, begin, end);
      cpu[t] = ThreadCpuSeconds() - c0;
      g_sink.fetch_add(sum, std::memory_order_relaxed);
    });
  }
  while (ready.load() < threads) std::this_thread::yield();
  start = WallSeconds();
  go.store(true, std::memory_order_release);
  for (std::thread& w : workers) w.join();
  const double wall = WallSeconds() - start;
  double cpuSum = 0;
  for (double c : cpu) cpuSum += c;
  return {wall, cpuSum};
}

RawRate Measure(const std::string& what, const std::string& api, const TraceFn& trace,
                const std::vector<Ray>& rays, int threads, double minSeconds, int repeats,
                size_t align) {
  // Passes per repeat: enough for minSeconds at the single-pass speed.
  const auto [probeWall, probeCpu] = RunPasses(trace, rays, threads, 1, align);
  (void)probeCpu;
  const int passes = std::max(1, int(std::ceil(minSeconds / std::max(probeWall, 1e-6))));
  const double traced = double(rays.size() / align * align) * passes;
  std::vector<double> wallRates, cpuRates;
  for (int r = 0; r < repeats; ++r) {
    const auto [wall, cpu] = RunPasses(trace, rays, threads, passes, align);
    wallRates.push_back(traced / wall * 1e-6);
    cpuRates.push_back(traced / cpu * 1e-6);
  }
  RawRate rate;
  rate.rays = what;
  rate.api = api;
  rate.threads = threads;
  rate.raysPerPass = double(rays.size() / align * align);
  rate.wallMraysPerSecond = Median(wallRates);
  rate.cpuMraysPerSecond = Median(cpuRates);
  return rate;
}

// Probe rays: one jittered direction per (row, column) cell. Tiled order: 4x4 blocks of cells,
// each made of two 4x2 halves made of two 2x2 quads, so every aligned run of 4, 8 or 16 rays is
// a compact tile of neighbouring directions. Random order: a hash-keyed shuffle of every ray of
// every probe.
void MakeProbeRays(const std::vector<Vec3d>& probes, const Vec3d& offset, std::vector<Ray>* tiled,
                   std::vector<Ray>* random) {
  for (size_t p = 0; p < probes.size(); ++p) {
    const Vec3f origin(probes[p] - offset);
    IndependentSampler sampler(17, p);
    std::vector<Ray> cells(kRows * kCols);
    for (int row = 0; row < kRows; ++row) {
      for (int col = 0; col < kCols; ++col) {
        sampler.StartSample(uint64_t(row * kCols + col));
        const Vec2d jitter = sampler.Get2D();
        const Vec3d w = SampleUniformSphere({(row + jitter.x) / kRows, (col + jitter.y) / kCols});
        cells[row * kCols + col] = {origin, Vec3f(w), kInf};
      }
    }
    for (int br = 0; br < kRows; br += 4)
      for (int bc = 0; bc < kCols; bc += 4)
        for (int half = 0; half < 2; ++half)
          for (int quad = 0; quad < 2; ++quad)
            for (int r = 0; r < 2; ++r)
              for (int c = 0; c < 2; ++c)
                tiled->push_back(cells[(br + 2 * half + r) * kCols + bc + 2 * quad + c]);
  }
  std::vector<std::pair<uint64_t, size_t>> keys(tiled->size());
  for (size_t i = 0; i < tiled->size(); ++i) keys[i] = {Hash(uint64_t(i), uint64_t(99)), i};
  std::sort(keys.begin(), keys.end());
  for (const auto& k : keys) random->push_back((*tiled)[k.second]);
}

}  // namespace

const RawRate* RawEmbreeResult::Find(const std::string& rays, const std::string& api,
                                     int threads) const {
  for (const RawRate& r : rates)
    if (r.rays == rays && r.api == api && r.threads == threads) return &r;
  return nullptr;
}

absl::StatusOr<RawEmbreeResult> MeasureRawEmbree(const BakeJob& job,
                                                 const std::vector<Vec3d>& probes,
                                                 double minSeconds, int repeats, int maxThreads) {
  RawEmbreeResult result;
  result.probes = int64_t(probes.size());
  const Vec3d offset = LocalOrigin(job.scene);
  EmbreeScene embree;
  const double buildStart = WallSeconds();
  PB_RETURN_IF_ERROR(embree.Build(job.scene, offset, &result.triangles));
  result.buildSeconds = WallSeconds() - buildStart;
  const RTCScene scene = embree.scene();

  std::vector<Ray> tiled, random;
  MakeProbeRays(probes, offset, &tiled, &random);

  // First hits of the random probe rays: origins of bounce and shadow rays.
  std::vector<Ray> bounce, shadow;
  {
    const RectLight* rect = nullptr;
    const SphereLight* sphere = nullptr;
    const DiskLight* disk = nullptr;
    Vec3d toSun;
    bool sun = false;
    for (const Light& light : job.scene.lights) {
      if (!rect && !sphere && !disk) {
        rect = std::get_if<RectLight>(&light);
        sphere = std::get_if<SphereLight>(&light);
        disk = std::get_if<DiskLight>(&light);
      }
      if (const auto* d = std::get_if<DirectionalLight>(&light); d && !sun) {
        toSun = -d->direction;
        sun = true;
      }
    }
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    for (size_t i = 0; i < random.size(); ++i) {
      RTCRayHit rh;
      FillRay(random[i], &rh.ray);
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(scene, &context, &rh);
      if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
      Vec3d n = Normalize(Vec3d{rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z});
      const Vec3d dir(random[i].dir);
      if (Dot(n, dir) > 0) n = -n;
      const Vec3d hit = Vec3d(random[i].origin) + dir * double(rh.ray.tfar);
      const Vec3d origin = hit + n * 1e-4 * (1 + MaxComponent(Abs(hit)));
      IndependentSampler sampler(23, i);
      sampler.StartSample(0);
      const Framed frame = Framed::FromZ(n);
      bounce.push_back(
          {Vec3f(origin), Vec3f(frame.FromLocal(SampleCosineHemisphere(sampler.Get2D()))), kInf});
      const Vec2d u = sampler.Get2D();
      Vec3d target;
      bool finite = (i % 2 == 0);
      if (finite && rect) {
        target = rect->corner + rect->edge1 * u.x + rect->edge2 * u.y - offset;
      } else if (finite && sphere) {
        target = sphere->center + SampleUniformSphere(u) * sphere->radius - offset;
      } else if (finite && disk) {
        const Vec2d d = SampleUniformDiskConcentric(u);
        const Framed f = Framed::FromZ(disk->normal);
        target = disk->center + f.FromLocal({d.x * disk->radius, d.y * disk->radius, 0}) - offset;
      } else {
        finite = false;
      }
      if (finite) {
        const Vec3d v = target - origin;
        const double d = Length(v);
        shadow.push_back({Vec3f(origin), Vec3f(v / d), float(d * (1 - 1e-4))});
      } else {
        const Vec3d w = sun ? toSun : frame.FromLocal(SampleCosineHemisphere(u));
        shadow.push_back({Vec3f(origin), Vec3f(w), kInf});
      }
    }
  }

  for (int threads = 1; threads <= maxThreads; ++threads) {
    auto add = [&](const std::string& what, const std::string& api, const TraceFn& fn,
                   const std::vector<Ray>& rays, size_t align) {
      result.rates.push_back(Measure(what, api, fn, rays, threads, minSeconds, repeats, align));
    };
    const TraceFn i1 = [&](const std::vector<Ray>& r, size_t b, size_t e) {
      return Intersect1(scene, r, b, e);
    };
    const TraceFn o1 = [&](const std::vector<Ray>& r, size_t b, size_t e) {
      return Occluded1(scene, r, b, e);
    };
    auto packets = [&](bool coherent, int n) -> TraceFn {
      if (n == 4)
        return [=](const std::vector<Ray>& r, size_t b, size_t e) {
          return IntersectN<4, RTCRayHit4>(scene, coherent, r, b, e);
        };
      if (n == 8)
        return [=](const std::vector<Ray>& r, size_t b, size_t e) {
          return IntersectN<8, RTCRayHit8>(scene, coherent, r, b, e);
        };
      return [=](const std::vector<Ray>& r, size_t b, size_t e) {
        return IntersectN<16, RTCRayHit16>(scene, coherent, r, b, e);
      };
    };
    add("probe random", "rtcIntersect1", i1, random, 16);
    add("probe tiled", "rtcIntersect1", i1, tiled, 16);
    for (int n : {4, 8, 16}) {
      add("probe random", "rtcIntersect" + std::to_string(n), packets(false, n), random, 16);
      add("probe tiled", "rtcIntersect" + std::to_string(n), packets(true, n), tiled, 16);
    }
    add("bounce", "rtcIntersect1", i1, bounce, 16);
    add("bounce", "rtcIntersect8", packets(false, 8), bounce, 16);
    add("shadow", "rtcOccluded1", o1, shadow, 16);
    add(
        "shadow", "rtcOccluded8",
        [&](const std::vector<Ray>& r, size_t b, size_t e) { return Occluded8(scene, r, b, e); },
        shadow, 16);
  }
  return result;
}

absl::StatusOr<RawRate> MeasureRawProbeRate(const BakeJob& job, const std::vector<Vec3d>& probes,
                                            double minSeconds, int repeats) {
  const Vec3d offset = LocalOrigin(job.scene);
  EmbreeScene embree;
  int64_t triangles = 0;
  PB_RETURN_IF_ERROR(embree.Build(job.scene, offset, &triangles));
  const RTCScene scene = embree.scene();
  std::vector<Ray> tiled, random;
  MakeProbeRays(probes, offset, &tiled, &random);
  const TraceFn i1 = [&](const std::vector<Ray>& r, size_t b, size_t e) {
    return Intersect1(scene, r, b, e);
  };
  return Measure("probe random", "rtcIntersect1", i1, random, 1, minSeconds, repeats, 16);
}

}  // namespace probebake::bench
