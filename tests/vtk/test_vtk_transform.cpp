#include "csrbf/space_map.hpp"
#include "csrbf/vtk/vtkCSRBFTransform.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <vtkCallbackCommand.h>
#include <vtkCommand.h>
#include <vtkDoubleArray.h>
#include <vtkFloatArray.h>
#include <vtkPointData.h>
#include <vtkSmartPointer.h>
#include <vtkGeneralTransform.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSphereSource.h>
#include <vtkTransform.h>
#include <vtkTransformPolyDataFilter.h>

#include <random>

using csrbf::Vec3;

namespace {

struct Landmarks {
  vtkNew<vtkPoints> source, target;
  /// A transform between these landmarks at radius R.
  vtkSmartPointer<vtkCSRBFTransform> transform(double radius) const {
    auto t = vtkSmartPointer<vtkCSRBFTransform>::New();
    t->SetSourceLandmarks(source);
    t->SetTargetLandmarks(target);
    t->SetRadius(radius);
    return t;
  }
  std::vector<Vec3> s, d;
  Landmarks() {
    source->SetDataTypeToDouble();  // vtkPoints are float by default
    target->SetDataTypeToDouble();
    // Points on the unit sphere, pushed outwards or inwards a little.
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int i = 0; i < 40; ++i) {
      Vec3 p(u(rng), u(rng), u(rng));
      p.normalize();
      const Vec3 q = p * (1 + 0.08 * u(rng));
      s.push_back(p);
      d.push_back(q);
      source->InsertNextPoint(p.data());
      target->InsertNextPoint(q.data());
    }
  }
};

/// Counts VTK errors instead of printing them.
struct ErrorCounter {
  int count = 0;
  vtkNew<vtkCallbackCommand> cb;
  explicit ErrorCounter(vtkObject* o) {
    cb->SetClientData(this);
    cb->SetCallback([](vtkObject*, unsigned long, void* self, void*) { ++static_cast<ErrorCounter*>(self)->count; });
    o->AddObserver(vtkCommand::ErrorEvent, cb);
  }
};

}  // namespace

TEST(VtkCSRBFTransform, MatchesTheSpaceMapInFloatAndDouble) {
  Landmarks l;
  vtkNew<vtkCSRBFTransform> t;
  t->SetSourceLandmarks(l.source);
  t->SetTargetLandmarks(l.target);
  t->SetRadius(0.8);
  t->SetKernel(vtkCSRBFTransform::KERNEL_C4);
  t->SetPolynomial(vtkCSRBFTransform::POLYNOMIAL_LINEAR);
  t->SetPhase(0.7);
  const auto map = csrbf::SpaceMap::fit(l.s, l.d, csrbf::FitOptions{0.8, csrbf::Kernel::C4, csrbf::Polynomial::Linear});
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.2, 1.2);
  for (int i = 0; i < 50; ++i) {
    const Vec3 x(u(rng), u(rng), u(rng));
    double out[3];
    t->TransformPoint(x.data(), out);
    EXPECT_LT((Vec3(out[0], out[1], out[2]) - map.map(x, 0.7)).norm(), 1e-14);
    const float xf[3] = {float(x.x()), float(x.y()), float(x.z())};
    float of[3];
    t->TransformPoint(xf, of);
    const Vec3 expect = map.map(Vec3(xf[0], xf[1], xf[2]), 0.7);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(of[c], expect[c], 1e-6);
    // The derivative, against the analytic Jacobian and central differences.
    double y[3], jac[3][3];
    t->InternalTransformDerivative(x.data(), y, jac);
    const Eigen::Matrix3d j = map.jacobian(x, 0.7);
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) EXPECT_NEAR(jac[a][b], j(a, b), 1e-14);
    const double h = 1e-6;
    for (int b = 0; b < 3; ++b) {
      Vec3 xp = x, xm = x;
      xp[b] += h;
      xm[b] -= h;
      const Vec3 fd = (map.map(xp, 0.7) - map.map(xm, 0.7)) / (2 * h);
      for (int a = 0; a < 3; ++a) EXPECT_NEAR(jac[a][b], fd[a], 1e-6);
    }
  }
}

TEST(VtkCSRBFTransform, WorksInAPipelineAndRefitsWhenLandmarksChange) {
  Landmarks l;
  vtkNew<vtkCSRBFTransform> t;
  t->SetSourceLandmarks(l.source);
  t->SetTargetLandmarks(l.target);
  t->SetRadius(0.6);
  vtkNew<vtkSphereSource> sphere;
  sphere->SetThetaResolution(64);
  sphere->SetPhiResolution(64);
  sphere->SetRadius(1.0);
  vtkNew<vtkTransformPolyDataFilter> filter;
  filter->SetInputConnection(sphere->GetOutputPort());
  filter->SetTransform(t);
  filter->Update();
  vtkPoints* in = sphere->GetOutput()->GetPoints();
  const auto check = [&](const std::vector<Vec3>& d) {
    const auto map = csrbf::SpaceMap::fit(l.s, d, csrbf::FitOptions{0.6});
    vtkPoints* out = filter->GetOutput()->GetPoints();
    ASSERT_EQ(out->GetNumberOfPoints(), in->GetNumberOfPoints());
    double worst = 0;
    for (vtkIdType i = 0; i < in->GetNumberOfPoints(); ++i) {
      Vec3 x, y;
      in->GetPoint(i, x.data());
      out->GetPoint(i, y.data());
      // The sphere source makes float points: the batch path evaluates in float.
      worst = std::max(worst, (y - map.map(Vec3(float(x.x()), float(x.y()), float(x.z())))).norm());
    }
    EXPECT_LT(worst, 1e-5);
  };
  check(l.d);
  // Move one target landmark: the filter re-executes and the transform refits, lazily.
  l.d[5] += Vec3(0, 0, 0.2);
  l.target->SetPoint(5, l.d[5].data());
  l.target->Modified();
  filter->Update();
  check(l.d);
}

TEST(VtkCSRBFTransform, InverseRoundTripsAndConcatenates) {
  Landmarks l;
  vtkNew<vtkCSRBFTransform> t;
  t->SetSourceLandmarks(l.source);
  t->SetTargetLandmarks(l.target);
  t->SetRadius(0.7);
  vtkAbstractTransform* inv = t->GetInverse();
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.1, 1.1);
  for (int i = 0; i < 100; ++i) {
    const double x[3] = {u(rng), u(rng), u(rng)};
    double y[3], back[3];
    t->TransformPoint(x, y);
    inv->TransformPoint(y, back);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(back[c], x[c], 1e-6);
  }
  // In a vtkGeneralTransform after a translation: x -> T(x + (0.1, 0, 0)).
  vtkNew<vtkTransform> shift;
  shift->Translate(0.1, 0, 0);
  vtkNew<vtkGeneralTransform> chain;
  chain->PostMultiply();
  chain->Concatenate(shift);
  chain->Concatenate(t);
  const double x[3] = {0.8, 0.3, -0.2};
  const double xs[3] = {0.9, 0.3, -0.2};
  double a[3], b[3];
  chain->TransformPoint(x, a);
  t->TransformPoint(xs, b);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], b[c], 1e-14);
}

TEST(VtkCSRBFTransform, BadLandmarksReportAnErrorAndGiveTheIdentity) {
  Landmarks l;
  vtkNew<vtkCSRBFTransform> t;
  ErrorCounter errors(t);
  t->SetSourceLandmarks(l.source);
  t->SetTargetLandmarks(l.target);
  t->SetRadius(0.7);
  t->Update();
  EXPECT_EQ(errors.count, 0);
  // A duplicate source: an error, and the identity rather than the old mapping.
  l.source->SetPoint(3, l.s[4].data());
  l.source->Modified();
  const double x[3] = {l.s[0].x(), l.s[0].y(), l.s[0].z()};
  double y[3];
  t->TransformPoint(x, y);
  EXPECT_EQ(errors.count, 1);
  EXPECT_NE(std::string(t->GetLastError()).find("same"), std::string::npos) << t->GetLastError();
  for (int c = 0; c < 3; ++c) EXPECT_EQ(y[c], x[c]);
  // Fixed: fitted again.
  l.source->SetPoint(3, l.s[3].data());
  l.source->Modified();
  t->TransformPoint(x, y);
  EXPECT_STREQ(t->GetLastError(), "");
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(y[c], l.d[0][c], 1e-9);
  // Different counts.
  l.target->InsertNextPoint(0, 0, 0);
  l.target->Modified();
  t->Update();
  EXPECT_NE(std::string(t->GetLastError()).find("40 points but TargetLandmarks has 41"), std::string::npos);
}

// Issue 32, point 4: a vtkPolyData with normals goes through csrbf's parallel path (it took VTK's
// per-point one, 35-80x slower): points as without normals, normals J^-T n normalised and vectors
// J v, equal to VTK's own per-point definition (through ForwardTransformDerivative), in float and
// double arrays.
TEST(VtkCSRBFTransform, NormalsAndVectorsGoThroughTheJacobianAsVtksOwnPath) {
  Landmarks l;
  const auto t = l.transform(0.6);
  t->SetPhase(0.9);
  vtkNew<vtkSphereSource> sphere;
  sphere->SetThetaResolution(120);
  sphere->SetPhiResolution(120);
  sphere->Update();
  vtkPolyData* pd = sphere->GetOutput();
  vtkDataArray* normals = pd->GetPointData()->GetNormals();
  ASSERT_NE(normals, nullptr);
  const vtkIdType n = pd->GetNumberOfPoints();
  vtkNew<vtkDoubleArray> vectors;
  vectors->SetNumberOfComponents(3);
  for (vtkIdType i = 0; i < n; ++i) vectors->InsertNextTuple3(1.0, 0.5 * double(i % 3), -0.25);
  for (const bool dbl : {false, true}) {
    vtkNew<vtkPoints> outFast, outRef;
    vtkSmartPointer<vtkDataArray> nFast, nRef, vFast, vRef;
    if (dbl) {
      outFast->SetDataTypeToDouble();
      outRef->SetDataTypeToDouble();
      nFast = vtkSmartPointer<vtkDoubleArray>::New();
      nRef = vtkSmartPointer<vtkDoubleArray>::New();
    } else {
      nFast = vtkSmartPointer<vtkFloatArray>::New();
      nRef = vtkSmartPointer<vtkFloatArray>::New();
    }
    vFast = vtkSmartPointer<vtkDoubleArray>::New();
    vRef = vtkSmartPointer<vtkDoubleArray>::New();
    for (vtkDataArray* a : {nFast.Get(), nRef.Get(), vFast.Get(), vRef.Get()}) a->SetNumberOfComponents(3);
    t->TransformPointsNormalsVectors(pd->GetPoints(), outFast, normals, nFast, vectors, vFast);
    t->vtkAbstractTransform::TransformPointsNormalsVectors(pd->GetPoints(), outRef, normals, nRef, vectors, vRef);
    ASSERT_EQ(outFast->GetNumberOfPoints(), n);
    ASSERT_EQ(nFast->GetNumberOfTuples(), n);
    ASSERT_EQ(vFast->GetNumberOfTuples(), n);
    double worst_point = 0, worst_angle = 0, worst_vector = 0, turned = 0;
    for (vtkIdType i = 0; i < n; ++i) {
      Vec3 a, b, na, nb, va, vb, n0;
      outFast->GetPoint(i, a.data());
      outRef->GetPoint(i, b.data());
      nFast->GetTuple(i, na.data());
      nRef->GetTuple(i, nb.data());
      vFast->GetTuple(i, va.data());
      vRef->GetTuple(i, vb.data());
      normals->GetTuple(i, n0.data());
      worst_point = std::max(worst_point, (a - b).norm());
      worst_angle = std::max(worst_angle, std::atan2(na.cross(nb).norm(), na.dot(nb)));
      worst_vector = std::max(worst_vector, (va - vb).norm());
      turned = std::max(turned, std::atan2(na.cross(n0).norm(), na.dot(n0)));
    }
    EXPECT_LT(worst_point, dbl ? 1e-12 : 1e-6);
    EXPECT_LT(worst_angle, dbl ? 1e-9 : 1e-6);
    EXPECT_LT(worst_vector, 1e-9);
    EXPECT_GT(turned, 3e-3);  // the landmarks did turn the normals (0.34 degrees at most)
  }
  // Through the filter, as a VTK user runs it: the output has as many normals as points.
  vtkNew<vtkTransformPolyDataFilter> filter;
  filter->SetInputConnection(sphere->GetOutputPort());
  filter->SetTransform(t);
  filter->Update();
  ASSERT_NE(filter->GetOutput()->GetPointData()->GetNormals(), nullptr);
  EXPECT_EQ(filter->GetOutput()->GetPointData()->GetNormals()->GetNumberOfTuples(), n);
}

// The filter's case: points and normals in contiguous arrays and no vectors, which the core
// evaluates in place in VTK's arrays (float in float), normals of the other type converted around
// the call (double points with float normals: vtkSphereSource at double precision; found by a new
// user, who saw that case take the gather path at 2.5x). Equal to VTK's per-point definition in
// every combination, the normals of unit length.
TEST(VtkCSRBFTransform, PointsAndNormalsOfOneTypeGoStraightThroughTheCore) {
  Landmarks l;
  const auto t = l.transform(0.6);
  t->SetPhase(0.9);
  vtkNew<vtkSphereSource> sphere;
  sphere->SetThetaResolution(200);
  sphere->SetPhiResolution(200);
  sphere->Update();
  vtkPolyData* pd = sphere->GetOutput();
  const vtkIdType n = pd->GetNumberOfPoints();
  for (const int kind : {0, 1, 2, 3}) {
    const bool dbl = kind & 1, dbl_normals = kind & 2;  // points double; normals double
    vtkNew<vtkPoints> in, outFast, outRef;
    vtkSmartPointer<vtkDataArray> normals, nFast, nRef;
    if (dbl) {
      in->SetDataTypeToDouble();
      outFast->SetDataTypeToDouble();
      outRef->SetDataTypeToDouble();
    }
    if (dbl_normals) {
      normals = vtkSmartPointer<vtkDoubleArray>::New();
      nFast = vtkSmartPointer<vtkDoubleArray>::New();
      nRef = vtkSmartPointer<vtkDoubleArray>::New();
    } else {
      normals = vtkSmartPointer<vtkFloatArray>::New();
      nFast = vtkSmartPointer<vtkFloatArray>::New();
      nRef = vtkSmartPointer<vtkFloatArray>::New();
    }
    for (vtkDataArray* a : {normals.Get(), nFast.Get(), nRef.Get()}) a->SetNumberOfComponents(3);
    for (vtkIdType i = 0; i < n; ++i) {
      in->InsertNextPoint(pd->GetPoint(i));
      normals->InsertNextTuple(pd->GetPointData()->GetNormals()->GetTuple(i));
    }
    t->TransformPointsNormalsVectors(in, outFast, normals, nFast, nullptr, nullptr);
    t->vtkAbstractTransform::TransformPointsNormalsVectors(in, outRef, normals, nRef, nullptr, nullptr);
    ASSERT_EQ(outFast->GetNumberOfPoints(), n);
    ASSERT_EQ(nFast->GetNumberOfTuples(), n);
    double worst_point = 0, worst_angle = 0, worst_length = 0;
    for (vtkIdType i = 0; i < n; ++i) {
      Vec3 a, b, na, nb;
      outFast->GetPoint(i, a.data());
      outRef->GetPoint(i, b.data());
      nFast->GetTuple(i, na.data());
      nRef->GetTuple(i, nb.data());
      worst_point = std::max(worst_point, (a - b).norm());
      worst_angle = std::max(worst_angle, std::atan2(na.cross(nb).norm(), na.dot(nb)));
      worst_length = std::max(worst_length, std::abs(na.norm() - 1.0));
    }
    const bool exact = dbl && dbl_normals;
    EXPECT_LT(worst_point, dbl ? 1e-12 : 1e-6) << kind;
    EXPECT_LT(worst_angle, exact ? 1e-9 : 1e-6) << kind;
    EXPECT_LT(worst_length, exact ? 1e-12 : 1e-6) << kind;
  }
}

// Found by the attacker: outputs that already held tuples lost them (SetNumberOfTuples reallocates
// without copying), and a vtkPoints transformed into itself read garbage. VTK appends: the old
// tuples stay, the new ones follow, equal to VTK's own per-point path.
TEST(VtkCSRBFTransform, AppendsToOutputsThatHoldTuplesAndToItsOwnInput) {
  Landmarks l;
  const auto t = l.transform(0.6);
  vtkNew<vtkSphereSource> sphere;
  sphere->SetThetaResolution(40);
  sphere->SetPhiResolution(40);
  sphere->SetRadius(1.0);
  sphere->Update();
  vtkPolyData* pd = sphere->GetOutput();
  const vtkIdType n = pd->GetNumberOfPoints();
  vtkNew<vtkPoints> ref;
  vtkNew<vtkFloatArray> ref_normals;
  ref_normals->SetNumberOfComponents(3);
  t->vtkAbstractTransform::TransformPointsNormalsVectors(pd->GetPoints(), ref, pd->GetPointData()->GetNormals(),
                                                         ref_normals, nullptr, nullptr);
  vtkNew<vtkPoints> out;
  out->InsertNextPoint(9, 9, 9);
  vtkNew<vtkFloatArray> normals;
  normals->SetNumberOfComponents(3);
  normals->InsertNextTuple3(7, 7, 7);
  t->TransformPointsNormalsVectors(pd->GetPoints(), out, pd->GetPointData()->GetNormals(), normals, nullptr, nullptr);
  ASSERT_EQ(out->GetNumberOfPoints(), n + 1);
  ASSERT_EQ(normals->GetNumberOfTuples(), n + 1);
  double p[3], q[3];
  out->GetPoint(0, p);
  EXPECT_EQ(p[0], 9.0);
  normals->GetTuple(0, p);
  EXPECT_EQ(p[2], 7.0);
  double worst = 0;
  for (vtkIdType i = 0; i < n; ++i) {
    out->GetPoint(i + 1, p);
    ref->GetPoint(i, q);
    for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(p[c] - q[c]));
    normals->GetTuple(i + 1, p);
    ref_normals->GetTuple(i, q);
    for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(p[c] - q[c]));
  }
  EXPECT_LT(worst, 1e-5);
  // Points transformed into their own vtkPoints: the originals, then their images.
  vtkNew<vtkPoints> self;
  self->DeepCopy(pd->GetPoints());
  t->TransformPoints(self, self);
  ASSERT_EQ(self->GetNumberOfPoints(), 2 * n);
  worst = 0;
  for (vtkIdType i = 0; i < n; ++i) {
    self->GetPoint(i, p);
    pd->GetPoints()->GetPoint(i, q);
    for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(p[c] - q[c]));
    self->GetPoint(n + i, p);
    ref->GetPoint(i, q);
    for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(p[c] - q[c]));
  }
  EXPECT_LT(worst, 1e-5);
}
