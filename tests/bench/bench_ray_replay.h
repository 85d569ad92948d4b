// The tracer against raw Embree on the tracer's own rays. A section of a bake (the
// ProbeIntegrator::TraceBatches calls of a fixed subset of its probes, every batch) is baked once
// with a RayRecorder, which keeps every ray the tracer casts in cast order (first rays from the
// probe, continuation rays, shadow rays: probebake/bake/ray_observer.h), and once more with a
// SectionTimer, which measures the CPU time the tracer spends in those calls without recording.
// The recorded rays are then replayed through raw Embree on the same scene (bench_embree_scene.h):
//  - "single": one by one in cast order, rtcIntersect1 for probe and bounce rays, rtcOccluded1
//    for shadow rays;
//  - "packet8": in 8-wide packets (rtcIntersect8 / rtcOccluded8) of consecutive rays of one kind,
//    in cast order (a packet is traced once its 8th ray of that kind has been cast), with the
//    coherent flag when its rays share one origin (as the tracer flags its own packets).
// The replay's rate is the limit of a tracer that casts these very rays and does nothing else;
// the tracer's rate over the same section, as a fraction of the better replay, says how much of
// its time is not Embree's (shading, sampling, bookkeeping, and rays cast in a costlier order or
// grouping than the replay's). Shadow rays the tracer counts but does not cast (their light point
// within float error of their origin) are left out of both rates.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "probebake/bake/ray_observer.h"
#include "probebake/scene/scene.h"

namespace probebake::bench {

// The section: the probes whose key (ProbeSite::key) hashes to 0 modulo `stride`; all of them
// when stride is 1.
struct BakeSection {
  uint64_t stride = 1;
  bool Contains(uint64_t probeKey) const;
};

// Keeps every ray of the section's calls, in cast order. For a bake on one thread.
class RayRecorder final : public RayObserver {
 public:
  explicit RayRecorder(BakeSection section) : section_(section) {}
  bool BeginCall(uint64_t probeKey, uint32_t firstBatch, int64_t samples) override;
  void EndCall() override {}
  void OnRays(std::span<const ObservedRay> rays) override;

  const std::vector<ObservedRay>& rays() const { return rays_; }
  // Rays of `kind` seen; castOnly: only those cast (ObservedRay::cast).
  int64_t Count(RayKind kind, bool castOnly) const;
  int64_t calls() const { return calls_; }

 private:
  BakeSection section_;
  std::vector<ObservedRay> rays_;
  int64_t calls_ = 0;
};

// Sums the CPU time of the calling thread spent in the section's calls; records no ray. For a
// bake on one thread.
class SectionTimer final : public RayObserver {
 public:
  explicit SectionTimer(BakeSection section) : section_(section) {}
  bool BeginCall(uint64_t probeKey, uint32_t firstBatch, int64_t samples) override;
  void EndCall() override;
  void OnRays(std::span<const ObservedRay>) override {}

  double cpuSeconds() const { return seconds_; }
  int64_t calls() const { return calls_; }

 private:
  BakeSection section_;
  bool inSection_ = false;
  double start_ = 0, seconds_ = 0;
  int64_t calls_ = 0;
};

// Raw Embree's rate on recorded rays.
struct ReplayRate {
  std::string rays;  // "all", "probe", "bounce", "shadow"
  std::string
      api;  // "single" (rtcIntersect1 / rtcOccluded1), "packet8" (rtcIntersect8 / rtcOccluded8)
  int64_t count = 0;             // cast rays replayed per pass
  double cpuMraysPerSecond = 0;  // median over repeats, rays per CPU second of the thread
};

// The rays of `rays` that were cast, as Embree received them, replayed through an Embree scene
// of `scene` built as the tracer builds it, in its local coordinates (LocalOrigin).
class RayReplay {
 public:
  static absl::StatusOr<RayReplay> Build(const Scene& scene, std::span<const ObservedRay> rays);
  RayReplay(RayReplay&&) noexcept;
  RayReplay& operator=(RayReplay&&) noexcept;
  ~RayReplay();

  // The rate of `api` ("single" or "packet8") over the rays of `kind` alone, or all of them
  // (kind null), passes repeated for at least minSeconds per repeat; the median of `repeats`.
  ReplayRate Measure(const std::string& api, const RayKind* kind, double minSeconds,
                     int repeats) const;

  // Embree's answers when each ray is traced as the tracer cast it (alone, or in its own packet
  // with the same lanes and flags): for every observed ray, cast or not, {hit, tHit} (occluded
  // for shadow rays; rays not cast get {false, 0}).
  std::vector<std::pair<bool, float>> ReplayAsCast() const;

 private:
  struct Impl;
  explicit RayReplay(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

const char* RayKindName(RayKind kind);

}  // namespace probebake::bench
