#include "texture_coordinates.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/io/error.hpp"

#include <vtkCallbackCommand.h>
#include <vtkCellArray.h>
#include <vtkCommand.h>
#include <vtkImageData.h>
#include <vtkImageReader2.h>
#include <vtkImageReader2Factory.h>
#include <vtkDataSetAlgorithm.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkTextureMapToCylinder.h>
#include <vtkTextureMapToPlane.h>
#include <vtkTextureMapToSphere.h>

#include <cmath>

namespace csrbf::render {

vtkSmartPointer<vtkDataArray> texture_coordinates(vtkPolyData* rest, anim::TextureMapping mapping) {
  vtkSmartPointer<vtkDataSetAlgorithm> map;
  switch (mapping) {
    case anim::TextureMapping::Sphere:
      map = vtkSmartPointer<vtkTextureMapToSphere>::New();
      break;
    case anim::TextureMapping::Plane:
      map = vtkSmartPointer<vtkTextureMapToPlane>::New();
      break;
    case anim::TextureMapping::Cylinder:
      map = vtkSmartPointer<vtkTextureMapToCylinder>::New();
      break;
  }
  map->SetInputData(rest);
  map->Update();
  // A surface the mapping cannot be fitted to (all its points on one line or at one point: "bad
  // cylinder axis", a plane through a line) gives no coordinates, or NaN ones.
  vtkSmartPointer<vtkDataArray> st = map->GetOutput()->GetPointData()->GetTCoords();
  bool finite = st != nullptr && st->GetNumberOfTuples() == rest->GetNumberOfPoints();
  for (vtkIdType i = 0; finite && i < st->GetNumberOfTuples(); ++i)
    finite = std::isfinite(st->GetComponent(i, 0)) && std::isfinite(st->GetComponent(i, 1));
  if (!finite) {
    const char* name = mapping == anim::TextureMapping::Sphere  ? "sphere"
                       : mapping == anim::TextureMapping::Plane ? "plane"
                                                                : "cylinder";
    throw InvalidInput(
        std::string("texture_mapping '") + name +
        "' cannot be fitted to this surface (its points lie on a line or at a point): no texture coordinates");
  }
  return st;
}

std::vector<float> texture_coordinates(const anim::Object& obj, const std::vector<std::uint32_t>& faces,
                                       anim::TextureMapping mapping) {
  // The renderer's surface: every rest vertex as float (its points are single precision), these faces.
  vtkNew<vtkPoints> pts;
  pts->SetDataTypeToFloat();
  pts->SetNumberOfPoints(vtkIdType(obj.rest.size()));
  for (std::size_t i = 0; i < obj.rest.size(); ++i)
    pts->SetPoint(vtkIdType(i), obj.rest[i].x(), obj.rest[i].y(), obj.rest[i].z());
  vtkNew<vtkCellArray> cells;
  for (const auto f : faces) {
    const auto poly = obj.faces[f];
    cells->InsertNextCell(vtkIdType(poly.size()));
    for (const auto v : poly) cells->InsertCellPoint(vtkIdType(v));
  }
  vtkNew<vtkPolyData> surface;
  surface->SetPoints(pts);
  surface->SetPolys(cells);
  const vtkSmartPointer<vtkDataArray> st = texture_coordinates(surface, mapping);
  std::vector<float> uv(2 * obj.rest.size());
  for (std::size_t i = 0; i < obj.rest.size(); ++i) {
    uv[2 * i] = float(st->GetComponent(vtkIdType(i), 0));
    uv[2 * i + 1] = float(1.0 - st->GetComponent(vtkIdType(i), 1));
  }
  return uv;
}

void check_image_decodes(const std::string& file) {
  vtkNew<vtkImageReader2Factory> factory;
  vtkSmartPointer<vtkImageReader2> reader;
  reader.TakeReference(factory->CreateImageReader2(file.c_str()));
  if (!reader) throw io::FileError("texture '" + file + "': not an image VTK can read (use PNG or JPEG)");
  // VTK reports a broken file through its error events (and libpng's messages), not an exception.
  bool failed = false;
  vtkNew<vtkCallbackCommand> on_error;
  on_error->SetClientData(&failed);
  on_error->SetCallback([](vtkObject*, unsigned long, void* flag, void*) { *static_cast<bool*>(flag) = true; });
  reader->AddObserver(vtkCommand::ErrorEvent, on_error);
  reader->SetFileName(file.c_str());
  reader->Update();
  int dims[3] = {0, 0, 0};
  reader->GetOutput()->GetDimensions(dims);
  if (failed || reader->GetErrorCode() != 0 || dims[0] < 1 || dims[1] < 1)
    throw io::FileError("texture '" + file + "' does not decode (a PNG or JPEG cut short or damaged?)");
}

}  // namespace csrbf::render
