// CSRBF_deformation for three.js (WebGL2): a GLTFLoader plugin that plays the extension in the
// vertex shader (docs/gltf/CSRBF_deformation.md; docs/export.md, "Playing CSRBF_deformation").
//
//   import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
//   import { CSRBFDeformationPlugin } from './csrbf_deformation.js';
//   const loader = new GLTFLoader();
//   loader.register((parser) => new CSRBFDeformationPlugin(parser));
//   loader.load('fish.glb', (gltf) => { ... play gltf.animations with an AnimationMixer as usual ... });
//
// Every mesh that carries the extension gets a CSRBFDeformation (CSRBFDeformation.of(mesh)): its
// sources, a neighbour grid and the coefficients live in textures, its materials run CSRBF_GLSL
// (web/csrbf_deformation.glsl, the same text) before the projection, and before each draw the
// mesh's morph weights, animated by the standard `weights` channel, become the coefficients' sum.
// The morph targets that the extension replaces are not added; the others are, as glTF adds them.
// Clones of the mesh share its materials and play with their own weights. A material set on the
// mesh later needs attach(mesh) again; dispose() frees the textures.
import * as THREE from 'three';

// The text of web/csrbf_deformation.glsl (a test checks that the two are the same).
// BEGIN CSRBF_GLSL
export const CSRBF_GLSL = `// CSRBF_deformation in a vertex shader (docs/gltf/CSRBF_deformation.md): one vertex's
// deformations, stage by stage, and the Jacobian J of the whole map, so that the deformed normal is
// the exact J^-T n. GLSL ES 3.00 (WebGL2) and desktop GLSL 3.30 or later; precision highp.
//
// The data, laid out by csrbf_deformation.js (or an engine, the same way): every texture is read
// with texelFetch, element k at (k % width, k / width).
//   csrbfSources       RGBA32F  element k: source k of all the mesh's deformations (xyz)
//   csrbfCoefficients  RGBA32F  element k: sum over the terms t of source k's deformation of
//                               w[t.weight] * alpha_t,k (xyz), updated each frame on the CPU
//   csrbfDeformations  RGBA32F  8 elements a deformation, sorted by stage:
//                               0: (R, kernel 0|2|4|6, stage, 1 if it has groups else -1)
//                               1: (grid origin xyz, 1 / cell side)
//                               2: (cells along x, y, z, first cell in csrbfCells)
//                               3: (sum of w * polynomial constant xyz, 1 if any term's w != 0)
//                               4..6: sum of w * the polynomial's rows of L (row k multiplies x_k)
//                               7: (first element in csrbfGroups, count, 0, 0) of its groups
//   csrbfCells         RG32I    element c: (first element in csrbfList, count) of the sources
//                               within R of cell c, a cell's side at least R
//   csrbfList          R32I     source indices
//   csrbfGroups        R32I     each grouped deformation's groups (_CSRBF_GROUP values that it
//                               moves), ascending, one deformation's after another
// csrbfDeformationCount is the number of deformations (0: nothing moves).

uniform highp sampler2D csrbfSources;
uniform highp sampler2D csrbfCoefficients;
uniform highp sampler2D csrbfDeformations;
uniform highp isampler2D csrbfCells;
uniform highp isampler2D csrbfList;
uniform highp isampler2D csrbfGroups;
uniform int csrbfDeformationCount;

ivec2 csrbfAt(int k, int width) { return ivec2(k % width, k / width); }

// Wendland's phi(r) and phi'(r) / r (finite at r = 0 for C2..C6; C0's gradient is 0 at a source).
void csrbfKernel(int kernel, float r, out float phi, out float dphiOverR) {
  float q = 1.0 - r;
  if (kernel == 0) {
    phi = q * q;
    dphiOverR = r > 0.0 ? -2.0 * q / r : 0.0;
  } else if (kernel == 2) {
    float q3 = q * q * q;
    phi = q3 * q * (4.0 * r + 1.0);
    dphiOverR = -20.0 * q3;
  } else if (kernel == 4) {
    float q5 = q * q * q * q * q;
    phi = q5 * q * ((35.0 * r + 18.0) * r + 3.0);
    dphiOverR = -q5 * (280.0 * r + 56.0);
  } else {
    float q7 = q * q * q * q * q * q * q;
    phi = q7 * q * (((32.0 * r + 25.0) * r + 8.0) * r + 1.0);
    dphiOverR = -q7 * ((352.0 * r + 154.0) * r + 22.0);
  }
}

// Moves x (the position after the morph targets that no term replaces) and n (its normal, any
// length; returned unit) by the mesh's deformations. group is the vertex's _CSRBF_GROUP (0 where
// the mesh has none).
void csrbfDeform(inout vec3 x, inout vec3 n, float group) {
  int sw = textureSize(csrbfSources, 0).x, cw = textureSize(csrbfCoefficients, 0).x;
  int dw = textureSize(csrbfDeformations, 0).x, gw = textureSize(csrbfCells, 0).x;
  int lw = textureSize(csrbfList, 0).x;
  int rw = textureSize(csrbfGroups, 0).x;
  vec3 y = x;
  mat3 stageJ = mat3(1.0), J = mat3(1.0);
  float stage = -1.0;
  for (int d = 0; d < csrbfDeformationCount; ++d) {
    vec4 head = texelFetch(csrbfDeformations, csrbfAt(8 * d, dw), 0);
    if (head.z != stage) {  // a new stage sees the points the stages before it produced
      x = y;
      J = stageJ * J;
      stageJ = mat3(1.0);
      stage = head.z;
    }
    vec4 constant = texelFetch(csrbfDeformations, csrbfAt(8 * d + 3, dw), 0);
    if (constant.w == 0.0) continue;  // every term's phase is 0 this frame
    if (head.w >= 0.0) {  // the vertex's group among the deformation's, by bisection
      vec4 groups = texelFetch(csrbfDeformations, csrbfAt(8 * d + 7, dw), 0);
      int g = int(group + 0.5), lo = int(groups.x), hi = int(groups.x) + int(groups.y);
      bool member = false;
      while (lo < hi) {
        int mid = (lo + hi) / 2, at = texelFetch(csrbfGroups, csrbfAt(mid, rw), 0).x;
        if (at == g) {
          member = true;
          break;
        }
        if (at < g) lo = mid + 1;
        else hi = mid;
      }
      if (!member) continue;
    }
    vec3 l0 = texelFetch(csrbfDeformations, csrbfAt(8 * d + 4, dw), 0).xyz;
    vec3 l1 = texelFetch(csrbfDeformations, csrbfAt(8 * d + 5, dw), 0).xyz;
    vec3 l2 = texelFetch(csrbfDeformations, csrbfAt(8 * d + 6, dw), 0).xyz;
    vec3 sum = constant.xyz + x.x * l0 + x.y * l1 + x.z * l2;
    mat3 gradient = mat3(l0, l1, l2);  // d sum_j / d x_k in column k, row j
    vec4 grid = texelFetch(csrbfDeformations, csrbfAt(8 * d + 1, dw), 0);
    vec4 dims = texelFetch(csrbfDeformations, csrbfAt(8 * d + 2, dw), 0);
    vec3 cellf = floor((x - grid.xyz) * grid.w);
    if (all(greaterThanEqual(cellf, vec3(0.0))) && all(lessThan(cellf, dims.xyz))) {
      ivec3 c = ivec3(cellf);
      ivec3 n3 = ivec3(dims.xyz);
      int cell = int(dims.w) + c.x + n3.x * (c.y + n3.y * c.z);
      ivec2 run = texelFetch(csrbfCells, csrbfAt(cell, gw), 0).xy;
      float invR = 1.0 / head.x;
      int kernel = int(head.y + 0.5);
      for (int k = 0; k < run.y; ++k) {
        int i = texelFetch(csrbfList, csrbfAt(run.x + k, lw), 0).x;
        vec3 e = (x - texelFetch(csrbfSources, csrbfAt(i, sw), 0).xyz) * invR;
        float r2 = dot(e, e);
        if (r2 >= 1.0) continue;
        float phi, dphiOverR;
        csrbfKernel(kernel, sqrt(r2), phi, dphiOverR);
        vec3 a = texelFetch(csrbfCoefficients, csrbfAt(i, cw), 0).xyz;
        sum += phi * a;
        gradient += outerProduct(a, e * (dphiOverR * invR));
      }
    }
    y += sum;
    stageJ += gradient;
  }
  x = y;
  J = stageJ * J;
  // J^-T n = cof(J) n / det J: the columns' cross products, with det's sign.
  vec3 a = J[0], b = J[1], c = J[2];
  vec3 m = n.x * cross(b, c) + n.y * cross(c, a) + n.z * cross(a, b);
  float s = dot(a, cross(b, c)) < 0.0 ? -1.0 : 1.0;
  float len = length(m);
  n = len > 0.0 ? m * (s / len) : n;
}
`;
// END CSRBF_GLSL

export const CSRBF_EXTENSION = 'CSRBF_deformation';
const KERNELS = { C0: 0, C2: 2, C4: 4, C6: 6 };
const WIDTH = 1024;  // texels a row of every data texture
const MAX_CELLS = 1 << 18;  // a deformation's grid: its cells grow past R to stay within this
const PLAYED_BY = new WeakMap();  // material -> the CSRBFDeformation it plays
const OWNER = new WeakMap();  // material -> the mesh it was made for
const BASE = new WeakMap();  // material -> the application's material it was cloned from

function rows(count) { return Math.max(1, Math.ceil(count / WIDTH)); }

function dataTexture(array, format, type, internal) {
  const t = new THREE.DataTexture(array, WIDTH, array.length / WIDTH / (format === THREE.RGBAFormat ? 4 : format === THREE.RGIntegerFormat ? 2 : 1), format, type);
  if (internal) t.internalFormat = internal;
  t.minFilter = t.magFilter = THREE.NearestFilter;
  t.generateMipmaps = false;
  t.flipY = false;
  t.unpackAlignment = 1;
  t.needsUpdate = true;
  return t;
}

// The cells of side h >= R over the sources' box grown by R, each listing the sources within R of
// it (the core's neighbour grid). A point outside the grid is farther than R from every source.
function neighbourGrid(sources, radius) {
  const n = sources.length / 3;
  const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  for (let i = 0; i < n; ++i)
    for (let k = 0; k < 3; ++k) {
      lo[k] = Math.min(lo[k], sources[3 * i + k]);
      hi[k] = Math.max(hi[k], sources[3 * i + k]);
    }
  const origin = lo.map((v) => v - radius);
  const extent = [0, 1, 2].map((k) => hi[k] + radius - origin[k]);
  let h = radius;
  let dims = extent.map((e) => Math.max(1, Math.ceil(e / h)));
  while (dims[0] * dims[1] * dims[2] > MAX_CELLS) {
    h *= 1.25;
    dims = extent.map((e) => Math.max(1, Math.ceil(e / h)));
  }
  const cells = dims[0] * dims[1] * dims[2];
  const count = new Int32Array(cells);
  const visit = (i, add) => {
    const s = [sources[3 * i], sources[3 * i + 1], sources[3 * i + 2]];
    const a = [0, 1, 2].map((k) => Math.max(0, Math.floor((s[k] - radius - origin[k]) / h)));
    const b = [0, 1, 2].map((k) => Math.min(dims[k] - 1, Math.floor((s[k] + radius - origin[k]) / h)));
    for (let z = a[2]; z <= b[2]; ++z)
      for (let y = a[1]; y <= b[1]; ++y)
        for (let x = a[0]; x <= b[0]; ++x) {
          // The distance from s to the cell's box, against R (a little wider: float rounding).
          const c = [x, y, z];
          let d2 = 0;
          for (let k = 0; k < 3; ++k) {
            const l = origin[k] + c[k] * h, u = l + h;
            const e = s[k] < l ? l - s[k] : s[k] > u ? s[k] - u : 0;
            d2 += e * e;
          }
          if (d2 <= radius * radius * (1 + 1e-6)) add(x + dims[0] * (y + dims[1] * z));
        }
  };
  for (let i = 0; i < n; ++i) visit(i, (c) => ++count[c]);
  const first = new Int32Array(cells + 1);
  for (let c = 0; c < cells; ++c) first[c + 1] = first[c] + count[c];
  const list = new Int32Array(first[cells]);
  const at = first.slice(0, cells);
  for (let i = 0; i < n; ++i) visit(i, (c) => { list[at[c]++] = i; });
  return { origin, h, dims, first, count, list };
}

// One mesh's deformations: textures, uniforms and the per-frame sum of its terms.
export class CSRBFDeformation {
  // deformations: [{ kernel: 'C2', radius, stage, groups: [..] | undefined, sources: Float32Array
  // (xyz), terms: [{ weight, coefficients: Float32Array (xyz), polynomial: [12] | undefined }] }]
  constructor(deformations) {
    this.enabled = true;
    this.deformations = deformations.map((d, index) => ({ ...d, index, stage: d.stage || 0 }))
      .sort((a, b) => a.stage - b.stage || a.index - b.index);
    this.replaced = new Set();
    let sources = 0, cells = 0, listed = 0;
    const groupList = [];  // each grouped deformation's groups, ascending, one after another
    for (const d of this.deformations) {
      if (!Object.prototype.hasOwnProperty.call(KERNELS, d.kernel)) throw new Error(`${CSRBF_EXTENSION}: kernel '${d.kernel}' is not C0, C2, C4 or C6`);
      if (!(d.radius > 0)) throw new Error(`${CSRBF_EXTENSION}: radius ${d.radius} is not > 0`);
      const n = d.sources.length / 3;
      for (const t of d.terms) {
        if (t.coefficients.length !== 3 * n) throw new Error(`${CSRBF_EXTENSION}: a term's coefficients are not one a source`);
        this.replaced.add(t.weight);
      }
      d.firstSource = sources;
      sources += n;
      d.grid = neighbourGrid(d.sources, d.radius);
      d.firstCell = cells;
      d.firstListed = listed;
      cells += d.grid.dims[0] * d.grid.dims[1] * d.grid.dims[2];
      listed += d.grid.list.length;
      if (d.groups && d.groups.length) {
        const sorted = [...new Set(d.groups)].sort((a, b) => a - b);
        d.groupsFirst = groupList.length;
        d.groupsCount = sorted.length;
        groupList.push(...sorted);
      } else d.groupsFirst = -1;
      if (cells > 2 ** 24 || sources > 2 ** 24) throw new Error(`${CSRBF_EXTENSION}: too many sources or cells for float indices`);
    }
    this.sourceCount = sources;
    const sourceData = new Float32Array(rows(sources) * WIDTH * 4);
    const cellData = new Int32Array(rows(cells) * WIDTH * 2);
    const listData = new Int32Array(rows(listed) * WIDTH);
    this.coefficientData = new Float32Array(rows(sources) * WIDTH * 4);
    this.deformationData = new Float32Array(rows(8 * this.deformations.length) * WIDTH * 4);
    if (groupList.length > 2 ** 24) throw new Error(`${CSRBF_EXTENSION}: more than 2^24 group numbers in all`);
    const groupData = new Int32Array(rows(groupList.length) * WIDTH);
    groupData.set(groupList);
    this.deformations.forEach((d, slot) => {
      const n = d.sources.length / 3;
      for (let i = 0; i < n; ++i)
        for (let k = 0; k < 3; ++k) sourceData[4 * (d.firstSource + i) + k] = d.sources[3 * i + k];
      const g = d.grid, cellsHere = g.dims[0] * g.dims[1] * g.dims[2];
      for (let c = 0; c < cellsHere; ++c) {
        cellData[2 * (d.firstCell + c)] = d.firstListed + g.first[c];
        cellData[2 * (d.firstCell + c) + 1] = g.count[c];
      }
      for (let k = 0; k < g.list.length; ++k) listData[d.firstListed + k] = d.firstSource + g.list[k];
      const o = 32 * slot;
      this.deformationData.set([d.radius, KERNELS[d.kernel], d.stage, d.groupsFirst < 0 ? -1 : 1], o);
      if (d.groupsFirst >= 0) this.deformationData.set([d.groupsFirst, d.groupsCount, 0, 0], o + 28);
      this.deformationData.set([g.origin[0], g.origin[1], g.origin[2], 1 / g.h], o + 4);
      this.deformationData.set([g.dims[0], g.dims[1], g.dims[2], d.firstCell], o + 8);
    });
    this.textures = {
      csrbfSources: dataTexture(sourceData, THREE.RGBAFormat, THREE.FloatType),
      csrbfCoefficients: dataTexture(this.coefficientData, THREE.RGBAFormat, THREE.FloatType),
      csrbfDeformations: dataTexture(this.deformationData, THREE.RGBAFormat, THREE.FloatType),
      csrbfCells: dataTexture(cellData, THREE.RGIntegerFormat, THREE.IntType, 'RG32I'),
      csrbfList: dataTexture(listData, THREE.RedIntegerFormat, THREE.IntType, 'R32I'),
    };
    this.textures.csrbfGroups = dataTexture(groupData, THREE.RedIntegerFormat, THREE.IntType, 'R32I');
    // The morph targets that terms replace, one texel a target (1: replaced).
    let targets = 2;
    for (const k of this.replaced) targets = Math.max(targets, k + 1);  // (no spread: a Set may be large)
    const replacedData = new Uint8Array(rows(targets) * WIDTH);
    for (const k of this.replaced) replacedData[k] = 255;
    this.textures.csrbfReplaced = dataTexture(replacedData, THREE.RedFormat, THREE.UnsignedByteType);
    this.uniforms = { csrbfDeformationCount: { value: this.deformations.length }, csrbfEnabled: { value: 1 } };
    for (const [k, t] of Object.entries(this.textures)) this.uniforms[k] = { value: t };
    this._weights = null;
    this.materials = new Set();
  }

  // The coefficients' and polynomials' sums at these weights (the mesh's morph weights).
  update(weights) {
    if (this._weights && this._weights.length === weights.length && this._weights.every((w, i) => w === weights[i])) return;
    this._weights = Array.from(weights);
    this.coefficientData.fill(0);
    this.deformations.forEach((d, slot) => {
      const o = 32 * slot;
      const poly = new Float32Array(16);
      let active = 0;
      for (const t of d.terms) {
        const w = t.weight < weights.length ? weights[t.weight] : 0;
        if (w === 0) continue;
        active = 1;
        const c = t.coefficients, n = c.length / 3;
        for (let i = 0; i < n; ++i)
          for (let k = 0; k < 3; ++k) this.coefficientData[4 * (d.firstSource + i) + k] += w * c[3 * i + k];
        if (t.polynomial)
          for (let k = 0; k < 12; ++k) poly[k + ((k / 3) | 0)] += w * t.polynomial[k];
      }
      poly[3] = active;
      this.deformationData.set(poly, o + 12);  // elements 3..6
    });
    this.textures.csrbfCoefficients.needsUpdate = true;
    this.textures.csrbfDeformations.needsUpdate = true;
  }

  // The CSRBFDeformation that plays mesh (through its material), or null.
  static of(mesh) {
    const materials = Array.isArray(mesh.material) ? mesh.material : [mesh.material];
    for (const m of materials) if (m && PLAYED_BY.has(m)) return PLAYED_BY.get(m);
    return null;
  }

  // Plays the deformations on mesh (a Mesh of a glTF mesh with the extension): its materials are
  // cloned for it and get CSRBF_GLSL; before each draw, its weights are summed. Call again after
  // setting another material on the mesh.
  attach(mesh) {
    const self = this;
    const patch = (material) => {
      if (OWNER.get(material) === mesh) return material;
      const base = BASE.get(material) || material;
      const m = base.clone();
      m.onBeforeCompile = (shader) => {
        Object.assign(shader.uniforms, self.uniforms);
        shader.vertexShader = injectCSRBF(shader.vertexShader);
      };
      m.customProgramCacheKey = () => 'csrbf-deformation';
      // Before every draw: the mesh's own weights. three.js uploads a material's uniforms when the
      // material changes between draws, so every mesh gets its own material: a clone (which shares
      // its original's) gets one at its first draw, and plays its own weights from its next frame.
      m.onBeforeRender = (renderer, scene, camera, geometry, object) => {
        self.uniforms.csrbfEnabled.value = self.enabled ? 1 : 0;
        self.uniforms.csrbfDeformationCount.value = self.enabled ? self.deformations.length : 0;
        if (self.enabled) self.update(object.morphTargetInfluences || []);
        if (object !== mesh && object.isMesh) self.attach(object);
      };
      PLAYED_BY.set(m, self);
      OWNER.set(m, mesh);
      BASE.set(m, base);
      self.materials.add(m);
      return m;
    };
    mesh.material = Array.isArray(mesh.material) ? mesh.material.map(patch) : patch(mesh.material);
    mesh.frustumCulled = false;  // the bounds are the rest shape's
    // Not enumerable: Object3D.clone copies userData through JSON, which would copy the textures' data.
    Object.defineProperty(mesh.userData, 'csrbfDeformation', { value: this, enumerable: false, configurable: true });
    return this;
  }

  // Frees the textures and forgets the materials (dispose those as usual).
  dispose() {
    for (const t of Object.values(this.textures)) t.dispose();
    for (const m of this.materials) PLAYED_BY.delete(m);
    this.materials.clear();
  }

  // The deformed positions (what = 'position') or unit normals ('normal') of mesh's vertices at
  // its current weights, computed by CSRBF_GLSL and read back from a float render target: M × 3.
  readback(renderer, mesh, what = 'position') {
    const geometry = mesh.geometry, count = geometry.attributes.position.count;
    const width = 256, height = Math.max(1, Math.ceil(count / width));
    const target = new THREE.WebGLRenderTarget(width, height, {
      type: THREE.FloatType, format: THREE.RGBAFormat, minFilter: THREE.NearestFilter,
      magFilter: THREE.NearestFilter, depthBuffer: false,
    });
    const weights = Array.from(mesh.morphTargetInfluences || []);
    this.update(weights);
    for (const k of this.replaced) if (k < weights.length) weights[k] = 0;
    const material = new THREE.ShaderMaterial({
      uniforms: { ...this.uniforms, csrbfReadWidth: { value: width }, csrbfReadHeight: { value: height },
        csrbfReadNormal: { value: what === 'normal' ? 1 : 0 } },
      vertexShader: `
        #include <common>
        #include <morphtarget_pars_vertex>
        attribute float _csrbf_group;
        ${CSRBF_GLSL}
        uniform int csrbfReadWidth, csrbfReadHeight, csrbfReadNormal;
        varying vec4 csrbfValue;
        void main() {
          vec3 objectNormal = vec3(normal);
          #include <morphnormal_vertex>
          vec3 transformed = vec3(position);
          #include <morphtarget_vertex>
          csrbfDeform(transformed, objectNormal, _csrbf_group);
          csrbfValue = vec4(csrbfReadNormal == 1 ? objectNormal : transformed, 1.0);
          vec2 at = vec2(float(gl_VertexID % csrbfReadWidth), float(gl_VertexID / csrbfReadWidth)) + 0.5;
          gl_Position = vec4(at / vec2(csrbfReadWidth, csrbfReadHeight) * 2.0 - 1.0, 0.0, 1.0);
          gl_PointSize = 1.0;
        }`,
      fragmentShader: `
        varying vec4 csrbfValue;
        void main() { gl_FragColor = csrbfValue; }`,
      depthTest: false, depthWrite: false, blending: THREE.NoBlending,
    });
    material.uniforms.csrbfDeformationCount.value = this.deformations.length;
    // Every vertex once, drawn as a point: the attributes without the primitive's index.
    const all = new THREE.BufferGeometry();
    for (const [k, a] of Object.entries(geometry.attributes)) all.setAttribute(k, a);
    all.morphAttributes = geometry.morphAttributes;
    all.morphTargetsRelative = geometry.morphTargetsRelative;
    const points = new THREE.Points(all, material);
    points.morphTargetInfluences = weights;
    points.frustumCulled = false;
    const scene = new THREE.Scene();
    scene.add(points);
    const camera = new THREE.OrthographicCamera(-1, 1, 1, -1, -1, 1);
    const before = renderer.getRenderTarget();
    renderer.setRenderTarget(target);
    renderer.setClearColor(0x000000, 0);
    renderer.clear();
    renderer.render(scene, camera);
    const pixels = new Float32Array(width * height * 4);
    renderer.readRenderTargetPixels(target, 0, 0, width, height, pixels);
    renderer.setRenderTarget(before);
    target.dispose();
    material.dispose();
    all.dispose();
    const out = new Float32Array(3 * count);
    for (let i = 0; i < count; ++i) for (let k = 0; k < 3; ++k) out[3 * i + k] = pixels[4 * i + k];
    return out;
  }
}

// A three.js vertex shader with CSRBF_GLSL run first: the position and normal after the morph
// targets that terms do not replace, deformed together at the start of main(); the material's own
// normal and position chunks then start from them (before skinning and the projection). Every
// material's shader works, lit or not.
export function injectCSRBF(vertexShader) {
  const head = `
    attribute float _csrbf_group;
    uniform int csrbfEnabled;
    uniform highp sampler2D csrbfReplaced;
    ${CSRBF_GLSL}
    bool csrbfIsReplaced(int target) {
      return csrbfEnabled == 1 &&
        texelFetch(csrbfReplaced, csrbfAt(target, textureSize(csrbfReplaced, 0).x), 0).r > 0.5;
    }
    void main() {`;
  const start = `
    vec3 csrbfPosition = vec3(position);
    vec3 csrbfNormal = vec3(normal);
    #ifdef USE_MORPHTARGETS
      csrbfPosition *= morphTargetBaseInfluence;
      #ifdef USE_MORPHNORMALS
        csrbfNormal *= morphTargetBaseInfluence;
      #endif
      for (int i = 0; i < MORPHTARGETS_COUNT; i++) {
        float w = morphTargetInfluences[i];
        if (w == 0.0 || csrbfIsReplaced(i)) continue;
        csrbfPosition += getMorph(gl_VertexID, i, 0).xyz * w;
        #ifdef USE_MORPHNORMALS
          csrbfNormal += getMorph(gl_VertexID, i, 1).xyz * w;
        #endif
      }
    #endif
    csrbfDeform(csrbfPosition, csrbfNormal, _csrbf_group);`;
  for (const chunk of ['void main() {', '#include <begin_vertex>', '#include <morphtarget_vertex>'])
    if (!vertexShader.includes(chunk))
      throw new Error(`${CSRBF_EXTENSION}: this three.js's vertex shader has no '${chunk}'`);
  return vertexShader.replace('void main() {', head + start)
    .replace('#include <beginnormal_vertex>', '#include <beginnormal_vertex>\nobjectNormal = csrbfNormal;')
    .replace('#include <morphnormal_vertex>', '')
    .replace('#include <begin_vertex>', '#include <begin_vertex>\ntransformed = csrbfPosition;')
    .replace('#include <morphtarget_vertex>', '');
}

// The GLTFLoader plugin: reads each mesh's extension (accessors through the parser) and attaches
// a CSRBFDeformation to every Mesh made of it.
export class CSRBFDeformationPlugin {
  constructor(parser) {
    this.parser = parser;
    this.name = CSRBF_EXTENSION;
  }

  async afterRoot(result) {
    const parser = this.parser, json = parser.json;
    const made = new Map();
    // Every value checked before it reaches the GPU: a malformed file is an error naming the field,
    // not a mesh drawn wrong (the same rules as csrbf::render::GltfRuntime).
    const fail = (where, why) => { throw new Error(`${CSRBF_EXTENSION}: ${where} ${why}`); };
    const integer = (x, lo, hi) => Number.isInteger(x) && x >= lo && x <= hi;
    const LARGEST = 1e30;  // coefficients and polynomials: their float sums stay finite
    const load = async (meshIndex) => {
      const mesh = json.meshes[meshIndex], ext = mesh.extensions[CSRBF_EXTENSION];
      const where = `meshes[${meshIndex}].extensions.${CSRBF_EXTENSION}`;
      const prims = Array.isArray(mesh.primitives) ? mesh.primitives : [];
      const targets = prims.length && Array.isArray(prims[0].targets) ? prims[0].targets.length : 0;
      const grouped = prims.length > 0 && prims.every((p) => p.attributes && p.attributes._CSRBF_GROUP !== undefined);
      const floats = async (index, what, largest) => {
        if (!integer(index, 0, (json.accessors || []).length - 1)) fail(what, `${JSON.stringify(index)} is not an accessor`);
        const a = await parser.getDependency('accessor', index);
        if (a.itemSize !== 3) fail(what, `(accessor ${index}) is not VEC3`);
        const out = new Float32Array(3 * a.count);
        for (let i = 0; i < a.count; ++i) { out[3 * i] = a.getX(i); out[3 * i + 1] = a.getY(i); out[3 * i + 2] = a.getZ(i); }
        for (let i = 0; i < out.length; ++i)
          if (!(Math.abs(out[i]) <= largest)) fail(what, `(accessor ${index}) holds ${out[i]} at ${Math.floor(i / 3)}`);
        return out;
      };
      if (!ext || !Array.isArray(ext.deformations) || !ext.deformations.length) fail(where, 'has no deformations');
      const deformations = [];
      for (const [di, d] of ext.deformations.entries()) {
        const dw = `${where}.deformations[${di}]`;
        const kernel = typeof d.kernel === 'string' ? d.kernel.toUpperCase() : '';
        if (!Object.prototype.hasOwnProperty.call(KERNELS, kernel)) fail(`${dw}.kernel`, `${JSON.stringify(d.kernel)} is not C0, C2, C4 or C6`);
        if (!(typeof d.radius === 'number' && d.radius >= 1e-18 && d.radius <= 1e18))
          fail(`${dw}.radius`, `${JSON.stringify(d.radius)} is not a number in [1e-18, 1e18]`);
        if (d.stage !== undefined && !integer(d.stage, 0, 65535)) fail(`${dw}.stage`, `${JSON.stringify(d.stage)} is not in 0..65535`);
        if (d.groups !== undefined) {
          if (!Array.isArray(d.groups) || !d.groups.length || !d.groups.every((g) => integer(g, 0, 65535)))
            fail(`${dw}.groups`, `${JSON.stringify(d.groups).slice(0, 60)} is not a non-empty array of group numbers`);
          if (!grouped) fail(dw, 'has groups but the mesh has no _CSRBF_GROUP');
        }
        if (!Array.isArray(d.terms) || !d.terms.length) fail(dw, 'has no terms');
        const sources = await floats(d.sources, `${dw}.sources`, 1e30);
        const terms = [];
        for (const [ti, t] of d.terms.entries()) {
          const tw = `${dw}.terms[${ti}]`;
          if (!integer(t.weight, 0, targets - 1)) fail(`${tw}.weight`, `${JSON.stringify(t.weight)} is not a morph weight of the mesh's ${targets}`);
          if (t.polynomial !== undefined && !(Array.isArray(t.polynomial) && t.polynomial.length === 12 &&
              t.polynomial.every((x) => typeof x === 'number' && Math.abs(x) <= LARGEST)))
            fail(`${tw}.polynomial`, 'is not 12 numbers of at most 1e30');
          const coefficients = await floats(t.coefficients, `${tw}.coefficients`, LARGEST);
          if (coefficients.length !== sources.length) fail(`${tw}.coefficients`, 'are not one a source');
          terms.push({ weight: t.weight, coefficients, polynomial: t.polynomial });
        }
        deformations.push({ kernel, radius: d.radius, stage: d.stage || 0, groups: d.groups, sources, terms });
      }
      return new CSRBFDeformation(deformations);
    };
    // The weights that animations give these meshes: finite (a NaN phase would draw NaN vertices).
    const animated = async () => {
      for (const [ai, an] of (json.animations || []).entries())
        for (const ch of an.channels || []) {
          if (!ch.target || ch.target.path !== 'weights') continue;
          const node = (json.nodes || [])[ch.target.node];
          if (!node || node.mesh === undefined || !((json.meshes[node.mesh] || {}).extensions || {})[CSRBF_EXTENSION]) continue;
          const out = await parser.getDependency('accessor', an.samplers[ch.sampler].output);
          for (let i = 0; i < out.array.length; ++i)
            if (!Number.isFinite(out.array[i])) fail(`animations[${ai}]`, `gives a weight of ${out.array[i]} (key ${i})`);
        }
    };
    const meshes = [];
    result.scene.traverse((o) => {
      const a = parser.associations.get(o);
      if (!o.isMesh || !a || a.meshes === undefined) return;
      const def = json.meshes[a.meshes];
      if (def && def.extensions && def.extensions[CSRBF_EXTENSION]) meshes.push([o, a.meshes]);
    });
    if (meshes.length) await animated();
    for (const [o, index] of meshes) {
      if (!made.has(index)) made.set(index, await load(index));
      made.get(index).attach(o);
    }
    result.userData.csrbfDeformations = [...new Set(made.values())];
  }
}
