#include "csrbf/render/scene_renderer.hpp"

#include "csrbf/io/scene.hpp"

#include "texture_coordinates.hpp"

#include "csrbf/errors.hpp"

#include "csrbf/render/process.hpp"

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkCellArray.h>
#include <vtkDataArray.h>
#include <vtkFloatArray.h>
#include <vtkIdList.h>
#include <vtkImageData.h>
#include <vtkImageReader2.h>
#include <vtkImageReader2Factory.h>
#include <vtkLight.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkPolyDataNormals.h>
#include <vtkProperty.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkSmartPointer.h>
#include <vtkTextureMapToCylinder.h>
#include <vtkTextureMapToPlane.h>
#include <vtkTextureMapToSphere.h>
#include <vtkTexture.h>
#include <vtkUnsignedCharArray.h>

#include <cstring>
#include <limits>

namespace csrbf::render {

namespace {

vtkSmartPointer<vtkCellArray> cells_of(const anim::Object& obj, const std::vector<std::uint32_t>& faces) {
  auto cells = vtkSmartPointer<vtkCellArray>::New();
  for (const auto f : faces) {
    const auto& poly = obj.faces[f];
    cells->InsertNextCell(vtkIdType(poly.size()));
    for (const auto v : poly) cells->InsertCellPoint(vtkIdType(v));
  }
  return cells;
}

vtkSmartPointer<vtkTexture> load_texture(const std::string& file) {
  vtkNew<vtkImageReader2Factory> factory;
  vtkSmartPointer<vtkImageReader2> reader;
  reader.TakeReference(factory->CreateImageReader2(file.c_str()));
  if (!reader) throw RenderError(file + ": not an image VTK can read (use PNG or JPEG)");
  reader->SetFileName(file.c_str());
  reader->Update();
  int dims[3];
  reader->GetOutput()->GetDimensions(dims);
  if (dims[0] < 1 || dims[1] < 1) throw RenderError(file + ": the image is empty or unreadable");
  auto t = vtkSmartPointer<vtkTexture>::New();
  t->SetInputConnection(reader->GetOutputPort());
  t->InterpolateOn();
  t->RepeatOn();
  return t;
}

}  // namespace

struct SceneRenderer::Impl {
  const anim::Scene* scene = nullptr;
  vtkNew<vtkRenderer> renderer;
  vtkSmartPointer<vtkRenderWindow> window;
  std::vector<vtkSmartPointer<vtkPoints>> points;      // per object, shared by its parts
  std::vector<vtkSmartPointer<vtkPolyData>> surfaces;  // per drawn part
  vtkNew<vtkUnsignedCharArray> pixels;
  int width = 0, height = 0;

  void add_surface(const anim::Object& obj, vtkPoints* pts, const std::vector<std::uint32_t>& faces,
                   const anim::Material& m) {
    if (faces.empty()) return;
    auto poly = vtkSmartPointer<vtkPolyData>::New();
    poly->SetPoints(pts);
    poly->SetPolys(cells_of(obj, faces));
    vtkSmartPointer<vtkTexture> texture;
    if (!m.texture.empty()) {
      texture = load_texture(m.texture);
      try {
        poly->GetPointData()->SetTCoords(texture_coordinates(poly, m.mapping));
      } catch (const InvalidInput& e) {
        throw InvalidInput("object '" + obj.name + "': " + e.what());
      }
    }
    vtkNew<vtkPolyDataNormals> normals;  // recomputed each frame from the moved points
    normals->SetInputData(poly);
    normals->SplittingOff();
    normals->ConsistencyOff();
    normals->AutoOrientNormalsOff();
    vtkNew<vtkPolyDataMapper> mapper;
    mapper->SetInputConnection(normals->GetOutputPort());
    vtkNew<vtkActor> actor;
    actor->SetMapper(mapper);
    vtkProperty* p = actor->GetProperty();
    p->SetColor(m.color.x(), m.color.y(), m.color.z());
    p->SetOpacity(m.opacity);
    p->SetSpecular(m.specular);
    p->SetSpecularPower(30);
    p->BackfaceCullingOff();
    if (texture) actor->SetTexture(texture);
    renderer->AddActor(actor);
    surfaces.push_back(poly);
  }
};

SceneRenderer::SceneRenderer(const anim::Scene& scene) : impl_(std::make_unique<Impl>()) {
  impl_->scene = &scene;
  auto& r = *impl_->renderer;
  r.SetBackground(scene.background.x(), scene.background.y(), scene.background.z());
  for (const auto& obj : scene.objects) {
    auto pts = vtkSmartPointer<vtkPoints>::New();
    pts->SetDataTypeToFloat();
    pts->SetNumberOfPoints(vtkIdType(obj.rest.size()));
    for (std::size_t i = 0; i < obj.rest.size(); ++i)
      pts->SetPoint(vtkIdType(i), obj.rest[i].x(), obj.rest[i].y(), obj.rest[i].z());
    impl_->points.push_back(pts);
    // Each face is drawn by the last part that lists it; the others with the object's material.
    std::vector<int> owner(obj.faces.size(), -1);
    for (std::size_t p = 0; p < obj.parts.size(); ++p)
      for (const auto f : obj.parts[p].faces) owner[f] = int(p);
    std::vector<std::uint32_t> rest_faces;
    for (std::size_t f = 0; f < obj.faces.size(); ++f)
      if (owner[f] < 0) rest_faces.push_back(std::uint32_t(f));
    impl_->add_surface(obj, pts, rest_faces, obj.material);
    for (std::size_t p = 0; p < obj.parts.size(); ++p) {
      std::vector<std::uint32_t> mine;
      for (const auto f : obj.parts[p].faces)
        if (owner[f] == int(p)) mine.push_back(f);
      impl_->add_surface(obj, pts, mine, obj.parts[p].material);
    }
  }
  vtkCamera* cam = r.GetActiveCamera();
  const auto& c = scene.camera;
  cam->SetPosition(c.position.x(), c.position.y(), c.position.z());
  cam->SetFocalPoint(c.focal_point.x(), c.focal_point.y(), c.focal_point.z());
  cam->SetViewUp(c.view_up.x(), c.view_up.y(), c.view_up.z());
  cam->SetViewAngle(c.view_angle);
  if (!scene.lights.empty()) {
    r.AutomaticLightCreationOff();
    for (const auto& l : scene.lights) {
      vtkNew<vtkLight> light;
      if (l.headlight) {
        light->SetLightTypeToHeadlight();
      } else {
        light->SetLightTypeToSceneLight();
        light->SetPosition(l.position.x(), l.position.y(), l.position.z());
        light->SetFocalPoint(c.focal_point.x(), c.focal_point.y(), c.focal_point.z());
      }
      light->SetColor(l.color.x(), l.color.y(), l.color.z());
      light->SetIntensity(l.intensity);
      r.AddLight(light);
    }
  }
}

double SceneRenderer::bytes(const anim::Scene& scene, int width, int height) {
  // 96 MiB whatever the scene (Mesa's and VTK's OpenGL state: a 640x480 movie of the fish peaks
  // 108 MB above the scene) and 64 bytes a pixel (Mesa's colour and depth buffers, VTK's and the
  // movie's copies of the frame: 1.0 GB more at 4096x4096). Each mesh: VTK's points, normals and
  // cells, the OpenGL buffers and llvmpipe's binning: 64 bytes a vertex and 320 a triangle bound
  // what a mesh of 490k vertices with 977k (or 179k) triangles took, small or screen-sized triangles
  // (measured 217 and 335 MB, 60 MB with 179k). And the textures, decoded (io::decoded_texture_bytes).
  double total = 96.0 * (1 << 20) + 64.0 * double(width) * double(height) + io::decoded_texture_bytes(scene);
  for (const anim::Object& obj : scene.objects) {
    total += 64.0 * double(obj.rest.size());
    for (const auto& f : obj.faces) total += f.size() >= 3 ? 320.0 * double(f.size() - 2) : 0.0;
  }
  return total;
}

SceneRenderer::~SceneRenderer() {
  if (impl_->window) impl_->window->Finalize();
}

void SceneRenderer::update(const anim::Player& player) {
  const auto& objects = impl_->scene->objects;
  for (std::size_t o = 0; o < objects.size(); ++o) {
    const auto& pos = player.positions(o);
    vtkPoints* pts = impl_->points[o];
    auto* data = static_cast<float*>(pts->GetVoidPointer(0));
    for (std::size_t i = 0; i < pos.size(); ++i) {
      // VTK's points are single precision: a vertex beyond it would be drawn as infinity.
      if (!(pos[i].cwiseAbs().maxCoeff() <= double(std::numeric_limits<float>::max())))
        throw RenderError("objects[" + std::to_string(o) + "] vertex " + std::to_string(i) +
                          " is beyond single precision (renderers store float): " + std::to_string(pos[i].x()) + " " +
                          std::to_string(pos[i].y()) + " " + std::to_string(pos[i].z()));
      data[3 * i] = float(pos[i].x());
      data[3 * i + 1] = float(pos[i].y());
      data[3 * i + 2] = float(pos[i].z());
    }
    pts->Modified();
  }
  impl_->renderer->ResetCameraClippingRange();
}

vtkRenderer* SceneRenderer::renderer() const { return impl_->renderer; }
vtkRenderWindow* SceneRenderer::window() const { return impl_->window; }

namespace {

/// VTK aborts the process when it cannot create an OpenGL context, which Mesa cannot under a tight
/// address-space limit (ulimit -v). Under such a limit the context is first made in a child
/// process: its death is then an error, not csrbf's abort.
void probe_context_under_limits(int width, int height) {
  rlimit as{};
  if (::getrlimit(RLIMIT_AS, &as) != 0 || as.rlim_cur == RLIM_INFINITY) return;
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) throw RenderError(std::string("cannot start the OpenGL probe: ") + std::strerror(errno));
  if (pid == 0) {
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (const int null = ::open("/dev/null", O_WRONLY | O_CLOEXEC); null >= 0) {
      ::dup2(null, 1);
      ::dup2(null, 2);
    }
    vtkNew<vtkRenderWindow> w;
    w->SetOffScreenRendering(1);
    w->SetSize(width, height);
    w->SetMultiSamples(4);
    vtkNew<vtkRenderer> r;
    w->AddRenderer(r);
    w->Render();
    ::_exit(w->SupportsOpenGL() ? 0 : 3);
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
    throw RenderError("cannot create an OpenGL context of " + std::to_string(width) + "x" + std::to_string(height) +
                      " within the address-space limit (ulimit -v " + std::to_string(as.rlim_cur / 1024) +
                      " KiB): Mesa needs more; raise the limit or give a smaller --size");
}

}  // namespace

void SceneRenderer::open_offscreen(int width, int height) {
  probe_context_under_limits(width, height);
  impl_->width = width;
  impl_->height = height;
  impl_->window = vtkSmartPointer<vtkRenderWindow>::New();
  impl_->window->SetOffScreenRendering(1);
  impl_->window->SetSize(width, height);
  impl_->window->SetMultiSamples(4);
  impl_->window->AddRenderer(impl_->renderer);
  impl_->window->Render();
  if (!impl_->window->SupportsOpenGL())
    throw RenderError("the X display '" + std::string(std::getenv("DISPLAY") ? std::getenv("DISPLAY") : "") +
                      "' offers no usable OpenGL");
}

void SceneRenderer::render_rgb(std::vector<std::uint8_t>& rgb) {
  const int w = impl_->width, h = impl_->height;
  impl_->window->Render();
  impl_->window->GetPixelData(0, 0, w - 1, h - 1, 0, impl_->pixels, 0);
  rgb.resize(std::size_t(w) * std::size_t(h) * 3);
  const unsigned char* src = impl_->pixels->GetPointer(0);
  const std::size_t row = std::size_t(w) * 3;
  for (int y = 0; y < h; ++y)  // OpenGL's rows run bottom to top
    std::memcpy(rgb.data() + std::size_t(y) * row, src + std::size_t(h - 1 - y) * row, row);
}

}  // namespace csrbf::render
