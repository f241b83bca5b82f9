// CHOLMOD loaded on first use (private to csrbf::core).
//
// csrbf_core calls seven CHOLMOD functions, through Eigen's CholmodSupport. Linked, CHOLMOD brought
// thirteen libraries into every program that uses the core (AMD, CAMD, COLAMD, CCOLAMD, METIS,
// LAPACK, BLAS, OpenBLAS, gfortran, quadmath, gomp, SuiteSparse's config), and their loading and
// OpenBLAS's start-up (its threads) cost about 10 ms of every command, most of csrbf morph's start
// on a small case, which never factorises with CHOLMOD. Here those seven are defined as forwarders:
// the first call opens CHOLMOD (dlopen of its soname, CSRBF_CHOLMOD_SONAME, found at configure
// time) and looks the real seven up in it. cholmod_available() says whether that worked; every
// path to CHOLMOD asks it before a first call. In a process that has loaded CHOLMOD already
// (PETSc's), dlopen finds that copy and the forwarders call it.
#include "cholmod_loader.hpp"

#include <cholmod.h>
#include <dlfcn.h>

#include <cstdlib>
#include <string>

namespace csrbf::detail {
namespace {

struct Cholmod {
  void* handle = nullptr;
  int (*start)(cholmod_common*) = nullptr;
  int (*finish)(cholmod_common*) = nullptr;
  cholmod_factor* (*analyze)(cholmod_sparse*, cholmod_common*) = nullptr;
  int (*factorize_p)(cholmod_sparse*, double*, int*, size_t, cholmod_factor*, cholmod_common*) = nullptr;
  cholmod_dense* (*solve)(int, cholmod_factor*, cholmod_dense*, cholmod_common*) = nullptr;
  int (*free_dense)(cholmod_dense**, cholmod_common*) = nullptr;
  int (*free_factor)(cholmod_factor**, cholmod_common*) = nullptr;
  bool ok = false;
  std::string error;  // why not ok
};

template <class F>
void find(void* handle, F& f, const char* name, std::string& missing) {
  f = reinterpret_cast<F>(dlsym(handle, name));
  if (!f) missing += (missing.empty() ? "" : ", ") + std::string(name);
}

const Cholmod& cholmod() {
  static const Cholmod c = [] {
    Cholmod l;
    l.handle = dlopen(CSRBF_CHOLMOD_SONAME, RTLD_NOW | RTLD_LOCAL);
    if (!l.handle) {
      const char* why = dlerror();
      l.error = std::string("CHOLMOD could not be loaded (") + (why ? why : CSRBF_CHOLMOD_SONAME) + ")";
      return l;
    }
    std::string missing;
    find(l.handle, l.start, "cholmod_start", missing);
    find(l.handle, l.finish, "cholmod_finish", missing);
    find(l.handle, l.analyze, "cholmod_analyze", missing);
    find(l.handle, l.factorize_p, "cholmod_factorize_p", missing);
    find(l.handle, l.solve, "cholmod_solve", missing);
    find(l.handle, l.free_dense, "cholmod_free_dense", missing);
    find(l.handle, l.free_factor, "cholmod_free_factor", missing);
    l.ok = missing.empty();
    if (!l.ok) l.error = std::string("the CHOLMOD that was loaded (") + CSRBF_CHOLMOD_SONAME + ") lacks " + missing;
    return l;
  }();
  return c;
}

/// A forwarder called where cholmod_loaded() said no: a path that skipped the check. Not reachable
/// from csrbf's own code; never a call through a null pointer.
[[noreturn]] void missing() { std::abort(); }

}  // namespace

bool cholmod_loaded() noexcept { return cholmod().ok; }
std::string cholmod_load_error() { return cholmod().ok ? std::string() : cholmod().error; }

}  // namespace csrbf::detail

using csrbf::detail::cholmod;

extern "C" {
int cholmod_start(cholmod_common* c) {
  if (!cholmod().ok) csrbf::detail::missing();
  return cholmod().start(c);
}
int cholmod_finish(cholmod_common* c) {
  if (!cholmod().ok) csrbf::detail::missing();
  return cholmod().finish(c);
}
cholmod_factor* cholmod_analyze(cholmod_sparse* a, cholmod_common* c) {
  if (!cholmod().ok) csrbf::detail::missing();
  return cholmod().analyze(a, c);
}
int cholmod_factorize_p(cholmod_sparse* a, double beta[2], int* fset, size_t fsize, cholmod_factor* l,
                        cholmod_common* c) {
  if (!cholmod().ok) csrbf::detail::missing();
  return cholmod().factorize_p(a, beta, fset, fsize, l, c);
}
cholmod_dense* cholmod_solve(int sys, cholmod_factor* l, cholmod_dense* b, cholmod_common* c) {
  if (!cholmod().ok) csrbf::detail::missing();
  return cholmod().solve(sys, l, b, c);
}
int cholmod_free_dense(cholmod_dense** x, cholmod_common* c) {
  if (!cholmod().ok) csrbf::detail::missing();
  return cholmod().free_dense(x, c);
}
int cholmod_free_factor(cholmod_factor** l, cholmod_common* c) {
  if (!cholmod().ok) csrbf::detail::missing();
  return cholmod().free_factor(l, c);
}
}
