// vtkCSRBFTransform in a VTK pipeline: read a mesh, warp it by a controls file, write the result.
//   csrbf-vtk-example IN.obj CONTROLS RADIUS OUT.obj
// e.g. csrbf-vtk-example examples/bunny.obj examples/bunny.controls 2.5 bunny-warped.obj
#include "csrbf/io/controls.hpp"
#include "csrbf/vtk/vtkCSRBFTransform.h"

#include <vtkNew.h>
#include <vtkOBJReader.h>
#include <vtkOBJWriter.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkTransformPolyDataFilter.h>

#include <cstdlib>
#include <iostream>

int main(int argc, char** argv) {
  if (argc != 5) {
    std::cerr << "usage: " << argv[0] << " IN.obj CONTROLS RADIUS OUT.obj\n";
    return 2;
  }
  try {
    const auto controls = csrbf::io::read_controls(argv[2]);
    vtkNew<vtkPoints> source, target;
    source->SetDataTypeToDouble();
    target->SetDataTypeToDouble();
    for (std::size_t i = 0; i < controls.sources.size(); ++i) {
      source->InsertNextPoint(controls.sources[i].data());
      target->InsertNextPoint(controls.destinations[i].data());
    }
    char* end = nullptr;
    const double radius = std::strtod(argv[3], &end);
    if (*end || !(radius > 0))
      throw std::invalid_argument(std::string("RADIUS must be a positive number, got '") + argv[3] + "'");

    vtkNew<vtkOBJReader> reader;
    reader->SetFileName(argv[1]);
    vtkNew<vtkCSRBFTransform> warp;
    warp->SetSourceLandmarks(source);
    warp->SetTargetLandmarks(target);
    warp->SetRadius(radius);
    vtkNew<vtkTransformPolyDataFilter> filter;
    filter->SetInputConnection(reader->GetOutputPort());
    filter->SetTransform(warp);
    vtkNew<vtkOBJWriter> writer;
    writer->SetInputConnection(filter->GetOutputPort());
    writer->SetFileName(argv[4]);
    writer->Write();
    if (*warp->GetLastError()) throw std::runtime_error(warp->GetLastError());
    if (filter->GetOutput()->GetNumberOfPoints() == 0)
      throw std::runtime_error(std::string(argv[1]) + ": no points read");
    std::cout << argv[1] << ": " << filter->GetOutput()->GetNumberOfPoints() << " points warped by "
              << controls.sources.size() << " controls, R = " << radius << " -> " << argv[4] << '\n';
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << '\n';
    return 1;
  }
  return 0;
}
