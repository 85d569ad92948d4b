#include "probebake/engines/probe_textures.h"

#include <Imath/half.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "probebake/engines/engine_export.h"
#include "probebake/engines/engine_probes.h"
#include "probebake/volume/visibility_map.h"

namespace probebake {
namespace {

void PutFloat(std::vector<uint8_t>* bin, size_t at, float v) {
  uint32_t bits;
  std::memcpy(&bits, &v, sizeof bits);
  for (int b = 0; b < 4; ++b) (*bin)[at + b] = static_cast<uint8_t>(bits >> (8 * b));
}

void PutHalf(std::vector<uint8_t>* bin, size_t at, double v) {
  const uint16_t bits = Imath::half(static_cast<float>(v)).bits();
  (*bin)[at] = static_cast<uint8_t>(bits & 0xff);
  (*bin)[at + 1] = static_cast<uint8_t>(bits >> 8);
}

}  // namespace

std::string ProbeTexturesBinPath(const std::string& jsonPath) {
  if (absl::EndsWith(jsonPath, ".json")) return jsonPath.substr(0, jsonPath.size() - 5) + ".bin";
  return jsonPath + ".bin";
}

absl::StatusOr<ProbeTextures> PackProbeTextures(const ProbeVolume& volume,
                                                const std::string& binName) {
  absl::StatusOr<std::vector<EngineProbe>> probes = EngineProbes(volume);
  if (!probes.ok()) return probes.status();
  const ProbeGrid& g = volume.grid;
  const size_t texels = static_cast<size_t>(g.ProbeCount());
  ProbeTextures out;
  double l2Max = 0;
  for (const EngineProbe& p : *probes)
    if (p.usable)
      for (int c = 4; c < 9; ++c)
        for (int ch = 0; ch < 3; ++ch) l2Max = std::max(l2Max, std::abs(p.radiance[c][ch]));
  out.l2Scale = l2Max > 0 ? l2Max : 1;

  const size_t halfBytes = texels * 8, byteBytes = texels * 4;
  const bool offsets = volume.offset.size() == 3 * texels;
  const bool moments = volume.visibility.size() == size_t(kVisibilityTexels);
  const size_t core = 4 * halfBytes + 4 * byteBytes;
  const size_t offsetAt = core, momentsAt = core + (offsets ? halfBytes : 0);
  const size_t momentsBytes = moments ? texels * kVisibilityTexels * 16 : 0;
  // Sky transfer: rows r < 9 (what the L2 textures hold) by the sky's S columns.
  const int skyCoeffs = volume.skyTransferOrder > 0 ? volume.SkyCoeffCount() : 0;
  const int transferRows = std::min(volume.CoeffCount(), 9);
  const size_t transferAt = momentsAt + momentsBytes;
  const size_t transferBytes = texels * size_t(skyCoeffs) * 9 * 8;
  out.bin.assign(transferAt + transferBytes, 0);
  // Unusable texels: half zeros are 0 bits; L2 bytes encode 0 as 128.
  std::fill(out.bin.begin() + 4 * halfBytes, out.bin.begin() + core, uint8_t{128});
  if (offsets)
    for (const EngineProbe& p : *probes) {
      const size_t at = offsetAt + 8 * static_cast<size_t>(p.index);
      for (int a = 0; a < 3; ++a) PutHalf(&out.bin, at + 2 * a, p.offset[a]);
      PutHalf(&out.bin, at + 6, p.filled ? 1.0 : 0.0);
    }
  if (moments)
    for (const EngineProbe& p : *probes) {
      const size_t probe = static_cast<size_t>(p.index);
      for (int t = 0; t < kVisibilityTexels; ++t) {
        const size_t x = size_t(kVisibilityMapSize * p.i + t % kVisibilityMapSize);
        const size_t y = size_t(kVisibilityMapSize * p.j + t / kVisibilityMapSize);
        const size_t nx = size_t(kVisibilityMapSize * g.counts[0]);
        const size_t ny = size_t(kVisibilityMapSize * g.counts[1]);
        const size_t at = momentsAt + 16 * ((size_t(p.k) * ny + y) * nx + x);
        for (int ch = 0; ch < 3; ++ch)
          PutFloat(&out.bin, at + 4 * size_t(ch), volume.visibility[size_t(t)][3 * probe + ch]);
      }
    }
  if (skyCoeffs > 0)
    for (const EngineProbe& p : *probes) {
      if (!p.usable) continue;
      const size_t probe = static_cast<size_t>(p.index);
      const size_t nx = size_t(skyCoeffs) * size_t(g.counts[0]), ny = 9 * size_t(g.counts[1]);
      for (int r = 0; r < transferRows; ++r)
        for (int c = 0; c < skyCoeffs; ++c) {
          const size_t x = size_t(skyCoeffs) * size_t(p.i) + size_t(c);
          const size_t y = 9 * size_t(p.j) + size_t(r);
          const size_t at = transferAt + 8 * ((size_t(p.k) * ny + y) * nx + x);
          const std::vector<float>& plane =
              volume.skyTransfer[size_t(r) * size_t(skyCoeffs) + size_t(c)];
          for (int ch = 0; ch < 3; ++ch)
            PutHalf(&out.bin, at + 2 * size_t(ch), plane[3 * probe + size_t(ch)]);
        }
    }
  for (const EngineProbe& p : *probes) {
    if (!p.usable) continue;
    const size_t t = static_cast<size_t>(p.index);
    for (int ch = 0; ch < 3; ++ch) PutHalf(&out.bin, 8 * t + 2 * ch, p.radiance[0][ch]);
    PutHalf(&out.bin, 8 * t + 6, 1.0);
    for (int ch = 0; ch < 3; ++ch)
      for (int c = 1; c <= 3; ++c)
        PutHalf(&out.bin, (1 + ch) * halfBytes + 8 * t + 2 * (c - 1), p.radiance[c][ch]);
    for (int v = 0; v < 15; ++v) {
      const int ch = v / 5, c = 4 + v % 5;
      const double q =
          128 + std::round(127 * std::clamp(p.radiance[c][ch] / out.l2Scale, -1.0, 1.0));
      out.bin[4 * halfBytes + (v / 4) * byteBytes + 4 * t + v % 4] = static_cast<uint8_t>(q);
    }
  }

  std::string& h = out.headerJson;
  absl::StrAppendFormat(&h,
                        "{\"format\":\"probebake-probe-textures\",\"version\":3,"
                        "\"counts\":[%d,%d,%d],\"origin\":[%.17g,%.17g,%.17g],"
                        "\"spacing\":[%.17g,%.17g,%.17g],\"l2Scale\":%.9g,"
                        "\"skyTransferOrder\":%d,\"bin\":\"%s\",\"textures\":[",
                        g.counts[0], g.counts[1], g.counts[2], g.origin.x, g.origin.y, g.origin.z,
                        g.spacing.x, g.spacing.y, g.spacing.z, out.l2Scale,
                        skyCoeffs > 0 ? volume.skyTransferOrder : 0, binName);
  const char* names[] = {"L0_validity", "L1_r", "L1_g", "L1_b", "L2_0", "L2_1", "L2_2", "L2_3"};
  size_t offset = 0;
  for (int i = 0; i < 8; ++i) {
    const size_t bytes = i < 4 ? halfBytes : byteBytes;
    absl::StrAppendFormat(&h, "%s{\"name\":\"%s\",\"format\":\"%s\",\"offset\":%d,\"bytes\":%d}",
                          i ? "," : "", names[i], i < 4 ? "RGBA16F" : "RGBA8", offset, bytes);
    offset += bytes;
  }
  if (offsets) {
    absl::StrAppendFormat(
        &h, ",{\"name\":\"offset_filled\",\"format\":\"RGBA16F\",\"offset\":%d,\"bytes\":%d}",
        offset, halfBytes);
    offset += halfBytes;
  }
  if (moments)
    absl::StrAppendFormat(&h,
                          ",{\"name\":\"visibility\",\"format\":\"RGBA32F\",\"offset\":%d,"
                          "\"bytes\":%d,\"size\":[%d,%d,%d]}",
                          offset, momentsBytes, kVisibilityMapSize * g.counts[0],
                          kVisibilityMapSize * g.counts[1], g.counts[2]);
  if (skyCoeffs > 0)
    absl::StrAppendFormat(&h,
                          ",{\"name\":\"sky_transfer\",\"format\":\"RGBA16F\",\"offset\":%d,"
                          "\"bytes\":%d,\"size\":[%d,%d,%d]}",
                          transferAt, transferBytes, skyCoeffs * g.counts[0], 9 * g.counts[1],
                          g.counts[2]);
  h += "]}\n";
  return out;
}

absl::Status WriteProbeTextures(const ProbeVolume& volume, const std::string& jsonPath) {
  const std::string binPath = ProbeTexturesBinPath(jsonPath);
  const size_t slash = binPath.find_last_of('/');
  absl::StatusOr<ProbeTextures> packed =
      PackProbeTextures(volume, slash == std::string::npos ? binPath : binPath.substr(slash + 1));
  if (!packed.ok()) return packed.status();
  if (absl::Status written =
          WriteTextFileAtomically(binPath, std::string(packed->bin.begin(), packed->bin.end()));
      !written.ok())
    return written;
  return WriteTextFileAtomically(jsonPath, packed->headerJson);
}

}  // namespace probebake
