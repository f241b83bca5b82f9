// csrbf.Interpolator: csrbf::Interpolator (csrbf/interpolator.hpp) for numpy, in the shape of
// scipy.interpolate.RBFInterpolator. Values of any trailing shape are fitted as P x V; float32
// values give float32 results. Fit and evaluation release the GIL and run in a TBB arena of
// `threads` threads where given. Pickled as its levels' coefficients (no refit).
#include "interpolator_binding.hpp"

#include "arrays.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/interpolator.hpp"
#include "csrbf/names.hpp"
#include "csrbf/units.hpp"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <memory>
#include <sstream>

namespace py = pybind11;
using namespace csrbf_python;

namespace {

/// obj as a numpy array of real numbers, or TypeError naming the argument.
py::array real_array(const py::object& obj, const char* what) {
  py::array a;
  if (py::isinstance<py::array>(obj))
    a = py::reinterpret_borrow<py::array>(obj);
  else {
    a = py::array::ensure(obj);
    if (!a)
      throw py::type_error(std::string(what) + " must be an array of numbers, got a " +
                           py::str(obj.get_type().attr("__name__")).cast<std::string>() +
                           " that numpy cannot make one of (ragged, or not numbers)");
  }
  const char kind = a.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u' && kind != 'b')
    throw py::type_error(std::string(what) + " must hold real numbers (float64 or float32), got dtype " +
                         std::string(py::str(a.dtype())));
  if (a.dtype().itemsize() > 8 && kind == 'f')
    throw py::type_error(std::string(what) + " has dtype " + std::string(py::str(a.dtype())) +
                         ", which float64 cannot hold exactly; convert it to float64 first");
  return a;
}

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

struct PyInterpolator {
  csrbf::Interpolator core;
  std::vector<py::ssize_t> value_shape;  // the trailing shape of the values
  bool single = false;                   // float32 values: float32 results
  int threads = 0;
  bool radius_auto = true;
  double neighbors = csrbf::kDefaultNeighbors;
  std::string solver = "auto";
};

py::dtype result_dtype(const PyInterpolator& s) { return s.single ? py::dtype::of<float>() : py::dtype::of<double>(); }

/// The evaluation points as (Q, D) and whether one point (D,) was given.
std::pair<py::array, bool> query_points(const PyInterpolator& s, const py::object& obj, const char* what) {
  py::array x = real_array(obj, what);
  const py::ssize_t d = s.core.dimension();
  if (x.ndim() == 1 && x.shape(0) == d) return {x.reshape({py::ssize_t(1), d}), true};
  if (x.ndim() == 0 && d == 1) return {x.reshape({py::ssize_t(1), py::ssize_t(1)}), true};
  if (x.ndim() != 2 || x.shape(1) != d)
    throw py::value_error(std::string(what) + " must have shape (Q, " + std::to_string(d) + ") or (" +
                          std::to_string(d) + ",), for this interpolant of " + std::to_string(d) + "-D points, got " +
                          shape_of(x));
  return {x, false};
}

/// The result's array: `out` checked (shape, dtype, C-contiguous, writeable), or a new one.
py::array result_for(const py::object& out, const std::vector<py::ssize_t>& shape, const py::dtype& dtype) {
  if (out.is_none()) return py::array(dtype, shape);
  if (!py::isinstance<py::array>(out))
    throw py::type_error("out must be a numpy array, got a " +
                         py::str(out.get_type().attr("__name__")).cast<std::string>());
  const auto a = py::reinterpret_borrow<py::array>(out);
  std::ostringstream m;
  m << "out must be a writeable C-contiguous " << shape_text(shape) << " "
    << py::str(py::handle(dtype)).cast<std::string>() << " array: ";
  if (!a.dtype().is(dtype))
    m << "its dtype is " << std::string(py::str(a.dtype()));
  else if (dims_of(a) != shape)
    m << "its shape is " << shape_of(a);
  else if (!(a.flags() & py::array::c_style))
    m << "it is not C-contiguous";
  else if (!a.writeable())
    m << "it is read-only";
  else
    return a;
  throw py::value_error(m.str());
}

py::array evaluate(const PyInterpolator& s, const py::object& x_obj, const py::object& out) {
  auto [x, one] = query_points(s, x_obj, "x");
  const std::size_t q = std::size_t(x.shape(0)), d = std::size_t(s.core.dimension()), nv = s.core.value_count();
  std::vector<py::ssize_t> shape;
  if (!one) shape.push_back(py::ssize_t(q));
  shape.insert(shape.end(), s.value_shape.begin(), s.value_shape.end());
  py::array result = result_for(out, shape, result_dtype(s));
  if (s.single && x.dtype().is(py::dtype::of<float>())) {
    const Flt xf = ensure_array<Flt>(x, "x");
    check_finite(xf.data(), q, d, "x", "must be finite");
    float* o = static_cast<float*>(result.mutable_data());
    const bool overlap = static_cast<const void*>(o) < static_cast<const void*>(xf.data() + q * d) &&
                         static_cast<const void*>(xf.data()) < static_cast<const void*>(o + q * nv);
    std::vector<float> staging(overlap ? q * nv : 0);
    run_released(s.threads, [&] {
      s.core.evaluate(xf.data(), q, overlap ? staging.data() : o);
      if (overlap) std::copy(staging.begin(), staging.end(), o);
    });
    return result;
  }
  const Dbl xd = ensure_array<Dbl>(x, "x");
  check_finite(xd.data(), q, d, "x", "must be finite");
  if (!s.single) {
    double* o = static_cast<double*>(result.mutable_data());
    const bool overlap = static_cast<const void*>(o) < static_cast<const void*>(xd.data() + q * d) &&
                         static_cast<const void*>(xd.data()) < static_cast<const void*>(o + q * nv);
    std::vector<double> staging(overlap ? q * nv : 0);
    run_released(s.threads, [&] {
      s.core.evaluate(xd.data(), q, overlap ? staging.data() : o);
      if (overlap) std::copy(staging.begin(), staging.end(), o);
    });
    return result;
  }
  std::vector<double> staging(q * nv);  // float32 values at float64 points: evaluated in double
  float* o = static_cast<float*>(result.mutable_data());
  run_released(s.threads, [&] {
    s.core.evaluate(xd.data(), q, staging.data());
    for (std::size_t i = 0; i < staging.size(); ++i) o[i] = float(staging[i]);
  });
  return result;
}

py::array gradient(const PyInterpolator& s, const py::object& x_obj, const py::object& out) {
  auto [x, one] = query_points(s, x_obj, "x");
  const std::size_t q = std::size_t(x.shape(0)), d = std::size_t(s.core.dimension()), nv = s.core.value_count();
  std::vector<py::ssize_t> shape;
  if (!one) shape.push_back(py::ssize_t(q));
  shape.insert(shape.end(), s.value_shape.begin(), s.value_shape.end());
  shape.push_back(py::ssize_t(d));
  py::array result = result_for(out, shape, result_dtype(s));
  const Dbl xd = ensure_array<Dbl>(x, "x");
  check_finite(xd.data(), q, d, "x", "must be finite");
  std::vector<double> g(q * nv * d);
  run_released(s.threads, [&] { s.core.gradient(xd.data(), q, g.data()); });
  if (s.single) {
    float* o = static_cast<float*>(result.mutable_data());
    for (std::size_t i = 0; i < g.size(); ++i) o[i] = float(g[i]);
  } else {
    std::copy(g.begin(), g.end(), static_cast<double*>(result.mutable_data()));
  }
  return result;
}

py::dict stats_of(const PyInterpolator& s) {
  py::list levels;
  double worst = 0;
  for (const auto& l : s.core.levels()) {
    py::dict d;
    d["points"] = l.points.size() / std::size_t(s.core.dimension());
    d["radius"] = l.radius;
    d["neighbors"] = l.mean_neighbors;
    d["solver"] = std::string(csrbf::solver_name(l.solver));
    d["iterations"] = l.iterations;
    d["residual"] = l.residual_relative;
    d["rms_before"] = l.rms_before;
    d["seconds"] = l.seconds;
    worst = std::max(worst, l.residual_relative);
    levels.append(d);
  }
  const auto& finest = s.core.levels().back();
  py::dict d;
  d["points"] = s.core.size();
  d["dimension"] = s.core.dimension();
  d["values"] = s.core.value_count();
  d["radius"] = finest.radius;
  d["radius_auto"] = s.radius_auto;
  d["target_neighbors"] = s.neighbors;
  d["neighbors"] = finest.mean_neighbors;
  d["solver"] = std::string(csrbf::solver_name(finest.solver));
  d["iterations"] = finest.iterations;
  d["residual"] = worst;
  d["levels"] = levels;
  d["seconds_fit"] = s.core.seconds_fit();
  return d;
}

py::array_t<double> vector_array(const std::vector<double>& v, py::ssize_t rows, py::ssize_t cols) {
  py::array_t<double> a({rows, cols});
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

std::vector<double> vector_of(const py::handle& obj, const char* what) {
  const Dbl a = Dbl::ensure(obj);
  if (!a) throw py::value_error(std::string("Interpolator state: ") + what + " is not an array of numbers");
  return {a.data(), a.data() + a.size()};
}

constexpr int kStateVersion = 1;

/// The fitted interpolant behind self, or ValueError for an object whose __init__ was not called or
/// failed (Interpolator.__new__, an empty pickle): pybind11 leaves its storage unconstructed.
const PyInterpolator& self_of(const py::handle& self) {
  if (!py::isinstance<PyInterpolator>(self)) throw py::type_error("not a csrbf.Interpolator");
  auto* inst = reinterpret_cast<py::detail::instance*>(self.ptr());
  auto vh = inst->get_value_and_holder(py::detail::get_type_info(typeid(PyInterpolator)));
  if (!vh || !vh.holder_constructed() || !vh.value_ptr())
    throw py::value_error("this csrbf.Interpolator was never fitted (its __init__ was not called, or failed)");
  return *vh.template value_ptr<PyInterpolator>();
}

py::tuple get_state(const PyInterpolator& s) {
  const auto d = py::ssize_t(s.core.dimension()), nv = py::ssize_t(s.core.value_count());
  py::list levels;
  const int terms0 = s.core.degree() < 0 ? 0 : s.core.degree() == 0 ? 1 : 1 + int(d);
  for (std::size_t k = 0; k < s.core.levels().size(); ++k) {
    const auto& l = s.core.levels()[k];
    const auto n = py::ssize_t(l.points.size()) / d;
    levels.append(py::make_tuple(l.radius, vector_array(l.points, n, d), vector_array(l.alpha, n, nv),
                                 vector_array(l.beta, k == 0 ? terms0 : 0, nv),
                                 py::make_tuple(l.center.x(), l.center.y(), l.center.z()), l.scale,
                                 py::make_tuple(l.mean_neighbors, std::string(csrbf::solver_name(l.solver)),
                                                l.iterations, l.residual_relative, l.rms_before, l.seconds)));
  }
  return py::make_tuple(kStateVersion, int(d), py::cast(s.value_shape), s.single,
                        std::string(csrbf::kernel_name(s.core.kernel())), s.core.degree(), levels, s.threads,
                        s.radius_auto, s.neighbors, s.solver, s.core.seconds_fit());
}

PyInterpolator set_state_checked(const py::tuple& t) {
  if (t.size() != 12 || !py::isinstance<py::int_>(t[0]) || t[0].cast<int>() != kStateVersion)
    throw py::value_error("Interpolator state: not a state of this version of csrbf");
  PyInterpolator s;
  const int d = t[1].cast<int>();
  s.value_shape = t[2].cast<std::vector<py::ssize_t>>();
  s.single = t[3].cast<bool>();
  const auto kernel = csrbf::parse_name<csrbf::Kernel>(t[4].cast<std::string>());
  if (!kernel) throw py::value_error("Interpolator state: unknown kernel");
  const int degree = t[5].cast<int>();
  std::size_t nv = 1;
  for (py::ssize_t e : s.value_shape) {
    if (e < 1 || e > (py::ssize_t(1) << 40) || nv > (std::size_t(1) << 40))
      throw py::value_error("Interpolator state: value shape " + shape_text(s.value_shape));
    nv *= std::size_t(e);
  }
  if (s.value_shape.size() > 32) throw py::value_error("Interpolator state: value shape of too many dimensions");
  std::vector<csrbf::InterpolatorLevel> levels;
  for (const py::handle h : t[6].cast<py::list>()) {
    const auto l = h.cast<py::tuple>();
    csrbf::InterpolatorLevel lv;
    lv.radius = l[0].cast<double>();
    lv.points = vector_of(l[1], "points");
    lv.alpha = vector_of(l[2], "alpha");
    lv.beta = vector_of(l[3], "beta");
    const auto c = l[4].cast<py::tuple>();
    lv.center = csrbf::Vec3(c[0].cast<double>(), c[1].cast<double>(), c[2].cast<double>());
    lv.scale = l[5].cast<double>();
    const auto st = l[6].cast<py::tuple>();
    lv.mean_neighbors = st[0].cast<double>();
    lv.solver = csrbf::parse_solver(st[1].cast<std::string>()).value_or(csrbf::Solver::Auto);
    lv.iterations = st[2].cast<std::size_t>();
    lv.residual_relative = st[3].cast<double>();
    lv.rms_before = st[4].cast<double>();
    lv.seconds = st[5].cast<double>();
    levels.push_back(std::move(lv));
  }
  s.core = csrbf::Interpolator::from_levels(d, nv, *kernel, degree, std::move(levels), t[11].cast<double>());
  s.threads = t[7].cast<int>();
  if (s.threads < 0 || s.threads > 4096)
    throw py::value_error("Interpolator state: threads " + std::to_string(s.threads));
  s.radius_auto = t[8].cast<bool>();
  s.neighbors = t[9].cast<double>();
  s.solver = t[10].cast<std::string>();
  return s;
}

PyInterpolator set_state(const py::object& state) {
  // Every malformed state is a ValueError naming the state (not pybind11's cast or index errors).
  try {
    if (!py::isinstance<py::tuple>(state)) throw py::value_error("Interpolator state: not a tuple");
    return set_state_checked(state.cast<py::tuple>());
  } catch (const py::cast_error& e) {
    throw py::value_error(std::string("Interpolator state: malformed (") + e.what() + ")");
  } catch (const py::index_error& e) {
    throw py::value_error(std::string("Interpolator state: malformed (") + e.what() + ")");
  } catch (const py::error_already_set& e) {
    if (e.matches(PyExc_TypeError) || e.matches(PyExc_IndexError) || e.matches(PyExc_OverflowError))
      throw py::value_error(std::string("Interpolator state: malformed (") + e.what() + ")");
    throw;
  }
}

std::string short_number(double v) { return csrbf::format_significant(v, 3); }

std::string type_name(const py::handle& h) { return py::str(h.get_type().attr("__name__")).cast<std::string>(); }

/// A keyword argument's text, lower case (names are matched in any case, as the CLI's are).
std::string text_of(const py::handle& h, const char* what, const std::string& expected) {
  if (!py::isinstance<py::str>(h))
    throw py::type_error(std::string(what) + " must be " + expected + ", got a " + type_name(h));
  std::string t = h.cast<std::string>();
  for (char& c : t) c = char(std::tolower(static_cast<unsigned char>(c)));
  return t;
}
/// A real number (a Python or numpy number, not a bool or a string).
double number_of(const py::handle& h, const char* what, const std::string& expected) {
  if (py::isinstance<py::bool_>(h) || py::isinstance<py::str>(h) || !py::hasattr(h, "__float__"))
    throw py::type_error(std::string(what) + " must be " + expected + ", got a " + type_name(h));
  return py::float_(py::reinterpret_borrow<py::object>(h)).cast<double>();
}
/// An integer (a Python or numpy integer, not a bool or a float).
long integer_of(const py::handle& h, const char* what, const std::string& expected) {
  if (py::isinstance<py::bool_>(h) || !PyIndex_Check(h.ptr()))
    throw py::type_error(std::string(what) + " must be " + expected + ", got a " + type_name(h) +
                         (py::hasattr(h, "__float__") ? " (" + py::repr(h).cast<std::string>() + ")" : ""));
  const py::int_ i(py::reinterpret_borrow<py::object>(h));
  int overflow = 0;
  const long v = PyLong_AsLongAndOverflow(i.ptr(), &overflow);
  if (overflow) throw py::value_error(std::string(what) + " is out of range: " + py::repr(h).cast<std::string>());
  return v;
}

constexpr const char* kKeywords[] = {"radius", "kernel", "degree",       "smoothing", "neighbors",
                                     "levels", "method", "memory_limit", "threads",   "solver"};

PyInterpolator make(const py::args& args, const py::kwargs& kwargs) {
  // Parsed here rather than by pybind11, whose errors print every element of the arrays given.
  if (args.size() != 2)
    throw py::type_error("Interpolator() takes points and values as its two positional arguments, got " +
                         std::to_string(args.size()) +
                         (args.size() > 2 ? "; radius and the rest are keyword-only" : ""));
  const py::object points_obj = args[0], values_obj = args[1];
  py::dict kw;
  for (const auto& [key, value] : kwargs) {
    const auto name = key.cast<std::string>();
    if (std::find_if(std::begin(kKeywords), std::end(kKeywords), [&](const char* k) { return name == k; }) ==
        std::end(kKeywords)) {
      std::string hint;
      if (name == "epsilon") hint = " (SciPy's shape parameter: csrbf's kernels have a radius of support, radius=)";
      if (name == "points" || name == "values") hint = " (points and values are positional)";
      throw py::type_error("Interpolator() got an unexpected keyword argument '" + name + "'" + hint +
                           "; it takes radius, kernel, degree, smoothing, neighbors, levels, method, memory_limit, "
                           "threads and solver");
    }
    kw[key] = value;
  }
  const auto get = [&](const char* name) -> py::object {
    return kw.contains(name) ? py::object(kw[name]) : py::object(py::none());
  };
  PyInterpolator s;
  csrbf::InterpolatorOptions o;
  // Options first (cheap), then the arrays.
  if (const py::object radius = get("radius"); !radius.is_none()) {
    if (py::isinstance<py::str>(radius)) {
      const auto text = text_of(radius, "radius", "a positive number or 'auto'");
      if (text != "auto")
        throw py::value_error("radius must be a positive number or 'auto', got '" + radius.cast<std::string>() + "'");
    } else {
      o.radius = number_of(radius, "radius", "a positive number or 'auto'");
      if (!(o.radius > 0) || !std::isfinite(o.radius) || o.radius < 1e-150 || o.radius > 1e150)
        throw py::value_error("radius must be a positive finite number (within [1e-150, 1e150]) or 'auto', got " +
                              py::repr(radius).cast<std::string>());
      s.radius_auto = false;
    }
  }
  if (const py::object kernel = get("kernel"); !kernel.is_none()) {
    const auto text = text_of(kernel, "kernel", "one of " + csrbf::names_text<csrbf::Kernel>());
    const auto k = csrbf::parse_name<csrbf::Kernel>(text);
    if (!k)
      throw py::value_error("kernel must be one of " + csrbf::names_text<csrbf::Kernel>() + ", got '" +
                            kernel.cast<std::string>() + "'" +
                            (text == "thin_plate_spline" || text == "gaussian" || text == "multiquadric"
                                 ? " (SciPy's global kernels; csrbf's are Wendland's compactly supported ones)"
                                 : ""));
    o.kernel = *k;
  }
  if (const py::object degree = get("degree"); !degree.is_none()) {  // None: the default, as SciPy's
    const long d = integer_of(degree, "degree", "-1 (none), 0 or 1");
    if (d < -1 || d > 1) throw py::value_error("degree must be -1 (none), 0 or 1, got " + std::to_string(d));
    o.degree = int(d);
  }
  if (const py::object neighbors = get("neighbors"); !neighbors.is_none()) {
    o.neighbors = number_of(neighbors, "neighbors", "a positive number");
    if (!(o.neighbors > 0) || !std::isfinite(o.neighbors))
      throw py::value_error("neighbors must be a positive number, got " + py::repr(neighbors).cast<std::string>());
    // neighbors chooses the automatic radius: beside a given radius it would be ignored.
    if (!s.radius_auto)
      throw py::value_error("neighbors=" + py::repr(neighbors).cast<std::string>() +
                            " chooses the automatic radius, but radius=" + shortest(o.radius) +
                            " is given: give one of them (radius='auto' with neighbors)");
  }
  std::string method;
  if (const py::object m = get("method"); !m.is_none()) {
    method = text_of(m, "method", "'single' or 'multiscale'");
    if (method != "single" && method != "multiscale")
      throw py::value_error("method must be 'single' or 'multiscale', got '" + m.cast<std::string>() + "'");
  }
  o.levels = method == "multiscale" ? 0 : 1;
  if (const py::object levels = get("levels"); !levels.is_none()) {
    const std::string expected = "an integer 1.." + std::to_string(csrbf::kMaxLevels) + " or 'auto'";
    if (py::isinstance<py::str>(levels)) {
      if (text_of(levels, "levels", expected) != "auto")
        throw py::value_error("levels must be " + expected + ", got '" + levels.cast<std::string>() + "'");
      o.levels = 0;
    } else {
      const long l = integer_of(levels, "levels", expected);
      if (l < 1 || l > csrbf::kMaxLevels)
        throw py::value_error("levels must be within 1.." + std::to_string(csrbf::kMaxLevels) + " or 'auto', got " +
                              std::to_string(l));
      o.levels = int(l);
    }
    if (method == "single" && o.levels != 1)
      throw py::value_error("method='single' with levels=" + py::str(levels).cast<std::string>() +
                            ": several levels are the multiscale method (give levels alone, or method='multiscale')");
    if (method == "multiscale" && o.levels == 1)
      throw py::value_error("method='multiscale' with levels=1: one level is the single-scale method");
  }
  if (const py::object solver = get("solver"); !solver.is_none()) {
    const auto text = text_of(solver, "solver", "one of " + csrbf::names_text<csrbf::Solver>());
    const auto sv = csrbf::parse_solver(text);
    if (!sv)
      throw py::value_error("solver must be one of " + csrbf::names_text<csrbf::Solver>() + ", got '" +
                            solver.cast<std::string>() + "'");
    o.solver = *sv;
    s.solver = std::string(csrbf::solver_name(*sv));
  }
  if (const py::object memory_limit = get("memory_limit"); !memory_limit.is_none()) {
    const double gib = number_of(memory_limit, "memory_limit", "a number of GiB");
    if (!(gib > 0 && gib <= 1e6))
      throw py::value_error("memory_limit is in GiB, as csrbf's --memory-limit: a number in (0, 1e6], got " +
                            py::repr(memory_limit).cast<std::string>() +
                            (gib > 1e6 ? " (bytes? that is " + short_number(gib / csrbf::kGiB) + " GiB)" : ""));
    o.memory_limit_bytes = gib * csrbf::kGiB;
  }
  if (const py::object threads = get("threads"); !threads.is_none()) {
    const long t = integer_of(threads, "threads", "a positive integer");
    if (t < 1 || t > 4096)
      throw py::value_error("threads must be a positive integer (at most 4096), got " + std::to_string(t));
    s.threads = int(t);
  }
  const py::object smoothing = get("smoothing");

  const py::array points = real_array(points_obj, "points");
  if (points.ndim() != 2)
    throw py::value_error("points must have shape (P, D), D = 1, 2 or 3, got " + shape_of(points) +
                          (points.ndim() == 1 ? " (1-D data: points[:, None])" : ""));
  if (points.shape(1) > csrbf::Interpolator::kMaxDimension && points.shape(0) >= 1 &&
      points.shape(0) <= csrbf::Interpolator::kMaxDimension)
    throw py::value_error("points must have shape (P, D) with D = 1, 2 or 3, got " + shape_of(points) +
                          ": is it transposed? (points.T has shape (" + std::to_string(points.shape(1)) + ", " +
                          std::to_string(points.shape(0)) + "))");
  if (points.shape(1) < 1 || points.shape(1) > csrbf::Interpolator::kMaxDimension)
    throw py::value_error(
        "points must have shape (P, D) with D = 1, 2 or 3, got " + shape_of(points) +
        ": csrbf's Wendland kernels are positive definite only up to 3 dimensions (built for R^3); in "
        "higher dimensions the system can be singular");
  if (points.shape(0) == 0) throw py::value_error("points is empty (shape " + shape_of(points) + ")");
  const py::array values = real_array(values_obj, "values");
  if (values.ndim() < 1 || values.shape(0) != points.shape(0))
    throw py::value_error("values must have shape (P, ...) with P = " + std::to_string(points.shape(0)) +
                          " (one row a point), got " + shape_of(values));
  s.value_shape.assign(values.shape() + 1, values.shape() + values.ndim());
  s.single = values.dtype().is(py::dtype::of<float>());
  const std::size_t p = std::size_t(points.shape(0)), d = std::size_t(points.shape(1));
  std::size_t nv = 1;
  for (py::ssize_t e : s.value_shape) nv *= std::size_t(e);
  if (nv == 0) throw py::value_error("values has no value a point (shape " + shape_of(values) + ")");
  const Dbl pts = ensure_array<Dbl>(points, "points"), vals = ensure_array<Dbl>(values, "values");
  check_finite(pts.data(), p, d, "points", "must be finite");
  check_finite(vals.data(), p, nv, "values", "must be finite");
  if (!smoothing.is_none()) {
    const py::array sm = real_array(smoothing, "smoothing");
    if (!(sm.ndim() == 0 || (sm.ndim() == 1 && std::size_t(sm.shape(0)) == p)))
      throw py::value_error("smoothing must be a number or an array of shape (" + std::to_string(p) + ",), got " +
                            shape_of(sm));
    const Dbl sd = ensure_array<Dbl>(sm, "smoothing");
    for (py::ssize_t i = 0; i < sd.size(); ++i)
      if (!(sd.data()[i] >= 0) || !std::isfinite(sd.data()[i])) {
        std::ostringstream m;
        m << "smoothing" << (sm.ndim() ? "[" + std::to_string(i) + "]" : std::string()) << " is " << sd.data()[i]
          << " (must be finite and >= 0)";
        throw py::value_error(m.str());
      }
    o.smoothing.assign(sd.data(), sd.data() + sd.size());
    if (std::all_of(o.smoothing.begin(), o.smoothing.end(), [](double v) { return v == 0; })) o.smoothing.clear();
  }
  try {
    run_released(s.threads, [&] {
      s.core = csrbf::Interpolator::fit({pts.data(), p * d}, int(d), {vals.data(), p * nv}, nv, o);
    });
    s.neighbors = o.neighbors > 0              ? o.neighbors
                  : s.core.levels().size() > 1 ? csrbf::kMultiscaleNeighbors
                                               : csrbf::kDefaultNeighbors;
  } catch (const csrbf::ResourceLimit& e) {
    const std::string m = std::string(e.what()) + " [csrbf.Interpolator: memory_limit is " +
                          short_number(o.memory_limit_bytes / csrbf::kGiB) +
                          " GiB; raise it, or ask for fewer neighbors or a smaller radius]";
    PyErr_SetString(PyExc_MemoryError, m.c_str());
    throw py::error_already_set();
  }
  return s;
}

std::string repr(const PyInterpolator& s) {
  std::ostringstream os;
  os.precision(6);
  const auto& finest = s.core.levels().back();
  os << "csrbf.Interpolator(points=" << s.core.size() << ", dimension=" << s.core.dimension()
     << ", values=" << shape_text(s.value_shape) << " " << (s.single ? "float32" : "float64") << ", kernel='"
     << csrbf::kernel_name(s.core.kernel()) << "', degree=" << s.core.degree() << ", levels=" << s.core.levels().size()
     << ", radius=" << finest.radius << (s.radius_auto ? " (auto)" : "") << ", neighbors=" << finest.mean_neighbors
     << ")";
  return os.str();
}

}  // namespace

void bind_interpolator(py::module_& m) {
  py::class_<PyInterpolator>(m, "Interpolator", R"doc(
Interpolation of scattered data by compactly supported radial basis functions (Wendland).

The compact-support counterpart of ``scipy.interpolate.RBFInterpolator``: each basis function
reaches only ``radius`` from its point, so the system is sparse and evaluation touches only the
points within ``radius`` of x.

    s(x) = sum_i alpha_i phi(|x - x_i| / R) + p(x),   s(x_i) + lambda_i alpha_i = f_i

Parameters
----------
points : array_like, shape (P, D)
    The data sites, D = 1, 2 or 3 (the Wendland kernels are positive definite up to 3-D).
values : array_like, shape (P, ...)
    The data values: any trailing shape (scalars, vectors, tensors). float32 values give float32
    results; anything else float64.
radius : float or 'auto', optional
    The radius of support R in the points' units. 'auto' (default) picks R so that a point has
    ``neighbors`` others within R on average; ``stats`` says what was chosen. With several levels,
    the radius of the finest level (the thinned levels have 4 R, 8 R, ...).
kernel : {'c0', 'c2', 'c4', 'c6'}, optional
    The Wendland function (smoothness C0 to C6). Default 'c2'.
degree : {-1, 0, 1}, optional
    The polynomial: -1 none (default; strictly local: s = 0 farther than R from every point, or
    with several levels farther than the coarsest level's radius from every point of that level),
    0 a constant, 1 linear (as SciPy's thin-plate spline: data with an offset or a trend, and
    points evaluated between sparse data, want 1). None is the default.
smoothing : float or array_like of shape (P,), optional
    lambda >= 0 added to the diagonal: 0 interpolates, larger values smooth noisy data. The
    diagonal is phi(0) = 1 (or 3 for C4), so lambda is relative to 1, not to SciPy's kernel scale.
neighbors : float, optional
    The mean number of other points within the automatic radius (default 40; 50 with several
    levels). Not SciPy's ``neighbors``: compact support is the locality, nothing is looked up a
    query. With several levels, the thinned levels have about this many; the finest (every point)
    half the automatic radius, about neighbors / 2^D.
levels : int or 'auto', optional
    1 (default): one radius. n > 1: the multiscale method (Floater & Iske 1996): nested subsets of
    the points, each level fitting what the coarser ones left with half their radius, the last at
    every point; fewer where a coarser level would have fewer than 2 points (``levels`` says how
    many). 'auto': levels until the coarsest has at most 250 points (at most 8).
method : {'single', 'multiscale'}, optional
    'multiscale' is ``levels='auto'``; 'single' is ``levels=1``.
memory_limit : float, optional
    The most memory the fit may take, in GiB (default 4); beyond it MemoryError, before allocating.
threads : int, optional
    Threads for fit and evaluation (default: all cores).
solver : {'auto', 'envelope', 'eigen', 'cholmod', 'cg'}, optional
    The sparse solver (default 'auto').

Raises
------
ValueError
    Bad shapes or values (the message names the argument, its shape and the first bad element),
    duplicate points without smoothing, a degenerate polynomial, an ill-conditioned system.
TypeError
    Arguments that are not arrays of real numbers.
MemoryError
    The fit would pass ``memory_limit``.

Examples
--------
>>> import numpy as np, csrbf
>>> rng = np.random.default_rng(0)
>>> xy = rng.random((2000, 2))
>>> f = np.sin(3 * xy[:, 0]) * xy[:, 1]
>>> s = csrbf.Interpolator(xy, f, neighbors=30)
>>> float(abs(s([0.5, 0.5]) - np.sin(1.5) * 0.5)) < 1e-2
True
)doc")
      .def(py::init(&make))
      .def(
          "__call__",
          [](py::handle self, const py::object& x, const py::object& out) { return evaluate(self_of(self), x, out); },
          py::arg("x"), py::kw_only(), py::arg("out") = py::none(), R"doc(
Evaluates the interpolant.

Parameters
----------
x : array_like, shape (Q, D) or (D,)
    The points.
out : numpy.ndarray, optional
    Where to write the result: C-contiguous, writeable, of the result's shape and dtype.

Returns
-------
numpy.ndarray, shape (Q, ...) or (...)
    The values' trailing shape, in the values' dtype.

Examples
--------
>>> import numpy as np, csrbf
>>> s = csrbf.Interpolator(np.eye(3), np.arange(3.0), radius=2.0)
>>> s(np.eye(3)).round(12).tolist()
[0.0, 1.0, 2.0]
)doc")
      .def(
          "gradient",
          [](py::handle self, const py::object& x, const py::object& out) { return gradient(self_of(self), x, out); },
          py::arg("x"), py::kw_only(), py::arg("out") = py::none(), R"doc(
The derivatives of the interpolant.

Parameters
----------
x : array_like, shape (Q, D) or (D,)
out : numpy.ndarray, optional

Returns
-------
numpy.ndarray, shape (Q, ..., D) or (..., D)
    ``g[q, ..., d]`` is the derivative of the value ``[...]`` along coordinate d at x[q].

Examples
--------
>>> import numpy as np, csrbf
>>> x = np.linspace(0, 1, 50)[:, None]
>>> s = csrbf.Interpolator(x, 2 * x[:, 0], radius=0.2, degree=1)
>>> round(float(s.gradient([0.5])[0]), 6)
2.0
)doc")
      .def_property_readonly(
          "stats", [](py::handle self) { return stats_of(self_of(self)); }, R"doc(
What the fit chose and did: the radius (and whether it was automatic), the mean neighbours, the
solver, its iterations, the largest relative residual of the system, and each level's figures.

Examples
--------
>>> import numpy as np, csrbf
>>> s = csrbf.Interpolator(np.random.default_rng(1).random((500, 2)), np.ones(500), neighbors=20)
>>> round(s.stats['neighbors'])
20
)doc")
      .def_property_readonly(
          "dimension",
          [](py::handle self) {
            const PyInterpolator& s = self_of(self);
            return s.core.dimension();
          },
          "D, the dimension of the points")
      .def_property_readonly(
          "value_shape",
          [](py::handle self) {
            const PyInterpolator& s = self_of(self);
            return py::tuple(py::cast(s.value_shape));
          },
          "The trailing shape of the values")
      .def_property_readonly(
          "dtype", [](py::handle self) { return result_dtype(self_of(self)); },
          "The dtype of the results (the values')")
      .def_property_readonly(
          "kernel",
          [](py::handle self) {
            const PyInterpolator& s = self_of(self);
            return std::string(csrbf::kernel_name(s.core.kernel()));
          },
          "The Wendland kernel")
      .def_property_readonly(
          "degree",
          [](py::handle self) {
            const PyInterpolator& s = self_of(self);
            return s.core.degree();
          },
          "The polynomial's degree")
      .def_property_readonly(
          "radius",
          [](py::handle self) {
            const PyInterpolator& s = self_of(self);
            return s.core.levels().back().radius;
          },
          "The radius of support (of the finest level)")
      .def_property_readonly(
          "levels",
          [](py::handle self) {
            const PyInterpolator& s = self_of(self);
            return s.core.levels().size();
          },
          "The number of levels (1: single scale)")
      .def("__len__",
           [](py::handle self) {
             const PyInterpolator& s = self_of(self);
             return s.core.size();
           })
      .def("__repr__",
           [](py::handle self) {
             if (!py::isinstance<PyInterpolator>(self)) return std::string("<not a csrbf.Interpolator>");
             try {
               return repr(self_of(self));
             } catch (const py::value_error&) {
               return std::string("csrbf.Interpolator(not fitted)");
             }
           })
      .def(py::pickle([](py::handle self) { return py::object(get_state(self_of(self))); }, &set_state));
}
