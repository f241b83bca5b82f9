/* csrbf's C API: a deformation fitted once, then applied to vertex buffers as engines keep them.
 * For Unity, Godot, Rust, an OpenFOAM motion solver or any code that binds C: `extern "C"`, every
 * name prefixed csrbf_, buffers owned by the caller, a status code and a message from each call,
 * nothing thrown, and an optional allocator for what the library keeps. C89 and C++ compilers take
 * it; it includes <stddef.h> only. csrbf/engine.hpp is a header-only C++ wrapper over it.
 *
 *   csrbf_settings s;
 *   csrbf_deformer* d = NULL;
 *   csrbf_result r;
 *   csrbf_settings_default(&s);
 *   s.radius = 0.3;
 *   if (csrbf_fit(sources, destinations, n, &s, &d, &r) != CSRBF_OK) log(r.message);
 *   csrbf_vertex_buffer vb = {vertices, count, sizeof(Vertex), offsetof(Vertex, pos),
 *                             offsetof(Vertex, normal), CSRBF_FLOAT32};
 *   csrbf_deform(d, &vb, &vb, phase, &r);   (in place; in and out may also be separate)
 *   csrbf_destroy(d);
 *
 * The map is T(x) = x + phase d(x), d the CSRBF interpolant of the controls' displacements (the
 * paper's eq. 1-3; docs/ALGORITHM.md). Normals are taken through the map exactly, n' = J^-T n with
 * J = dT/dx at the vertex (scaled to the length n had). Float buffers are deformed in float where the
 * map's float check passes (normals within 1e-5 rad of double's for the smooth kernels C2-C6), else
 * in double. A fitted deformer is immutable: every call that takes it as const may run on several
 * threads at once. */
#ifndef CSRBF_H
#define CSRBF_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* What a call did. The values are those of csrbf::engine::Status. */
typedef enum csrbf_status {
  CSRBF_OK = 0,
  CSRBF_INVALID_INPUT = 1,         /* an argument, a layout or a control is not valid */
  CSRBF_DUPLICATE_SOURCE = 2,      /* two controls share a source */
  CSRBF_DEGENERATE_POLYNOMIAL = 3, /* the sources do not determine the polynomial asked for */
  CSRBF_ILL_CONDITIONED = 4,       /* the controls are too close together for the radius */
  CSRBF_NOT_POSITIVE_DEFINITE = 5, /* the solver failed */
  CSRBF_RESOURCE_LIMIT = 6,        /* the fit would pass its memory limit (said before allocating) */
  CSRBF_OUT_OF_MEMORY = 7,         /* an allocation failed */
  CSRBF_INTERNAL = 8               /* anything else (the message says what) */
} csrbf_status;

/* A call's status and, on failure, what went wrong: NUL-terminated English naming the argument or
 * control and the value; empty on success. Every call takes one (or NULL: no message). */
#define CSRBF_MESSAGE_SIZE 480
typedef struct csrbf_result {
  int status; /* a csrbf_status */
  char message[CSRBF_MESSAGE_SIZE];
} csrbf_result;

/* Wendland's functions: C0 psi_{2,0} = (1-r)^2, C2 psi_{3,1} = (1-r)^4 (4r+1) (the default), C4, C6. */
typedef enum csrbf_kernel {
  CSRBF_KERNEL_C0 = 0,
  CSRBF_KERNEL_C2 = 2,
  CSRBF_KERNEL_C4 = 4,
  CSRBF_KERNEL_C6 = 6
} csrbf_kernel;
/* NONE: strictly local (a vertex farther than R from every source keeps its bits). LINEAR: the
 * paper's, reproducing any affine map the controls admit, moving the whole space. */
typedef enum csrbf_polynomial {
  CSRBF_POLYNOMIAL_NONE = 0,
  CSRBF_POLYNOMIAL_CONSTANT = 1,
  CSRBF_POLYNOMIAL_LINEAR = 2
} csrbf_polynomial;
typedef enum csrbf_scalar { CSRBF_FLOAT32 = 0, CSRBF_FLOAT64 = 1 } csrbf_scalar;

typedef struct csrbf_settings {
  double radius;           /* radius of support R, in the sources' units (> 0) */
  int kernel;              /* a csrbf_kernel */
  int polynomial;          /* a csrbf_polynomial */
  double memory_limit_gib; /* the fit refuses (CSRBF_RESOURCE_LIMIT) beyond it, before allocating */
} csrbf_settings;

/* The defaults: radius 0 (to be set), C2, no polynomial, 4 GiB. */
void csrbf_settings_default(csrbf_settings* settings);

/* `count` vertices at `base`, each `stride` bytes after the one before; a vertex's position (3
 * scalars) at `position_offset` bytes from its start, its normal at `normal_offset` (CSRBF_NO_NORMAL:
 * none). Scalars in native byte order, aligned to their size. */
#define CSRBF_NO_NORMAL ((size_t)-1)
typedef struct csrbf_vertex_buffer {
  void* base;
  size_t count;
  size_t stride;
  size_t position_offset;
  size_t normal_offset;
  int scalar; /* a csrbf_scalar */
} csrbf_vertex_buffer;

/* A fitted deformation (opaque). */
typedef struct csrbf_deformer csrbf_deformer;

/* Fits n controls: sources and destinations as n x 3 doubles (x y z, one control after another).
 * On success *out is a new deformer (release it with csrbf_destroy); on failure *out is left as it
 * was. result may be NULL. */
csrbf_status csrbf_fit(const double* sources, const double* destinations, size_t n, const csrbf_settings* settings,
                       csrbf_deformer** out, csrbf_result* result);

/* The same sources and settings with new destinations (n x 3, n as fitted): only the solve is redone
 * (an animation's frame). *out is a new deformer; deformer stays valid. */
csrbf_status csrbf_refit(const csrbf_deformer* deformer, const double* destinations, csrbf_deformer** out,
                         csrbf_result* result);

/* Deforms the vertices of in into out at phase (normally in [0, 1]): positions T(x), normals J^-T n.
 * in and out have the same count and scalar; they may be the same buffer with one base and stride (in
 * place; the offsets may differ), or separate buffers of any layout. Buffers that overlap otherwise
 * are refused, as is a layout past the end of the address space. Where in has normals, out must have
 * them too. A NULL deformer is the identity. */
csrbf_status csrbf_deform(const csrbf_deformer* deformer, const csrbf_vertex_buffer* in, const csrbf_vertex_buffer* out,
                          double phase, csrbf_result* result);

/* The number of controls (0 for NULL). */
size_t csrbf_size(const csrbf_deformer* deformer);

/* Another owner of the same deformer (a reference count: no allocation, cannot fail); each owner
 * calls csrbf_destroy once. NULL gives NULL. */
csrbf_deformer* csrbf_share(const csrbf_deformer* deformer);

/* Releases an owner's hold; the deformer is freed with its last owner. NULL is ignored. */
void csrbf_destroy(csrbf_deformer* deformer);

/* The GPU layout: the textures that web/csrbf_deformation.glsl reads, filled for deformers the way
 * csrbf_deformation.js fills them from a CSRBF_deformation file, so that an engine plays deformers
 * with the same shader, texel for texel (tests/capi checks it against the JS module on an exported
 * fish). Every texture is CSRBF_GPU_WIDTH texels a row, element k at (k % width, k / width), and
 * at least one row:
 *   sources       RGBA32F  4 floats a texel: source k of all the deformations (x y z, 0)
 *   coefficients  RGBA32F  source k's coefficients times its deformation's weight (x y z, 0)
 *   deformations  RGBA32F  8 texels a deformation: (R, kernel, stage, -1); (grid origin, 1 / cell
 *                          side); (cells along x y z, first cell); (weight x the polynomial's
 *                          constant, 1 if the weight is not 0); the polynomial's rows for x, y, z
 *                          times the weight; (0 0 0 0)
 *   cells         RG32I    2 ints a texel: (first element in list, count) of the sources within R
 *                          of the cell; a deformation's cells are at least R wide, widened by 1.25
 *                          until it has at most 2^18
 *   list          R32I     source indices
 *   groups        R32I     (one row of zeros: deformers have no vertex groups)
 * Set the shader's csrbfDeformationCount to count. Deformations of one stage are summed, each
 * evaluated at the points the stages before produced; the layout sorts them by stage (stably).
 * A weight of 0 leaves its coefficients and polynomial 0 (the shader skips the deformation). */
#define CSRBF_GPU_WIDTH 1024
typedef struct csrbf_gpu_deformation {
  const csrbf_deformer* deformer; /* fitted, not NULL */
  double weight;                  /* the phase this frame: the coefficients and polynomial times it */
  int stage;                      /* >= 0 */
} csrbf_gpu_deformation;

/* The textures' data, allocated by the caller: each of rows x CSRBF_GPU_WIDTH texels, the rows as
 * csrbf_gpu_size sets them (floats: 4 a texel, cells: 2 ints a texel, list and groups: 1). */
typedef struct csrbf_gpu_layout {
  float* sources;
  float* coefficients;
  float* deformations;
  int* cells;
  int* list;
  int* groups;
  size_t sources_rows, coefficients_rows, deformations_rows, cells_rows, list_rows, groups_rows;
} csrbf_gpu_layout;

/* Sets layout's *_rows for these count deformations (its pointers are left as they are). Refuses a
 * layout of more than 2^24 sources or cells (the shader's float indices). */
csrbf_status csrbf_gpu_size(const csrbf_gpu_deformation* deformations, size_t count, csrbf_gpu_layout* layout,
                            csrbf_result* result);

/* Fills every texture of layout (its rows as csrbf_gpu_size set them for the same deformations;
 * every texel written, padding zero). */
csrbf_status csrbf_gpu_fill(const csrbf_gpu_deformation* deformations, size_t count, csrbf_gpu_layout* layout,
                            csrbf_result* result);

/* A new frame's weights: refills coefficients and the deformations' texels 3..6 only (upload those
 * two textures), for the same deformers and stages that csrbf_gpu_fill laid out. */
csrbf_status csrbf_gpu_update(const csrbf_gpu_deformation* deformations, size_t count, csrbf_gpu_layout* layout,
                              csrbf_result* result);

/* The allocator for the deformer handles and the scratch of csrbf_deform (as meshopt_setAllocator):
 * allocate returns memory aligned for any scalar or NULL; NULL for both restores malloc and free.
 * Set it before the first deformer is made and keep it until the last is destroyed. The fit's own
 * arrays are the C++ runtime's (operator new). */
void csrbf_set_allocator(void* (*allocate)(size_t), void (*deallocate)(void*));

/* "major.minor.patch", as csrbf --version. */
const char* csrbf_version(void);

#ifdef __cplusplus
} /* extern "C" */
#endif

#endif /* CSRBF_H */
