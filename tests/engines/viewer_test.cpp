// The viewer page (`probebake view`) rendered by headless Chromium (WebGL through SwiftShader):
// pixels of a floor lit by known probes match the core's irradiance within 2%.
#include <gtest/gtest.h>
#include <png.h>

#include <array>
#include <cmath>
#include <fstream>
#include <numbers>

#include "engine_test_util.h"
#include "probebake/engines/viewer_page.h"
#include "probebake/sh/sh_convolution.h"
#include "probebake/volume/vdb_io.h"
#include "volume/test_volumes.h"

namespace probebake {
// The viewer's JavaScript, bundled at build time (web/CMakeLists.txt).
extern const std::string_view kViewerBundle;
}  // namespace probebake

namespace probebake::testing {
namespace {

struct Png {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;
};

Png ReadPngRgb(const std::string& path) {
  Png result;
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&image, path.c_str())) {
    ADD_FAILURE() << path << ": " << image.message;
    return result;
  }
  image.format = PNG_FORMAT_RGB;
  result.width = static_cast<int>(image.width);
  result.height = static_cast<int>(image.height);
  result.rgb.resize(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, result.rgb.data(), 0, nullptr))
    ADD_FAILURE() << path << ": " << image.message;
  return result;
}

double SrgbToLinear(double v) {
  return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
}

// Every probe holds the same radiance (ambient + a lobe from above), except one invalid probe
// holding a huge value that the page must skip: any floor pixel then shows albedo * E(+Z) / pi,
// whatever point of the floor it sees.
struct FloorProbes {
  ProbeVolume volume;
  std::array<Vec3d, 9> radiance{};
  FloorProbes() {
    TestVolumeSpec spec;
    spec.counts[0] = 3;
    spec.counts[1] = 3;
    spec.counts[2] = 2;
    spec.origin = {-1, -1, 0.5};
    spec.spacing = {1, 1, 1};
    spec.inactiveEvery = 0;
    spec.invalidEvery = 0;
    spec.awkwardValues = false;
    volume = MakeTestVolume(spec);
    double lobe[9];
    HenyeyGreensteinLobe(2, 0.5, {0.3, 0.2, 0.93}, lobe);
    const Vec3d ambient{0.25, 0.3, 0.4}, power{1.2, 1.0, 0.6};
    for (int c = 0; c < 9; ++c) {
      radiance[c] = power * lobe[c];
      if (c == 0) radiance[c] += ambient * std::sqrt(4 * std::numbers::pi);
    }
    for (int64_t p = 0; p < volume.grid.ProbeCount(); ++p) {
      volume.validity[p] = 1;
      for (int c = 0; c < volume.CoeffCount(); ++c)
        for (int ch = 0; ch < 3; ++ch)
          volume.radiance[c][3 * p + ch] = c < 9 ? static_cast<float>(radiance[c][ch]) : 0.0f;
    }
    const int64_t invalid = volume.grid.LinearIndex(1, 1, 0);
    volume.validity[invalid] = 0;
    for (int ch = 0; ch < 3; ++ch) volume.radiance[0][3 * invalid + ch] = 1e4f;
  }
};

constexpr double kFloorAlbedo[3] = {0.6, 0.5, 0.4};

// Screenshots `html` in headless Chromium and checks pixels that see the floor against
// albedo * E(+Z) / pi within 2%.
void ExpectFloorPixels(const TempDir& dir, const std::string& html,
                       const std::array<Vec3d, 9>& radiance) {
  const std::string png = dir.File("shot.png");
  // probes=0 hides the probe spheres so the pixels see the floor.
  ASSERT_EQ(RunCommand("chromium --headless=new --no-sandbox --disable-gpu --use-angle=swiftshader "
                       "--enable-unsafe-swiftshader --hide-scrollbars --user-data-dir=" +
                       dir.File("chromium-profile") +
                       " --window-size=640,480 --virtual-time-budget=10000 --screenshot=" + png +
                       " 'file://" + html + "?probes=0' >/dev/null 2>&1"),
            0);
  const Png image = ReadPngRgb(png);
  ASSERT_EQ(image.width, 640);
  ASSERT_EQ(image.height, 480);

  const Vec3d albedo{kFloorAlbedo[0], kFloorAlbedo[1], kFloorAlbedo[2]};
  const Vec3d expected = albedo * IrradianceAtRgb(2, radiance, {0, 0, 1}) / std::numbers::pi;
  for (int ch = 0; ch < 3; ++ch) ASSERT_LT(expected[ch], 0.95) << "the test must not clip";
  // The page's camera looks at the middle of the floor and probes: these pixels see the floor.
  const int pixels[][2] = {{320, 240}, {260, 260}, {380, 220}, {320, 330}, {200, 300}};
  for (const auto& xy : pixels) {
    const uint8_t* px = &image.rgb[3 * (xy[1] * image.width + xy[0])];
    for (int ch = 0; ch < 3; ++ch) {
      const double got = SrgbToLinear(px[ch] / 255.0);
      // 2% plus half an 8-bit step of the sRGB encoding at this level.
      const double step = SrgbToLinear((px[ch] + 0.5) / 255.0) - got;
      EXPECT_NEAR(got, expected[ch], 0.02 * expected[ch] + step)
          << "pixel (" << xy[0] << ", " << xy[1] << ") channel " << ch << " = " << int(px[ch]);
    }
  }
}

TEST(Viewer, HeadlessChromiumShowsTheFloorLitByTheProbes) {
  ASSERT_TRUE(HaveProgram("chromium"))
      << "chromium is missing: run scripts/install-deps.sh (Debian's chromium package)";
  TempDir dir;
  const FloorProbes probes;
  const std::string vdb = dir.File("probes.vdb");
  ASSERT_TRUE(WriteProbeVolume(vdb, probes.volume, MakeTestMetadata()).ok());
  std::ofstream(dir.File("job.json")) << R"({
  "scene": {
    "materials": [{"name": "floor", "albedo": [0.6, 0.5, 0.4]}],
    "meshes": [{"name": "floor", "positions": [-4,-4,0, 4,-4,0, 4,4,0, -4,4,0],
                "indices": [0,1,2, 0,2,3], "material": "floor"}]
  },
  "grid": {"min": [-1, -1, 0.5], "max": [1, 1, 1.5], "counts": [3, 3, 2], "placement": "ALL"},
  "settings": {"shOrder": 2, "samplesPerProbe": 16}
})";
  const std::string html = dir.File("view.html");
  std::string out;
  ASSERT_EQ(RunCommand(std::string(PROBEBAKE_CLI) + " view " + vdb + " --scene " +
                           dir.File("job.json") + " --exposure 1 -o " + html + " 2>&1",
                       &out),
            0)
      << out;
  ExpectFloorPixels(dir, html, probes.radiance);
}

// The same floor as one 4 x 4 tile placed four times (an instanced mesh, drawn as a three.js
// InstancedMesh), one placement mirroring it: every pixel that saw the floor sees a tile.
TEST(Viewer, APlacedMeshIsDrawnAtEachPlacement) {
  ASSERT_TRUE(HaveProgram("chromium"))
      << "chromium is missing: run scripts/install-deps.sh (Debian's chromium package)";
  TempDir dir;
  const FloorProbes probes;
  Scene scene;
  scene.materials.push_back({"floor", {kFloorAlbedo[0], kFloorAlbedo[1], kFloorAlbedo[2]}, {}});
  TriangleMesh tile;
  tile.positions = {{0, 0, 0}, {4, 0, 0}, {4, 4, 0}, {0, 4, 0}};
  tile.indices = {0, 1, 2, 0, 2, 3};
  Mat3d mirror;
  mirror(0, 0) = -1;
  tile.placements = {{Mat3d::Identity(), {-4, -4, 0}},
                     {Mat3d::Identity(), {0, -4, 0}},
                     {Mat3d::Identity(), {-4, 0, 0}},
                     {mirror, {4, 0, 0}}};  // x in [0, 4], mirrored
  scene.meshes.push_back(tile);
  ViewerOptions options;
  options.exposure = 1;
  const absl::StatusOr<std::string> page =
      ViewerPageHtml(probes.volume, &scene, kViewerBundle, options);
  ASSERT_TRUE(page.ok()) << page.status();
  ASSERT_NE(page->find("\"placements\":["), std::string::npos);
  const std::string html = dir.File("view.html");
  std::ofstream(html) << *page;
  ExpectFloorPixels(dir, html, probes.radiance);
}

}  // namespace
}  // namespace probebake::testing
