// One light of a scene, of any kind, as LightSet chooses, samples and finds it.
//
// Each kind is its own type (as in pbrt-v4's lights.h) with one contract, EmitterKind below:
//   kFamily             how rays meet it besides sampling (light_sample.h: kDelta, kSurface,
//                       kDistant)
//   power()             the luminance it emits (radiance, intensity or irradiance); a light of
//                       power <= 0 is never chosen
//   Importance(p, n)    the selection importance at local point p: a cheap estimate of the
//                       irradiance it could deliver there, in irradiance units for every kind, and
//                       exactly 0 only where it cannot contribute (p behind it, or the light
//                       wholly below the tangent plane of the surface with unit normal n; n is
//                       nullptr at a probe, where there is no surface)
//   Sample(p, n, u, s)  a direction toward it with u in [0, 1)^2: *s without `light`, its pdf per
//                       steradian without the selection probability; false when it cannot light p
//                       (delta kinds have EvalDelta(p, s) instead: their one direction, pdf 1)
//   EvalHit(p, wi, hit, pmf, out)   kSurface: a ray from p along wi hit it; its radiance toward
//                       p and pmf x the pdf Sample would have had for wi (false: the back side)
//   EvalEscaped(p, wi, n, pmf, out) kDistant: the same for a ray from p along wi that left the
//                       scene
//   TreeItem(item)      its bounds, weight and emission cone for a light tree (light_tree.h);
//                       false for lights at infinity, which stay in the linear choice
// A kind's Sample, EvalHit and EvalEscaped agree: the pdf the last two report for a direction
// is the one Sample gives it, which MIS needs.
//
// Emitter holds one of the kinds in a std::variant and dispatches with a switch on its index,
// inlined into the caller: no virtual call, and LightSet's importance loop reads its lights from
// one array.
#pragma once

#include <concepts>
#include <type_traits>
#include <utility>
#include <variant>

#include "area_emitters.h"
#include "distant_emitters.h"
#include "light_sample.h"
#include "light_tree.h"
#include "mesh_emitter.h"
#include "point_emitters.h"
#include "probebake/base/check.h"
#include "tracer_scene.h"

namespace probebake {

// The parts of EmitterKind: what every kind has, and the evaluations of each family.
template <typename T>
concept EmitterCommon = requires(const T& e, const Vec3d& p, const Vec3d* n,
                                 LightTree::Item* item) {
  { T::kFamily } -> std::convertible_to<EmitterFamily>;
  { e.power() } -> std::same_as<double>;
  { e.Importance(p, n) } -> std::same_as<double>;
  { e.TreeItem(item) } -> std::same_as<bool>;
};
template <typename T>
concept SampledEmitter = requires(const T& e, const Vec3d& p, const Vec3d* n, const Vec2d& u,
                                  LightSample* s) {
  { e.Sample(p, n, u, s) } -> std::same_as<bool>;
};
template <typename T>
concept DeltaEmitter = requires(const T& e, const Vec3d& p, LightSample* s) {
  { e.EvalDelta(p, s) } -> std::same_as<bool>;
};
template <typename T>
concept SurfaceEmitter = requires(const T& e, const Vec3d& p, const SurfaceHit& hit,
                                  LightHit* out) {
  { e.EvalHit(p, p, hit, 1.0, out) } -> std::same_as<bool>;
};
template <typename T>
concept DistantEmitter = requires(const T& e, const Vec3d& wi, const Vec3d* n, LightHit* out) {
  { e.EvalEscaped(wi, wi, n, 1.0, out) } -> std::same_as<bool>;
};

// Whether T has its family's evaluations: EvalDelta, or Sample and EvalHit or EvalEscaped.
template <typename T>
constexpr bool HasFamilyEvaluations() {
  if constexpr (T::kFamily == EmitterFamily::kDelta) {
    return DeltaEmitter<T>;
  } else if constexpr (T::kFamily == EmitterFamily::kSurface) {
    return SampledEmitter<T> && SurfaceEmitter<T>;
  } else {
    return SampledEmitter<T> && DistantEmitter<T>;
  }
}

template <typename T>
concept EmitterKind = EmitterCommon<T> && HasFamilyEvaluations<T>();

class Emitter {
 public:
  using Kind = std::variant<PointEmitter, SpotEmitter, DirectionalEmitter, SunEmitter, RectEmitter,
                            DiskEmitter, SphereEmitter, MeshEmitter, EnvironmentEmitter>;

  template <EmitterKind K>
  explicit Emitter(K kind) : kind_(std::move(kind)) {}

  EmitterFamily family() const {
    return Visit([]<typename K>(const K&) { return K::kFamily; });
  }
  // Point, spot and zero-size directional lights: projected exactly at the probe, never hit.
  bool delta() const { return family() == EmitterFamily::kDelta; }
  double power() const {
    return Visit([](const auto& k) { return k.power(); });
  }

  [[gnu::always_inline]] double Importance(const Vec3d& p, const Vec3d* n) const {
    return Visit([&](const auto& k) { return k.power() <= 0 ? 0.0 : k.Importance(p, n); });
  }

  // The kind's Sample; for delta lights their one direction (s->delta set, pdf 1).
  bool Sample(const Vec3d& p, const Vec3d* n, const Vec2d& u, LightSample* s) const {
    s->delta = false;
    return Visit([&]<typename K>(const K& k) {
      if constexpr (K::kFamily == EmitterFamily::kDelta) {
        return k.EvalDelta(p, s);
      } else {
        return k.Sample(p, n, u, s);
      }
    });
  }

  // Precondition: delta().
  bool EvalDelta(const Vec3d& p, LightSample* s) const {
    return Visit([&]<typename K>(const K& k) {
      if constexpr (K::kFamily == EmitterFamily::kDelta) {
        return k.EvalDelta(p, s);
      } else {
        PB_CHECK(false);
        return false;
      }
    });
  }

  // Precondition: family() == kSurface.
  bool EvalHit(const Vec3d& p, const Vec3d& wi, const SurfaceHit& hit, double pmf,
               LightHit* out) const {
    return Visit([&]<typename K>(const K& k) {
      if constexpr (K::kFamily == EmitterFamily::kSurface) {
        return k.EvalHit(p, wi, hit, pmf, out);
      } else {
        PB_CHECK(false);
        return false;
      }
    });
  }

  // Precondition: family() == kDistant.
  bool EvalEscaped(const Vec3d& p, const Vec3d& wi, const Vec3d* n, double pmf,
                   LightHit* out) const {
    return Visit([&]<typename K>(const K& k) {
      if constexpr (K::kFamily == EmitterFamily::kDistant) {
        return k.EvalEscaped(p, wi, n, pmf, out);
      } else {
        PB_CHECK(false);
        return false;
      }
    });
  }

  bool TreeItem(LightTree::Item* item) const {
    return Visit([&](const auto& k) { return k.TreeItem(item); });
  }

  // The kind K held, or null.
  template <EmitterKind K>
  K* get_if() {
    return std::get_if<K>(&kind_);
  }

 private:
  // std::visit as a switch the compiler inlines into the caller: std::visit's own was left out of
  // line in the importance loop, a call per light.
  template <typename F>
  [[gnu::always_inline]] std::invoke_result_t<F, const PointEmitter&> Visit(F&& f) const {
    static_assert(std::variant_size_v<Kind> == 9, "a case per kind");
    switch (kind_.index()) {
      case 0:
        return f(*std::get_if<0>(&kind_));
      case 1:
        return f(*std::get_if<1>(&kind_));
      case 2:
        return f(*std::get_if<2>(&kind_));
      case 3:
        return f(*std::get_if<3>(&kind_));
      case 4:
        return f(*std::get_if<4>(&kind_));
      case 5:
        return f(*std::get_if<5>(&kind_));
      case 6:
        return f(*std::get_if<6>(&kind_));
      case 7:
        return f(*std::get_if<7>(&kind_));
      default:
        return f(*std::get_if<8>(&kind_));
    }
  }

  Kind kind_;
};

}  // namespace probebake
