// An emissive mesh as one light (emitter.h's contract, family kSurface): every triangle of a mesh
// whose material emits, emitting from its front side (counter-clockwise) with the material's
// radiance (times its emission map at the point, if any; from both sides when double-sided;
// nothing where a cutout removes it). Sampled by picking a triangle in
// proportion to its area, then a point uniform on it: the area pdf is 1 / (the mesh's area).
// Importance: luminance x area / d^2 to the centre of its bounds (d^2 floored at the area), 0 where
// its bounds lie wholly below p's tangent plane.
#pragma once

#include <algorithm>
#include <optional>
#include <span>

#include "area_emitters.h"
#include "light_sample.h"
#include "light_tree.h"
#include "probebake/math/vec3.h"
#include "probebake/sampling/distribution.h"
#include "probebake/scene/scene.h"
#include "tracer_scene.h"

namespace probebake {

class MeshEmitter {
 public:
  static constexpr EmitterFamily kFamily = EmitterFamily::kSurface;

  // The light of scene.meshes[mesh], or nothing when it emits nothing (black emission, or no
  // triangle of positive area). `scene` and `tracer` (built from it) outlive the light.
  static std::optional<MeshEmitter> Build(const Scene& scene, const TracerScene& tracer,
                                          uint32_t mesh);

  double power() const { return power_; }

  double Importance(const Vec3d& p, const Vec3d* n) const {
    if (n && BoundsBelow(p, *n)) return 0;
    return AreaImportance(power_, area_, centre_, p);
  }
  bool Sample(const Vec3d& p, const Vec3d* n, const Vec2d& u, LightSample* s) const;
  // A ray from p along wi hit one of its triangles (hit.ng, hit.t); pmf: the probability of
  // choosing this light.
  bool EvalHit(const Vec3d& p, const Vec3d& wi, const SurfaceHit& hit, double pmf,
               LightHit* out) const;
  bool TreeItem(LightTree::Item* item) const;

 private:
  MeshEmitter(const TriangleMesh& mesh, const TracerScene& tracer, uint32_t index,
              const Material& material, std::span<const double> triangleAreas);

  // True when every corner of the bounds lies on or below the plane through p with normal n.
  bool BoundsBelow(const Vec3d& p, const Vec3d& n) const {
    for (int k = 0; k < 8; ++k) {
      const Vec3d c{(k & 1) ? hi_.x : lo_.x, (k & 2) ? hi_.y : lo_.y, (k & 4) ? hi_.z : lo_.z};
      if (Dot(c - p, n) > 0) return false;
    }
    return true;
  }

  const TriangleMesh* mesh_;
  const TracerScene* tracer_;
  uint32_t index_;  // in Scene::meshes
  Vec3d radiance_;  // the material's constant emission
  double power_;
  // Set when the radiance varies over the surface: an emission map, or a cutout.
  const Material* material_;
  bool doubleSided_;  // emits from both sides
  double area_ = 0;
  Vec3d lo_, hi_;  // bounds (local)
  Vec3d centre_;   // of the bounds
  double vertexScale_ = 0;
  DiscreteDistribution triangles_;  // by area
};

}  // namespace probebake
