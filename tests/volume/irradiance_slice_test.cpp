// Slice pictures: analytic radiance fields give known irradiance, the PNG decodes with libpng to
// the expected size and pixels, and the options are validated.
#include "probebake/volume/irradiance_slice.h"

#include <png.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>

#include "volume/test_volumes.h"

namespace probebake {
namespace {

using testing::TempDir;

constexpr double kPi = std::numbers::pi;
// Y_00 and Y_10 = c z (docs/spherical-harmonics.md): a radiance a + b z has L_00 = 2 sqrt(pi) a,
// L_10 = sqrt(4 pi / 3) b.
const double kL00PerUnit = 2 * std::sqrt(kPi);
const double kL10PerUnit = std::sqrt(4 * kPi / 3);

// A dense, all-valid volume of order `order` with zero coefficients.
ProbeVolume EmptyVolume(int nx, int ny, int nz, int order, bool irradiance = false) {
  ProbeVolume v;
  v.grid.origin = {-1.0, 2.0, 0.5};
  v.grid.spacing = {0.5, 0.25, 1.0};
  v.grid.counts[0] = nx;
  v.grid.counts[1] = ny;
  v.grid.counts[2] = nz;
  v.shOrder = order;
  const size_t n = size_t(v.grid.ProbeCount());
  v.active.assign(n, 1);
  v.radiance.assign(size_t(v.CoeffCount()), std::vector<float>(3 * n, 0.0f));
  if (irradiance) v.irradiance = v.radiance;
  v.validity.assign(n, 1.0f);
  v.stdError.assign(n, 0.0f);
  v.stdErrorL0.assign(n, 0.0f);
  v.sampleCount.assign(n, 64.0f);
  return v;
}

struct Png {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;
};

// Decodes an 8-bit RGB PNG with libpng; fails the test on any other kind.
Png ReadPng(const std::string& path) {
  Png result;
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&image, path.c_str())) {
    ADD_FAILURE() << path << ": " << image.message;
    return result;
  }
  EXPECT_EQ(image.format & PNG_FORMAT_FLAG_COLOR, PNG_FORMAT_FLAG_COLOR);
  EXPECT_EQ(image.format & PNG_FORMAT_FLAG_ALPHA, 0u);
  image.format = PNG_FORMAT_RGB;
  result.width = int(image.width);
  result.height = int(image.height);
  result.rgb.resize(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, result.rgb.data(), 0, nullptr)) {
    ADD_FAILURE() << path << ": " << image.message;
  }
  return result;
}

TEST(IrradianceSlice, ConstantRadianceGivesPiLEverywhere) {
  ProbeVolume v = EmptyVolume(5, 3, 4, 2);
  const double radiance[3] = {0.5, 1.0, 2.0};
  for (size_t p = 0; p < v.active.size(); ++p) {
    for (int ch = 0; ch < 3; ++ch)
      v.radiance[0][3 * p + size_t(ch)] = float(kL00PerUnit * radiance[ch]);
  }
  SliceOptions options;
  options.axis = 2;
  options.value = 1.75;  // between layers 1 and 2
  const absl::StatusOr<SliceImage> image = RenderIrradianceSlice(v, options);
  ASSERT_TRUE(image.ok()) << image.status();
  EXPECT_EQ(image->width, 5 * 16);
  EXPECT_EQ(image->height, 3 * 16);
  for (size_t i = 0; i < image->irradiance.size(); ++i) {
    // L_00 is stored as float (relative error <= 2^-24); Y_00 and A_0 are within a few ulp of
    // double; the blend of equal values adds a few ulp more: 1e-6 relative is ample.
    const double expected = kPi * radiance[i % 3];
    ASSERT_NEAR(image->irradiance[i], expected, 1e-6 * expected) << "pixel value " << i;
  }

  TempDir dir;
  const std::string path = dir.File("constant.png");
  PB_ASSERT_OK(WriteIrradianceSlice(v, options, path));
  const Png png = ReadPng(path);
  ASSERT_EQ(png.width, 80);
  ASSERT_EQ(png.height, 48);
  // Uniform picture; the 99th percentile of a constant is the constant, so luminance maps to 1 and
  // the colour is (pi L) / luminance(pi L) in sRGB.
  const double luminance = 0.2126 * 0.5 + 0.7152 * 1.0 + 0.0722 * 2.0;
  auto srgb = [](double c) {
    c = std::min(1.0, c);
    return int(
        std::lround(255 * (c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1 / 2.4) - 0.055)));
  };
  for (size_t i = 0; i < png.rgb.size(); ++i) {
    ASSERT_EQ(int(png.rgb[i]), srgb(radiance[i % 3] / luminance)) << "byte " << i;
  }
}

TEST(IrradianceSlice, IrradianceGridsAreUsedWhenPresent) {
  ProbeVolume v = EmptyVolume(3, 3, 2, 1, /*irradiance=*/true);
  for (size_t p = 0; p < v.active.size(); ++p) {
    v.radiance[0][3 * p] = 1000.0f;  // would dominate if the radiance were used
    v.irradiance[0][3 * p] = float(kL00PerUnit * kPi * 0.25);  // E = pi * 0.25 * ... / (2 sqrt(pi))
  }
  SliceOptions options;
  options.axis = 0;
  options.value = 0.0;
  const absl::StatusOr<SliceImage> image = RenderIrradianceSlice(v, options);
  ASSERT_TRUE(image.ok()) << image.status();
  // E(n) = E_00 Y_00 = 2 sqrt(pi) pi 0.25 / (2 sqrt(pi)) = pi / 4 in red, 0 elsewhere.
  for (size_t i = 0; i < image->irradiance.size(); i += 3) {
    ASSERT_NEAR(image->irradiance[i], kPi / 4, 1e-6) << i;
    ASSERT_EQ(image->irradiance[i + 1], 0.0f) << i;
  }
}

TEST(IrradianceSlice, NormalSelectsTheHemisphere) {
  // Radiance a + b z: E(n) = pi a + (2 pi / 3) b n_z.
  ProbeVolume v = EmptyVolume(3, 3, 3, 2);
  const double a = 1.0, b = 0.6;
  for (size_t p = 0; p < v.active.size(); ++p) {
    for (int ch = 0; ch < 3; ++ch) {
      v.radiance[0][3 * p + size_t(ch)] = float(kL00PerUnit * a);
      v.radiance[2][3 * p + size_t(ch)] = float(kL10PerUnit * b);
    }
  }
  SliceOptions options;
  options.axis = 1;
  options.value = 2.25;
  for (const double nz : {1.0, -1.0, 0.0}) {
    options.normal = nz == 0 ? Vec3d{1, 0, 0} : Vec3d{0, 0, 3 * nz};  // not unit: normalised
    const absl::StatusOr<SliceImage> image = RenderIrradianceSlice(v, options);
    ASSERT_TRUE(image.ok()) << image.status();
    const double expected = kPi * a + 2 * kPi / 3 * b * nz;
    for (size_t i = 0; i < image->irradiance.size(); ++i) {
      ASSERT_NEAR(image->irradiance[i], expected, 1e-6 * expected) << "n_z " << nz << " at " << i;
    }
  }
}

TEST(IrradianceSlice, GradientInXIsMonotoneAlongTheRows) {
  ProbeVolume v = EmptyVolume(6, 4, 2, 2);
  for (int k = 0; k < 2; ++k) {
    for (int j = 0; j < 4; ++j) {
      for (int i = 0; i < 6; ++i) {
        const size_t p = size_t(v.grid.LinearIndex(i, j, k));
        const double radiance = 0.2 + 0.5 * v.grid.Position(i, j, k).x + 1.5;  // > 0 on the grid
        for (int ch = 0; ch < 3; ++ch)
          v.radiance[0][3 * p + size_t(ch)] = float(kL00PerUnit * radiance);
      }
    }
  }
  SliceOptions options;
  options.axis = 2;
  options.value = 0.9;
  options.pixelsPerProbe = 10;
  const absl::StatusOr<SliceImage> image = RenderIrradianceSlice(v, options);
  ASSERT_TRUE(image.ok()) << image.status();
  ASSERT_EQ(image->width, 60);
  for (int y = 0; y < image->height; ++y) {
    for (int x = 1; x < image->width; ++x) {
      const size_t here = 3 * (size_t(y) * 60 + size_t(x)), left = here - 3;
      // Half a probe cell at each end is clamped (constant); in between, strictly increasing.
      if (x > 5 && x < 55) {
        ASSERT_GT(image->irradiance[here], image->irradiance[left]) << x << "," << y;
      } else {
        ASSERT_GE(image->irradiance[here], image->irradiance[left]) << x << "," << y;
      }
      ASSERT_GE(image->rgb[here], image->rgb[left]) << x << "," << y;
    }
    // E = pi (1.7 + 0.5 x): x = -1 at the first probe, 1.5 at the last.
    EXPECT_NEAR(image->irradiance[3 * size_t(y) * 60], kPi * 1.2, 1e-5);
    EXPECT_NEAR(image->irradiance[3 * (size_t(y) * 60 + 59)], kPi * 2.45, 1e-5);
  }
  TempDir dir;
  const std::string path = dir.File("gradient.png");
  PB_ASSERT_OK(WriteIrradianceSlice(v, options, path));
  const Png png = ReadPng(path);
  ASSERT_EQ(png.width, 60);
  ASSERT_EQ(png.height, 40);
  ASSERT_EQ(png.rgb, image->rgb);
  EXPECT_LT(png.rgb[0], png.rgb[3 * 59]);
}

TEST(IrradianceSlice, InvalidAndInactiveProbesAreSkipped) {
  ProbeVolume v = EmptyVolume(4, 4, 2, 0);
  for (size_t p = 0; p < v.active.size(); ++p) {
    for (int ch = 0; ch < 3; ++ch) v.radiance[0][3 * p + size_t(ch)] = float(kL00PerUnit);
  }
  // A huge value at an invalid probe and at an inactive one must not leak into the picture.
  const size_t invalid = size_t(v.grid.LinearIndex(1, 1, 0));
  const size_t inactive = size_t(v.grid.LinearIndex(2, 2, 1));
  v.validity[invalid] = 0;
  v.active[inactive] = 0;
  for (size_t p : {invalid, inactive}) {
    for (int ch = 0; ch < 3; ++ch) v.radiance[0][3 * p + size_t(ch)] = 1e6f;
  }
  SliceOptions options;
  options.axis = 2;
  options.value = 1.0;
  const absl::StatusOr<SliceImage> image = RenderIrradianceSlice(v, options);
  ASSERT_TRUE(image.ok()) << image.status();
  for (size_t i = 0; i < image->irradiance.size(); ++i) {
    ASSERT_NEAR(image->irradiance[i], kPi, 1e-5) << i;
  }
}

TEST(IrradianceSlice, NoValidNeighbourShowsAGreyChecker) {
  ProbeVolume v = EmptyVolume(3, 2, 2, 1);
  for (float& x : v.validity) x = 0;
  SliceOptions options;
  options.axis = 2;
  options.value = 1.0;
  const absl::StatusOr<SliceImage> image = RenderIrradianceSlice(v, options);
  ASSERT_TRUE(image.ok()) << image.status();
  for (size_t i = 0; i < image->rgb.size(); ++i) {
    ASSERT_TRUE(std::isnan(image->irradiance[i])) << i;
    ASSERT_TRUE(image->rgb[i] == 96 || image->rgb[i] == 128) << i << ": " << int(image->rgb[i]);
  }
  EXPECT_NE(image->rgb[0], image->rgb[3 * 8]);  // neighbouring 8-pixel squares differ
}

TEST(IrradianceSlice, ProbeDotsMarkValidAndInvalidProbes) {
  ProbeVolume v = EmptyVolume(3, 3, 1, 0);
  for (size_t p = 0; p < v.active.size(); ++p) v.radiance[0][3 * p + 2] = float(kL00PerUnit);
  v.validity[size_t(v.grid.LinearIndex(2, 0, 0))] = 0;
  SliceOptions options;
  options.axis = 2;
  options.value = 0.5;
  options.markProbes = true;
  const absl::StatusOr<SliceImage> image = RenderIrradianceSlice(v, options);
  ASSERT_TRUE(image.ok()) << image.status();
  auto pixel = [&](int x, int y) { return &image->rgb[3 * (size_t(y) * 48 + size_t(x))]; };
  // Probe (0, 2) is at the top-left cell's centre (8, 8); probe (2, 0) bottom right (40, 40).
  const uint8_t* valid = pixel(8, 8);
  EXPECT_EQ(valid[0], 255);
  EXPECT_EQ(valid[1], 255);
  EXPECT_EQ(valid[2], 255);
  const uint8_t* invalidDot = pixel(40, 40);
  EXPECT_EQ(invalidDot[0], 255);
  EXPECT_LT(invalidDot[1], 64);
  const uint8_t* between = pixel(16, 8);  // cell border, no dot: blue field
  EXPECT_EQ(between[0], 0);
  EXPECT_GT(between[2], 200);
}

TEST(IrradianceSlice, SizeIsCappedByMaxImageSize) {
  ProbeVolume v = EmptyVolume(100, 10, 1, 0);
  SliceOptions options;
  options.axis = 2;
  options.value = 0.5;
  options.maxImageSize = 400;
  const absl::StatusOr<SliceImage> image = RenderIrradianceSlice(v, options);
  ASSERT_TRUE(image.ok()) << image.status();
  EXPECT_EQ(image->width, 400);
  EXPECT_EQ(image->height, 40);
}

TEST(IrradianceSlice, OptionsAreValidated) {
  const ProbeVolume v = EmptyVolume(3, 3, 3, 1);
  SliceOptions options;
  options.axis = 2;
  options.value = 3.5;  // z range [0.5, 2.5] widened by 0.5: 3.0 is the limit
  absl::StatusOr<SliceImage> image = RenderIrradianceSlice(v, options);
  EXPECT_EQ(image.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(std::string(image.status().message()).find("z=3.5"), std::string::npos)
      << image.status();
  options.value = 2.9;
  EXPECT_TRUE(RenderIrradianceSlice(v, options).ok());
  options.normal = Vec3d{0, 0, 0};
  EXPECT_EQ(RenderIrradianceSlice(v, options).status().code(), absl::StatusCode::kInvalidArgument);
  options.normal.reset();
  options.pixelsPerProbe = 0;
  EXPECT_EQ(RenderIrradianceSlice(v, options).status().code(), absl::StatusCode::kInvalidArgument);
  ProbeVolume broken = v;
  broken.radiance[1].resize(5);
  options.pixelsPerProbe = 4;
  const absl::Status status = RenderIrradianceSlice(broken, options).status();
  EXPECT_NE(std::string(status.message()).find("volume.radiance[1]"), std::string::npos) << status;
}

TEST(IrradianceSlice, ParseSliceSpec) {
  SliceOptions options;
  ASSERT_TRUE(ParseSliceSpec("z=1.5", &options).ok());
  EXPECT_EQ(options.axis, 2);
  EXPECT_EQ(options.value, 1.5);
  ASSERT_TRUE(ParseSliceSpec("Y=-2e-1", &options).ok());
  EXPECT_EQ(options.axis, 1);
  EXPECT_EQ(options.value, -0.2);
  for (const char* bad : {"w=1", "z=", "z=abc", "z=1.5x", "z1.5", "", "zz=1", "x=nan", "x=inf"}) {
    const absl::Status status = ParseSliceSpec(bad, &options);
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << bad;
    EXPECT_EQ(std::string(status.message()).rfind("slice: ", 0), 0u) << status;
  }
}

}  // namespace
}  // namespace probebake
