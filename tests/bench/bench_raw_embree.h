// The practical ceiling of a CPU baker: Embree tracing a scene's probe rays with nothing
// else around it. The scene is built as the tracer builds it (tracer_scene.cpp: the same meshes in
// the same local coordinates, area lights as geometry, RTC_SCENE_FLAG_ROBUST, build quality
// HIGH), and rays are made up front so the timed loop only fills Embree's ray structures and
// calls Embree:
//  - probe rays: from each probe, 2048 directions, one per cell of a 32 (z) x 64 (phi) grid over
//    the sphere (jittered), either in random order ("random") or in 4x4 tiles of neighbouring
//    cells ("tiled", the order a packet tracer of first-hit rays would use); rtcIntersect1 and
//    rtcIntersect4/8/16 (4 and 8 native on AVX2, 16 emulated); packets of tiled rays are traced
//    with the coherent context flag;
//  - bounce rays: from the first hits of the random probe rays, cosine-distributed about the
//    surface normal (what a path's continuation rays look like), rtcIntersect1 and rtcIntersect8;
//  - shadow rays: from the same hit points, alternately to a random point on the scene's first
//    finite area light and toward a distant light (the sun's direction, else a cosine direction),
//    rtcOccluded1 and rtcOccluded8.
// The packet rates of bounce and shadow rays are the ceiling of a wavefront tracer that traces
// its paths' incoherent rays 8 at a time.
// Each measurement splits the rays over `threads` threads and repeats whole passes for at least
// `minSeconds`; rates are medians over repeats, per wall second and per CPU second (the latter is
// robust to other work on the machine).
#pragma once

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "probebake/math/vec3.h"
#include "probebake/scene/scene.h"

namespace probebake::bench {

struct RawRate {
  std::string rays;  // "probe random", "probe tiled", "bounce", "shadow"
  std::string api;   // "rtcIntersect1", "rtcIntersect8", "rtcOccluded1", ...
  int threads = 1;
  double raysPerPass = 0;
  double wallMraysPerSecond = 0;  // median over repeats
  double cpuMraysPerSecond = 0;   // rays per CPU second of the tracing threads, median
};

struct RawEmbreeResult {
  int64_t triangles = 0;
  double buildSeconds = 0;
  int64_t probes = 0;
  std::vector<RawRate> rates;

  // The rate of (rays, api, threads), or null.
  const RawRate* Find(const std::string& rays, const std::string& api, int threads) const;
};

// Measures `job`'s scene from the probes at world positions `probes`.
absl::StatusOr<RawEmbreeResult> MeasureRawEmbree(const BakeJob& job,
                                                 const std::vector<Vec3d>& probes,
                                                 double minSeconds, int repeats, int maxThreads);

// The "probe random" rtcIntersect1 rate alone, at 1 thread: the denominator of the tracer's
// fraction, quick enough to measure right after each of several tracer bakes (paired readings).
absl::StatusOr<RawRate> MeasureRawProbeRate(const BakeJob& job, const std::vector<Vec3d>& probes,
                                            double minSeconds, int repeats);

}  // namespace probebake::bench
