// probebake probe textures (`probebake export VOLUME --format textures`, docs/engines.md) sampled
// in HLSL (SM 4.0+) with the weights of probebake's reference sampler: the same maths as
// probebake_probes.glsl, line by line (see there for the weights). probebake's tests compile it
// with glslang and run it, cross-compiled by SPIRV-Cross, in WebGL against the core sampler.
// Points and normals in probebake's frame (right-handed, Z up): from Unity,
// pb = float3(p.x, p.z, p.y). Set pbHasOffsets / pbHasVisibility when the header lists
// `offset_filled` / `visibility`; bind some 3D texture to those slots when it does not. To relight
// a volume baked with a sky transfer, set pbSkyCoeffs = (Ls + 1)^2 and pbSky (see the GLSL).
#ifndef PROBEBAKE_PROBES_HLSL
#define PROBEBAKE_PROBES_HLSL

Texture3D<float4> pbL0_validity;    // RGBA16F (L0.rgb, usable)
Texture3D<float4> pbL1_r;           // RGBA16F (c1, c2, c3, 0) of red
Texture3D<float4> pbL1_g;
Texture3D<float4> pbL1_b;
Texture3D<float4> pbL2_0;           // RGBA8 UNORM: c4..c8 of r, g, b, 4 per texel
Texture3D<float4> pbL2_1;
Texture3D<float4> pbL2_2;
Texture3D<float4> pbL2_3;
Texture3D<float4> pboffset_filled;  // RGBA16F (offset xyz in scene units, filled)
Texture3D<float4> pbvisibility;     // RGBA32F atlas 8nx x 8ny x nz: (mean 1/t, mean 1/t^2)
float3 pbGridOrigin;
float3 pbGridSpacing;
int3 pbGridCounts;
float pbL2Scale;
bool pbHasOffsets;
bool pbHasVisibility;

#ifndef PB_MAX_SKY_COEFFS
#define PB_MAX_SKY_COEFFS 25
#endif
Texture3D<float4> pbsky_transfer;  // RGBA16F atlas S nx x 9 ny x nz: T[r][s].rgb
int pbSkyCoeffs;                   // (Ls + 1)^2 to relight, else 0
float3 pbSky[PB_MAX_SKY_COEFFS];   // the sky's radiance SH (probebake's basis and frame)

#ifndef PB_NORMAL_BIAS
#define PB_NORMAL_BIAS 0.01
#endif
static const int pbVisSize = 8;
static const float pbCrush = 0.2;
static const float pbMinWeight = 1e-30;
static const float pbMinRelativeVariance = 6e-3;

void pbProbeSh(int3 p, out float3 c[9]) {
  c[0] = pbL0_validity.Load(int4(p, 0)).rgb;
  float3 r = pbL1_r.Load(int4(p, 0)).xyz, g = pbL1_g.Load(int4(p, 0)).xyz,
         b = pbL1_b.Load(int4(p, 0)).xyz;
  c[1] = float3(r.x, g.x, b.x);
  c[2] = float3(r.y, g.y, b.y);
  c[3] = float3(r.z, g.z, b.z);
  float4 t[4] = {pbL2_0.Load(int4(p, 0)), pbL2_1.Load(int4(p, 0)), pbL2_2.Load(int4(p, 0)),
                 pbL2_3.Load(int4(p, 0))};
  float l2[16];
  [unroll] for (int i = 0; i < 15; i++) l2[i] = (round(t[i / 4][i % 4] * 255.0) - 128.0) / 127.0 * pbL2Scale;
  [unroll] for (int k = 0; k < 5; k++) c[4 + k] = float3(l2[k], l2[5 + k], l2[10 + k]);
  for (int row = 0; row < 9; row++)
    for (int col = 0; col < pbSkyCoeffs; col++)
      c[row] += pbsky_transfer.Load(int4(pbSkyCoeffs * p.x + col, 9 * p.y + row, p.z, 0)).rgb *
                pbSky[col];
}

float3 pbShIrradiance(float3 c[9], float3 n) {
  const float A0 = 3.14159265358979, A1 = 2.09439510239320, A2 = 0.785398163397448;
  float x = n.x, y = n.y, z = n.z;
  return A0 * 0.282094792 * c[0] +
         A1 * 0.488602512 * (-y * c[1] + z * c[2] - x * c[3]) +
         A2 * (1.092548431 * (x * y * c[4] - y * z * c[5] - x * z * c[7]) +
               0.946174696 * (z * z - 1.0 / 3.0) * c[6] + 0.546274215 * (x * x - y * y) * c[8]);
}

float pbSignNotZero(float v) {
  return v >= 0.0 ? 1.0 : -1.0;
}

float2 pbOctahedralEncode(float3 w) {
  float2 uv = w.xy / (abs(w.x) + abs(w.y) + abs(w.z));
  if (w.z < 0.0)
    uv = float2((1.0 - abs(uv.y)) * pbSignNotZero(uv.x), (1.0 - abs(uv.x)) * pbSignNotZero(uv.y));
  return uv;
}

float3 pbOctahedralDecode(float2 uv) {
  float3 w = float3(uv, 1.0 - abs(uv.x) - abs(uv.y));
  if (w.z < 0.0)
    w.xy = float2((1.0 - abs(uv.y)) * pbSignNotZero(uv.x), (1.0 - abs(uv.x)) * pbSignNotZero(uv.y));
  return normalize(w);
}

int2 pbWrappedTexel(int2 t) {
  if (t.x < 0 || t.x >= pbVisSize) {
    t.x = t.x < 0 ? 0 : pbVisSize - 1;
    t.y = pbVisSize - 1 - t.y;
  }
  if (t.y < 0 || t.y >= pbVisSize) {
    t.y = t.y < 0 ? 0 : pbVisSize - 1;
    t.x = pbVisSize - 1 - t.x;
  }
  return t;
}

bool pbVisibilityMoments(int3 probe, float3 w, out float mean, out float variance) {
  float2 f = (pbOctahedralEncode(w) + 1.0) * 0.5 * float(pbVisSize) - 0.5;
  int2 ij = int2(floor(f));
  float2 ab = f - float2(ij);
  bool wrapped = ij.x < 0 || ij.y < 0 || ij.x + 1 >= pbVisSize || ij.y + 1 >= pbVisSize;
  float q[4], tap[4], weight[4], scale[4];
  float4 m[4];
  float total = 0.0;
  [unroll] for (int k = 0; k < 4; k++) {
    int2 o = int2(k & 1, k >> 1);
    int2 t = pbWrappedTexel(ij + o);
    float3 centre = pbOctahedralDecode((float2(t) + 0.5) / float(pbVisSize) * 2.0 - 1.0);
    scale[k] = wrapped ? 1.0 : 1.0 / (abs(centre.x) + abs(centre.y) + abs(centre.z));
    m[k] = pbvisibility.Load(int4(pbVisSize * probe.xy + t, probe.z, 0));
    tap[k] = (o.x == 1 ? ab.x : 1.0 - ab.x) * (o.y == 1 ? ab.y : 1.0 - ab.y);
    weight[k] = m[k].z > 0.0 ? tap[k] : 0.0;
    total += weight[k];
  }
  mean = 0.0;
  variance = 0.0;
  if (!(total > 0.0)) return false;
  [unroll] for (int k2 = 0; k2 < 4; k2++) {
    q[k2] = scale[k2] * m[k2].x;
    weight[k2] /= total;
    mean += weight[k2] * q[k2];
    variance += weight[k2] * scale[k2] * scale[k2] * max(m[k2].y - m[k2].x * m[k2].x, 0.0);
  }
  [unroll] for (int k3 = 0; k3 < 4; k3++)
    if (weight[k3] == 0.0) q[k3] = mean;
  float wu = tap[1] + tap[3], wv = tap[2] + tap[3];
  float gu = (q[1] - q[0]) * (1.0 - wv) + (q[3] - q[2]) * wv;
  float gv = (q[2] - q[0]) * (1.0 - wu) + (q[3] - q[1]) * wu;
  variance = max(variance - (gu * gu + gv * gv) / 12.0, pbMinRelativeVariance * mean * mean);
  float l1 = wrapped ? 1.0 : abs(w.x) + abs(w.y) + abs(w.z);
  mean *= l1;
  variance *= l1 * l1;
  return true;
}

float pbChebyshev(float mean, float variance, float d) {
  float s = 1.0 / d;
  if (s >= mean) return 1.0;
  float excess = mean - s;
  float p = variance / (variance + excess * excess);
  return p * p * p;
}

float pbProbeVisibility(int3 probe, float3 probePos, float3 x) {
  float3 fromProbe = x - probePos;
  float d = length(fromProbe);
  if (!(d > 0.0)) return 1.0;
  float mean, variance;
  if (!pbVisibilityMoments(probe, fromProbe / d, mean, variance)) return 1.0;
  return pbChebyshev(mean, variance, d);
}

int pbBlendSh(float3 x, float3 n, out float3 c[9]) {
  n = normalize(n);
  float3 biased =
      x + n * (PB_NORMAL_BIAS * min(pbGridSpacing.x, min(pbGridSpacing.y, pbGridSpacing.z)));
  float3 g = clamp((x - pbGridOrigin) / pbGridSpacing, 0.0, float3(pbGridCounts - 1));
  int3 i0 = min(int3(floor(g)), max(pbGridCounts - 2, int3(0, 0, 0)));
  float3 f = saturate(g - float3(i0));
  bool usable[8];
  int3 probe[8];
  float3 probePos[8];
  float tri[8], seen[8];
  [unroll] for (int corner = 0; corner < 8; corner++) {
    int3 o = int3(corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
    probe[corner] = min(i0 + o, pbGridCounts - 1);
    float3 wv = lerp(1.0 - f, f, float3(o));
    tri[corner] = wv.x * wv.y * wv.z;
    usable[corner] = pbL0_validity.Load(int4(probe[corner], 0)).a >= 0.5;
    probePos[corner] = pbGridOrigin + float3(probe[corner]) * pbGridSpacing;
    if (pbHasOffsets) probePos[corner] += pboffset_filled.Load(int4(probe[corner], 0)).xyz;
    seen[corner] = 1.0;
    if (pbHasVisibility && usable[corner] && tri[corner] > 0.0)
      seen[corner] = min(pbProbeVisibility(probe[corner], probePos[corner], biased),
                         pbProbeVisibility(probe[corner], probePos[corner], x));
  }
  float connected[8];
  [unroll] for (int i1 = 0; i1 < 8; i1++) connected[i1] = 1.0;
  if (pbHasVisibility) {
    bool known[24];
    float tMean[24], tVar[24], tLen[24];
    [unroll] for (int i0 = 0; i0 < 8; i0++) {
      [unroll] for (int a0 = 0; a0 < 3; a0++) {
        int j0 = i0 ^ (1 << a0);
        int k0 = 3 * i0 + a0;
        known[k0] = false;
        tLen[k0] = 0.0;
        tMean[k0] = 0.0;
        tVar[k0] = 0.0;
        if (!usable[i0] || !usable[j0]) continue;
        float3 along0 = probePos[j0] - probePos[i0];
        tLen[k0] = length(along0);
        if (tLen[k0] > 0.0) {
          float mean0, variance0;
          known[k0] = pbVisibilityMoments(probe[i0], along0 / tLen[k0], mean0, variance0);
          tMean[k0] = mean0;
          tVar[k0] = variance0;
        }
      }
    }
    float b[64], edge[24], claim[8];
    [unroll] for (int i2 = 0; i2 < 64; i2++) b[i2] = i2 / 8 == i2 % 8 ? 1.0 : 0.0;
    [unroll] for (int i3 = 0; i3 < 8; i3++) {
      [unroll] for (int a = 0; a < 3; a++) {
        int j = i3 ^ (1 << a);
        edge[3 * i3 + a] = 0.0;
        if (!usable[i3] || !usable[j]) continue;
        int kij = 3 * i3 + a, kji = 3 * j + a;
        float ij = known[kij] ? pbChebyshev(tMean[kij], tVar[kij], tLen[kij]) : 1.0;
        float ji = known[kji] ? pbChebyshev(tMean[kji], tVar[kji], tLen[kji]) : 1.0;
        edge[kij] = min(ij, ji);
        b[8 * i3 + j] = edge[kij];
      }
    }
    [loop] for (int m = 0; m < 8; m++)
      [loop] for (int i4 = 0; i4 < 8; i4++)
        [unroll] for (int j4 = 0; j4 < 8; j4++)
          b[8 * i4 + j4] = max(b[8 * i4 + j4], min(b[8 * i4 + m], b[8 * m + j4]));
    [unroll] for (int i7 = 0; i7 < 8; i7++) {
      claim[i7] = 1.0;
      [unroll] for (int a7 = 0; a7 < 3; a7++) {
        int k7 = 3 * i7 + a7;
        if (!known[k7] || !(tMean[k7] > 0.0)) continue;
        float3 along = probePos[i7 ^ (1 << a7)] - probePos[i7];
        float beyond = dot(x - probePos[i7], along) / tLen[k7] - 1.0 / tMean[k7];
        float step = clamp(0.5 - beyond / (0.01 * tLen[k7]), 0.0, 1.0);
        claim[i7] *= 1.0 - (1.0 - edge[k7]) * (1.0 - step);
      }
    }
    float support[8];
    float most = 0.0;
    [loop] for (int pass = 0; pass < 2; pass++) {
      [unroll] for (int i5 = 0; i5 < 8; i5++) {
        support[i5] = 0.0;
        [unroll] for (int j5 = 0; j5 < 8; j5++)
          if (usable[j5] && tri[j5] > 0.0)
            support[i5] += (pass == 1 ? seen[j5] : claim[j5]) * b[8 * i5 + j5];
        if (usable[i5] && tri[i5] > 0.0) most = max(most, support[i5]);
      }
      if (most > 0.0) break;
    }
    if (most > 0.0) {
      [unroll] for (int i6 = 0; i6 < 8; i6++) {
        float r = support[i6] / most;
        float r2 = r * r, r4 = r2 * r2;
        connected[i6] = r4 * r4;
      }
    }
  }
  float v[8];
  float vmax = 0.0;
  [unroll] for (int corner1 = 0; corner1 < 8; corner1++) {
    v[corner1] = 0.0;
    if (tri[corner1] <= 0.0 || !usable[corner1]) continue;
    float3 toProbe = probePos[corner1] - x;
    float len = length(toProbe);
    float h = ((len > 0.0 ? dot(toProbe / len, n) : 1.0) + 1.0) * 0.5;
    float w = h * h + 0.2;
    if (pbHasVisibility) w = max(w * min(seen[corner1], connected[corner1]), pbMinWeight);
    v[corner1] = w;
    vmax = max(vmax, w);
  }
  [unroll] for (int k = 0; k < 9; k++) c[k] = float3(0.0, 0.0, 0.0);
  float total = 0.0;
  int probes = 0;
  [unroll] for (int corner2 = 0; corner2 < 8; corner2++) {
    if (v[corner2] <= 0.0) continue;
    float w = v[corner2];
    if (pbHasVisibility && vmax < pbCrush) {
      float r = w / vmax;
      w = r * r * r;
    } else if (pbHasVisibility && w < pbCrush) {
      w *= w * w / (pbCrush * pbCrush);
    }
    w *= tri[corner2];
    float3 p[9];
    pbProbeSh(probe[corner2], p);
    [unroll] for (int k2 = 0; k2 < 9; k2++) c[k2] += w * p[k2];
    total += w;
    probes++;
  }
  if (total > 0.0)
    [unroll] for (int k3 = 0; k3 < 9; k3++) c[k3] /= total;
  return probes;
}

float4 pbIrradiance(float3 x, float3 n) {
  float3 c[9];
  int probes = pbBlendSh(x, n, c);
  return float4(pbShIrradiance(c, normalize(n)), float(probes));
}

#endif  // PROBEBAKE_PROBES_HLSL
