// The page `probebake view VOLUME [--scene JOB.json] -o view.html` writes (docs/engines.md): one
// self-contained HTML file, three.js and the viewer's code inlined (bundled at build time from
// web/), so nothing is fetched when it is viewed.
//
// Data inlined as JSON (three.js frame, three (x, y, z) = probebake (x, z, -y), engine_export.h):
//   grid {origin, spacing, counts} in probebake's frame (the shader finds a point's 8 probes
//   there); probes: every active probe with its three.js SH, validity, std_error, sample count;
//   meshes: the scene's triangles (positions in three's frame) with their material albedo.
//   textures: the probes as `export --format textures` packs them (probe_textures.h; header and
//   base64 binary).
// The page lights the meshes through integrations/shaders/probebake_probes.glsl on those textures
// (trilinear, invalid probes skipped and the weights renormalised, like the slices), colour =
// albedo * E / pi * exposure, then sRGB; each probe is a small sphere shaded by its own SH (E(n) /
// pi * exposure); a menu switches the spheres to validity, std_error or sample-count colours.
#pragma once

#include <string>
#include <string_view>

#include "probebake/bake/probe_volume.h"
#include "probebake/base/status.h"
#include "probebake/scene/scene.h"

namespace probebake {

struct ViewerOptions {
  // Scale applied to the linear colour before sRGB encoding. <= 0: automatic (the 99th
  // percentile of the usable probes' E(+Z)/pi maps to 0.8).
  double exposure = 0;
};

// The page's HTML. `scene` may be null (probes only). `bundle` is the viewer's JavaScript
// (web/src/viewer.js bundled with three.js). Errors as EngineProbes.
absl::StatusOr<std::string> ViewerPageHtml(const ProbeVolume& volume, const Scene* scene,
                                           std::string_view bundle, const ViewerOptions& options);

}  // namespace probebake
