#include "light_set.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <variant>

#include "probebake/base/check.h"
#include "probebake/math/frame.h"
#include "probebake/sampling/spherical_rectangle.h"
#include "probebake/sampling/warps.h"

namespace probebake {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kInf = std::numeric_limits<double>::infinity();

double SmoothStep(double x, double a, double b) {
  if (a == b) return x < a ? 0 : 1;
  const double t = std::clamp((x - a) / (b - a), 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

// True when every corner of the box lies on or below the plane through p with normal n.
bool BoxBelow(const Vec3d& lo, const Vec3d& hi, const Vec3d& p, const Vec3d& n) {
  for (int k = 0; k < 8; ++k) {
    const Vec3d c{(k & 1) ? hi.x : lo.x, (k & 2) ? hi.y : lo.y, (k & 4) ? hi.z : lo.z};
    if (Dot(c - p, n) > 0) return false;
  }
  return true;
}

}  // namespace

LightSet::LightSet(const Scene& scene, const TracerScene& tracer, size_t treeMinLights)
    : scene_(&scene), tracer_(&tracer) {
  const Vec3d& offset = tracer.offset();
  for (uint32_t i = 0; i < scene.lights.size(); ++i) {
    LightData l{};
    const Light& light = scene.lights[i];
    if (const auto* p = std::get_if<PointLight>(&light)) {
      l.kind = Kind::kPoint;
      l.position = p->position - offset;
      l.radiance = p->intensity;
    } else if (const auto* s = std::get_if<SpotLight>(&light)) {
      l.kind = Kind::kSpot;
      l.position = s->position - offset;
      l.axis = s->direction;
      l.radiance = s->intensity;
      l.cosInner = s->cosInner;
      l.cosOuter = s->cosOuter;
    } else if (const auto* d = std::get_if<DirectionalLight>(&light)) {
      l.axis = -d->direction;
      if (d->cosHalfAngle >= 1) {
        l.kind = Kind::kDirectional;
        l.radiance = d->irradiance;
      } else {
        // A disk of uniform radiance L and angular radius theta gives E = L pi sin^2(theta) on a
        // surface facing it.
        l.kind = Kind::kSun;
        l.cosOuter = d->cosHalfAngle;
        l.oneMinusCos = 1 - d->cosHalfAngle;
        const double sin2 = l.oneMinusCos * (1 + d->cosHalfAngle);
        l.sin2Outer = sin2;
        l.sinOuter = std::sqrt(sin2);
        l.radiance = d->irradiance / (kPi * sin2);
        l.frame = Framed::FromZ(l.axis);
      }
    } else if (const auto* r = std::get_if<RectLight>(&light)) {
      l.kind = Kind::kRect;
      l.position = r->corner - offset;
      l.edge1 = r->edge1;
      l.edge2 = r->edge2;
      const Vec3d c = Cross(r->edge1, r->edge2);
      l.area = Length(c);
      l.axis = c / l.area;
      l.radiance = r->radiance;
      l.twoSided = r->twoSided;
      // Orthogonal edges (to rounding): sampled by solid angle.
      l.rectangular =
          std::abs(Dot(r->edge1, r->edge2)) <= 1e-12 * Length(r->edge1) * Length(r->edge2);
      l.corners[0] = l.position;
      l.corners[1] = l.position + l.edge1;
      l.corners[2] = l.position + l.edge1 + l.edge2;
      l.corners[3] = l.position + l.edge2;
      l.centre = l.position + (l.edge1 + l.edge2) * 0.5;
      for (const Vec3d& q : l.corners)
        l.vertexScale = std::max(l.vertexScale, MaxComponent(Abs(q)));
    } else if (const auto* k = std::get_if<DiskLight>(&light)) {
      l.kind = Kind::kDisk;
      l.position = k->center - offset;
      l.axis = k->normal;
      l.frame = Framed::FromZ(l.axis);
      l.radius = k->radius;
      l.area = kPi * k->radius * k->radius;
      l.radiance = k->radiance;
      l.twoSided = k->twoSided;
      l.vertexScale = MaxComponent(Abs(l.position)) + l.radius;
    } else if (const auto* sp = std::get_if<SphereLight>(&light)) {
      l.kind = Kind::kSphere;
      l.position = sp->center - offset;
      l.radius = sp->radius;
      l.area = 4 * kPi * sp->radius * sp->radius;
      l.radiance = sp->radiance;
      l.vertexScale = MaxComponent(Abs(l.position)) + l.radius;
    }
    l.power = Luminance(l.radiance);
    lights_.push_back(l);
    if (IsDelta(l.kind)) deltaLights_.push_back(i);
    if (l.kind == Kind::kSun) distantLights_.push_back(i);
  }

  meshLight_.assign(scene.meshes.size(), UINT32_MAX);
  for (uint32_t m = 0; m < scene.meshes.size(); ++m) {
    const TriangleMesh& mesh = scene.meshes[m];
    const Vec3d& emission = scene.materials[mesh.material].emission;
    if (MaxComponent(emission) <= 0 || mesh.TriangleCount() == 0) continue;
    LightData l{};
    l.kind = Kind::kMesh;
    l.mesh = m;
    l.radiance = emission;
    l.power = Luminance(emission);
    l.boundsMin = {kInf, kInf, kInf};
    l.boundsMax = {-kInf, -kInf, -kInf};
    std::vector<double> areas(mesh.TriangleCount());
    for (size_t t = 0; t < mesh.TriangleCount(); ++t) {
      const Vec3d& a = mesh.positions[mesh.indices[3 * t]];
      const Vec3d& b = mesh.positions[mesh.indices[3 * t + 1]];
      const Vec3d& c = mesh.positions[mesh.indices[3 * t + 2]];
      areas[t] = 0.5 * Length(Cross(b - a, c - a));
      l.area += areas[t];
      for (const Vec3d* v : {&a, &b, &c}) {
        l.boundsMin = Min(l.boundsMin, *v - offset);
        l.boundsMax = Max(l.boundsMax, *v - offset);
      }
    }
    if (!(l.area > 0)) continue;
    l.position = (l.boundsMin + l.boundsMax) * 0.5;
    l.radius = 0.5 * Length(l.boundsMax - l.boundsMin);
    l.vertexScale = std::max(MaxComponent(Abs(l.boundsMin)), MaxComponent(Abs(l.boundsMax)));
    meshLight_[m] = uint32_t(lights_.size());
    triangleDistribution_.resize(lights_.size() + 1);
    triangleDistribution_.back() = std::make_unique<DiscreteDistribution>(areas);
    lights_.push_back(l);
  }

  environment_ = std::make_unique<EnvironmentLight>(scene.environment);
  if (!environment_->IsBlack()) {
    LightData l{};
    l.kind = Kind::kEnv;
    l.power = environment_->Importance();
    envLight_ = uint32_t(lights_.size());
    distantLights_.push_back(envLight_);
    lights_.push_back(l);
  }
  triangleDistribution_.resize(lights_.size());
  BuildTrees(treeMinLights);
}

void LightSet::BuildTrees(size_t treeMinLights) {
  // Tree 0: area lights (rect, disk, sphere, emissive mesh); tree 1: point and spot lights, apart
  // because the probe leaves delta lights out of its choice (it projects them exactly).
  std::vector<LightTree::Item> items[2];
  for (uint32_t i = 0; i < lights_.size(); ++i) {
    const LightData& l = lights_[i];
    LightTree::Item it;
    it.light = i;
    if (l.kind == Kind::kPoint || l.kind == Kind::kSpot) {
      it.lo = it.hi = l.position;
      it.weight = l.power;
      it.clamp = 1e-300;
      if (l.kind == Kind::kSpot)
        it.axis = l.axis, it.thetaO = 0, it.thetaE = std::acos(std::clamp(l.cosOuter, -1.0, 1.0));
      items[1].push_back(it);
      continue;
    }
    const Vec3d r{l.radius, l.radius, l.radius};
    switch (l.kind) {
      case Kind::kRect:
        it.lo = it.hi = l.corners[0];
        for (const Vec3d& q : l.corners) it.lo = Min(it.lo, q), it.hi = Max(it.hi, q);
        break;
      case Kind::kDisk:
      case Kind::kSphere:
        it.lo = l.position - r, it.hi = l.position + r;
        break;
      case Kind::kMesh:
        it.lo = l.boundsMin, it.hi = l.boundsMax;
        break;
      default:
        continue;  // distant lights stay in the linear choice
    }
    // W and the d^2 floor of LightImportance: the emitting area (a sphere's disk, seen from afar).
    if (l.kind == Kind::kSphere) {
      it.weight = l.power * kPi * l.radius * l.radius;
      it.clamp = kPi * l.radius * l.radius;
    } else {
      it.weight = l.power * l.area;
      it.clamp = l.area;
    }
    if ((l.kind == Kind::kRect || l.kind == Kind::kDisk) && !l.twoSided)
      it.axis = l.axis, it.thetaO = 0, it.thetaE = kPi / 2;
    items[0].push_back(it);
  }
  treeOfLight_.assign(lights_.size(), -1);
  slotOfLight_.assign(lights_.size(), 0);
  std::vector<bool> treeIsDelta;
  for (int t = 0; t < 2; ++t) {
    if (items[t].empty() || items[t].size() < treeMinLights) continue;
    for (const LightTree::Item& it : items[t]) treeOfLight_[it.light] = int(trees_.size());
    trees_.push_back(std::make_unique<LightTree>(std::move(items[t])));
    treeIsDelta.push_back(t == 1);
  }
  // Plain lights in index order, then one slot per tree.
  for (uint32_t i = 0; i < lights_.size(); ++i) {
    if (treeOfLight_[i] >= 0) continue;
    const Kind k = lights_[i].kind;
    slotOfLight_[i] = uint32_t(slots_.size());
    slots_.push_back({i, -1, IsDelta(k)});
  }
  std::vector<uint32_t> slotOfTree(trees_.size());
  for (size_t t = 0; t < trees_.size(); ++t) {
    slotOfTree[t] = uint32_t(slots_.size());
    slots_.push_back({0, int(t), treeIsDelta[t]});
  }
  for (uint32_t i = 0; i < lights_.size(); ++i)
    if (treeOfLight_[i] >= 0) slotOfLight_[i] = slotOfTree[treeOfLight_[i]];
}

size_t LightSet::TreeLightCount() const {
  size_t n = 0;
  for (const auto& tree : trees_) n += tree->Size();
  return n;
}

namespace {
// A rectangle seen nearly edge-on subtends almost no solid angle however near it is; there the
// solid-angle map degenerates (a sliver of the sphere spread over the whole rectangle), and area
// sampling, well behaved at any angle, takes over.
constexpr double kMaxSolidAnglePdf = 1e6;
// Solid-angle sampling pays only where a rectangle looks large: area sampling's radiance / pdf
// varies across the light as cos / d^2, by (1 + (a / d)^2)^(-3/2) from its centre to an edge a
// away, which is 28% where area / d^2 = 1 (a square of side d, spanning ~53 degrees) and 4% at
// 0.1. Beyond that area sampling's noise is small next to the rest of the estimate's, at a
// fraction of the cost (solid-angle sampling: ~150 ns a sample, probebake_sampling_bench).
// Measured by the bench at 4096 samples per probe, one thread, with the threshold moved from 0.02
// to 1: the demo room (a 1.5 m^2 ceiling light, probes 0.25 to 2.75 m below it) baked in 14% less
// time with a 1.7% higher mean irradiance error (RMS std_error +1.6%), 11% less time to the same
// error; the courtyard (a small lantern, sampled by solid angle only from points near it) in the
// same time, RMS std_error +1.1%.
constexpr double kMinSolidAngleRatio = 1;
}  // namespace

bool LightSet::UseSolidAngleSampling(const LightData& l, const Vec3d& p) const {
  if (!l.rectangular) return false;
  return l.area >= kMinSolidAngleRatio * LengthSquared(l.centre - p);
}

double LightSet::SolidAnglePdf(const LightData& l, const Vec3d& p) const {
  if (!UseSolidAngleSampling(l, p)) return 0;
  const double pdf = SphericalRectanglePdf(p, l.position, l.edge1, l.edge2);
  return pdf > 0 && pdf <= kMaxSolidAnglePdf ? pdf : 0;
}

double LightSet::SpotFalloff(const LightData& l, const Vec3d& wFromLight) const {
  return SmoothStep(Dot(wFromLight, l.axis), l.cosOuter, l.cosInner);
}

bool LightSet::HasEmission(bool delta) const {
  for (const LightData& l : lights_) {
    if (IsDelta(l.kind) == delta && l.power > 0) return true;
  }
  return false;
}

[[gnu::always_inline]] inline double LightSet::LightImportance(const LightData& l, const Vec3d& p,
                                                               const Vec3d* n) const {
  if (l.power <= 0) return 0;
  switch (l.kind) {
    case Kind::kPoint:
    case Kind::kSpot: {
      const Vec3d v = l.position - p;
      const double d2 = LengthSquared(v);
      if (n && Dot(v, *n) <= 0) return 0;
      double falloff = 1;
      if (l.kind == Kind::kSpot) {
        if (!(d2 > 0)) return 0;
        falloff = SpotFalloff(l, -v / std::sqrt(d2));
      }
      return l.power * falloff / std::max(d2, 1e-300);
    }
    case Kind::kDirectional:
      if (n && Dot(l.axis, *n) <= 0) return 0;
      return l.power;
    case Kind::kSun: {
      // E = L pi sin^2: importance in irradiance units like the others. The cap is wholly below
      // the tangent plane when its axis is more than 90 degrees + its radius from n.
      if (n && Dot(l.axis, *n) <= -l.sinOuter) return 0;
      return l.power * kPi * l.sin2Outer;
    }
    case Kind::kRect: {
      if (!l.twoSided && Dot(p - l.position, l.axis) <= 0) return 0;
      if (n) {
        bool below = true;
        for (const Vec3d& q : l.corners) below = below && Dot(q - p, *n) <= 0;
        if (below) return 0;
      }
      return l.power * l.area / std::max(LengthSquared(l.centre - p), l.area);
    }
    case Kind::kDisk: {
      if (!l.twoSided && Dot(p - l.position, l.axis) <= 0) return 0;
      if (n && Dot(l.position - p, *n) <= -l.radius) return 0;
      return l.power * l.area / std::max(LengthSquared(l.position - p), l.area);
    }
    case Kind::kSphere: {
      const double d2 = LengthSquared(l.position - p);
      if (d2 <= l.radius * l.radius) return 0;  // inside: the surface emits outward only
      if (n && Dot(l.position - p, *n) <= -l.radius) return 0;
      const double disk = kPi * l.radius * l.radius;
      return l.power * disk / std::max(d2, disk);
    }
    case Kind::kMesh: {
      if (n && BoxBelow(l.boundsMin, l.boundsMax, p, *n)) return 0;
      return l.power * l.area / std::max(LengthSquared(l.position - p), l.area);
    }
    case Kind::kEnv:
      return l.power;
  }
  return 0;
}

double LightSet::Importance(const Vec3d& p, const Vec3d* n, bool includeDelta,
                            std::span<double> importance) const {
  PB_DCHECK_EQ(importance.size(), slots_.size());
  double total = 0;
  const float* factor = visibility_.At(p);  // nullptr: no table, or p outside it
  if (trees_.empty()) {
    // Every slot is the light of its index (BuildTrees): a lean loop without the slots' and
    // trees' indirections, LightImportance inlined. A third fewer instructions than the general
    // loop below in the demo room (callgrind), same results.
    const LightData* lights = lights_.data();
    double* out = importance.data();
    const size_t count = lights_.size();
    for (size_t s = 0; s < count; ++s) {
      double w = !includeDelta && IsDelta(lights[s].kind) ? 0.0 : LightImportance(lights[s], p, n);
      if (factor) w *= factor[s];
      out[s] = w;
      total += w;
    }
    return total;
  }
  const auto leaf = [&](uint32_t light) { return LightImportance(lights_[light], p, n); };
  for (size_t s = 0; s < slots_.size(); ++s) {
    const Slot& slot = slots_[s];
    if (slot.delta && !includeDelta) {
      importance[s] = 0;
    } else if (slot.tree >= 0) {
      importance[s] = trees_[slot.tree]->RootImportance(p, n, leaf);
    } else {
      importance[s] = LightImportance(lights_[slot.light], p, n);
    }
    if (factor) importance[s] *= factor[s];
    total += importance[s];
  }
  return total;
}

bool LightSet::SampleEntry(size_t entry, const Vec3d& p, double uTree, const Vec2d& u,
                           LightSample* sample) const {
  const Slot& slot = slots_[entry];
  uint32_t light = slot.light;
  if (slot.tree >= 0) {
    const auto leaf = [&](uint32_t i) { return LightImportance(lights_[i], p, nullptr); };
    double treePmf;
    if (!trees_[slot.tree]->Sample(p, nullptr, uTree, leaf, &light, &treePmf)) return false;
  } else if (!(LightImportance(lights_[light], p, nullptr) > 0)) {
    return false;
  }
  if (!SampleOne(lights_[light], light, p, nullptr, u, sample)) return false;
  sample->light = light;
  return true;
}

double LightSet::SelectionPmf(uint32_t light, const Vec3d& p, const Vec3d* n,
                              std::span<const double> importance, double total) const {
  if (!(total > 0)) return 0;
  const double pmf = importance[slotOfLight_[light]] / total;
  const int tree = treeOfLight_[light];
  if (tree < 0) return pmf;
  const auto leaf = [&](uint32_t i) { return LightImportance(lights_[i], p, n); };
  return pmf * trees_[tree]->Pmf(light, p, n, leaf);
}

bool LightSet::Choose(const Vec3d& p, const Vec3d* n, std::span<const double> importance,
                      double total, double uSelect, uint32_t* light, double* pmf) const {
  return ChooseInline(p, n, importance, total, uSelect, light, pmf);
}

[[gnu::always_inline]] inline bool LightSet::ChooseInline(const Vec3d& p, const Vec3d* n,
                                                          std::span<const double> importance,
                                                          double total, double uSelect,
                                                          uint32_t* light, double* pmfOut) const {
  if (!(total > 0)) return false;
  // Linear scan: the importance array is rebuilt at every vertex anyway.
  const double target = uSelect * total;
  double cdf = 0;
  size_t chosen = slots_.size();
  for (size_t s = 0; s < slots_.size(); ++s) {
    if (importance[s] <= 0) continue;
    chosen = s;
    if (target < cdf + importance[s]) break;
    cdf += importance[s];
  }
  if (chosen == slots_.size()) return false;
  const Slot& slot = slots_[chosen];
  double pmf = importance[chosen] / total;
  *light = slot.light;
  if (slot.tree >= 0) {
    // The position of target within the chosen entry, uniform in [0, 1), picks the tree's light.
    const double uTree = std::clamp((target - cdf) / importance[chosen], 0.0, kOneMinusEpsilon);
    const auto leaf = [&](uint32_t i) { return LightImportance(lights_[i], p, n); };
    double treePmf;
    if (!trees_[slot.tree]->Sample(p, n, uTree, leaf, light, &treePmf)) return false;
    pmf = pmf * treePmf;  // as SelectionPmf computes it
  }
  *pmfOut = pmf;
  return true;
}

bool LightSet::Sample(const Vec3d& p, const Vec3d* n, std::span<const double> importance,
                      double total, double uSelect, const Vec2d& u, LightSample* sample) const {
  uint32_t light;
  double pmf;
  if (!ChooseInline(p, n, importance, total, uSelect, &light, &pmf)) return false;
  if (!SampleOne(lights_[light], light, p, n, u, sample)) return false;
  sample->pdf *= pmf;
  sample->light = light;
  return sample->pdf > 0;
}

namespace {

// A point q sampled on a rect or disk light seen from p: direction, distance, radiance and pdf
// (solidAnglePdf when q was sampled by solid angle, else the area pdf turned into solid angle).
// False when q cannot light p (behind a one-sided light, or grazing).
bool FinishAreaSampleImpl(const Vec3d& axis, double area, bool twoSided, const Vec3d& radiance,
                          double vertexScale, const Vec3d& p, const Vec3d& q, double solidAnglePdf,
                          LightSample* s) {
  const Vec3d v = q - p;
  const double d2 = LengthSquared(v);
  if (!(d2 > 0)) return false;
  const double d = std::sqrt(d2);
  s->wi = v * (1 / d);
  const double cosLight = -Dot(s->wi, axis);
  if ((cosLight <= 0 && !twoSided) || cosLight == 0) return false;
  s->distance = d;
  s->point = q;
  s->vertexScale = vertexScale;
  s->radiance = radiance;
  s->pdf = solidAnglePdf > 0 ? solidAnglePdf : d2 / (area * std::abs(cosLight));
  return true;
}

// cos of the half-angle of the cap a sphere light subtends from p; false when p is inside it
// (the surface emits outward only).
bool SphereCapCos(const Vec3d& centre, double radius, const Vec3d& p, double* cosMax,
                  double* oneMinusCos) {
  const double dc2 = LengthSquared(centre - p);
  const double r2 = radius * radius;
  if (dc2 <= r2) return false;
  const double sin2 = r2 / dc2;
  *cosMax = std::sqrt(std::max(0.0, 1 - sin2));
  // For small caps 1 - cos without cancellation: from r / d ~ 1e-8 the difference was 0, the pdf
  // infinite and the bake NaN (1e-7: 2% off). Above 1e-6 the difference is accurate to 1e-10 and
  // keeps the bits of earlier versions.
  *oneMinusCos = sin2 < 1e-6 ? sin2 / (1 + *cosMax) : 1 - *cosMax;
  if (!(*oneMinusCos > 0)) return false;  // r^2 / d^2 underflowed: the sphere is not there
  return true;
}

}  // namespace

bool LightSet::FinishAreaSample(const LightData& l, const Vec3d& p, const Vec3d& q,
                                double solidAnglePdf, LightSample* s) const {
  return FinishAreaSampleImpl(l.axis, l.area, l.twoSided, l.radiance, l.vertexScale, p, q,
                              solidAnglePdf, s);
}

bool LightSet::SampleOne(const LightData& l, uint32_t index, const Vec3d& p, const Vec3d* n,
                         const Vec2d& u, LightSample* s) const {
  s->delta = false;
  switch (l.kind) {
    case Kind::kPoint:
    case Kind::kSpot:
    case Kind::kDirectional:
      return EvalDelta(index, p, s);
    case Kind::kSun: {
      const Vec3d local = SampleUniformCone(u, l.cosOuter);
      s->wi = l.frame.FromLocal(local);
      s->distance = kInf;
      s->radiance = l.radiance;
      s->pdf = UniformConePdf(l.cosOuter);
      return true;
    }
    case Kind::kRect:
    case Kind::kDisk: {
      if (l.kind == Kind::kRect && UseSolidAngleSampling(l, p)) {
        // Solid-angle sampling, unless the rectangle is too small a target for it (then area
        // sampling below, with the same u: the choice depends on p alone, as in EvalSurfaceHit).
        const SphericalRectangleSample r =
            SampleSphericalRectangle(u, p, l.position, l.edge1, l.edge2);
        if (r.pdf > 0 && r.pdf <= kMaxSolidAnglePdf) return FinishAreaSample(l, p, r.p, r.pdf, s);
      }
      Vec3d q;
      if (l.kind == Kind::kRect) {
        q = SampleUniformParallelogram(u, l.position, l.edge1, l.edge2);
      } else {
        const Vec2d d = SampleUniformDiskConcentric(u);
        q = l.position + (l.frame.s * d.x + l.frame.t * d.y) * l.radius;
      }
      return FinishAreaSample(l, p, q, 0, s);
    }
    case Kind::kSphere: {
      double cosMax, oneMinusCos;
      if (!SphereCapCos(l.position, l.radius, p, &cosMax, &oneMinusCos)) return false;
      const Vec3d toCentre = l.position - p;
      const double dc2 = LengthSquared(toCentre);
      const double r2 = l.radius * l.radius;
      const Vec3d axis = toCentre / std::sqrt(dc2);
      const Vec3d local = SampleUniformConeFromOneMinusCos(u, oneMinusCos);
      s->wi = Framed::FromZ(axis).FromLocal(local);
      // Nearest intersection with the sphere; at the silhouette rounding may leave the
      // discriminant slightly negative: take the tangent point.
      const double b = Dot(toCentre, s->wi);
      const double disc = r2 - (dc2 - b * b);
      s->distance = b - std::sqrt(std::max(0.0, disc));
      s->point = p + s->wi * s->distance;
      s->vertexScale = l.vertexScale;
      s->radiance = l.radiance;
      s->pdf = UniformConePdfFromOneMinusCos(oneMinusCos);
      return true;
    }
    case Kind::kMesh: {
      const DiscreteSample pick = triangleDistribution_[index]->Sample(u.x);
      const size_t t = size_t(pick.index);
      const double uRemapped = pick.uRemapped;
      const TriangleMesh& mesh = scene_->meshes[l.mesh];
      const Vec3d& offset = tracer_->offset();
      const Vec3d a = mesh.positions[mesh.indices[3 * t]] - offset;
      const Vec3d b = mesh.positions[mesh.indices[3 * t + 1]] - offset;
      const Vec3d c = mesh.positions[mesh.indices[3 * t + 2]] - offset;
      const std::array<double, 3> bary = SampleUniformTriangle({uRemapped, u.y});
      const Vec3d q = a * bary[0] + b * bary[1] + c * bary[2];
      const Vec3d v = q - p;
      const double d2 = LengthSquared(v);
      if (!(d2 > 0)) return false;
      const double d = std::sqrt(d2);
      s->wi = v * (1 / d);
      const Vec3d ng = Vec3d(tracer_->TriangleNormal(l.mesh, uint32_t(t)));
      const double cosLight = -Dot(s->wi, ng);
      if (cosLight <= 0) return false;  // emissive triangles emit from their front side only
      s->distance = d;
      s->point = q;
      s->vertexScale = l.vertexScale;
      s->radiance = l.radiance;
      // pmf(t) = area_t / area; uniform on t: 1 / area_t; together 1 / area.
      s->pdf = d2 / (l.area * cosLight);
      return true;
    }
    case Kind::kEnv: {
      s->radiance = environment_->Sample(u, n, &s->wi, &s->pdf);
      s->distance = kInf;
      return s->pdf > 0 && MaxComponent(s->radiance) > 0;
    }
  }
  return false;
}

bool LightSet::EvalDelta(uint32_t index, const Vec3d& p, LightSample* s) const {
  const LightData& l = lights_[index];
  s->delta = true;
  s->light = index;
  s->pdf = 1;
  if (l.kind == Kind::kDirectional) {
    s->wi = l.axis;
    s->distance = kInf;
    s->radiance = l.radiance;
    return true;
  }
  const Vec3d v = l.position - p;
  const double d2 = LengthSquared(v);
  if (!(d2 > 0)) return false;
  const double d = std::sqrt(d2);
  s->wi = v * (1 / d);
  s->distance = d;
  s->point = l.position;
  s->vertexScale = 0;  // a point, not a surface: set, as callers may reuse *s
  double falloff = 1;
  if (l.kind == Kind::kSpot) falloff = SpotFalloff(l, -s->wi);
  if (falloff <= 0) return false;
  s->radiance = l.radiance * (falloff / d2);
  return true;
}

bool LightSet::EvalSurfaceHit(const Vec3d& p, const Vec3d* n, std::span<const double> importance,
                              double total, const Vec3d& wi, const SurfaceHit& hit,
                              LightHit* out) const {
  uint32_t index = UINT32_MAX;
  if (hit.kind == SurfaceKind::kMesh) {
    index = meshLight_[hit.index];
    if (index == UINT32_MAX) return false;
  } else {
    index = hit.index;
  }
  const LightData& l = lights_[index];
  out->light = index;
  out->radiance = l.radiance;
  const double pmf = SelectionPmf(index, p, n, importance, total);
  const double d2 = hit.t * hit.t;
  switch (l.kind) {
    case Kind::kRect:
    case Kind::kDisk: {
      const double cosLight = -Dot(wi, l.axis);
      if (cosLight <= 0 && !l.twoSided) return false;
      const double solidAnglePdf = l.kind == Kind::kRect ? SolidAnglePdf(l, p) : 0;
      if (solidAnglePdf > 0) {
        out->pdf = pmf * solidAnglePdf;
      } else {
        out->pdf = cosLight != 0 ? pmf * d2 / (l.area * std::abs(cosLight)) : 0;
      }
      return true;
    }
    case Kind::kSphere: {
      double cosMax, oneMinusCos;
      if (!SphereCapCos(l.position, l.radius, p, &cosMax, &oneMinusCos)) return false;
      out->pdf = pmf * UniformConePdfFromOneMinusCos(oneMinusCos);
      return true;
    }
    case Kind::kMesh: {
      const double cosLight = -Dot(wi, hit.ng);
      if (cosLight <= 0) return false;
      out->pdf = pmf * d2 / (l.area * cosLight);
      return true;
    }
    default:
      PB_CHECK(false);
  }
  return false;
}

}  // namespace probebake
