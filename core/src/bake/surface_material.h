// A mesh material's values at a point of a triangle: constant factors times textures and vertex
// colours (scene.h's Material). A point is a triangle `prim` of the mesh and Embree's barycentrics
// (bu, bv): p = (1 - bu - bv) a + bu b + bv c for the triangle's vertices a, b, c, and every
// per-vertex attribute is interpolated the same way.
#pragma once

#include <array>
#include <cstdint>

#include "probebake/math/vec3.h"
#include "probebake/scene/scene.h"

namespace probebake {

// Linear RGBA of `map` at image coordinates (x, y) (x right, y down, [0, 1]^2 spans the image):
// bilinear between texel centres, the map's wrap modes per axis, colour channels sRGB-decoded
// when map.srgb, alpha (and a non-sRGB map's channels) value / 255. Non-finite coordinates read
// (0, 0). `map.image` must be set.
std::array<double, 4> SampleTexture(const TextureMap& map, double x, double y);

// Diffuse albedo: material.albedo x albedoMap's RGB x the vertex colour's RGB.
Vec3d AlbedoAt(const Material& material, const TriangleMesh& mesh, uint32_t prim, double bu,
               double bv);
// Coverage (alpha): material.coverage x albedoMap's alpha x coverageMap x the vertex colour's
// alpha, in [0, 1].
double CoverageAt(const Material& material, const TriangleMesh& mesh, uint32_t prim, double bu,
                  double bv);
// Emitted radiance: material.emission x emissionMap's RGB.
Vec3d EmissionAt(const Material& material, const TriangleMesh& mesh, uint32_t prim, double bu,
                 double bv);
// The mean over texels of the luminance of `map`'s linear RGB (a textured emitter's power).
double MeanLuminance(const TextureMap& map);
// For displays (the viewer), not for baking: material.albedo times the mean over texels of
// albedoMap's linear RGB (vertex colours not included); and the fraction of a cutout's texels that
// stay (coverage of the albedo map's alpha, or of the coverage map, at or above alphaCutoff; 1
// without a cutout, material.coverage against the cutoff without a map).
Vec3d MeanAlbedo(const Material& material);
double KeptFraction(const Material& material);

}  // namespace probebake
