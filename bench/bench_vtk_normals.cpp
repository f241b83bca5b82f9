// vtkCSRBFTransform through vtkTransformPolyDataFilter on a UV sphere of about 1e6 points, with and
// without point normals (issue 32, point 4: normals took VTK's per-point path, 35-80x slower), and
// VTK's own per-point path for the normals as the reference. docs/PERFORMANCE.md, "VTK with normals".
//   build/bin/bench_vtk_normals --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include "csrbf/vtk/vtkCSRBFTransform.h"

#include <benchmark/benchmark.h>

#include <vtkAlgorithm.h>
#include <vtkFloatArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSphereSource.h>
#include <vtkTransformPolyDataFilter.h>

#include <cmath>
#include <random>

namespace {

struct Scene {
  vtkNew<vtkPoints> source, target;
  vtkNew<vtkCSRBFTransform> transform;
  vtkNew<vtkPolyData> with_normals, without_normals;
  /// The same mesh at double precision (vtkSphereSource's points double, its normals float).
  vtkNew<vtkPolyData> double_with_normals, double_without_normals;
  Scene() {
    // 1000 landmarks on the unit sphere, pushed along the normal; ~25 a landmark's neighbours.
    std::mt19937 rng(32);
    std::normal_distribution<double> g;
    for (int i = 0; i < 1000; ++i) {
      double p[3] = {g(rng), g(rng), g(rng)};
      const double len = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
      const double s = 1.0 + 0.05 * std::sin(5 * p[0] / len);
      source->InsertNextPoint(p[0] / len, p[1] / len, p[2] / len);
      target->InsertNextPoint(s * p[0] / len, s * p[1] / len, s * p[2] / len);
    }
    transform->SetSourceLandmarks(source);
    transform->SetTargetLandmarks(target);
    transform->SetRadius(std::sqrt(4.0 * 25.0 / 1000.0));
    vtkNew<vtkSphereSource> sphere;
    sphere->SetThetaResolution(1000);
    sphere->SetPhiResolution(1000);
    sphere->SetRadius(1.0);  // on the landmarks (the default is 0.5)
    sphere->Update();
    with_normals->DeepCopy(sphere->GetOutput());
    without_normals->DeepCopy(sphere->GetOutput());
    without_normals->GetPointData()->SetNormals(nullptr);
    sphere->SetOutputPointsPrecision(vtkAlgorithm::DOUBLE_PRECISION);
    sphere->Update();
    double_with_normals->DeepCopy(sphere->GetOutput());
    double_without_normals->DeepCopy(sphere->GetOutput());
    double_without_normals->GetPointData()->SetNormals(nullptr);
    transform->Update();
  }
};

Scene& scene() {
  static Scene s;
  return s;
}

void run(benchmark::State& state, vtkPolyData* input) {
  vtkNew<vtkTransformPolyDataFilter> filter;
  filter->SetInputData(input);
  filter->SetTransform(scene().transform);
  for (auto _ : state) {
    filter->Modified();
    filter->Update();
    benchmark::DoNotOptimize(filter->GetOutput()->GetPoints()->GetVoidPointer(0));
  }
  state.counters["points"] = double(input->GetNumberOfPoints());
}

void BM_VtkFilterWithoutNormals(benchmark::State& state) { run(state, scene().without_normals); }
void BM_VtkFilterWithNormals(benchmark::State& state) { run(state, scene().with_normals); }
void BM_VtkFilterDoubleWithoutNormals(benchmark::State& state) { run(state, scene().double_without_normals); }
void BM_VtkFilterDoubleWithNormals(benchmark::State& state) { run(state, scene().double_with_normals); }
/// VTK's own path for points and normals (vtkAbstractTransform's per-point loop through
/// ForwardTransformDerivative), what the filter ran before.
void BM_VtkPerPointPathWithNormals(benchmark::State& state) {
  vtkPolyData* pd = scene().with_normals;
  for (auto _ : state) {
    vtkNew<vtkPoints> out;
    vtkNew<vtkFloatArray> normals;
    normals->SetNumberOfComponents(3);
    scene().transform->vtkAbstractTransform::TransformPointsNormalsVectors(
        pd->GetPoints(), out, pd->GetPointData()->GetNormals(), normals, nullptr, nullptr);
    benchmark::DoNotOptimize(out->GetVoidPointer(0));
  }
}

}  // namespace

BENCHMARK(BM_VtkFilterWithoutNormals)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_VtkFilterWithNormals)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_VtkFilterDoubleWithoutNormals)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_VtkFilterDoubleWithNormals)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_VtkPerPointPathWithNormals)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);
