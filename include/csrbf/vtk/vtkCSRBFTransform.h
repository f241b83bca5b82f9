// vtkCSRBFTransform: the CSRBF space mapping as a VTK warp transform, shaped like
// vtkThinPlateSplineTransform (source and target landmarks, lazy re-fit) but compactly supported
// and solved sparsely (csrbf::SpaceMap). Works in vtkTransformPolyDataFilter, concatenates in
// vtkGeneralTransform, and inverts by VTK's Newton iteration on the analytic derivative.
//
// GetInverse() uses vtkWarpTransform's Newton iteration with InverseTolerance 1e-9 (VTK's default
// is 1e-3) and up to 500 iterations.
//
// A fit that fails (duplicate landmarks, a degenerate linear polynomial, different landmark counts)
// reports a VTK error (ErrorEvent) and leaves the transform the identity until the inputs change:
// never the previous, stale mapping. GetLastError() holds the message.
#pragma once

#include <vtkWarpTransform.h>

#include <memory>
#include <string>

class vtkPoints;

class vtkCSRBFTransform : public vtkWarpTransform {
 public:
  static vtkCSRBFTransform* New();
// VTK's wrappers need the ';' after vtkTypeMacro, which -Wpedantic calls extra.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpedantic"
  vtkTypeMacro(vtkCSRBFTransform, vtkWarpTransform);
#pragma GCC diagnostic pop
  void PrintSelf(ostream& os, vtkIndent indent) override;

  enum { KERNEL_C0 = 0, KERNEL_C2 = 2, KERNEL_C4 = 4, KERNEL_C6 = 6 };
  enum { POLYNOMIAL_NONE = 0, POLYNOMIAL_CONSTANT = 1, POLYNOMIAL_LINEAR = 2 };

  /// Landmarks (control points): the transform maps each source landmark to its target landmark.
  void SetSourceLandmarks(vtkPoints* source);
  vtkGetObjectMacro(SourceLandmarks, vtkPoints);
  void SetTargetLandmarks(vtkPoints* target);
  vtkGetObjectMacro(TargetLandmarks, vtkPoints);

  /// Radius of support R, in the landmarks' units (> 0). Default 1.
  vtkSetMacro(Radius, double);
  vtkGetMacro(Radius, double);
  /// Wendland kernel: KERNEL_C0 (psi_2,0), KERNEL_C2 (psi_3,1, the default), KERNEL_C4, KERNEL_C6.
  vtkSetMacro(Kernel, int);
  vtkGetMacro(Kernel, int);
  /// POLYNOMIAL_NONE (default: strictly local), POLYNOMIAL_CONSTANT, POLYNOMIAL_LINEAR.
  vtkSetMacro(Polynomial, int);
  vtkGetMacro(Polynomial, int);
  /// T(x) = x + Phase * d(x): 0 is the identity, 1 (default) the full mapping.
  vtkSetMacro(Phase, double);
  vtkGetMacro(Phase, double);

  /// Empty after a successful fit.
  const char* GetLastError() const { return this->LastError.c_str(); }

  /// The landmarks' modification times count too (editing a vtkPoints refits).
  vtkMTimeType GetMTime() override;
  vtkAbstractTransform* MakeTransform() override;
  /// Forward transforms go through csrbf's parallel, vectorised evaluation in one call.
  void TransformPoints(vtkPoints* in, vtkPoints* out) override;
  /// Points, normals and vectors together (vtkTransformPolyDataFilter with point normals), in
  /// parallel: normals exactly through the Jacobian, J^-T n normalised (as VTK's own per-point path
  /// defines them), vectors J v. The inverse goes VTK's per-point way.
  void TransformPointsNormalsVectors(vtkPoints* inPts, vtkPoints* outPts, vtkDataArray* inNms, vtkDataArray* outNms,
                                     vtkDataArray* inVrs, vtkDataArray* outVrs, int nOptionalVectors = 0,
                                     vtkDataArray** inVrsArr = nullptr, vtkDataArray** outVrsArr = nullptr) override;

 protected:
  vtkCSRBFTransform();
  ~vtkCSRBFTransform() override;
  void InternalUpdate() override;
  void InternalDeepCopy(vtkAbstractTransform* transform) override;
  void ForwardTransformPoint(const float in[3], float out[3]) override;
  void ForwardTransformPoint(const double in[3], double out[3]) override;
  void ForwardTransformDerivative(const float in[3], float out[3], float derivative[3][3]) override;
  void ForwardTransformDerivative(const double in[3], double out[3], double derivative[3][3]) override;

  vtkPoints* SourceLandmarks = nullptr;
  vtkPoints* TargetLandmarks = nullptr;
  double Radius = 1.0;
  int Kernel = KERNEL_C2;
  int Polynomial = POLYNOMIAL_NONE;
  double Phase = 1.0;
  std::string LastError;

 private:
  struct Fitted;
  std::shared_ptr<const Fitted> Map;  // null: the identity
  vtkCSRBFTransform(const vtkCSRBFTransform&) = delete;
  void operator=(const vtkCSRBFTransform&) = delete;
};
