// Every emitter of a scene, for next-event estimation: sampling a direction toward one emitter at a
// shading point, the solid-angle pdf of that choice (for multiple importance sampling against
// direction sampling), and the radiance of emitters found by rays.
//
// Emitters ("lights" below) are, in this order: the scene's lights (index = Scene::lights index),
// one light per emissive mesh, and the environment when it is not black. A light is chosen with
// probability proportional to an importance computed at the shading point: a cheap estimate of the
// irradiance it could deliver there (luminance x area / distance^2 for finite lights, luminance
// x pi for the environment), exactly zero only where the light cannot contribute (behind a
// one-sided emitter, or wholly below the surface's tangent plane). Any positive importance keeps
// the estimator unbiased; a good one lowers variance. The same importance, recomputed at the same
// point, gives the pdf that MIS needs when a sampled direction hits a light.
//
// With many lights (kLightTreeMinLights or more area lights, or as many point and spot lights) the
// choice is made in two steps: the lights of that kind are one entry of the linear choice, whose
// importance is a bounding hierarchy's estimate for all of them, and a walk down the hierarchy
// (light_tree.h) picks one of them in O(log n). Scenes with fewer lights keep the exact linear
// choice.
//
// With a visibility table (SetVisibility, light_visibility.h) each entry's importance is also
// scaled by a factor in (0, 1] for the region of p: the fraction of shadow rays from there that
// reach that light, floored. Sample, the pdfs and MIS all read the scaled importance.
//
// Units: pdfs per steradian and include the selection probability; for delta lights `pdf` is the
// selection probability alone and `radiance` is the delta's weight (I / d^2 for point lights, E for
// directional ones). Positions are the tracer's local coordinates (tracer_scene.h).
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <utility>
#include <vector>

#include "environment_light.h"
#include "light_tree.h"
#include "light_visibility.h"
#include "probebake/math/frame.h"
#include "probebake/math/vec3.h"
#include "probebake/scene/scene.h"
#include "tracer_scene.h"

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

// From this many lights of a kind (area, or point and spot) LightSet chooses among them through a
// light tree. Measured in the demo room at 256 samples per probe, as efficiency (1 / (CPU time x
// variance)) of the tree over the linear choice: with N small lights spread over the ceiling,
// 0.95x at N = 8, 1.7x at 64, 3.4x at 256, 8.5x at 1024; with N mixed point, spot, rect and sphere
// lights scattered through the room's volume, where a cluster's estimate is poorer, 0.55x at 24,
// 0.87x at 96 and 2.3x at 384. The linear choice's own time grows with N (1.7x at 64, 3.6x at 256,
// 10x at 1024, against one light; the tree's 1.3x, 1.5x, 1.6x).
inline constexpr size_t kLightTreeMinLights = 64;

class LightSet {
 public:
  // treeMinLights: the number of lights of a kind from which they are chosen through a light
  // tree (tests lower it to exercise the tree on small scenes).
  LightSet(const Scene& scene, const TracerScene& tracer,
           size_t treeMinLights = kLightTreeMinLights);

  // Number of lights.
  size_t Count() const { return lights_.size(); }
  bool Empty() const { return lights_.empty(); }
  // The size of an importance array: one entry per light chosen linearly, one per light tree.
  size_t ImportanceSize() const { return slots_.size(); }
  // Number of lights chosen through light trees (0 when there are none).
  size_t TreeLightCount() const;

  // Selection importance at local point p of every entry of the linear choice (a light, or a
  // tree's lights together); n is the unit normal of the surface being shaded, oriented to the
  // side the light must reach, or nullptr at a probe (no surface). Delta lights are left out
  // (importance 0) when `includeDelta` is false: the probe projects them exactly. Returns the sum.
  double Importance(const Vec3d& p, const Vec3d* n, bool includeDelta,
                    std::span<double> importance) const;

  // Picks a light by `importance` (computed at (p, n), sum `total` > 0) with uSelect in [0, 1):
  // its index and the probability of picking it, equal bit for bit to SelectionPmf. False when
  // there is nothing to pick (total == 0, or a light tree's walk finds no light that can reach p).
  bool Choose(const Vec3d& p, const Vec3d* n, std::span<const double> importance, double total,
              double uSelect, uint32_t* light, double* pmf) const;
  // The probability that Choose picks `light` at (p, n), given that point's importance array.
  double SelectionPmf(uint32_t light, const Vec3d& p, const Vec3d* n,
                      std::span<const double> importance, double total) const;

  // Samples a point of entry `entry` of the linear choice from p (no surface), as Sample would
  // once that entry is chosen: uTree walks its light tree, if it is one, and u samples the light.
  // False when it cannot light p. For building the visibility table.
  bool SampleEntry(size_t entry, const Vec3d& p, double uTree, const Vec2d& u,
                   LightSample* sample) const;
  // Scales importance by `visibility`'s factors from now on (built for ImportanceSize() entries
  // over this scene). Not thread-safe: call before sampling starts.
  void SetVisibility(LightVisibility visibility) { visibility_ = std::move(visibility); }

  // Chooses a light as Choose does and samples it with u.
  // Returns false when the chosen light cannot light p (the sample then contributes nothing).
  bool Sample(const Vec3d& p, const Vec3d* n, std::span<const double> importance, double total,
              double uSelect, const Vec2d& u, LightSample* sample) const;

  // A hint, no effect on results: starts loading the memory that Sample(..., u, ...) reads if it
  // picks a large environment map. Call it with the u of a later Sample, with work in between.
  void Prefetch(const Vec2d& u) const {
    if (environment_) environment_->Prefetch(u);
  }

  // Whether EvalSurfaceHit can find emission at `hit`: false for the surface of a mesh that does
  // not emit (most hits), cheaply, so that callers skip the call.
  bool MayEmit(const SurfaceHit& hit) const {
    return hit.kind != SurfaceKind::kMesh || meshLight_[hit.index] != UINT32_MAX;
  }
  // A ray from p (normal n as above, importance as computed there) along wi hit `hit`: the
  // emitted radiance toward p and NEE's pdf of that direction. False if the surface hit emits
  // nothing (not a light, or its back side).
  bool EvalSurfaceHit(const Vec3d& p, const Vec3d* n, std::span<const double> importance,
                      double total, const Vec3d& wi, const SurfaceHit& hit, LightHit* out) const;

  // A ray from p along wi escaped the scene: adds every distant light's radiance from wi, each
  // with its own NEE pdf, through `visit(const LightHit&)`.
  template <typename Visit>
  void ForEachEscaped(const Vec3d* n, std::span<const double> importance, double total,
                      const Vec3d& wi, Visit&& visit) const;

  // Delta lights (point, spot, zero-size directional), for the probe's exact projection.
  // Radiance weight and direction of delta light `light` at p: false if it cannot reach p.
  bool EvalDelta(uint32_t light, const Vec3d& p, LightSample* sample) const;
  const std::vector<uint32_t>& deltaLights() const { return deltaLights_; }
  // True when a delta light (delta = true) or any other light (false: area, emissive mesh, sun,
  // environment; what a path or a light sample can find) emits.
  bool HasEmission(bool delta) const;

  // Radiance of the environment alone (escaped rays with no MIS, e.g. the naive estimator).
  const EnvironmentLight* environment() const { return environment_.get(); }
  // Index of the emissive-mesh light of mesh m, or UINT32_MAX when the mesh does not emit.
  uint32_t MeshLight(uint32_t mesh) const { return meshLight_[mesh]; }

 private:
  enum class Kind : uint8_t {
    kPoint,
    kSpot,
    kDirectional,
    kSun,
    kRect,
    kDisk,
    kSphere,
    kMesh,
    kEnv
  };
  // Point, spot and zero-size directional lights: projected exactly at the probe, never hit.
  static bool IsDelta(Kind k) {
    return k == Kind::kPoint || k == Kind::kSpot || k == Kind::kDirectional;
  }
  struct LightData {
    Kind kind;
    Vec3d radiance;  // area lights, sun disk: emitted radiance; point/spot: intensity;
                     // directional: irradiance; mesh: emission
    Vec3d position;  // point/spot; rect corner; disk/sphere centre; mesh bounds centre
    Vec3d axis;      // spot: travel direction; directional/sun: toward the light; rect/disk: normal
    Framed frame;    // sun, disk: Framed::FromZ(axis), built once rather than per sample
    Vec3d edge1, edge2;                  // rect
    Vec3d corners[4];                    // rect: position, +edge1, +edge1+edge2, +edge2
    Vec3d centre;                        // rect
    double radius = 0;                   // disk, sphere; mesh: bounding radius
    double vertexScale = 0;              // rect, disk, sphere, mesh: LightSample::vertexScale
    double area = 0;                     // rect, disk, mesh (total)
    double cosInner = 1, cosOuter = 0;   // spot; sun: cosOuter = cos of the angular radius
    double oneMinusCos = 0;              // sun: 1 - cos(angular radius), without cancellation
    double sinOuter = 0, sin2Outer = 0;  // sun: sin(angular radius) and its square
    bool twoSided = false;
    bool rectangular = false;  // rect with orthogonal edges
    double power = 0;          // luminance of `radiance`
    uint32_t mesh = 0;
    Vec3d boundsMin, boundsMax;  // mesh
  };

  double LightImportance(const LightData& l, const Vec3d& p, const Vec3d* n) const;
  // Choose's body, inlined into Sample.
  bool ChooseInline(const Vec3d& p, const Vec3d* n, std::span<const double> importance,
                    double total, double uSelect, uint32_t* light, double* pmf) const;
  void BuildTrees(size_t treeMinLights);
  bool SampleOne(const LightData& l, uint32_t index, const Vec3d& p, const Vec3d* n, const Vec2d& u,
                 LightSample* s) const;
  double SpotFalloff(const LightData& l, const Vec3d& wFromLight) const;
  bool FinishAreaSample(const LightData& l, const Vec3d& p, const Vec3d& q, double solidAnglePdf,
                        LightSample* s) const;
  // Whether a rect light is sampled by solid angle from p (else by area).
  bool UseSolidAngleSampling(const LightData& l, const Vec3d& p) const;
  // The solid-angle pdf of a rectangular light seen from p, or 0 when it is sampled by area.
  double SolidAnglePdf(const LightData& l, const Vec3d& p) const;

  const Scene* scene_;
  const TracerScene* tracer_;
  std::vector<LightData> lights_;
  std::vector<uint32_t> deltaLights_;
  std::vector<uint32_t> distantLights_;  // suns and the environment
  std::vector<uint32_t> meshLight_;
  // Per emissive mesh light: triangle selection by area.
  std::vector<std::unique_ptr<DiscreteDistribution>> triangleDistribution_;
  std::unique_ptr<EnvironmentLight> environment_;
  uint32_t envLight_ = UINT32_MAX;

  // The linear choice: each entry is one light or one tree (tree >= 0).
  struct Slot {
    uint32_t light = 0;  // plain lights
    int tree = -1;       // index into trees_, or -1
    bool delta = false;  // point/spot/directional light, or the tree of point and spot lights
  };
  std::vector<Slot> slots_;
  std::vector<uint32_t> slotOfLight_;  // per light: its slot, or its tree's slot
  std::vector<int> treeOfLight_;       // per light: index into trees_, or -1
  std::vector<std::unique_ptr<LightTree>> trees_;
  LightVisibility visibility_;  // empty unless SetVisibility was called
};

template <typename Visit>
void LightSet::ForEachEscaped(const Vec3d* n, std::span<const double> importance, double total,
                              const Vec3d& wi, Visit&& visit) const {
  for (uint32_t index : distantLights_) {
    const LightData& l = lights_[index];
    LightHit hit;
    hit.light = index;
    if (l.kind == Kind::kSun) {
      if (Dot(wi, l.axis) < l.cosOuter) continue;
      hit.radiance = l.radiance;
      hit.pdf = total > 0 ? importance[slotOfLight_[index]] / total /
                                (2 * 3.14159265358979323846 * l.oneMinusCos)
                          : 0;
    } else {
      double pdf;
      hit.radiance = environment_->RadianceAndPdf(wi, n, &pdf);
      if (MaxComponent(hit.radiance) <= 0) continue;
      hit.pdf = total > 0 ? importance[slotOfLight_[index]] / total * pdf : 0;
    }
    visit(hit);
  }
}

}  // namespace probebake
