// The Python module `csrbf` (pybind11 over numpy): SpaceMap, DisplacementField, mesh, controls,
// deformation and scene files, and scene evaluation. Points are (n, 3) float64 or float32 arrays;
// C-contiguous inputs of either type are read in place, without a copy. Fit and evaluation release
// the GIL. docs/python.md is the tutorial.
#include "csrbf/anim/scene.hpp"
#include "csrbf/displacement_field.hpp"
#include "csrbf/errors.hpp"
#include "csrbf/estimate.hpp"
#include "csrbf/names.hpp"
#include "csrbf/io/controls.hpp"
#include "csrbf/io/deformation.hpp"
#include "csrbf/io/mesh.hpp"
#include "csrbf/io/scene.hpp"
#ifdef CSRBF_HAVE_MORPH
#include "csrbf/morph/job.hpp"
#endif
#include "csrbf/space_map.hpp"
#include "csrbf/version.hpp"
#include "arrays.hpp"
#include "interpolator_binding.hpp"

#include <nlohmann/json.hpp>
#include <pybind11/numpy.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

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

/// Checks an (n, 3) array of real numbers; `what` names the argument in messages.
/// obj as a numpy array. What numpy cannot make one of (a ragged list, a list of objects) is a
/// TypeError naming the argument, its type and length and the first element that is not three
/// numbers, never the whole value (pybind11 printed every element of a bad list).
py::array as_array(const py::object& obj, const char* what) {
  if (py::isinstance<py::array>(obj)) return py::reinterpret_borrow<py::array>(obj);
  if (py::array a = py::array::ensure(obj)) return a;  // ensure clears numpy's error when it fails
  std::ostringstream m;
  m << what << " must be an array of shape (n, 3) of numbers, got a "
    << py::str(obj.get_type().attr("__name__")).cast<std::string>();
  if (py::hasattr(obj, "__len__") && py::hasattr(obj, "__iter__")) {
    m << " of " << py::len(obj) << " elements";
    std::size_t k = 0;
    for (const py::handle item : obj) {
      bool ok = py::hasattr(item, "__len__") && py::len(item) == 3;
      if (ok)
        for (const py::handle x : item) ok = ok && (py::isinstance<py::float_>(x) || py::isinstance<py::int_>(x));
      if (!ok) {
        std::string shown = py::repr(item).cast<std::string>();
        if (shown.size() > 60) shown = shown.substr(0, 57) + "...";
        m << "; element [" << k << "] is " << csrbf::printable(shown) << " ("
          << py::str(item.get_type().attr("__name__")).cast<std::string>() << ")";
        break;
      }
      ++k;
    }
  }
  throw py::type_error(m.str());
}

void check_points(const py::array& a, const char* what, bool allow_empty = true) {
  if (a.ndim() != 2 || a.shape(1) != 3)
    throw py::value_error(std::string(what) + " must have shape (n, 3), got " + shape_of(a));
  if (!allow_empty && a.shape(0) == 0) throw py::value_error(std::string(what) + " is empty");
  const char kind = a.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u')
    throw py::type_error(std::string(what) + " must hold real numbers (float64 or float32), got dtype " +
                         std::string(py::str(a.dtype())));
}

std::vector<Vec3> to_vec3(const py::object& obj, const char* what, bool allow_empty = false) {
  const py::array a = as_array(obj, what);
  check_points(a, what, allow_empty);
  const Dbl d = ensure_array<Dbl>(a, what);
  const std::size_t n = std::size_t(d.shape(0));
  check_finite(d.data(), n, 3, what, "points must be finite");
  std::vector<Vec3> out(n);
  for (std::size_t i = 0; i < n; ++i) out[i] = Vec3(d.data()[3 * i], d.data()[3 * i + 1], d.data()[3 * i + 2]);
  return out;
}

py::array_t<double> from_vec3(const std::vector<Vec3>& v) {
  py::array_t<double> out({py::ssize_t(v.size()), py::ssize_t(3)});
  double* p = out.mutable_data();
  for (std::size_t i = 0; i < v.size(); ++i)
    for (int c = 0; c < 3; ++c) p[3 * i + std::size_t(c)] = v[i][c];
  return out;
}

/// Polygons as a list of lists of vertex indices.
py::list polygons(const csrbf::PolygonList& list) {
  py::list out;
  for (const auto face : list) {
    py::list f;
    for (const std::uint32_t v : face) f.append(v);
    out.append(std::move(f));
  }
  return out;
}

/// The value of an option enum named `text` (any case), or ValueError listing the names.
template <class E>
E named(const std::string& text, const char* what) {
  const auto v = csrbf::parse_name<E>(text);
  if (!v)
    throw py::value_error(std::string(what) + " must be one of " + csrbf::names_text<E>() + ", got '" + text + "'");
  return *v;
}

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

/// A scene and its player together (the player borrows the scene).
struct ScenePlayer {
  std::unique_ptr<csrbf::anim::Scene> scene;
  std::unique_ptr<csrbf::anim::Player> player;
};

}  // namespace

PYBIND11_MODULE(csrbf, m) {
  m.doc() = "Real-time 3D deformation by compactly supported radial basis functions (Wendland CSRBF)";
  m.attr("__version__") = csrbf::kVersion;

  static py::exception<csrbf::io::FileError> file_error(m, "FileError", PyExc_OSError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const csrbf::io::FileError& e) {
      file_error(e.what());
    } catch (const csrbf::ResourceLimit& e) {
      PyErr_SetString(PyExc_MemoryError, e.what());
    } catch (const csrbf::Error& e) {  // bad input, a failed factorisation
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });

  bind_interpolator(m);

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
                   csrbf::io::format_number(memory_limit) +
                   (memory_limit > 1e6
                        ? " (bytes? " + csrbf::io::format_number(memory_limit / double(1ull << 30)) + " GiB)"
                        : std::string()));
             o.memory_limit_bytes = memory_limit * double(1ull << 30);
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

  m.def(
      "read_mesh",
      [](const std::filesystem::path& path) {
        const auto mesh = csrbf::io::MeshDocument::load(path);
        return py::make_tuple(from_vec3(mesh.positions()), polygons(mesh.faces()));
      },
      py::arg("path"), "(positions (n, 3), faces as lists of vertex indices) of a mesh file");
  m.def(
      "write_mesh",
      [](const std::filesystem::path& template_path, const py::object& positions, const std::filesystem::path& path) {
        auto mesh = csrbf::io::MeshDocument::load(template_path);
        const auto p = to_vec3(positions, "positions");
        if (p.size() != mesh.positions().size())
          throw py::value_error("positions has " + std::to_string(p.size()) + " points but " + template_path.string() +
                                " has " + std::to_string(mesh.positions().size()));
        mesh.positions() = p;
        mesh.save(path);
      },
      py::arg("template"), py::arg("positions"), py::arg("path"),
      "Writes the mesh of `template` with new positions to `path` (format by extension, atomically)");
  m.def(
      "estimate",
      [](const py::object& sources, double radius, const std::string& solver, double memory_limit) {
        const auto s = to_vec3(sources, "sources");
        csrbf::FitOptions o;
        o.solver = named<csrbf::Solver>(solver, "solver");
        if (!(memory_limit > 0 && memory_limit <= 1e6))
          throw py::value_error("memory_limit is in GiB: a number in (0, 1e6], got " +
                                csrbf::io::format_number(memory_limit));
        o.memory_limit_bytes = memory_limit * double(1ull << 30);
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
average (from a seeded sample of 256). Example: csrbf.SpaceMap(s, d, csrbf.suggest_radius(s, 25)).)doc");
  m.def(
      "read_controls",
      [](const std::filesystem::path& path) {
        const auto c = csrbf::io::read_controls(path);
        return py::make_tuple(from_vec3(c.sources), from_vec3(c.destinations));
      },
      py::arg("path"), "(sources, destinations) of a controls text file");
  m.def(
      "read_deformation",
      [](const std::filesystem::path& path) {
        const auto d = csrbf::io::read_deformation(path);
        py::gil_scoped_release release;
        return d.fit();
      },
      py::arg("path"), "The SpaceMap of a deformation JSON file (without its active area: see apply_deformation)");
  m.def(
      "read_active_area",
      [](const std::filesystem::path& path) -> py::object {
        const auto d = csrbf::io::read_deformation(path);
        if (!d.area) return py::none();
        py::array_t<std::uint32_t> out(py::ssize_t(d.area->vertices.size()));
        std::copy(d.area->vertices.begin(), d.area->vertices.end(), out.mutable_data());
        return out;
      },
      py::arg("path"),
      "The active area of a deformation JSON file: the sorted vertex indices it moves, or None for every vertex");
  m.def(
      "apply_deformation",
      [](const std::filesystem::path& path, const py::object& positions, double phase) {
        csrbf::check_phase(phase);
        const auto d = csrbf::io::read_deformation(path);
        auto p = to_vec3(positions, "positions", true);
        if (d.area) csrbf::io::check_active_area(*d.area, p, path.string(), "positions");  // before the fit
        {
          py::gil_scoped_release release;
          csrbf::io::apply_deformation(d.fit(), d.area, p, phase);
        }
        return from_vec3(p);
      },
      py::arg("path"), py::arg("positions"), py::arg("phase") = 1.0,
      "The (n, 3) positions of a mesh's vertices moved as `csrbf deform --deformation` moves them: by the "
      "deformation file at `phase`, inside its active area only (the mesh must have the area's vertex count)");
  m.def(
      "write_deformation",
      [](const std::filesystem::path& path, const csrbf::SpaceMap& map) {
        csrbf::io::DeformationSpec d;
        d.options = csrbf::FitOptions{map.radius(), map.kernel(), map.polynomial()};
        d.sources.assign(map.sources().begin(), map.sources().end());
        d.destinations.assign(map.destinations().begin(), map.destinations().end());
        csrbf::io::write_deformation(path, d);
      },
      py::arg("path"), py::arg("map"), "Writes a SpaceMap as a deformation JSON file (atomically)");

#ifdef CSRBF_HAVE_MORPH
  m.def(
      "morph",
      [](const py::object& mesh, const py::object& motion, const std::optional<std::filesystem::path>& output,
         bool in_place, const py::object& radius, std::optional<std::string> kernel,
         std::optional<std::string> polynomial, std::optional<double> greedy, double phase, const std::string& solver,
         bool force, double memory_limit, const std::optional<py::dict>& patches, const py::object& greedy_budget,
         const py::object& time, const py::object& levels) {
        namespace mo = csrbf::morph;
        const auto is_path = [](const py::object& o) {
          return py::isinstance<py::str>(o) || py::isinstance<py::bytes>(o) || py::hasattr(o, "__fspath__");
        };
        mo::MorphJob job;
        job.in_place = in_place;
        job.write = output.has_value() || in_place;
        if (output) job.out = *output;
        if (py::isinstance<py::str>(radius) && radius.cast<std::string>() == "auto")
          job.radius_auto = true;
        else if (!radius.is_none()) {
          if (py::isinstance<py::bool_>(radius) ||
              (!py::isinstance<py::float_>(radius) && !py::isinstance<py::int_>(radius) &&
               !py::hasattr(radius, "__float__")))
            throw py::type_error("radius must be a number > 0, \"auto\" or None, got " +
                                 py::repr(radius).cast<std::string>().substr(0, 80));
          try {
            job.radius = py::float_(radius).cast<double>();
          } catch (const py::error_already_set&) {
            throw py::value_error("radius must be a finite number > 0, got " +
                                  py::repr(radius).cast<std::string>().substr(0, 80));
          }
        }
        if (kernel) job.kernel = named<csrbf::Kernel>(*kernel, "kernel");
        if (polynomial) job.polynomial = named<csrbf::Polynomial>(*polynomial, "polynomial");
        job.greedy = greedy;
        if (!greedy_budget.is_none()) {
          if (py::isinstance<py::bool_>(greedy_budget) ||
              (!py::isinstance<py::float_>(greedy_budget) && !py::isinstance<py::int_>(greedy_budget)))
            throw py::type_error("greedy_budget must be a number >= 0, got " +
                                 py::repr(greedy_budget).cast<std::string>().substr(0, 80));
          if (!greedy) throw py::value_error("greedy_budget: it bounds greedy's rounds, so give greedy= too");
          job.greedy_budget = greedy_budget.cast<double>();
        }
        if (!time.is_none()) {
          if (!is_path(mesh)) throw py::value_error("time: mesh is an array of points, which has no time folders");
          if (py::isinstance<py::str>(time))
            job.time = time.cast<std::string>();
          else if (!py::isinstance<py::bool_>(time) &&
                   (py::isinstance<py::int_>(time) || py::isinstance<py::float_>(time)))
            job.time = py::str(time).cast<std::string>();
          else
            throw py::type_error("time must be \"latest\", a time (str or number) or None, got " +
                                 py::repr(time).cast<std::string>().substr(0, 80));
          if (job.time.empty()) throw py::value_error("time: '' names no time (\"latest\" or a time such as 0.5)");
        }
        // "auto", or an integer 1 or 2 of any integer type (numpy's too, through operator.index).
        const std::string levels_text = py::repr(levels).cast<std::string>().substr(0, 80);
        if (py::isinstance<py::str>(levels)) {
          if (levels.cast<std::string>() != "auto")
            throw py::value_error("levels must be \"auto\", 1 or 2, got " + levels_text);
          job.levels = 0;
        } else {
          if (py::isinstance<py::bool_>(levels) || !py::hasattr(levels, "__index__"))
            throw py::type_error("levels must be \"auto\", 1 or 2, got " + levels_text);
          const py::object v = py::module_::import("operator").attr("index")(levels);
          if (!v.equal(py::int_(1)) && !v.equal(py::int_(2)))
            throw py::value_error("levels must be \"auto\", 1 or 2, got " + levels_text);
          job.levels = v.cast<int>();
        }
        job.solver = named<csrbf::Solver>(solver, "solver");
        job.phase = phase;
        job.force = force;
        job.memory_limit_bytes = memory_limit * double(1ull << 30);
        const bool points_given = !is_path(mesh);
        // The mesh: a file or case, or points with patches of point indices.
        mo::VolumeMesh cloud;
        if (points_given) {
          if (job.write)
            throw py::value_error(
                "output, in_place: mesh is an array of points, which has no file to write; the "
                "moved points are returned");
          if (!patches || patches->empty())
            throw py::value_error("patches: mesh is an array of points, so give patches={name: point indices}");
          cloud.points = to_vec3(mesh, "mesh");
          for (const auto& [key, value] : *patches) {
            mo::Patch p;
            if (!py::isinstance<py::str>(key))
              throw py::type_error("patches: its keys are patch names (str), got " +
                                   py::repr(key).cast<std::string>().substr(0, 80));
            p.name = key.cast<std::string>();
            p.boundary = true;
            const py::array a = py::array::ensure(value);
            if (!a || a.ndim() != 1 || (a.size() > 0 && a.dtype().kind() != 'i' && a.dtype().kind() != 'u'))
              throw py::type_error("patches['" + p.name + "'] must be a 1-D array of point indices, got " +
                                   py::repr(value).cast<std::string>().substr(0, 80));
            if (a.size() > 0 && a.dtype().kind() == 'u' && a.itemsize() == 8) {
              const auto big = py::array_t<unsigned long long, py::array::c_style | py::array::forcecast>::ensure(a);
              for (py::ssize_t k = 0; k < big.size(); ++k)
                if (big.data()[k] >= cloud.points.size())
                  throw py::value_error("patches['" + p.name + "'][" + std::to_string(k) + "] is " +
                                        std::to_string(big.data()[k]) + ": mesh has " +
                                        std::to_string(cloud.points.size()) + " points");
            }
            const auto idx = py::array_t<long long, py::array::c_style | py::array::forcecast>::ensure(a);
            for (py::ssize_t k = 0; k < idx.size(); ++k) {
              const long long i = idx.data()[k];
              if (i < 0 || std::size_t(i) >= cloud.points.size())
                throw py::value_error("patches['" + p.name + "'][" + std::to_string(k) + "] is " + std::to_string(i) +
                                      ": mesh has " + std::to_string(cloud.points.size()) + " points");
              p.points.push_back(std::uint32_t(i));
            }
            std::sort(p.points.begin(), p.points.end());
            p.points.erase(std::unique(p.points.begin(), p.points.end()), p.points.end());
            cloud.patches.push_back(std::move(p));
          }
        } else {
          if (patches) throw py::value_error("patches: only for a mesh given as an array of points");
          job.mesh = mesh.cast<std::filesystem::path>();
        }
        // The motion: a file, or a dict of the same form (numpy arrays allowed in it).
        if (is_path(motion)) {
          job.motion = motion.cast<std::filesystem::path>();
        } else if (py::isinstance<py::dict>(motion)) {
          const py::object dumps = py::module_::import("json").attr("dumps");
          const py::cpp_function plain([](const py::object& o) -> py::object {
            if (py::hasattr(o, "tolist")) return o.attr("tolist")();
            throw py::type_error("motion: " + py::repr(o).cast<std::string>().substr(0, 80) + " is not JSON");
          });
          std::string text;
          try {
            text = dumps(motion, py::arg("default") = plain, py::arg("allow_nan") = false).cast<std::string>();
          } catch (py::error_already_set& e) {
            if (!e.matches(PyExc_ValueError)) throw;
            throw py::value_error(
                "motion: a number in it is not finite (NaN or infinity): every number of a motion "
                "must be finite");
          }
          nlohmann::json j;
          try {
            j = nlohmann::json::parse(text);
          } catch (const nlohmann::json::exception& e) {
            throw py::value_error(std::string("motion: not a motion's JSON: ") + e.what());
          }
          // Points given: a patch's displacements may be rows (dx, dy, dz), one per index of the patch
          // as given.
          if (points_given && j.is_object() && j.contains("patches") && j["patches"].is_object())
            for (auto& [name, entry] : j["patches"].items()) {
              if (!entry.is_object() || !entry.contains("displacements") || !entry["displacements"].is_array())
                continue;
              auto& rows = entry["displacements"];
              if (rows.empty() || !rows[0].is_array() || rows[0].size() != 3) continue;
              const py::str key(name);
              if (!patches->contains(key))
                throw py::value_error("motion: patches." + name +
                                      ".displacements: rows (dx, dy, dz) belong to a "
                                      "patch given in patches=, and there is no '" +
                                      name + "'");
              const auto idx =
                  py::array_t<long long, py::array::c_style | py::array::forcecast>::ensure((*patches)[key]);
              if (!idx || std::size_t(idx.size()) != rows.size())
                throw py::value_error("motion: patches." + name + ".displacements has " + std::to_string(rows.size()) +
                                      " rows, patches['" + name + "'] " + std::to_string(idx ? idx.size() : 0) +
                                      " points");
              for (std::size_t k = 0; k < rows.size(); ++k) {
                if (!rows[k].is_array() || rows[k].size() != 3)
                  throw py::value_error("motion: patches." + name + ".displacements[" + std::to_string(k) +
                                        "] is not a row (dx, dy, dz)");
                rows[k].insert(rows[k].begin(), std::uint64_t(idx.data()[k]));  // checked >= 0 above
              }
            }
          try {
            job.motion_given = mo::motion_from_json(j, "motion", std::filesystem::current_path());
          } catch (const csrbf::io::FileError& e) {
            throw py::value_error(e.what());
          }
          job.motion = "motion (dict)";
        } else {
          throw py::type_error("motion must be a motion file's path or a dict of its form, got " +
                               py::repr(motion).cast<std::string>().substr(0, 80));
        }
        mo::MorphOutcome o;
        if (points_given) {
          const mo::Motion mot = job.motion_given ? *job.motion_given : mo::read_motion(job.motion);
          mo::check_job(job);  // the command's checks of the options (radius, phase, greedy, memory)
          o.mesh = "points";
          o.motion = job.motion.string();
          o.format = "points";
          o.points = cloud.points.size();
          o.patches = cloud.patches.size();
          o.options = mo::morph_options(job, mot);
          try {
            py::gil_scoped_release release;
            o.result = mo::morph(cloud, mot, o.options);
          } catch (const csrbf::io::FileError& e) {
            throw py::value_error(e.what());
          }
        } else {
          py::gil_scoped_release release;
          o = mo::run_job(job);
        }
        py::object report = py::module_::import("json").attr("loads")(mo::outcome_json(o));
        if (job.write && o.inverts && !o.written)
          throw py::value_error(job.mesh.string() + ": the morph inverts " +
                                std::to_string(o.after.inverted_cells() - o.before.inverted_cells()) +
                                " cells; the largest phase that inverts none is " + std::to_string(o.safe_phase) +
                                "; nothing written (force=True writes anyway)");
        return py::make_tuple(from_vec3(o.result.points), report);
      },
      py::arg("mesh"), py::arg("motion"), py::arg("output") = py::none(), py::arg("in_place") = false,
      py::arg("radius") = py::none(), py::arg("kernel") = py::none(), py::arg("polynomial") = py::none(),
      py::arg("greedy") = py::none(), py::arg("phase") = 1.0, py::arg("solver") = "auto", py::arg("force") = false,
      py::arg("memory_limit") = 4.0, py::arg("patches") = py::none(), py::arg("greedy_budget") = py::none(),
      py::arg("time") = py::none(), py::arg("levels") = "auto",
      R"doc(Morphs a volume mesh, or a cloud of points, as `csrbf morph` does (docs/morphing.md).

Parameters
----------
mesh : str or os.PathLike or array_like (n, 3)
    An OpenFOAM case folder, a .vtu, .vtk, .msh or .cgns file; or the points themselves, whose
    boundaries ``patches`` names.
motion : str or os.PathLike or dict
    The motion JSON file, or a dict of its form: ``{"radius": 0.5, "patches": {"wall":
    {"translate": [0, 0.01, 0]}, "far": "fixed"}}``. A patch's ``"displacements"`` may be a file,
    rows ``[point, dx, dy, dz]``, or (points given) an (k, 3) array, one row per index of
    ``patches[name]`` in its order. numpy arrays may stand anywhere in the dict.
output : str or os.PathLike, optional
    A new case folder or file to write (None: nothing is written).
in_place : bool
    Rewrite the input.
radius : float or "auto", optional
    Overrides the motion's; "auto" (the default where neither gives one) picks R from the largest
    displacement, the boundary's spacing and ``memory_limit`` (``report["radius_why"]``).
kernel, polynomial : str, optional
    Override the motion's.
greedy : float, optional
    The greedy tolerance.
greedy_budget : float, optional
    With greedy: its rounds' budget, a share of the plain fit and evaluation (default 0.2); past
    it every control is fitted (``report["greedy_stopped"]``).
levels : "auto" or int
    The fit's levels, as ``--levels``: 1, every control at R; 2, a coarse fit at R of controls R/4
    apart, then what it leaves at every control at about 1.75 x the boundary's spacing
    (``report["two_levels"]``); "auto", two where one level would pass its memory budget, or is
    predicted to take 10 s or more and 4 times as long (``report["levels_why"]``).
time : str or float, optional
    OpenFOAM: the time whose mesh is morphed, ``"latest"`` or a time such as ``0.5``, as
    ``-time``; the moved points are written into that time's folder.
patches : dict of str to array_like of int, optional
    With points: each patch's point indices.

Returns
-------
points : ndarray (n, 3)
    The moved points.
report : dict
    The report of ``csrbf morph --json``: with a mesh, the quality before and after.

A morph that inverts cells writes nothing and raises ValueError, unless force=True; without an
output it only reports them (``report["safe_phase"]``). Bad arguments raise ValueError or
TypeError naming them; a bad file raises csrbf.FileError.

Examples
--------
>>> import numpy as np, csrbf
>>> g = np.stack(np.meshgrid(*[np.linspace(0, 1, 11)] * 3, indexing="ij"), -1).reshape(-1, 3)
>>> bottom, top = np.flatnonzero(g[:, 2] == 0), np.flatnonzero(g[:, 2] == 1)
>>> moved, report = csrbf.morph(g, {"radius": 0.5, "patches": {"bottom": {"translate": [0, 0, 0.05]},
...                                 "top": "fixed"}}, patches={"bottom": bottom, "top": top})
>>> float(moved[bottom, 2].max()), bool((moved[top] == g[top]).all())
(0.05, True)
)doc");
#endif

  py::class_<ScenePlayer>(m, "Scene", "An animation scene file (docs/scene-format.md), evaluated at any time")
      .def(py::init([](const std::filesystem::path& path) {
             auto sp = std::make_unique<ScenePlayer>();
             sp->scene = std::make_unique<csrbf::anim::Scene>(csrbf::io::read_scene(path));
             sp->player = std::make_unique<csrbf::anim::Player>(*sp->scene);
             return sp;
           }),
           py::arg("path"))
      .def_property_readonly("duration", [](const ScenePlayer& s) { return s.scene->duration; })
      .def_property_readonly("fps", [](const ScenePlayer& s) { return s.scene->fps; })
      .def_property_readonly("objects",
                             [](const ScenePlayer& s) {
                               std::vector<std::string> names;
                               for (const auto& o : s.scene->objects) names.push_back(o.name);
                               return names;
                             })
      .def(
          "positions",
          [](ScenePlayer& s, double t) {
            {
              py::gil_scoped_release release;
              s.player->evaluate(t);
            }
            py::list out;
            for (std::size_t o = 0; o < s.scene->objects.size(); ++o) out.append(from_vec3(s.player->positions(o)));
            return out;
          },
          py::arg("t"), "World positions of every object's vertices at time t: a list of (n, 3) arrays")
      .def(
          "faces", [](const ScenePlayer& s, std::size_t o) { return polygons(s.scene->objects.at(o).faces); },
          py::arg("object"));
}
