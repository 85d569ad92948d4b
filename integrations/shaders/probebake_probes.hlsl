// probebake probe textures (`probebake export VOLUME --format textures`, docs/engines.md) sampled
// in HLSL (SM 4.0+): the same maths as probebake_probes.glsl, which the viewer's test runs
// against the core; this file is its line-by-line translation (not compiled in probebake's CI).
// Points and normals in probebake's frame (right-handed, Z up): from Unity,
// pb = float3(p.x, p.z, p.y).
#ifndef PROBEBAKE_PROBES_HLSL
#define PROBEBAKE_PROBES_HLSL

Texture3D<float4> pbL0_validity;  // RGBA16F (L0.rgb, usable)
Texture3D<float4> pbL1_r;         // RGBA16F (c1, c2, c3, 0) of red
Texture3D<float4> pbL1_g;
Texture3D<float4> pbL1_b;
Texture3D<float4> pbL2_0;        // RGBA8 UNORM: c4..c8 of r, g, b, 4 per texel
Texture3D<float4> pbL2_1;
Texture3D<float4> pbL2_2;
Texture3D<float4> pbL2_3;
float3 pbGridOrigin;
float3 pbGridSpacing;
int3 pbGridCounts;
float pbL2Scale;

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
  [unroll] for (int i = 0; i < 15; i++) l2[i] = (t[i / 4][i % 4] - 0.5) * 2.0 * pbL2Scale;
  [unroll] for (int k = 0; k < 5; k++) c[4 + k] = float3(l2[k], l2[5 + k], l2[10 + k]);
}

float3 pbShIrradiance(float3 c[9], float3 n) {
  const float A0 = 3.14159265358979, A1 = 2.09439510239320, A2 = 0.785398163397448;
  float x = n.x, y = n.y, z = n.z;
  return A0 * 0.282094792 * c[0] +
         A1 * 0.488602512 * (-y * c[1] + z * c[2] - x * c[3]) +
         A2 * (1.092548431 * (x * y * c[4] - y * z * c[5] - x * z * c[7]) +
               0.946174696 * (z * z - 1.0 / 3.0) * c[6] + 0.546274215 * (x * x - y * y) * c[8]);
}

float4 pbIrradiance(float3 p, float3 n) {
  float3 g = clamp((p - pbGridOrigin) / pbGridSpacing, 0.0, float3(pbGridCounts - 1));
  int3 i0 = min(int3(floor(g)), max(pbGridCounts - 2, int3(0, 0, 0)));
  float3 f = saturate(g - float3(i0));
  float3 sum = 0.0;
  float wsum = 0.0;
  [unroll] for (int corner = 0; corner < 8; corner++) {
    int3 o = int3(corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
    int3 q = min(i0 + o, pbGridCounts - 1);
    float3 wv = lerp(1.0 - f, f, float3(o));
    float w = wv.x * wv.y * wv.z;
    if (w <= 0.0 || pbL0_validity.Load(int4(q, 0)).a < 0.5) continue;
    float3 c[9];
    pbProbeSh(q, c);
    sum += w * pbShIrradiance(c, n);
    wsum += w;
  }
  return float4(wsum > 0.0 ? sum / wsum : float3(0.0, 0.0, 0.0), wsum);
}

#endif  // PROBEBAKE_PROBES_HLSL
