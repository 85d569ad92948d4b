// The ray-traceable scene of one bake: Embree 3 device and BVH over the meshes and the area
// lights' own surfaces (rect: two triangles, disk: an oriented disc, sphere: a sphere), built once
// per job and held in RAII wrappers. An instanced mesh (TriangleMesh::placements) is one Embree
// scene of its own, placed by one Embree instance per placement: its triangles are stored once.
// Meshes with a cutout material (scene.h) reject hits where their coverage is below the cutoff, for
// every query that traces rays; the point queries (MeshWithin, MeshSurfaceAt) see their triangles
// whole. The scene must outlive the tracer.
//
// Coordinates: the tracer works in "local" coordinates, world minus `offset` (the centre of the
// scene's bounds), in double. Embree stores float vertices of the local coordinates, so a scene far
// from the world origin traces like the same scene at the origin. Thread safe for queries after
// Build.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <vector>

#include "absl/status/statusor.h"
#include "probebake/math/mat3.h"
#include "probebake/math/vec3.h"
#include "probebake/scene/scene.h"

namespace probebake {

enum class SurfaceKind : uint8_t { kMesh, kRectLight, kDiskLight, kSphereLight };

struct SurfaceHit {
  double t = 0;  // distance along the unit ray direction
  Vec3d p;       // local position
  Vec3d ng;      // unit geometric normal of the front (counter-clockwise / emitting) side
  // Largest magnitude of the hit triangle's float vertex coordinates: the scale of the float
  // error of the surface near p, as Embree sees it (ray_offset.h). Meshes only.
  double vertexScale = 0;
  SurfaceKind kind = SurfaceKind::kMesh;
  uint32_t index = 0;     // mesh index (kMesh) or light index in Scene::lights
  uint32_t instance = 0;  // an instanced mesh's placement (TriangleMesh::placements), else 0
  uint32_t prim = 0;      // triangle index within the mesh
  // Embree's barycentrics of the hit on triangle `prim`, p = (1 - u - v) a + u b + v c (meshes
  // and rect lights): where a material's textures and vertex colours are read.
  float u = 0, v = 0;
};

// The Embree device configuration of every bake. Embree picks its kernels by the CPU's
// instruction set at run time, and its AVX2 and AVX-512 kernels use fused multiply-adds: they
// round hit distances and barycentrics differently from its SSE and AVX kernels, so the same job
// would bake different bits on different machines (and the shards of one grid baked on a mixed
// cluster would not merge into a local bake's bits). Capped at AVX, every x86-64 CPU runs kernels
// without fused multiply-adds and traces the same hits; on the bench scenes the cap costs no
// measurable time (docs/performance-history.md).
inline constexpr const char* kEmbreeDeviceConfig = "max_isa=avx";

class TracerScene {
 public:
  // Builds the BVH. Errors reported by Embree's device callback come back as INTERNAL.
  // deviceConfig: Embree's rtcNewDevice configuration (tests compare kernels through it).
  static absl::StatusOr<std::unique_ptr<TracerScene>> Build(
      const Scene& scene, const Vec3d& offset, const char* deviceConfig = kEmbreeDeviceConfig);
  ~TracerScene();
  TracerScene(const TracerScene&) = delete;
  TracerScene& operator=(const TracerScene&) = delete;

  // Nearest hit along origin + t dir, t in (0, tMax); dir unit. Returns false on a miss.
  bool Intersect(const Vec3f& origin, const Vec3d& dir, double tMax, SurfaceHit* hit) const;
  // The float tfar Embree is given for a ray's tMax (infinite beyond the float range).
  static float EmbreeTFar(double tMax) {
    return tMax >= double(std::numeric_limits<float>::max())
               ? std::numeric_limits<float>::infinity()
               : float(tMax);
  }
  // Rays traced together by IntersectPacket.
  static constexpr int kPacketWidth = 8;
  // Intersect(origins[k], dirs[k], inf, &hits[k]) for up to kPacketWidth unit directions, traced
  // as one packet: found[k] is its return value (hits[k] is left alone on a miss). `origins` holds
  // one origin per ray, or a single one that all the rays share. Cheaper per ray than Intersect
  // when the rays are close, since they share most of the BVH traversal; the hits may differ from
  // Intersect's in the last float bits.
  void IntersectPacket(std::span<const Vec3f> origins, std::span<const Vec3d> dirs,
                       SurfaceHit* hits, bool* found) const;
  // occluded[k] = Occluded(origins[k], dirs[k], tMax[k]) for up to kPacketWidth rays, as one
  // packet; `origins` as above.
  void OccludedPacket(std::span<const Vec3f> origins, std::span<const Vec3d> dirs,
                      const double* tMax, bool* occluded) const;
  // True when anything lies along origin + t dir, t in (0, tMax).
  bool Occluded(const Vec3f& origin, const Vec3d& dir, double tMax) const;
  // True when a mesh triangle lies within `radius` of p (area lights' surfaces are not counted).
  bool MeshWithin(const Vec3d& p, double radius) const;
  // The mesh surface p lies on, if any: among the triangles closer to p than the tracer resolves
  // (SurfaceResolution, ray_offset.h), the nearest (ties: lowest geometry, then triangle index, so
  // the answer never depends on traversal order). Rays from such a point may start on either
  // side of the surface. Fills `on`: p = that triangle's closest point, ng its front normal,
  // vertexScale, t = the distance, kind, index and prim.
  bool MeshSurfaceAt(const Vec3d& p, SurfaceHit* on) const;

  const Vec3d& offset() const { return offset_; }
  // Unit geometric normal of triangle `prim` of mesh `mesh` (local = world orientation); for an
  // instanced mesh, in the mesh's own frame (hits carry their world normal).
  const Vec3f& TriangleNormal(uint32_t mesh, uint32_t prim) const { return normals_[mesh][prim]; }
  // Whether both sides of mesh `mesh` are front faces (its material is double-sided): for
  // validity, a back-face hit on it counts as a front one.
  bool DoubleSided(uint32_t mesh) const { return doubleSided_[mesh] != 0; }
  // Local-coordinate bounds of all geometry (meshes and area lights); empty scenes give min > max.
  const Vec3d& boundsMin() const { return boundsMin_; }
  const Vec3d& boundsMax() const { return boundsMax_; }

 private:
  struct GeomInfo {
    SurfaceKind kind;
    uint32_t index;
    uint32_t instance = 0;          // the placement, for an instance of a mesh
    uint32_t placed = 0xFFFFFFFFu;  // its index in placed_, for an instance of a mesh
  };
  // One placement of an instanced mesh, in local coordinates: x = linear * p + translation for p
  // in the mesh's frame.
  struct Placed {
    uint32_t prototype = 0;  // the Embree scene it places: prototypeMeshes_'s index
    uint32_t instance = 0;   // its index in the placements of the prototype's meshes
    unsigned geomID = 0;     // its Embree instance's ID in the top-level scene
    Mat3d linear, inverse;
    // inverse(linear)^T: a placed triangle's front normal from its own, unnormalized. A mirroring
    // placement keeps the mesh's front faces (scene.h), though it turns the placed winding.
    Mat3d normals;
    Vec3d translation;
    // The float error of a placed hit grows by these over the mesh's own (tracer_scene.cpp).
    double linearNorm = 1, conditioning = 1;
    // The Frobenius norm of inverse: a sphere of radius r maps into one of r times this.
    double inverseStretch = 1;
    Vec3d boundsMin, boundsMax;  // local bounds of the placed mesh
  };
  struct Impl;

  // Calls visit(mesh, geomID, primID, a, b, c) with the local vertices of mesh triangles whose
  // bounds come within `radius` of p (Embree's point query), until it returns true.
  // Fills `hit` from Embree's hit record of the ray origin + t dir.
  // geomID: the top-level geometry (an instance's own ID for a hit inside an instance);
  // childGeomID: the geometry within the instance's scene.
  void FillHit(uint32_t geomID, uint32_t childGeomID, uint32_t primID, float u, float v,
               const Vec3d& ng, float tfar, const Vec3f& origin, const Vec3d& dir,
               SurfaceHit* hit) const;
  // The unit front normal of triangle `prim` of mesh `mesh` where `placed` puts it.
  Vec3d PlacedNormal(const Placed& placed, uint32_t mesh, uint32_t prim) const {
    return Normalize(placed.normals * Vec3d(normals_[mesh][prim]));
  }
  // The top-level geometry of an Embree hit record.
  static uint32_t TopGeometry(uint32_t geomID, uint32_t instID) {
    return instID != 0xFFFFFFFFu ? instID : geomID;
  }
  template <typename Visit>
  void VisitMeshTrianglesNear(const Vec3d& p, double radius, Visit&& visit) const;

  TracerScene() = default;

  Vec3d offset_;
  Vec3d boundsMin_, boundsMax_;
  std::unique_ptr<Impl> impl_;
  std::vector<GeomInfo> geoms_;  // by Embree geometry ID
  std::vector<Placed> placed_;   // every placement of every instanced mesh
  // Per Embree scene of instanced meshes: the mesh of each of its geometry IDs.
  std::vector<std::vector<uint32_t>> prototypeMeshes_;
  std::vector<std::vector<Vec3f>> normals_;  // per mesh, per triangle
  // Per mesh: Embree's own float vertex (x y z per vertex) and index buffers, alive as long as
  // the Embree scene.
  std::vector<const float*> meshVerts_;
  std::vector<const uint32_t*> meshIndices_;
  std::vector<uint8_t> doubleSided_;  // per mesh
};

// The centre of the bounds of everything finite in the scene (meshes, finite lights), or the world
// origin when there is nothing finite: the origin of the tracer's local coordinates. It depends on
// the scene alone, not on the probe grid, so a sub-grid bakes in the same coordinates as the whole
// grid (probe_site.h).
Vec3d LocalOrigin(const Scene& scene);
// World bounds of everything finite in the scene (meshes, finite lights, point and spot lights);
// false when there is nothing finite.
bool FiniteSceneBounds(const Scene& scene, Vec3d* boundsMin, Vec3d* boundsMax);

}  // namespace probebake
