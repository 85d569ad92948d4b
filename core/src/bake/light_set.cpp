#include "light_set.h"

#include <algorithm>
#include <optional>
#include <variant>

#include "probebake/base/check.h"
#include "probebake/sampling/warps.h"

namespace probebake {

LightSet::LightSet(const Scene& scene, const TracerScene& tracer, size_t treeMinLights,
                   bool environment) {
  const Vec3d& offset = tracer.offset();
  for (uint32_t i = 0; i < scene.lights.size(); ++i) {
    const Light& light = scene.lights[i];
    if (const auto* p = std::get_if<PointLight>(&light)) {
      lights_.emplace_back(PointEmitter(*p, offset));
    } else if (const auto* s = std::get_if<SpotLight>(&light)) {
      lights_.emplace_back(SpotEmitter(*s, offset));
    } else if (const auto* d = std::get_if<DirectionalLight>(&light)) {
      if (d->cosHalfAngle >= 1) {
        lights_.emplace_back(DirectionalEmitter(*d));
      } else {
        lights_.emplace_back(SunEmitter(*d));
      }
    } else if (const auto* r = std::get_if<RectLight>(&light)) {
      lights_.emplace_back(RectEmitter(*r, offset));
    } else if (const auto* k = std::get_if<DiskLight>(&light)) {
      lights_.emplace_back(DiskEmitter(*k, offset));
    } else if (const auto* sp = std::get_if<SphereLight>(&light)) {
      lights_.emplace_back(SphereEmitter(*sp, offset));
    }
    if (lights_.back().delta()) deltaLights_.push_back(i);
    if (lights_.back().family() == EmitterFamily::kDistant) distantLights_.push_back(i);
  }

  meshLight_.assign(scene.meshes.size(), UINT32_MAX);
  for (uint32_t m = 0; m < scene.meshes.size(); ++m) {
    std::optional<MeshEmitter> light = MeshEmitter::Build(scene, tracer, m);
    if (!light) continue;
    meshLight_[m] = uint32_t(lights_.size());
    lights_.emplace_back(std::move(*light));
  }

  environment_ =
      std::make_unique<EnvironmentLight>(environment ? scene.environment : Environment{});
  if (!environment_->IsBlack()) {
    distantLights_.push_back(uint32_t(lights_.size()));
    lights_.emplace_back(EnvironmentEmitter(*environment_));
  }
  BuildTrees(treeMinLights);
}

LightSet::LightSet(LightSet&& lights, LightVisibility visibility) : LightSet(std::move(lights)) {
  visibility_ = std::move(visibility);
}

void LightSet::BuildTrees(size_t treeMinLights) {
  // Tree 0: area lights (rect, disk, sphere, emissive mesh); tree 1: point and spot lights, apart
  // because the probe leaves delta lights out of its choice (it projects them exactly).
  std::vector<LightTree::Item> items[2];
  for (uint32_t i = 0; i < lights_.size(); ++i) {
    LightTree::Item it;
    it.light = i;
    if (!lights_[i].TreeItem(&it)) continue;  // distant lights stay in the linear choice
    items[lights_[i].delta() ? 1 : 0].push_back(it);
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
    slotOfLight_[i] = uint32_t(slots_.size());
    slots_.push_back({i, -1, lights_[i].delta()});
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

bool LightSet::HasEmission(bool delta) const {
  for (const Emitter& l : lights_) {
    if (l.delta() == delta && l.power() > 0) return true;
  }
  return false;
}

double LightSet::Importance(const Vec3d& p, const Vec3d* n, bool includeDelta,
                            std::span<double> importance) const {
  PB_DCHECK_EQ(importance.size(), slots_.size());
  double total = 0;
  const float* factor = visibility_.At(p);  // nullptr: no table, or p outside it
  if (trees_.empty()) {
    // Every slot is the light of its index (BuildTrees): a lean loop without the slots' and
    // trees' indirections.
    const Emitter* lights = lights_.data();
    double* out = importance.data();
    const size_t count = lights_.size();
    for (size_t s = 0; s < count; ++s) {
      double w = !includeDelta && lights[s].delta() ? 0.0 : lights[s].Importance(p, n);
      if (factor) w *= factor[s];
      if (n && !surfaceScale_.empty()) w *= surfaceScale_[s];
      out[s] = w;
      total += w;
    }
    return total;
  }
  const auto leaf = [&](uint32_t light) { return lights_[light].Importance(p, n); };
  for (size_t s = 0; s < slots_.size(); ++s) {
    const Slot& slot = slots_[s];
    if (slot.delta && !includeDelta) {
      importance[s] = 0;
    } else if (slot.tree >= 0) {
      importance[s] = trees_[slot.tree]->RootImportance(p, n, leaf);
    } else {
      importance[s] = lights_[slot.light].Importance(p, n);
    }
    if (factor) importance[s] *= factor[s];
    if (n && !surfaceScale_.empty()) importance[s] *= surfaceScale_[s];
    total += importance[s];
  }
  return total;
}

void LightSet::SetEnvironmentGuide(std::unique_ptr<EnvironmentGuide> guide) {
  environmentGuide_ = std::move(guide);
  if (environment_->IsBlack()) return;
  // The environment is the last light (the constructor).
  EnvironmentEmitter* emitter = lights_.back().get_if<EnvironmentEmitter>();
  PB_CHECK(emitter != nullptr);
  emitter->SetGuide(environmentGuide_.get());
}

void LightSet::ScaleAtSurfaces(uint32_t light, double factor) {
  PB_CHECK_LT(size_t(light), lights_.size());
  const uint32_t slot = slotOfLight_[light];
  PB_CHECK(slots_[slot].tree < 0);
  if (surfaceScale_.empty()) surfaceScale_.assign(slots_.size(), 1.0);
  surfaceScale_[slot] = factor;
}

bool LightSet::SampleEntry(size_t entry, const Vec3d& p, double uTree, const Vec2d& u,
                           LightSample* sample) const {
  const Slot& slot = slots_[entry];
  uint32_t light = slot.light;
  if (slot.tree >= 0) {
    const auto leaf = [&](uint32_t i) { return lights_[i].Importance(p, nullptr); };
    double treePmf;
    if (!trees_[slot.tree]->Sample(p, nullptr, uTree, leaf, &light, &treePmf)) return false;
  } else if (!(lights_[light].Importance(p, nullptr) > 0)) {
    return false;
  }
  if (!lights_[light].Sample(p, nullptr, u, sample)) return false;
  sample->light = light;
  return true;
}

double LightSet::SelectionPmf(uint32_t light, const Vec3d& p, const Vec3d* n,
                              std::span<const double> importance, double total) const {
  if (!(total > 0)) return 0;
  const double pmf = importance[slotOfLight_[light]] / total;
  const int tree = treeOfLight_[light];
  if (tree < 0) return pmf;
  const auto leaf = [&](uint32_t i) { return lights_[i].Importance(p, n); };
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
    const auto leaf = [&](uint32_t i) { return lights_[i].Importance(p, n); };
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
  if (!lights_[light].Sample(p, n, u, sample)) return false;
  sample->pdf *= pmf;
  sample->light = light;
  return sample->pdf > 0;
}

bool LightSet::EvalDelta(uint32_t light, const Vec3d& p, LightSample* sample) const {
  sample->light = light;
  return lights_[light].EvalDelta(p, sample);
}

bool LightSet::EvalSurfaceHit(const Vec3d& p, const Vec3d* n, std::span<const double> importance,
                              double total, const Vec3d& wi, const SurfaceHit& hit,
                              LightHit* out) const {
  uint32_t light = hit.index;  // a rect, disk or sphere light: its index in Scene::lights
  if (hit.kind == SurfaceKind::kMesh) {
    light = meshLight_[hit.index];
    if (light == UINT32_MAX) return false;
  }
  out->light = light;
  const double pmf = SelectionPmf(light, p, n, importance, total);
  return lights_[light].EvalHit(p, wi, hit, pmf, out);
}

}  // namespace probebake
