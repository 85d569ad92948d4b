#include "distant_light_paths.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <variant>

#include <tbb/parallel_for.h>
#include "probe_integrator.h"
#include "probebake/base/check.h"
#include "probebake/sampling/hash.h"
#include "probebake/sampling/sampler.h"
#include "probebake/sampling/warps.h"
#include "probebake/sh/sh_basis.h"
#include "ray_offset.h"
#include "shadow_roulette.h"
#include "surface_material.h"

namespace probebake {
namespace {

constexpr double kInvPi = std::numbers::inv_pi;
constexpr double kInf = std::numeric_limits<double>::infinity();
// Streams of the light paths, apart from the probes' (Hash(probe key, batch)).
constexpr uint64_t kLightPathTag = 0x6c69676874706174;  // "lightpat"
constexpr uint64_t kPilotBatch = ~uint64_t{0};

// Whether the shadow ray from origin along the unit dir up to tMax is blocked; tells `observer`
// (when not null) of the ray.
bool Occluded(const TracerScene& tracer, const Vec3f& origin, const Vec3d& dir, double tMax,
              RayObserver* observer) {
  const bool occluded = tracer.Occluded(origin, dir, tMax);
  if (observer) {
    ObservedRay r;
    r.origin = origin;
    r.dir = Vec3f(dir);
    r.tfar = TracerScene::EmbreeTFar(tMax);
    r.kind = RayKind::kShadow;
    r.hit = occluded;
    observer->OnRays({&r, 1});
  }
  return occluded;
}

}  // namespace

DistantLightPaths::DistantLightPaths(const Scene& scene, const TracerScene& tracer,
                                     const LightSet& lights, const BakeSettings& settings)
    : scene_(scene), tracer_(tracer), lights_(lights), settings_(settings) {}

std::unique_ptr<DistantLightPaths> DistantLightPaths::Build(const Scene& scene,
                                                            const TracerScene& tracer,
                                                            LightSet* lights,
                                                            const BakeSettings& settings,
                                                            std::span<const int64_t> batchSizes) {
  if (scene.medium || settings.estimator != Estimator::kNeeMis || scene.meshes.empty() ||
      batchSizes.empty())
    return nullptr;
  const Vec3d lo = tracer.boundsMin(), hi = tracer.boundsMax();
  if (!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z)) return nullptr;
  std::unique_ptr<DistantLightPaths> paths(new DistantLightPaths(scene, tracer, *lights, settings));
  DistantLightPaths& d = *paths;
  d.center_ = (lo + hi) * 0.5;
  d.half_ = (hi - lo) * 0.5;
  // A little more than the bounds, so that rounding never drops a point on them.
  d.radius_ = Length(d.half_) * (1 + 1e-6) + RayOffsetDistance(d.center_, 0);
  d.diskArea_ = std::numbers::pi * d.radius_ * d.radius_;
  d.facingSlack_ = 1e-6 * d.radius_;
  d.batchSizes_.assign(batchSizes.begin(), batchSizes.end());
  d.sourceOfLight_.assign(lights->Count(), -1);

  // The brightest kMaxSources directional lights (ties by index), the others left to the probes'
  // paths alone.
  std::vector<uint32_t> candidates;
  for (size_t i = 0; i < scene.lights.size(); ++i) {
    const auto* light = std::get_if<DirectionalLight>(&scene.lights[i]);
    if (light && Luminance(light->irradiance) > 0) candidates.push_back(uint32_t(i));
  }
  const auto brightness = [&](uint32_t i) {
    return Luminance(std::get<DirectionalLight>(scene.lights[i]).irradiance);
  };
  std::stable_sort(candidates.begin(), candidates.end(),
                   [&](uint32_t a, uint32_t b) { return brightness(a) > brightness(b); });
  if (candidates.size() > kMaxSources) candidates.resize(kMaxSources);
  std::sort(candidates.begin(), candidates.end());
  for (uint32_t i : candidates) {
    const DirectionalLight& light = std::get<DirectionalLight>(scene.lights[i]);
    Source s;
    s.light = i;
    s.toLight = -light.direction;
    s.frame = Framed::FromZ(s.toLight);
    s.cosOuter = light.cosHalfAngle;
    s.delta = !(light.cosHalfAngle < 1);
    // Radiance irradiance / (pi sin^2) over a cone of 2 pi (1 - cos): irradiance 2 / (1 + cos).
    s.conePdf = s.delta ? 1.0 : UniformConePdf(s.cosOuter);
    s.power = light.irradiance * (s.delta ? 1.0 : 2 / (1 + s.cosOuter)) * d.diskArea_;
    int kept = 0;
    for (int k = 0; k < kPilotPaths; ++k)
      kept += d.TracePath(s, Hash(kLightPathTag, s.light, kPilotBatch), uint64_t(k), nullptr);
    if (kept == 0) continue;
    s.keptFraction = double(kept) / kPilotPaths;
    s.lambda = int(std::clamp(std::ceil(kKeptPerSample / s.keptFraction), 1.0, double(kMaxLambda)));
    d.sourceOfLight_[i] = int(d.sources_.size());
    d.sources_.push_back(s);
  }
  if (d.sources_.empty()) return nullptr;
  // Before the paths are traced: their next-event pdfs read the scaled choice.
  for (const Source& s : d.sources_)
    lights->ScaleAtSurfaces(s.light, std::min(1.0, kSurfaceShare * s.keptFraction));

  const size_t batches = d.batchSizes_.size();
  d.paths_.resize(d.sources_.size() * batches);
  d.firsts_.resize(d.paths_.size());
  // lambda n_b paths a batch, but no more than about kMaxKeptPaths kept over all of a light's
  // batches: a bake of millions of samples per probe joins fewer paths per sample instead of
  // holding (and tracing) millions of them.
  d.pathCounts_.resize(d.paths_.size());
  for (size_t job = 0; job < d.paths_.size(); ++job) {
    const Source& s = d.sources_[job / batches];
    const int64_t cap = std::max<int64_t>(
        1, int64_t(std::ceil(double(kMaxKeptPaths) / (double(batches) * s.keptFraction))));
    d.pathCounts_[job] = std::min(int64_t(s.lambda) * d.batchSizes_[job % batches], cap);
  }
  tbb::parallel_for(size_t{0}, d.paths_.size(), [&](size_t job) {
    const Source& s = d.sources_[job / batches];
    const size_t b = job % batches;
    const uint64_t stream = Hash(kLightPathTag, s.light, uint64_t(b));
    const int64_t n = d.pathCounts_[job];
    std::vector<Vertex>& out = d.paths_[job];
    std::vector<uint32_t>& firsts = d.firsts_[job];
    for (int64_t i = 0; i < n; ++i) {
      const size_t before = out.size();
      d.TracePath(s, stream, uint64_t(i), &out);
      if (out.size() > before) firsts.push_back(uint32_t(before));
    }
    out.shrink_to_fit();
    firsts.shrink_to_fit();
  });
  return paths;
}

bool DistantLightPaths::Keeps(const Vec3d& x, const Vec3d& n) const {
  const Vec3d v = x - center_;
  const double slack = facingSlack_;
  if (std::fabs(v.x) > half_.x + slack || std::fabs(v.y) > half_.y + slack ||
      std::fabs(v.z) > half_.z + slack)
    return false;
  // The farthest corner of the bounds in front of the surface: some of the scene lies on the
  // side the light arrives from.
  const double ahead = Dot(n, center_ - x) + std::fabs(n.x) * half_.x + std::fabs(n.y) * half_.y +
                       std::fabs(n.z) * half_.z;
  return ahead > slack;
}

bool DistantLightPaths::TracePath(const Source& s, uint64_t stream, uint64_t index,
                                  std::vector<Vertex>* out) const {
  SobolSampler sampler(settings_.seed, stream);
  sampler.StartSample(index);
  const Vec2d uDisk = sampler.Get2D();
  const Vec2d uCone = sampler.Get2D();
  const Vec3d toLight =
      s.delta ? s.toLight : s.frame.FromLocal(SampleUniformCone(uCone, s.cosOuter));
  const Framed across = Framed::FromZ(toLight);
  const Vec2d disk = SampleUniformDiskConcentric(uDisk);
  // From beyond the bounds' sphere, so the first hit is the ray's first surface.
  const Vec3d start =
      center_ + toLight * (2 * radius_) + across.FromLocal({disk.x * radius_, disk.y * radius_, 0});
  Vec3f origin(start);
  Vec3d dir = -toLight;
  SurfaceHit hit;
  if (!tracer_.Intersect(origin, dir, kInf, &hit) || hit.kind != SurfaceKind::kMesh) return false;
  Vec3d n = Dot(dir, hit.ng) < 0 ? hit.ng : -hit.ng;
  if (!Keeps(hit.p, n)) return false;
  if (!out) return true;

  // The path's first-hit terms: what the probe paths' weights compare with.
  const double cos1 = Dot(toLight, n);
  Vertex v;
  v.a = cos1 * s.conePdf / diskArea_;
  std::vector<double> importance(lights_.ImportanceSize());
  const double total = lights_.Importance(hit.p, &n, /*includeDelta=*/true, importance);
  const double pmf = total > 0 ? lights_.SelectionPmf(s.light, hit.p, &n, importance, total) : 0;
  v.pN = pmf * s.conePdf;
  v.pB = s.delta ? 0 : cos1 * kInvPi;

  Vec3d beta = s.power;
  double c12 = 0;
  Vec3d relative{1, 1, 1};  // the albedos and survivals alone, for the roulette
  for (int m = 1;; ++m) {
    const TriangleMesh& mesh = scene_.meshes[hit.index];
    const Material& material = scene_.materials[mesh.material];
    const Vec3d albedo = material.AlbedoVaries() ? AlbedoAt(material, mesh, hit.prim, hit.u, hit.v)
                                                 : material.albedo;
    if (!(MaxComponent(albedo) > 0)) break;
    v.x = hit.p;
    v.n = n;
    v.spawn = OffsetRayOrigin(hit.p, n, hit.vertexScale);
    v.weight = beta * albedo * kInvPi;
    out->push_back(v);
    if (m >= settings_.maxDepth) break;
    const Vec2d uNext = sampler.Get2D();
    const double uRoulette = sampler.Get1D();
    Vec3d next = relative * albedo;
    double survive = 1;
    if (settings_.russianRoulette && m >= settings_.rrMinDepth) {
      survive = std::min(1.0, MaxComponent(next));
      if (uRoulette >= survive) break;
    }
    relative = next / survive;
    beta = beta * albedo / survive;
    const Vec3d local = SampleCosineHemisphere(uNext);
    if (!(local.z > 0)) break;
    dir = Framed::FromZ(n).FromLocal(local);
    origin = v.spawn;
    if (!tracer_.Intersect(origin, dir, kInf, &hit) || hit.kind != SurfaceKind::kMesh) break;
    if (m == 1) {
      // The density of this bounce, for the weight of joining the second vertex to the first.
      const double g = local.z * std::fabs(Dot(dir, hit.ng)) * kInvPi / (hit.t * hit.t);
      c12 = g > 0 ? v.a / g : 0;
    }
    v.c = c12;
    n = Dot(dir, hit.ng) < 0 ? hit.ng : -hit.ng;
  }
  return true;
}

double DistantLightPaths::OtherDensitySquared(uint32_t light, const Vec3d& x, const Vec3d& n,
                                              const Vec3d& toLight, double d1, const Vec3d* xPrev,
                                              const Vec3d* nPrev, uint32_t batch) const {
  if (!Traces(light) || !(d1 > 0)) return 0;
  const Source& s = sources_[size_t(sourceOfLight_[light])];
  const double cosK = Dot(toLight, n);
  if (!(cosK > 0) || !Keeps(x, n)) return 0;
  const double a = cosK * s.conePdf / diskArea_;
  PB_DCHECK_LT(size_t(batch), batchSizes_.size());
  const double q = Ratio(size_t(sourceOfLight_[light]), batch) * a / d1;
  double c = 0;
  if (xPrev && nPrev) {
    const Vec3d v = x - *xPrev;
    const double r2 = Dot(v, v);
    const double g = std::fabs(Dot(*nPrev, v)) * std::fabs(Dot(n, v)) * kInvPi / (r2 * r2);
    if (g > 0) c = a * Boost(size_t(sourceOfLight_[light]), batch) / g;
  }
  return q * q + c * c;
}

Vec3d DistantLightPaths::ConnectVertex(const Vec3d& x, const Vec3d& n, const Vec3f& spawn,
                                       uint32_t batch, double u, double d1,
                                       const Roulette& roulette, TraceCounters* counters,
                                       RayObserver* observer) const {
  const size_t batches = batchSizes_.size();
  Vec3d sum;
  if (size_t(batch) >= batches || !(d1 > 0)) return sum;
  for (size_t si = 0; si < sources_.size(); ++si) {
    const std::vector<uint32_t>& firsts = firsts_[si * batches + batch];
    if (firsts.empty()) continue;
    const size_t kept = firsts.size();
    const size_t pick = std::min(kept - 1, size_t(u * double(kept)));
    const Vertex& y = paths_[si * batches + batch][firsts[pick]];
    const Vec3d v = y.x - x;
    const double r2 = Dot(v, v);
    if (!(r2 > 0)) continue;
    const double cosX = Dot(n, v), cosY = -Dot(y.n, v);
    if (!(cosX > 0) || !(cosY > 0)) continue;
    const double geometry = cosX * cosY / (r2 * r2);  // G, the cosines over r^2
    const double g = geometry * kInvPi;
    const double c = y.a * Boost(si, batch) / g, q = Ratio(si, batch) * y.a / d1;
    const double w = c * c / (y.pN * y.pN + y.pB * y.pB + q * q + c * c);
    const double paths = double(pathCounts_[si * batches + batch]);
    Vec3d value = y.weight * (geometry * w * double(kept) / paths);
    if (!(MaxComponent(value) > 0)) continue;
    const double played =
        ShadowRouletteWeight(MaxComponent(value) * roulette.scale, roulette.threshold, roulette.u);
    if (played == 0) continue;
    value *= played;
    const Vec3d to = Vec3d(y.spawn) - Vec3d(spawn);
    const double distance = Length(to);
    ++counters->rays;
    ++counters->shadowRays;
    if (!(distance > 0) || Occluded(tracer_, spawn, to / distance, distance, observer)) continue;
    sum += value;
  }
  return sum;
}

void DistantLightPaths::ConnectProbe(const Vec3d& p, uint32_t batch, int64_t count, int order,
                                     const ProbeRoulette& roulette, std::span<double> sum,
                                     TraceCounters* counters, RayObserver* observer) const {
  const size_t batches = batchSizes_.size();
  PB_CHECK_LT(size_t(batch), batches);
  PB_CHECK_EQ(count, batchSizes_[batch]);
  double y[kMaxShCoeffCount];
  const int coeffs = ShCoeffCount(order);
  for (size_t si = 0; si < sources_.size(); ++si) {
    const double ratio = Ratio(si, batch);  // light paths per probe sample
    const double boost = Boost(si, batch);
    const std::vector<Vertex>& vertices = paths_[si * batches + batch];
    for (size_t k = 0; k < vertices.size(); ++k) {
      const Vertex& v = vertices[k];
      const Vec3d toProbe = p - v.x;
      const double r2 = Dot(toProbe, toProbe);
      if (!(r2 > 0)) continue;
      const double r = std::sqrt(r2);
      const double cosY = Dot(v.n, toProbe) / r;
      if (!(cosY > 0)) continue;
      const double d1 = cosY / (4 * std::numbers::pi * r2);
      const double light = ratio * v.a;
      const double pN = d1 * v.pN, pB = d1 * v.pB, c = d1 * v.c * boost;
      const double w = light * light / (light * light + pN * pN + pB * pB + c * c);
      Vec3d value = v.weight * (cosY / r2 * w / ratio);
      if (!(MaxComponent(value) > 0)) continue;
      // A probe sample of radiance L adds 4 pi L Y to the sum.
      const double radiance = MaxComponent(value) / (4 * std::numbers::pi);
      if (radiance < roulette.threshold) {
        const uint64_t key = Hash(roulette.key, uint64_t(si), uint64_t(k));
        const double played =
            ShadowRouletteWeight(radiance, roulette.threshold, U32ToUnit(uint32_t(key >> 32)));
        if (played == 0) continue;
        value *= played;
      }
      // From the vertex's ray origin (off its surface, on the probe's side) to the probe. Traced
      // one at a time: 8-wide packets from the probe toward the vertices, whose directions
      // spread as the sunlit points do, took 10% longer on the demo room.
      const Vec3d fromSpawn = p - Vec3d(v.spawn);
      const double distance = Length(fromSpawn);
      ++counters->rays;
      ++counters->shadowRays;
      if (!(distance > 0) || Occluded(tracer_, v.spawn, fromSpawn / distance, distance, observer))
        continue;
      EvalShBasis(order, toProbe * (-1 / r), y);
      for (int i = 0; i < coeffs; ++i) {
        sum[3 * size_t(i)] += y[i] * value.x;
        sum[3 * size_t(i) + 1] += y[i] * value.y;
        sum[3 * size_t(i) + 2] += y[i] * value.z;
      }
    }
  }
}

double DistantLightPaths::Boost(size_t source, uint32_t batch) const {
  const size_t batches = batchSizes_.size();
  if (size_t(batch) >= batches) return 0;
  const size_t kept = firsts_[source * batches + batch].size();
  if (kept == 0) return 0;
  return double(pathCounts_[source * batches + batch]) / double(kept);
}

double DistantLightPaths::KeptFraction(uint32_t light) const {
  return Traces(light) ? sources_[size_t(sourceOfLight_[light])].keptFraction : 0;
}

double DistantLightPaths::Ratio(size_t source, uint32_t batch) const {
  const size_t job = source * batchSizes_.size() + batch;
  return double(pathCounts_[job]) / double(batchSizes_[batch]);
}

int DistantLightPaths::Lambda(uint32_t light) const {
  return Traces(light) ? sources_[size_t(sourceOfLight_[light])].lambda : 0;
}

int64_t DistantLightPaths::PathCount(uint32_t light) const {
  if (!Traces(light)) return 0;
  const size_t source = size_t(sourceOfLight_[light]), batches = batchSizes_.size();
  int64_t n = 0;
  for (size_t b = 0; b < batches; ++b) n += pathCounts_[source * batches + b];
  return n;
}

int64_t DistantLightPaths::KeptCount(uint32_t light) const {
  if (!Traces(light)) return 0;
  const size_t source = size_t(sourceOfLight_[light]), batches = batchSizes_.size();
  int64_t n = 0;
  for (size_t b = 0; b < batches; ++b) n += int64_t(firsts_[source * batches + b].size());
  return n;
}

int64_t DistantLightPaths::VertexCount() const {
  int64_t n = 0;
  for (const std::vector<Vertex>& v : paths_) n += int64_t(v.size());
  return n;
}

}  // namespace probebake
