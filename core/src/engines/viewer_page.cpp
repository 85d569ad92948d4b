#include "probebake/engines/viewer_page.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "../bake/surface_material.h"
#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_replace.h"
#include "probebake/engines/engine_export.h"
#include "probebake/engines/engine_probes.h"
#include "probebake/engines/probe_textures.h"
#include "probebake/sh/sh_convolution.h"

namespace probebake {
namespace {

void AppendVec(std::string* s, const Vec3d& v) {
  absl::StrAppendFormat(s, "[%.9g,%.9g,%.9g]", v.x, v.y, v.z);
}

// A float for JSON: non-finite values (an unknown std_error is +inf) become -1.
double JsonNumber(float v) {
  return std::isfinite(v) ? v : -1.0;
}

}  // namespace

absl::StatusOr<std::string> ViewerPageHtml(const ProbeVolume& volume, const Scene* scene,
                                           std::string_view bundle, const ViewerOptions& options) {
  absl::StatusOr<std::vector<EngineProbe>> probes = EngineProbes(volume);
  if (!probes.ok()) return probes.status();
  const Mat3d axes = ThreeJsFromProbebakeAxes();

  double exposure = options.exposure;
  if (exposure <= 0) {
    std::vector<double> levels;
    for (const EngineProbe& p : *probes) {
      if (!p.usable) continue;
      const Vec3d e = IrradianceAtRgb(2, p.radiance, {0, 0, 1}) / std::numbers::pi;
      levels.push_back(std::max({e.x, e.y, e.z}));
    }
    std::sort(levels.begin(), levels.end());
    const double top = levels.empty() ? 0 : levels[static_cast<size_t>(0.99 * (levels.size() - 1))];
    exposure = top > 0 ? 0.8 / top : 1;
  }

  std::string data = "{";
  const ProbeGrid& g = volume.grid;
  data += "\"grid\":{\"origin\":";
  AppendVec(&data, g.origin);
  data += ",\"spacing\":";
  AppendVec(&data, g.spacing);
  absl::StrAppendFormat(&data, ",\"counts\":[%d,%d,%d]}", g.counts[0], g.counts[1], g.counts[2]);
  absl::StrAppendFormat(&data, ",\"exposure\":%.9g,\"probes\":[", exposure);
  bool first = true;
  for (const EngineProbe& p : *probes) {
    if (!first) data += ",";
    first = false;
    absl::StrAppendFormat(&data, "\n{\"ijk\":[%d,%d,%d],\"position\":", p.i, p.j, p.k);
    AppendVec(&data, axes * p.position);
    data += ",\"sh\":[";
    const std::array<Vec3d, 9> sh = ThreeJsSh(p.radiance);
    for (int c = 0; c < 9; ++c) {
      if (c) data += ",";
      AppendVec(&data, sh[c]);
    }
    absl::StrAppendFormat(&data,
                          "],\"validity\":%.9g,\"filled\":%s,\"offset\":%.9g,\"stdError\":%.9g,"
                          "\"sampleCount\":%.9g}",
                          p.validity, p.filled ? "true" : "false", Length(p.offset),
                          JsonNumber(p.stdError), p.sampleCount);
  }
  data += "],\"meshes\":[";
  if (scene) {
    for (size_t m = 0; m < scene->meshes.size(); ++m) {
      const TriangleMesh& mesh = scene->meshes[m];
      if (m) data += ",";
      // One colour per mesh: a texture's mean, and a cutout drawn translucent by the share of
      // its texels that stay.
      const bool known = mesh.material < scene->materials.size();
      data += "\n{\"albedo\":";
      AppendVec(&data, known ? MeanAlbedo(scene->materials[mesh.material]) : Vec3d{0.8, 0.8, 0.8});
      absl::StrAppendFormat(&data, ",\"opacity\":%.4g",
                            known ? KeptFraction(scene->materials[mesh.material]) : 1.0);
      // Positions in three's frame; an instanced mesh's in its own frame, with its placements
      // (row-major 3 x 4, in three's frame: axes L axes^T and axes t) drawn as a three.js
      // InstancedMesh, so a level of many placed copies stays as small as its distinct meshes.
      data += ",\"positions\":[";
      for (size_t v = 0; v < mesh.positions.size(); ++v) {
        const Vec3d t = axes * mesh.positions[v];
        absl::StrAppendFormat(&data, "%s%.7g,%.7g,%.7g", v ? "," : "", t.x, t.y, t.z);
      }
      data += "],\"indices\":[";
      for (size_t i = 0; i < mesh.indices.size(); ++i)
        absl::StrAppendFormat(&data, "%s%u", i ? "," : "", mesh.indices[i]);
      data += "]";
      if (!mesh.placements.empty()) {
        data += ",\"placements\":[";
        for (size_t k = 0; k < mesh.placements.size(); ++k) {
          const MeshPlacement& placement = mesh.placements[k];
          const Mat3d linear = axes * placement.linear * Transpose(axes);
          const Vec3d t = axes * placement.translation;
          for (int r = 0; r < 3; ++r) {
            absl::StrAppendFormat(&data, "%s%.9g,%.9g,%.9g,%.9g", k + r ? "," : "", linear(r, 0),
                                  linear(r, 1), linear(r, 2), t[r]);
          }
        }
        data += "]";
      }
      data += "}";
    }
  }
  data += "],\"textures\":";
  absl::StatusOr<ProbeTextures> textures = PackProbeTextures(volume, "");
  if (!textures.ok()) return textures.status();
  data += textures->headerJson;
  data += ",\"texturesBin\":\"";
  data += absl::Base64Escape(
      absl::string_view(reinterpret_cast<const char*>(textures->bin.data()), textures->bin.size()));
  data += "\"}";

  // Inline scripts end at the first "</script": keep it out of both payloads ("<\/" is the same
  // text inside JavaScript strings and JSON).
  const std::string safeBundle = absl::StrReplaceAll(
      absl::string_view(bundle.data(), bundle.size()), {{"</script", "<\\/script"}});
  return absl::StrCat(
      "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>probebake view</title>\n"
      "<style>html,body{margin:0;height:100%;overflow:hidden;background:#202020;"
      "font:13px sans-serif;color:#ddd}#ui{position:absolute;top:8px;left:8px;"
      "background:rgba(0,0,0,.6);padding:6px 8px;border-radius:4px}</style></head><body>\n"
      "<div id=\"ui\">probebake view &middot; probes: <select id=\"overlay\">"
      "<option value=\"sh\">irradiance (SH)</option><option value=\"validity\">validity</option>"
      "<option value=\"offset\">offset</option><option value=\"stdError\">std_error</option>"
      "<option value=\"sampleCount\">sample count</option></select>"
      " <label><input type=\"checkbox\" id=\"showProbes\" checked> probes</label>"
      " <span id=\"legend\"></span></div>\n"
      "<script type=\"application/json\" id=\"probebake-data\">",
      absl::StrReplaceAll(data, {{"</", "<\\/"}}), "</script>\n<script>", safeBundle,
      "</script>\n</body></html>\n");
}

}  // namespace probebake
