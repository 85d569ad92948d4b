// The textures export read back: header and binary decoded as docs/engines.md says, irradiance of
// the decoded coefficients against the core's at every usable probe, within the bound the
// quantisation gives (half: relative 2^-11 per coefficient; L2 bytes: l2Scale / 254 absolute).
#include <Imath/half.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <numbers>

#include "engine_test_util.h"
#include "probebake/engines/probe_textures.h"
#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sh_convolution.h"
#include "probebake/volume/vdb_io.h"
#include "probebake/volume/visibility_map.h"
#include "volume/test_volumes.h"

namespace probebake::testing {
namespace {

double Half(const std::string& bin, size_t at) {
  Imath::half h;
  h.setBits(static_cast<uint16_t>(static_cast<uint8_t>(bin[at]) |
                                  (static_cast<uint8_t>(bin[at + 1]) << 8)));
  return static_cast<float>(h);
}

TEST(ProbeTextures, ExportDecodesToTheCoreIrradianceWithinTheQuantisationBound) {
  TempDir dir;
  const ProbeVolume volume = PlausibleVolume(11);
  const std::string vdb = dir.File("probes.vdb");
  ASSERT_TRUE(WriteProbeVolume(vdb, volume, MakeTestMetadata()).ok());
  const std::string json = dir.File("tex.json");
  ASSERT_EQ(
      RunCommand(std::string(PROBEBAKE_CLI) + " export " + vdb + " --format textures -o " + json),
      0);
  const google::protobuf::Struct header = ParseJson(ReadFileText(json));
  EXPECT_EQ(header.fields().at("format").string_value(), "probebake-probe-textures");
  EXPECT_EQ(header.fields().at("bin").string_value(), "tex.bin");
  const std::string bin = ReadFileText(dir.File("tex.bin"));
  const double l2Scale = header.fields().at("l2Scale").number_value();
  const auto& textures = header.fields().at("textures").list_value();
  ASSERT_EQ(textures.values_size(), 8);
  const size_t texels = static_cast<size_t>(volume.grid.ProbeCount());
  size_t offsets[8];
  size_t total = 0;
  for (int i = 0; i < 8; ++i) {
    const auto& t = textures.values(i).struct_value().fields();
    offsets[i] = static_cast<size_t>(t.at("offset").number_value());
    EXPECT_EQ(offsets[i], total);
    EXPECT_EQ(t.at("bytes").number_value(), (i < 4 ? 8.0 : 4.0) * texels);
    EXPECT_EQ(t.at("format").string_value(), i < 4 ? "RGBA16F" : "RGBA8");
    total += static_cast<size_t>(t.at("bytes").number_value());
  }
  ASSERT_EQ(bin.size(), total);

  int usable = 0, unusable = 0;
  double worstRatio = 0;
  for (size_t t = 0; t < texels; ++t) {
    const bool isUsable = volume.active[t] && volume.validity[t] >= 0.5f;
    EXPECT_EQ(Half(bin, offsets[0] + 8 * t + 6), isUsable ? 1.0 : 0.0) << t;
    if (!isUsable) {
      ++unusable;
      continue;
    }
    ++usable;
    Vec3d c[9], err[9];
    for (int ch = 0; ch < 3; ++ch) {
      c[0][ch] = Half(bin, offsets[0] + 8 * t + 2 * ch);
      for (int k = 1; k <= 3; ++k) c[k][ch] = Half(bin, offsets[1 + ch] + 8 * t + 2 * (k - 1));
    }
    for (int v = 0; v < 15; ++v) {
      const int ch = v / 5, k = 4 + v % 5;
      const double q = static_cast<uint8_t>(bin[offsets[4 + v / 4] + 4 * t + v % 4]);
      c[k][ch] = (q - 128) / 127 * l2Scale;
    }
    for (int k = 0; k < 9; ++k)
      for (int ch = 0; ch < 3; ++ch) {
        const double exact = volume.radiance[k][3 * t + ch];
        err[k][ch] = k < 4 ? std::ldexp(std::abs(exact), -11) : l2Scale / 254;
      }
    for (const Vec3d& n : {Vec3d{0, 0, 1}, Vec3d{0, 0, -1}, Vec3d{1, 0, 0}, Vec3d{0.48, 0.6, 0.64},
                           Vec3d{-0.6, 0.64, -0.48}}) {
      double y[9];
      EvalShBasis(2, n, y);
      std::array<Vec3d, 9> exact;
      for (int k = 0; k < 9; ++k)
        exact[k] = {volume.radiance[k][3 * t], volume.radiance[k][3 * t + 1],
                    volume.radiance[k][3 * t + 2]};
      const Vec3d want = IrradianceAtRgb(2, exact, n);
      for (int ch = 0; ch < 3; ++ch) {
        double got = 0, bound = 1e-12;
        for (int k = 0; k < 9; ++k) {
          const double a = IrradianceBandFactor(k == 0 ? 0 : (k < 4 ? 1 : 2));
          got += a * c[k][ch] * y[k];
          bound += a * err[k][ch] * std::abs(y[k]);
        }
        EXPECT_LE(std::abs(got - want[ch]), bound)
            << "texel " << t << " channel " << ch << ": decoded " << got << ", core " << want[ch];
        worstRatio = std::max(worstRatio, std::abs(got - want[ch]) / bound);
      }
    }
  }
  EXPECT_GT(usable, 10);
  EXPECT_GT(unusable, 0);
  std::printf("textures: %d usable texels, worst error / bound %.3g\n", usable, worstRatio);
}

// A probe in a dark room holds 0 in every coefficient; its texels must read 0, not the L2
// encoding's nearest code (version 2 read l2Scale / 255 there).
TEST(ProbeTextures, ABlackProbeReadsExactlyZero) {
  ProbeVolume volume = PlausibleVolume(3);
  size_t black = 0;
  while (!(volume.active[black] && volume.validity[black] >= 0.5f)) ++black;
  for (auto& plane : volume.radiance)
    for (int ch = 0; ch < 3; ++ch) plane[3 * black + size_t(ch)] = 0;
  const absl::StatusOr<ProbeTextures> packed = PackProbeTextures(volume, "x.bin");
  ASSERT_TRUE(packed.ok()) << packed.status();
  const std::string bin(packed->bin.begin(), packed->bin.end());
  const size_t texels = static_cast<size_t>(volume.grid.ProbeCount());
  ASSERT_GT(packed->l2Scale, 0);
  EXPECT_EQ(Half(bin, 8 * black + 6), 1.0) << "the black probe is usable";
  for (int ch = 0; ch < 3; ++ch) EXPECT_EQ(Half(bin, 8 * black + 2 * size_t(ch)), 0.0);
  for (int t = 1; t <= 3; ++t)
    for (int c = 0; c < 3; ++c)
      EXPECT_EQ(Half(bin, t * 8 * texels + 8 * black + 2 * size_t(c)), 0.0);
  for (int v = 0; v < 15; ++v) {
    const double q =
        static_cast<uint8_t>(bin[32 * texels + (v / 4) * 4 * texels + 4 * black + v % 4]);
    EXPECT_EQ((q - 128) / 127 * packed->l2Scale, 0.0) << "L2 value " << v;
  }
}

TEST(ProbeTextures, OffsetsFilledFlagsAndVisibilityAreCarried) {
  ProbeVolume volume = PlausibleVolume(5);
  const size_t texels = static_cast<size_t>(volume.grid.ProbeCount());
  volume.offset.assign(3 * texels, 0.0f);
  volume.filled.assign(texels, 0.0f);
  volume.visibility.assign(kVisibilityTexels, std::vector<float>(3 * texels, 0.0f));
  int filledProbes = 0;
  for (size_t p = 0; p < texels; ++p) {
    if (!volume.active[p]) continue;
    for (int a = 0; a < 3; ++a) volume.offset[3 * p + a] = 0.01f * float(p % 7) - 0.02f * float(a);
    if (volume.validity[p] < 0.5f) {
      volume.filled[p] = 1;
      ++filledProbes;
    }
    for (int t = 0; t < kVisibilityTexels; ++t)
      for (int ch = 0; ch < 3; ++ch)
        volume.visibility[t][3 * p + ch] = 1e4f / float(1 + t + 3 * int(p) + ch);  // > half's max
  }
  ASSERT_GT(filledProbes, 0) << "the volume must have probes to fill";
  const absl::StatusOr<ProbeTextures> packed = PackProbeTextures(volume, "x.bin");
  ASSERT_TRUE(packed.ok()) << packed.status();
  const google::protobuf::Struct header = ParseJson(packed->headerJson);
  EXPECT_EQ(header.fields().at("version").number_value(), 3);
  const auto& textures = header.fields().at("textures").list_value();
  ASSERT_EQ(textures.values_size(), 10);
  const auto& offsetTexture = textures.values(8).struct_value().fields();
  const auto& atlas = textures.values(9).struct_value().fields();
  EXPECT_EQ(offsetTexture.at("name").string_value(), "offset_filled");
  EXPECT_EQ(atlas.at("name").string_value(), "visibility");
  EXPECT_EQ(atlas.at("format").string_value(), "RGBA32F");
  const auto& size = atlas.at("size").list_value();
  ASSERT_EQ(size.values_size(), 3);
  const size_t nx = size_t(size.values(0).number_value()),
               ny = size_t(size.values(1).number_value());
  EXPECT_EQ(nx, 8u * size_t(volume.grid.counts[0]));
  EXPECT_EQ(ny, 8u * size_t(volume.grid.counts[1]));
  EXPECT_EQ(size.values(2).number_value(), volume.grid.counts[2]);
  const size_t offsetAt = size_t(offsetTexture.at("offset").number_value());
  const size_t atlasAt = size_t(atlas.at("offset").number_value());
  EXPECT_EQ(atlas.at("bytes").number_value(), 16.0 * 64 * double(texels));
  ASSERT_EQ(packed->bin.size(), atlasAt + 16 * 64 * texels);
  const std::string bin(packed->bin.begin(), packed->bin.end());
  for (size_t p = 0; p < texels; ++p) {
    if (!volume.active[p]) continue;
    // Filled probes are usable: alpha 1 in L0_validity.
    EXPECT_EQ(Half(bin, 8 * p + 6), 1.0) << p;
    for (int a = 0; a < 3; ++a)
      EXPECT_EQ(Half(bin, offsetAt + 8 * p + 2 * size_t(a)),
                float(Imath::half(volume.offset[3 * p + size_t(a)])))
          << p;
    EXPECT_EQ(Half(bin, offsetAt + 8 * p + 6), volume.filled[p]) << p;
    int i, j, k;
    volume.grid.Coords(int64_t(p), &i, &j, &k);
    for (int t = 0; t < kVisibilityTexels; ++t) {
      const size_t x = 8 * size_t(i) + size_t(t % 8), y = 8 * size_t(j) + size_t(t / 8);
      const size_t at = atlasAt + 16 * ((size_t(k) * ny + y) * nx + x);
      for (int ch = 0; ch < 3; ++ch) {
        float v;
        std::memcpy(&v, &bin[at + 4 * size_t(ch)], 4);  // little-endian host
        EXPECT_EQ(v, volume.visibility[size_t(t)][3 * p + size_t(ch)]) << p << " texel " << t;
      }
    }
  }
}

}  // namespace
}  // namespace probebake::testing
