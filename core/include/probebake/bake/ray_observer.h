// A hook that sees the rays a bake's path tracer casts, for measuring the tracer against Embree on
// its own rays (the bench's ray replay, tests/bench/bench_ray_replay.h). Nothing in the bake
// depends on it: with no observer (BakeOptions::rayObserver null, the default) the tracer checks
// one pointer per call of ProbeIntegrator::TraceBatches and per packet, and bakes the same bits
// with or without one.
//
// Scope: the rays of the probes' sampling (ProbeIntegrator::TraceBatches): each sample's first
// ray from the probe, the continuation rays of its path, the shadow rays of its light samples at
// the probe and at every vertex, and the shadow rays that join the probe and its paths' vertices
// to light traced from directional lights (core/src/bake/distant_light_paths.h), cast one at a
// time. Not seen: placement and validity rays, the light visibility table's rays, the paths traced
// from directional lights (once per bake, shared by the probes) and the shadow rays of delta
// lights at the probe (projected once per probe, outside the batches).
#pragma once

#include <cstdint>
#include <limits>
#include <span>

#include "probebake/math/vec3.h"

namespace probebake {

enum class RayKind : uint8_t {
  kProbe,   // a sample's first ray, from the probe (closest hit)
  kBounce,  // a path's continuation from a surface or medium vertex (closest hit)
  kShadow,  // toward a sampled light point or direction (occlusion only)
};
inline constexpr int kRayKinds = 3;

// One ray as Embree received it (local coordinates, tracer_scene.h), and what Embree answered.
struct ObservedRay {
  Vec3f origin;
  Vec3f dir;  // unit to float rounding
  float tnear = 0;
  float tfar = std::numeric_limits<float>::infinity();
  RayKind kind = RayKind::kProbe;
  // How it was cast: alone (rtcIntersect1 / rtcOccluded1), or (packed) as one of `lanes` active
  // lanes of an 8-wide packet (rtcIntersect8 / rtcOccluded8), lane `lane`, traced with the
  // coherent flag when `coherent` (the packet's rays share one origin) and the incoherent flag
  // otherwise. Not `cast`: a shadow ray whose light point lies within float error of its origin,
  // counted by the tracer and visible without tracing (its tfar is then <= 0).
  bool cast = true;
  bool packed = false;
  bool coherent = false;
  uint8_t lanes = 1;
  uint8_t lane = 0;
  // Closest-hit rays: whether a surface was found and Embree's hit distance (its tfar out).
  // Shadow rays: hit = occluded; tHit unused.
  bool hit = false;
  float tHit = 0;
};

class RayObserver {
 public:
  virtual ~RayObserver() = default;
  // One call of ProbeIntegrator::TraceBatches begins: the probe's key (ProbeSite::key), its
  // first batch and its samples. Returns whether the call's rays are to be reported to OnRays.
  virtual bool BeginCall(uint64_t probeKey, uint32_t firstBatch, int64_t samples) = 0;
  // The call that BeginCall announced has ended (also when it returned false, or the call was
  // cancelled).
  virtual void EndCall() = 0;
  // The rays of one Embree call (a single ray or one packet's active lanes), in the order they
  // were cast; then, after a wave's shadow packets, its shadow rays that needed no tracing.
  virtual void OnRays(std::span<const ObservedRay> rays) = 0;
};
// Threads: a call's BeginCall, OnRays and EndCall come from the thread that runs it, in that
// order; calls of different probes or batch groups run concurrently on a bake of several threads,
// so an observer of such a bake must be thread-safe (or the bake run on one thread).

}  // namespace probebake
