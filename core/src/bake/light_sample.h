// What sampling a light, or finding one with a ray, returns (emitter.h, light_set.h), and the
// three ways a light can be found.
//
// Units: pdfs per steradian, with the probability of choosing the light included once LightSet
// has chosen it; for delta lights `pdf` is that selection probability alone and `radiance` is the
// delta's weight (I / d^2 for point lights, E for directional ones). Positions are the tracer's
// local coordinates (tracer_scene.h).
#pragma once

#include <cstdint>

#include "probebake/math/vec3.h"

namespace probebake {

struct LightSample {
  Vec3d wi;             // unit, from the shading point toward the light
  double distance = 0;  // to the sampled point; infinity for distant lights
  Vec3d point;          // the sampled point (local), when `distance` is finite
  // Largest magnitude of the float coordinates Embree holds for the light's surface (0 for
  // points and distant lights): the scale of the float error where a shadow ray meets it.
  double vertexScale = 0;
  Vec3d radiance;  // arriving along -wi
  double pdf = 0;  // per steradian, selection included (delta: selection pmf)
  bool delta = false;
  uint32_t light = 0;  // which light
};

// A light a ray reached: an area light's surface, an emissive triangle, or the sky.
struct LightHit {
  uint32_t light = 0;
  Vec3d radiance;  // emitted toward the ray's origin
  double pdf = 0;  // the pdf NEE would have had for this direction at the ray's origin
};

// How a light is met besides by sampling it (emitter.h: each kind's family names which of the
// three evaluations it has).
enum class EmitterFamily : uint8_t {
  kDelta,    // one direction from each point (EvalDelta), projected exactly at the probe; never hit
  kSurface,  // a surface that rays hit (EvalHit)
  kDistant,  // at infinity, found by rays that escape the scene (EvalEscaped)
};

}  // namespace probebake
