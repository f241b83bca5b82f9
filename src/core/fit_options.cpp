#include "csrbf/fit_options.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/names.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <functional>
#include <vector>
#include <cmath>
#include <random>
#include <sstream>

#include "cholmod_loader.hpp"

namespace csrbf {

std::string_view polynomial_name(Polynomial p) noexcept { return name_of(p); }
std::optional<Polynomial> parse_polynomial(std::string_view name) noexcept { return parse_name<Polynomial>(name); }
std::string_view solver_name(Solver s) noexcept { return name_of(s); }
std::optional<Solver> parse_solver(std::string_view name) noexcept { return parse_name<Solver>(name); }

#ifndef CSRBF_HAVE_CHOLMOD
std::string detail::cholmod_load_error() { return "this build of csrbf has no CHOLMOD (SuiteSparse)"; }
#endif

bool cholmod_available() noexcept {
#ifdef CSRBF_HAVE_CHOLMOD
  return detail::cholmod_loaded();  // opened on this first question (cholmod_loader.cpp)
#else
  return false;
#endif
}

Solver resolve_solver(Solver requested, double envelope_work, std::size_t controls,
                      std::size_t neighbor_pairs) noexcept {
  if (requested != Solver::Auto) return requested;
  const double cg_work = kCgStepsEstimate * 3.0 * (2.0 * double(neighbor_pairs) + double(controls));
  if (envelope_work <= kEnvelopeWorkLimit && (controls == 0 || kEnvelopeCostRatio * envelope_work <= cg_work))
    return Solver::Envelope;
  return Solver::Cg;
}

void check_phase(double phase) {
  // |phase| <= 1e6: beyond it x + phase d(x) can overflow for displacements that fit allows.
  if (!std::isfinite(phase) || std::abs(phase) > 1e6) {
    std::ostringstream os;
    os << "phase must be a finite number within [-1e6, 1e6], got " << phase;
    throw InvalidInput(os.str());
  }
}

FitMemoryEstimate estimate_fit_memory(std::span<const Vec3> sources, double radius) {
  const std::size_t n = sources.size();
  FitMemoryEstimate e;
  if (n < 2) return e;
  // Neighbours of a seeded sample of sources, counted against all of them, or against a seeded
  // sample of 2^16 of them beyond that and scaled (about 10% error: 20.7 against 22.7 on the 1e6 sphere; 2^18 took 0.3
  // s of a 1e6-control fit's 5 on 2 cores, every source 0.2 s more). The samples are counted in parallel.
  const std::size_t samples = std::min<std::size_t>(n, 256);
  constexpr std::size_t kOthers = std::size_t(1) << 16;
  std::mt19937_64 rng(12345);
  std::vector<std::size_t> picked(samples);
  for (std::size_t k = 0; k < samples; ++k) picked[k] = samples == n ? k : std::size_t(rng() % n);
  std::vector<std::size_t> others;
  if (n > kOthers) {
    others.resize(kOthers);
    for (auto& j : others) j = std::size_t(rng() % n);
  }
  const double r2 = radius * radius;
  const double scale = others.empty() ? 1.0 : double(n) / double(kOthers);
  std::vector<double> counts(samples);
  const double count = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, samples, 8), 0.0,
      [&](const tbb::blocked_range<std::size_t>& r, double c) {
        for (std::size_t k = r.begin(); k < r.end(); ++k) {
          const std::size_t i = picked[k];
          const Vec3& p = sources[i];
          std::size_t hits = 0;
          if (others.empty())
            for (std::size_t j = 0; j < n; ++j) hits += j != i && (sources[j] - p).squaredNorm() < r2;
          else
            for (std::size_t j : others) hits += j != i && (sources[j] - p).squaredNorm() < r2;
          counts[k] = double(hits) * scale;
          c += counts[k];
        }
        return c;
      },
      std::plus<double>());
  e.mean_neighbors = count / double(samples);
  e.max_neighbors = std::min(*std::max_element(counts.begin(), counts.end()), double(n - 1));
  const double nd = double(n), pairs = nd * e.mean_neighbors / 2;
  // Graph: both directions, a 4-byte index and an 8-byte squared distance each. The sparse solvers'
  // lower triangle (an 8-byte value and a 4-byte index an entry), held beside the graph. Factor: at
  // least that triangle again, and for a dense-ish matrix the full N^2 / 2 of the envelope. The
  // solver's own analysis checks the factor's real size later, before it is allocated.
  const double graph = 2 * pairs * 12, matrix = 12 * (pairs + nd);
  const double factor = std::max(12 * (pairs + nd), e.mean_neighbors > nd / 4 ? 4 * nd * nd : 0.0);
  e.bytes = graph + matrix + factor;
  return e;
}

}  // namespace csrbf
