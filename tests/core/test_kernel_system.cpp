// csrbf::KernelSystem (kernel_system.hpp) and Auto's solver (src/core/auto_solver.hpp): the phased
// system against a dense solve of the same kernel matrix with its polynomial block, in float and
// double, with every solver; CG's stagnation as a status, and Auto's hand-over to a direct solver.
#include "csrbf/kernel_system.hpp"

#include "csrbf/detail/kernel_solver.hpp"
#include "csrbf/errors.hpp"

#include "../../src/core/auto_solver.hpp"

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

using namespace csrbf;

namespace {

/// A jittered lattice in the unit cube of `dim` dimensions (coordinates past dim 0), spacing h: well
/// spaced, so that A's condition lets a float solve agree to 1e-4.
std::vector<Vec3> lattice(int dim, double h, std::mt19937& rng) {
  std::uniform_real_distribution<double> jitter(-0.2 * h, 0.2 * h);
  const int k = int(std::round(1.0 / h));
  std::vector<Vec3> pts;
  for (int i = 0; i < k; ++i)
    for (int j = 0; j < (dim > 1 ? k : 1); ++j)
      for (int l = 0; l < (dim > 2 ? k : 1); ++l) {
        Vec3 p(h * i + jitter(rng), dim > 1 ? h * j + jitter(rng) : 0.0, dim > 2 ? h * l + jitter(rng) : 0.0);
        pts.push_back(p);
      }
  return pts;
}

/// The points and right-hand sides as a Scalar buffer holds them (rounded to float for float).
template <class Scalar>
void round_to(std::vector<Vec3>& pts, RowMatrix& g) {
  for (Vec3& p : pts)
    for (int a = 0; a < 3; ++a) p[a] = double(Scalar(p[a]));
  g = g.cast<Scalar>().template cast<double>();
}

/// The dense saddle-point system [A + shift I, P; P^T, 0] [alpha; beta] = [g; 0] assembled and solved
/// (LU) in Scalar, P = [1, u] in the system's coordinates u = (x - center) / scale.
template <class Scalar>
std::pair<Eigen::MatrixXd, Eigen::MatrixXd> dense_solution(const std::vector<Vec3>& pts, const KernelSystem& system,
                                                           double shift, const RowMatrix& g) {
  using Dense = Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic>;
  const auto n = Eigen::Index(pts.size());
  const int t = system.terms();
  const KernelSystemOptions& o = system.options();
  Dense k = Dense::Zero(n + t, n + t);
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = 0; j < n; ++j) {
      const double r = (pts[std::size_t(i)] - pts[std::size_t(j)]).norm();
      if (r < o.radius) k(i, j) = Scalar(wendland(o.kernel, r / o.radius));
    }
    k(i, i) += Scalar(shift);
    const Vec3 u = (pts[std::size_t(i)] - system.center()) / system.scale();
    for (int c = 0; c < t; ++c) k(i, n + c) = k(n + c, i) = Scalar(c == 0 ? 1.0 : u[c - 1]);
  }
  Dense rhs = Dense::Zero(n + t, g.cols());
  rhs.topRows(n) = g.cast<Scalar>();
  const Dense x = k.fullPivLu().solve(rhs);
  return {x.topRows(n).template cast<double>(), x.bottomRows(t).template cast<double>()};
}

double largest(const Eigen::MatrixXd& m) { return m.size() ? m.cwiseAbs().maxCoeff() : 0.0; }

std::vector<Solver> every_solver() {
  std::vector<Solver> s{Solver::Envelope, Solver::Eigen, Solver::Cg, Solver::Auto};
  if (cholmod_available()) s.push_back(Solver::Cholmod);
  return s;
}

}  // namespace

// Outside the anonymous namespace: the typed test's classes derive from it (unity builds).
template <class Scalar>
class KernelSystemTyped : public ::testing::Test {};
using KernelSystemScalars = ::testing::Types<float, double>;
TYPED_TEST_SUITE(KernelSystemTyped, KernelSystemScalars);

// Every solver, every degree, 1-D to 3-D, with and without smoothing, 3 and 10 right-hand sides (CG
// takes 8 at once): alpha and beta agree with the dense solve, to 5e-4 of the largest in float and
// 1e-9 in double (measured: 3e-5 and 2e-12), and the system's residual check agrees.
TYPED_TEST(KernelSystemTyped, PhasesAgreeWithADenseSolve) {
  using Scalar = TypeParam;
  const double tolerance = std::is_same_v<Scalar, float> ? 5e-4 : 1e-9;
  std::mt19937 rng(50);
  for (int dim = 1; dim <= 3; ++dim)
    for (Solver solver : every_solver())
      for (int degree = -1; degree <= 1; ++degree) {
        const double h = dim == 1 ? 0.005 : dim == 2 ? 1.0 / 15 : 1.0 / 6;
        std::vector<Vec3> pts = lattice(dim, h, rng);
        const Eigen::Index m = degree == 0 ? 10 : 3;
        RowMatrix g = RowMatrix::Random(Eigen::Index(pts.size()), m);
        round_to<Scalar>(pts, g);
        const double shift = degree == 1 ? 0.0 : 0.1;
        KernelSystemOptions o;
        o.radius = 2.2 * h;
        o.dimension = dim;
        o.degree = degree;
        o.solver = solver;
        KernelSystem system(pts, o, shift > 0 ? std::vector<double>{shift} : std::vector<double>{});
        const std::string what = "D = " + std::to_string(dim) + ", " + std::string(solver_name(solver)) + ", degree " +
                                 std::to_string(degree);
        system.analyse();
        system.factorise();
        ASSERT_EQ(system.info(), SystemInfo::Success) << what;
        EXPECT_EQ(system.terms(), degree < 0 ? 0 : degree == 0 ? 1 : 1 + dim) << what;
        std::vector<bool> seen(pts.size(), false);
        for (std::uint32_t k : system.order()) seen.at(k) = true;
        EXPECT_EQ(std::count(seen.begin(), seen.end(), true), Eigen::Index(pts.size())) << what;

        RowMatrix alpha = g;
        Eigen::MatrixXd beta;
        const SolveStatus s = system.solve(alpha, beta);
        ASSERT_TRUE(s.ok()) << what << ": " << s.message;
        ASSERT_EQ(beta.rows(), system.terms()) << what;
        ASSERT_EQ(beta.cols(), m) << what;
        const auto [alpha_ref, beta_ref] = dense_solution<Scalar>(pts, system, shift, g);
        EXPECT_LE(largest(alpha - alpha_ref), tolerance * largest(alpha_ref)) << what;
        if (system.terms() > 0) {
          EXPECT_LE(largest(beta - beta_ref), tolerance * largest(beta_ref)) << what;
        }
        // P^T alpha = 0: the polynomial block's condition.
        if (degree >= 0) {
          EXPECT_LE(alpha.colwise().sum().cwiseAbs().maxCoeff(), 1e-8 * largest(alpha)) << what;
        }
        const KernelSystem::Residual r = system.residual(alpha, beta, g);
        EXPECT_LE(r.relative, 1e-9) << what;
        EXPECT_DOUBLE_EQ(r.largest, g.rowwise().norm().maxCoeff()) << what;
      }
}

// The residual check sees a wrong solution, and counts coefficients that are not finite as infinite.
TEST(KernelSystem, ResidualCheckSeesWrongAndNonFiniteSolutions) {
  std::mt19937 rng(51);
  const std::vector<Vec3> pts = lattice(3, 1.0 / 5, rng);
  KernelSystemOptions o;
  o.radius = 0.45;
  o.degree = 0;
  KernelSystem system(pts, o);
  system.analyse();
  system.factorise();
  const RowMatrix g = RowMatrix::Random(Eigen::Index(pts.size()), 2);
  RowMatrix alpha = g;
  Eigen::MatrixXd beta;
  ASSERT_TRUE(system.solve(alpha, beta).ok());
  EXPECT_LE(system.residual(alpha, beta, g).relative, 1e-12);
  RowMatrix off = alpha;
  off(3, 1) += 1e-3;
  EXPECT_GT(system.residual(off, beta, g).relative, 1e-5);
  off(3, 1) = std::nan("");
  EXPECT_TRUE(std::isinf(system.residual(off, beta, g).max));
}

// Without a polynomial, solve_matrix is A^-1 b in the system's order; the condition estimate is that
// of the dense matrix.
TEST(KernelSystem, SolveMatrixAndConditionAgreeWithTheDenseMatrix) {
  std::mt19937 rng(52);
  const std::vector<Vec3> pts = lattice(2, 1.0 / 12, rng);
  for (Solver solver : {Solver::Envelope, Solver::Cg}) {
    KernelSystemOptions o;
    o.radius = 0.2;
    o.dimension = 2;
    o.solver = solver;
    KernelSystem system(pts, o);
    system.analyse();
    system.factorise();
    const auto n = Eigen::Index(pts.size());
    Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n);
    for (Eigen::Index i = 0; i < n; ++i)
      for (Eigen::Index j = 0; j < n; ++j) {
        const double r = (pts[std::size_t(i)] - pts[std::size_t(j)]).norm();
        if (r < o.radius) a(i, j) = wendland(o.kernel, r / o.radius);
      }
    const RowMatrix b = RowMatrix::Random(n, 2);
    RowMatrix x(n, 2);  // in the system's order
    for (Eigen::Index k = 0; k < n; ++k) x.row(k) = b.row(system.order()[std::size_t(k)]);
    ASSERT_TRUE(system.solve_matrix(x).ok());
    RowMatrix back(n, 2);
    for (Eigen::Index k = 0; k < n; ++k) back.row(system.order()[std::size_t(k)]) = x.row(k);
    EXPECT_LE((a * back - b).cwiseAbs().maxCoeff(), 1e-9) << solver_name(solver);
    const Eigen::VectorXd ev = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(a).eigenvalues();
    EXPECT_NEAR(system.condition() / (ev.maxCoeff() / ev.minCoeff()), 1.0, 0.05) << solver_name(solver);
  }
}

// A degenerate polynomial is a status of factorise(), not an exception: collinear points in 2-D with
// degree 1 (the callers name it in their own words).
TEST(KernelSystem, DegeneratePolynomialIsAStatus) {
  std::vector<Vec3> line;
  for (int i = 0; i < 50; ++i) line.emplace_back(0.02 * i, 0.01 * i, 0);
  KernelSystemOptions o;
  o.radius = 0.1;
  o.dimension = 2;
  o.degree = 1;
  KernelSystem system(line, o);
  EXPECT_TRUE(system.polynomial_degenerate());
  system.analyse();
  ASSERT_NO_THROW(system.factorise());
  EXPECT_EQ(system.info(), SystemInfo::DegeneratePolynomial);
  o.degree = 0;  // a constant they do determine
  KernelSystem constant(line, o);
  constant.analyse();
  constant.factorise();
  EXPECT_EQ(constant.info(), SystemInfo::Success);
}

// The public constructor checks its inputs.
TEST(KernelSystem, RefusesBadInputs) {
  const std::vector<Vec3> pts{Vec3(0, 0, 0), Vec3(0.1, 0, 0), Vec3(0, 0.1, 0)};
  KernelSystemOptions o;
  o.radius = 0.5;
  EXPECT_THROW(KernelSystem(std::vector<Vec3>{}, o), InvalidInput);
  EXPECT_THROW(KernelSystem(std::vector<Vec3>{Vec3(0, std::nan(""), 0)}, o), InvalidInput);
  EXPECT_THROW(KernelSystem(pts, o, std::vector<double>{0.1, 0.2}), InvalidInput);
  EXPECT_THROW(KernelSystem(pts, o, std::vector<double>{-1.0}), InvalidInput);
  KernelSystemOptions bad = o;
  bad.radius = 0;
  EXPECT_THROW(KernelSystem(pts, bad), InvalidInput);
  bad = o;
  bad.dimension = 4;
  EXPECT_THROW(KernelSystem(pts, bad), InvalidInput);
  EXPECT_NO_THROW(KernelSystem(pts, o, std::vector<double>{0.1, 0.2, 0.3}));
}

// A phase out of order, or right-hand sides of another size, is a UsageError naming it (it read and
// wrote past b's end in a Release build).
TEST(KernelSystem, MisuseIsAUsageErrorNotACrash) {
  std::mt19937 rng(5);
  const std::vector<Vec3> pts = lattice(3, 1.0 / 6, rng);  // 216 points
  const Eigen::Index n = Eigen::Index(pts.size());
  KernelSystemOptions o;
  o.radius = 0.4;
  o.degree = 1;
  KernelSystem sys(pts, o);
  RowMatrix b = RowMatrix::Ones(n, 1);
  Eigen::MatrixXd beta;
  const auto message = [&](auto&& f) -> std::string {
    try {
      f();
    } catch (const UsageError& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_EQ(message([&] { sys.factorise(); }), "KernelSystem: call analyse() before factorise()");
  sys.analyse();
  EXPECT_EQ(message([&] { sys.analyse(); }), "KernelSystem: analyse() was called already (once a system)");
  EXPECT_EQ(message([&] { sys.solve(b, beta); }), "KernelSystem: call factorise() before solve()");
  EXPECT_EQ(message([&] { sys.solve_matrix(b); }), "KernelSystem: call factorise() before solve_matrix()");
  sys.factorise();
  EXPECT_EQ(message([&] { sys.factorise(); }), "KernelSystem: factorise() was called already (once a system)");
  RowMatrix shorter = RowMatrix::Ones(n - 7, 1);
  EXPECT_EQ(message([&] { sys.solve(shorter, beta); }),
            "KernelSystem::solve(): the right-hand sides are 209 x 1, not of the system's 216 rows");
  const RowMatrix guess = RowMatrix::Zero(n, 2);
  EXPECT_EQ(message([&] { sys.solve(b, beta, &guess); }),
            "KernelSystem::solve(): the guess is 216 x 2, the right-hand sides 216 x 1");
  ASSERT_TRUE(sys.solve(b, beta).ok());
  EXPECT_EQ(beta.rows(), 4);
  EXPECT_LT(sys.residual(b, beta, RowMatrix::Ones(n, 1)).relative, 1e-9);
}

// Two points at one position: DuplicateSource from analyse(), unless both are shifted.
TEST(KernelSystem, CoincidentPointsNeedAShift) {
  const std::vector<Vec3> pts{Vec3(0, 0, 0), Vec3(0.1, 0, 0), Vec3(0.1, 0, 0), Vec3(0, 0.1, 0)};
  KernelSystemOptions o;
  o.radius = 0.5;
  KernelSystem plain(pts, o);
  EXPECT_THROW(plain.analyse(), DuplicateSource);
  KernelSystem smoothed(pts, o, std::vector<double>{0.5});
  ASSERT_NO_THROW(smoothed.analyse());
  smoothed.factorise();
  RowMatrix b = RowMatrix::Ones(4, 1);
  Eigen::MatrixXd beta;
  EXPECT_TRUE(smoothed.solve(b, beta).ok());
}

namespace {
/// 400 sources 1e-4 apart on a line, R = 1: thousands of neighbours each and a condition number far
/// beyond what CG can reach 1e-12 in kCgMaxIterations steps, which a direct solver factorises.
std::vector<Vec3> stagnating_line() {
  std::vector<Vec3> line;
  for (int i = 0; i < 400; ++i) line.emplace_back(1e-4 * i, 0, 0);
  return line;
}
RowMatrix line_values(std::size_t n) {
  RowMatrix g(Eigen::Index(n), 3);
  for (Eigen::Index i = 0; i < g.rows(); ++i) g.row(i) << 1e-3 * std::sin(0.1 * double(i)), 0.5, -1e-3 * double(i);
  return g;
}
}  // namespace

// CG that stagnates says so as a status (no exception), and leaves the right-hand sides as they were;
// Auto's solver (here CG asked for by name: no probe) hands over to the direct solver, keeps CG's
// status as the cause, and later solves go straight to the direct solver.
TEST(AutoSolver, ReportsStagnationAsAStatusAndHandsOver) {
  const std::vector<Vec3> line = stagnating_line();
  const KernelMatrix a(AdjacencyGraph::brute_force(line, 1.0), Kernel::C2, 1.0);
  const RowMatrix g = line_values(line.size());

  const auto cg =
      detail::conjugate_gradients(a, reverse_cuthill_mckee_order(a.pattern()), kCgTolerance, kCgMaxIterations);
  RowMatrix untouched = g;
  SolveStatus s;
  ASSERT_NO_THROW(s = cg->solve(untouched));
  EXPECT_EQ(s.info, SystemInfo::NoConvergence) << s.message;
  EXPECT_GT(s.steps, 0u);
  EXPECT_FALSE(s.message.empty());
  EXPECT_EQ(untouched, g);

  detail::AutoInputs in;
  in.asked = Solver::Cg;
  in.memory_limit_bytes = 4.0 * kGiB;
  in.envelope_work = 1e12;
  in.neighbor_pairs = a.values().size() / 2;
  detail::AutoSolver solver(a, line, reverse_cuthill_mckee_order(a.pattern()), in, {});
  RowMatrix x = g;
  s = solver.solve(x);
  ASSERT_TRUE(s.ok()) << s.message;
  const detail::AutoSolver::Stage stage = solver.stage();
  EXPECT_TRUE(stage.handed_over);
  EXPECT_EQ(stage.solver, cholmod_available() ? Solver::Cholmod : Solver::Eigen);
  EXPECT_EQ(stage.cause.info, SystemInfo::NoConvergence);
  EXPECT_EQ(stage.cause.steps, solver.cg_iterations());
  EXPECT_FALSE(stage.cause.message.empty());
  ASSERT_NE(stage.taken, nullptr);
  EXPECT_FALSE(solver.iterative());
  EXPECT_LE((a * x - g).norm() / g.norm(), 1e-6);
  const std::size_t steps = solver.cg_iterations();
  RowMatrix y = g;
  ASSERT_TRUE(solver.solve(y).ok());
  EXPECT_EQ(y, x);                           // the same direct solve
  EXPECT_EQ(solver.cg_iterations(), steps);  // CG did not run again
}

// Through the kernel system: CG by name on the line hands over inside solve(), and report() says so.
TEST(AutoSolver, KernelSystemHandsOverWhereCgStagnates) {
  const std::vector<Vec3> line = stagnating_line();
  KernelSystemOptions o;
  o.radius = 1.0;
  o.solver = Solver::Cg;
  KernelSystem system(line, o);
  system.analyse();
  system.factorise();
  EXPECT_TRUE(system.warm_starts());
  EXPECT_FALSE(system.handed_over());
  const RowMatrix g = line_values(line.size());
  RowMatrix alpha = g;
  Eigen::MatrixXd beta;
  ASSERT_TRUE(system.solve(alpha, beta).ok());
  EXPECT_TRUE(system.handed_over());
  EXPECT_NE(system.solver(), Solver::Cg);
  EXPECT_FALSE(system.warm_starts());
  EXPECT_LE(system.residual(alpha, beta, g).relative, kResidualLimit);
  FitStats stats;
  system.report(stats, false);
  EXPECT_TRUE(stats.fell_back);
  EXPECT_EQ(stats.solver, system.solver());
  EXPECT_GT(stats.iterations, 0u);  // CG's, before it stagnated
}

// Chosen by Auto, CG gives way (a status from its probe) on a system it converges on slowly: 1000
// points in the unit cube with R = 1 (nearly dense) get at most 50 steps, then the direct solver.
TEST(AutoSolver, AutoHandsOverWhereItsProbeFindsADirectSolverCheaper) {
  std::mt19937 rng(53);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Vec3> cube(1000);
  for (Vec3& p : cube) p = Vec3(u(rng), u(rng), u(rng));
  KernelSystemOptions o;
  o.radius = 1.0;
  KernelSystem system(cube, o);
  system.analyse();
  system.factorise();
  EXPECT_GT(system.stats().envelope_work, kEnvelopeWorkLimit);
  EXPECT_EQ(system.stats().solver, Solver::Cg);
  RowMatrix alpha = RowMatrix::Random(1000, 3);
  const RowMatrix g = alpha;
  Eigen::MatrixXd beta;
  ASSERT_TRUE(system.solve(alpha, beta).ok());
  EXPECT_TRUE(system.handed_over());
  EXPECT_EQ(system.solver(), cholmod_available() ? Solver::Cholmod : Solver::Eigen);
  FitStats stats;
  system.report(stats, false);
  EXPECT_TRUE(stats.fell_back);
  EXPECT_LE(stats.iterations, 50u);
  EXPECT_LE(system.residual(alpha, beta, g).relative, kResidualLimit);
}
