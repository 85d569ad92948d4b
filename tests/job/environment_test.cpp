// Environment maps: 32-bit float OpenEXR lat-long images and their orientation
// (docs/job-format.md).
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfEnvmap.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfOutputFile.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "job/test_util.h"
#include "probebake/job/digest.h"
#include "probebake/job/file_refs.h"
#include "probebake/job/job.h"
#include "probebake/job/job_json.h"

namespace probebake {
namespace {

using testing::HasFieldError;
using testing::ReadText;
using testing::TempDir;

// An odd-sized map, so that a pixel centre sits exactly at longitude 0, latitude 0 (map +Z):
// Imf::LatLongMap puts the first and last columns at longitude +pi and -pi, the first and last
// rows at latitude +pi/2 and -pi/2.
constexpr int kWidth = 65, kHeight = 33;

struct Image {
  int width = kWidth, height = kHeight;
  Imath::V2i origin{0, 0};  // data window origin
  std::vector<float> rgb = std::vector<float>(size_t(kWidth) * kHeight * 3, 0.25f);
  bool grey = false;  // write one Y channel (from rgb's red)

  Imath::Box2i Window() const { return {origin, origin + Imath::V2i(width - 1, height - 1)}; }
  void Set(int x, int y, float r, float g, float b) {  // x, y relative to the origin
    float* p = &rgb[3 * (size_t(y) * width + x)];
    p[0] = r, p[1] = g, p[2] = b;
  }
};

std::string WriteExr(const TempDir& dir, const std::string& name, const Image& image) {
  const std::string path = dir.File(name);
  Imf::Header header(image.Window(), image.Window());
  const size_t xStride = 3 * sizeof(float), yStride = xStride * size_t(image.width);
  Imf::FrameBuffer frame;
  if (image.grey) {
    header.channels().insert("Y", Imf::Channel(Imf::FLOAT));
    frame.insert("Y",
                 Imf::Slice::Make(Imf::FLOAT, image.rgb.data(), image.Window(), xStride, yStride));
  } else {
    for (int c = 0; c < 3; ++c) {
      const char* channel = c == 0 ? "R" : c == 1 ? "G" : "B";
      header.channels().insert(channel, Imf::Channel(Imf::FLOAT));
      frame.insert(channel, Imf::Slice::Make(Imf::FLOAT, image.rgb.data() + c, image.Window(),
                                             xStride, yStride));
    }
  }
  Imf::OutputFile file(path.c_str(), header);
  file.setFrameBuffer(frame);
  file.writePixels(image.height);
  return path;
}

absl::StatusOr<BakeJob> BuildEnvJob(const TempDir& dir, const std::string& map,
                                    const JobLimits& limits = {}) {
  const std::string json =
      R"({"scene": {"environment": {"map": )" + map +
      R"(}}, "grid": {"min": [0, 0, 0], "max": [0, 0, 0], "counts": [1, 1, 1]}})";
  const absl::StatusOr<v1::JobSpec> job = ParseJobJson(json);
  EXPECT_TRUE(job.ok()) << job.status();
  if (!job.ok()) return job.status();
  return BuildBakeJob(*job, LocalAssetSource(dir.path()), limits);
}

// The loaded map's brightest pixel, as its LatLongMap direction over the loaded data window.
Vec3d BrightestDirection(const EnvironmentMap& map) {
  size_t best = 0;
  for (size_t p = 0; p < size_t(map.width) * map.height; ++p)
    if (map.rgb[3 * p] > map.rgb[3 * best]) best = p;
  const Imath::Box2i window(
      Imath::V2i(map.dataWindowMinX, map.dataWindowMinY),
      Imath::V2i(map.dataWindowMinX + map.width - 1, map.dataWindowMinY + map.height - 1));
  const Imath::V2f pixel(float(map.dataWindowMinX + int(best % map.width)),
                         float(map.dataWindowMinY + int(best / map.width)));
  const Imath::V3f d = Imf::LatLongMap::direction(window, pixel);
  return {d.x, d.y, d.z};
}

// LatLongMap evaluates in float: directions are good to a few float ulps.
constexpr double kFloatTolerance = 1e-6;

void ExpectNear(const Vec3d& got, const Vec3d& expected, const std::string& what) {
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(got[a], expected[a], kFloatTolerance)
        << what << ": got " << got << ", expected " << expected;
  }
}

TEST(EnvironmentMap, BrightPixelLandsWhereSpecSays) {
  TempDir dir;
  Image image;
  image.origin = {10, -5};              // a data window off the origin is kept
  image.Set(32, 16, 1000, 1000, 1000);  // map direction +Z (longitude 0, latitude 0)
  WriteExr(dir, "sky.exr", image);

  struct Case {
    const char* map;
    Vec3d world;  // where map +Z must land
  };
  const double c30 = std::cos(M_PI / 6), s30 = 0.5;
  const Case cases[] = {
      {R"({"file": "sky.exr"})", {0, 0, 1}},                                // Y up: identity
      {R"({"file": "sky.exr", "up": "Y", "rotationDeg": 90})", {1, 0, 0}},  // +Z -> +X about +Y
      {R"({"file": "sky.exr", "up": "Y", "rotationDeg": -90})", {-1, 0, 0}},
      {R"({"file": "sky.exr", "up": "Z"})", {0, -1, 0}},                    // (x, -z, y)
      {R"({"file": "sky.exr", "up": "Z", "rotationDeg": 90})", {1, 0, 0}},  // -Y -> +X about +Z
      {R"({"file": "sky.exr", "up": "Z", "rotationDeg": 30})", {s30, -c30, 0}},
      {R"({"file": "sky.exr", "up": "Z", "rotationDeg": 450})", {1, 0, 0}},
  };
  for (const Case& c : cases) {
    const absl::StatusOr<BakeJob> built = BuildEnvJob(dir, c.map);
    ASSERT_TRUE(built.ok()) << built.status();
    ASSERT_EQ(built->scene.environment.kind, Environment::Kind::kMap) << c.map;
    const EnvironmentMap& map = *built->scene.environment.map;
    EXPECT_EQ(map.width, kWidth);
    EXPECT_EQ(map.height, kHeight);
    EXPECT_EQ(map.dataWindowMinX, 10);
    EXPECT_EQ(map.dataWindowMinY, -5);
    const Vec3d mapDirection = BrightestDirection(map);
    ExpectNear(mapDirection, {0, 0, 1}, "map direction of the bright pixel");
    ExpectNear(map.worldFromMap * mapDirection, c.world, c.map);
    // A rotation: orthonormal rows, determinant +1.
    EXPECT_NEAR(Determinant(map.worldFromMap), 1, 1e-15) << c.map;
  }
}

TEST(EnvironmentMap, ImageTopIsWorldUp) {
  TempDir dir;
  Image image;
  image.Set(20, 0, 1000, 1000, 1000);  // first row: latitude +pi/2, map +Y
  WriteExr(dir, "sky.exr", image);
  for (const auto& [map, up] :
       {std::pair{R"({"file": "sky.exr", "up": "Y"})", Vec3d(0, 1, 0)},
        std::pair{R"({"file": "sky.exr", "up": "Z"})", Vec3d(0, 0, 1)},
        std::pair{R"({"file": "sky.exr", "up": "Z", "rotationDeg": 77})", Vec3d(0, 0, 1)}}) {
    const absl::StatusOr<BakeJob> built = BuildEnvJob(dir, map);
    ASSERT_TRUE(built.ok()) << built.status();
    const EnvironmentMap& m = *built->scene.environment.map;
    ExpectNear(m.worldFromMap * BrightestDirection(m), up, map);
  }
}

TEST(EnvironmentMap, ThirtyTwoBitValuesSurvive) {
  TempDir dir;
  Image image;
  image.Set(3, 4, 1.0e6f, 123456.7f, 65505.f);  // above half's largest value, 65504
  WriteExr(dir, "sun.exr", image);
  const absl::StatusOr<BakeJob> built = BuildEnvJob(dir, R"({"file": "sun.exr", "scale": 2})");
  ASSERT_TRUE(built.ok()) << built.status();
  const EnvironmentMap& map = *built->scene.environment.map;
  const size_t p = 3 * (4 * size_t(kWidth) + 3);
  EXPECT_EQ(map.rgb[p], 1.0e6f);
  EXPECT_EQ(map.rgb[p + 1], 123456.7f);
  EXPECT_EQ(map.rgb[p + 2], 65505.f);
  EXPECT_EQ(map.rgb[0], 0.25f);
  EXPECT_EQ(map.scale, 2);
  EXPECT_EQ(map.digest, Sha256Hex(ReadText(dir.File("sun.exr"))));
}

TEST(EnvironmentMap, DefaultsSpelledOutGiveTheSameDigests) {
  TempDir dir;
  WriteExr(dir, "sky.exr", Image());
  const absl::StatusOr<BakeJob> base = BuildEnvJob(dir, R"({"file": "sky.exr"})");
  ASSERT_TRUE(base.ok()) << base.status();
  for (const char* same :
       {R"({"file": "sky.exr", "scale": 1})", R"({"file": "sky.exr", "up": "Y"})",
        R"({"file": "sky.exr", "up": "Y", "scale": 1, "rotationDeg": 0})"}) {
    const absl::StatusOr<BakeJob> built = BuildEnvJob(dir, same);
    ASSERT_TRUE(built.ok()) << built.status();
    EXPECT_EQ(built->sceneDigest, base->sceneDigest) << same;
    EXPECT_EQ(built->jobDigest, base->jobDigest) << same;
  }
  for (const char* other :
       {R"({"file": "sky.exr", "scale": 2})", R"({"file": "sky.exr", "up": "Z"})",
        R"({"file": "sky.exr", "rotationDeg": 90})"}) {
    const absl::StatusOr<BakeJob> built = BuildEnvJob(dir, other);
    ASSERT_TRUE(built.ok()) << built.status();
    EXPECT_NE(built->sceneDigest, base->sceneDigest) << other;
  }
  // A map scaled to black bakes as no environment at all.
  const absl::StatusOr<BakeJob> black = BuildEnvJob(dir, R"({"file": "sky.exr", "scale": 0})");
  ASSERT_TRUE(black.ok()) << black.status();
  EXPECT_EQ(black->scene.environment.kind, Environment::Kind::kNone);
  const std::string none = R"({"grid": {"min": [0, 0, 0], "max": [1, 1, 1], "counts": [2, 2, 2]}})";
  const absl::StatusOr<BakeJob> noEnvironment =
      BuildBakeJob(*ParseJobJson(none), LocalAssetSource(dir.path()), {});
  ASSERT_TRUE(noEnvironment.ok()) << noEnvironment.status();
  EXPECT_EQ(black->sceneDigest, noEnvironment->sceneDigest);
}

TEST(EnvironmentMap, PixelsTimesScaleBeyondWhatFloatsHoldAreRefused) {
  TempDir dir;
  Image image;
  image.Set(3, 4, 5e28f, 0, 0);
  WriteExr(dir, "sun.exr", image);
  EXPECT_TRUE(BuildEnvJob(dir, R"({"file": "sun.exr", "scale": 10})").ok());
  EXPECT_TRUE(HasFieldError(BuildEnvJob(dir, R"({"file": "sun.exr", "scale": 100})").status(),
                            "scene.environment.map.scale",
                            "times the scale (100) is more than 1e30"));
  image.Set(3, 4, 1e31f, 0, 0);
  WriteExr(dir, "sun.exr", image);
  EXPECT_TRUE(HasFieldError(BuildEnvJob(dir, R"({"file": "sun.exr"})").status(),
                            "scene.environment.map.file", "is more than 1e30"));
}

TEST(EnvironmentMap, LuminanceOnlyIsGrey) {
  TempDir dir;
  Image image;
  image.grey = true;
  image.Set(1, 2, 7.5f, 0, 0);
  WriteExr(dir, "grey.exr", image);
  const absl::StatusOr<BakeJob> built = BuildEnvJob(dir, R"({"file": "grey.exr"})");
  ASSERT_TRUE(built.ok()) << built.status();
  const EnvironmentMap& map = *built->scene.environment.map;
  const size_t p = 3 * (2 * size_t(kWidth) + 1);
  EXPECT_EQ(map.rgb[p], 7.5f);
  EXPECT_EQ(map.rgb[p + 1], 7.5f);
  EXPECT_EQ(map.rgb[p + 2], 7.5f);
  EXPECT_EQ(map.scale, 1);
}

TEST(EnvironmentMap, BadMapsAreRejectedWithThePath) {
  TempDir dir;
  Image negative;
  negative.Set(5, 6, 1, -0.5f, 1);
  WriteExr(dir, "negative.exr", negative);
  EXPECT_TRUE(HasFieldError(BuildEnvJob(dir, R"({"file": "negative.exr"})").status(),
                            "scene.environment.map.file",
                            "\"negative.exr\" pixel (5, 6) has a negative value (-0.5)"));
  Image nan;
  nan.Set(0, 0, std::nanf(""), 0, 0);
  WriteExr(dir, "nan.exr", nan);
  EXPECT_TRUE(HasFieldError(BuildEnvJob(dir, R"({"file": "nan.exr"})").status(),
                            "scene.environment.map.file", "non-finite"));

  WriteExr(dir, "big.exr", Image());
  JobLimits limits;
  limits.maxEnvironmentPixels = 1000;
  EXPECT_TRUE(HasFieldError(BuildEnvJob(dir, R"({"file": "big.exr"})", limits).status(),
                            "scene.environment.map.file",
                            "65 x 33 pixels, above the limit of 1000"));

  dir.Write("garbage.exr", "not an exr");
  EXPECT_TRUE(HasFieldError(BuildEnvJob(dir, R"({"file": "garbage.exr"})").status(),
                            "scene.environment.map.file",
                            "\"garbage.exr\" is neither an OpenEXR nor a Radiance HDR file"));
  // A header attribute declaring more bytes than the file holds is refused before OpenEXR
  // allocates them.
  std::string lying = ReadText(dir.File("big.exr"));
  const size_t channels = lying.find(std::string("channels\0chlist\0", 16));
  ASSERT_NE(channels, std::string::npos);
  lying.replace(channels + 16, 4, std::string("\xff\xff\xff\x7f", 4));
  dir.Write("lying.exr", lying);
  EXPECT_TRUE(HasFieldError(BuildEnvJob(dir, R"({"file": "lying.exr"})").status(),
                            "scene.environment.map.file",
                            "its header attribute \"channels\" declares 2147483647 bytes"));
  // A channel list whose contents run past its declared size (OpenEXR reads it by contents, and
  // then takes pixel bytes for the next attribute's size: env_image_fuzz found 2 GB allocations).
  std::string shortList = ReadText(dir.File("big.exr"));
  shortList.replace(channels + 16, 4, std::string("\x34\0\0\0", 4));  // 52; it holds 55
  dir.Write("short_list.exr", shortList);
  EXPECT_TRUE(HasFieldError(BuildEnvJob(dir, R"({"file": "short_list.exr"})").status(),
                            "scene.environment.map.file",
                            "\"channels\" (chlist) does not hold what its size of 52 bytes"));
  // A truncated file fails cleanly too.
  const std::string whole = ReadText(dir.File("big.exr"));
  dir.Write("truncated.exr", whole.substr(0, whole.size() / 2));
  EXPECT_TRUE(HasFieldError(BuildEnvJob(dir, R"({"file": "truncated.exr"})").status(),
                            "scene.environment.map.file", "truncated.exr"));
}

TEST(EnvironmentMap, ZeroScaleIsNoEnvironmentButTheFileIsStillChecked) {
  TempDir dir;
  WriteExr(dir, "sky.exr", Image());
  const absl::StatusOr<BakeJob> built = BuildEnvJob(dir, R"({"file": "sky.exr", "scale": 0})");
  ASSERT_TRUE(built.ok()) << built.status();
  EXPECT_EQ(built->scene.environment.kind, Environment::Kind::kNone);
  EXPECT_TRUE(HasFieldError(BuildEnvJob(dir, R"({"file": "gone.exr", "scale": 0})").status(),
                            "scene.environment.map.file", "gone.exr"));
}

TEST(EnvironmentMap, FileAndBlobGiveTheSameDigests) {
  TempDir dir, blobs;
  WriteExr(dir, "sky.exr", Image());
  const std::string json = R"({"scene": {"environment": {"map": {"file": "sky.exr", "up": "Z"}}},
      "grid": {"min": [0, 0, 0], "max": [1, 1, 1], "counts": [2, 2, 2]}})";
  const absl::StatusOr<v1::JobSpec> job = ParseJobJson(json);
  ASSERT_TRUE(job.ok()) << job.status();
  v1::JobSpec uploaded = *job;
  const std::vector<FileReference> refs = ListFileReferences(*job);
  ASSERT_EQ(refs.size(), 1u);
  const std::string bytes = ReadText(dir.File("sky.exr"));
  blobs.Write(Sha256Hex(bytes), bytes);
  ASSERT_TRUE(ReplaceFileWithBlob(refs[0], DigestOf(bytes), &uploaded).ok());
  EXPECT_TRUE(uploaded.scene().environment().map().file().empty());

  const absl::StatusOr<BakeJob> local = BuildBakeJob(*job, LocalAssetSource(dir.path()), {});
  const absl::StatusOr<BakeJob> remote =
      BuildBakeJob(uploaded, LocalAssetSource("", blobs.path()), {});
  ASSERT_TRUE(local.ok()) << local.status();
  ASSERT_TRUE(remote.ok()) << remote.status();
  EXPECT_EQ(local->sceneDigest, remote->sceneDigest);
  EXPECT_EQ(local->jobDigest, remote->jobDigest);
  EXPECT_EQ(local->scene.environment.map->rgb, remote->scene.environment.map->rgb);
}

}  // namespace
}  // namespace probebake
