#include "bench_embree_scene.h"

#include <algorithm>
#include <string>
#include <variant>

#include "core/src/bake/tracer_scene.h"

namespace probebake::bench {

absl::Status EmbreeScene::Build(const Scene& scene, const Vec3d& offset, int64_t* triangles) {
  device_ = rtcNewDevice(kEmbreeDeviceConfig);  // the kernels the tracer runs
  if (!device_) return absl::InternalError("Embree: cannot create a device");
  scene_ = rtcNewScene(device_);
  rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_HIGH);
  *triangles = 0;
  for (const TriangleMesh& mesh : scene.meshes) {
    if (mesh.TriangleCount() == 0) continue;
    // The bench's scenes are flat; instances would need the tracer's two-level scene here.
    if (!mesh.placements.empty())
      return absl::UnimplementedError("raw-Embree bench scene: mesh " + mesh.name +
                                      " is instanced");
    RTCGeometry geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(
        geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, mesh.positions.size()));
    auto* idx = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(
        geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, mesh.TriangleCount()));
    for (size_t i = 0; i < mesh.positions.size(); ++i) {
      const Vec3d local = mesh.positions[i] - offset;
      v[3 * i] = float(local.x), v[3 * i + 1] = float(local.y), v[3 * i + 2] = float(local.z);
    }
    std::copy(mesh.indices.begin(), mesh.indices.end(), idx);
    *triangles += int64_t(mesh.TriangleCount());
    Attach(geom);
  }
  for (const Light& light : scene.lights) {
    if (const auto* rect = std::get_if<RectLight>(&light)) {
      RTCGeometry geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
      auto* v = static_cast<float*>(
          rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, 4));
      auto* idx = static_cast<uint32_t*>(
          rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, 2));
      const Vec3d c = rect->corner - offset;
      const Vec3d corners[4] = {c, c + rect->edge1, c + rect->edge1 + rect->edge2, c + rect->edge2};
      for (int k = 0; k < 4; ++k)
        for (int a = 0; a < 3; ++a) v[3 * k + a] = float(corners[k][a]);
      const uint32_t tris[6] = {0, 1, 2, 0, 2, 3};
      std::copy(tris, tris + 6, idx);
      Attach(geom);
    } else if (const auto* disk = std::get_if<DiskLight>(&light)) {
      RTCGeometry geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_ORIENTED_DISC_POINT);
      auto* v = static_cast<float*>(
          rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 16, 1));
      auto* n = static_cast<float*>(
          rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_NORMAL, 0, RTC_FORMAT_FLOAT3, 12, 1));
      const Vec3d c = disk->center - offset;
      v[0] = float(c.x), v[1] = float(c.y), v[2] = float(c.z), v[3] = float(disk->radius);
      n[0] = float(disk->normal.x), n[1] = float(disk->normal.y), n[2] = float(disk->normal.z);
      Attach(geom);
    } else if (const auto* sphere = std::get_if<SphereLight>(&light)) {
      RTCGeometry geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_SPHERE_POINT);
      auto* v = static_cast<float*>(
          rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 16, 1));
      const Vec3d c = sphere->center - offset;
      v[0] = float(c.x), v[1] = float(c.y), v[2] = float(c.z), v[3] = float(sphere->radius);
      Attach(geom);
    }
  }
  rtcCommitScene(scene_);
  const RTCError error = rtcGetDeviceError(device_);
  if (error != RTC_ERROR_NONE)
    return absl::InternalError("Embree error " + std::to_string(int(error)));
  return absl::OkStatus();
}

}  // namespace probebake::bench
