// The scene as the tracer's Embree sees it, for the bench's raw-Embree measurements: the same
// meshes in the same local coordinates (tracer_scene.h: world minus LocalOrigin), area lights as
// geometry (rect: two triangles, disk: an oriented disc, sphere: a sphere), RTC_SCENE_FLAG_ROBUST,
// build quality HIGH and the tracer's device configuration (kEmbreeDeviceConfig).
#pragma once

#include <embree3/rtcore.h>

#include <cstdint>

#include "absl/status/status.h"
#include "probebake/math/vec3.h"
#include "probebake/scene/scene.h"

namespace probebake::bench {

// An Embree device and scene, released on destruction.
class EmbreeScene {
 public:
  EmbreeScene() = default;
  ~EmbreeScene() {
    if (scene_) rtcReleaseScene(scene_);
    if (device_) rtcReleaseDevice(device_);
  }
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  // Builds `scene` in local coordinates (world minus `offset`), as the tracer does; *triangles
  // gets the meshes' triangle count. Instanced meshes are refused (UNIMPLEMENTED).
  absl::Status Build(const Scene& scene, const Vec3d& offset, int64_t* triangles);

  RTCScene scene() const { return scene_; }

 private:
  void Attach(RTCGeometry geom) {
    rtcCommitGeometry(geom);
    rtcAttachGeometry(scene_, geom);
    rtcReleaseGeometry(geom);
  }
  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
};

}  // namespace probebake::bench
