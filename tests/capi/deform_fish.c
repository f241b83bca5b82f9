/* A C11 consumer of csrbf.h (built with -std=c11 -Wall -Wextra -Werror -pedantic): reads an OBJ's
 * vertices and a controls file, fits them through the C API, checks the API's promises on the way
 * (status codes and messages, the NULL deformer's identity, shared handles, refit, the allocator
 * hook), and prints the deformed vertices as "v x y z" with 17 significant digits, for
 * test_c_api.sh to hold against `csrbf deform`. With PREFIX, WEIGHT, KERNEL (0, 2, 4, 6) and
 * POLYNOMIAL (0 none, 1 constant, 2 linear) it also writes the GPU layout of that fit at that weight
 * (csrbf_gpu_fill) as PREFIX.<texture>.bin, for test_c_api.sh to hold against csrbf_deformation.js's
 * textures of the same fit exported by `csrbf export --compact`.
 *   deform_fish MESH.obj CONTROLS RADIUS [PREFIX WEIGHT KERNEL POLYNOMIAL] */
#include <csrbf/csrbf.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static size_t allocations = 0, releases = 0;
static void* counting_allocate(size_t bytes) {
  ++allocations;
  return malloc(bytes);
}
static void counting_release(void* p) {
  ++releases;
  free(p);
}

/* Appends the numbers of each line of path that starts with prefix ("v " or "" for any line that
 * holds `width` numbers); returns how many lines were read, or 0 on failure. */
static size_t read_rows(const char* path, const char* prefix, int width, double** out) {
  FILE* f = fopen(path, "r");
  char line[512];
  size_t n = 0, cap = 0;
  if (!f) return 0;
  *out = NULL;
  while (fgets(line, sizeof line, f)) {
    double v[6];
    char* p = line;
    int k;
    if (line[0] == '#' || line[0] == '\n') continue;
    if (prefix[0] && strncmp(line, prefix, strlen(prefix)) != 0) continue;
    p += strlen(prefix);
    for (k = 0; k < width; ++k) {
      char* end;
      v[k] = strtod(p, &end);
      if (end == p) break;
      p = end;
    }
    if (k != width) continue;
    if (n == cap) {
      double* grown;
      cap = cap ? 2 * cap : 1024;
      grown = (double*)realloc(*out, cap * (size_t)width * sizeof(double));
      if (!grown) {
        fclose(f);
        return 0;
      }
      *out = grown;
    }
    memcpy(*out + n * (size_t)width, v, (size_t)width * sizeof(double));
    ++n;
  }
  fclose(f);
  return n;
}

static int fail(const char* what) {
  fprintf(stderr, "deform_fish: %s\n", what);
  return 1;
}

static int write_file(const char* prefix, const char* name, const void* data, size_t bytes) {
  char path[1024];
  FILE* f;
  size_t written;
  snprintf(path, sizeof path, "%s.%s.bin", prefix, name);
  f = fopen(path, "wb");
  if (!f) return 0;
  written = fwrite(data, 1, bytes, f);
  return fclose(f) == 0 && written == bytes;
}

/* A texture's bytes: `per_texel` scalars a texel, CSRBF_GPU_WIDTH texels a row. */
static size_t texture_bytes(size_t rows, size_t per_texel, size_t scalar) {
  return rows * CSRBF_GPU_WIDTH * per_texel * scalar;
}
#define SOURCES_BYTES(l) texture_bytes((l).sources_rows, 4, sizeof(float))
#define COEFFICIENTS_BYTES(l) texture_bytes((l).coefficients_rows, 4, sizeof(float))
#define DEFORMATIONS_BYTES(l) texture_bytes((l).deformations_rows, 4, sizeof(float))
#define CELLS_BYTES(l) texture_bytes((l).cells_rows, 2, sizeof(int))
#define LIST_BYTES(l) texture_bytes((l).list_rows, 1, sizeof(int))
#define GROUPS_BYTES(l) texture_bytes((l).groups_rows, 1, sizeof(int))

/* The six textures of l's rows, allocated; 0 where one could not be. */
static int allocate_layout(csrbf_gpu_layout* l) {
  l->sources = (float*)malloc(SOURCES_BYTES(*l));
  l->coefficients = (float*)malloc(COEFFICIENTS_BYTES(*l));
  l->deformations = (float*)malloc(DEFORMATIONS_BYTES(*l));
  l->cells = (int*)malloc(CELLS_BYTES(*l));
  l->list = (int*)malloc(LIST_BYTES(*l));
  l->groups = (int*)malloc(GROUPS_BYTES(*l));
  return l->sources && l->coefficients && l->deformations && l->cells && l->list && l->groups;
}

static void free_layout(csrbf_gpu_layout* l) {
  free(l->sources);
  free(l->coefficients);
  free(l->deformations);
  free(l->cells);
  free(l->list);
  free(l->groups);
}

/* The GPU layout of the fit with these settings at weight, checked on the way (rows refused by
 * name, csrbf_gpu_update equal to a fill at the new weight), written as prefix.<texture>.bin. */
static int gpu_layout(const double* sources, const double* destinations, size_t nc, const csrbf_settings* settings,
                      double weight, const char* prefix) {
  csrbf_deformer* deformer = NULL;
  csrbf_gpu_deformation g;
  csrbf_gpu_layout l, again;
  csrbf_result result;
  int ok;
  if (csrbf_fit(sources, destinations, nc, settings, &deformer, &result) != CSRBF_OK) return fail(result.message);
  g.deformer = deformer;
  g.weight = 0.25;
  g.stage = 0;
  memset(&l, 0, sizeof l);
  if (csrbf_gpu_size(&g, 1, &l, &result) != CSRBF_OK) return fail(result.message);
  if (l.deformations_rows != 1 || l.groups_rows != 1 || l.sources_rows != l.coefficients_rows)
    return fail("csrbf_gpu_size: unexpected rows for one deformation");
  again = l;
  if (!allocate_layout(&l) || !allocate_layout(&again)) return fail("out of memory");
  /* A layout of other rows than csrbf_gpu_size's: refused by name, nothing written. */
  again.list_rows += 1;
  if (csrbf_gpu_fill(&g, 1, &again, &result) != CSRBF_INVALID_INPUT || !strstr(result.message, "layout.list_rows"))
    return fail("csrbf_gpu_fill took a layout of the wrong rows");
  again.list_rows = l.list_rows;
  g.stage = -1;
  if (csrbf_gpu_fill(&g, 1, &l, &result) != CSRBF_INVALID_INPUT || !strstr(result.message, "deformations[0].stage"))
    return fail("csrbf_gpu_fill took a negative stage");
  g.stage = 0;
  /* Filled at 0.25, then updated to the weight: the same as a fill at the weight. */
  if (csrbf_gpu_fill(&g, 1, &l, &result) != CSRBF_OK) return fail(result.message);
  g.weight = weight;
  if (csrbf_gpu_update(&g, 1, &l, &result) != CSRBF_OK) return fail(result.message);
  if (csrbf_gpu_fill(&g, 1, &again, &result) != CSRBF_OK) return fail(result.message);
  if (memcmp(again.coefficients, l.coefficients, COEFFICIENTS_BYTES(l)) ||
      memcmp(again.deformations, l.deformations, DEFORMATIONS_BYTES(l)))
    return fail("csrbf_gpu_update differs from csrbf_gpu_fill at the same weight");
  ok = write_file(prefix, "sources", l.sources, SOURCES_BYTES(l)) &&
       write_file(prefix, "coefficients", l.coefficients, COEFFICIENTS_BYTES(l)) &&
       write_file(prefix, "deformations", l.deformations, DEFORMATIONS_BYTES(l)) &&
       write_file(prefix, "cells", l.cells, CELLS_BYTES(l)) && write_file(prefix, "list", l.list, LIST_BYTES(l)) &&
       write_file(prefix, "groups", l.groups, GROUPS_BYTES(l));
  free_layout(&l);
  free_layout(&again);
  csrbf_destroy(deformer);
  return ok ? 0 : fail("cannot write the GPU layout's files");
}

int main(int argc, char** argv) {
  double *vertices = NULL, *controls = NULL, *sources, *destinations, *moved, *buffer;
  size_t nv, nc, i;
  csrbf_settings settings;
  csrbf_deformer *deformer = NULL, *shared, *again = NULL;
  csrbf_result result;
  csrbf_vertex_buffer in, out;
  if (argc != 4 && argc != 8)
    return fail("usage: deform_fish MESH.obj CONTROLS RADIUS [PREFIX WEIGHT KERNEL POLYNOMIAL]");
  nv = read_rows(argv[1], "v ", 3, &vertices);
  nc = read_rows(argv[2], "", 6, &controls);
  if (!nv || !nc) return fail("cannot read the mesh or the controls");
  csrbf_set_allocator(counting_allocate, counting_release);

  sources = (double*)malloc(nc * 3 * sizeof(double));
  destinations = (double*)malloc(nc * 3 * sizeof(double));
  moved = (double*)malloc(nc * 3 * sizeof(double));
  buffer = (double*)malloc(nv * 3 * sizeof(double));
  if (!sources || !destinations || !moved || !buffer) return fail("out of memory");
  for (i = 0; i < nc; ++i) {
    memcpy(sources + 3 * i, controls + 6 * i, 3 * sizeof(double));
    memcpy(destinations + 3 * i, controls + 6 * i + 3, 3 * sizeof(double));
    moved[3 * i] = 2 * destinations[3 * i] - sources[3 * i];
    moved[3 * i + 1] = 2 * destinations[3 * i + 1] - sources[3 * i + 1];
    moved[3 * i + 2] = 2 * destinations[3 * i + 2] - sources[3 * i + 2];
  }

  /* A bad setting: a status and a message naming it, *out untouched. */
  csrbf_settings_default(&settings);
  if (csrbf_fit(sources, destinations, nc, &settings, &deformer, &result) != CSRBF_INVALID_INPUT ||
      result.status != CSRBF_INVALID_INPUT || !strstr(result.message, "radius") || deformer != NULL)
    return fail("radius 0 was not refused by name");
  settings.kernel = 3;
  settings.radius = atof(argv[3]);
  if (csrbf_fit(sources, destinations, nc, &settings, &deformer, &result) != CSRBF_INVALID_INPUT ||
      !strstr(result.message, "settings.kernel is 3"))
    return fail("kernel 3 was not refused by name");
  settings.kernel = CSRBF_KERNEL_C2;

  if (csrbf_fit(sources, destinations, nc, &settings, &deformer, &result) != CSRBF_OK || result.message[0] != '\0') {
    fprintf(stderr, "%s\n", result.message);
    return fail("the fit failed");
  }
  if (csrbf_size(deformer) != nc || allocations != 1) return fail("size or allocation count wrong after the fit");

  /* The NULL deformer is the identity, bit for bit. */
  memcpy(buffer, vertices, nv * 3 * sizeof(double));
  in.base = buffer;
  in.count = nv;
  in.stride = 3 * sizeof(double);
  in.position_offset = 0;
  in.normal_offset = CSRBF_NO_NORMAL;
  in.scalar = CSRBF_FLOAT64;
  out = in;
  if (csrbf_deform(NULL, &in, &out, 1.0, &result) != CSRBF_OK || memcmp(buffer, vertices, nv * 3 * sizeof(double)))
    return fail("the NULL deformer moved a vertex");

  /* Refit to controls moved twice as far: at phase 1/2 the same map as the fit's at phase 1, to
   * rounding (its coefficients are exactly twice as large in exact arithmetic). */
  shared = csrbf_share(deformer);
  if (shared != deformer) return fail("csrbf_share returned another handle");
  if (csrbf_refit(shared, moved, &again, &result) != CSRBF_OK) return fail(result.message);
  csrbf_destroy(shared); /* the first owner still holds the fit */
  if (csrbf_deform(again, &in, &out, 0.5, &result) != CSRBF_OK) return fail(result.message);
  {
    double *reference = (double*)malloc(nv * 3 * sizeof(double)), worst = 0;
    csrbf_vertex_buffer r = in;
    if (!reference) return fail("out of memory");
    memcpy(reference, vertices, nv * 3 * sizeof(double));
    r.base = reference;
    if (csrbf_deform(deformer, &r, &r, 1.0, &result) != CSRBF_OK) return fail(result.message);
    for (i = 0; i < 3 * nv; ++i) worst = fmax(worst, fabs(reference[i] - buffer[i]));
    if (worst > 1e-12) return fail("the refit at phase 1/2 differs from the fit at phase 1");
    free(reference);
  }
  csrbf_destroy(again);

  /* Overlapping buffers of another layout: refused by name. */
  out.base = buffer + 1;
  if (csrbf_deform(deformer, &in, &out, 1.0, &result) != CSRBF_INVALID_INPUT || !strstr(result.message, "overlap"))
    return fail("an overlapping output was not refused");
  if (csrbf_deform(deformer, &in, &in, 1.0, NULL) != CSRBF_OK) return fail("deform with a NULL result failed");
  /* A layout whose first vertex wraps around the address space (it once wrote before base). */
  {
    csrbf_vertex_buffer wrap = in;
    wrap.count = 1;
    wrap.stride = (size_t)-1 - 3;
    wrap.position_offset = (size_t)-1 - 15;
    if (csrbf_deform(deformer, &wrap, &wrap, 1.0, &result) != CSRBF_INVALID_INPUT ||
        !strstr(result.message, "passes the end of the address space"))
      return fail("a layout past the end of the address space was not refused");
  }
  (void)out;

  if (argc == 8) {
    csrbf_settings layout_settings = settings;
    layout_settings.kernel = atoi(argv[6]);
    layout_settings.polynomial = atoi(argv[7]);
    if (gpu_layout(sources, destinations, nc, &layout_settings, atof(argv[5]), argv[4]) != 0) return 1;
  }

  /* The answer: the fit at phase 1, in place. */
  memcpy(buffer, vertices, nv * 3 * sizeof(double));
  if (csrbf_deform(deformer, &in, &in, 1.0, &result) != CSRBF_OK) return fail(result.message);
  for (i = 0; i < nv; ++i) printf("v %.17g %.17g %.17g\n", buffer[3 * i], buffer[3 * i + 1], buffer[3 * i + 2]);
  csrbf_destroy(deformer);
  if (releases != allocations || allocations < 2) return fail("the allocator hook's allocations and releases differ");
  fprintf(stderr, "deform_fish: %lu vertices, %lu controls, csrbf %s; %lu handle and scratch allocations\n",
          (unsigned long)nv, (unsigned long)nc, csrbf_version(), (unsigned long)allocations);
  free(vertices);
  free(controls);
  free(sources);
  free(destinations);
  free(moved);
  free(buffer);
  return 0;
}
