// csrbf_deformation.js's textures for a .glb with CSRBF_deformation, loaded by three's GLTFLoader
// with the module's plugin (as a page loads it), at morph weight W, written as PREFIX.<texture>.bin.
//   node gpu_layout.mjs FILE.glb W PREFIX
import { readFileSync, writeFileSync } from 'node:fs';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { CSRBFDeformationPlugin } from './csrbf_deformation.js';

const [file, weight, prefix] = process.argv.slice(2);
const bytes = readFileSync(file);
const loader = new GLTFLoader();
loader.register((parser) => new CSRBFDeformationPlugin(parser));
loader.parse(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength), '', (gltf) => {
  const [d] = gltf.userData.csrbfDeformations;
  d.update([Number(weight)]);
  const names = { csrbfSources: 'sources', csrbfCoefficients: 'coefficients', csrbfDeformations: 'deformations',
    csrbfCells: 'cells', csrbfList: 'list', csrbfGroups: 'groups' };
  for (const [k, name] of Object.entries(names)) {
    const a = d.textures[k].image.data;
    writeFileSync(`${prefix}.${name}.bin`, Buffer.from(a.buffer, a.byteOffset, a.byteLength));
  }
  console.log(`csrbf_deformation.js: ${d.deformations.length} deformation, ${d.sourceCount} sources, weight ${weight}`);
}, (e) => { console.error(e); process.exit(1); });
