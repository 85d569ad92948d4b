// Engine exports read back (docs/engines.md): three.js's by three.js itself under node, Unity's
// by an independent ShadeSH9 (Unity's ConvertSHConstants packing), both against the core's
// irradiance E(n) = sum A_l L_lm Y_lm(n) (sh_convolution.h) at the probe's own position.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <numbers>
#include <random>

#include "absl/strings/str_format.h"
#include "engine_test_util.h"
#include "probebake/engines/engine_export.h"
#include "probebake/engines/engine_probes.h"
#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sh_convolution.h"
#include "probebake/volume/vdb_io.h"
#include "volume/test_volumes.h"

namespace probebake::testing {
namespace {

// Unit directions spread over the sphere (spherical Fibonacci) plus the six axes.
std::vector<Vec3d> TestNormals(int n) {
  std::vector<Vec3d> out = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  const double golden = (std::sqrt(5.0) - 1) / 2;
  for (int i = 0; i < n; ++i) {
    const double z = 1 - (2 * i + 1.0) / n;
    const double r = std::sqrt(1 - z * z), phi = 2 * std::numbers::pi * (i * golden);
    out.push_back({r * std::cos(phi), r * std::sin(phi), z});
  }
  return out;
}

std::array<Vec3d, 9> Radiance(const ProbeVolume& v, int64_t p) {
  std::array<Vec3d, 9> c;
  for (int i = 0; i < 9; ++i)
    c[i] = {v.radiance[i][3 * p], v.radiance[i][3 * p + 1], v.radiance[i][3 * p + 2]};
  return c;
}

// three.js's SphericalHarmonics3 basis (its source, math/SphericalHarmonics3.js getAt), with
// exact constants: no Condon-Shortley sign.
double ThreeBasis(int i, const Vec3d& d) {
  const double k0 = 0.5 / std::sqrt(std::numbers::pi), k1 = std::sqrt(3 / (4 * std::numbers::pi));
  const double k2 = std::sqrt(15 / (4 * std::numbers::pi)),
               k6 = std::sqrt(5 / (16 * std::numbers::pi));
  const double x = d.x, y = d.y, z = d.z;
  const double b[9] = {k0,
                       k1 * y,
                       k1 * z,
                       k1 * x,
                       k2 * x * y,
                       k2 * y * z,
                       k6 * (3 * z * z - 1),
                       k2 * x * z,
                       k2 / 2 * (x * x - y * y)};
  return b[i];
}

class EngineExportTest : public ::testing::Test {
 protected:
  void SetUp() override {
    volume_ = PlausibleVolume(7);
    vdb_ = dir_.File("probes.vdb");
    const absl::Status written = WriteProbeVolume(vdb_, volume_, MakeTestMetadata());
    ASSERT_TRUE(written.ok()) << written;
    for (int64_t p = 0; p < volume_.grid.ProbeCount(); ++p)
      if (volume_.active[p] && volume_.validity[p] >= 0.5f) usable_.push_back(p);
    ASSERT_GT(usable_.size(), 10u);
    ASSERT_LT(usable_.size(), static_cast<size_t>(volume_.grid.ProbeCount()))
        << "the volume should have unusable probes the export leaves out";
  }
  // Runs `probebake export` and returns the parsed file.
  google::protobuf::Struct Export(const std::string& format) {
    const std::string out = dir_.File(format + ".json");
    EXPECT_EQ(RunCommand(std::string(PROBEBAKE_CLI) + " export " + vdb_ + " --format " + format +
                         " -o " + out),
              0);
    return ParseJson(ReadFileText(out));
  }

  TempDir dir_;
  ProbeVolume volume_;
  std::string vdb_;
  std::vector<int64_t> usable_;
};

TEST(ThreeJsSh, RotatesTheFunctionIntoThreesFrameAndBasis) {
  // three's reconstruction at the mapped direction equals probebake's at the original one.
  std::mt19937_64 rng(3);
  std::normal_distribution<double> g;
  const Mat3d axes = ThreeJsFromProbebakeAxes();
  for (int trial = 0; trial < 20; ++trial) {
    std::array<Vec3d, 9> c;
    for (Vec3d& v : c) v = {g(rng), g(rng), g(rng)};
    const std::array<Vec3d, 9> t = ThreeJsSh(c);
    // The closed form docs/engines.md states (a permutation with signs, and a 2 x 2 mix of the
    // m = 0 and m = 2 terms of band 2, since the map moves the polar axis).
    const double h = std::sqrt(3.0) / 2;
    const Vec3d expected[9] = {
        c[0], c[2], c[1], -c[3], -c[7], c[5], -0.5 * c[6] - h * c[8], -c[4], 0.5 * c[8] - h * c[6]};
    for (int i = 0; i < 9; ++i)
      for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(t[i][ch], expected[i][ch], 1e-12) << i;
    for (const Vec3d& d : TestNormals(32)) {
      double y[9];
      EvalShBasis(2, d, y);
      Vec3d pb{}, three{};
      for (int i = 0; i < 9; ++i) {
        pb += c[i] * y[i];
        three += t[i] * ThreeBasis(i, axes * d);
      }
      for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(three[ch], pb[ch], 1e-12);
    }
  }
}

TEST_F(EngineExportTest, ThreeJsGetIrradianceAtUnderNodeMatchesTheCore) {
  ASSERT_TRUE(HaveProgram("node")) << "node is missing: run scripts/install-deps.sh";
  const std::string threeModule =
      std::string(PROBEBAKE_WEB_DIR) + "/node_modules/three/build/three.module.js";
  ASSERT_TRUE(std::ifstream(threeModule).good())
      << threeModule
      << " is missing: configure with -DPROBEBAKE_VIEWER=ON (npm ci of web/package-lock.json)";
  const google::protobuf::Struct exported = Export("threejs");
  const auto& probes = exported.fields().at("probes").list_value();
  ASSERT_EQ(probes.values_size(), static_cast<int>(usable_.size()));

  const Mat3d axes = ThreeJsFromProbebakeAxes();
  const std::vector<Vec3d> normals = TestNormals(200);
  std::string normalsJson = "[";
  for (size_t i = 0; i < normals.size(); ++i) {
    const Vec3d t = axes * normals[i];
    absl::StrAppendFormat(&normalsJson, "%s[%.6f,%.6f,%.6f]", i ? "," : "", t.x, t.y, t.z);
  }
  normalsJson += "]";
  // 6 decimals: read the normals back as three sees them.
  std::ofstream(dir_.File("normals.json")) << normalsJson;
  const google::protobuf::Struct parsedNormals = ParseJson("{\"n\":" + normalsJson + "}");
  std::string out;
  ASSERT_EQ(RunCommand("node " + std::string(PROBEBAKE_SOURCE_DIR) +
                           "/tests/engines/three_irradiance.mjs " + threeModule + " " +
                           dir_.File("threejs.json") + " " + dir_.File("normals.json"),
                       &out),
            0);
  const google::protobuf::Struct result = ParseJson(out);
  const auto& irradiance = result.fields().at("irradiance").list_value();
  ASSERT_EQ(irradiance.values_size(), static_cast<int>(usable_.size()));

  // Tolerance: three's getIrradianceAt folds the band factors into 6-digit constants (relative
  // rounding <= 2.1e-6, 0.247708 being the worst), and the export prints 9 digits; with the
  // ambient-dominated radiance here the sum of |terms| stays within 3 |E|, so 1e-5 relative
  // holds with margin. A frame, basis sign or scale error shows as O(1).
  double worst = 0;
  int compared = 0;
  for (size_t p = 0; p < usable_.size(); ++p) {
    const auto& probe = probes.values(static_cast<int>(p)).struct_value();
    const Vec3d position = ToVec3(probe.fields().at("position"));
    const Vec3d expectedPosition =
        axes *
        volume_.grid.Position(int(usable_[p] % 3), int(usable_[p] / 3 % 4), int(usable_[p] / 12));
    for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(position[ch], expectedPosition[ch], 1e-6);
    const std::array<Vec3d, 9> radiance = Radiance(volume_, usable_[p]);
    const auto& perNormal = irradiance.values(static_cast<int>(p)).list_value();
    ASSERT_EQ(perNormal.values_size(), static_cast<int>(normals.size()));
    for (size_t n = 0; n < normals.size(); ++n) {
      const Vec3d nThree = ToVec3(parsedNormals.fields().at("n").list_value().values(int(n)));
      const Vec3d nProbebake = Transpose(axes) * nThree;  // the direction three evaluated
      const Vec3d core = IrradianceAtRgb(2, radiance, nProbebake);
      const Vec3d three = ToVec3(perNormal.values(static_cast<int>(n)));
      for (int ch = 0; ch < 3; ++ch) {
        ASSERT_GT(core[ch], 0);
        const double rel = std::abs(three[ch] - core[ch]) / core[ch];
        worst = std::max(worst, rel);
        EXPECT_LE(rel, 1e-5) << "probe " << usable_[p] << " normal " << n << " channel " << ch
                             << ": three " << three[ch] << ", core " << core[ch];
        ++compared;
      }
    }
  }
  EXPECT_EQ(compared, static_cast<int>(usable_.size() * normals.size() * 3));
  std::printf("three.js r%s: %d values, worst relative difference %.3g\n",
              result.fields().at("revision").string_value().c_str(), compared, worst);
}

// Unity's ShadeSH9 from SphericalHarmonicsL2 coefficients, written from Unity's
// ConvertSHConstants (the packing of unity_SHAr..unity_SHC) and UnityCG.cginc's SHEvalLinearL0L1
// and SHEvalLinearL2: returns irradiance / pi at the unit normal n (Unity's frame).
Vec3d ShadeSh9(const std::array<Vec3d, 9>& sh, const Vec3d& n) {
  const double sqrtPi = std::sqrt(std::numbers::pi);
  const double fC0 = 1 / (2 * sqrtPi), fC1 = std::sqrt(3.0) / (3 * sqrtPi);
  const double fC2 = std::sqrt(15.0) / (8 * sqrtPi), fC3 = std::sqrt(5.0) / (16 * sqrtPi);
  const double fC4 = 0.5 * fC2;
  Vec3d out;
  for (int ch = 0; ch < 3; ++ch) {
    const double shA[4] = {-fC1 * sh[3][ch], -fC1 * sh[1][ch], fC1 * sh[2][ch],
                           fC0 * sh[0][ch] - fC3 * sh[6][ch]};
    const double shB[4] = {fC2 * sh[4][ch], -fC2 * sh[5][ch], 3 * fC3 * sh[6][ch],
                           -fC2 * sh[7][ch]};
    const double shC = fC4 * sh[8][ch];
    const double l0l1 = shA[0] * n.x + shA[1] * n.y + shA[2] * n.z + shA[3];
    const double vB[4] = {n.x * n.y, n.y * n.z, n.z * n.z, n.z * n.x};
    const double l2 = shB[0] * vB[0] + shB[1] * vB[1] + shB[2] * vB[2] + shB[3] * vB[3] +
                      shC * (n.x * n.x - n.y * n.y);
    out[ch] = l0l1 + l2;
  }
  return out;
}

TEST_F(EngineExportTest, UnityShadeSh9OfTheExportMatchesTheCore) {
  const google::protobuf::Struct exported = Export("unity");
  const auto& probes = exported.fields().at("probes").list_value();
  ASSERT_EQ(probes.values_size(), static_cast<int>(usable_.size()));
  const std::vector<Vec3d> normals = TestNormals(200);
  double worst = 0;
  for (size_t p = 0; p < usable_.size(); ++p) {
    const auto& probe = probes.values(static_cast<int>(p)).struct_value();
    const Vec3d q =
        volume_.grid.Position(int(usable_[p] % 3), int(usable_[p] / 3 % 4), int(usable_[p] / 12));
    const Vec3d position = ToVec3(probe.fields().at("position"));
    const Vec3d unityPosition{q.x, q.z, q.y};  // Unity (x, y, z) = probebake (x, z, y)
    for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(position[ch], unityPosition[ch], 1e-6);
    const auto& list = probe.fields().at("sh").list_value();
    ASSERT_EQ(list.values_size(), 27);
    std::array<Vec3d, 9> sh;  // sh[9 * channel + i] is SphericalHarmonicsL2[channel, i]
    for (int ch = 0; ch < 3; ++ch)
      for (int i = 0; i < 9; ++i) sh[i][ch] = list.values(9 * ch + i).number_value();
    const std::array<Vec3d, 9> radiance = Radiance(volume_, usable_[p]);
    for (const Vec3d& n : normals) {
      const Vec3d core = IrradianceAtRgb(2, radiance, n);
      const Vec3d unity = std::numbers::pi * ShadeSh9(sh, {n.x, n.z, n.y});
      for (int ch = 0; ch < 3; ++ch) {
        // Double evaluation of 9-digit coefficients: relative error ~1e-8 of the terms.
        const double rel = std::abs(unity[ch] - core[ch]) / core[ch];
        worst = std::max(worst, rel);
        EXPECT_LE(rel, 1e-6) << "probe " << usable_[p] << " channel " << ch << ": unity "
                             << unity[ch] << ", core " << core[ch];
      }
    }
  }
  std::printf("unity: worst relative difference %.3g\n", worst);
}

TEST(EngineExport, UnknownFormatIsRefusedNamingTheFlag) {
  const absl::StatusOr<EngineFormat> format = ParseEngineFormat("gltf");
  ASSERT_FALSE(format.ok());
  EXPECT_NE(format.status().message().find("--format: unknown format 'gltf'"), std::string::npos)
      << format.status();
}

TEST(EngineExport, InconsistentVolumeIsRefusedNamingThePlane) {
  ProbeVolume volume = PlausibleVolume(1);
  volume.radiance[4].pop_back();
  const absl::StatusOr<std::vector<EngineProbe>> probes = EngineProbes(volume);
  ASSERT_FALSE(probes.ok());
  EXPECT_NE(probes.status().message().find("radiance"), std::string::npos) << probes.status();
}

TEST(EngineExport, CliRefusesAnUnreadableVolumeWithExitCode2) {
  TempDir dir;
  std::ofstream(dir.File("bad.vdb")) << "not a volume";
  std::string out;
  EXPECT_EQ(RunCommand(std::string(PROBEBAKE_CLI) + " export " + dir.File("bad.vdb") +
                           " --format threejs -o " + dir.File("x.json") + " 2>&1",
                       &out),
            2);
  EXPECT_NE(out.find("bad.vdb"), std::string::npos) << out;
  EXPECT_EQ(RunCommand(std::string(PROBEBAKE_CLI) + " export " + dir.File("bad.vdb") +
                           " --format obj -o " + dir.File("x.json") + " 2>&1",
                       &out),
            2);
  EXPECT_NE(out.find("--format"), std::string::npos) << out;
}

}  // namespace
}  // namespace probebake::testing
