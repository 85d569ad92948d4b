// The lights of a scene, for next-event estimation: choosing one at a shading point, sampling a
// direction toward it, the solid-angle pdf of that choice (for multiple importance sampling against
// direction sampling), and the radiance of lights found by rays. Each kind of light samples,
// bounds and evaluates itself (emitter.h); LightSet builds the list and chooses among it.
//
// Lights are, in this order: the scene's lights (index = Scene::lights index), one light per
// emissive mesh, and the environment when it is not black. A light is chosen with probability
// proportional to its importance at the shading point (emitter.h): any positive importance keeps
// the estimator unbiased; a good one lowers variance. The same importance, recomputed at the same
// point, gives the pdf that MIS needs when a sampled direction hits a light.
//
// With many lights (kLightTreeMinLights or more area lights, or as many point and spot lights) the
// choice is made in two steps: the lights of that kind are one entry of the linear choice, whose
// importance is a bounding hierarchy's estimate for all of them, and a walk down the hierarchy
// (light_tree.h) picks one of them in O(log n). Scenes with fewer lights keep the exact linear
// choice.
//
// With a visibility table (light_visibility.h, given when the set is built) each entry's
// importance is also scaled by a factor in (0, 1] for the region of p: the fraction of shadow rays
// from there that reach that light, floored. Sample, the pdfs and MIS all read the scaled
// importance. The table is traced from the set without it (SampleEntry), which is then rebuilt
// with it: LightSet(LightSet&&, LightVisibility).
//
// Units (light_sample.h): pdfs per steradian and include the selection probability; for delta
// lights `pdf` is the selection probability alone. Positions are the tracer's local coordinates
// (tracer_scene.h). Immutable once built; const methods may be called from any thread.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "emitter.h"
#include "environment_guide.h"
#include "environment_light.h"
#include "light_sample.h"
#include "light_tree.h"
#include "light_visibility.h"
#include "probebake/math/vec3.h"
#include "probebake/scene/scene.h"
#include "tracer_scene.h"

namespace probebake {

// From this many lights of a kind (area, or point and spot) LightSet chooses among them through a
// light tree: below it the tree's poorer estimate of a cluster costs more variance than its
// O(log n) walk saves time (the measurements: docs/performance-history.md).
inline constexpr size_t kLightTreeMinLights = 64;

class LightSet {
 public:
  // The scene's lights, without a visibility table. treeMinLights: the number of lights of a kind
  // from which they are chosen through a light tree (tests lower it to exercise the tree on small
  // scenes). environment false: the scene's environment is left out (black to every ray), as a
  // sky-transfer bake needs (its sky is applied later). `scene` and `tracer` (built from it)
  // outlive the set.
  LightSet(const Scene& scene, const TracerScene& tracer,
           size_t treeMinLights = kLightTreeMinLights, bool environment = true);
  // `lights`, its importance scaled from now on by `visibility`'s factors: a table built for
  // lights.ImportanceSize() entries over this scene (LightVisibility::Build from `lights`), or an
  // empty one.
  LightSet(LightSet&& lights, LightVisibility visibility);
  LightSet(LightSet&&) = default;

  // Samples the environment from now on through `guide` (environment_guide.h; built over this
  // scene), which the set then owns. No effect when the set has no environment. Not thread-safe:
  // call before sampling.
  void SetEnvironmentGuide(std::unique_ptr<EnvironmentGuide> guide);

  // Multiplies the importance of `light` (one of the linear choice, not in a light tree) at
  // surface points (n given) by factor > 0 from now on; at probes and in a medium it is left
  // alone. Not thread-safe: call before sampling.
  void ScaleAtSurfaces(uint32_t light, double factor);

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
  void ForEachEscaped(const Vec3d& p, const Vec3d* n, std::span<const double> importance,
                      double total, const Vec3d& wi, Visit&& visit) const;

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
  // Choose's body, inlined into Sample.
  bool ChooseInline(const Vec3d& p, const Vec3d* n, std::span<const double> importance,
                    double total, double uSelect, uint32_t* light, double* pmf) const;
  void BuildTrees(size_t treeMinLights);

  std::vector<Emitter> lights_;
  std::vector<uint32_t> deltaLights_;
  std::vector<uint32_t> distantLights_;  // suns and the environment
  std::vector<uint32_t> meshLight_;
  std::unique_ptr<EnvironmentLight> environment_;
  std::unique_ptr<EnvironmentGuide> environmentGuide_;

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
  LightVisibility visibility_;        // empty: importance unscaled
  std::vector<double> surfaceScale_;  // per slot, at surfaces (ScaleAtSurfaces); empty: all 1
};

template <typename Visit>
void LightSet::ForEachEscaped(const Vec3d& p, const Vec3d* n, std::span<const double> importance,
                              double total, const Vec3d& wi, Visit&& visit) const {
  for (uint32_t index : distantLights_) {
    LightHit hit;
    hit.light = index;
    const double pmf = total > 0 ? importance[slotOfLight_[index]] / total : 0;
    if (!lights_[index].EvalEscaped(p, wi, n, pmf, &hit)) continue;
    if (!(total > 0)) hit.pdf = 0;  // NEE chooses nothing there, whatever the light's pdf
    visit(hit);
  }
}

}  // namespace probebake
