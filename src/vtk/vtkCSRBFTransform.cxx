#include "csrbf/vtk/vtkCSRBFTransform.h"

#include "csrbf/names.hpp"
#include "csrbf/space_map.hpp"

#include <vtkDataArray.h>
#include <vtkDoubleArray.h>
#include <vtkFloatArray.h>
#include <vtkObjectFactory.h>
#include <vtkMath.h>
#include <vtkPoints.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <type_traits>

#include <vector>

vtkStandardNewMacro(vtkCSRBFTransform);

struct vtkCSRBFTransform::Fitted {
  csrbf::SpaceMap map;
};

vtkCSRBFTransform::vtkCSRBFTransform() {
  // VTK's default Newton tolerance (0.001, in the points' units) leaves round-trip errors of 1e-4
  // on a unit-sized model; the iteration is cheap, so ask for much less.
  this->InverseTolerance = 1e-9;
  this->InverseIterations = 500;
}

vtkCSRBFTransform::~vtkCSRBFTransform() {
  this->SetSourceLandmarks(nullptr);
  this->SetTargetLandmarks(nullptr);
}

void vtkCSRBFTransform::SetSourceLandmarks(vtkPoints* source) {
  if (this->SourceLandmarks == source) return;
  if (this->SourceLandmarks) this->SourceLandmarks->Delete();
  if (source) source->Register(this);
  this->SourceLandmarks = source;
  this->Modified();
}

void vtkCSRBFTransform::SetTargetLandmarks(vtkPoints* target) {
  if (this->TargetLandmarks == target) return;
  if (this->TargetLandmarks) this->TargetLandmarks->Delete();
  if (target) target->Register(this);
  this->TargetLandmarks = target;
  this->Modified();
}

vtkMTimeType vtkCSRBFTransform::GetMTime() {
  vtkMTimeType m = this->vtkWarpTransform::GetMTime();
  if (this->SourceLandmarks) m = std::max(m, this->SourceLandmarks->GetMTime());
  if (this->TargetLandmarks) m = std::max(m, this->TargetLandmarks->GetMTime());
  return m;
}

void vtkCSRBFTransform::InternalUpdate() {
  this->Map.reset();
  this->LastError.clear();
  if (!this->SourceLandmarks || !this->TargetLandmarks) return;  // no landmarks: the identity
  const vtkIdType n = this->SourceLandmarks->GetNumberOfPoints();
  if (n == 0 && this->TargetLandmarks->GetNumberOfPoints() == 0) return;
  try {
    if (this->TargetLandmarks->GetNumberOfPoints() != n)
      throw csrbf::InvalidInput("SourceLandmarks has " + std::to_string(n) + " points but TargetLandmarks has " +
                                std::to_string(this->TargetLandmarks->GetNumberOfPoints()));
    std::vector<csrbf::Vec3> s(static_cast<std::size_t>(n)), d(static_cast<std::size_t>(n));
    for (vtkIdType i = 0; i < n; ++i) {
      this->SourceLandmarks->GetPoint(i, s[std::size_t(i)].data());
      this->TargetLandmarks->GetPoint(i, d[std::size_t(i)].data());
    }
    csrbf::FitOptions o;
    o.radius = this->Radius;
    // KERNEL_Cn is the kernel's smoothness n; POLYNOMIAL_* its position in the name table.
    bool known = false;
    for (const auto& e : csrbf::NameTable<csrbf::Kernel>::entries)
      if (csrbf::kernel_smoothness(e.value) == this->Kernel) o.kernel = e.value, known = true;
    if (!known)
      throw csrbf::InvalidInput("Kernel must be KERNEL_C0, _C2, _C4 or _C6 (" + csrbf::names_text<csrbf::Kernel>() +
                                "), got " + std::to_string(this->Kernel));
    const auto& polynomials = csrbf::NameTable<csrbf::Polynomial>::entries;
    if (this->Polynomial < 0 || std::size_t(this->Polynomial) >= polynomials.size())
      throw csrbf::InvalidInput("Polynomial must be POLYNOMIAL_NONE, _CONSTANT or _LINEAR (" +
                                csrbf::names_text<csrbf::Polynomial>() + "), got " + std::to_string(this->Polynomial));
    o.polynomial = polynomials[std::size_t(this->Polynomial)].value;
    csrbf::check_phase(this->Phase);
    this->Map = std::make_shared<const Fitted>(Fitted{csrbf::SpaceMap::fit(s, d, o)});
  } catch (const std::exception& e) {
    this->LastError = e.what();
    vtkErrorMacro(<< "cannot fit: " << e.what() << "; the transform is the identity until its inputs change");
  }
}

template <class T>
static void forward(const csrbf::SpaceMap* map, double phase, const T in[3], T out[3], T (*derivative)[3]) {
  const csrbf::Vec3 x(in[0], in[1], in[2]);
  if (!map) {
    for (int i = 0; i < 3; ++i) out[i] = in[i];
    if (derivative)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) derivative[i][j] = T(i == j);
    return;
  }
  const csrbf::Vec3 y = map->map(x, phase);
  for (int i = 0; i < 3; ++i) out[i] = T(y[i]);
  if (derivative) {
    const Eigen::Matrix3d jac = map->jacobian(x, phase);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) derivative[i][j] = T(jac(i, j));
  }
}

void vtkCSRBFTransform::ForwardTransformPoint(const float in[3], float out[3]) {
  forward<float>(this->Map ? &this->Map->map : nullptr, this->Phase, in, out, nullptr);
}
void vtkCSRBFTransform::ForwardTransformPoint(const double in[3], double out[3]) {
  forward<double>(this->Map ? &this->Map->map : nullptr, this->Phase, in, out, nullptr);
}
void vtkCSRBFTransform::ForwardTransformDerivative(const float in[3], float out[3], float derivative[3][3]) {
  forward<float>(this->Map ? &this->Map->map : nullptr, this->Phase, in, out, derivative);
}
void vtkCSRBFTransform::ForwardTransformDerivative(const double in[3], double out[3], double derivative[3][3]) {
  forward<double>(this->Map ? &this->Map->map : nullptr, this->Phase, in, out, derivative);
}

namespace {
/// Grows `a` (3 components) by n tuples, keeping what it holds, as VTK's per-point path appends;
/// returns where the new tuples start. SetNumberOfTuples alone reallocates without copying, so
/// Resize first (an output that already held points lost them, and in == out read garbage).
vtkIdType grow_by(vtkDataArray* a, vtkIdType n) {
  const vtkIdType at = a->GetNumberOfTuples();
  if (at == 0) a->SetNumberOfComponents(3);
  a->Resize(at + n);
  a->SetNumberOfTuples(at + n);
  return at;
}
}  // namespace

void vtkCSRBFTransform::TransformPoints(vtkPoints* in, vtkPoints* out) {
  this->Update();
  if (this->InverseFlag || !this->Map) {  // the inverse is Newton's, point by point
    this->vtkWarpTransform::TransformPoints(in, out);
    return;
  }
  const vtkIdType n = in->GetNumberOfPoints();
  const vtkIdType start = grow_by(out->GetData(), n);
  // Contiguous float or double arrays go through the batch path without a copy (an array of another
  // layout, vtkSOADataArrayTemplate, gives a copy from GetVoidPointer: the generic path).
  vtkDataArray* src = in->GetData();
  vtkDataArray* dst = out->GetData();
  const auto& map = this->Map->map;
  const bool raw = src->HasStandardMemoryLayout() && dst->HasStandardMemoryLayout();
  if (raw && src->GetDataType() == VTK_DOUBLE && dst->GetDataType() == VTK_DOUBLE) {
    map.apply(static_cast<double*>(src->GetVoidPointer(0)), static_cast<double*>(dst->GetVoidPointer(3 * start)),
              std::size_t(n), this->Phase);
  } else if (raw && src->GetDataType() == VTK_FLOAT && dst->GetDataType() == VTK_FLOAT) {
    map.apply(static_cast<float*>(src->GetVoidPointer(0)), static_cast<float*>(dst->GetVoidPointer(3 * start)),
              std::size_t(n), this->Phase);
  } else {
    std::vector<double> buf(3 * std::size_t(n));
    for (vtkIdType i = 0; i < n; ++i) in->GetPoint(i, buf.data() + 3 * i);
    map.apply(buf.data(), buf.data(), std::size_t(n), this->Phase);
    for (vtkIdType i = 0; i < n; ++i) out->SetPoint(start + i, buf.data() + 3 * i);
  }
  out->Modified();
}

void vtkCSRBFTransform::TransformPointsNormalsVectors(vtkPoints* inPts, vtkPoints* outPts, vtkDataArray* inNms,
                                                      vtkDataArray* outNms, vtkDataArray* inVrs, vtkDataArray* outVrs,
                                                      int nOptionalVectors, vtkDataArray** inVrsArr,
                                                      vtkDataArray** outVrsArr) {
  this->Update();
  // Outputs of another shape than 3 components that already hold tuples: VTK's own way with them.
  const auto odd = [](vtkDataArray* a) { return a && a->GetNumberOfTuples() > 0 && a->GetNumberOfComponents() != 3; };
  bool odd_output = (inNms && odd(outNms)) || (inVrs && odd(outVrs));
  for (int k = 0; inVrsArr && outVrsArr && k < nOptionalVectors; ++k) odd_output = odd_output || odd(outVrsArr[k]);
  if (this->InverseFlag || !this->Map || odd_output) {
    this->vtkWarpTransform::TransformPointsNormalsVectors(inPts, outPts, inNms, outNms, inVrs, outVrs, nOptionalVectors,
                                                          inVrsArr, outVrsArr);
    return;
  }
  const vtkIdType n = inPts->GetNumberOfPoints();
  // Each output grows by n tuples as VTK's per-point path appends them, sized here once so that the
  // blocks below set their own tuples in parallel.
  const vtkIdType start = grow_by(outPts->GetData(), n);
  const auto grow = [n](vtkDataArray* a) { return grow_by(a, n); };
  const vtkIdType normals_at = inNms ? grow(outNms) : 0, vectors_at = inVrs ? grow(outVrs) : 0;
  std::vector<vtkIdType> optional_at;
  for (int k = 0; inVrsArr && k < nOptionalVectors; ++k) optional_at.push_back(grow(outVrsArr[k]));
  const bool vectors = inVrs || (nOptionalVectors > 0 && inVrsArr);
  const auto& map = this->Map->map;
  const double phase = this->Phase;
  // Points as contiguous arrays of one type, float or double, normals as contiguous float or double
  // arrays, and no vectors: the core evaluates them in place in the points' arrays (float in float
  // where the map's float check passes), normals scaled to 1 as VTK's per-point path normalises
  // them. Normals of the other type (double points with float normals: vtkSphereSource's default
  // at double precision) are converted to the points' type around the call, in parallel.
  vtkDataArray* const pin = inPts->GetData();
  vtkDataArray* const pout = outPts->GetData();
  vtkDataArray *const nin = inNms, *const nout = inNms ? outNms : nullptr;
  const auto contiguous = [](vtkDataArray* a) {
    return !a || (a->HasStandardMemoryLayout() && (a->GetDataType() == VTK_FLOAT || a->GetDataType() == VTK_DOUBLE));
  };
  if (!vectors && pin->GetDataType() == pout->GetDataType() && contiguous(pin) && contiguous(pout) && contiguous(nin) &&
      contiguous(nout)) {
    const auto direct = [&](auto* type) {
      using T = std::remove_pointer_t<decltype(type)>;
      constexpr int own = std::is_same_v<T, float> ? VTK_FLOAT : VTK_DOUBLE;
      const auto at = [](vtkDataArray* a, vtkIdType tuple) { return static_cast<T*>(a->GetVoidPointer(3 * tuple)); };
      if (!nin || (nin->GetDataType() == own && nout->GetDataType() == own)) {
        map.apply_with_normals(at(pin, 0), at(pout, start), std::size_t(n), phase, nin ? at(nin, 0) : nullptr,
                               nin ? at(nout, normals_at) : nullptr, nullptr, true);
        return;
      }
      // Normals of the other type: blocks in parallel, each block's normals converted into its
      // task's buffer, deformed (a block runs in its thread) and converted back. (One conversion
      // of the whole array into a fresh buffer cost more than the deformation: page faults and the
      // buffer's zeroing.)
      const auto convert = [](vtkDataArray* a, vtkIdType first, vtkIdType count, T* to, bool out) {
        const auto go = [&](auto* p) {
          for (vtkIdType k = 0; k < 3 * count; ++k) {
            if (out)
              p[3 * first + k] = static_cast<std::remove_pointer_t<decltype(p)>>(to[k]);
            else
              to[k] = static_cast<T>(p[3 * first + k]);
          }
        };
        if (a->GetDataType() == VTK_FLOAT)
          go(static_cast<float*>(a->GetVoidPointer(0)));
        else
          go(static_cast<double*>(a->GetVoidPointer(0)));
      };
      constexpr vtkIdType block = 4096;
      tbb::parallel_for(tbb::blocked_range<vtkIdType>(0, n, block), [&](const tbb::blocked_range<vtkIdType>& r) {
        std::vector<T> nm(3 * std::size_t(block));  // the task's own (see SpaceMap's float fallback)
        for (vtkIdType b0 = r.begin(); b0 < r.end(); b0 += block) {
          const vtkIdType m = std::min(block, r.end() - b0);
          convert(nin, b0, m, nm.data(), false);
          map.apply_with_normals(at(pin, b0), at(pout, start + b0), std::size_t(m), phase, nm.data(), nm.data(),
                                 nullptr, true);
          convert(nout, normals_at + b0, m, nm.data(), true);
        }
      });
    };
    if (pin->GetDataType() == VTK_FLOAT)
      direct(static_cast<float*>(nullptr));
    else
      direct(static_cast<double*>(nullptr));
    outPts->Modified();
    if (nout) nout->Modified();
    return;
  }
  // Otherwise gathered into doubles (VTK's own path computes in double too), a block at a time in
  // parallel.
  constexpr vtkIdType block = 4096;
  tbb::parallel_for(tbb::blocked_range<vtkIdType>(0, (n + block - 1) / block),
                    [&](const tbb::blocked_range<vtkIdType>& r) {
                      std::vector<double> p, nm, jac;
                      for (vtkIdType b = r.begin(); b < r.end(); ++b) {
                        const vtkIdType first = b * block, m = std::min(block, n - first);
                        p.resize(3 * std::size_t(m));
                        nm.resize(inNms ? 3 * std::size_t(m) : 0);
                        jac.resize(vectors ? 9 * std::size_t(m) : 0);
                        for (vtkIdType i = 0; i < m; ++i) {
                          inPts->GetPoint(first + i, p.data() + 3 * i);
                          if (inNms) inNms->GetTuple(first + i, nm.data() + 3 * i);
                        }
                        map.apply_with_normals(p.data(), p.data(), std::size_t(m), phase, inNms ? nm.data() : nullptr,
                                               inNms ? nm.data() : nullptr, vectors ? jac.data() : nullptr);
                        for (vtkIdType i = 0; i < m; ++i) {
                          outPts->SetPoint(start + first + i, p.data() + 3 * i);
                          if (inNms) {
                            double* v = nm.data() + 3 * i;
                            vtkMath::Normalize(v);
                            outNms->SetTuple(normals_at + first + i, v);
                          }
                          const auto vector = [&](vtkDataArray* from, vtkDataArray* to, vtkIdType at) {
                            double v[3], w[3];
                            from->GetTuple(first + i, v);
                            const double* j = jac.data() + 9 * i;
                            for (int a = 0; a < 3; ++a)
                              w[a] = j[3 * a] * v[0] + j[3 * a + 1] * v[1] + j[3 * a + 2] * v[2];
                            to->SetTuple(at + first + i, w);
                          };
                          if (inVrs) vector(inVrs, outVrs, vectors_at);
                          for (std::size_t k = 0; k < optional_at.size(); ++k)
                            vector(inVrsArr[k], outVrsArr[k], optional_at[k]);
                        }
                      }
                    });
  outPts->Modified();
}

vtkAbstractTransform* vtkCSRBFTransform::MakeTransform() { return vtkCSRBFTransform::New(); }

void vtkCSRBFTransform::InternalDeepCopy(vtkAbstractTransform* transform) {
  auto* t = static_cast<vtkCSRBFTransform*>(transform);
  this->SetInverseTolerance(t->InverseTolerance);
  this->SetInverseIterations(t->InverseIterations);
  this->Radius = t->Radius;
  this->Kernel = t->Kernel;
  this->Polynomial = t->Polynomial;
  this->Phase = t->Phase;
  this->SetSourceLandmarks(t->SourceLandmarks);
  this->SetTargetLandmarks(t->TargetLandmarks);
  if (this->InverseFlag != t->InverseFlag) {
    this->InverseFlag = t->InverseFlag;
    this->Modified();
  }
}

void vtkCSRBFTransform::PrintSelf(ostream& os, vtkIndent indent) {
  this->Superclass::PrintSelf(os, indent);
  os << indent << "Radius: " << this->Radius << "\n"
     << indent << "Kernel: C" << this->Kernel << "\n"
     << indent << "Polynomial: " << this->Polynomial << "\n"
     << indent << "Phase: " << this->Phase << "\n"
     << indent << "SourceLandmarks: " << this->SourceLandmarks << "\n"
     << indent << "TargetLandmarks: " << this->TargetLandmarks << "\n"
     << indent << "LastError: " << this->LastError << "\n";
}
