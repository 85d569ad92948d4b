// probebake probe textures (`probebake export VOLUME --format textures`, docs/engines.md) sampled
// in GLSL (ES 3.00 / 3.30 and later) with the weights of probebake's reference sampler
// (ProbeSampler, core/include/probebake/volume/probe_sampler.h): for a point x with unit normal n,
// each of the 8 grid probes around x that holds light (alpha >= 0.5) weighs
//   trilinear(x) * backface * visibility,
// backface = ((dot(dir to the probe, n) + 1) / 2)^2 + 0.2 (the probe where it was baked: grid
// point + offset), visibility = the smaller of Chebyshev's bound from the probe's moments of 1/t
// (itself the smaller of its values at x + n * bias and at x) and the probe's connectivity
// (pbBlendSh: whether the probes it is connected to have x on their side of what blocks the
// cell's edges), weights below 0.2 crushed to w^3 / 0.2^2; the blend is normalised.
// Without the offset texture probes sit at their grid points; without the visibility
// atlas the weight is trilinear * backface. E(n) = sum_l A_l sum_m L_lm Y_lm(n) with probebake's
// SH basis (Condon-Shortley signs, +Z polar).
//
// Points and normals are in probebake's frame (right-handed, Z up); map yours first, e.g. from
// three.js: pb = vec3(p.x, -p.z, p.y); from Unity: pb = vec3(p.x, p.z, p.y).
// Bind the textures with NEAREST filtering (texelFetch reads texels exactly) and set the uniforms
// from the header: counts, origin, spacing, l2Scale, and pbHasOffsets / pbHasVisibility when the
// header lists `offset_filled` / `visibility`, and the sky (below) to relight a volume baked with
// a sky transfer. Texture uniforms are named "pb" followed by the header's texture name. Declare
// float and sampler3D precision highp before including.
#ifndef PROBEBAKE_PROBES_GLSL
#define PROBEBAKE_PROBES_GLSL

uniform highp sampler3D pbL0_validity;    // RGBA16F (L0.rgb, usable)
uniform highp sampler3D pbL1_r;           // RGBA16F (c1, c2, c3, 0) of red
uniform highp sampler3D pbL1_g;
uniform highp sampler3D pbL1_b;
uniform highp sampler3D pbL2_0;           // RGBA8: c4..c8 of r, g, b, 4 per texel
uniform highp sampler3D pbL2_1;
uniform highp sampler3D pbL2_2;
uniform highp sampler3D pbL2_3;
uniform highp sampler3D pboffset_filled;  // RGBA16F (offset xyz in scene units, filled)
uniform highp sampler3D pbvisibility;     // RGBA32F atlas 8nx x 8ny x nz: (mean 1/t, mean 1/t^2)
uniform vec3 pbGridOrigin;
uniform vec3 pbGridSpacing;
uniform ivec3 pbGridCounts;
uniform float pbL2Scale;
uniform bool pbHasOffsets;     // the header lists offset_filled
uniform bool pbHasVisibility;  // the header lists visibility

// Relighting (a volume baked with a sky transfer, header skyTransferOrder Ls > 0): the textures'
// coefficients are the local lights, and each probe adds T times the sky's SH. Set pbSkyCoeffs to
// (Ls + 1)^2 and pbSky to the sky's radiance SH coefficients (probebake's basis and frame,
// docs/engines.md); 0 leaves the local lights alone.
#ifndef PB_MAX_SKY_COEFFS
#define PB_MAX_SKY_COEFFS 25
#endif
uniform highp sampler3D pbsky_transfer;  // RGBA16F atlas S nx x 9 ny x nz: T[r][s].rgb
uniform int pbSkyCoeffs;
uniform vec3 pbSky[PB_MAX_SKY_COEFFS];

// The normal bias as a fraction of the smallest spacing (the core's ProbeSamplerOptions default).
#ifndef PB_NORMAL_BIAS
#define PB_NORMAL_BIAS 0.01
#endif
const int pbVisSize = 8;        // octahedral texels per side of a probe's visibility map
const float pbCrush = 0.2;      // DDGI's crushing threshold
const float pbMinWeight = 1e-30;
const float pbMinRelativeVariance = 6e-3;

// The 9 RGB radiance coefficients of probe p (relit when pbSkyCoeffs > 0).
void pbProbeSh(ivec3 p, out vec3 c[9]) {
  c[0] = texelFetch(pbL0_validity, p, 0).rgb;
  vec3 r = texelFetch(pbL1_r, p, 0).xyz, g = texelFetch(pbL1_g, p, 0).xyz,
       b = texelFetch(pbL1_b, p, 0).xyz;
  c[1] = vec3(r.x, g.x, b.x);
  c[2] = vec3(r.y, g.y, b.y);
  c[3] = vec3(r.z, g.z, b.z);
  // v = (q - 128) / 127 * l2Scale; texelFetch of RGBA8 gives q / 255.
  float l2[16];
  vec4 t0 = texelFetch(pbL2_0, p, 0), t1 = texelFetch(pbL2_1, p, 0),
       t2 = texelFetch(pbL2_2, p, 0), t3 = texelFetch(pbL2_3, p, 0);
  vec4 t[4] = vec4[4](t0, t1, t2, t3);
  for (int i = 0; i < 15; i++) l2[i] = (round(t[i / 4][i % 4] * 255.0) - 128.0) / 127.0 * pbL2Scale;
  for (int k = 0; k < 5; k++) c[4 + k] = vec3(l2[k], l2[5 + k], l2[10 + k]);
  // radiance_r = local_r + sum_s T[r][s] sky_s
  for (int row = 0; row < 9; row++)
    for (int col = 0; col < pbSkyCoeffs; col++)
      c[row] += texelFetch(pbsky_transfer, ivec3(pbSkyCoeffs * p.x + col, 9 * p.y + row, p.z), 0)
                    .rgb * pbSky[col];
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

float pbSignNotZero(float v) {
  return v >= 0.0 ? 1.0 : -1.0;
}

// Unit direction w to octahedral coordinates in [-1, 1]^2, the lower hemisphere folded over the
// diagonals (docs/volume-format.md).
vec2 pbOctahedralEncode(vec3 w) {
  vec2 uv = w.xy / (abs(w.x) + abs(w.y) + abs(w.z));
  if (w.z < 0.0)
    uv = vec2((1.0 - abs(uv.y)) * pbSignNotZero(uv.x), (1.0 - abs(uv.x)) * pbSignNotZero(uv.y));
  return uv;
}

vec3 pbOctahedralDecode(vec2 uv) {
  vec3 w = vec3(uv, 1.0 - abs(uv.x) - abs(uv.y));
  if (w.z < 0.0)
    w.xy = vec2((1.0 - abs(uv.y)) * pbSignNotZero(uv.x), (1.0 - abs(uv.x)) * pbSignNotZero(uv.y));
  return normalize(w);
}

// A texel (column, row) of the map with its border wrapped: off an edge onto the mirrored texel
// of the same edge, off a corner onto the opposite corner.
ivec2 pbWrappedTexel(ivec2 t) {
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

// The mean and variance of s = 1/t that probe `probe` saw around unit direction w: the moments
// of the four texels around w, each texel's 1/t scaled by 1 / |its centre direction|_1 so a plane
// stays linear in the map (raw 1/t where a tap lies across the map's seam, whose mirrored taps do
// not surround w), blended bilinearly over the texels some ray went through and scaled back by
// |w|_1; the variance less what the trend between the texels explains, at least (7.7% of the
// mean)^2. False when no ray went through any of the four.
bool pbVisibilityMoments(ivec3 probe, vec3 w, out float mean, out float variance) {
  vec2 f = (pbOctahedralEncode(w) + 1.0) * 0.5 * float(pbVisSize) - 0.5;
  ivec2 ij = ivec2(floor(f));
  vec2 ab = f - vec2(ij);
  bool wrapped = ij.x < 0 || ij.y < 0 || ij.x + 1 >= pbVisSize || ij.y + 1 >= pbVisSize;
  float q[4], tap[4], weight[4], scale[4];
  vec4 m[4];
  float total = 0.0;
  for (int k = 0; k < 4; k++) {
    ivec2 o = ivec2(k & 1, k >> 1);
    ivec2 t = pbWrappedTexel(ij + o);
    vec3 centre = pbOctahedralDecode((vec2(t) + 0.5) / float(pbVisSize) * 2.0 - 1.0);
    scale[k] = wrapped ? 1.0 : 1.0 / (abs(centre.x) + abs(centre.y) + abs(centre.z));
    m[k] = texelFetch(pbvisibility, ivec3(pbVisSize * probe.xy + t, probe.z), 0);
    tap[k] = (o.x == 1 ? ab.x : 1.0 - ab.x) * (o.y == 1 ? ab.y : 1.0 - ab.y);
    weight[k] = m[k].z > 0.0 ? tap[k] : 0.0;
    total += weight[k];
  }
  mean = 0.0;
  variance = 0.0;
  if (!(total > 0.0)) return false;
  for (int k = 0; k < 4; k++) {
    q[k] = scale[k] * m[k].x;
    weight[k] /= total;
    mean += weight[k] * q[k];
    variance += weight[k] * scale[k] * scale[k] * max(m[k].y - m[k].x * m[k].x, 0.0);
  }
  for (int k = 0; k < 4; k++)
    if (weight[k] == 0.0) q[k] = mean;
  float wu = tap[1] + tap[3], wv = tap[2] + tap[3];
  float gu = (q[1] - q[0]) * (1.0 - wv) + (q[3] - q[2]) * wv;
  float gv = (q[2] - q[0]) * (1.0 - wu) + (q[3] - q[1]) * wu;
  variance = max(variance - (gu * gu + gv * gv) / 12.0, pbMinRelativeVariance * mean * mean);
  float l1 = wrapped ? 1.0 : abs(w.x) + abs(w.y) + abs(w.z);
  mean *= l1;
  variance *= l1 * l1;
  return true;
}

// Chebyshev's visibility of a point at distance d > 0 where the moments of 1/t are (mean,
// variance): 1 where 1/d >= mean, else the one-sided bound, cubed.
float pbChebyshev(float mean, float variance, float d) {
  float s = 1.0 / d;
  if (s >= mean) return 1.0;
  float excess = mean - s;
  float p = variance / (variance + excess * excess);
  return p * p * p;
}

// Visibility in [0, 1] of point x from probe `probe` baked at probePos; 1 where no ray went that
// way.
float pbProbeVisibility(ivec3 probe, vec3 probePos, vec3 x) {
  vec3 fromProbe = x - probePos;
  float d = length(fromProbe);
  if (!(d > 0.0)) return 1.0;
  float mean, variance;
  if (!pbVisibilityMoments(probe, fromProbe / d, mean, variance)) return 1.0;
  return pbChebyshev(mean, variance, d);
}

// The blended radiance SH at world point x with normal n (probebake's frame, any length), in
// c; returns the number of probes that took part (0: none holds light here, c is then 0).
int pbBlendSh(vec3 x, vec3 n, out vec3 c[9]) {
  n = normalize(n);
  vec3 biased = x + n * (PB_NORMAL_BIAS * min(pbGridSpacing.x, min(pbGridSpacing.y, pbGridSpacing.z)));
  vec3 g = clamp((x - pbGridOrigin) / pbGridSpacing, vec3(0.0), vec3(pbGridCounts - 1));
  ivec3 i0 = min(ivec3(floor(g)), max(pbGridCounts - 2, ivec3(0)));
  vec3 f = clamp(g - vec3(i0), 0.0, 1.0);
  // The cell's corners: which hold light, where they were baked, their trilinear weights and how
  // well each sees x.
  bool usable[8];
  ivec3 probe[8];
  vec3 probePos[8];
  float tri[8], seen[8];
  for (int corner = 0; corner < 8; corner++) {
    ivec3 o = ivec3(corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
    probe[corner] = min(i0 + o, pbGridCounts - 1);
    vec3 wv = mix(1.0 - f, f, vec3(o));
    tri[corner] = wv.x * wv.y * wv.z;
    usable[corner] = texelFetch(pbL0_validity, probe[corner], 0).a >= 0.5;
    probePos[corner] = pbGridOrigin + vec3(probe[corner]) * pbGridSpacing;
    if (pbHasOffsets) probePos[corner] += texelFetch(pboffset_filled, probe[corner], 0).xyz;
    seen[corner] = 1.0;
    if (pbHasVisibility && usable[corner] && tri[corner] > 0.0)
      seen[corner] = min(pbProbeVisibility(probe[corner], probePos[corner], biased),
                         pbProbeVisibility(probe[corner], probePos[corner], x));
  }
  // Connectivity (probe_sampler.h): each edge as open as its probes see each other, b[8i + j] the
  // bottleneck over paths of edges from corner i to j; claim[i] whether x lies on probe i's side
  // of what blocks its edges (x's distance along each edge against the first surface the probe
  // saw that way, within 1% of the edge's length); a probe's support the claims (where no probe
  // claims x, the visibilities) of the probes weighing in as far as they are connected to it;
  // each probe counts at most (support / the largest support)^8.
  float connected[8];
  for (int i = 0; i < 8; i++) connected[i] = 1.0;
  if (pbHasVisibility) {
    // Each probe's moments toward its neighbours along the edges, read once.
    bool known[24];
    float tMean[24], tVar[24], tLen[24];
    for (int i = 0; i < 8; i++) {
      for (int a = 0; a < 3; a++) {
        int j = i ^ (1 << a);
        known[3 * i + a] = false;
        tLen[3 * i + a] = 0.0;
        if (!usable[i] || !usable[j]) continue;
        vec3 along = probePos[j] - probePos[i];
        tLen[3 * i + a] = length(along);
        known[3 * i + a] = tLen[3 * i + a] > 0.0 &&
            pbVisibilityMoments(probe[i], along / tLen[3 * i + a], tMean[3 * i + a], tVar[3 * i + a]);
      }
    }
    float b[64], edge[24], claim[8];
    for (int i = 0; i < 64; i++) b[i] = i / 8 == i % 8 ? 1.0 : 0.0;
    for (int i = 0; i < 8; i++) {
      for (int a = 0; a < 3; a++) {
        int j = i ^ (1 << a);
        edge[3 * i + a] = 0.0;
        if (!usable[i] || !usable[j]) continue;
        float ij = known[3 * i + a] ? pbChebyshev(tMean[3 * i + a], tVar[3 * i + a], tLen[3 * i + a]) : 1.0;
        float ji = known[3 * j + a] ? pbChebyshev(tMean[3 * j + a], tVar[3 * j + a], tLen[3 * j + a]) : 1.0;
        edge[3 * i + a] = min(ij, ji);
        b[8 * i + j] = edge[3 * i + a];
      }
    }
    for (int m = 0; m < 8; m++)
      for (int i = 0; i < 8; i++)
        for (int j = 0; j < 8; j++) b[8 * i + j] = max(b[8 * i + j], min(b[8 * i + m], b[8 * m + j]));
    for (int i = 0; i < 8; i++) {
      claim[i] = 1.0;
      for (int a = 0; a < 3; a++) {
        int k = 3 * i + a;
        if (!known[k] || !(tMean[k] > 0.0)) continue;
        vec3 along = probePos[i ^ (1 << a)] - probePos[i];
        float beyond = dot(x - probePos[i], along) / tLen[k] - 1.0 / tMean[k];
        float step = clamp(0.5 - beyond / (0.01 * tLen[k]), 0.0, 1.0);
        claim[i] *= 1.0 - (1.0 - edge[k]) * (1.0 - step);
      }
    }
    float support[8];
    float most = 0.0;
    for (int pass = 0; pass < 2; pass++) {
      for (int i = 0; i < 8; i++) {
        support[i] = 0.0;
        for (int j = 0; j < 8; j++)
          if (usable[j] && tri[j] > 0.0) support[i] += (pass == 1 ? seen[j] : claim[j]) * b[8 * i + j];
        if (usable[i] && tri[i] > 0.0) most = max(most, support[i]);
      }
      if (most > 0.0) break;
    }
    if (most > 0.0) {
      for (int i = 0; i < 8; i++) {
        float r = support[i] / most;
        float r2 = r * r, r4 = r2 * r2;
        connected[i] = r4 * r4;
      }
    }
  }
  // The weights before crushing and trilinear, then the crush relative to the largest: when
  // every probe is crushed, w^3 / 0.2^2 underflows float for the hidden ones (w down to 1e-30),
  // and the blend depends only on the ratios w / max w.
  float v[8];
  float vmax = 0.0;
  for (int corner = 0; corner < 8; corner++) {
    v[corner] = 0.0;
    if (tri[corner] <= 0.0 || !usable[corner]) continue;
    vec3 toProbe = probePos[corner] - x;
    float len = length(toProbe);
    float h = ((len > 0.0 ? dot(toProbe / len, n) : 1.0) + 1.0) * 0.5;
    float w = h * h + 0.2;
    if (pbHasVisibility) w = max(w * min(seen[corner], connected[corner]), pbMinWeight);
    v[corner] = w;
    vmax = max(vmax, w);
  }
  for (int k = 0; k < 9; k++) c[k] = vec3(0.0);
  float total = 0.0;
  int probes = 0;
  for (int corner = 0; corner < 8; corner++) {
    if (v[corner] <= 0.0) continue;
    float w = v[corner];
    if (pbHasVisibility && vmax < pbCrush) {
      float r = w / vmax;
      w = r * r * r;
    } else if (pbHasVisibility && w < pbCrush) {
      w *= w * w / (pbCrush * pbCrush);
    }
    w *= tri[corner];
    vec3 p[9];
    pbProbeSh(probe[corner], p);
    for (int k = 0; k < 9; k++) c[k] += w * p[k];
    total += w;
    probes++;
  }
  if (total > 0.0)
    for (int k = 0; k < 9; k++) c[k] /= total;
  return probes;
}

// Irradiance at world point x with normal n (probebake's frame); .w is the number of probes that
// took part (0: no probe holds light here, .rgb is then 0).
vec4 pbIrradiance(vec3 x, vec3 n) {
  vec3 c[9];
  int probes = pbBlendSh(x, n, c);
  return vec4(pbShIrradiance(c, normalize(n)), float(probes));
}

#endif  // PROBEBAKE_PROBES_GLSL
