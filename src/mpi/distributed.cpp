#include "csrbf/mpi/distributed.hpp"

#include "csrbf/detail/kernel_solver.hpp"
#include "csrbf/errors.hpp"
#include "csrbf/kernels.hpp"
#include "csrbf/mpi/runtime.hpp"
#include "csrbf/kernel_matrix.hpp"
#include "csrbf/neighbor_index.hpp"
#include "csrbf/ordering.hpp"
#include "csrbf/units.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <petscksp.h>
#include <petscmat.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <sstream>
#include <unordered_map>

namespace csrbf::mpi {

namespace {

std::string num(double v) { return format_significant(v, 10); }

struct Box {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 hi = Vec3::Constant(-std::numeric_limits<double>::infinity());
  bool empty() const { return !(lo.x() <= hi.x()); }
  void add(const Vec3& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  /// Distance from p to the box (0 inside); infinite for an empty box.
  double distance(const Vec3& p) const {
    if (empty()) return std::numeric_limits<double>::infinity();
    return (lo - p).cwiseMax(p - hi).cwiseMax(0.0).norm();
  }
};

Box box_of(std::span<const Vec3> p) {
  Box b;
  for (const Vec3& x : p) b.add(x);
  return b;
}

std::vector<Box> all_boxes(MPI_Comm comm, const Box& mine, std::size_t& bytes) {
  int size = 1;
  MPI_Comm_size(comm, &size);
  double v[6] = {mine.lo.x(), mine.lo.y(), mine.lo.z(), mine.hi.x(), mine.hi.y(), mine.hi.z()};
  std::vector<double> all(6 * std::size_t(size));
  MPI_Allgather(v, 6, MPI_DOUBLE, all.data(), 6, MPI_DOUBLE, comm);
  bytes += sizeof(v) * std::size_t(size - 1);
  std::vector<Box> boxes(static_cast<std::size_t>(size));
  for (int r = 0; r < size; ++r) {
    const double* a = all.data() + 6 * r;
    boxes[std::size_t(r)].lo = Vec3(a[0], a[1], a[2]);
    boxes[std::size_t(r)].hi = Vec3(a[3], a[4], a[5]);
  }
  return boxes;
}

/// A control sent to another rank: its global row (or position), its id for messages, its source
/// and a vector (a displacement, or the coefficients).
struct Packet {
  std::uint64_t global = 0, user = 0;
  double x[3] = {0, 0, 0}, v[3] = {0, 0, 0};
  Vec3 source() const { return Vec3(x[0], x[1], x[2]); }
  Vec3 value() const { return Vec3(v[0], v[1], v[2]); }
};
static_assert(std::is_trivially_copyable_v<Packet>);

Packet packet(std::uint64_t global, std::uint64_t user, const Vec3& x, const Vec3& v) {
  Packet p;
  p.global = global;
  p.user = user;
  for (int c = 0; c < 3; ++c) {
    p.x[c] = x[c];
    p.v[c] = v[c];
  }
  return p;
}

/// Each rank's packets for every other rank, exchanged (MPI_Alltoallv); what this rank received, in
/// rank order, with the rank each came from.
std::vector<Packet> exchange(MPI_Comm comm, const std::vector<std::vector<Packet>>& out, std::vector<int>* from,
                             std::size_t& bytes) {
  int size = 1;
  MPI_Comm_size(comm, &size);
  std::vector<int> send_counts(static_cast<std::size_t>(size)), recv_counts(static_cast<std::size_t>(size));
  for (int r = 0; r < size; ++r) {
    const std::size_t b = out[std::size_t(r)].size() * sizeof(Packet);
    if (b > std::size_t(INT_MAX))
      throw ResourceLimit("a halo of " + std::to_string(out[std::size_t(r)].size()) +
                          " controls for one rank passes what one MPI message carries (2 GiB): use more ranks");
    send_counts[std::size_t(r)] = int(b);
  }
  MPI_Alltoall(send_counts.data(), 1, MPI_INT, recv_counts.data(), 1, MPI_INT, comm);
  std::vector<int> send_displs(static_cast<std::size_t>(size), 0), recv_displs(static_cast<std::size_t>(size), 0);
  long long send_total = 0, recv_total = 0;
  for (int r = 0; r < size; ++r) {
    send_displs[std::size_t(r)] = int(send_total);
    recv_displs[std::size_t(r)] = int(recv_total);
    send_total += send_counts[std::size_t(r)];
    recv_total += recv_counts[std::size_t(r)];
  }
  if (send_total > INT_MAX || recv_total > INT_MAX)
    throw ResourceLimit(
        "a rank's halo passes what one MPI exchange carries (2 GiB): use more ranks or a smaller radius");
  std::vector<Packet> send(std::size_t(send_total) / sizeof(Packet)), recv(std::size_t(recv_total) / sizeof(Packet));
  std::size_t k = 0;
  for (int r = 0; r < size; ++r)
    for (const Packet& p : out[std::size_t(r)]) send[k++] = p;
  MPI_Alltoallv(send.data(), send_counts.data(), send_displs.data(), MPI_BYTE, recv.data(), recv_counts.data(),
                recv_displs.data(), MPI_BYTE, comm);
  bytes += std::size_t(send_total);
  if (from) {
    from->clear();
    for (int r = 0; r < size; ++r)
      from->insert(from->end(), std::size_t(recv_counts[std::size_t(r)]) / sizeof(Packet), r);
  }
  return recv;
}

std::size_t sum(MPI_Comm comm, std::size_t v, std::size_t& bytes) {
  unsigned long long a = v, b = 0;
  MPI_Allreduce(&a, &b, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, comm);
  bytes += sizeof(a);
  return std::size_t(b);
}

double max_of(MPI_Comm comm, double v, std::size_t& bytes) {
  double out = 0;
  MPI_Allreduce(&v, &out, 1, MPI_DOUBLE, MPI_MAX, comm);
  bytes += sizeof(v);
  return out;
}

/// An exact-position key (the bits of the three coordinates) for the dedupe of shared points.
struct PositionHash {
  std::size_t operator()(const Vec3& p) const noexcept {
    std::uint64_t h = 1469598103934665603ull;
    for (int c = 0; c < 3; ++c) {
      std::uint64_t b;
      const double v = p[c] == 0.0 ? 0.0 : p[c];  // -0 and +0 alike
      std::memcpy(&b, &v, sizeof b);
      h = (h ^ b) * 1099511628211ull;
    }
    return std::size_t(h);
  }
};

/// PETSc objects released on every path.
struct PetscMat {
  Mat m = nullptr;
  ~PetscMat() {
    if (m) MatDestroy(&m);
  }
};
struct PetscVec {
  Vec v = nullptr;
  ~PetscVec() {
    if (v) VecDestroy(&v);
  }
};
/// Auto's probe of CG (the serial rule's, fit_options.hpp): every 10 steps from step 20, the steps
/// still needed are predicted from the rate the residual fell over the last two thirds of the steps
/// taken, and CG gives way to MUMPS where they pass `budget`.
struct CgProbe {
  void* default_test = nullptr;
  double budget = 0;
  std::vector<double> log_residual;
  bool gave_way = false;
  double predicted = 0;
};

PetscErrorCode probe_test(KSP ksp, PetscInt it, PetscReal rnorm, KSPConvergedReason* reason, void* p) {
  auto* probe = static_cast<CgProbe*>(p);
  const PetscErrorCode e = KSPConvergedDefault(ksp, it, rnorm, reason, probe->default_test);
  if (e != 0 || *reason != KSP_CONVERGED_ITERATING) return e;
  if (it == 0) probe->log_residual.clear();
  probe->log_residual.push_back(std::log(std::max(double(rnorm), 1e-300)));
  const std::size_t k = probe->log_residual.size() - 1;
  if (k >= 20 && k % 10 == 0) {
    const std::size_t k0 = k / 3;
    const double rate = (probe->log_residual[k] - probe->log_residual[k0]) / double(k - k0);
    const double to_go = std::log(kCgTolerance) + probe->log_residual[0] - probe->log_residual[k];
    const double predicted = rate < 0 ? double(k) + to_go / rate : std::numeric_limits<double>::infinity();
    if (predicted > probe->budget) {
      probe->gave_way = true;
      probe->predicted = predicted;
      *reason = KSP_DIVERGED_ITS;
    }
  }
  return 0;
}

PetscErrorCode destroy_probe(void* p) {
  auto* probe = static_cast<CgProbe*>(p);
  if (probe->default_test) KSPConvergedDefaultDestroy(probe->default_test);
  probe->default_test = nullptr;
  return 0;
}

struct PetscKsp {
  KSP k = nullptr;
  CgProbe probe;
  ~PetscKsp() {
    if (k) KSPDestroy(&k);
  }
};

using Columns = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic>;

/// Whether PETSc's options replace csrbf's KSP or PC ("-csrbf_ksp_type", "-csrbf_pc_type").
bool petsc_options_set() {
  PetscBool ksp = PETSC_FALSE, pc = PETSC_FALSE;
  PetscOptionsHasName(nullptr, "csrbf_", "-ksp_type", &ksp);
  PetscOptionsHasName(nullptr, "csrbf_", "-pc_type", &pc);
  return ksp == PETSC_TRUE || pc == PETSC_TRUE;
}

/// One rank's CG: the serial fit's own (the core's conjugate gradients on the same matrix, in the
/// reverse Cuthill-McKee order, its block incomplete Cholesky where plain CG's first steps predict
/// a long solve), every column of rhs in one block solve. False where Auto's budget is passed
/// (predicted steps) or CG stagnates, as PETSc's KSP reports divergence.
bool core_cg(std::span<const Vec3> sources, const FitOptions& options, const Columns& rhs, double budget, Columns& sol,
             std::size_t& iterations) {
  const NeighborIndex index(sources, options.radius);
  const KernelMatrix a(AdjacencyGraph::from_index(index, sources, options.memory_limit_bytes / 12.0), options.kernel,
                       options.radius);
  std::vector<std::uint32_t> order = reverse_cuthill_mckee_order(a.pattern());
  detail::CgProbe probe;
  if (budget > 0) {
    probe.steps = 10;
    probe.worth_it = [budget](double predicted, double) { return predicted <= budget; };
  }
  const auto cg = detail::conjugate_gradients(a, std::move(order), kCgTolerance, kCgMaxIterations, std::move(probe));
  RowMatrix b = rhs;
  if (!cg->solve(b).ok()) return false;  // stagnated, or gave way to the budget: a status, as KSP's
  sol = b;
  iterations = std::max(iterations, cg->iterations());
  return true;
}

/// The KSP of one solver over A: MUMPS's Cholesky (PCCHOLESKY, MATSOLVERMUMPS, factorised at the
/// first solve and reused), or CG with additive Schwarz and a shifted incomplete Cholesky on each block.
void make_ksp(MPI_Comm comm, Mat a, DistributedSolver s, PetscKsp& ksp, int workspace_percent, double cg_budget) {
  if (ksp.k) KSPDestroy(&ksp.k);
  ksp.probe = CgProbe{};
  check_petsc(KSPCreate(comm, &ksp.k), "KSPCreate");
  check_petsc(KSPSetOperators(ksp.k, a, a), "KSPSetOperators");
  PC pc = nullptr;
  check_petsc(KSPGetPC(ksp.k, &pc), "KSPGetPC");
  if (s == DistributedSolver::Mumps) {
    check_petsc(KSPSetType(ksp.k, KSPPREONLY), "KSPSetType(preonly)");
    check_petsc(PCSetType(pc, PCCHOLESKY), "PCSetType(cholesky)");
    check_petsc(PCFactorSetMatSolverType(pc, MATSOLVERMUMPS), "PCFactorSetMatSolverType(mumps)");
    check_petsc(PCFactorSetUpMatSolverType(pc), "PCFactorSetUpMatSolverType");
    Mat f = nullptr;
    check_petsc(PCFactorGetMatrix(pc, &f), "PCFactorGetMatrix");
    // ICNTL(14): the room MUMPS adds to its estimated workspace, in percent. Its estimate can fall
    // short with the parallel ordering (INFOG(1) = -9): the caller retries with more.
    check_petsc(MatMumpsSetIcntl(f, 14, workspace_percent), "MatMumpsSetIcntl(14)");
    check_petsc(KSPSetUp(ksp.k), "the MUMPS factorisation");
  } else {
    check_petsc(KSPSetType(ksp.k, KSPCG), "KSPSetType(cg)");
    check_petsc(KSPSetNormType(ksp.k, KSP_NORM_UNPRECONDITIONED), "KSPSetNormType");
    check_petsc(KSPSetTolerances(ksp.k, kCgTolerance, 1e-300, PETSC_DEFAULT, PetscInt(kCgMaxIterations)),
                "KSPSetTolerances");
    if (cg_budget > 0) {
      ksp.probe.budget = cg_budget;
      check_petsc(KSPConvergedDefaultCreate(&ksp.probe.default_test), "KSPConvergedDefaultCreate");
      check_petsc(KSPSetConvergenceTest(ksp.k, probe_test, &ksp.probe, destroy_probe), "KSPSetConvergenceTest");
    }
    // Additive Schwarz with one layer of overlap, an incomplete Cholesky on each rank's block: block
    // Jacobi (no overlap) needed 47 steps on 2 ranks where one rank's ICC needed 12; the overlap
    // keeps it at 13 (docs/DISTRIBUTED.md).
    check_petsc(PCSetType(pc, PCASM), "PCSetType(asm)");
    check_petsc(PCASMSetOverlap(pc, 1), "PCASMSetOverlap");
    // PETSc's own options (PETSC_OPTIONS="-csrbf_pc_type gamg ...") may replace these defaults.
    check_petsc(KSPSetOptionsPrefix(ksp.k, "csrbf_"), "KSPSetOptionsPrefix");
    check_petsc(KSPSetFromOptions(ksp.k), "KSPSetFromOptions");
    check_petsc(KSPSetUp(ksp.k), "KSPSetUp(cg)");
    PCType type = nullptr;
    check_petsc(PCGetType(pc, &type), "PCGetType");
    if (std::string(type) != PCASM) return;
    PetscInt blocks = 0, first = 0;
    KSP* sub = nullptr;
    check_petsc(PCASMGetSubKSP(pc, &blocks, &first, &sub), "PCASMGetSubKSP");
    for (PetscInt b = 0; b < blocks; ++b) {
      PC sub_pc = nullptr;
      check_petsc(KSPGetPC(sub[b], &sub_pc), "KSPGetPC(sub)");
      check_petsc(PCSetType(sub_pc, PCICC), "PCSetType(icc)");
      check_petsc(PCFactorSetShiftType(sub_pc, MAT_SHIFT_POSITIVE_DEFINITE), "PCFactorSetShiftType");
    }
  }
}

/// Solves A x = b for each column of b (this rank's rows); false where the KSP did not converge
/// (CG), with the steps of the slowest column in `iterations`.
bool solve_columns(Mat a, KSP ksp, const Columns& b, Columns& x, std::size_t& iterations, bool* out_of_memory) {
  PetscVec vb, vx;
  check_petsc(MatCreateVecs(a, &vx.v, &vb.v), "MatCreateVecs");
  x.resize(b.rows(), b.cols());
  for (Eigen::Index c = 0; c < b.cols(); ++c) {
    PetscScalar* p = nullptr;
    check_petsc(VecGetArray(vb.v, &p), "VecGetArray");
    for (Eigen::Index i = 0; i < b.rows(); ++i) p[i] = b(i, c);
    check_petsc(VecRestoreArray(vb.v, &p), "VecRestoreArray");
    check_petsc(VecSet(vx.v, 0.0), "VecSet");
    check_petsc(KSPSolve(ksp, vb.v, vx.v), "KSPSolve");
    KSPConvergedReason reason;
    check_petsc(KSPGetConvergedReason(ksp, &reason), "KSPGetConvergedReason");
    PetscInt it = 0;
    KSPGetIterationNumber(ksp, &it);
    iterations = std::max(iterations, std::size_t(it));
    if (reason < 0) {
      PC pc = nullptr;
      KSPGetPC(ksp, &pc);
      PCFailedReason why = PC_NOERROR;
      PCGetFailedReasonRank(pc, &why);
      if (why == PC_FACTOR_OUTMEMORY) *out_of_memory = true;
      return false;
    }
    const PetscScalar* q = nullptr;
    check_petsc(VecGetArrayRead(vx.v, &q), "VecGetArrayRead");
    for (Eigen::Index i = 0; i < b.rows(); ++i) x(i, c) = q[i];
    check_petsc(VecRestoreArrayRead(vx.v, &q), "VecRestoreArrayRead");
  }
  return true;
}

/// A x for each column of x (this rank's rows).
Columns multiply(Mat a, const Columns& x) {
  PetscVec vx, vy;
  check_petsc(MatCreateVecs(a, &vx.v, &vy.v), "MatCreateVecs");
  Columns y(x.rows(), x.cols());
  for (Eigen::Index c = 0; c < x.cols(); ++c) {
    PetscScalar* p = nullptr;
    check_petsc(VecGetArray(vx.v, &p), "VecGetArray");
    for (Eigen::Index i = 0; i < x.rows(); ++i) p[i] = x(i, c);
    check_petsc(VecRestoreArray(vx.v, &p), "VecRestoreArray");
    check_petsc(MatMult(a, vx.v, vy.v), "MatMult");
    const PetscScalar* q = nullptr;
    check_petsc(VecGetArrayRead(vy.v, &q), "VecGetArrayRead");
    for (Eigen::Index i = 0; i < x.rows(); ++i) y(i, c) = q[i];
    check_petsc(VecRestoreArrayRead(vy.v, &q), "VecRestoreArrayRead");
  }
  return y;
}

/// Sums a small matrix over the ranks.
Columns sum_over_ranks(MPI_Comm comm, const Columns& m, std::size_t& bytes) {
  Columns out(m.rows(), m.cols());
  MPI_Allreduce(m.data(), out.data(), int(m.size()), MPI_DOUBLE, MPI_SUM, comm);
  bytes += std::size_t(m.size()) * sizeof(double);
  return out;
}

/// This rank in the fit's communicator, and its count of the bytes csrbf's own exchanges send.
struct FitRank {
  MPI_Comm comm;
  int rank = 0, size = 1;
  std::size_t& bytes;
};

/// A control's id for messages: ids[i], or i where none are given.
std::uint64_t id_of(std::span<const std::uint64_t> ids, std::size_t i) {
  return ids.empty() ? std::uint64_t(i) : ids[i];
}

/// Checks every rank makes of its own share, agreed before any exchange.
void check_controls(MPI_Comm comm, std::span<const Vec3> sources_in, std::span<const Vec3> destinations_in,
                    std::span<const std::uint64_t> ids_in, const FitOptions& options) {
  const double radius = options.radius;
  collectively(comm, [&] {
    if (sources_in.size() != destinations_in.size())
      throw InvalidInput("control points: " + std::to_string(sources_in.size()) + " sources but " +
                         std::to_string(destinations_in.size()) + " destinations");
    if (!ids_in.empty() && ids_in.size() != sources_in.size())
      throw InvalidInput("control points: " + std::to_string(ids_in.size()) + " ids for " +
                         std::to_string(sources_in.size()) + " controls");
    if (!(radius >= 1e-150 && radius <= 1e150))
      throw InvalidInput("radius must be a positive finite number in [1e-150, 1e150], got " + num(radius));
    if (!(options.memory_limit_bytes > 0))
      throw InvalidInput("memory_limit_bytes must be a number > 0, got " + num(options.memory_limit_bytes));
    for (std::size_t i = 0; i < sources_in.size(); ++i) {
      if (!sources_in[i].allFinite() || !destinations_in[i].allFinite())
        throw InvalidInput("control " + std::to_string(ids_in.empty() ? i : ids_in[i]) +
                           ": a coordinate is not finite");
      // The serial fit's limit (squared distances stay normal doubles).
      if (sources_in[i].cwiseAbs().maxCoeff() > 1e150 || destinations_in[i].cwiseAbs().maxCoeff() > 1e150)
        throw InvalidInput("control " + std::to_string(ids_in.empty() ? i : ids_in[i]) + ": a coordinate beyond 1e150");
    }
  });
}

/// Which of this rank's controls it keeps (1) after the dedupe: a source another rank also has, bit
/// for bit, is owned by the lowest such rank.
std::vector<char> kept_controls(const FitRank& fr, std::span<const Vec3> sources_in,
                                std::span<const Vec3> destinations_in, std::span<const std::uint64_t> ids_in,
                                bool dedupe) {
  std::vector<char> keep(sources_in.size(), 1);
  if (!dedupe || fr.size <= 1) return keep;
  double gmax = 0;
  for (std::size_t i = 0; i < sources_in.size(); ++i)
    gmax = std::max(gmax, (destinations_in[i] - sources_in[i]).norm());
  gmax = max_of(fr.comm, gmax, fr.bytes);
  const std::vector<Box> boxes = all_boxes(fr.comm, box_of(sources_in), fr.bytes);
  std::vector<std::vector<Packet>> out(static_cast<std::size_t>(fr.size));
  for (int r = fr.rank + 1; r < fr.size; ++r)  // only higher ranks drop theirs: send to them
    for (std::size_t i = 0; i < sources_in.size(); ++i)
      if (boxes[std::size_t(r)].distance(sources_in[i]) == 0.0)
        out[std::size_t(r)].push_back(packet(0, id_of(ids_in, i), sources_in[i], destinations_in[i] - sources_in[i]));
  std::vector<int> from;
  const std::vector<Packet> got = exchange(fr.comm, out, &from, fr.bytes);
  collectively(fr.comm, [&] {
    std::unordered_map<Vec3, std::size_t, PositionHash> lower;
    lower.reserve(got.size());
    for (std::size_t k = 0; k < got.size(); ++k) lower.emplace(got[k].source(), k);
    for (std::size_t i = 0; i < sources_in.size(); ++i) {
      const auto it = lower.find(sources_in[i]);
      if (it == lower.end()) continue;
      const Packet& p = got[it->second];
      if ((p.value() - (destinations_in[i] - sources_in[i])).norm() > 1e-12 * std::max(gmax, 1e-300))
        throw InvalidInput("control " + std::to_string(id_of(ids_in, i)) + " on rank " + std::to_string(fr.rank) +
                           " and control " + std::to_string(p.user) + " on rank " + std::to_string(from[it->second]) +
                           " are the same point, moved differently");
      keep[i] = 0;
    }
  });
  return keep;
}

/// The controls over all ranks (Failure where none, or more than PETSc's indices hold), and in
/// `offset` the global row of this rank's first.
std::size_t count_controls(const FitRank& fr, std::size_t n, std::size_t& offset) {
  const std::size_t total = sum(fr.comm, n, fr.bytes);
  if (total == 0) throw Failure("control points: none given on any rank (need at least 1)", 0, 1);
  if (total >= std::size_t(std::numeric_limits<PetscInt>::max()))
    throw Failure("control points: " + std::to_string(total) + " controls: more than PETSc's 32-bit indices hold", 0,
                  1);
  unsigned long long mine = n, before = 0;
  MPI_Exscan(&mine, &before, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, fr.comm);
  offset = fr.rank == 0 ? 0 : std::size_t(before);
  return total;
}

/// The polynomial's frame: the mean of all sources and their spread (as the serial fit).
void polynomial_frame(const FitRank& fr, std::span<const Vec3> sources, std::size_t total, Vec3& center,
                      double& scale) {
  Vec3 s = Vec3::Zero();
  for (const Vec3& x : sources) s += x;
  Vec3 all = Vec3::Zero();
  MPI_Allreduce(s.data(), all.data(), 3, MPI_DOUBLE, MPI_SUM, fr.comm);
  center = all / double(total);
  double spread = 0;
  for (const Vec3& x : sources) spread = std::max(spread, (x - center).cwiseAbs().maxCoeff());
  spread = max_of(fr.comm, spread, fr.bytes);
  scale = spread > 0 ? spread : 1.0;
}

/// Failure where a linear polynomial is not determined: fewer than 4 sources over all ranks, or
/// sources that do not span 3-D space.
void check_linear_span(const FitRank& fr, std::span<const Vec3> sources, std::size_t total, const Vec3& center,
                       double scale) {
  if (total < 4)
    throw Failure("polynomial 'linear' needs at least 4 control points that are not coplanar, got " +
                      std::to_string(total) + "; use polynomial 'constant' or 'none'",
                  0, 1);
  Eigen::Matrix3d utu = Eigen::Matrix3d::Zero();
  for (const Vec3& x : sources) {
    const Vec3 u = (x - center) / scale;
    utu += u * u.transpose();
  }
  const Columns all = sum_over_ranks(fr.comm, Columns(utu), fr.bytes);
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(Eigen::Matrix3d(all), Eigen::EigenvaluesOnly);
  const Vec3 ev = es.eigenvalues().cwiseMax(0.0);
  const double sv0 = std::sqrt(ev(2)), sv1 = std::sqrt(ev(1)), sv2 = std::sqrt(ev(0));
  const double tol = 1e-9 * std::max(sv0, 1e-300);
  if (sv2 <= tol)
    throw Failure("polynomial 'linear' needs control sources that span 3-D space, but the " + std::to_string(total) +
                      " sources are " + (sv1 <= tol ? "collinear" : "coplanar") +
                      "; use polynomial 'constant' or 'none'",
                  0, 1);
}

/// The halo of the matrix rows: every rank's controls within R of this rank's controls.
std::vector<Packet> row_halo(const FitRank& fr, std::span<const Vec3> sources, std::span<const std::uint64_t> ids,
                             std::size_t offset, double radius) {
  const std::vector<Box> boxes = all_boxes(fr.comm, box_of(sources), fr.bytes);
  std::vector<std::vector<Packet>> out(static_cast<std::size_t>(fr.size));
  for (int r = 0; r < fr.size; ++r) {
    if (r == fr.rank) continue;
    for (std::size_t i = 0; i < sources.size(); ++i)
      if (boxes[std::size_t(r)].distance(sources[i]) < radius)
        out[std::size_t(r)].push_back(packet(offset + i, ids[i], sources[i], Vec3::Zero()));
  }
  return exchange(fr.comm, out, nullptr, fr.bytes);
}

/// This rank's rows of A in compressed form, global column numbers.
struct LocalRows {
  std::vector<PetscInt> row_start, cols;
  std::vector<double> vals;
};

/// The rows of this rank's controls: neighbours among the owned and halo controls. Everything that
/// can fail on this rank alone (a duplicate source, the memory limit), agreed before PETSc's
/// collective calls.
LocalRows matrix_rows(const FitRank& fr, std::span<const Vec3> sources, std::span<const std::uint64_t> ids,
                      std::span<const Packet> halo, std::size_t offset, const FitOptions& options, RankStats& rs) {
  const std::size_t n = sources.size();
  const double radius = options.radius;
  LocalRows rows;
  std::vector<PetscInt>& row_start = rows.row_start;
  std::vector<PetscInt>& cols = rows.cols;
  std::vector<double>& vals = rows.vals;
  row_start.assign(n + 1, 0);
  collectively(fr.comm, [&] {
    std::vector<Vec3> local(sources.begin(), sources.end());
    for (const Packet& p : halo) local.push_back(p.source());
    const NeighborIndex index(local, radius);
    const auto global_of = [&](std::size_t j) { return j < n ? offset + j : halo[j - n].global; };
    const auto user_of = [&](std::size_t j) { return j < n ? ids[j] : halo[j - n].user; };
    std::size_t nnz = 0;
    for (std::size_t i = 0; i < n; ++i) {
      index.for_each_within(sources[i], [&](std::size_t j, double d2) {
        if (d2 == 0.0 && j != i)
          throw DuplicateSource(std::min(user_of(i), user_of(j)), std::max(user_of(i), user_of(j)),
                                "controls " + std::to_string(user_of(i)) + " and " + std::to_string(user_of(j)) +
                                    " have the same source " + num(sources[i].x()) + " " + num(sources[i].y()) + " " +
                                    num(sources[i].z()));
        ++nnz;
      });
    }
    // PETSc's matrix (a value and a column index an entry, twice while assembling) and MUMPS's
    // factor, at least as large again: refused before anything is allocated.
    const double need = 48.0 * double(nnz);
    if (need > options.memory_limit_bytes)
      throw ResourceLimit("the matrix rows of rank " + std::to_string(fr.rank) + " hold " + std::to_string(nnz) +
                          " entries (" + num(need / kGiB) + " GiB with the factor), more than the limit of " +
                          num(options.memory_limit_bytes / kGiB) + " GiB: use a smaller radius or more ranks");
    cols.reserve(nnz);
    vals.reserve(nnz);
    for (std::size_t i = 0; i < n; ++i) {
      index.for_each_within(sources[i], [&](std::size_t j, double d2) {
        const std::size_t gj = global_of(j);
        cols.push_back(PetscInt(gj));
        vals.push_back(wendland(options.kernel, std::sqrt(d2) / radius));
      });
      row_start[i + 1] = PetscInt(cols.size());
    }
    rs.matrix_nonzeros = cols.size();
  });
  return rows;
}

/// A (n of `total` rows on this rank) handed to PETSc, each row's columns ascending first.
void create_matrix(MPI_Comm comm, LocalRows& rows, std::size_t total, PetscMat& a) {
  const std::size_t n = rows.row_start.size() - 1;
  std::vector<PetscInt>& cols = rows.cols;
  std::vector<double>& vals = rows.vals;
  // Each row's columns ascending, then the whole local CSR handed to PETSc in one call (row by row
  // MatSetValues took 7 s at 1e6 rows).
  {
    std::vector<std::pair<PetscInt, double>> row;
    for (std::size_t i = 0; i < n; ++i) {
      const auto b = std::size_t(rows.row_start[i]), e = std::size_t(rows.row_start[i + 1]);
      row.clear();
      for (std::size_t k = b; k < e; ++k) row.emplace_back(cols[k], vals[k]);
      std::sort(row.begin(), row.end());
      for (std::size_t k = b; k < e; ++k) {
        cols[k] = row[k - b].first;
        vals[k] = row[k - b].second;
      }
    }
  }
  check_petsc(MatCreate(comm, &a.m), "MatCreate");
  check_petsc(MatSetSizes(a.m, PetscInt(n), PetscInt(n), PetscInt(total), PetscInt(total)), "MatSetSizes");
  check_petsc(MatSetType(a.m, MATMPIAIJ), "MatSetType(mpiaij)");
  check_petsc(MatMPIAIJSetPreallocationCSR(a.m, rows.row_start.data(), cols.data(), vals.data()),
              "MatMPIAIJSetPreallocationCSR");
  check_petsc(MatAssemblyBegin(a.m, MAT_FINAL_ASSEMBLY), "MatAssemblyBegin");
  check_petsc(MatAssemblyEnd(a.m, MAT_FINAL_ASSEMBLY), "MatAssemblyEnd");
  check_petsc(MatSetOption(a.m, MAT_SYMMETRIC, PETSC_TRUE), "MatSetOption(symmetric)");
  check_petsc(MatSetOption(a.m, MAT_SPD, PETSC_TRUE), "MatSetOption(spd)");
  std::vector<PetscInt>().swap(cols);
  std::vector<double>().swap(vals);
}

/// Right-hand sides: the displacements g, then P = [1, u] (u = (x - center) / scale).
Columns right_hand_sides(std::span<const Vec3> sources, std::span<const Vec3> g, const Vec3& center, double scale,
                         int terms) {
  const std::size_t n = sources.size();
  Columns rhs(Eigen::Index(n), 3 + terms);
  for (std::size_t i = 0; i < n; ++i) {
    rhs.row(Eigen::Index(i)).head<3>() = g[i].transpose();
    if (terms > 0) rhs(Eigen::Index(i), 3) = 1.0;
    if (terms == 4) rhs.row(Eigen::Index(i)).tail<3>() = ((sources[i] - center) / scale).transpose();
  }
  return rhs;
}

/// A sol = rhs, by `solver` (Auto: MUMPS up to kDirectBelow controls, else CG, which gives way to
/// MUMPS where it does not converge); Failure where none solves it. Returns the solver that solved;
/// stats.core_cg and stats.fell_back as it went. ksp: the solver's, kept by the caller.
DistributedSolver solve_system(const FitRank& fr, Mat a, DistributedSolver solver, std::size_t total,
                               std::span<const Vec3> sources, const FitOptions& options, const Columns& rhs,
                               PetscKsp& ksp, Columns& sol, std::size_t& iterations, DistributedStats& stats) {
  const MPI_Comm comm = fr.comm;
  DistributedSolver use = solver;
  if (use == DistributedSolver::Auto) use = total <= kDirectBelow ? DistributedSolver::Mumps : DistributedSolver::Cg;
  const auto run = [&](DistributedSolver s) {
    for (int workspace = 50; workspace <= 3200; workspace *= 4) {
      int ok = 1, out_of_memory = 0;
      // Auto's CG gives way where MUMPS is predicted cheaper: a factorisation cost kMumpsCgSteps CG
      // steps at 1e5 controls, and the ratio grows with N (3-D nested dissection: factor flops ~N^2,
      // a CG step ~N).
      const double budget = solver == DistributedSolver::Auto && s == DistributedSolver::Cg
                                ? kMumpsCgSteps * std::max(1.0, double(total) / 1e5)
                                : 0.0;
      // One rank and csrbf's own CG: the serial fit's solver, not a second implementation.
      if (fr.size == 1 && s == DistributedSolver::Cg && !petsc_options_set()) {
        stats.core_cg = true;
        return core_cg(sources, options, rhs, budget, sol, iterations);
      }
      collectively(comm, [&] {
        make_ksp(comm, a, s, ksp, workspace, budget);
        bool oom = false;
        ok = solve_columns(a, ksp.k, rhs, sol, iterations, &oom) ? 1 : 0;
        out_of_memory = oom ? 1 : 0;
      });
      int flags[2] = {ok, -out_of_memory}, all[2] = {0, 0};
      MPI_Allreduce(flags, all, 2, MPI_INT, MPI_MIN, comm);
      if (all[0] == 1) return true;
      if (s != DistributedSolver::Mumps || all[1] == 0) return false;
    }
    return false;
  };
  bool solved = run(use);
  if (!solved && use == DistributedSolver::Cg && solver == DistributedSolver::Auto) {
    stats.fell_back = true;
    use = DistributedSolver::Mumps;
    solved = run(use);
  }
  if (!solved)
    throw Failure(use == DistributedSolver::Cg
                      ? "conjugate gradients did not converge in " + std::to_string(kCgMaxIterations) +
                            " steps (--solver mumps factorises instead)"
                      : "MUMPS's Cholesky factorisation failed: the interpolation matrix is not numerically positive "
                        "definite (sources too close together for R = " +
                            num(options.radius) + ")",
                  0, 1);
  return use;
}

/// The polynomial block: (P^T Y) beta = P^T z, alpha = z - Y beta, with Y = A^-1 P, z = A^-1 g (sol's
/// columns, P the last `terms` of rhs). Returns alpha; beta's first `terms` rows are set.
Columns polynomial_block(const FitRank& fr, const Columns& sol, const Columns& rhs, int terms,
                         const FitOptions& options, Eigen::Matrix<double, 4, 3>& beta) {
  Columns alpha = sol.leftCols(3);
  if (terms > 0) {
    const Columns y = sol.rightCols(terms);
    const Columns p = rhs.rightCols(terms);
    const Columns s = sum_over_ranks(fr.comm, Columns(p.transpose() * y), fr.bytes);
    const Columns t = sum_over_ranks(fr.comm, Columns(p.transpose() * alpha), fr.bytes);
    Eigen::LLT<Eigen::MatrixXd> llt(s);
    if (llt.info() != Eigen::Success)
      throw Failure("the polynomial block P^T A^-1 P is not positive definite (controls degenerate for polynomial '" +
                        std::string(polynomial_name(options.polynomial)) + "')",
                    0, 1);
    const Columns b = llt.solve(t);
    alpha -= y * b;
    beta.topRows(terms) = b;
  }
  return alpha;
}

/// The residual, global: max ||A alpha + P beta - g|| over max ||g||.
double relative_residual(const FitRank& fr, Mat a, std::span<const Vec3> sources, std::span<const Vec3> g,
                         const Eigen::Matrix<double, Eigen::Dynamic, 3>& alpha, const Eigen::Matrix<double, 4, 3>& beta,
                         const Vec3& center, double scale, int terms) {
  double res = 0, gmax = 0;
  const Columns aa = multiply(a, Columns(alpha));
  for (std::size_t i = 0; i < sources.size(); ++i) {
    Vec3 v = aa.row(Eigen::Index(i)).transpose();
    if (terms > 0) {
      const Vec3 u = (sources[i] - center) / scale;
      v += (beta.row(0) + u.transpose() * beta.bottomRows<3>()).transpose();
    }
    const double e = (v - g[i]).norm();
    res = std::isnan(e) ? std::numeric_limits<double>::infinity() : std::max(res, e);
    gmax = std::max(gmax, g[i].norm());
  }
  if (!alpha.allFinite() || !beta.allFinite()) res = std::numeric_limits<double>::infinity();
  res = max_of(fr.comm, res, fr.bytes);
  gmax = max_of(fr.comm, gmax, fr.bytes);
  return gmax > 0 ? res / gmax : res;
}

}  // namespace

std::optional<DistributedSolver> parse_distributed_solver(const std::string& name) noexcept {
  if (name == "auto") return DistributedSolver::Auto;
  if (name == "mumps" || name == "envelope" || name == "eigen" || name == "cholmod") return DistributedSolver::Mumps;
  if (name == "cg") return DistributedSolver::Cg;
  return std::nullopt;
}

std::string distributed_solver_name(DistributedSolver s) {
  return s == DistributedSolver::Auto ? "auto" : s == DistributedSolver::Mumps ? "mumps" : "cg";
}

DistributedMap DistributedMap::fit(MPI_Comm comm, std::span<const Vec3> sources_in,
                                   std::span<const Vec3> destinations_in, const FitOptions& options,
                                   DistributedSolver solver, std::span<const std::uint64_t> ids_in, bool dedupe) {
  DistributedMap m;
  m.comm_ = comm;
  m.options_ = options;
  int rank = 0, size = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  RankStats& rs = m.rank_stats_;
  rs.rank = rank;
  const FitRank fr{comm, rank, size, rs.bytes_sent};
  const double radius = options.radius;
  const auto t_halo = Clock::now();

  check_controls(comm, sources_in, destinations_in, ids_in, options);
  const std::vector<char> keep = kept_controls(fr, sources_in, destinations_in, ids_in, dedupe);
  std::vector<std::uint64_t> ids;
  for (std::size_t i = 0; i < sources_in.size(); ++i) {
    if (!keep[i]) {
      ++rs.controls_dropped;
      continue;
    }
    m.sources_.push_back(sources_in[i]);
    ids.push_back(id_of(ids_in, i));
  }
  std::vector<Vec3> g;  // displacements
  for (std::size_t i = 0; i < sources_in.size(); ++i)
    if (keep[i]) g.push_back(destinations_in[i] - sources_in[i]);
  const std::size_t n = m.sources_.size();
  const std::size_t total = count_controls(fr, n, m.offset_);
  rs.controls_owned = n;
  m.stats_.controls = total;
  m.stats_.ranks = std::size_t(size);

  const int terms = options.polynomial == Polynomial::None ? 0 : options.polynomial == Polynomial::Constant ? 1 : 4;
  polynomial_frame(fr, m.sources_, total, m.center_, m.scale_);
  if (options.polynomial == Polynomial::Linear) check_linear_span(fr, m.sources_, total, m.center_, m.scale_);

  const std::vector<Packet> halo = row_halo(fr, m.sources_, ids, m.offset_, radius);
  rs.controls_halo = halo.size();
  rs.seconds_halo = seconds_since(t_halo);

  const auto t_asm = Clock::now();
  PetscMat a;
  LocalRows rows = matrix_rows(fr, m.sources_, ids, halo, m.offset_, options, rs);
  create_matrix(comm, rows, total, a);
  rs.seconds_assembly = seconds_since(t_asm);

  const auto t_solve = Clock::now();
  const Columns rhs = right_hand_sides(m.sources_, g, m.center_, m.scale_, terms);
  Columns sol;
  PetscKsp ksp;
  std::size_t iterations = 0;
  m.stats_.solver = solve_system(fr, a.m, solver, total, m.sources_, options, rhs, ksp, sol, iterations, m.stats_);
  m.stats_.iterations = iterations;
  m.alpha_ = polynomial_block(fr, sol, rhs, terms, options, m.beta_);
  rs.seconds_solve = seconds_since(t_solve);

  const auto t_res = Clock::now();
  m.stats_.residual_relative = relative_residual(fr, a.m, m.sources_, g, m.alpha_, m.beta_, m.center_, m.scale_, terms);
  rs.seconds_residual = seconds_since(t_res);
  if (!(m.stats_.residual_relative <= kResidualLimit))
    throw Failure("the controls cannot be interpolated to a relative residual of " + num(kResidualLimit) + " (got " +
                      num(m.stats_.residual_relative) +
                      "): the matrix is too ill-conditioned; merge or separate close sources, or use a smaller radius",
                  0, 1);
  rs.peak_bytes = peak_memory_bytes();
  return m;
}

Eigen::Matrix<double, 4, 3> DistributedMap::polynomial_coefficients() const {
  Eigen::Matrix<double, 4, 3> out;
  const Eigen::Matrix3d lin = beta_.bottomRows<3>() / scale_;
  out.row(0) = beta_.row(0) - center_.transpose() * lin;
  out.bottomRows<3>() = lin;
  return out;
}

void DistributedMap::displacements(std::span<const Vec3> in, std::span<Vec3> out) {
  apply(in, out, 1.0);
  for (std::size_t i = 0; i < in.size(); ++i) out[i] -= in[i];
}

void DistributedMap::apply(std::span<const Vec3> in, std::span<Vec3> out, double phase) {
  int rank = 0, size = 1;
  MPI_Comm_rank(comm_, &rank);
  MPI_Comm_size(comm_, &size);
  const auto t0 = Clock::now();
  collectively(comm_, [&] {
    if (in.size() != out.size())
      throw InvalidInput(std::to_string(in.size()) + " points in but room for " + std::to_string(out.size()));
    check_phase(phase);
    for (std::size_t i = 0; i < in.size(); ++i)
      if (!in[i].allFinite()) throw InvalidInput("point " + std::to_string(i) + ": a coordinate is not finite");
  });
  const double radius = options_.radius;
  // Every rank's controls within R of this rank's points, with their coefficients.
  const std::vector<Box> boxes = all_boxes(comm_, box_of(in), rank_stats_.bytes_sent);
  std::vector<std::vector<Packet>> send(static_cast<std::size_t>(size));
  for (int r = 0; r < size; ++r) {
    if (r == rank) continue;
    for (std::size_t i = 0; i < sources_.size(); ++i)
      if (boxes[std::size_t(r)].distance(sources_[i]) < radius)
        send[std::size_t(r)].push_back(packet(offset_ + i, 0, sources_[i], alpha_.row(Eigen::Index(i)).transpose()));
  }
  const std::vector<Packet> got = exchange(comm_, send, nullptr, rank_stats_.bytes_sent);
  rank_stats_.eval_halo = got.size();
  collectively(comm_, [&] {
    if (in.empty()) return;
    const Box& mine = boxes[std::size_t(rank)];
    std::vector<Vec3> s;
    std::vector<Vec3> a;
    for (std::size_t i = 0; i < sources_.size(); ++i)
      if (mine.distance(sources_[i]) < radius) {
        s.push_back(sources_[i]);
        a.push_back(alpha_.row(Eigen::Index(i)).transpose());
      }
    for (const Packet& p : got) {
      s.push_back(p.source());
      a.push_back(p.value());
    }
    Eigen::Matrix<double, Eigen::Dynamic, 3> alpha(Eigen::Index(s.size()), 3);
    for (std::size_t k = 0; k < a.size(); ++k) alpha.row(Eigen::Index(k)) = a[k].transpose();
    const SpaceMap local = SpaceMap::from_solution(s, alpha, beta_, center_, scale_, options_, in.size());
    local.apply(in, out, phase);
  });
  rank_stats_.points += in.size();
  rank_stats_.seconds_evaluate += seconds_since(t0);
  rank_stats_.peak_bytes = peak_memory_bytes();
}

int Partition::part_of(const Vec3& x) const {
  if (tree.empty()) return 0;
  int k = 0;
  while (tree[std::size_t(k)].part < 0) {
    const Node& n = tree[std::size_t(k)];
    k = x[n.axis] < n.cut ? n.left : n.right;
  }
  return tree[std::size_t(k)].part;
}

Partition rcb_partition(std::span<const Vec3> points, std::span<const Vec3> controls, int parts) {
  Partition out;
  out.point_part.assign(points.size(), 0);
  out.control_part.assign(controls.size(), 0);
  parts = std::max(parts, 1);
  const double wc = controls.empty() ? 1.0 : std::max(1.0, double(points.size()) / double(controls.size()));
  // Items: points first, then controls (index >= points.size()).
  const std::size_t np = points.size();
  if (np + controls.size() >= (std::size_t(1) << 32))
    throw ResourceLimit("more than 2^32 points and controls to partition");
  std::vector<std::uint32_t> items(np + controls.size());
  std::iota(items.begin(), items.end(), 0u);
  const auto at = [&](std::uint32_t k) -> const Vec3& { return k < np ? points[k] : controls[k - np]; };
  const auto weight = [&](std::uint32_t k) { return k < np ? 1.0 : wc; };
  struct Range {
    std::size_t begin, end;
    int first, parts, node;
  };
  out.tree.emplace_back();
  std::vector<Range> stack{{0, items.size(), 0, parts, 0}};
  while (!stack.empty()) {
    const Range r = stack.back();
    stack.pop_back();
    if (r.parts == 1) {
      out.tree[std::size_t(r.node)].part = r.first;
      for (std::size_t k = r.begin; k < r.end; ++k) {
        const std::uint32_t i = items[k];
        (i < np ? out.point_part[i] : out.control_part[i - np]) = r.first;
      }
      continue;
    }
    Box b;
    for (std::size_t k = r.begin; k < r.end; ++k) b.add(at(items[k]));
    int axis = 0;
    if (!b.empty()) (b.hi - b.lo).maxCoeff(&axis);
    tbb::parallel_sort(items.begin() + std::ptrdiff_t(r.begin), items.begin() + std::ptrdiff_t(r.end),
                       [&](std::uint32_t p, std::uint32_t q) {
                         const double a = at(p)[axis], c = at(q)[axis];
                         return a < c || (a == c && p < q);
                       });
    const int left = r.parts / 2;
    double total = 0;
    for (std::size_t k = r.begin; k < r.end; ++k) total += weight(items[k]);
    const double target = total * double(left) / double(r.parts);
    double acc = 0;
    std::size_t cut = r.begin;
    while (cut < r.end && acc + 0.5 * weight(items[cut]) < target) acc += weight(items[cut++]);
    // Items that share the cut's coordinate go right, as part_of places them.
    const double value = cut < r.end ? at(items[cut])[axis] : std::numeric_limits<double>::infinity();
    while (cut > r.begin && at(items[cut - 1])[axis] == value) --cut;
    const int l = int(out.tree.size()), rr = l + 1;
    out.tree.emplace_back();
    out.tree.emplace_back();
    Partition::Node& n = out.tree[std::size_t(r.node)];
    n.axis = axis;
    n.cut = value;
    n.left = l;
    n.right = rr;
    stack.push_back({r.begin, cut, r.first, left, l});
    stack.push_back({cut, r.end, r.first + left, r.parts - left, rr});
  }
  return out;
}

}  // namespace csrbf::mpi
