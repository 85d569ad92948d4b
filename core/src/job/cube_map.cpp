#include "cube_map.h"

#include <OpenEXR/ImfEnvmap.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "probebake/base/status.h"
#include "text.h"

namespace probebake::job_internal {

namespace {
constexpr double kPi = std::numbers::pi;
}  // namespace

absl::StatusOr<EnvironmentMap> StackCubeFaces(const std::array<EnvironmentMap, 6>& faces,
                                              const std::array<std::string, 6>& fieldPaths) {
  const int n = faces[0].width;
  for (int f = 0; f < 6; ++f) {
    const EnvironmentMap& face = faces[size_t(f)];
    if (face.width != face.height) {
      return FieldError(fieldPaths[size_t(f)], "a cube face must be square, this one is " +
                                                   Num(face.width) + " x " + Num(face.height));
    }
    if (face.width != n) {
      return FieldError(fieldPaths[size_t(f)], "a cube face of " + Num(face.width) + " x " +
                                                   Num(face.height) + " pixels, but face 0 is " +
                                                   Num(n) + " x " + Num(n));
    }
  }
  EnvironmentMap cube;
  cube.width = n;
  cube.height = 6 * n;
  cube.rgb.reserve(size_t(n) * size_t(n) * 18);
  for (const EnvironmentMap& face : faces)
    cube.rgb.insert(cube.rgb.end(), face.rgb.begin(), face.rgb.end());
  return cube;
}

absl::StatusOr<EnvironmentMap> LatLongFromCube(const EnvironmentMap& cube,
                                               const std::string& fieldPath, int64_t maxPixels) {
  const int n = cube.width;
  if (n < 1 || int64_t(cube.height) != 6 * int64_t(n)) {
    return FieldError(fieldPath,
                      "a cube map in OpenEXR's cube-face layout is N wide and 6N high, "
                      "this image is " +
                          Num(cube.width) + " x " + Num(cube.height));
  }
  const int64_t w = 4 * int64_t(n) + 1, h = 2 * int64_t(n) + 1;
  if (maxPixels > 0 && w * h > maxPixels) {
    return FieldError(fieldPath, "the cube map's faces of " + Num(n) + " x " + Num(n) +
                                     " pixels make a lat-long map of " + Num(w) + " x " + Num(h) +
                                     " pixels, above the limit of " + Num(maxPixels));
  }
  // Positions are computed against the data window at the origin; the image's own data window
  // origin does not move its pixels relative to each other.
  const Imath::Box2i window(Imath::V2i(0, 0), Imath::V2i(n - 1, 6 * n - 1));
  EnvironmentMap out;
  out.width = int(w);
  out.height = int(h);
  out.rgb.assign(size_t(w * h * 3), 0.0f);
  // OpenEXR's lat-long layout: longitude pi at x = 0 down to -pi at x = w - 1, latitude pi/2 at
  // y = 0 down to -pi/2 at y = h - 1; pixel (x, y) covers [x - 1/2, x + 1/2] x [y - 1/2, y + 1/2]
  // clipped to the image.
  const auto longitude = [w](double x) { return 2 * kPi * (0.5 - x / double(w - 1)); };
  const auto latitude = [h](double y) { return kPi * (0.5 - y / double(h - 1)); };
  constexpr int s = kCubeSupersampling;
  tbb::parallel_for(int64_t(0), h, [&](int64_t y) {
    const double y0 = std::max(0.0, double(y) - 0.5), y1 = std::min(double(h - 1), y + 0.5);
    const double z0 = std::sin(latitude(y1)), z1 = std::sin(latitude(y0));
    for (int64_t x = 0; x < w; ++x) {
      const double x0 = std::max(0.0, double(x) - 0.5), x1 = std::min(double(w - 1), x + 0.5);
      double sum[3] = {0, 0, 0};
      for (int j = 0; j < s; ++j) {
        const double z = z0 + (z1 - z0) * (j + 0.5) / s;
        const double r = std::sqrt(std::max(0.0, (1 - z) * (1 + z)));
        for (int i = 0; i < s; ++i) {
          const double lon = longitude(x0 + (x1 - x0) * (i + 0.5) / s);
          // Imf::LatLongMap's direction of (latitude, longitude).
          const Imath::V3f d(float(r * std::sin(lon)), float(z), float(r * std::cos(lon)));
          Imf::CubeMapFace face;
          Imath::V2f inFace;
          Imf::CubeMap::faceAndPixelPosition(d, window, face, inFace);
          const Imath::V2f p = Imf::CubeMap::pixelPosition(face, window, inFace);
          const int px = std::clamp(int(std::lround(p.x)), 0, n - 1);
          const int py = std::clamp(int(std::lround(p.y)), 0, 6 * n - 1);
          const float* c = &cube.rgb[3 * (size_t(py) * size_t(n) + size_t(px))];
          for (int k = 0; k < 3; ++k) sum[k] += c[k];
        }
      }
      float* o = &out.rgb[size_t(3 * (y * w + x))];
      for (int k = 0; k < 3; ++k) o[k] = float(sum[k] / (s * s));
    }
  });
  return out;
}

}  // namespace probebake::job_internal
