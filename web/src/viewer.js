// probebake's viewer (docs/engines.md): reads the JSON `probebake view` inlines, lights the
// scene's meshes with the probes' SH irradiance through the GLSL include (the core sampler's
// weights: trilinear, backface, visibility, offsets), and draws each probe
// as a small sphere shaded by its SH or coloured by an overlay. Bundled with three.js by esbuild
// at build time (web/CMakeLists.txt); everything runs from the one HTML file.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import probesGlsl from '../../integrations/shaders/probebake_probes.glsl';

const data = JSON.parse(document.getElementById('probebake-data').textContent);
const [nx, ny, nz] = data.grid.counts;

// The probes as the textures `probebake export --format textures` writes (inlined, base64),
// sampled by integrations/shaders/probebake_probes.glsl: the include engines use.
const header = data.textures;
const bin = Uint8Array.from(atob(data.texturesBin), (ch) => ch.charCodeAt(0));
const textureUniforms = {
  pbGridOrigin: { value: new THREE.Vector3(...header.origin) },
  pbGridSpacing: { value: new THREE.Vector3(...header.spacing) },
  pbGridCounts: { value: new THREE.Vector3(nx, ny, nz) },
  pbL2Scale: { value: header.l2Scale },
  // The include weighs probes as the core's sampler does with what the textures hold: offsets
  // (relocation) and visibility moments when the volume has them.
  pbHasOffsets: { value: header.textures.some((t) => t.name === 'offset_filled') },
  pbHasVisibility: { value: header.textures.some((t) => t.name === 'visibility') },
  // A volume baked with a sky transfer is shown with its local lights only: relight it first
  // (`probebake relight`) to see it under a sky.
  pbSkyCoeffs: { value: 0 },
};
for (const t of header.textures) {
  const half = t.format === 'RGBA16F', float = t.format === 'RGBA32F';
  const texels = half ? new Uint16Array(bin.buffer, t.offset, t.bytes / 2)
    : float ? new Float32Array(bin.buffer, t.offset, t.bytes / 4)
      : new Uint8Array(bin.buffer, t.offset, t.bytes);
  const [sx, sy, sz] = t.size || [nx, ny, nz];  // the visibility atlas has its own size
  const texture = new THREE.Data3DTexture(texels, sx, sy, sz);
  texture.format = THREE.RGBAFormat;
  texture.type = half ? THREE.HalfFloatType : float ? THREE.FloatType : THREE.UnsignedByteType;
  texture.minFilter = texture.magFilter = THREE.NearestFilter;
  texture.unpackAlignment = 1;
  texture.needsUpdate = true;
  textureUniforms['pb' + t.name] = { value: texture };  // the include's uniform names
}
// The optional textures' samplers still need a 3D texture bound (WebGL refuses a draw whose
// samplers of different kinds share a unit); the flags above keep the include from reading them.
for (const name of ['pboffset_filled', 'pbvisibility', 'pbsky_transfer'])
  textureUniforms[name] ||= { value: textureUniforms.pbL0_validity.value };

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

const exposureUniform = { value: data.exposure };

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
  // A cutout (a trellis, leaves) is drawn translucent by the share of its texels that stay.
  const opacity = mesh.opacity ?? 1;
  // A mesh the scene places several times (placements: 12 numbers each, a row-major 3 x 4 in
  // three's frame) is one InstancedMesh.
  const placements = mesh.placements ? mesh.placements.length / 12 : 0;
  const material = new THREE.ShaderMaterial({
    glslVersion: THREE.GLSL3,
    // Front faces only: a closed room seen from outside shows its inside (walls wound inward).
    // Both for cutouts, and for placed meshes (a mirroring placement turns their winding).
    side: opacity < 1 || placements > 0 ? THREE.DoubleSide : THREE.FrontSide,
    transparent: opacity < 1,
    depthWrite: opacity >= 1,
    uniforms: {
      ...textureUniforms,
      exposure: exposureUniform,
      albedo: { value: new THREE.Vector3(...mesh.albedo) },
      opacity: { value: opacity },
    },
    vertexShader: /* glsl */ `
      out vec3 vWorld;
      void main() {
        vec4 w = vec4(position, 1.0);
        #ifdef USE_INSTANCING
        w = instanceMatrix * w;
        #endif
        w = modelMatrix * w;
        vWorld = w.xyz;
        gl_Position = projectionMatrix * viewMatrix * w;
      }`,
    fragmentShader: /* glsl */ `
      precision highp float;
      precision highp sampler3D;
      uniform vec3 albedo;
      uniform float exposure;
      uniform float opacity;
      in vec3 vWorld;
      out vec4 outColor;
      ${shGlsl}
      ${probesGlsl}
      void main() {
        // Flat shading: the face normal, turned toward the viewer (double-sided walls).
        vec3 n = normalize(cross(dFdx(vWorld), dFdy(vWorld)));
        if (dot(n, cameraPosition - vWorld) < 0.0) n = -n;
        // three's frame to probebake's: (x, y, z) -> (x, -z, y).
        vec4 e = pbIrradiance(vec3(vWorld.x, -vWorld.z, vWorld.y), vec3(n.x, -n.z, n.y));
        if (e.w <= 0.0) {  // no valid probe: a grey checker
          float check = mod(floor(vWorld.x * 4.0) + floor(vWorld.y * 4.0) + floor(vWorld.z * 4.0), 2.0);
          outColor = vec4(vec3(0.3 + 0.1 * check), 1.0);
          return;
        }
        outColor = vec4(srgbEncode(albedo * max(e.rgb, 0.0) / 3.14159265358979 * exposure), opacity);
      }`,
  });
  let object;
  if (placements > 0) {
    object = new THREE.InstancedMesh(geometry, material, placements);
    const m = new THREE.Matrix4();
    for (let k = 0; k < placements; ++k) {
      const a = mesh.placements.slice(12 * k, 12 * k + 12);
      m.set(...a, 0, 0, 0, 1);  // Matrix4.set takes row-major
      object.setMatrixAt(k, m);
    }
    object.computeBoundingBox();
    box.union(object.boundingBox);
  } else {
    object = new THREE.Mesh(geometry, material);
    geometry.computeBoundingBox();
    box.union(geometry.boundingBox);
  }
  scene.add(object);
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
      exposure: exposureUniform,
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
  const maxOffset = Math.max(1e-9, ...data.probes.map((p) => p.offset));
  for (const { material, probe } of probeMaterials) {
    const u = material.uniforms;
    u.useFlat.value = mode === 'sh' ? 0 : 1;
    if (mode === 'validity') {
      u.flatColor.value = probe.validity >= 0.5 ? new THREE.Vector3(0.1, 0.9, 0.2)
        : probe.filled ? new THREE.Vector3(0.95, 0.85, 0.1) : new THREE.Vector3(0.95, 0.1, 0.1);
    }
    if (mode === 'offset') u.flatColor.value = probe.offset > 0 ? ramp(probe.offset / maxOffset) : new THREE.Vector3(0.5, 0.5, 0.5);
    if (mode === 'stdError') u.flatColor.value = probe.stdError < 0 ? new THREE.Vector3(1, 0, 1) : ramp(probe.stdError / 0.1);
    if (mode === 'sampleCount') u.flatColor.value = ramp(probe.sampleCount / maxSamples);
  }
  legend.textContent = {
    sh: `exposure ${data.exposure.toPrecision(3)}`,
    validity: 'green valid, yellow invalid and filled by dilation, red invalid',
    offset: `grey not moved; blue to red: relocation offset up to ${maxOffset.toPrecision(3)}`,
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
