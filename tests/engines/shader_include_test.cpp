// The GLSL include (integrations/shaders/probebake_probes.glsl) run by WebGL in headless Chromium
// against the core's reference sampler (ProbeSampler) on the same textures: a baked two-room leak
// scene with relocation offsets, dilation and visibility moments, sampled at points near the thin
// wall on both sides and throughout the rooms, with the visibility weights on and off.
#include <Imath/half.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <numbers>
#include <random>

#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "bake/bake_test_util.h"
#include "engine_test_util.h"
#include "probebake/bake/relight.h"
#include "probebake/engines/probe_textures.h"
#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sh_convolution.h"
#include "probebake/volume/probe_sampler.h"
#include "probebake/volume/visibility_map.h"
#include "volume/test_volumes.h"

namespace probebake::testing {
namespace {

float HalfAt(const std::vector<uint8_t>& bin, size_t at) {
  Imath::half h;
  h.setBits(static_cast<uint16_t>(bin[at] | (bin[at + 1] << 8)));
  return static_cast<float>(h);
}

float FloatAt(const std::vector<uint8_t>& bin, size_t at) {
  uint32_t bits = 0;
  for (int b = 0; b < 4; ++b) bits |= uint32_t(bin[at + size_t(b)]) << (8 * b);
  float v;
  std::memcpy(&v, &bits, sizeof v);
  return v;
}

// The volume the textures hold, decoded as docs/engines.md states (order 2 radiance, usable =
// alpha, offsets and filled flags, the visibility atlas): what a shader reading them can know.
ProbeVolume DecodeTextures(const ProbeTextures& packed) {
  const google::protobuf::Struct header = ParseJson(packed.headerJson);
  ProbeVolume v;
  const auto& f = header.fields();
  for (int a = 0; a < 3; ++a)
    v.grid.counts[a] = int(f.at("counts").list_value().values(a).number_value());
  v.grid.origin = ToVec3(f.at("origin"));
  v.grid.spacing = ToVec3(f.at("spacing"));
  v.shOrder = 2;
  const size_t texels = size_t(v.grid.ProbeCount());
  v.active.assign(texels, 1);
  v.validity.assign(texels, 0);
  v.radiance.assign(9, std::vector<float>(3 * texels, 0));
  const double l2Scale = f.at("l2Scale").number_value();
  std::map<std::string, size_t> at;
  for (const auto& t : f.at("textures").list_value().values())
    at[t.struct_value().fields().at("name").string_value()] =
        size_t(t.struct_value().fields().at("offset").number_value());
  const auto& bin = packed.bin;
  for (size_t t = 0; t < texels; ++t) {
    v.validity[t] = HalfAt(bin, at["L0_validity"] + 8 * t + 6);
    for (int ch = 0; ch < 3; ++ch) {
      v.radiance[0][3 * t + size_t(ch)] = HalfAt(bin, at["L0_validity"] + 8 * t + 2 * size_t(ch));
      const char* l1[] = {"L1_r", "L1_g", "L1_b"};
      for (int k = 1; k <= 3; ++k)
        v.radiance[size_t(k)][3 * t + size_t(ch)] =
            HalfAt(bin, at[l1[ch]] + 8 * t + 2 * size_t(k - 1));
    }
    for (int i = 0; i < 15; ++i) {
      const double q = bin[at[absl::StrCat("L2_", i / 4)] + 4 * t + size_t(i % 4)];
      // What the shader computes, in float.
      v.radiance[size_t(4 + i % 5)][3 * t + size_t(i / 5)] =
          (float(q) - 128.0f) / 127.0f * float(l2Scale);
    }
  }
  if (at.count("offset_filled")) {
    v.offset.assign(3 * texels, 0);
    v.filled.assign(texels, 0);
    for (size_t t = 0; t < texels; ++t) {
      for (int a = 0; a < 3; ++a)
        v.offset[3 * t + size_t(a)] = HalfAt(bin, at["offset_filled"] + 8 * t + 2 * size_t(a));
      v.filled[t] = HalfAt(bin, at["offset_filled"] + 8 * t + 6);
    }
  }
  if (at.count("visibility")) {
    v.visibility.assign(kVisibilityTexels, std::vector<float>(3 * texels, 0));
    const size_t nx = size_t(kVisibilityMapSize * v.grid.counts[0]);
    const size_t ny = size_t(kVisibilityMapSize * v.grid.counts[1]);
    for (size_t p = 0; p < texels; ++p) {
      int i, j, k;
      v.grid.Coords(int64_t(p), &i, &j, &k);
      for (int t = 0; t < kVisibilityTexels; ++t) {
        const size_t x = size_t(kVisibilityMapSize * i + t % kVisibilityMapSize);
        const size_t y = size_t(kVisibilityMapSize * j + t / kVisibilityMapSize);
        for (int ch = 0; ch < 3; ++ch)
          v.visibility[size_t(t)][3 * p + size_t(ch)] = FloatAt(
              bin, at["visibility"] + 16 * ((size_t(k) * ny + y) * nx + x) + 4 * size_t(ch));
      }
    }
  }
  const int skyOrder = int(f.at("skyTransferOrder").number_value());
  if (skyOrder > 0) {
    v.skyTransferOrder = skyOrder;
    const size_t columns = size_t(v.SkyCoeffCount());
    v.skyTransfer.assign(9 * columns, std::vector<float>(3 * texels, 0));
    const size_t nx = columns * size_t(v.grid.counts[0]), ny = 9 * size_t(v.grid.counts[1]);
    for (size_t p = 0; p < texels; ++p) {
      int i, j, k;
      v.grid.Coords(int64_t(p), &i, &j, &k);
      for (size_t r = 0; r < 9; ++r)
        for (size_t c = 0; c < columns; ++c)
          for (int ch = 0; ch < 3; ++ch)
            v.skyTransfer[r * columns + c][3 * p + size_t(ch)] = HalfAt(
                bin, at["sky_transfer"] +
                         8 * ((size_t(k) * ny + 9 * size_t(j) + r) * nx + columns * size_t(i) + c) +
                         2 * size_t(ch));
    }
  }
  // Not in the textures; Relight wants every per-probe plane.
  v.stdError.assign(texels, 0);
  v.stdErrorL0.assign(texels, 0);
  v.sampleCount.assign(texels, 0);
  return v;
}

struct Query {
  Vec3d position, normal;  // float-representable
};

Vec3d ToFloats(const Vec3d& v) {
  return {float(v.x), float(v.y), float(v.z)};
}

Vec3d RandomDirection(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0, 1);
  const double cz = 2 * u(rng) - 1, phi = 2 * std::numbers::pi * u(rng), r = std::sqrt(1 - cz * cz);
  return {r * std::cos(phi), r * std::sin(phi), cz};
}

// Points near the wall on both sides (2 cm to a quarter spacing, the leak tests' points) with
// axis normals, and points throughout both rooms with random normals.
std::vector<Query> LeakQueries() {
  std::vector<Query> out;
  const Vec3d normals[] = {{1, 0, 0}, {-1, 0, 0}, {0, 0, 1}, {0, 1, 0}, {0, -1, 0}, {0, 0, -1}};
  for (double delta : {0.02, 0.05, 0.09, 0.125})
    for (double x : {kTwoRoomsWall + delta, -delta})
      for (double y : {-0.6, -0.1, 0.35})
        for (double z : {0.0, 0.05, 0.3, 0.9, 1.6})
          for (const Vec3d& n : normals)
            if (z > 0 || n.z == 1) out.push_back({ToFloats({x, y, z}), n});
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  while (out.size() < 1024) {
    const Vec3d x{-1.99 + 3.98 * u(rng), -0.99 + 1.98 * u(rng), 0.01 + 1.98 * u(rng)};
    if (x.x > -0.01 && x.x < kTwoRoomsWall + 0.01) continue;  // in the wall
    out.push_back({ToFloats(x), ToFloats(RandomDirection(rng))});
  }
  return out;
}

// The size of the numbers the shader blends at query q: the largest, over the usable probes of
// q's cell, of sum_k A_l |c_k Y_k(n)| (the terms of E(n) before they cancel). Float rounding of
// the weights moves the normalised blend by at most twice their relative error times this, and
// the evaluation of E(n) by a few float roundings of it.
double CellMagnitude(const ProbeVolume& volume, const Query& q) {
  const ProbeGrid& grid = volume.grid;
  int base[3];
  for (int a = 0; a < 3; ++a) {
    const double f = std::clamp((q.position[a] - grid.origin[a]) / grid.spacing[a], 0.0,
                                double(grid.counts[a] - 1));
    base[a] = std::min(int(std::floor(f)), std::max(grid.counts[a] - 2, 0));
  }
  double y[9];
  EvalShBasis(2, Normalize(q.normal), y);
  double magnitude = 0;
  for (int corner = 0; corner < 8; ++corner) {
    const int64_t p = grid.LinearIndex(std::min(base[0] + (corner & 1), grid.counts[0] - 1),
                                       std::min(base[1] + ((corner >> 1) & 1), grid.counts[1] - 1),
                                       std::min(base[2] + ((corner >> 2) & 1), grid.counts[2] - 1));
    if (volume.validity[size_t(p)] < 0.5f) continue;
    for (int ch = 0; ch < 3; ++ch) {
      double sum = 0;
      for (int k = 0; k < 9; ++k)
        sum += IrradianceBandFactor(k == 0  ? 0
                                    : k < 4 ? 1
                                            : 2) *
               std::abs(volume.radiance[size_t(k)][3 * size_t(p) + size_t(ch)] * y[k]);
      magnitude = std::max(magnitude, sum);
    }
  }
  return magnitude;
}

// Points of a dense lattice near the wall (5 cm apart over its face, 2 to 12.5 cm from it on
// both sides, 26 normals) where the cell's connectivity moves the core's irradiance by more than
// a tenth of the cell's magnitude: the include must cut the lit probes off as the core does.
// At most `limit` of them, spread over the lattice.
std::vector<Query> ConnectivityQueries(const ProbeTextures& packed, size_t limit) {
  const ProbeVolume volume = DecodeTextures(packed);
  const ProbeSampler with(volume);
  ProbeSamplerOptions options;
  options.connectivity = false;
  const ProbeSampler without(volume, options);
  const std::vector<Vec3d> normals = CubeDirections();
  std::vector<Query> found;
  for (double delta : {0.02, 0.05, 0.09, 0.125})
    for (double x : {kTwoRoomsWall + delta, -delta})
      for (int iy = 0; iy <= 38; ++iy)
        for (int iz = 1; iz <= 39; ++iz)
          for (const Vec3d& n : normals) {
            // 3 mm off the grid's planes, where float and double could pick different cells.
            const Query q{ToFloats({x, -0.947 + 0.05 * iy, 0.003 + 0.05 * iz}), ToFloats(n)};
            const Vec3d a = with.Sample(q.position, q.normal).irradiance;
            const Vec3d b = without.Sample(q.position, q.normal).irradiance;
            if (MaxComponent(Abs(a - b)) > 0.1 * CellMagnitude(volume, q)) found.push_back(q);
          }
  std::vector<Query> out;
  for (size_t i = 0; i < std::min(limit, found.size()); ++i)
    out.push_back(found[i * found.size() / std::min(limit, found.size())]);
  return out;
}

// Tolerances, relative to CellMagnitude, from float (u = 2^-24 = 6e-8) against double:
// - without visibility the weights are trilinear x backface from float positions: a cell
//   coordinate off by ~u (|x| + |origin|) / spacing + u g <= 16 u = 1e-6, each of 8 weights off
//   by <= 3e-6, moving E by <= 2 x 8 x 3e-6 = 5e-5; E(n)'s nine terms add < 20 u. Bound 1e-4.
// - with visibility, Chebyshev's variance is m1 - m0^2 less the texels' trend, all of the order
//   of the largest texel's s^2, and floored at 6e-3 mean^2: float's rounding of them, 2u s_max^2,
//   is amplified by s_max^2 / (6e-3 mean^2) in the variance. The bilinear taps of one point hold
//   surfaces within 8x of each other in s here (a wall 0.25 m away beside the room's far side), so
//   by up to 64 / 6e-3 = 1.1e4; it passes into p = var / (var + excess^2) at most 1:1, is tripled
//   by the cube and tripled again by the crush: 9 x 2u x 1.1e4 = 1.1e-2 relative in a weight,
//   2.2e-2 in the blend. The connectivity (probe_sampler.h) raises the ratio of two probes'
//   supports (sums of claims, each a product of ramps in the edges' visibilities and the wall's
//   distance along them) to the 8th power, so where it binds a weight carries up to 16 times
//   their relative error; that is not covered by the bound, which is kept: measured with the
//   points where the connectivity matters, the worst difference is 5.4e-4 and 1.7e-6 in the two
//   leak scenes (the edges are read head-on along grid axes, where a texel's s are alike and the
//   variance's cancellation is mild).
constexpr double kTolerance = 1e-4;
constexpr double kVisibilityTolerance = 2.2e-2;

std::string FloatList(const std::vector<Query>& queries, bool normals) {
  std::vector<std::string> values;
  for (const Query& q : queries) {
    const Vec3d& v = normals ? q.normal : q.position;
    for (int a = 0; a < 3; ++a) values.push_back(absl::StrFormat("%.9g", float(v[a])));
    values.push_back("0");
  }
  return absl::StrJoin(values, ",");
}

// The GLSL include in a fragment shader that writes pbIrradiance of query gl_FragCoord.x.
std::string GlslFragment() {
  return absl::StrCat(R"(#version 300 es
precision highp float;
precision highp int;
precision highp sampler3D;
precision highp sampler2D;
)",
                      ReadFileText(std::string(PROBEBAKE_SHADER_DIR) + "/probebake_probes.glsl"),
                      R"(
uniform sampler2D queryPositions;
uniform sampler2D queryNormals;
out vec4 result;
void main() {
  int i = int(gl_FragCoord.x);
  result = pbIrradiance(texelFetch(queryPositions, ivec2(i, 0), 0).xyz,
                        texelFetch(queryNormals, ivec2(i, 0), 0).xyz);
})");
}

// The HLSL include in the same fragment shader, compiled to SPIR-V by glslang and back to GLSL ES
// 3.00 by SPIRV-Cross (which names a texture T's sampler SPIRV_Cross_CombinedTSPIRV_Cross_Dummy-
// Sampler and puts the globals in a struct: the page finds uniforms by their last name part).
std::string HlslFragment(const TempDir& dir) {
  const std::string driver = dir.File("driver.hlsl"), spirv = dir.File("driver.spv");
  std::ofstream(driver) << R"(#include "probebake_probes.hlsl"
Texture2D<float4> queryPositions;
Texture2D<float4> queryNormals;
float4 main(float4 position : SV_Position) : SV_Target {
  int i = int(position.x);
  return pbIrradiance(queryPositions.Load(int3(i, 0, 0)).xyz, queryNormals.Load(int3(i, 0, 0)).xyz);
}
)";
  std::string log;
  if (RunCommand("glslangValidator -D -S frag -e main -V -I" + std::string(PROBEBAKE_SHADER_DIR) +
                     " " + driver + " -o " + spirv + " 2>&1",
                 &log) != 0) {
    ADD_FAILURE() << "glslangValidator refused the HLSL include:\n" << log;
    return "";
  }
  std::string glsl;
  if (RunCommand("spirv-cross " + spirv + " --es --version 300 --glsl-emit-ubo-as-plain-uniforms",
                 &glsl) != 0) {
    ADD_FAILURE() << "spirv-cross failed on the compiled HLSL include";
    return "";
  }
  return glsl;
}

// A page that draws one fragment per query with `fragment` into an RGBA32F target, twice (row 0
// with the visibility weights, row 1 without), and writes the pixels as JSON into <pre id="out">.
std::string Page(const ProbeTextures& packed, const std::string& fragment,
                 const std::vector<Query>& queries, const std::vector<Vec3d>& sky) {
  std::vector<std::string> skyValues;
  for (const Vec3d& c : sky)
    for (int ch = 0; ch < 3; ++ch) skyValues.push_back(absl::StrFormat("%.17g", c[ch]));
  const std::string bin(packed.bin.begin(), packed.bin.end());
  return absl::StrCat(R"(<!doctype html><html><body><pre id="out">pending</pre>
<script type="x-shader" id="fragment">)",
                      fragment, R"(</script>
<script>
const out = document.getElementById('out');
try {
  const header = )",
                      packed.headerJson, R"(;
  const bin = Uint8Array.from(atob(')",
                      absl::Base64Escape(bin), R"('), (c) => c.charCodeAt(0));
  const positions = new Float32Array([)",
                      FloatList(queries, false), R"(]);
  const normals = new Float32Array([)",
                      FloatList(queries, true), R"(]);
  const sky = [)",
                      absl::StrJoin(skyValues, ","), R"(];
  const n = positions.length / 4;
  const gl = document.createElement('canvas').getContext('webgl2');
  if (!gl) throw new Error('no WebGL2');
  if (!gl.getExtension('EXT_color_buffer_float')) throw new Error('no EXT_color_buffer_float');
  const vs = `#version 300 es
in vec2 corner;
void main() { gl_Position = vec4(corner, 0.0, 1.0); }`;
  const program = gl.createProgram();
  for (const [type, source] of [[gl.VERTEX_SHADER, vs],
                                [gl.FRAGMENT_SHADER, document.getElementById('fragment').textContent.trim()]]) {
    const s = gl.createShader(type);
    gl.shaderSource(s, source);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    gl.attachShader(program, s);
  }
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(program));
  gl.useProgram(program);
  const uniforms = {};
  for (let i = 0; i < gl.getProgramParameter(program, gl.ACTIVE_UNIFORMS); i++) {
    const info = gl.getActiveUniform(program, i);
    const name = info.name.replace(/^.*\./, '').replace(/\[0\]$/, '')
                     .replace(/^SPIRV_Cross_Combined/, '').replace(/SPIRV_Cross_DummySampler$/, '');
    uniforms[name] = { location: gl.getUniformLocation(program, info.name), type: info.type };
  }
  const setInt = (name, v) => {
    const u = uniforms[name];
    if (!u) throw new Error('no uniform ' + name);
    if (u.type === gl.UNSIGNED_INT) gl.uniform1ui(u.location, v); else gl.uniform1i(u.location, v);
  };
  let unit = 0;
  const bind = (name, target, texture) => {
    gl.activeTexture(gl.TEXTURE0 + unit);
    gl.bindTexture(target, texture);
    setInt(name, unit++);
  };
  // Textures are made on a unit no sampler uses, so that making one never replaces a binding.
  const scratchUnit = gl.TEXTURE0 + gl.getParameter(gl.MAX_COMBINED_TEXTURE_IMAGE_UNITS) - 1;
  const [nx, ny, nz] = header.counts;
  const textures = {};
  for (const t of header.textures) {
    const [sx, sy, sz] = t.size || [nx, ny, nz];
    const tex = gl.createTexture();
    gl.activeTexture(scratchUnit);
    gl.bindTexture(gl.TEXTURE_3D, tex);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    if (t.format === 'RGBA16F')
      gl.texImage3D(gl.TEXTURE_3D, 0, gl.RGBA16F, sx, sy, sz, 0, gl.RGBA, gl.HALF_FLOAT,
                    new Uint16Array(bin.buffer, t.offset, t.bytes / 2));
    else if (t.format === 'RGBA32F')
      gl.texImage3D(gl.TEXTURE_3D, 0, gl.RGBA32F, sx, sy, sz, 0, gl.RGBA, gl.FLOAT,
                    new Float32Array(bin.buffer, t.offset, t.bytes / 4));
    else
      gl.texImage3D(gl.TEXTURE_3D, 0, gl.RGBA8, sx, sy, sz, 0, gl.RGBA, gl.UNSIGNED_BYTE,
                    new Uint8Array(bin.buffer, t.offset, t.bytes));
    for (const p of [gl.TEXTURE_MIN_FILTER, gl.TEXTURE_MAG_FILTER]) gl.texParameteri(gl.TEXTURE_3D, p, gl.NEAREST);
    const error = gl.getError();
    if (error) throw new Error('GL error ' + error + ' uploading ' + t.name);
    textures[t.name] = tex;
  }
  for (const name of ['L0_validity', 'L1_r', 'L1_g', 'L1_b', 'L2_0', 'L2_1', 'L2_2', 'L2_3',
                      'offset_filled', 'visibility', 'sky_transfer'])
    bind('pb' + name, gl.TEXTURE_3D, textures[name] || textures.L0_validity);
  for (const [name, data] of [['queryPositions', positions], ['queryNormals', normals]]) {
    const tex = gl.createTexture();
    gl.activeTexture(scratchUnit);
    gl.bindTexture(gl.TEXTURE_2D, tex);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, n, 1, 0, gl.RGBA, gl.FLOAT, data);
    for (const p of [gl.TEXTURE_MIN_FILTER, gl.TEXTURE_MAG_FILTER]) gl.texParameteri(gl.TEXTURE_2D, p, gl.NEAREST);
    bind(name, gl.TEXTURE_2D, tex);
  }
  gl.uniform3fv(uniforms.pbGridOrigin.location, header.origin);
  gl.uniform3fv(uniforms.pbGridSpacing.location, header.spacing);
  gl.uniform3iv(uniforms.pbGridCounts.location, header.counts);
  gl.uniform1f(uniforms.pbL2Scale.location, header.l2Scale);
  setInt('pbHasOffsets', textures.offset_filled ? 1 : 0);
  const skyCoeffs = textures.sky_transfer ? (header.skyTransferOrder + 1) ** 2 : 0;
  if (skyCoeffs !== sky.length / 3) throw new Error('the sky has ' + sky.length / 3 + ' coefficients, the textures ' + skyCoeffs);
  setInt('pbSkyCoeffs', skyCoeffs);
  if (skyCoeffs) gl.uniform3fv(uniforms.pbSky.location, sky);
  const target = gl.createTexture();
  gl.activeTexture(scratchUnit);
  gl.bindTexture(gl.TEXTURE_2D, target);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, n, 2, 0, gl.RGBA, gl.FLOAT, null);
  const fb = gl.createFramebuffer();
  gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
  gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, target, 0);
  if (gl.checkFramebufferStatus(gl.FRAMEBUFFER) !== gl.FRAMEBUFFER_COMPLETE) throw new Error('framebuffer incomplete');
  const quad = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, quad);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 1, -1, -1, 1, 1, 1]), gl.STATIC_DRAW);
  const corner = gl.getAttribLocation(program, 'corner');
  gl.enableVertexAttribArray(corner);
  gl.vertexAttribPointer(corner, 2, gl.FLOAT, false, 0, 0);
  for (const row of [0, 1]) {
    setInt('pbHasVisibility', row === 0 && textures.visibility ? 1 : 0);
    gl.viewport(0, row, n, 1);
    gl.drawArrays(gl.TRIANGLE_STRIP, 0, 4);
  }
  const pixels = new Float32Array(4 * n * 2);
  gl.readPixels(0, 0, n, 2, gl.RGBA, gl.FLOAT, pixels);
  const error = gl.getError();
  if (error) throw new Error('GL error ' + error + ' drawing');
  out.textContent = JSON.stringify(Array.from(pixels));
} catch (e) {
  out.textContent = 'ERROR ' + e.message;
}
</script></body></html>
)");
}

// The <pre id="out"> text of the page after Chromium ran it.
std::string RunInChromium(const TempDir& dir, const std::string& html) {
  const std::string page = dir.File("include.html");
  std::ofstream(page) << html;
  std::string dom;
  EXPECT_EQ(
      RunCommand("chromium --headless=new --no-sandbox --disable-gpu --use-angle=swiftshader "
                 "--enable-unsafe-swiftshader --user-data-dir=" +
                     dir.File("chromium-profile") +
                     " --virtual-time-budget=20000 --dump-dom 'file://" + page + "' 2>/dev/null",
                 &dom),
      0);
  const size_t from = dom.find("<pre id=\"out\">"), to = dom.find("</pre>");
  if (from == std::string::npos || to == std::string::npos)
    return "no output in: " + dom.substr(0, 400);
  return dom.substr(from + 14, to - from - 14);
}

// An open scene under a sky baked with its sky transfer (Ls = 2): a floor, a box the sky and a
// point light cast shadows from, relocation and visibility on. Its textures hold the point
// light's radiance and T.
BakeJob OpenSceneWithSkyTransfer() {
  BakeJob job = MakeJob(2, 256, {-0.9, -0.9, 0.2});
  job.grid.counts[0] = 4;
  job.grid.counts[1] = 4;
  job.grid.counts[2] = 3;
  job.grid.spacing = {0.6, 0.6, 0.6};
  job.settings.batches = 4;
  job.settings.maxDepth = 4;
  job.settings.visibility = true;
  job.settings.relocationMaxOffset = 0.4;
  job.settings.skyTransferOrder = 2;
  const uint32_t grey = AddMaterial(&job.scene, {0.6, 0.6, 0.6});
  const uint32_t red = AddMaterial(&job.scene, {0.7, 0.2, 0.1});
  AddQuad(&job.scene, {-2, -2, 0}, {2, -2, 0}, {2, 2, 0}, {-2, 2, 0}, grey);
  // A box whose face x = -0.3 holds a probe layer 2 cm inside it (grid x = -0.3).
  AddBox(&job.scene, {-0.32, -0.4, 0}, {0.4, 0.5, 0.9}, red, /*inward=*/false);
  job.scene.lights.push_back(PointLight{{0.8, -0.8, 1.4}, {2, 2, 2}});
  job.scene.environment = {Environment::Kind::kUniform, {0.3, 0.4, 0.6}, nullptr};
  return job;
}

// Random points over the open scene's floor and in its air, outside the box, random normals.
std::vector<Query> OpenSceneQueries() {
  std::vector<Query> out;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  while (out.size() < 512) {
    const bool floor = out.size() < 128;
    const Vec3d x{-1.2 + 2.4 * u(rng), -1.2 + 2.4 * u(rng), floor ? 0.0 : 1.6 * u(rng)};
    if (x.x > -0.33 && x.x < 0.41 && x.y > -0.41 && x.y < 0.51 && x.z < 0.91) continue;
    Vec3d n = RandomDirection(rng);
    if (floor) n = {0, 0, 1};
    out.push_back({ToFloats(x), ToFloats(n)});
  }
  return out;
}

// A sky to relight with (order 2): a blue ambient and a warm lobe from low in the west.
std::vector<Vec3d> RelightSky() {
  double lobe[9];
  HenyeyGreensteinLobe(2, 0.6, Normalize(Vec3d{-0.8, 0.2, 0.35}), lobe);
  std::vector<Vec3d> sky(9);
  for (int k = 0; k < 9; ++k) sky[size_t(k)] = Vec3d{3.0, 1.8, 0.9} * lobe[k];
  sky[0] += Vec3d{0.2, 0.3, 0.5} * (2 * std::sqrt(std::numbers::pi));
  return sky;
}

// The two scenes' textures, baked once for both includes.
class ShaderInclude : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // The leak scene with layers 2 cm into the wall: relocation moves them out (offsets), the
    // probes that cannot move are filled by dilation, and the wall splits the cells the queries
    // near it sit in.
    BakeJob leak = TwoRoomsWithThinWall(-1.98);
    leak.settings.samplesPerProbe = 256;
    leak_ = Pack(BakeOrDie(leak));
    // Layers 6 cm behind the wall and 40 cm before it at 128 samples (two rays a texel, some
    // texels empty): points between the wall and the near layer, which Chebyshev alone leaves to
    // the probes beyond the wall, are decided by the cell's connectivity.
    BakeJob near = TwoRoomsWithThinWall(-1.9);
    near.settings.samplesPerProbe = 128;
    near_ = Pack(BakeOrDie(near));
    open_ = Pack(BakeOrDie(OpenSceneWithSkyTransfer()));
  }
  static void TearDownTestSuite() {
    delete leak_;
    delete near_;
    delete open_;
    leak_ = near_ = open_ = nullptr;
  }
  static ProbeTextures* Pack(const ProbeVolume& volume) {
    absl::StatusOr<ProbeTextures> textures = PackProbeTextures(volume, "x.bin");
    EXPECT_TRUE(textures.ok()) << textures.status();
    return textures.ok() ? new ProbeTextures(*std::move(textures)) : nullptr;
  }

  // Runs `fragment` on the queries in Chromium and compares with the core sampler on the
  // volume decoded from the textures (relit by the core for `sky` when it has a sky transfer),
  // visibility on and off.
  void ExpectMatchesTheCore(const std::string& language, const std::string& fragment,
                            const ProbeTextures* packed, const std::vector<Query>& queries,
                            const std::vector<Vec3d>& sky, bool offsets = true) {
    ASSERT_TRUE(HaveProgram("chromium"))
        << "chromium is missing: run scripts/install-deps.sh (Debian's chromium package)";
    ASSERT_NE(packed, nullptr);
    ASSERT_FALSE(fragment.empty());
    const ProbeVolume decoded = DecodeTextures(*packed);
    ASSERT_FALSE(decoded.offset.empty());
    ASSERT_FALSE(decoded.visibility.empty());
    int moved = 0;
    for (size_t p = 0; p < decoded.filled.size(); ++p)
      moved += decoded.offset[3 * p] != 0 || decoded.offset[3 * p + 1] != 0 ||
               decoded.offset[3 * p + 2] != 0;
    if (offsets) {
      EXPECT_GT(moved, 0) << "the scene must move probes for the offsets to be tested";
    }
    ASSERT_EQ(decoded.skyTransferOrder > 0, !sky.empty());

    // What the shader blends, and the size of its terms: |local| + sum |T| |sky| per coefficient.
    ProbeVolume volume = decoded, magnitudes = decoded;
    if (!sky.empty()) {
      absl::StatusOr<ProbeVolume> relit = Relight(decoded, sky);
      ASSERT_TRUE(relit.ok()) << relit.status();
      volume = *std::move(relit);
      const size_t columns = size_t(decoded.SkyCoeffCount());
      for (size_t r = 0; r < 9; ++r)
        for (size_t v = 0; v < magnitudes.radiance[r].size(); ++v) {
          double sum = std::abs(decoded.radiance[r][v]);
          for (size_t c = 0; c < columns; ++c)
            sum += std::abs(decoded.skyTransfer[r * columns + c][v] * sky[c][int(v % 3)]);
          magnitudes.radiance[r][v] = float(sum);
        }
    }

    const std::string text = RunInChromium(dir_, Page(*packed, fragment, queries, sky));
    ASSERT_EQ(text.rfind("[", 0), 0u) << text;
    const google::protobuf::Struct parsed = ParseJson("{\"v\":" + text + "}");
    const auto& values = parsed.fields().at("v").list_value();
    const size_t n = queries.size();
    ASSERT_EQ(size_t(values.values_size()), 8 * n);
    for (int row = 0; row < 2; ++row) {
      ProbeSamplerOptions options;
      options.visibility = row == 0;
      const ProbeSampler sampler(volume, options);
      double worst = 0;
      for (size_t i = 0; i < n; ++i) {
        const ProbeSample want = sampler.Sample(queries[i].position, queries[i].normal);
        const size_t at = 4 * (size_t(row) * n + i);
        EXPECT_EQ(values.values(int(at + 3)).number_value(), want.probes)
            << "query " << i << " at (" << queries[i].position.x << ", " << queries[i].position.y
            << ", " << queries[i].position.z << ")";
        const double magnitude = CellMagnitude(magnitudes, queries[i]);
        for (int ch = 0; ch < 3; ++ch) {
          const double got = values.values(int(at) + ch).number_value();
          const double relative = std::abs(got - want.irradiance[ch]) / std::max(magnitude, 1e-30);
          worst = std::max(worst, relative);
          EXPECT_LE(relative, row ? kTolerance : kVisibilityTolerance)
              << language << ", query " << i << " at (" << queries[i].position.x << ", "
              << queries[i].position.y << ", " << queries[i].position.z << ") channel " << ch
              << ": shader " << got << ", core " << want.irradiance[ch]
              << (row ? " (no visibility)" : "");
        }
      }
      std::printf("%s vs core, %zu queries%s%s: worst |difference| / magnitude %.3g\n",
                  language.c_str(), n, sky.empty() ? "" : ", relit",
                  row ? " without visibility" : " with visibility", worst);
    }
  }

  static ProbeTextures* leak_;
  static ProbeTextures* near_;
  static ProbeTextures* open_;
  TempDir dir_;
};
ProbeTextures* ShaderInclude::leak_ = nullptr;
ProbeTextures* ShaderInclude::near_ = nullptr;
ProbeTextures* ShaderInclude::open_ = nullptr;

bool HaveHlslTools() {
  return HaveProgram("glslangValidator") && HaveProgram("spirv-cross");
}
constexpr char kNoHlslTools[] =
    "glslang-tools or spirv-cross is missing: run scripts/install-deps.sh";

// The leak queries and up to 256 points where the connectivity matters (the test asserts there
// are at least 128, so that it compares the include's connectivity with the core's).
std::vector<Query> LeakAndConnectivityQueries(const ProbeTextures* packed) {
  std::vector<Query> queries = LeakQueries();
  if (packed == nullptr) return queries;
  const std::vector<Query> cut = ConnectivityQueries(*packed, 256);
  EXPECT_GE(cut.size(), 128u) << "too few points where the connectivity matters";
  queries.insert(queries.end(), cut.begin(), cut.end());
  return queries;
}

TEST_F(ShaderInclude, GlslMatchesTheCoreSamplerOnTheLeakScene) {
  ExpectMatchesTheCore("GLSL", GlslFragment(), leak_, LeakAndConnectivityQueries(leak_), {});
}

TEST_F(ShaderInclude, GlslMatchesTheCoreSamplerBesideAThinWall) {
  ExpectMatchesTheCore("GLSL", GlslFragment(), near_, LeakAndConnectivityQueries(near_), {},
                       /*offsets=*/false);
}

TEST_F(ShaderInclude, HlslMatchesTheCoreSamplerOnTheLeakScene) {
  ASSERT_TRUE(HaveHlslTools()) << kNoHlslTools;
  ExpectMatchesTheCore("HLSL", HlslFragment(dir_), leak_, LeakAndConnectivityQueries(leak_), {});
}

TEST_F(ShaderInclude, HlslMatchesTheCoreSamplerBesideAThinWall) {
  ASSERT_TRUE(HaveHlslTools()) << kNoHlslTools;
  ExpectMatchesTheCore("HLSL", HlslFragment(dir_), near_, LeakAndConnectivityQueries(near_), {},
                       /*offsets=*/false);
}

TEST_F(ShaderInclude, GlslRelightsAsTheCoreDoes) {
  ExpectMatchesTheCore("GLSL", GlslFragment(), open_, OpenSceneQueries(), RelightSky());
}

TEST_F(ShaderInclude, HlslRelightsAsTheCoreDoes) {
  ASSERT_TRUE(HaveHlslTools()) << kNoHlslTools;
  ExpectMatchesTheCore("HLSL", HlslFragment(dir_), open_, OpenSceneQueries(), RelightSky());
}

}  // namespace
}  // namespace probebake::testing
