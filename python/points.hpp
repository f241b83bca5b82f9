// Points between numpy and csrbf, shared by the module's bindings (module.cpp, module_io.cpp):
// (n, 3) arrays checked and converted with messages that name the argument, and option names.
#pragma once

#include "arrays.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/names.hpp"
#include "csrbf/types.hpp"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <sstream>
#include <string>
#include <vector>

namespace csrbf_python {

namespace py = pybind11;
using csrbf::Vec3;

/// obj as a numpy array. What numpy cannot make one of (a ragged list, a list of objects) is a
/// TypeError naming the argument, its type and length and the first element that is not three
/// numbers, never the whole value (pybind11 printed every element of a bad list).
inline py::array as_array(const py::object& obj, const char* what) {
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

/// Checks an (n, 3) array of real numbers; `what` names the argument in messages.
inline void check_points(const py::array& a, const char* what, bool allow_empty = true) {
  if (a.ndim() != 2 || a.shape(1) != 3)
    throw py::value_error(std::string(what) + " must have shape (n, 3), got " + shape_of(a));
  if (!allow_empty && a.shape(0) == 0) throw py::value_error(std::string(what) + " is empty");
  const char kind = a.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u')
    throw py::type_error(std::string(what) + " must hold real numbers (float64 or float32), got dtype " +
                         std::string(py::str(a.dtype())));
}

/// The points of an (n, 3) array of finite real numbers, any dtype numpy converts (empty where allowed).
inline std::vector<Vec3> to_vec3(const py::object& obj, const char* what, bool allow_empty = false) {
  const py::array a = as_array(obj, what);
  check_points(a, what, allow_empty);
  const Dbl d = ensure_array<Dbl>(a, what);
  const std::size_t n = std::size_t(d.shape(0));
  check_finite(d.data(), n, 3, what, "points must be finite");
  std::vector<Vec3> out(n);
  for (std::size_t i = 0; i < n; ++i) out[i] = Vec3(d.data()[3 * i], d.data()[3 * i + 1], d.data()[3 * i + 2]);
  return out;
}

/// An (n, 3) float64 array of the points.
inline py::array_t<double> from_vec3(const std::vector<Vec3>& v) {
  py::array_t<double> out({py::ssize_t(v.size()), py::ssize_t(3)});
  double* p = out.mutable_data();
  for (std::size_t i = 0; i < v.size(); ++i)
    for (int c = 0; c < 3; ++c) p[3 * i + std::size_t(c)] = v[i][c];
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

}  // namespace csrbf_python
