// probebake probe textures (`probebake export VOLUME --format textures`, docs/engines.md) sampled
// in GLSL (ES 3.00 / 3.30 and later). Irradiance at a world point and normal: the 8 grid probes
// around the point blended trilinearly, probes whose validity alpha is < 0.5 skipped and the
// weights renormalised (the weights of the core's slices), each probe's irradiance
// E(n) = sum_l A_l sum_m L_lm Y_lm(n) with probebake's SH basis (Condon-Shortley signs, +Z polar).
//
// Points and normals are in probebake's frame (right-handed, Z up); map yours first, e.g. from
// three.js: pb = vec3(p.x, -p.z, p.y); from Unity: pb = vec3(p.x, p.z, p.y).
// Bind the eight textures with NEAREST filtering (texelFetch reads texels exactly) and set the
// uniforms from the header: counts, origin, spacing, l2Scale. Texture uniforms are named "pb"
// followed by the header's texture name.
#ifndef PROBEBAKE_PROBES_GLSL
#define PROBEBAKE_PROBES_GLSL

uniform highp sampler3D pbL0_validity;  // RGBA16F (L0.rgb, usable)
uniform highp sampler3D pbL1_r;         // RGBA16F (c1, c2, c3, 0) of red
uniform highp sampler3D pbL1_g;
uniform highp sampler3D pbL1_b;
uniform highp sampler3D pbL2_0;        // RGBA8: c4..c8 of r, g, b, 4 per texel
uniform highp sampler3D pbL2_1;
uniform highp sampler3D pbL2_2;
uniform highp sampler3D pbL2_3;
uniform vec3 pbGridOrigin;
uniform vec3 pbGridSpacing;
uniform ivec3 pbGridCounts;
uniform float pbL2Scale;

// The 9 RGB radiance coefficients of probe p.
void pbProbeSh(ivec3 p, out vec3 c[9]) {
  c[0] = texelFetch(pbL0_validity, p, 0).rgb;
  vec3 r = texelFetch(pbL1_r, p, 0).xyz, g = texelFetch(pbL1_g, p, 0).xyz,
       b = texelFetch(pbL1_b, p, 0).xyz;
  c[1] = vec3(r.x, g.x, b.x);
  c[2] = vec3(r.y, g.y, b.y);
  c[3] = vec3(r.z, g.z, b.z);
  // v = (q / 255 - 0.5) * 2 * l2Scale; texelFetch of RGBA8 gives q / 255.
  float l2[16];
  vec4 t0 = texelFetch(pbL2_0, p, 0), t1 = texelFetch(pbL2_1, p, 0),
       t2 = texelFetch(pbL2_2, p, 0), t3 = texelFetch(pbL2_3, p, 0);
  vec4 t[4] = vec4[4](t0, t1, t2, t3);
  for (int i = 0; i < 15; i++) l2[i] = (t[i / 4][i % 4] - 0.5) * 2.0 * pbL2Scale;
  for (int k = 0; k < 5; k++) c[4 + k] = vec3(l2[k], l2[5 + k], l2[10 + k]);
}

// E(n) of one probe's coefficients, n a unit normal in probebake's frame.
vec3 pbShIrradiance(vec3 c[9], vec3 n) {
  const float A0 = 3.14159265358979, A1 = 2.09439510239320, A2 = 0.785398163397448;
  float x = n.x, y = n.y, z = n.z;
  return A0 * 0.282094792 * c[0] +
         A1 * 0.488602512 * (-y * c[1] + z * c[2] - x * c[3]) +
         A2 * (1.092548431 * (x * y * c[4] - y * z * c[5] - x * z * c[7]) +
               0.946174696 * (z * z - 1.0 / 3.0) * c[6] + 0.546274215 * (x * x - y * y) * c[8]);
}

// Irradiance at world point p with unit normal n (probebake's frame); .w is the weight of the
// valid probes found (0: none, .rgb is then 0).
vec4 pbIrradiance(vec3 p, vec3 n) {
  vec3 g = clamp((p - pbGridOrigin) / pbGridSpacing, vec3(0.0), vec3(pbGridCounts - 1));
  ivec3 i0 = min(ivec3(floor(g)), max(pbGridCounts - 2, ivec3(0)));
  vec3 f = clamp(g - vec3(i0), 0.0, 1.0);
  vec3 sum = vec3(0.0);
  float wsum = 0.0;
  for (int corner = 0; corner < 8; corner++) {
    ivec3 o = ivec3(corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
    ivec3 q = min(i0 + o, pbGridCounts - 1);
    vec3 wv = mix(1.0 - f, f, vec3(o));
    float w = wv.x * wv.y * wv.z;
    if (w <= 0.0 || texelFetch(pbL0_validity, q, 0).a < 0.5) continue;
    vec3 c[9];
    pbProbeSh(q, c);
    sum += w * pbShIrradiance(c, n);
    wsum += w;
  }
  return vec4(wsum > 0.0 ? sum / wsum : vec3(0.0), wsum);
}

#endif  // PROBEBAKE_PROBES_GLSL
