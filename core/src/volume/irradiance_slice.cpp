#include "probebake/volume/irradiance_slice.h"
#include "probebake/volume/probe_sampler.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>

#include "png_io.h"
#include "vdb_format.h"

namespace probebake {
namespace {

using volume_internal::ValidateVolume;

constexpr double kLumaR = 0.2126, kLumaG = 0.7152, kLumaB = 0.0722;  // Rec.709 luminance

// The picture's horizontal and vertical world axes for a slice normal to `axis`.
void ImageAxes(int axis, int* u, int* v) {
  switch (axis) {
    case 0:
      *u = 1, *v = 2;
      break;
    case 1:
      *u = 0, *v = 2;
      break;
    default:
      *u = 0, *v = 1;
      break;
  }
}

// The shortest decimal that reads back as `x`.
std::string ShortNumber(double x) {
  char buffer[32];
  const auto [end, ec] = std::to_chars(buffer, buffer + sizeof buffer, x);
  return ec == std::errc() ? std::string(buffer, end) : std::string("?");
}

uint8_t EncodeSrgb8(double linear) {
  const double c = std::clamp(linear, 0.0, 1.0);
  const double s = c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1.0 / 2.4) - 0.055;
  return uint8_t(std::lround(255.0 * s));
}

}  // namespace

absl::Status ParseSliceSpec(const std::string& spec, SliceOptions* options) {
  const size_t eq = spec.find('=');
  if (eq != 1)
    return FieldError("slice", "expected <axis>=<value>, e.g. z=1.5, got '" + spec + "'");
  const char axis = char(std::tolower(static_cast<unsigned char>(spec[0])));
  if (axis < 'x' || axis > 'z') {
    return FieldError("slice", "axis must be x, y or z, got '" + spec.substr(0, 1) + "'");
  }
  double value = 0;
  const char* first = spec.data() + 2;
  const char* last = spec.data() + spec.size();
  const auto [end, ec] = std::from_chars(first, last, value);
  if (first == last || ec != std::errc() || end != last || !std::isfinite(value)) {
    return FieldError("slice", "value must be a finite number, got '" + spec.substr(2) + "'");
  }
  options->axis = axis - 'x';
  options->value = value;
  return absl::OkStatus();
}

absl::StatusOr<SliceImage> RenderIrradianceSlice(const ProbeVolume& volume,
                                                 const SliceOptions& options) {
  PB_RETURN_IF_ERROR(ValidateVolume(volume));
  if (options.axis < 0 || options.axis > 2) return FieldError("slice.axis", "must be 0, 1 or 2");
  if (options.pixelsPerProbe < 1) return FieldError("slice.pixelsPerProbe", "must be >= 1");
  if (options.maxImageSize < 1) return FieldError("slice.maxImageSize", "must be >= 1");
  if (!(options.exposurePercentile > 0 && options.exposurePercentile <= 1)) {
    return FieldError("slice.exposurePercentile", "must be in (0, 1]");
  }
  const ProbeGrid& grid = volume.grid;
  const int axis = options.axis;
  int ua = 0, va = 0;
  ImageAxes(axis, &ua, &va);
  const char axisName = char('x' + axis);

  // Where the plane cuts the grid, in probe units along `axis`.
  const double t = (options.value - grid.origin[axis]) / grid.spacing[axis];
  const int nAxis = grid.counts[axis];
  if (!std::isfinite(options.value) || t < -0.5 || t > double(nAxis - 1) + 0.5) {
    const double lo = grid.origin[axis] - 0.5 * grid.spacing[axis];
    const double hi = grid.origin[axis] + (nAxis - 0.5) * grid.spacing[axis];
    return FieldError("slice", std::string(1, axisName) + "=" + ShortNumber(options.value) +
                                   " is outside the grid's range [" + ShortNumber(lo) + ", " +
                                   ShortNumber(hi) + "]");
  }
  const double tc = std::clamp(t, 0.0, double(nAxis - 1));

  Vec3d normal{0, 0, 0};
  normal[axis] = 1;
  if (options.normal) {
    const Vec3d n = *options.normal;
    const double len2 = LengthSquared(n);
    if (!(std::isfinite(len2) && len2 > 0)) {
      return FieldError("slice.normal", "must be a finite non-zero vector");
    }
    normal = n / std::sqrt(len2);
  }

  const int nu = grid.counts[ua], nv = grid.counts[va];
  auto probeIndex = [&](int a, int b, int k) {
    int c[3];
    c[ua] = a;
    c[va] = b;
    c[axis] = k;
    return grid.LinearIndex(c[0], c[1], c[2]);
  };

  // Image size: pixelsPerProbe per probe cell, shrunk to fit maxImageSize.
  const double scale = std::min(double(options.pixelsPerProbe),
                                double(options.maxImageSize) / double(std::max(nu, nv)));
  SliceImage image;
  image.width = std::clamp(int(std::lround(nu * scale)), 1, options.maxImageSize);
  image.height = std::clamp(int(std::lround(nv * scale)), 1, options.maxImageSize);
  const size_t pixels = size_t(image.width) * size_t(image.height);
  image.irradiance.assign(3 * pixels, std::numeric_limits<float>::quiet_NaN());
  image.rgb.assign(3 * pixels, 0);

  const ProbeSampler sampler(volume);
  std::vector<double> luminance;
  luminance.reserve(pixels);
  for (int py = 0; py < image.height; ++py) {
    // Continuous probe coordinates of the pixel centre; rows run top (high v) to bottom.
    const double sv =
        std::clamp(double(nv) - (py + 0.5) * double(nv) / image.height - 0.5, 0.0, double(nv - 1));
    for (int px = 0; px < image.width; ++px) {
      const double su =
          std::clamp((px + 0.5) * double(nu) / image.width - 0.5, 0.0, double(nu - 1));
      // The reference sampler at the pixel's world point (probe_sampler.h).
      Vec3d x;
      x[axis] = grid.origin[axis] + tc * grid.spacing[axis];
      x[ua] = grid.origin[ua] + su * grid.spacing[ua];
      x[va] = grid.origin[va] + sv * grid.spacing[va];
      const ProbeSample sample = sampler.Sample(x, normal);
      const double total = sample.probes > 0 ? 1.0 : 0.0;
      const Vec3d sum = sample.irradiance;
      const size_t pixel = size_t(py) * size_t(image.width) + size_t(px);
      if (total > 0) {
        const Vec3d e = sum / total;
        for (int ch = 0; ch < 3; ++ch) image.irradiance[3 * pixel + size_t(ch)] = float(e[ch]);
        luminance.push_back(std::max(0.0, kLumaR * e.x + kLumaG * e.y + kLumaB * e.z));
      }
    }
  }

  // Exposure: the chosen percentile of data-pixel luminance maps to 1.
  double reference = 0;
  if (!luminance.empty()) {
    const size_t rank =
        std::min(luminance.size() - 1,
                 size_t(std::max(
                     0.0, std::ceil(options.exposurePercentile * double(luminance.size())) - 1)));
    std::nth_element(luminance.begin(), luminance.begin() + std::ptrdiff_t(rank), luminance.end());
    reference = luminance[rank];
    if (!(reference > 0)) reference = *std::max_element(luminance.begin(), luminance.end());
  }
  image.exposure = reference > 0 && std::isfinite(reference) ? 1.0 / reference : 1.0;

  for (int py = 0; py < image.height; ++py) {
    for (int px = 0; px < image.width; ++px) {
      const size_t pixel = size_t(py) * size_t(image.width) + size_t(px);
      uint8_t* out = &image.rgb[3 * pixel];
      const float* e = &image.irradiance[3 * pixel];
      if (std::isnan(e[0])) {
        // No valid probe around: a grey checker, 8-pixel squares.
        const uint8_t grey = ((px / 8 + py / 8) % 2) ? 96 : 128;
        out[0] = out[1] = out[2] = grey;
        continue;
      }
      for (int ch = 0; ch < 3; ++ch) out[ch] = EncodeSrgb8(double(e[ch]) * image.exposure);
    }
  }

  if (options.markProbes && scale >= 8) {
    // Dots at the probes of the layer nearest the plane: a dark ring, then white (valid) or red
    // (invalid) inside.
    const int kn = std::clamp(int(std::lround(tc)), 0, nAxis - 1);
    const double radius = std::max(1.5, scale / 8);
    for (int b = 0; b < nv; ++b) {
      for (int a = 0; a < nu; ++a) {
        const size_t p = size_t(probeIndex(a, b, kn));
        if (!volume.active[p]) continue;
        const bool valid = volume.validity[p] >= 0.5f;
        const double cx = (a + 0.5) * image.width / double(nu);
        const double cy = (double(nv) - b - 0.5) * image.height / double(nv);
        const int x0 = std::max(0, int(std::floor(cx - radius - 1)));
        const int x1 = std::min(image.width - 1, int(std::ceil(cx + radius + 1)));
        const int y0 = std::max(0, int(std::floor(cy - radius - 1)));
        const int y1 = std::min(image.height - 1, int(std::ceil(cy + radius + 1)));
        for (int y = y0; y <= y1; ++y) {
          for (int x = x0; x <= x1; ++x) {
            const double dx = x + 0.5 - cx, dy = y + 0.5 - cy;
            const double d = std::sqrt(dx * dx + dy * dy);
            uint8_t* out = &image.rgb[3 * (size_t(y) * size_t(image.width) + size_t(x))];
            if (d <= radius) {
              out[0] = 255;
              out[1] = valid ? 255 : 40;
              out[2] = valid ? 255 : 40;
            } else if (d <= radius + 1) {
              out[0] = out[1] = out[2] = 20;
            }
          }
        }
      }
    }
  }
  return image;
}

absl::Status WriteIrradianceSlice(const ProbeVolume& volume, const SliceOptions& options,
                                  const std::string& pngPath) {
  PB_ASSIGN_OR_RETURN(SliceImage image, RenderIrradianceSlice(volume, options));
  return volume_internal::WritePngRgb8(pngPath, image.width, image.height, image.rgb);
}

}  // namespace probebake
