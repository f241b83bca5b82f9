// csrbf._core's fitted interpolant: csrbf::Interpolator (csrbf/interpolator.hpp) under
// csrbf/_interpolate.py, which checks the user's arguments, shapes the results and pickles. This layer
// takes the C-contiguous float64 arrays that module makes (float32 points too, to evaluate), checks
// their shapes again (a wrong call is a ValueError, never a read out of bounds), and runs fit and
// evaluation without the GIL in a TBB arena of `threads` threads (0: TBB's default).
#include "interpolator_binding.hpp"

#include "arrays.hpp"
#include "points.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/interpolator.hpp"
#include "csrbf/names.hpp"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <string>
#include <vector>

namespace py = pybind11;
using namespace csrbf_python;

namespace {

/// Runs f without the GIL, in an arena of `threads` threads (0: TBB's default).
template <class F>
void run_released(int threads, F&& f) {
  py::gil_scoped_release release;
  if (threads > 0) {
    tbb::task_arena arena(threads);
    arena.execute(f);
  } else {
    f();
  }
}

int threads_of(long threads) {
  if (threads < 0 || threads > 4096) throw py::value_error("threads " + std::to_string(threads) + " (0..4096)");
  return int(threads);
}

/// A C-contiguous 2-D float64 array with `cols` columns (any where cols < 0), or ValueError.
const Dbl& matrix(const Dbl& a, const char* what, py::ssize_t rows, py::ssize_t cols) {
  if (a.ndim() != 2 || (rows >= 0 && a.shape(0) != rows) || (cols >= 0 && a.shape(1) != cols))
    throw py::value_error(std::string(what) + ": shape " + shape_of(a));
  return a;
}

struct Fitted {
  csrbf::Interpolator core;
};

/// `out` as the C-contiguous writeable array of `count` elements of T that evaluate writes, or ValueError.
template <class T>
T* output_of(py::array out, std::size_t count) {
  if (!out.dtype().is(py::dtype::of<T>()) || std::size_t(out.size()) != count || !(out.flags() & py::array::c_style) ||
      !out.writeable())
    throw py::value_error("out: a writeable C-contiguous array of " + std::to_string(count) + " " +
                          (sizeof(T) == 4 ? "float32" : "float64") + " numbers, got " + shape_of(out) + " " +
                          std::string(py::str(out.dtype())));
  return static_cast<T*>(out.mutable_data());
}

/// out (Q x V) = the interpolant at x (Q x D), both of T; through a copy where out overlaps x.
template <class T>
void evaluate_into(const Fitted& f, const py::array& x_in, const py::array& out, long threads) {
  using A = py::array_t<T, py::array::c_style | py::array::forcecast>;
  const A x = ensure_array<A>(x_in, "x");
  const std::size_t d = std::size_t(f.core.dimension()), nv = f.core.value_count();
  if (x.ndim() != 2 || std::size_t(x.shape(1)) != d) throw py::value_error("x: shape " + shape_of(x));
  const std::size_t q = std::size_t(x.shape(0));
  check_finite(x.data(), q, d, "x", "must be finite");
  T* o = output_of<T>(out, q * nv);
  const void* xb = x.data();
  const bool overlap = static_cast<const void*>(o) < static_cast<const void*>(x.data() + q * d) &&
                       xb < static_cast<const void*>(o + q * nv);
  std::vector<T> staging(overlap ? q * nv : 0);
  run_released(threads_of(threads), [&] {
    f.core.evaluate(x.data(), q, overlap ? staging.data() : o);
    if (overlap) std::copy(staging.begin(), staging.end(), o);
  });
}

py::array_t<double> rows_of(const std::vector<double>& v, py::ssize_t cols) {
  const py::ssize_t rows = cols > 0 ? py::ssize_t(v.size()) / cols : 0;
  py::array_t<double> a({rows, cols});
  std::copy(v.begin(), v.begin() + rows * cols, a.mutable_data());
  return a;
}

/// Each level's figures (what stats reports); with `arrays`, also its points, alpha, beta, centre and scale.
py::list levels_of(const Fitted& f, bool arrays) {
  const auto d = py::ssize_t(f.core.dimension()), nv = py::ssize_t(f.core.value_count());
  py::list out;
  for (const auto& l : f.core.levels()) {
    py::dict e;
    e["points"] = l.points.size() / std::size_t(d);
    e["radius"] = l.radius;
    e["neighbors"] = l.mean_neighbors;
    e["solver"] = std::string(csrbf::solver_name(l.solver));
    e["iterations"] = l.iterations;
    e["residual"] = l.residual_relative;
    e["rms_before"] = l.rms_before;
    e["seconds"] = l.seconds;
    if (arrays) {
      e["points"] = rows_of(l.points, d);
      e["alpha"] = rows_of(l.alpha, nv);
      e["beta"] = rows_of(l.beta, nv);
      e["center"] = py::make_tuple(l.center.x(), l.center.y(), l.center.z());
      e["scale"] = l.scale;
    }
    out.append(e);
  }
  return out;
}

Fitted fit(const Dbl& points, const Dbl& values, const Dbl& smoothing, double radius, const std::string& kernel,
           int degree, double neighbors, int levels, double memory_limit_bytes, long threads,
           const std::string& solver) {
  matrix(points, "points", -1, -1);
  const std::size_t p = std::size_t(points.shape(0)), d = std::size_t(points.shape(1));
  matrix(values, "values", py::ssize_t(p), -1);
  const std::size_t nv = std::size_t(values.shape(1));
  if (smoothing.ndim() != 1 || (smoothing.size() > 1 && std::size_t(smoothing.size()) != p))
    throw py::value_error("smoothing: shape " + shape_of(smoothing));
  csrbf::InterpolatorOptions o;
  o.radius = radius;
  o.kernel = named<csrbf::Kernel>(kernel, "kernel");
  o.degree = degree;
  o.neighbors = neighbors;
  o.levels = levels;
  o.memory_limit_bytes = memory_limit_bytes;
  const auto sv = csrbf::parse_solver(solver);
  if (!sv)
    throw py::value_error("solver must be one of " + csrbf::names_text<csrbf::Solver>() + ", got '" + solver + "'");
  o.solver = *sv;
  o.smoothing.assign(smoothing.data(), smoothing.data() + smoothing.size());
  Fitted f;
  run_released(threads_of(threads), [&] {
    f.core = csrbf::Interpolator::fit({points.data(), p * d}, int(d), {values.data(), p * nv}, nv, o);
  });
  return f;
}

/// The interpolant of levels written by levels_of(arrays=True) (a pickle's); csrbf::Interpolator checks them.
Fitted from_levels(int dimension, std::size_t values, const std::string& kernel, int degree, const py::list& levels,
                   double seconds_fit) {
  std::vector<csrbf::InterpolatorLevel> out;
  for (const py::handle h : levels) {
    const auto e = h.cast<py::dict>();
    const auto vector = [&](const char* key) {
      const Dbl a = ensure_array<Dbl>(py::array(e[key]), key);
      return std::vector<double>(a.data(), a.data() + a.size());
    };
    csrbf::InterpolatorLevel l;
    l.radius = e["radius"].cast<double>();
    l.points = vector("points");
    l.alpha = vector("alpha");
    l.beta = vector("beta");
    const auto c = e["center"].cast<std::vector<double>>();
    if (c.size() != 3) throw py::value_error("center: " + std::to_string(c.size()) + " numbers, not 3");
    l.center = csrbf::Vec3(c[0], c[1], c[2]);
    l.scale = e["scale"].cast<double>();
    l.mean_neighbors = e["neighbors"].cast<double>();
    l.solver = csrbf::parse_solver(e["solver"].cast<std::string>()).value_or(csrbf::Solver::Auto);
    l.iterations = e["iterations"].cast<std::size_t>();
    l.residual_relative = e["residual"].cast<double>();
    l.rms_before = e["rms_before"].cast<double>();
    l.seconds = e["seconds"].cast<double>();
    out.push_back(std::move(l));
  }
  return {csrbf::Interpolator::from_levels(dimension, values, named<csrbf::Kernel>(kernel, "kernel"), degree,
                                           std::move(out), seconds_fit)};
}

}  // namespace

void bind_interpolator(py::module_& m) {
  py::class_<Fitted>(m, "_Fitted", "A fitted csrbf::Interpolator (csrbf.Interpolator holds one)")
      .def(
          "evaluate",
          [](const Fitted& f, const py::array& x, const py::array& out, long threads) {
            if (x.dtype().is(py::dtype::of<float>()) && out.dtype().is(py::dtype::of<float>()))
              evaluate_into<float>(f, x, out, threads);
            else
              evaluate_into<double>(f, x, out, threads);
          },
          py::arg("x"), py::arg("out"), py::arg("threads"),
          "out (Q x V, float32 for float32 x or float64) = the interpolant at x (Q x D)")
      .def(
          "gradient",
          [](const Fitted& f, const Dbl& x, long threads) {
            const std::size_t d = std::size_t(f.core.dimension()), nv = f.core.value_count();
            matrix(x, "x", -1, py::ssize_t(d));
            const std::size_t q = std::size_t(x.shape(0));
            check_finite(x.data(), q, d, "x", "must be finite");
            py::array_t<double> g({py::ssize_t(q), py::ssize_t(nv), py::ssize_t(d)});
            double* o = g.mutable_data();
            run_released(threads_of(threads), [&] { f.core.gradient(x.data(), q, o); });
            return g;
          },
          py::arg("x"), py::arg("threads"), "The derivatives at x (Q x D): a (Q, V, D) float64 array")
      .def("levels", &levels_of, py::arg("arrays"))
      .def_property_readonly("dimension", [](const Fitted& f) { return f.core.dimension(); })
      .def_property_readonly("value_count", [](const Fitted& f) { return f.core.value_count(); })
      .def_property_readonly("kernel", [](const Fitted& f) { return std::string(csrbf::kernel_name(f.core.kernel())); })
      .def_property_readonly("degree", [](const Fitted& f) { return f.core.degree(); })
      .def_property_readonly("size", [](const Fitted& f) { return f.core.size(); })
      .def_property_readonly("seconds_fit", [](const Fitted& f) { return f.core.seconds_fit(); });
  m.def("_fit_interpolator", &fit, py::arg("points"), py::arg("values"), py::arg("smoothing"), py::arg("radius"),
        py::arg("kernel"), py::arg("degree"), py::arg("neighbors"), py::arg("levels"), py::arg("memory_limit_bytes"),
        py::arg("threads"), py::arg("solver"),
        "csrbf::Interpolator::fit of float64 points (P x D) and values (P x V), options as checked by "
        "csrbf/_interpolate.py (radius 0: automatic; neighbors 0: the default; levels 0: automatic)");
  m.def("_interpolator_from_levels", &from_levels, py::arg("dimension"), py::arg("values"), py::arg("kernel"),
        py::arg("degree"), py::arg("levels"), py::arg("seconds_fit"),
        "The interpolant of the levels a _Fitted's levels(arrays=True) gave");
}
