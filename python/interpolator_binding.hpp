// csrbf.Interpolator's binding (interpolator.cpp), added to the module by module.cpp.
#pragma once

#include <pybind11/pybind11.h>

void bind_interpolator(pybind11::module_& m);
