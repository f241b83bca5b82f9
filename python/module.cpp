// csrbf._core (pybind11 over numpy): SpaceMap, DisplacementField, estimate and suggest_radius, and the
// fitted interpolant under csrbf.Interpolator (interpolator.cpp; csrbf/_interpolate.py checks its
// arguments), linked against csrbf's core alone. The file readers and writers, the morph and the scenes
// are csrbf._io (module_io.cpp, which links VTK, assimp and CGNS), which csrbf/__init__.py imports on
// first use of one of its names. Points are (n, 3) float64 or float32 arrays; C-contiguous inputs of
// either type are read in place, without a copy. Fit and evaluation release the GIL. docs/python.md is
// the tutorial.
#include "csrbf/displacement_field.hpp"
#include "csrbf/errors.hpp"
#include "csrbf/estimate.hpp"
#include "csrbf/interpolator.hpp"
#include "csrbf/names.hpp"
#include "csrbf/space_map.hpp"
#include "csrbf/version.hpp"
#include "csrbf/units.hpp"
#include "arrays.hpp"
#include "interpolator_binding.hpp"
#include "points.hpp"

#include <pybind11/numpy.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <optional>
#include <sstream>

namespace py = pybind11;
using csrbf::Vec3;
using namespace csrbf_python;

namespace {

/// The output array of apply_points: `out` when the caller gives one (checked: (n, 3), C-contiguous,
/// writeable, of the result's type), else a new one.
template <class T>
py::array_t<T> output_for(const py::object& out, std::size_t n) {
  if (out.is_none()) return py::array_t<T>({py::ssize_t(n), py::ssize_t(3)});
  if (!py::isinstance<py::array>(out)) throw py::type_error("out must be a numpy array");
  const auto a = py::reinterpret_borrow<py::array>(out);
  const char* type = std::is_same_v<T, float> ? "float32" : "float64";
  std::ostringstream m;
  m << "out must be a writeable C-contiguous (" << n << ", 3) " << type << " array: ";
  if (!a.dtype().is(py::dtype::of<T>()))
    m << "its dtype is " << std::string(py::str(a.dtype())) << " (the result of these points is " << type << ")";
  else if (a.ndim() != 2 || std::size_t(a.shape(0)) != n || a.shape(1) != 3)
    m << "its shape is " << shape_of(a);
  else if (!(a.flags() & py::array::c_style))
    m << "it is not C-contiguous (a strided view or Fortran order)";
  else if (!a.writeable())
    m << "it is read-only";
  else
    return py::reinterpret_borrow<py::array_t<T>>(a);
  throw py::value_error(m.str());
}

/// out = f(in) over (n, 3) points, float32 in float32 out, anything else in float64. Without the GIL,
/// in parallel: the finiteness check of the input, fused with the first touch of a new output's
/// pages (faults that cost 2x the evaluation of a million points when left to a scattered write).
template <class T, class F>
py::array apply_typed(const py::array& points, const char* what, const py::object& out_arg, F&& f) {
  using A = py::array_t<T, py::array::c_style | py::array::forcecast>;
  const A in = ensure_array<A>(points, what);
  const std::size_t n = std::size_t(in.shape(0));
  py::array_t<T> out = output_for<T>(out_arg, n);
  const T* i = in.data();
  T* o = out.mutable_data();
  // An out that overlaps the points without being them would be written while still being read:
  // the result goes through a temporary then (out == points itself is evaluated in place).
  const bool overlap = o != i && o < i + 3 * n && i < o + 3 * n;
  std::vector<T> staging(overlap ? 3 * n : 0);
  T* target = overlap ? staging.data() : o;
  std::size_t bad = n;
  {
    py::gil_scoped_release release;
    std::atomic<std::size_t> first_bad{n};
    const bool touch = out_arg.is_none() && static_cast<const void*>(o) != static_cast<const void*>(i);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1 << 14), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t k = r.begin(); k < r.end(); ++k)
        if (!(std::isfinite(i[3 * k]) && std::isfinite(i[3 * k + 1]) && std::isfinite(i[3 * k + 2]))) {
          std::size_t seen = first_bad.load();
          while (k < seen && !first_bad.compare_exchange_weak(seen, k)) {
          }
          break;
        }
      if (touch) std::fill(o + 3 * r.begin(), o + 3 * r.end(), T(0));
    });
    bad = first_bad.load();
    if (bad == n) {
      f(i, target, n);
      if (overlap) std::copy(staging.begin(), staging.end(), o);
    }
  }
  if (bad < n) {
    int c = 0;
    while (c < 2 && std::isfinite(i[3 * bad + std::size_t(c)])) ++c;
    std::ostringstream m;
    m << what << "[" << bad << ", " << c << "] is " << i[3 * bad + std::size_t(c)] << " (points must be finite)";
    throw py::value_error(m.str());
  }
  return out;
}

template <class F64, class F32>
py::array apply_points(const py::object& obj, const char* what, const py::object& out, F64&& f64, F32&& f32) {
  const py::array points = as_array(obj, what);
  check_points(points, what);
  if (points.dtype().is(py::dtype::of<float>())) return apply_typed<float>(points, what, out, f32);
  return apply_typed<double>(points, what, out, f64);
}

py::dict stats_dict(const csrbf::SpaceMap& m) {
  const auto& s = m.stats();
  py::dict d;
  d["controls"] = s.controls;
  d["neighbor_pairs"] = s.neighbor_pairs;
  d["mean_neighbors"] = s.mean_neighbors;
  d["ordering"] = std::string(csrbf::ordering_name(s.ordering));
  d["bandwidth"] = s.bandwidth;
  d["envelope_entries"] = s.envelope_entries;
  d["envelope_bytes"] = s.envelope_bytes;
  d["dense_bytes"] = s.dense_bytes;
  d["envelope_work"] = s.envelope_work;
  d["solver"] = std::string(csrbf::solver_name(s.solver));
  d["iterations"] = s.iterations;
  d["solver_residual"] = s.solver_residual;
  d["fell_back"] = s.fell_back;
  d["warm_start"] = s.warm_start;
  d["factor_nonzeros"] = s.factor_nonzeros;
  d["residual_max"] = s.residual_max;
  d["residual_relative"] = s.residual_relative;
  d["seconds_total"] = s.seconds_total();
  d["seconds"] = py::dict(py::arg("index") = s.seconds_index, py::arg("graph") = s.seconds_graph,
                          py::arg("ordering") = s.seconds_ordering, py::arg("assembly") = s.seconds_assembly,
                          py::arg("factorization") = s.seconds_factorization, py::arg("solve") = s.seconds_solve,
                          py::arg("residual") = s.seconds_residual);
  return d;
}

void bind_space_map(py::module_& m) {
  py::class_<csrbf::SpaceMap>(m, "SpaceMap", R"doc(
A CSRBF space mapping T(x) = x + phase * d(x), fitted to control points.

sources, destinations: (n, 3) arrays; radius: the radius of support R (> 0, in the points' units);
kernel: 'c0', 'c2' (default), 'c4' or 'c6' (Wendland); polynomial: 'none' (default, strictly
local), 'constant' or 'linear'. Keyword-only: solver: 'auto' (default), 'envelope', 'eigen',
'cholmod' or 'cg'; ordering (of the envelope solver and CG's rows): 'auto' (default),
'breadth-first', 'reverse-breadth-first', 'rcm' or 'identity'; memory_limit: the most memory the fit
may take, in GiB as `csrbf --memory-limit` takes it (a float, default 4.0; beyond it MemoryError). The fit
releases the GIL.)doc")
      .def(py::init([](const py::object& sources, const py::object& destinations, double radius,
                       const std::string& kernel, const std::string& polynomial, const std::string& solver,
                       const std::string& ordering, double memory_limit) {
             const auto s = to_vec3(sources, "sources");
             const auto d = to_vec3(destinations, "destinations");
             if (s.size() != d.size())
               throw py::value_error("sources has " + std::to_string(s.size()) + " points but destinations has " +
                                     std::to_string(d.size()));
             csrbf::FitOptions o{radius, named<csrbf::Kernel>(kernel, "kernel"),
                                 named<csrbf::Polynomial>(polynomial, "polynomial")};
             o.solver = named<csrbf::Solver>(solver, "solver");
             o.ordering = named<csrbf::Ordering>(ordering, "ordering");
             // GiB, as the command line and csrbf.morph take it (it was bytes here: a value in bytes is refused).
             if (!(memory_limit > 0 && memory_limit <= 1e6))
               throw py::value_error(
                   "memory_limit is in GiB, as csrbf's --memory-limit: a number in (0, 1e6], got " +
                   shortest(memory_limit) +
                   (memory_limit > 1e6 ? " (bytes? " + shortest(memory_limit / csrbf::kGiB) + " GiB)" : std::string()));
             o.memory_limit_bytes = memory_limit * csrbf::kGiB;
             py::gil_scoped_release release;
             return csrbf::SpaceMap::fit(s, d, o);
           }),
           py::arg("sources"), py::arg("destinations"), py::arg("radius"), py::arg("kernel") = "c2",
           py::arg("polynomial") = "none", py::kw_only(), py::arg("solver") = "auto", py::arg("ordering") = "auto",
           py::arg("memory_limit") = 4.0)
      .def(
          "with_destinations",
          [](const csrbf::SpaceMap& map, const py::object& destinations) {
            const auto d = to_vec3(destinations, "destinations");
            py::gil_scoped_release release;
            return map.with_destinations(d);
          },
          py::arg("destinations"),
          "The same sources, radius, kernel and polynomial with new destinations ((n, 3), n as fitted): only the "
          "solve is redone, with the matrix and its factor kept; where the solver is conjugate gradients they "
          "start from this map's solution (stats['warm_start']). For animation frames.")
      .def(
          "__call__",
          [](const csrbf::SpaceMap& map, const py::object& points, double phase, const py::object& out) {
            csrbf::check_phase(phase);
            return apply_points(
                points, "points", out, [&](const double* i, double* o, std::size_t n) { map.apply(i, o, n, phase); },
                [&](const float* i, float* o, std::size_t n) { map.apply(i, o, n, phase); });
          },
          py::arg("points"), py::arg("phase") = 1.0, py::kw_only(), py::arg("out") = py::none(),
          "T(points) = points + phase * d(points): an (n, 3) array of the input's float type; `out` (a "
          "C-contiguous (n, 3) array of that type, the input itself allowed) receives it instead of a new array")
      .def(
          "displacement",
          [](const csrbf::SpaceMap& map, const py::object& points, const py::object& out) {
            return apply_points(
                points, "points", out, [&](const double* i, double* o, std::size_t n) { map.displacements(i, o, n); },
                [&](const float* i, float* o, std::size_t n) { map.displacements(i, o, n); });
          },
          py::arg("points"), py::kw_only(), py::arg("out") = py::none(),
          "d(points), the displacement at phase 1: an (n, 3) array (or into `out`, as for calls)")
      .def(
          "jacobian",
          [](const csrbf::SpaceMap& map, const py::object& points, double phase) {
            csrbf::check_phase(phase);
            const auto x = to_vec3(points, "points", true);
            py::array_t<double> out({py::ssize_t(x.size()), py::ssize_t(3), py::ssize_t(3)});
            double* o = out.mutable_data();
            {
              py::gil_scoped_release release;
              for (std::size_t i = 0; i < x.size(); ++i) {
                const Eigen::Matrix3d j = map.jacobian(x[i], phase);
                for (int a = 0; a < 3; ++a)
                  for (int b = 0; b < 3; ++b) o[9 * i + std::size_t(3 * a + b)] = j(a, b);
              }
            }
            return out;
          },
          py::arg("points"), py::arg("phase") = 1.0, "dT/dx at each point: an (n, 3, 3) array, [i, a, b] = dT_a/dx_b")
      .def_property_readonly("stats", &stats_dict,
                             "What the fit did and cost (a dict): controls, neighbor_pairs, mean_neighbors, ordering, "
                             "bandwidth, envelope_entries, envelope_bytes, dense_bytes, envelope_work, solver, "
                             "iterations and solver_residual (CG), fell_back, warm_start, factor_nonzeros, "
                             "residual_max, residual_relative (at the controls), seconds_total and seconds (a "
                             "dict of the phases: index, graph, ordering, assembly, factorization, solve, "
                             "residual)")
      .def_property_readonly("radius", &csrbf::SpaceMap::radius)
      .def_property_readonly("kernel",
                             [](const csrbf::SpaceMap& m) { return std::string(csrbf::kernel_name(m.kernel())); })
      .def_property_readonly(
          "polynomial", [](const csrbf::SpaceMap& m) { return std::string(csrbf::polynomial_name(m.polynomial())); })
      .def_property_readonly(
          "sources",
          [](const csrbf::SpaceMap& m) { return from_vec3(std::vector<Vec3>(m.sources().begin(), m.sources().end())); })
      .def_property_readonly("destinations",
                             [](const csrbf::SpaceMap& m) {
                               return from_vec3(std::vector<Vec3>(m.destinations().begin(), m.destinations().end()));
                             })
      .def_property_readonly(
          "coefficients",
          [](const csrbf::SpaceMap& m) {
            const auto& c = m.coefficients();
            py::array_t<double> out({py::ssize_t(c.rows()), py::ssize_t(3)});
            for (Eigen::Index i = 0; i < c.rows(); ++i)
              for (int k = 0; k < 3; ++k) out.mutable_at(i, k) = c(i, k);
            return out;
          },
          "alpha, one row per source, in the sources' order")
      .def("__len__", &csrbf::SpaceMap::size)
      .def("__repr__", [](const csrbf::SpaceMap& m) {
        std::ostringstream s;
        s << "SpaceMap(" << m.size() << " controls, radius=" << m.radius() << ", kernel='"
          << csrbf::kernel_name(m.kernel()) << "', polynomial='" << csrbf::polynomial_name(m.polynomial()) << "')";
        return s.str();
      });
}

void bind_displacement_field(py::module_& m) {
  py::class_<csrbf::DisplacementField<double>>(m, "DisplacementField", R"doc(
Per-vertex displacements of one point set under a SpaceMap, kept so that a new phase costs one pass
over memory: field(phase) = rest + phase * d(rest).)doc")
      .def(py::init([](const csrbf::SpaceMap& map, const py::object& rest_obj) {
             const py::array rest = as_array(rest_obj, "rest");
             check_points(rest, "rest");
             const Dbl r = ensure_array<Dbl>(rest, "rest");
             check_finite(r.data(), std::size_t(r.shape(0)), 3, "rest", "points must be finite");
             py::gil_scoped_release release;
             return std::make_unique<csrbf::DisplacementField<double>>(map, r.data(), std::size_t(r.shape(0)));
           }),
           py::arg("map"), py::arg("rest"))
      .def(
          "__call__",
          [](const csrbf::DisplacementField<double>& f, double phase) {
            csrbf::check_phase(phase);
            py::array_t<double> out({py::ssize_t(f.size()), py::ssize_t(3)});
            double* o = out.mutable_data();
            py::gil_scoped_release release;
            f.apply(phase, o);
            return out;
          },
          py::arg("phase"))
      .def("update", &csrbf::DisplacementField<double>::update, py::arg("map"),
           py::call_guard<py::gil_scoped_release>(), "Recomputes d for another map over the same rest points")
      .def_property_readonly("displacements",
                             [](const csrbf::DisplacementField<double>& f) {
                               py::array_t<double> out({py::ssize_t(f.size()), py::ssize_t(3)});
                               std::copy(f.displacements().begin(), f.displacements().end(), out.mutable_data());
                               return out;
                             })
      .def("__len__", &csrbf::DisplacementField<double>::size);
}

/// estimate and suggest_radius.
void bind_estimates(py::module_& m) {
  m.def(
      "estimate",
      [](const py::object& sources, double radius, const std::string& solver, double memory_limit) {
        const auto s = to_vec3(sources, "sources");
        csrbf::FitOptions o;
        o.solver = named<csrbf::Solver>(solver, "solver");
        if (!(memory_limit > 0 && memory_limit <= 1e6))
          throw py::value_error("memory_limit is in GiB: a number in (0, 1e6], got " + shortest(memory_limit));
        o.memory_limit_bytes = memory_limit * csrbf::kGiB;
        csrbf::FitEstimate e;
        {
          py::gil_scoped_release release;
          e = csrbf::estimate(s, radius, o);
        }
        py::list solvers;
        for (const auto& x : e.solvers)
          solvers.append(py::dict(py::arg("solver") = std::string(csrbf::solver_name(x.solver)),
                                  py::arg("bytes") = x.bytes,
                                  py::arg("seconds") = std::isfinite(x.seconds) ? py::object(py::float_(x.seconds))
                                                                                : py::object(py::none()),
                                  py::arg("factor_entries") = x.factor_entries, py::arg("work") = x.work,
                                  py::arg("within_limit") = x.within_limit, py::arg("note") = x.note));
        return py::dict(py::arg("controls") = e.controls, py::arg("radius") = e.radius,
                        py::arg("mean_neighbors") = e.mean_neighbors, py::arg("max_neighbors") = e.max_neighbors,
                        py::arg("nonzeros") = e.nonzeros, py::arg("exact") = e.exact, py::arg("counted") = e.counted,
                        py::arg("auto_starts_with") = std::string(csrbf::solver_name(e.chosen)),
                        py::arg("solvers") = solvers);
      },
      py::arg("sources"), py::arg("radius"), py::kw_only(), py::arg("solver") = "auto", py::arg("memory_limit") = 4.0,
      R"doc(What a fit of these sources ((n, 3)) at `radius` would cost, without fitting: a dict with the
neighbours per control (mean, max), the matrix's non-zeros, and per solver ('envelope', 'cholmod' or
'eigen', 'cg') its predicted peak memory (bytes), time (seconds on 2 cores; None where unknown) and
whether it is within memory_limit (GiB). Example: csrbf.estimate(points, 0.05)["mean_neighbors"].)doc");
  m.def(
      "suggest_radius",
      [](const py::object& sources, double neighbours) {
        const auto s = to_vec3(sources, "sources");
        py::gil_scoped_release release;
        return csrbf::suggest_radius(s, neighbours);
      },
      py::arg("sources"), py::arg("neighbours"),
      R"doc(The radius R at which each of the sources ((n, 3)) has `neighbours` other sources within R on
average (from a seeded sample of up to 4096). Example: csrbf.SpaceMap(s, d, csrbf.suggest_radius(s, 25)).)doc");
}

/// Option names as csrbf::parse_name reads them, for csrbf/_interpolate.py.
template <class E>
void bind_names(py::dict& table, const char* kind) {
  table[kind] =
      py::make_tuple(py::cpp_function([](const std::string& text) -> py::object {
                       const auto v = csrbf::parse_name<E>(text);
                       return v ? py::object(py::str(std::string(csrbf::name_of(*v)))) : py::object(py::none());
                     }),
                     csrbf::names_text<E>());
}

}  // namespace

PYBIND11_MODULE(_core, m) {
  m.doc() =
      "csrbf's compiled core (SpaceMap, DisplacementField, estimate, suggest_radius, the interpolant): use it as csrbf";
  m.attr("__version__") = csrbf::kVersion;

  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const csrbf::ResourceLimit& e) {
      PyErr_SetString(PyExc_MemoryError, e.what());
    } catch (const csrbf::Error& e) {  // bad input, a failed factorisation
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });

  bind_space_map(m);
  bind_displacement_field(m);
  bind_estimates(m);
  bind_interpolator(m);
  py::dict names;
  bind_names<csrbf::Kernel>(names, "kernel");
  bind_names<csrbf::Solver>(names, "solver");
  m.attr("_names") = names;  // kind: (canonical name of a text or None, the names as messages list them)
  m.attr("_DEFAULT_NEIGHBORS") = csrbf::kDefaultNeighbors;
  m.attr("_MULTISCALE_NEIGHBORS") = csrbf::kMultiscaleNeighbors;
  m.attr("_MAX_LEVELS") = csrbf::kMaxLevels;
  m.attr("_MAX_DIMENSION") = csrbf::Interpolator::kMaxDimension;
#ifdef CSRBF_HAVE_MORPH
  m.attr("_HAVE_MORPH") = true;  // csrbf._io has morph
#else
  m.attr("_HAVE_MORPH") = false;
#endif
  // Named as users reach them (help(csrbf.SpaceMap) says "in module csrbf", as pickle looks them up).
  for (const char* name : {"SpaceMap", "DisplacementField", "estimate", "suggest_radius"})
    m.attr(name).attr("__module__") = "csrbf";
}
