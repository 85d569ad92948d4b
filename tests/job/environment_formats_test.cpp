// Environment images beyond OpenEXR lat-long: Radiance .hdr files and cube maps (six face images,
// or one image in OpenEXR's cube-face layout), resampled into the lat-long map the tracer samples
// (docs/job-format.md).
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfEnvmap.h>
#include <OpenEXR/ImfEnvmapAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>

#include "core/src/job/cube_map.h"
#include "job/test_util.h"
#include "probebake/job/digest.h"
#include "probebake/job/file_refs.h"
#include "probebake/job/job.h"
#include "probebake/job/job_json.h"

#include "job/stb_image_write_static.h"

namespace probebake {
namespace {

using testing::HasFieldError;
using testing::ReadText;
using testing::TempDir;

constexpr double kPi = std::numbers::pi;
constexpr const char* kFaceNames[6] = {"px", "nx", "py", "ny", "pz", "nz"};

// Radiance as a function of the map-space direction.
using Radiance = std::function<Vec3d(const Vec3d&)>;

struct Pixels {
  int width = 0, height = 0;
  std::vector<float> rgb;
};

void WriteHdr(const TempDir& dir, const std::string& name, const Pixels& p) {
  ASSERT_TRUE(stbi_write_hdr(dir.File(name).c_str(), p.width, p.height, 3, p.rgb.data()));
}

void WriteExr(const TempDir& dir, const std::string& name, const Pixels& p, bool cubeTag) {
  const Imath::Box2i window({0, 0}, {p.width - 1, p.height - 1});
  Imf::Header header(window, window);
  if (cubeTag) Imf::addEnvmap(header, Imf::ENVMAP_CUBE);
  Imf::FrameBuffer frame;
  const size_t xStride = 3 * sizeof(float), yStride = xStride * size_t(p.width);
  for (int c = 0; c < 3; ++c) {
    const char* channel = c == 0 ? "R" : c == 1 ? "G" : "B";
    header.channels().insert(channel, Imf::Channel(Imf::FLOAT));
    frame.insert(channel,
                 Imf::Slice::Make(Imf::FLOAT, (float*)p.rgb.data() + c, window, xStride, yStride));
  }
  Imf::OutputFile file(dir.File(name).c_str(), header);
  file.setFrameBuffer(frame);
  file.writePixels(p.height);
}

// The n x 6n cube-face image of `f`, each pixel f at its centre's direction (Imf::CubeMap).
Pixels CubeStrip(int n, const Radiance& f) {
  Pixels p{n, 6 * n, std::vector<float>(size_t(n) * n * 18)};
  const Imath::Box2i window({0, 0}, {n - 1, 6 * n - 1});
  for (int face = 0; face < 6; ++face)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        const Imath::V3f d =
            Imf::CubeMap::direction(Imf::CubeMapFace(face), window, Imath::V2f(float(x), float(y)));
        const Vec3d v = f(Normalize(Vec3d(d.x, d.y, d.z)));
        const Imath::V2f at =
            Imf::CubeMap::pixelPosition(Imf::CubeMapFace(face), window, Imath::V2f(x, y));
        float* o = &p.rgb[3 * (size_t(at.y) * n + size_t(at.x))];
        o[0] = float(v.x), o[1] = float(v.y), o[2] = float(v.z);
      }
  return p;
}

// Face `face` (n x n) of a cube-face image.
Pixels Face(const Pixels& strip, int face) {
  const int n = strip.width;
  const auto begin = strip.rgb.begin() + ptrdiff_t(size_t(face) * n * n * 3);
  return {n, n, std::vector<float>(begin, begin + ptrdiff_t(size_t(n) * n * 3))};
}

std::string FacesJson(const std::string& extension) {
  std::string faces;
  for (const char* name : kFaceNames)
    faces +=
        std::string(faces.empty() ? "" : ", ") + R"({"file": ")" + name + "." + extension + R"("})";
  return R"({"faces": [)" + faces + "]}";
}

absl::StatusOr<BakeJob> BuildEnvJob(const TempDir& dir, const std::string& map,
                                    const JobLimits& limits = {}) {
  const std::string json =
      R"({"scene": {"environment": {"map": )" + map +
      R"(}}, "grid": {"min": [0, 0, 0], "max": [0, 0, 0], "counts": [1, 1, 1]}})";
  const absl::StatusOr<v1::JobSpec> job = ParseJobJson(json);
  if (!job.ok()) return job.status();
  return BuildBakeJob(*job, LocalAssetSource(dir.path()), limits);
}

// Imf::LatLongMap's direction of lat-long pixel (x, y) of a w x h map.
Vec3d LatLongDirection(int x, int y, int w, int h) {
  const double lon = 2 * kPi * (0.5 - double(x) / (w - 1));
  const double lat = kPi * (0.5 - double(y) / (h - 1));
  return {std::cos(lat) * std::sin(lon), std::sin(lat), std::cos(lat) * std::cos(lon)};
}

TEST(EnvironmentFormats, RadianceHdrReadsAsLinearFloats) {
  TempDir dir;
  // Values RGBE holds exactly: 8-bit mantissas under a shared exponent, so within a factor 2^8
  // of the pixel's largest.
  Pixels p{5, 3, std::vector<float>(45, 0.5f)};
  p.rgb[3 * 7] = 1024, p.rgb[3 * 7 + 1] = 256, p.rgb[3 * 7 + 2] = 64;
  WriteHdr(dir, "sky.hdr", p);
  const absl::StatusOr<BakeJob> built = BuildEnvJob(dir, R"({"file": "sky.hdr"})");
  ASSERT_TRUE(built.ok()) << built.status();
  const EnvironmentMap& map = *built->scene.environment.map;
  EXPECT_EQ(map.width, 5);
  EXPECT_EQ(map.height, 3);
  EXPECT_EQ(map.rgb, p.rgb);
  EXPECT_EQ(map.digest, Sha256Hex(ReadText(dir.File("sky.hdr"))));
}

TEST(EnvironmentFormats, ConstantCubeMapsAreThatConstant) {
  // Resampling averages equal values: the lat-long map is the constant exactly, so a constant
  // cube bakes as the uniform sky does (tests/bake/closed_form_test.cpp).
  TempDir dir;
  const Pixels strip = CubeStrip(8, [](const Vec3d&) { return Vec3d(0.25, 0.5, 2); });
  for (int f = 0; f < 6; ++f) WriteHdr(dir, std::string(kFaceNames[f]) + ".hdr", Face(strip, f));
  WriteExr(dir, "strip.exr", strip, /*cubeTag=*/true);
  WriteExr(dir, "untagged.exr", strip, /*cubeTag=*/false);
  for (const std::string& json :
       {FacesJson("hdr"), std::string(R"({"file": "strip.exr"})"),
        std::string(R"({"file": "untagged.exr", "projection": "CUBE"})")}) {
    const absl::StatusOr<BakeJob> built = BuildEnvJob(dir, json);
    ASSERT_TRUE(built.ok()) << built.status();
    const EnvironmentMap& map = *built->scene.environment.map;
    EXPECT_EQ(map.width, 4 * 8 + 1) << json;
    EXPECT_EQ(map.height, 2 * 8 + 1) << json;
    for (size_t k = 0; k < map.rgb.size(); k += 3) {
      ASSERT_EQ(map.rgb[k], 0.25f) << json;
      ASSERT_EQ(map.rgb[k + 1], 0.5f) << json;
      ASSERT_EQ(map.rgb[k + 2], 2.0f) << json;
    }
  }
  // Without the tag or CUBE, the strip is read as a (tall) lat-long image.
  const absl::StatusOr<BakeJob> latLong = BuildEnvJob(dir, R"({"file": "untagged.exr"})");
  ASSERT_TRUE(latLong.ok()) << latLong.status();
  EXPECT_EQ(latLong->scene.environment.map->height, 6 * 8);
}

TEST(EnvironmentFormats, EachCubePixelLandsInItsDirection) {
  // One bright pixel per face at a corner-ish spot: the resampled map's brightest pixel lies in
  // the direction OpenEXR's CubeMap gives that pixel, within the two pixels' extents (a cube
  // pixel of a 16-pixel face spans at most 2 atan(1/16) = 0.125 rad; a lat-long pixel of the
  // 65 x 33 map at most its diagonal, 0.14 rad).
  constexpr int n = 16;
  const Imath::Box2i window({0, 0}, {n - 1, 6 * n - 1});
  for (int face = 0; face < 6; ++face) {
    TempDir dir;
    Pixels strip = CubeStrip(n, [](const Vec3d&) { return Vec3d(1, 1, 1); });
    const Imath::V2f inFace(3, 11);
    const Imath::V2f at = Imf::CubeMap::pixelPosition(Imf::CubeMapFace(face), window, inFace);
    float* bright = &strip.rgb[3 * (size_t(at.y) * n + size_t(at.x))];
    bright[0] = bright[1] = bright[2] = 1e4f;
    WriteExr(dir, "strip.exr", strip, true);
    const absl::StatusOr<BakeJob> built = BuildEnvJob(dir, R"({"file": "strip.exr"})");
    ASSERT_TRUE(built.ok()) << built.status();
    const EnvironmentMap& map = *built->scene.environment.map;
    size_t best = 0;
    for (size_t p = 0; p < size_t(map.width) * map.height; ++p)
      if (map.rgb[3 * p] > map.rgb[3 * best]) best = p;
    const Vec3d got =
        LatLongDirection(int(best % map.width), int(best / map.width), map.width, map.height);
    const Imath::V3f d = Imf::CubeMap::direction(Imf::CubeMapFace(face), window, inFace);
    const Vec3d expected = Normalize(Vec3d(d.x, d.y, d.z));
    EXPECT_LT(std::acos(std::clamp(Dot(got, expected), -1.0, 1.0)), 0.125 + 0.14)
        << "face " << face << ": brightest at " << got << ", expected " << expected;
  }
}

TEST(EnvironmentFormats, ResampledCubeFollowsASmoothSky) {
  // f = 1 + A max(0, d . s)^4 is Lipschitz with constant L = 4A per radian of arc. A resampled
  // pixel averages cube pixels whose centres lie within the cube pixel radius r_c of points of
  // the lat-long cell, which lie within the cell radius r_l of its centre: it differs from f at
  // the centre by at most L (r_c + r_l). A face turned or mirrored puts the lobe elsewhere: errors
  // of order A.
  constexpr int n = 32;
  constexpr double A = 10;
  const Vec3d s = Normalize(Vec3d(0.3, 0.5, -0.8));
  const auto f = [&](const Vec3d& d) {
    return Vec3d(1, 1, 1) * (1 + A * std::pow(std::max(0.0, Dot(d, s)), 4));
  };
  const Pixels strip = CubeStrip(n, f);
  EnvironmentMap cube;
  cube.width = n;
  cube.height = 6 * n;
  cube.rgb = strip.rgb;
  const absl::StatusOr<EnvironmentMap> map = job_internal::LatLongFromCube(cube, "map", 0);
  ASSERT_TRUE(map.ok()) << map.status();
  // Imf::CubeMap puts pixel centres 2 / (n - 1) apart in face coordinates (the first and last on
  // the cube's edges), whose tangent plane is nearest at the face centre: half a pixel diagonal
  // subtends at most sqrt(2) / (n - 1) rad.
  const double rc = std::sqrt(2.0) / (n - 1);
  const int w = map->width, h = map->height;
  double worst = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const Vec3d centre = LatLongDirection(x, y, w, h);
      // Cell radius: the farthest of its corners and edge midpoints (cells are small).
      double rl = 0;
      for (double dx : {-0.5, 0.0, 0.5})
        for (double dy : {-0.5, 0.0, 0.5}) {
          const double cx = std::clamp(x + dx, 0.0, double(w - 1));
          const double cy = std::clamp(y + dy, 0.0, double(h - 1));
          const double lon = 2 * kPi * (0.5 - cx / (w - 1)), lat = kPi * (0.5 - cy / (h - 1));
          const Vec3d c{std::cos(lat) * std::sin(lon), std::sin(lat),
                        std::cos(lat) * std::cos(lon)};
          rl = std::max(rl, std::acos(std::clamp(Dot(c, centre), -1.0, 1.0)));
        }
      const double bound = 4 * A * (rc + rl) + 1e-5;  // + float rounding of values near 11
      const double err = std::abs(double(map->rgb[3 * (size_t(y) * w + x)]) - f(centre).x);
      worst = std::max(worst, err / bound);
      ASSERT_LE(err, bound) << "pixel " << x << ", " << y;
    }
  std::printf(
      "[measured] smooth sky resampled from a 32-pixel cube: worst error %.2f of its "
      "bound\n",
      worst);
}

TEST(EnvironmentFormats, BadCubeMapsNameTheField) {
  TempDir dir;
  const Pixels strip = CubeStrip(4, [](const Vec3d&) { return Vec3d(1, 1, 1); });
  for (int f = 0; f < 6; ++f) WriteHdr(dir, std::string(kFaceNames[f]) + ".hdr", Face(strip, f));
  WriteHdr(dir, "wide.hdr", Pixels{8, 4, std::vector<float>(96, 1.0f)});
  WriteHdr(dir, "big.hdr", Pixels{8, 8, std::vector<float>(192, 1.0f)});
  WriteExr(dir, "square.exr", Pixels{4, 4, std::vector<float>(48, 1.0f)}, true);

  EXPECT_TRUE(HasFieldError(
      BuildEnvJob(dir, R"({"faces": [{"file": "px.hdr"}, {"file": "nx.hdr"}]})").status(),
      "scene.environment.map.faces", "expected 6 faces"));
  std::string json = FacesJson("hdr");
  EXPECT_TRUE(HasFieldError(
      BuildEnvJob(dir, json.substr(0, json.size() - 1) + R"(, "file": "px.hdr"})").status(),
      "scene.environment.map", "not both"));
  EXPECT_TRUE(HasFieldError(
      BuildEnvJob(dir, json.substr(0, json.size() - 1) + R"(, "projection": "LAT_LONG"})").status(),
      "scene.environment.map.projection", "must be CUBE"));
  std::string wide = json, big = json, gone = json;
  wide.replace(wide.find("nz.hdr"), 6, "wide.hdr");
  EXPECT_TRUE(HasFieldError(BuildEnvJob(dir, wide).status(), "scene.environment.map.faces[5].file",
                            "must be square, this one is 8 x 4"));
  big.replace(big.find("py.hdr"), 6, "big.hdr");
  EXPECT_TRUE(HasFieldError(BuildEnvJob(dir, big).status(), "scene.environment.map.faces[2].file",
                            "8 x 8 pixels, but face 0 is 4 x 4"));
  gone.replace(gone.find("ny.hdr"), 6, "gone.hdr");
  EXPECT_TRUE(HasFieldError(BuildEnvJob(dir, gone).status(), "scene.environment.map.faces[3].file",
                            "gone"));
  EXPECT_TRUE(HasFieldError(BuildEnvJob(dir, R"({"file": "square.exr"})").status(),
                            "scene.environment.map.file", "N wide and 6N high"));
  JobLimits limits;
  limits.maxEnvironmentPixels = 100;
  EXPECT_TRUE(HasFieldError(BuildEnvJob(dir, FacesJson("hdr"), limits).status(),
                            "scene.environment.map.faces", "lat-long map of 17 x 9 pixels"));
  dir.Write("text.hdr", "#?RADIANCE\nnot really\n");
  EXPECT_TRUE(HasFieldError(BuildEnvJob(dir, R"({"file": "text.hdr"})").status(),
                            "scene.environment.map.file", "cannot read \"text.hdr\" as Radiance"));
}

// A run-length .hdr cut short inside its scanlines made stb_image loop for ever (it reads bytes
// past the end as zero-length runs): refused, and at once. Cut at every point of the data, so
// each kind of field (scanline header, run, literal) is the one cut somewhere.
TEST(EnvironmentFormats, ARadianceFileCutShortInItsScanlinesIsRefused) {
  TempDir dir;
  Pixels p{16, 4, std::vector<float>(16 * 4 * 3)};
  for (size_t i = 0; i < p.rgb.size(); ++i) p.rgb[i] = float(i % 7) * 0.25f;  // runs and literals
  WriteHdr(dir, "whole.hdr", p);
  ASSERT_TRUE(BuildEnvJob(dir, R"({"file": "whole.hdr"})").ok());
  const std::string whole = ReadText(dir.File("whole.hdr"));
  const size_t data = whole.find("+X 16\n") + 6;
  ASSERT_LT(data, whole.size());
  for (size_t end = data; end < whole.size(); ++end) {
    dir.Write("cut.hdr", whole.substr(0, end));
    EXPECT_TRUE(HasFieldError(BuildEnvJob(dir, R"({"file": "cut.hdr"})").status(),
                              "scene.environment.map.file",
                              "cannot read \"cut.hdr\" as Radiance HDR: its pixel data is cut "
                              "short"))
        << "cut at " << end << " of " << whole.size();
  }
}

TEST(EnvironmentFormats, FacesUploadAsBlobsWithTheSameDigests) {
  TempDir dir, blobs;
  const Pixels strip = CubeStrip(4, [](const Vec3d& d) { return Vec3d(1 + d.x, 1, 1); });
  for (int f = 0; f < 6; ++f) WriteHdr(dir, std::string(kFaceNames[f]) + ".hdr", Face(strip, f));
  const absl::StatusOr<v1::JobSpec> job =
      ParseJobJson(R"({"scene": {"environment": {"map": )" + FacesJson("hdr") +
                   R"(}}, "grid": {"min": [0, 0, 0], "max": [1, 1, 1], "counts": [2, 2, 2]}})");
  ASSERT_TRUE(job.ok()) << job.status();
  v1::JobSpec uploaded = *job;
  const std::vector<FileReference> refs = ListFileReferences(*job);
  ASSERT_EQ(refs.size(), 6u);
  for (const FileReference& ref : refs) {
    EXPECT_EQ(ref.kind, FileReference::Kind::kEnvironmentFace);
    EXPECT_EQ(ref.fieldPath,
              "scene.environment.map.faces[" + std::to_string(ref.faceIndex) + "].file");
    const std::string bytes = ReadText(dir.File(ref.relativePath));
    blobs.Write(Sha256Hex(bytes), bytes);
    ASSERT_TRUE(ReplaceFileWithBlob(ref, DigestOf(bytes), &uploaded).ok());
  }
  EXPECT_TRUE(ListFileReferences(uploaded).empty());
  const std::vector<BlobReference> needed = ListBlobReferences(uploaded);
  ASSERT_EQ(needed.size(), 6u);
  EXPECT_EQ(needed[4].fieldPath, "scene.environment.map.faces[4].blob");

  const absl::StatusOr<BakeJob> local = BuildBakeJob(*job, LocalAssetSource(dir.path()), {});
  const absl::StatusOr<BakeJob> remote =
      BuildBakeJob(uploaded, LocalAssetSource("", blobs.path()), {});
  ASSERT_TRUE(local.ok()) << local.status();
  ASSERT_TRUE(remote.ok()) << remote.status();
  EXPECT_EQ(local->sceneDigest, remote->sceneDigest);
  EXPECT_EQ(local->jobDigest, remote->jobDigest);
  EXPECT_EQ(local->scene.environment.map->rgb, remote->scene.environment.map->rgb);

  // Swapping two faces is another sky.
  v1::JobSpec swapped = *job;
  swapped.mutable_scene()->mutable_environment()->mutable_map()->mutable_faces()->SwapElements(0,
                                                                                               1);
  const absl::StatusOr<BakeJob> other = BuildBakeJob(swapped, LocalAssetSource(dir.path()), {});
  ASSERT_TRUE(other.ok()) << other.status();
  EXPECT_NE(other->sceneDigest, local->sceneDigest);
}

}  // namespace
}  // namespace probebake
