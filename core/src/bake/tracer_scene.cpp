#include "tracer_scene.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>
#include <string>
#include <tuple>
#include <variant>

#include "probebake/base/check.h"
#include "probebake/base/log.h"
#include "probebake/base/status.h"
#include "ray_offset.h"
#include "surface_material.h"

namespace probebake {
namespace {

// Device errors arrive through a callback; the first one is kept and turned into a status.
struct DeviceErrors {
  std::mutex mutex;
  std::string first;
};

void OnEmbreeError(void* user, RTCError code, const char* message) {
  auto* errors = static_cast<DeviceErrors*>(user);
  std::lock_guard lock(errors->mutex);
  if (errors->first.empty())
    errors->first = "Embree error " + std::to_string(int(code)) + ": " + (message ? message : "");
}

// Closest point of triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5), in double.
Vec3d ClosestPointOnTriangle(const Vec3d& p, const Vec3d& a, const Vec3d& b, const Vec3d& c) {
  const Vec3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = Dot(ab, ap), d2 = Dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3d bp = p - b;
  const double d3 = Dot(ab, bp), d4 = Dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
  const Vec3d cp = p - c;
  const double d5 = Dot(ab, cp), d6 = Dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const double denom = 1 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

Vec3d Vertex(const float* v, uint32_t i) {
  return {v[3 * i], v[3 * i + 1], v[3 * i + 2]};
}

// One Embree point (sphere or disc) at local `centre` with `radius`; grows the bounds by its box.
template <typename Grow>
RTCGeometry NewPointGeometry(RTCDevice device, RTCGeometryType type, const Vec3d& centre,
                             double radius, Grow&& grow) {
  RTCGeometry geom = rtcNewGeometry(device, type);
  auto* v = static_cast<float*>(
      rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 16, 1));
  v[0] = float(centre.x), v[1] = float(centre.y), v[2] = float(centre.z), v[3] = float(radius);
  grow(centre - Vec3d{radius, radius, radius});
  grow(centre + Vec3d{radius, radius, radius});
  return geom;
}

// An Embree ray origin + t dir, t in (0, tMax) (tMax may be infinite), all masks.
void InitRay(RTCRay& ray, const Vec3f& origin, const Vec3d& dir, double tMax) {
  ray.org_x = origin.x;
  ray.org_y = origin.y;
  ray.org_z = origin.z;
  ray.tnear = 0;
  ray.dir_x = float(dir.x);
  ray.dir_y = float(dir.y);
  ray.dir_z = float(dir.z);
  ray.time = 0;
  ray.tfar = TracerScene::EmbreeTFar(tMax);
  ray.mask = 0xFFFFFFFFu;
  ray.id = 0;
  ray.flags = 0;
}

// The step between a packet's ray origins: 0 when all its rays share origins[0], else 1 (one
// origin per ray).
size_t OriginStep(std::span<const Vec3f> origins, std::span<const Vec3d> dirs) {
  PB_CHECK(origins.size() == 1 || origins.size() == dirs.size());
  return origins.size() == 1 ? 0 : 1;
}

// Rays from one origin (the caller sorts them by direction) share most of their BVH traversal:
// Embree's coherent mode. Rays from several origins (neighbouring surface points, toward one
// light or on in cosine-distributed directions) are not that alike: flagged coherent, their
// packets traced slower than single rays, flagged incoherent faster
// (docs/performance-history.md).
RTCIntersectContextFlags PacketFlags(size_t originStep) {
  return originStep == 0 ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT
                         : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
}

// Lane k of an 8-ray packet set to `one`.
void SetLane(RTCRay8& packet, int k, const RTCRay& one) {
  packet.org_x[k] = one.org_x;
  packet.org_y[k] = one.org_y;
  packet.org_z[k] = one.org_z;
  packet.tnear[k] = one.tnear;
  packet.dir_x[k] = one.dir_x;
  packet.dir_y[k] = one.dir_y;
  packet.dir_z[k] = one.dir_z;
  packet.time[k] = one.time;
  packet.tfar[k] = one.tfar;
  packet.mask[k] = one.mask;
  packet.id[k] = one.id;
  packet.flags[k] = one.flags;
}

// A mesh with a cutout material, as its Embree filter functions see it.
struct Cutout {
  const Material* material;
  const TriangleMesh* mesh;
};

// Embree's intersection and occlusion filter of a cutout mesh: a hit where the coverage is below
// the material's cutoff is rejected, and the ray goes on as if the triangle were not there (for
// every ray: paths, shadow rays, validity). Installed only on such meshes: other geometry is
// traced without a callback.
void CutoutFilter(const RTCFilterFunctionNArguments* args) {
  const auto* cutout = static_cast<const Cutout*>(args->geometryUserPtr);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    const uint32_t prim = RTCHitN_primID(args->hit, args->N, i);
    const double u = RTCHitN_u(args->hit, args->N, i), v = RTCHitN_v(args->hit, args->N, i);
    if (CoverageAt(*cutout->material, *cutout->mesh, prim, u, v) < cutout->material->alphaCutoff)
      args->valid[i] = 0;
  }
}

}  // namespace

struct TracerScene::Impl {
  DeviceErrors errors;
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::vector<uint32_t> meshOfGeom;
  std::vector<RTCScene> prototypes;  // the instanced meshes' own scenes (TracerScene::Placed)
  std::vector<std::unique_ptr<Cutout>> cutouts;  // Embree's user data of cutout meshes

  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    for (RTCScene prototype : prototypes)
      if (prototype) rtcReleaseScene(prototype);
    if (device) rtcReleaseDevice(device);
  }
  absl::Status Check(const char* what) {
    std::lock_guard lock(errors.mutex);
    if (errors.first.empty()) return absl::OkStatus();
    return absl::InternalError(std::string(what) + ": " + errors.first);
  }
};

TracerScene::~TracerScene() = default;

bool FiniteSceneBounds(const Scene& scene, Vec3d* boundsMin, Vec3d* boundsMax) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  Vec3d lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
  auto add = [&](const Vec3d& p) {
    lo = Min(lo, p);
    hi = Max(hi, p);
  };
  for (const TriangleMesh& m : scene.meshes) GrowMeshBounds(m, &lo, &hi);
  for (const Light& light : scene.lights) {
    if (const auto* l = std::get_if<RectLight>(&light)) {
      add(l->corner);
      add(l->corner + l->edge1 + l->edge2);
    } else if (const auto* d = std::get_if<DiskLight>(&light)) {
      add(d->center);
    } else if (const auto* s = std::get_if<SphereLight>(&light)) {
      add(s->center);
    } else if (const auto* pl = std::get_if<PointLight>(&light)) {
      add(pl->position);
    } else if (const auto* sl = std::get_if<SpotLight>(&light)) {
      add(sl->position);
    }
  }
  *boundsMin = lo;
  *boundsMax = hi;
  return lo.x <= hi.x;
}

Vec3d LocalOrigin(const Scene& scene) {
  Vec3d lo, hi;
  // Nothing finite: no surface to leave without self-intersection, so any origin will do.
  if (!FiniteSceneBounds(scene, &lo, &hi)) return {};
  return (lo + hi) * 0.5;
}

absl::StatusOr<std::unique_ptr<TracerScene>> TracerScene::Build(const Scene& scene,
                                                                const Vec3d& offset,
                                                                const char* deviceConfig) {
  std::unique_ptr<TracerScene> out(new TracerScene);
  out->offset_ = offset;
  out->impl_ = std::make_unique<Impl>();
  Impl& impl = *out->impl_;
  impl.device = rtcNewDevice(deviceConfig);
  if (!impl.device)
    return absl::InternalError("Embree: cannot create a device (error " +
                               std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
  rtcSetDeviceErrorFunction(impl.device, OnEmbreeError, &impl.errors);
  impl.scene = rtcNewScene(impl.device);
  // Robust traversal: closed meshes must not leak rays through shared edges, or probes inside
  // geometry would be misclassified.
  rtcSetSceneFlags(impl.scene, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(impl.scene, RTC_BUILD_QUALITY_HIGH);

  constexpr double kInf = std::numeric_limits<double>::infinity();
  out->boundsMin_ = {kInf, kInf, kInf};
  out->boundsMax_ = {-kInf, -kInf, -kInf};
  auto grow = [&](const Vec3d& p) {
    out->boundsMin_ = Min(out->boundsMin_, p);
    out->boundsMax_ = Max(out->boundsMax_, p);
  };
  auto attach = [&](RTCGeometry geom, SurfaceKind kind, uint32_t index, uint32_t instance = 0) {
    rtcCommitGeometry(geom);
    const unsigned id = rtcAttachGeometry(impl.scene, geom);
    rtcReleaseGeometry(geom);
    if (out->geoms_.size() <= id) out->geoms_.resize(id + 1);
    out->geoms_[id] = {kind, index, instance, UINT32_MAX};
    if (impl.meshOfGeom.size() <= id) impl.meshOfGeom.resize(id + 1, UINT32_MAX);
    return id;
  };

  out->normals_.resize(scene.meshes.size());
  out->meshVerts_.assign(scene.meshes.size(), nullptr);
  out->meshIndices_.assign(scene.meshes.size(), nullptr);
  out->doubleSided_.assign(scene.meshes.size(), 0);
  // Consecutive instanced meshes with the same placements (the materials of one mesh a model
  // places several times) share one Embree scene, placed by one Embree instance per placement.
  struct Open {
    const std::vector<MeshPlacement>* placements = nullptr;
    Vec3d lo, hi;  // bounds of its meshes, in their own frame
  } open;
  const auto place = [&]() {
    if (open.placements == nullptr) return;
    const uint32_t prototype = uint32_t(impl.prototypes.size() - 1);
    rtcCommitScene(impl.prototypes.back());
    for (uint32_t k = 0; k < open.placements->size(); ++k) {
      const MeshPlacement& placement = (*open.placements)[k];
      Placed placed;
      placed.prototype = prototype;
      placed.instance = k;
      placed.linear = placement.linear;
      placed.inverse = Inverse(placement.linear);
      placed.normals = Transpose(placed.inverse);
      placed.translation = placement.translation - offset;
      const auto norm = [](const Mat3d& a) {  // the infinity norm: the largest row sum
        double n = 0;
        for (int r = 0; r < 3; ++r)
          n = std::max(n, std::abs(a(r, 0)) + std::abs(a(r, 1)) + std::abs(a(r, 2)));
        return n;
      };
      placed.linearNorm = norm(placed.linear);
      placed.conditioning = std::max(1.0, placed.linearNorm * norm(placed.inverse));
      double frobenius = 0;
      for (int r = 0; r < 3; ++r) frobenius += Dot(placed.inverse.Row(r), placed.inverse.Row(r));
      placed.inverseStretch = std::sqrt(frobenius);
      placed.boundsMin = {kInf, kInf, kInf};
      placed.boundsMax = {-kInf, -kInf, -kInf};
      GrowPlacedBox({placed.linear, placed.translation}, open.lo, open.hi, &placed.boundsMin,
                    &placed.boundsMax);
      grow(placed.boundsMin);
      grow(placed.boundsMax);
      RTCGeometry instance = rtcNewGeometry(impl.device, RTC_GEOMETRY_TYPE_INSTANCE);
      rtcSetGeometryInstancedScene(instance, impl.prototypes.back());
      float xfm[12];
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) xfm[4 * r + c] = float(placed.linear(r, c));
        xfm[4 * r + 3] = float(placed.translation[r]);
      }
      rtcSetGeometryTransform(instance, 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, xfm);
      placed.geomID = attach(instance, SurfaceKind::kMesh, out->prototypeMeshes_.back()[0], k);
      out->geoms_[placed.geomID].placed = uint32_t(out->placed_.size());
      out->placed_.push_back(placed);
    }
    open.placements = nullptr;
  };
  const auto samePlacements = [](const std::vector<MeshPlacement>& a,
                                 const std::vector<MeshPlacement>& b) {
    if (a.size() != b.size()) return false;
    for (size_t k = 0; k < a.size(); ++k)
      if (!(a[k].linear == b[k].linear) || !(a[k].translation == b[k].translation)) return false;
    return true;
  };
  for (uint32_t m = 0; m < scene.meshes.size(); ++m) {
    const TriangleMesh& mesh = scene.meshes[m];
    if (mesh.TriangleCount() == 0) continue;
    // An instanced mesh's vertices stay in its own frame; the others move to local coordinates.
    const bool instanced = !mesh.placements.empty();
    const Vec3d shift = instanced ? Vec3d{0, 0, 0} : offset;
    RTCGeometry geom = rtcNewGeometry(impl.device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* verts = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0,
                                                              RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                                              mesh.positions.size()));
    auto* indices = static_cast<uint32_t*>(
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                3 * sizeof(uint32_t), mesh.TriangleCount()));
    if (!verts || !indices) {
      rtcReleaseGeometry(geom);
      PB_RETURN_IF_ERROR(impl.Check("Embree: allocating mesh buffers"));
      return absl::InternalError("Embree: cannot allocate mesh buffers");
    }
    Vec3d lo = mesh.positions[0] - shift, hi = lo;
    for (size_t i = 0; i < mesh.positions.size(); ++i) {
      const Vec3d local = mesh.positions[i] - shift;
      verts[3 * i] = float(local.x);
      verts[3 * i + 1] = float(local.y);
      verts[3 * i + 2] = float(local.z);
      lo = Min(lo, local);
      hi = Max(hi, local);
      if (!instanced) grow(local);
    }
    std::copy(mesh.indices.begin(), mesh.indices.end(), indices);
    std::vector<Vec3f>& normals = out->normals_[m];
    normals.resize(mesh.TriangleCount());
    for (size_t t = 0; t < mesh.TriangleCount(); ++t) {
      const Vec3d& a = mesh.positions[mesh.indices[3 * t]];
      const Vec3d& b = mesh.positions[mesh.indices[3 * t + 1]];
      const Vec3d& c = mesh.positions[mesh.indices[3 * t + 2]];
      const Vec3d n = Cross(b - a, c - a);
      const double len = Length(n);
      normals[t] = len > 0 ? Vec3f(n / len) : Vec3f(0, 0, 1);
    }
    out->meshVerts_[m] = verts;
    out->meshIndices_[m] = indices;
    const Material& material = scene.materials[mesh.material];
    out->doubleSided_[m] = material.doubleSided;
    if (material.HasCutout()) {
      if (!rtcGetDeviceProperty(impl.device, RTC_DEVICE_PROPERTY_FILTER_FUNCTION_SUPPORTED)) {
        rtcReleaseGeometry(geom);
        return absl::InternalError("Embree was built without filter functions: cutout material " +
                                   material.name + " cannot be traced");
      }
      impl.cutouts.push_back(std::make_unique<Cutout>(Cutout{&material, &mesh}));
      rtcSetGeometryUserData(geom, impl.cutouts.back().get());
      rtcSetGeometryIntersectFilterFunction(geom, CutoutFilter);
      rtcSetGeometryOccludedFilterFunction(geom, CutoutFilter);
    }
    if (!instanced) {
      impl.meshOfGeom[attach(geom, SurfaceKind::kMesh, m)] = m;
      continue;
    }
    if (open.placements == nullptr || !samePlacements(*open.placements, mesh.placements)) {
      place();
      RTCScene prototype = rtcNewScene(impl.device);
      impl.prototypes.push_back(prototype);
      rtcSetSceneFlags(prototype, RTC_SCENE_FLAG_ROBUST);
      rtcSetSceneBuildQuality(prototype, RTC_BUILD_QUALITY_HIGH);
      out->prototypeMeshes_.emplace_back();
      open = {&mesh.placements, lo, hi};
    }
    open.lo = Min(open.lo, lo);
    open.hi = Max(open.hi, hi);
    rtcCommitGeometry(geom);
    const unsigned child = rtcAttachGeometry(impl.prototypes.back(), geom);
    rtcReleaseGeometry(geom);
    std::vector<uint32_t>& meshOfChild = out->prototypeMeshes_.back();
    if (meshOfChild.size() <= child) meshOfChild.resize(child + 1, UINT32_MAX);
    meshOfChild[child] = m;
  }
  place();

  for (uint32_t i = 0; i < scene.lights.size(); ++i) {
    const Light& light = scene.lights[i];
    if (const auto* rect = std::get_if<RectLight>(&light)) {
      RTCGeometry geom = rtcNewGeometry(impl.device, RTC_GEOMETRY_TYPE_TRIANGLE);
      auto* v = static_cast<float*>(
          rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, 4));
      auto* idx = static_cast<uint32_t*>(
          rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, 2));
      const Vec3d c = rect->corner - offset;
      const Vec3d corners[4] = {c, c + rect->edge1, c + rect->edge1 + rect->edge2, c + rect->edge2};
      for (int k = 0; k < 4; ++k) {
        v[3 * k] = float(corners[k].x);
        v[3 * k + 1] = float(corners[k].y);
        v[3 * k + 2] = float(corners[k].z);
        grow(corners[k]);
      }
      // Counter-clockwise seen from the emitting side: normal along edge1 x edge2.
      const uint32_t tris[6] = {0, 1, 2, 0, 2, 3};
      std::copy(tris, tris + 6, idx);
      attach(geom, SurfaceKind::kRectLight, i);
    } else if (const auto* disk = std::get_if<DiskLight>(&light)) {
      RTCGeometry geom = NewPointGeometry(impl.device, RTC_GEOMETRY_TYPE_ORIENTED_DISC_POINT,
                                          disk->center - offset, disk->radius, grow);
      auto* n = static_cast<float*>(
          rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_NORMAL, 0, RTC_FORMAT_FLOAT3, 12, 1));
      n[0] = float(disk->normal.x), n[1] = float(disk->normal.y), n[2] = float(disk->normal.z);
      attach(geom, SurfaceKind::kDiskLight, i);
    } else if (const auto* sphere = std::get_if<SphereLight>(&light)) {
      attach(NewPointGeometry(impl.device, RTC_GEOMETRY_TYPE_SPHERE_POINT, sphere->center - offset,
                              sphere->radius, grow),
             SurfaceKind::kSphereLight, i);
    }
  }

  PB_RETURN_IF_ERROR(impl.Check("Embree: creating geometry"));
  rtcCommitScene(impl.scene);
  PB_RETURN_IF_ERROR(impl.Check("Embree: building the BVH"));
  return out;
}

bool TracerScene::Intersect(const Vec3f& origin, const Vec3d& dir, double tMax,
                            SurfaceHit* hit) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh;
  InitRay(rh.ray, origin, dir, tMax);
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene, &context, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
  FillHit(TopGeometry(rh.hit.geomID, rh.hit.instID[0]), rh.hit.geomID, rh.hit.primID, rh.hit.u,
          rh.hit.v, Vec3d{rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z}, rh.ray.tfar, origin, dir, hit);
  return true;
}

void TracerScene::IntersectPacket(std::span<const Vec3f> origins, std::span<const Vec3d> dirs,
                                  SurfaceHit* hits, bool* found) const {
  PB_CHECK_LE(dirs.size(), size_t(kPacketWidth));
  const size_t originStep = OriginStep(origins, dirs);
  static_assert(kPacketWidth == 8, "rtcIntersect8 below");
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  context.flags = PacketFlags(originStep);
  alignas(32) int valid[kPacketWidth];
  alignas(32) RTCRayHit8 rh;
  for (int k = 0; k < kPacketWidth; ++k) {
    const bool active = size_t(k) < dirs.size();
    valid[k] = active ? -1 : 0;
    RTCRay one;
    const size_t lane = active ? size_t(k) : 0;
    InitRay(one, origins[lane * originStep], dirs[lane], std::numeric_limits<double>::infinity());
    SetLane(rh.ray, k, one);
    rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID[k] = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
  }
  rtcIntersect8(valid, impl_->scene, &context, &rh);
  for (size_t k = 0; k < dirs.size(); ++k) {
    found[k] = rh.hit.geomID[k] != RTC_INVALID_GEOMETRY_ID;
    if (!found[k]) continue;
    FillHit(TopGeometry(rh.hit.geomID[k], rh.hit.instID[0][k]), rh.hit.geomID[k], rh.hit.primID[k],
            rh.hit.u[k], rh.hit.v[k], Vec3d{rh.hit.Ng_x[k], rh.hit.Ng_y[k], rh.hit.Ng_z[k]},
            rh.ray.tfar[k], origins[k * originStep], dirs[k], &hits[k]);
  }
}

void TracerScene::OccludedPacket(std::span<const Vec3f> origins, std::span<const Vec3d> dirs,
                                 const double* tMax, bool* occluded) const {
  PB_CHECK_LE(dirs.size(), size_t(kPacketWidth));
  const size_t originStep = OriginStep(origins, dirs);
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  context.flags = PacketFlags(originStep);
  alignas(32) int valid[kPacketWidth];
  alignas(32) RTCRay8 ray;
  for (int k = 0; k < kPacketWidth; ++k) {
    const bool active = size_t(k) < dirs.size();
    valid[k] = active ? -1 : 0;
    RTCRay one;
    const size_t lane = active ? size_t(k) : 0;
    InitRay(one, origins[lane * originStep], dirs[lane], active ? tMax[k] : 0);
    SetLane(ray, k, one);
  }
  rtcOccluded8(valid, impl_->scene, &context, &ray);
  for (size_t k = 0; k < dirs.size(); ++k) occluded[k] = ray.tfar[k] < 0;
}

void TracerScene::FillHit(uint32_t geomID, uint32_t childGeomID, uint32_t primID, float u, float v,
                          const Vec3d& ng, float tfar, const Vec3f& origin, const Vec3d& dir,
                          SurfaceHit* hit) const {
  const GeomInfo info = geoms_[geomID];
  hit->t = tfar;
  hit->kind = info.kind;
  hit->index = info.index;
  hit->instance = info.instance;
  hit->prim = primID;
  hit->u = u;
  hit->v = v;
  if (info.kind == SurfaceKind::kMesh) {
    // A placed mesh's triangle is read in the mesh's own frame and placed below.
    const Placed* placed = info.placed != UINT32_MAX ? &placed_[info.placed] : nullptr;
    const uint32_t mesh = placed ? prototypeMeshes_[placed->prototype][childGeomID] : info.index;
    hit->index = mesh;
    const float* verts = meshVerts_[mesh];
    const uint32_t* idx = meshIndices_[mesh] + 3 * primID;
    // Interpolated in double: the point lies on the float triangle's plane to ~1e-16 of the
    // vertex magnitudes (a float interpolation would leave it ulps of those magnitudes off it).
    const double bu = u, bw = v, b0 = 1 - bu - bw;
    const float* a = verts + 3 * idx[0];
    const float* b = verts + 3 * idx[1];
    const float* c = verts + 3 * idx[2];
    hit->p = {b0 * a[0] + bu * b[0] + bw * c[0], b0 * a[1] + bu * b[1] + bw * c[1],
              b0 * a[2] + bu * b[2] + bw * c[2]};
    // The largest in float, converted once: the same value (conversion to double is exact).
    float scale = 0;
    for (int k = 0; k < 3; ++k)
      scale = std::max({scale, std::fabs(a[k]), std::fabs(b[k]), std::fabs(c[k])});
    hit->vertexScale = scale;
    if (placed == nullptr) {
      // Embree's geometric normal, (v1 - v0) x (v2 - v0) like ours: no table lookup (a cache miss
      // per hit in large scenes).
      hit->ng = Normalize(ng);
    } else {
      hit->p = placed->linear * hit->p + placed->translation;
      // Embree intersects in the mesh's frame (error ~ its vertex magnitudes, scaled out by the
      // linear part) after moving the ray there (error ~ the world coordinates, amplified by the
      // linear part's conditioning).
      hit->vertexScale = std::max(placed->linearNorm * double(scale),
                                  placed->conditioning * MaxComponent(Abs(hit->p)));
      hit->ng = PlacedNormal(*placed, mesh, primID);
    }
  } else {
    // Area lights end paths: their hit point is needed for pdfs only, never to spawn rays.
    hit->p = Vec3d(origin) + dir * hit->t;
    hit->ng = Normalize(ng);
  }
}

bool TracerScene::Occluded(const Vec3f& origin, const Vec3d& dir, double tMax) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRay ray;
  InitRay(ray, origin, dir, tMax);
  rtcOccluded1(impl_->scene, &context, &ray);
  return ray.tfar < 0;
}

template <typename Visit>
void TracerScene::VisitMeshTrianglesNear(const Vec3d& p, double radius, Visit&& visit) const {
  struct State {
    const TracerScene* scene;
    Visit* visit;
    bool stopped = false;
  } state{this, &visit};
  RTCPointQuery query;
  query.x = float(p.x);
  query.y = float(p.y);
  query.z = float(p.z);
  query.radius = float(radius);
  query.time = 0;
  RTCPointQueryContext context;
  rtcInitPointQueryContext(&context);
  auto callback = [](RTCPointQueryFunctionArguments* args) -> bool {
    auto* s = static_cast<State*>(args->userPtr);
    const std::vector<uint32_t>& meshOfGeom = s->scene->impl_->meshOfGeom;
    // Placed meshes are queried below, in their own frames.
    if (args->context->instStackSize > 0) return false;
    if (s->stopped || args->geomID >= meshOfGeom.size()) return false;
    const uint32_t mesh = meshOfGeom[args->geomID];
    if (mesh == UINT32_MAX) return false;
    const float* v = s->scene->meshVerts_[mesh];
    const uint32_t* idx = s->scene->meshIndices_[mesh] + 3 * args->primID;
    if (!(*s->visit)(mesh, args->geomID, args->primID, Vertex(v, idx[0]), Vertex(v, idx[1]),
                     Vertex(v, idx[2])))
      return false;
    s->stopped = true;
    args->query->radius = 0;  // done: shrink the search to end traversal quickly
    return true;
  };
  rtcPointQuery(impl_->scene, &query, &context, callback, &state);

  // Each placement whose box comes within `radius`: its mesh's scene queried in the mesh's frame,
  // around the point moved there, with a radius that covers the sphere's image (the Frobenius
  // norm of the inverse bounds how far it stretches), and the triangles placed back exactly.
  struct PlacedState {
    const TracerScene* scene;
    const Placed* placed;
    Visit* visit;
    bool* stopped;
  };
  auto placedCallback = [](RTCPointQueryFunctionArguments* args) -> bool {
    auto* s = static_cast<PlacedState*>(args->userPtr);
    if (*s->stopped) return false;
    const Placed& placed = *s->placed;
    const uint32_t mesh = s->scene->prototypeMeshes_[placed.prototype][args->geomID];
    const float* v = s->scene->meshVerts_[mesh];
    const uint32_t* idx = s->scene->meshIndices_[mesh] + 3 * args->primID;
    const auto place = [&](uint32_t i) {
      return placed.linear * Vertex(v, i) + placed.translation;
    };
    if (!(*s->visit)(mesh, placed.geomID, args->primID, place(idx[0]), place(idx[1]),
                     place(idx[2])))
      return false;
    *s->stopped = true;
    args->query->radius = 0;
    return true;
  };
  for (const Placed& placed : placed_) {
    if (state.stopped) return;
    bool apart = false;
    for (int a = 0; a < 3; ++a)
      apart = apart || p[a] < placed.boundsMin[a] - radius || p[a] > placed.boundsMax[a] + radius;
    if (apart) continue;
    const Vec3d q = placed.inverse * (p - placed.translation);
    RTCPointQuery local;
    local.x = float(q.x);
    local.y = float(q.y);
    local.z = float(q.z);
    // Widened by float's rounding of the moved point, so a triangle at the edge is not culled.
    local.radius = float(radius * placed.inverseStretch * (1 + 1e-5) + 1e-6 * MaxComponent(Abs(q)));
    local.time = 0;
    RTCPointQueryContext localContext;
    rtcInitPointQueryContext(&localContext);
    PlacedState placedState{this, &placed, &visit, &state.stopped};
    rtcPointQuery(impl_->prototypes[placed.prototype], &local, &localContext, placedCallback,
                  &placedState);
  }
}

bool TracerScene::MeshWithin(const Vec3d& p, double radius) const {
  bool found = false;
  VisitMeshTrianglesNear(
      p, radius, [&](uint32_t, unsigned, unsigned, const Vec3d& a, const Vec3d& b, const Vec3d& c) {
        found = Length(ClosestPointOnTriangle(p, a, b, c) - p) <= double(float(radius));
        return found;
      });
  return found;
}

bool TracerScene::MeshSurfaceAt(const Vec3d& p, SurfaceHit* on) const {
  // Every triangle's resolution is at most that of the largest coordinates in the scene.
  const double maxAbs = std::max(
      {MaxComponent(Abs(p)), MaxComponent(Abs(boundsMin_)), MaxComponent(Abs(boundsMax_))});
  bool found = false;
  unsigned bestGeom = 0, bestPrim = 0;
  VisitMeshTrianglesNear(
      p, 2 * SurfaceResolution(p, maxAbs),
      [&](uint32_t mesh, unsigned geomID, unsigned primID, const Vec3d& a, const Vec3d& b,
          const Vec3d& c) {
        const double vertexScale =
            std::max({MaxComponent(Abs(a)), MaxComponent(Abs(b)), MaxComponent(Abs(c))});
        const Vec3d q = ClosestPointOnTriangle(p, a, b, c);
        const double distance = Length(q - p);
        if (!(distance < SurfaceResolution(q, vertexScale))) return false;
        if (found && std::tie(distance, geomID, primID) >= std::tie(on->t, bestGeom, bestPrim))
          return false;
        found = true;
        bestGeom = geomID;
        bestPrim = primID;
        on->p = q;
        on->t = distance;
        const uint32_t placed = geoms_[geomID].placed;
        on->ng = placed == UINT32_MAX ? Vec3d(TriangleNormal(mesh, primID))
                                      : PlacedNormal(placed_[placed], mesh, primID);
        on->vertexScale = vertexScale;
        on->kind = SurfaceKind::kMesh;
        on->index = mesh;
        on->instance = placed == UINT32_MAX ? 0 : placed_[placed].instance;
        on->prim = primID;
        return false;  // a nearer triangle may still come
      });
  return found;
}

}  // namespace probebake
