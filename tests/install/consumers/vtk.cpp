// Fits a SpaceMap and uses vtkCSRBFTransform from an installed csrbf; prints "ok" and exits 0 when
// both move a control's source to its destination.
#include <csrbf/space_map.hpp>
#include <csrbf/vtk/vtkCSRBFTransform.h>

#include <vtkNew.h>
#include <vtkPoints.h>

#include <cmath>
#include <iostream>
#include <vector>

int main() {
  const std::vector<csrbf::Vec3> s{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, d{{0, 0, 0.1}, {1, 0, 0}, {0, 1, 0}};
  const auto map = csrbf::SpaceMap::fit(s, d, csrbf::FitOptions{0.8});
  vtkNew<vtkPoints> src, dst;
  src->SetDataTypeToDouble();
  dst->SetDataTypeToDouble();
  for (std::size_t i = 0; i < s.size(); ++i) {
    src->InsertNextPoint(s[i].data());
    dst->InsertNextPoint(d[i].data());
  }
  vtkNew<vtkCSRBFTransform> t;
  t->SetSourceLandmarks(src);
  t->SetTargetLandmarks(dst);
  t->SetRadius(0.8);
  double out[3];
  const double in[3] = {0, 0, 0};
  t->TransformPoint(in, out);
  const bool ok = std::abs(map.map(s[0]).z() - 0.1) < 1e-12 && std::abs(out[2] - 0.1) < 1e-12;
  std::cout << (ok ? "ok" : "wrong") << '\n';
  return ok ? 0 : 1;
}
