// Limits a job must respect (docs/job-format.md): configuration, reported by the server in
// GetCapabilities (the fields mirror probebake.v1.JobLimits one to one). A job past any limit is
// rejected up front with INVALID_ARGUMENT naming the field, never discovered mid-bake.
//
// 0 means "no limit" for every field, as in the proto; the baker's own bounds still apply (SH
// orders 0 to kMaxJobShOrder, grid counts that fit an int32).
#pragma once

#include <cstdint>

namespace probebake {

// The highest SH order a job may ask for (docs/job-format.md: 0 to 8). The SH code itself goes to
// kMaxShOrder (sh_basis.h, 9); the name differs so that no translation unit can see two values.
inline constexpr int kMaxJobShOrder = 8;

// The most a light may emit, in any unit (radiance, intensity, irradiance, emission, a map's
// brightest pixel times its scale): the volume stores 32-bit floats (largest 3.4e38), and
// projection, distances and bounces multiply. Physical skies and suns stay below 1e10.
inline constexpr double kMaxEmitted = 1e30;

struct JobLimits {
  // Probes in the grid (the product of the counts per axis), before placement. A probe costs
  // 12 (L+1)^2 bytes per SH grid plus bookkeeping: 4M probes at order 8 is ~4 GB of radiance.
  int64_t maxProbes = int64_t(1) << 22;
  // Triangles over every mesh of the scene, inline and from files, after triangulation and before
  // zero-area triangles are dropped; a mesh file's instanced meshes count once, however many nodes
  // place them, and each placement as 8 triangles. ~170 bytes each in the scene and the BVH: 16M
  // is ~3 GB.
  int64_t maxTriangles = int64_t(1) << 24;
  // A mesh file whose nodes place at most this many triangles is moved into world space whole
  // (~700 MB at 4M): the fastest to trace. Above it, what several nodes place alike (8 triangles
  // or more) is kept once and instanced (one Embree scene placed per node: a fraction of the memory
  // and build time, each ray 25-35% dearer on docs/performance-history.md's level). Not a limit; 0
  // instances every repeated mesh.
  int64_t flattenUpToTriangles = int64_t(1) << 22;
  // settings.samplesPerProbe (the sample cap of one probe).
  int64_t maxSamplesPerProbe = int64_t(1) << 24;
  // settings.shOrder; never above kMaxJobShOrder whatever this says.
  int maxShOrder = kMaxJobShOrder;
  // settings.maxDepth (bounces per path).
  int maxDepth = 1024;
  // Lights in scene.lights (emissive triangles are not counted).
  int maxLights = 1 << 16;
  // Size of any one referenced asset (mesh or environment map file), bytes.
  int64_t maxAssetBytes = int64_t(1) << 30;
  // Environment map pixels (width * height of the data window): 12 bytes each as float RGB, plus
  // the sampling tables the tracer builds; 64M pixels (e.g. 11k x 5.7k) is ~1.5 GB.
  int64_t maxEnvironmentPixels = int64_t(1) << 26;
  // Pixels of any one texture of a mesh file's materials (width * height), held as 8-bit RGBA:
  // 64M pixels (8k x 8k) is 256 MB. Each image is decoded once per mesh that uses it.
  int64_t maxTexturePixels = int64_t(1) << 26;
};

}  // namespace probebake
