// numpy helpers shared by the module's bindings (module.cpp, interpolator.cpp): shapes as text,
// C-contiguous arrays of one type without a silent null, and the finiteness check that names the
// first bad element.
#pragma once

#include <pybind11/numpy.h>
#include "csrbf/units.hpp"

#include <charconv>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

namespace csrbf_python {

namespace py = pybind11;

using Dbl = py::array_t<double, py::array::c_style | py::array::forcecast>;
using Flt = py::array_t<float, py::array::c_style | py::array::forcecast>;

/// The shortest text that reads back as v.
inline std::string shortest(double v) { return csrbf::format_shortest(v); }

/// A shape as numpy prints it: (3,), (2, 3), ().
inline std::string shape_text(const std::vector<py::ssize_t>& s) {
  std::ostringstream os;
  os << "(";
  for (std::size_t i = 0; i < s.size(); ++i) os << (i ? ", " : "") << s[i];
  os << (s.size() == 1 ? ",)" : ")");
  return os.str();
}
inline std::vector<py::ssize_t> dims_of(const py::array& a) { return {a.shape(), a.shape() + a.ndim()}; }
inline std::string shape_of(const py::array& a) { return shape_text(dims_of(a)); }

/// A C-contiguous array of A's type, reading a in place where it already is one. A copy numpy
/// cannot make (a broadcast view of 2**40 rows) is a MemoryError, not a null array.
template <class A>
A ensure_array(const py::array& a, const char* what) {
  A r = A::ensure(a);
  if (!r) {
    std::ostringstream m;
    m << what << ": cannot make a contiguous copy of " << shape_of(a) << " points ("
      << double(a.size()) * double(sizeof(typename A::value_type)) / csrbf::kGiB << " GiB)";
    PyErr_SetString(PyExc_MemoryError, m.str().c_str());
    throw py::error_already_set();
  }
  return r;
}

/// ValueError naming the first element of the n x width array p that is not finite:
/// "what[i, j] is nan (rule)".
template <class T>
void check_finite(const T* p, std::size_t n, std::size_t width, const char* what, const char* rule) {
  for (std::size_t i = 0; i < n * width; ++i)
    if (!std::isfinite(p[i])) {
      std::ostringstream m;
      m << what << "[" << i / width << ", " << i % width << "] is " << p[i] << " (" << rule << ")";
      throw py::value_error(m.str());
    }
}

}  // namespace csrbf_python
