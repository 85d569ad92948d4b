#include "surface_material.h"

#include <algorithm>
#include <cmath>

#include "probebake/base/check.h"

namespace probebake {
namespace {

// The 256 sRGB-encoded 8-bit values decoded to linear (IEC 61966-2-1).
const std::array<double, 256>& SrgbToLinear() {
  static const std::array<double, 256> table = [] {
    std::array<double, 256> t{};
    for (int i = 0; i < 256; ++i) {
      const double c = i / 255.0;
      t[size_t(i)] = c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
    }
    return t;
  }();
  return table;
}

// Texel index i of an axis of n texels under `wrap`.
int64_t Wrap(int64_t i, int64_t n, TextureWrap wrap) {
  switch (wrap) {
    case TextureWrap::kClamp:
      return std::clamp<int64_t>(i, 0, n - 1);
    case TextureWrap::kMirror: {
      const int64_t m = ((i % (2 * n)) + 2 * n) % (2 * n);
      return m < n ? m : 2 * n - 1 - m;
    }
    case TextureWrap::kRepeat:
      break;
  }
  return ((i % n) + n) % n;
}

// Texel coordinate of image coordinate u on an axis of n texels (texel centres at k + 0.5), split
// into the lower texel and the weight of the upper one. Coordinates far outside [0, 1] (where a
// double no longer resolves texels) are brought back first: clamped, or by whole periods.
void Split(double u, int64_t n, TextureWrap wrap, int64_t* lower, double* weight) {
  if (!std::isfinite(u)) u = 0;
  if (wrap == TextureWrap::kClamp) {
    u = std::clamp(u, -1.0, 2.0);
  } else if (std::fabs(u) > 1 << 20) {
    u -= 2 * std::floor(u / 2);  // whole mirror and repeat periods
  }
  const double x = u * double(n) - 0.5;
  const double f = std::floor(x);
  *lower = int64_t(f);
  *weight = x - f;
}

template <size_t N>
std::array<double, N> Interpolate(const std::vector<std::array<float, N>>& values,
                                  const TriangleMesh& mesh, uint32_t prim, double bu, double bv) {
  const uint32_t* idx = &mesh.indices[3 * size_t(prim)];
  const std::array<float, N>& a = values[idx[0]];
  const std::array<float, N>& b = values[idx[1]];
  const std::array<float, N>& c = values[idx[2]];
  const double b0 = 1 - bu - bv;
  std::array<double, N> out{};
  for (size_t k = 0; k < N; ++k) out[k] = b0 * a[k] + bu * b[k] + bv * c[k];
  return out;
}

std::array<double, 4> SampleAt(const TextureMap& map, const std::vector<std::array<float, 2>>& uv,
                               const TriangleMesh& mesh, uint32_t prim, double bu, double bv) {
  const std::array<double, 2> xy = Interpolate(uv, mesh, prim, bu, bv);
  return SampleTexture(map, xy[0], xy[1]);
}

}  // namespace

std::array<double, 4> SampleTexture(const TextureMap& map, double x, double y) {
  const Texture& t = *map.image;
  const int64_t w = t.width, h = t.height;
  int64_t x0, y0;
  double fx, fy;
  Split(x, w, map.wrapX, &x0, &fx);
  Split(y, h, map.wrapY, &y0, &fy);
  const int64_t xs[2] = {Wrap(x0, w, map.wrapX), Wrap(x0 + 1, w, map.wrapX)};
  const int64_t ys[2] = {Wrap(y0, h, map.wrapY), Wrap(y0 + 1, h, map.wrapY)};
  const double wx[2] = {1 - fx, fx}, wy[2] = {1 - fy, fy};
  const std::array<double, 256>& srgb = SrgbToLinear();
  std::array<double, 4> out{};
  for (int j = 0; j < 2; ++j) {
    for (int i = 0; i < 2; ++i) {
      const double weight = wx[i] * wy[j];
      const uint8_t* texel = &t.rgba[4 * size_t(xs[i] + w * ys[j])];
      for (int c = 0; c < 3; ++c)
        out[size_t(c)] += weight * (map.srgb ? srgb[texel[c]] : texel[c] / 255.0);
      out[3] += weight * (texel[3] / 255.0);
    }
  }
  return out;
}

Vec3d AlbedoAt(const Material& material, const TriangleMesh& mesh, uint32_t prim, double bu,
               double bv) {
  Vec3d albedo = material.albedo;
  if (material.albedoMap.image) {
    const std::array<double, 4> t = SampleAt(material.albedoMap, mesh.albedoUv, mesh, prim, bu, bv);
    albedo = albedo * Vec3d(t[0], t[1], t[2]);
  }
  if (material.vertexColors) {
    const std::array<double, 4> c = Interpolate(mesh.colors, mesh, prim, bu, bv);
    albedo = albedo * Vec3d(c[0], c[1], c[2]);
  }
  return albedo;
}

double CoverageAt(const Material& material, const TriangleMesh& mesh, uint32_t prim, double bu,
                  double bv) {
  double coverage = material.coverage;
  if (material.albedoMap.image)
    coverage *= SampleAt(material.albedoMap, mesh.albedoUv, mesh, prim, bu, bv)[3];
  if (material.coverageMap.image) {
    const std::array<double, 4> t =
        SampleAt(material.coverageMap, mesh.coverageUv, mesh, prim, bu, bv);
    coverage *= material.coverageMap.image->hasAlpha ? t[3] : t[0];
  }
  if (material.vertexColors) coverage *= Interpolate(mesh.colors, mesh, prim, bu, bv)[3];
  return std::clamp(coverage, 0.0, 1.0);
}

Vec3d EmissionAt(const Material& material, const TriangleMesh& mesh, uint32_t prim, double bu,
                 double bv) {
  if (!material.emissionMap.image) return material.emission;
  const std::array<double, 4> t =
      SampleAt(material.emissionMap, mesh.emissionUv, mesh, prim, bu, bv);
  return material.emission * Vec3d(t[0], t[1], t[2]);
}

double MeanLuminance(const TextureMap& map) {
  const Texture& t = *map.image;
  const std::array<double, 256>& srgb = SrgbToLinear();
  double sum = 0;
  const size_t texels = size_t(t.width) * size_t(t.height);
  for (size_t k = 0; k < texels; ++k) {
    const uint8_t* texel = &t.rgba[4 * k];
    double rgb[3];
    for (int c = 0; c < 3; ++c) rgb[c] = map.srgb ? srgb[texel[c]] : texel[c] / 255.0;
    sum += Luminance(Vec3d(rgb[0], rgb[1], rgb[2]));
  }
  return texels > 0 ? sum / double(texels) : 0;
}

Vec3d MeanAlbedo(const Material& material) {
  if (!material.albedoMap.image) return material.albedo;
  const Texture& t = *material.albedoMap.image;
  const std::array<double, 256>& srgb = SrgbToLinear();
  Vec3d sum{0, 0, 0};
  const size_t texels = size_t(t.width) * size_t(t.height);
  for (size_t k = 0; k < texels; ++k)
    for (int c = 0; c < 3; ++c) {
      const uint8_t v = t.rgba[4 * k + size_t(c)];
      sum[c] += material.albedoMap.srgb ? srgb[v] : v / 255.0;
    }
  return texels > 0 ? material.albedo * sum / double(texels) : material.albedo;
}

double KeptFraction(const Material& material) {
  if (!material.HasCutout()) return 1;
  const TextureMap& map = material.coverageMap.image ? material.coverageMap : material.albedoMap;
  if (!map.image) return material.coverage >= material.alphaCutoff ? 1 : 0;
  const Texture& t = *map.image;
  const int channel = &map == &material.albedoMap || t.hasAlpha ? 3 : 0;
  const size_t texels = size_t(t.width) * size_t(t.height);
  size_t kept = 0;
  for (size_t k = 0; k < texels; ++k)
    kept += material.coverage * (t.rgba[4 * k + size_t(channel)] / 255.0) >= material.alphaCutoff;
  return texels > 0 ? double(kept) / double(texels) : 1;
}

}  // namespace probebake
