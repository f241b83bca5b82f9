// CSRBF_deformation in a vertex shader (docs/gltf/CSRBF_deformation.md): one vertex's
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
