#include "mesh_emitter.h"
#include "probebake/base/check.h"

#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "probebake/base/check.h"
#include "probebake/sampling/warps.h"
#include "surface_material.h"

namespace probebake {

std::optional<MeshEmitter> MeshEmitter::Build(const Scene& scene, const TracerScene& tracer,
                                              uint32_t mesh) {
  const TriangleMesh& m = scene.meshes[mesh];
  const Vec3d& emission = scene.materials[m.material].emission;
  if (MaxComponent(emission) <= 0 || m.TriangleCount() == 0) return std::nullopt;
  // The job builder places an emissive mesh's copies in world space (scene.h).
  PB_CHECK(m.placements.empty());
  std::vector<double> areas(m.TriangleCount());
  for (size_t t = 0; t < m.TriangleCount(); ++t) {
    const Vec3d& a = m.positions[m.indices[3 * t]];
    const Vec3d& b = m.positions[m.indices[3 * t + 1]];
    const Vec3d& c = m.positions[m.indices[3 * t + 2]];
    areas[t] = 0.5 * Length(Cross(b - a, c - a));
  }
  MeshEmitter light(m, tracer, mesh, scene.materials[m.material], areas);
  if (!(light.area_ > 0)) return std::nullopt;
  return light;
}

MeshEmitter::MeshEmitter(const TriangleMesh& mesh, const TracerScene& tracer, uint32_t index,
                         const Material& material, std::span<const double> triangleAreas)
    : mesh_(&mesh),
      tracer_(&tracer),
      index_(index),
      radiance_(material.emission),
      // A textured emitter's power at the map's mean: the selection probability is consistent
      // whatever it is, only its variance depends on it.
      power_(Luminance(material.emission) *
             (material.emissionMap.image ? MeanLuminance(material.emissionMap) : 1.0)),
      material_(material.emissionMap.image || material.HasCutout() ? &material : nullptr),
      doubleSided_(material.doubleSided),
      triangles_(triangleAreas) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const Vec3d& offset = tracer.offset();
  lo_ = {kInf, kInf, kInf};
  hi_ = {-kInf, -kInf, -kInf};
  for (size_t t = 0; t < triangleAreas.size(); ++t) {
    area_ += triangleAreas[t];
    for (int k = 0; k < 3; ++k) {
      const Vec3d v = mesh.positions[mesh.indices[3 * t + k]] - offset;
      lo_ = Min(lo_, v);
      hi_ = Max(hi_, v);
    }
  }
  centre_ = (lo_ + hi_) * 0.5;
  vertexScale_ = std::max(MaxComponent(Abs(lo_)), MaxComponent(Abs(hi_)));
}

bool MeshEmitter::Sample(const Vec3d& p, const Vec3d* /*n*/, const Vec2d& u, LightSample* s) const {
  const DiscreteSample pick = triangles_.Sample(u.x);
  const size_t t = size_t(pick.index);
  const Vec3d& offset = tracer_->offset();
  const Vec3d a = mesh_->positions[mesh_->indices[3 * t]] - offset;
  const Vec3d b = mesh_->positions[mesh_->indices[3 * t + 1]] - offset;
  const Vec3d c = mesh_->positions[mesh_->indices[3 * t + 2]] - offset;
  const std::array<double, 3> bary = SampleUniformTriangle({pick.uRemapped, u.y});
  const Vec3d q = a * bary[0] + b * bary[1] + c * bary[2];
  const Vec3d v = q - p;
  const double d2 = LengthSquared(v);
  if (!(d2 > 0)) return false;
  const double d = std::sqrt(d2);
  s->wi = v * (1 / d);
  const Vec3d ng = Vec3d(tracer_->TriangleNormal(index_, uint32_t(t)));
  double cosLight = -Dot(s->wi, ng);
  if (doubleSided_) cosLight = std::fabs(cosLight);
  if (cosLight <= 0) return false;  // emissive triangles emit from their front side only
  if (material_ && material_->HasCutout() &&
      CoverageAt(*material_, *mesh_, uint32_t(t), bary[1], bary[2]) < material_->alphaCutoff)
    return false;  // a cut-out point emits nothing
  s->distance = d;
  s->point = q;
  s->vertexScale = vertexScale_;
  s->radiance =
      material_ ? EmissionAt(*material_, *mesh_, uint32_t(t), bary[1], bary[2]) : radiance_;
  // pmf(t) = area_t / area; uniform on t: 1 / area_t; together 1 / area.
  s->pdf = d2 / (area_ * cosLight);
  return true;
}

bool MeshEmitter::EvalHit(const Vec3d& /*p*/, const Vec3d& wi, const SurfaceHit& hit, double pmf,
                          LightHit* out) const {
  double cosLight = -Dot(wi, hit.ng);
  if (doubleSided_) cosLight = std::fabs(cosLight);
  if (cosLight <= 0) return false;
  out->radiance = material_ && material_->emissionMap.image
                      ? EmissionAt(*material_, *mesh_, hit.prim, hit.u, hit.v)
                      : radiance_;
  out->pdf = pmf * (hit.t * hit.t) / (area_ * cosLight);
  return true;
}

bool MeshEmitter::TreeItem(LightTree::Item* item) const {
  item->lo = lo_, item->hi = hi_;
  item->weight = power_ * area_;
  item->clamp = area_;
  return true;
}

}  // namespace probebake
