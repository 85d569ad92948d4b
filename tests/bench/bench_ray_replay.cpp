#include "bench_ray_replay.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

#include "bench_embree_scene.h"
#include "bench_util.h"
#include "core/src/bake/tracer_scene.h"
#include "probebake/base/check.h"
#include "probebake/base/status.h"
#include "probebake/sampling/hash.h"

namespace probebake::bench {
namespace {

constexpr int kLanes = 8;
constexpr uint64_t kSectionSalt = 0x5ec7;

// A cast ray, compact: what the timed loops read.
struct Ray {
  Vec3f origin, dir;
  float tnear, tfar;
  bool shadow;
};

// A packet of the "packet8" replay: up to 8 rays of one kind, by index into the rays.
struct Packet {
  uint32_t ray[kLanes];
  uint8_t count = 0;
  bool shadow = false;
  bool coherent = false;
};

void FillRay(const Ray& r, RTCRay* ray) {
  ray->org_x = r.origin.x, ray->org_y = r.origin.y, ray->org_z = r.origin.z;
  ray->tnear = r.tnear;
  ray->dir_x = r.dir.x, ray->dir_y = r.dir.y, ray->dir_z = r.dir.z;
  ray->time = 0;
  ray->tfar = r.tfar;
  ray->mask = 0xFFFFFFFFu;
  ray->id = 0;
  ray->flags = 0;
}

void FillLane(const Ray& r, int k, RTCRay8* ray) {
  ray->org_x[k] = r.origin.x, ray->org_y[k] = r.origin.y, ray->org_z[k] = r.origin.z;
  ray->tnear[k] = r.tnear;
  ray->dir_x[k] = r.dir.x, ray->dir_y[k] = r.dir.y, ray->dir_z[k] = r.dir.z;
  ray->time[k] = 0;
  ray->tfar[k] = r.tfar;
  ray->mask[k] = 0xFFFFFFFFu;
  ray->id[k] = 0;
  ray->flags[k] = 0;
}

Ray Compact(const ObservedRay& o) {
  return {o.origin, o.dir, o.tnear, o.tfar, o.kind == RayKind::kShadow};
}

std::atomic<uint64_t> g_sink{0};

}  // namespace

const char* RayKindName(RayKind kind) {
  switch (kind) {
    case RayKind::kProbe:
      return "probe";
    case RayKind::kBounce:
      return "bounce";
    case RayKind::kShadow:
      return "shadow";
  }
  return "?";
}

bool BakeSection::Contains(uint64_t probeKey) const {
  return stride <= 1 || Hash(probeKey, kSectionSalt) % stride == 0;
}

bool RayRecorder::BeginCall(uint64_t probeKey, uint32_t, int64_t) {
  if (!section_.Contains(probeKey)) return false;
  ++calls_;
  return true;
}

void RayRecorder::OnRays(std::span<const ObservedRay> rays) {
  rays_.insert(rays_.end(), rays.begin(), rays.end());
}

int64_t RayRecorder::Count(RayKind kind, bool castOnly) const {
  int64_t n = 0;
  for (const ObservedRay& r : rays_) n += r.kind == kind && (r.cast || !castOnly);
  return n;
}

bool SectionTimer::BeginCall(uint64_t probeKey, uint32_t, int64_t) {
  inSection_ = section_.Contains(probeKey);
  if (inSection_) start_ = ThreadCpuSeconds();
  return false;
}

void SectionTimer::EndCall() {
  if (!inSection_) return;
  seconds_ += ThreadCpuSeconds() - start_;
  ++calls_;
  inSection_ = false;
}

struct RayReplay::Impl {
  EmbreeScene embree;
  std::vector<ObservedRay> observed;
  std::vector<Ray> rays;                // the cast rays, in cast order
  std::vector<RayKind> kinds;           // by ray
  std::vector<uint32_t> observedIndex;  // by ray: its index in `observed`

  // One pass over `order` (indices into rays) one by one; returns a checksum.
  uint64_t Single(const std::vector<uint32_t>& order) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    uint64_t sum = 0;
    for (uint32_t i : order) {
      const Ray& r = rays[i];
      if (r.shadow) {
        RTCRay ray;
        FillRay(r, &ray);
        rtcOccluded1(embree.scene(), &context, &ray);
        sum += ray.tfar < 0;
      } else {
        RTCRayHit rh;
        FillRay(r, &rh.ray);
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(embree.scene(), &context, &rh);
        sum += rh.hit.primID;
      }
    }
    return sum;
  }

  uint64_t Packets(const std::vector<Packet>& packets) const {
    RTCIntersectContext coherent, incoherent;
    rtcInitIntersectContext(&coherent);
    rtcInitIntersectContext(&incoherent);
    coherent.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    incoherent.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
    uint64_t sum = 0;
    for (const Packet& p : packets) {
      alignas(32) int valid[kLanes];
      RTCIntersectContext* context = p.coherent ? &coherent : &incoherent;
      if (p.shadow) {
        alignas(32) RTCRay8 ray;
        for (int k = 0; k < kLanes; ++k) {
          valid[k] = k < p.count ? -1 : 0;
          FillLane(rays[p.ray[k < p.count ? k : 0]], k, &ray);
        }
        rtcOccluded8(valid, embree.scene(), context, &ray);
        for (int k = 0; k < p.count; ++k) sum += ray.tfar[k] < 0;
      } else {
        alignas(32) RTCRayHit8 rh;
        for (int k = 0; k < kLanes; ++k) {
          valid[k] = k < p.count ? -1 : 0;
          FillLane(rays[p.ray[k < p.count ? k : 0]], k, &rh.ray);
          rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
          rh.hit.primID[k] = RTC_INVALID_GEOMETRY_ID;
          rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
        }
        rtcIntersect8(valid, embree.scene(), context, &rh);
        for (int k = 0; k < p.count; ++k) sum += rh.hit.primID[k];
      }
    }
    return sum;
  }

  // The rays of `kind` (all when null) in cast order.
  std::vector<uint32_t> Order(const RayKind* kind) const {
    std::vector<uint32_t> order;
    for (uint32_t i = 0; i < rays.size(); ++i)
      if (!kind || kinds[i] == *kind) order.push_back(i);
    return order;
  }

  // Packets of 8 consecutive rays of one kind among `order`: each kind fills its own packet, which
  // is traced once full; the partly filled ones at the end.
  std::vector<Packet> MakePackets(const std::vector<uint32_t>& order) const {
    std::vector<Packet> packets;
    Packet pending[kRayKinds];
    auto flush = [&](Packet& p) {
      if (p.count == 0) return;
      p.coherent = true;
      for (int k = 1; k < p.count; ++k) {
        const Vec3f& a = rays[p.ray[0]].origin;
        const Vec3f& b = rays[p.ray[k]].origin;
        p.coherent = p.coherent && a.x == b.x && a.y == b.y && a.z == b.z;
      }
      packets.push_back(p);
      p = Packet{};
    };
    for (uint32_t i : order) {
      Packet& p = pending[int(kinds[i])];
      p.shadow = rays[i].shadow;
      p.ray[p.count++] = i;
      if (p.count == kLanes) flush(p);
    }
    for (Packet& p : pending) flush(p);
    return packets;
  }
};

RayReplay::RayReplay(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
RayReplay::RayReplay(RayReplay&&) noexcept = default;
RayReplay& RayReplay::operator=(RayReplay&&) noexcept = default;
RayReplay::~RayReplay() = default;

absl::StatusOr<RayReplay> RayReplay::Build(const Scene& scene, std::span<const ObservedRay> rays) {
  auto impl = std::make_unique<Impl>();
  int64_t triangles = 0;
  PB_RETURN_IF_ERROR(impl->embree.Build(scene, LocalOrigin(scene), &triangles));
  impl->observed.assign(rays.begin(), rays.end());
  for (uint32_t i = 0; i < rays.size(); ++i) {
    if (!rays[i].cast) continue;
    impl->rays.push_back(Compact(rays[i]));
    impl->kinds.push_back(rays[i].kind);
    impl->observedIndex.push_back(i);
  }
  return RayReplay(std::move(impl));
}

ReplayRate RayReplay::Measure(const std::string& api, const RayKind* kind, double minSeconds,
                              int repeats) const {
  const std::vector<uint32_t> order = impl_->Order(kind);
  const bool packets = api == "packet8";
  const std::vector<Packet> packetList =
      packets ? impl_->MakePackets(order) : std::vector<Packet>{};
  auto pass = [&] { return packets ? impl_->Packets(packetList) : impl_->Single(order); };
  ReplayRate rate;
  rate.rays = kind ? RayKindName(*kind) : "all";
  rate.api = api;
  rate.count = int64_t(order.size());
  if (order.empty()) return rate;
  // Passes per repeat: enough for minSeconds at the first pass's speed.
  double c0 = ThreadCpuSeconds();
  uint64_t sum = pass();
  const double first = std::max(ThreadCpuSeconds() - c0, 1e-6);
  const int passes = std::max(1, int(std::ceil(minSeconds / first)));
  std::vector<double> rates;
  for (int r = 0; r < repeats; ++r) {
    c0 = ThreadCpuSeconds();
    for (int p = 0; p < passes; ++p) sum += pass();
    const double cpu = std::max(ThreadCpuSeconds() - c0, 1e-9);
    rates.push_back(double(order.size()) * passes / cpu * 1e-6);
  }
  g_sink.fetch_add(sum, std::memory_order_relaxed);
  rate.cpuMraysPerSecond = Median(rates);
  return rate;
}

std::vector<std::pair<bool, float>> RayReplay::ReplayAsCast() const {
  const Impl& m = *impl_;
  const RTCScene scene = m.embree.scene();
  std::vector<std::pair<bool, float>> out(m.observed.size(), {false, 0.0f});
  for (size_t i = 0; i < m.rays.size();) {
    const ObservedRay& head = m.observed[m.observedIndex[i]];
    const bool shadow = head.kind == RayKind::kShadow;
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    if (!head.packed) {
      if (shadow) {
        RTCRay ray;
        FillRay(m.rays[i], &ray);
        rtcOccluded1(scene, &context, &ray);
        out[m.observedIndex[i]] = {ray.tfar < 0, 0.0f};
      } else {
        RTCRayHit rh;
        FillRay(m.rays[i], &rh.ray);
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(scene, &context, &rh);
        const bool hit = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
        out[m.observedIndex[i]] = {hit, hit ? rh.ray.tfar : 0.0f};
      }
      ++i;
      continue;
    }
    // A packet as the tracer cast it: its lanes in order, the inactive ones holding lane 0's ray
    // (length 0 for occlusion), the same flag.
    const size_t n = head.lanes;
    PB_CHECK(head.lane == 0 && i + n <= m.rays.size());
    context.flags =
        head.coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
    alignas(32) int valid[kLanes];
    for (int k = 0; k < kLanes; ++k) valid[k] = size_t(k) < n ? -1 : 0;
    auto laneRay = [&](int k) {
      if (size_t(k) < n) return m.rays[i + size_t(k)];
      Ray r = m.rays[i];
      r.tfar = shadow ? 0.0f : std::numeric_limits<float>::infinity();
      return r;
    };
    if (shadow) {
      alignas(32) RTCRay8 ray;
      for (int k = 0; k < kLanes; ++k) FillLane(laneRay(k), k, &ray);
      rtcOccluded8(valid, scene, &context, &ray);
      for (size_t k = 0; k < n; ++k) out[m.observedIndex[i + k]] = {ray.tfar[k] < 0, 0.0f};
    } else {
      alignas(32) RTCRayHit8 rh;
      for (int k = 0; k < kLanes; ++k) {
        FillLane(laneRay(k), k, &rh.ray);
        rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
        rh.hit.primID[k] = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
      }
      rtcIntersect8(valid, scene, &context, &rh);
      for (size_t k = 0; k < n; ++k) {
        const bool hit = rh.hit.geomID[k] != RTC_INVALID_GEOMETRY_ID;
        out[m.observedIndex[i + k]] = {hit, hit ? rh.ray.tfar[k] : 0.0f};
      }
    }
    i += n;
  }
  return out;
}

}  // namespace probebake::bench
