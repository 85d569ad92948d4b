#include "probebake/engines/engine_export.h"

#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "probebake/base/atomic_file.h"
#include "probebake/base/check.h"
#include "probebake/engines/probe_textures.h"
#include "probebake/sh/sh_rotation.h"
#include "probebake/sh/sh_unity.h"

namespace probebake {
namespace {

std::array<Vec3d, 9> Rotate(std::span<const Vec3d, 9> radiance, const Mat3d& axes) {
  // The axis maps are exact orthogonal matrices: Create cannot fail.
  const absl::StatusOr<ShRotation> rotation = ShRotation::Create(2, axes);
  PB_CHECK(rotation.ok());
  std::array<Vec3d, 9> out;
  rotation->ApplyRgb(radiance, out);
  return out;
}

void AppendVec(std::string* s, const Vec3d& v) {
  absl::StrAppendFormat(s, "[%.9g,%.9g,%.9g]", v.x, v.y, v.z);
}

}  // namespace

absl::StatusOr<EngineFormat> ParseEngineFormat(const std::string& name) {
  if (name == "threejs") return EngineFormat::kThreeJs;
  if (name == "unity") return EngineFormat::kUnity;
  if (name == "textures") return EngineFormat::kTextures;
  return absl::InvalidArgumentError(
      absl::StrCat("--format: unknown format '", name, "' (threejs, unity, textures)"));
}

Mat3d ThreeJsFromProbebakeAxes() {
  return Mat3d::FromRows({1, 0, 0}, {0, 0, 1}, {0, -1, 0});
}

std::array<Vec3d, 9> ThreeJsSh(std::span<const Vec3d, 9> radiance) {
  std::array<Vec3d, 9> sh = Rotate(radiance, ThreeJsFromProbebakeAxes());
  // three's basis has no Condon-Shortley phase: +0.488603 y, +z, +x, +1.092548 yz, +xz.
  for (int i : {1, 3, 5, 7}) sh[i] = -sh[i];
  return sh;
}

std::array<Vec3d, 9> UnitySh(std::span<const Vec3d, 9> radiance) {
  return Rotate(radiance, UnityFromProbebakeAxes());
}

std::string EngineExportJson(std::span<const EngineProbe> probes, EngineFormat format) {
  PB_CHECK(format != EngineFormat::kTextures);
  const bool three = format == EngineFormat::kThreeJs;
  const Mat3d axes = three ? ThreeJsFromProbebakeAxes() : UnityFromProbebakeAxes();
  std::string s = "{";
  if (three) {
    s += R"js("frame":"three.js Y-up: (x, y, z) = probebake (x, z, -y)",)js";
    s +=
        R"js("sh_convention":"THREE.SphericalHarmonics3 radiance coefficients (LightProbe.sh)",)js";
  } else {
    s += R"js("frame":"Unity Y-up left-handed: (x, y, z) = probebake (x, z, y)",)js";
    s +=
        R"js("sh_convention":"UnityEngine.Rendering.SphericalHarmonicsL2: sh[9 * rgb + i] = )js"
        R"js(SphericalHarmonicsL2[rgb, i], radiance coefficients, ShadeSH9 gives irradiance / pi",)js";
  }
  s += "\"probes\":[";
  bool first = true;
  for (const EngineProbe& probe : probes) {
    if (!probe.usable) continue;
    if (!first) s += ",";
    first = false;
    s += "\n{\"position\":";
    AppendVec(&s, axes * probe.position);
    s += ",\"sh\":[";
    if (three) {
      const std::array<Vec3d, 9> sh = ThreeJsSh(probe.radiance);
      for (int c = 0; c < 9; ++c) {
        if (c) s += ",";
        AppendVec(&s, sh[c]);
      }
    } else {
      // Flat, channel-major: Unity's JsonUtility reads no nested arrays.
      const std::array<Vec3d, 9> sh = UnitySh(probe.radiance);
      for (int ch = 0; ch < 3; ++ch)
        for (int c = 0; c < 9; ++c)
          absl::StrAppendFormat(&s, "%s%.9g", ch || c ? "," : "", sh[c][ch]);
    }
    s += "]}";
  }
  s += "]}\n";
  return s;
}

absl::Status WriteTextFileAtomically(const std::string& path, const std::string& text) {
  absl::StatusOr<AtomicFile> file = AtomicFile::Create(path);
  if (!file.ok()) return file.status();
  size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(file->fd(), text.data() + done, text.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      return absl::InternalError(absl::StrCat(path, ": write: ", std::strerror(errno)));
    }
    done += static_cast<size_t>(n);
  }
  return file->Commit();
}

absl::Status WriteEngineExport(const ProbeVolume& volume, EngineFormat format,
                               const std::string& path) {
  if (format == EngineFormat::kTextures) return WriteProbeTextures(volume, path);
  absl::StatusOr<std::vector<EngineProbe>> probes = EngineProbes(volume);
  if (!probes.ok()) return probes.status();
  return WriteTextFileAtomically(path, EngineExportJson(*probes, format));
}

}  // namespace probebake
