// probebake's viewer (docs/engines.md): reads the JSON `probebake view` inlines, lights the
// scene's meshes by trilinear interpolation of the probes' SH irradiance, and draws each probe
// as a small sphere shaded by its SH or coloured by an overlay. Bundled with three.js by esbuild
// at build time (web/CMakeLists.txt); everything runs from the one HTML file.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';

const data = JSON.parse(document.getElementById('probebake-data').textContent);
const [nx, ny, nz] = data.grid.counts;

// Probe texture: texel (10 i + c, j, k) holds SH coefficient c (three's basis and frame, RGB)
// for c < 9, and (usable ? 1 : 0) in texel 10 i + 9. Inactive probes stay 0 (not usable).
const texels = new Float32Array(nx * 10 * ny * nz * 4);
for (const p of data.probes) {
  const [i, j, k] = p.ijk;
  const base = ((k * ny + j) * nx * 10 + i * 10) * 4;
  for (let c = 0; c < 9; c++) texels.set([...p.sh[c], 0], base + 4 * c);
  texels[base + 36] = p.validity >= 0.5 ? 1 : 0;
}
const probeTexture = new THREE.Data3DTexture(texels, nx * 10, ny, nz);
probeTexture.format = THREE.RGBAFormat;
probeTexture.type = THREE.FloatType;
probeTexture.minFilter = probeTexture.magFilter = THREE.NearestFilter;
probeTexture.unpackAlignment = 1;
probeTexture.needsUpdate = true;

// three.js's SphericalHarmonics3.getIrradianceAt, in GLSL: E(n) from radiance coefficients.
const shGlsl = /* glsl */ `
vec3 shIrradiance(vec3 c[9], vec3 n) {
  float x = n.x, y = n.y, z = n.z;
  return c[0] * 0.886227 + c[1] * (2.0 * 0.511664 * y) + c[2] * (2.0 * 0.511664 * z) +
         c[3] * (2.0 * 0.511664 * x) + c[4] * (2.0 * 0.429043 * x * y) +
         c[5] * (2.0 * 0.429043 * y * z) + c[6] * (0.743125 * z * z - 0.247708) +
         c[7] * (2.0 * 0.429043 * x * z) + c[8] * (0.429043 * (x * x - y * y));
}
vec3 srgbEncode(vec3 c) {
  c = clamp(c, 0.0, 1.0);
  return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, c));
}
`;

// Trilinear probe irradiance at a world point (three's frame) for a unit normal (three's frame):
// the 8 surrounding grid probes, invalid or inactive ones skipped and the weights renormalised,
// clamped to the grid at its border. Returns (E, weight sum); weight sum 0 means no data.
const trilinearGlsl = /* glsl */ `
uniform highp sampler3D probes;
uniform vec3 gridOrigin;   // probebake frame
uniform vec3 gridSpacing;
uniform ivec3 gridCounts;
vec4 probeIrradianceTrilinear(vec3 worldThree, vec3 normalThree) {
  vec3 pb = vec3(worldThree.x, -worldThree.z, worldThree.y);  // three -> probebake frame
  vec3 g = clamp((pb - gridOrigin) / gridSpacing, vec3(0.0), vec3(gridCounts - 1));
  ivec3 i0 = min(ivec3(floor(g)), max(gridCounts - 2, ivec3(0)));
  vec3 f = clamp(g - vec3(i0), 0.0, 1.0);
  vec3 sum = vec3(0.0);
  float wsum = 0.0;
  for (int corner = 0; corner < 8; corner++) {
    ivec3 o = ivec3(corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
    ivec3 p = min(i0 + o, gridCounts - 1);
    vec3 wv = mix(1.0 - f, f, vec3(o));
    float w = wv.x * wv.y * wv.z;
    if (w <= 0.0 || texelFetch(probes, ivec3(10 * p.x + 9, p.y, p.z), 0).r < 0.5) continue;
    vec3 c[9];
    for (int i = 0; i < 9; i++) c[i] = texelFetch(probes, ivec3(10 * p.x + i, p.y, p.z), 0).rgb;
    sum += w * shIrradiance(c, normalThree);
    wsum += w;
  }
  return vec4(wsum > 0.0 ? sum / wsum : vec3(0.0), wsum);
}
`;

const gridUniforms = {
  probes: { value: probeTexture },
  gridOrigin: { value: new THREE.Vector3(...data.grid.origin) },
  gridSpacing: { value: new THREE.Vector3(...data.grid.spacing) },
  gridCounts: { value: new THREE.Vector3(nx, ny, nz) },
  exposure: { value: data.exposure },
};

const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
renderer.setSize(window.innerWidth, window.innerHeight);
document.body.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x202020);

const box = new THREE.Box3();
for (const mesh of data.meshes) {
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.Float32BufferAttribute(mesh.positions, 3));
  geometry.setIndex(mesh.indices);
  geometry.computeVertexNormals();
  const material = new THREE.ShaderMaterial({
    glslVersion: THREE.GLSL3,
    // Front faces only: a closed room seen from outside shows its inside (walls wound inward).
    side: THREE.FrontSide,
    uniforms: { ...gridUniforms, albedo: { value: new THREE.Vector3(...mesh.albedo) } },
    vertexShader: /* glsl */ `
      out vec3 vWorld;
      void main() {
        vec4 w = modelMatrix * vec4(position, 1.0);
        vWorld = w.xyz;
        gl_Position = projectionMatrix * viewMatrix * w;
      }`,
    fragmentShader: /* glsl */ `
      precision highp float;
      precision highp sampler3D;
      uniform vec3 albedo;
      uniform float exposure;
      in vec3 vWorld;
      out vec4 outColor;
      ${shGlsl}
      ${trilinearGlsl}
      void main() {
        // Flat shading: the face normal, turned toward the viewer (double-sided walls).
        vec3 n = normalize(cross(dFdx(vWorld), dFdy(vWorld)));
        if (dot(n, cameraPosition - vWorld) < 0.0) n = -n;
        vec4 e = probeIrradianceTrilinear(vWorld, n);
        if (e.w <= 0.0) {  // no valid probe: a grey checker
          float check = mod(floor(vWorld.x * 4.0) + floor(vWorld.y * 4.0) + floor(vWorld.z * 4.0), 2.0);
          outColor = vec4(vec3(0.3 + 0.1 * check), 1.0);
          return;
        }
        outColor = vec4(srgbEncode(albedo * max(e.rgb, 0.0) / 3.14159265358979 * exposure), 1.0);
      }`,
  });
  const object = new THREE.Mesh(geometry, material);
  scene.add(object);
  geometry.computeBoundingBox();
  box.union(geometry.boundingBox);
}

// Probe spheres.
const spacing = Math.min(...data.grid.spacing);
const sphere = new THREE.SphereGeometry(0.12 * spacing, 24, 16);
const probeGroup = new THREE.Group();
const probeMaterials = [];
for (const p of data.probes) {
  const material = new THREE.ShaderMaterial({
    glslVersion: THREE.GLSL3,
    uniforms: {
      sh: { value: p.sh.map((c) => new THREE.Vector3(...c)) },
      flatColor: { value: new THREE.Vector3(1, 1, 1) },
      useFlat: { value: 0 },
      exposure: gridUniforms.exposure,
    },
    vertexShader: /* glsl */ `
      out vec3 vNormal;
      void main() {
        vNormal = normalize(mat3(modelMatrix) * normal);
        gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0);
      }`,
    fragmentShader: /* glsl */ `
      precision highp float;
      uniform vec3 sh[9];
      uniform vec3 flatColor;
      uniform float useFlat;
      uniform float exposure;
      in vec3 vNormal;
      out vec4 outColor;
      ${shGlsl}
      void main() {
        vec3 e = shIrradiance(sh, normalize(vNormal)) / 3.14159265358979 * exposure;
        outColor = vec4(useFlat > 0.5 ? flatColor : srgbEncode(max(e, 0.0)), 1.0);
      }`,
  });
  probeMaterials.push({ material, probe: p });
  const mesh = new THREE.Mesh(sphere, material);
  mesh.position.set(...p.position);
  probeGroup.add(mesh);
  box.expandByPoint(mesh.position);
}
scene.add(probeGroup);

// Overlays: colours per probe; a value of -1 std_error means unknown (shown magenta).
function ramp(t) {
  t = Math.min(Math.max(t, 0), 1);
  return new THREE.Vector3(t, 0.2 + 0.6 * (1 - Math.abs(2 * t - 1)), 1 - t);
}
function applyOverlay(mode) {
  const legend = document.getElementById('legend');
  const maxSamples = Math.max(1, ...data.probes.map((p) => p.sampleCount));
  for (const { material, probe } of probeMaterials) {
    const u = material.uniforms;
    u.useFlat.value = mode === 'sh' ? 0 : 1;
    if (mode === 'validity') u.flatColor.value = probe.validity >= 0.5 ? new THREE.Vector3(0.1, 0.9, 0.2) : new THREE.Vector3(0.95, 0.1, 0.1);
    if (mode === 'stdError') u.flatColor.value = probe.stdError < 0 ? new THREE.Vector3(1, 0, 1) : ramp(probe.stdError / 0.1);
    if (mode === 'sampleCount') u.flatColor.value = ramp(probe.sampleCount / maxSamples);
  }
  legend.textContent = {
    sh: `exposure ${data.exposure.toPrecision(3)}`,
    validity: 'green valid, red invalid',
    stdError: 'blue 0 to red >= 10% relative std error; magenta unknown',
    sampleCount: `blue 0 to red ${maxSamples} samples`,
  }[mode];
}
const overlay = document.getElementById('overlay');
overlay.addEventListener('change', () => { applyOverlay(overlay.value); render(); });
document.getElementById('showProbes').addEventListener('change', (e) => {
  probeGroup.visible = e.target.checked; render();
});
const params = new URLSearchParams(window.location.search);
if (params.get('overlay')) overlay.value = params.get('overlay');
if (params.get('probes') === '0') { probeGroup.visible = false; document.getElementById('showProbes').checked = false; }
applyOverlay(overlay.value);

// Camera: looks at the centre of everything, from above and in front (three's +Z is probebake -Y).
const center = box.getCenter(new THREE.Vector3());
const size = Math.max(box.getSize(new THREE.Vector3()).length(), 1e-6);
const camera = new THREE.PerspectiveCamera(45, window.innerWidth / window.innerHeight, size * 1e-3, size * 100);
camera.position.copy(center).add(new THREE.Vector3(0.35, 0.55, 0.75).multiplyScalar(size));
camera.lookAt(center);
const controls = new OrbitControls(camera, renderer.domElement);
controls.target.copy(center);
controls.addEventListener('change', () => render());
function render() { renderer.render(scene, camera); }
window.addEventListener('resize', () => {
  camera.aspect = window.innerWidth / window.innerHeight;
  camera.updateProjectionMatrix();
  renderer.setSize(window.innerWidth, window.innerHeight);
  render();
});
render();
document.title = 'probebake view (ready)';
