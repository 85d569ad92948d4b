// node three_irradiance.mjs THREE_MODULE EXPORT.json NORMALS.json
// Loads a `probebake export --format threejs` file with three.js itself and prints, as JSON, for
// every probe and every normal (three's frame): SphericalHarmonics3.fromArray(probe.sh.flat())
// .getIrradianceAt(normal). Output: {"irradiance": [[[r, g, b] per normal] per probe]}.
import { readFileSync } from 'node:fs';
import { pathToFileURL } from 'node:url';

const [threeModule, exportPath, normalsPath] = process.argv.slice(2);
const THREE = await import(pathToFileURL(threeModule).href);
const exported = JSON.parse(readFileSync(exportPath, 'utf8'));
const normals = JSON.parse(readFileSync(normalsPath, 'utf8'));
const irradiance = exported.probes.map((probe) => {
  if (probe.sh.length !== 9) throw new Error(`sh: ${probe.sh.length} coefficients, want 9`);
  const sh = new THREE.SphericalHarmonics3().fromArray(probe.sh.flat());
  return normals.map((n) => {
    const e = sh.getIrradianceAt(new THREE.Vector3(...n), new THREE.Vector3());
    return [e.x, e.y, e.z];
  });
});
process.stdout.write(JSON.stringify({ revision: THREE.REVISION, irradiance }));
