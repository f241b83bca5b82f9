// morph()'s fit of its controls (see morph_phases.hpp): the controls gathered (a 2-D case's on its
// mid-plane), R chosen, far staying controls culled, the fit predicted, then greedy's rounds or
// every control, in one level or two.
#include "morph_phases.hpp"

#include "csrbf/errors.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/io/memory.hpp"
#include "csrbf/morph/progress.hpp"
#include "csrbf/neighbor_index.hpp"
#include "csrbf/units.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <numeric>
#include <sstream>
#include <unordered_map>

namespace csrbf::morph::detail {
namespace {

/// Points added in one greedy round are at least R apart: each one's correction then reaches no
/// other one's neighbourhood, and a round can add many.
class SpacedSet {
 public:
  explicit SpacedSet(double r) : r_(r) {}
  bool try_add(const Vec3& p) {
    const auto cell = key(p);
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const auto it = cells_.find(pack(cell[0] + dx, cell[1] + dy, cell[2] + dz));
          if (it == cells_.end()) continue;
          for (const Vec3& q : it->second)
            if ((q - p).squaredNorm() < r_ * r_) return false;
        }
    cells_[pack(cell[0], cell[1], cell[2])].push_back(p);
    return true;
  }

 private:
  std::array<std::int64_t, 3> key(const Vec3& p) const {
    return {std::int64_t(std::floor(p.x() / r_)), std::int64_t(std::floor(p.y() / r_)),
            std::int64_t(std::floor(p.z() / r_))};
  }
  static std::uint64_t pack(std::int64_t x, std::int64_t y, std::int64_t z) {
    return (std::uint64_t(x) * 73856093ull) ^ (std::uint64_t(y) * 19349663ull) ^ (std::uint64_t(z) * 83492791ull);
  }
  double r_;
  std::unordered_map<std::uint64_t, std::vector<Vec3>> cells_;
};

}  // namespace

// The controls: the prescribed points (those included), or in a 2-D case their projections on
// the mid-plane, each pair of the two planes' points one control; then the fit.
std::unique_ptr<FittedMapping> Morpher::fit_controls(const Included& included, const std::vector<Vec3>& displacements,
                                                     double largest) {
  sources_.clear();
  targets_.clear();
  ids_.clear();
  std::unique_ptr<FittedMapping> map;
  b.agree(caught([&] {
    if (flat_)
      gather_flat_controls(included, displacements);
    else
      gather_controls(included, displacements);
  }));
  if (first_fit_ && options_.radius_auto) choose_radius(largest);
  // With a polynomial, the mapping moves the whole space: every control is kept.
  if (fit_.polynomial == Polynomial::None) cull_far_controls();
  const std::size_t nc = sources_.size();
  if (first_fit_) {
    predict_fit();
    first_fit_ = false;
  }
  // Once greedy stopped in the motion's fit, a slip correction's fit takes every control too: the
  // result is then the plain morph's, and the report's one stop describes it.
  bool fit_all = !(options_.greedy > 0 && b.max(double(nc)) > 1) || !rep.greedy_stopped.empty();
  if (!fit_all) fit_all = !greedy(largest, map);
  if (fit_all) {
    map.reset();
    // Two levels: asked for, or where auto finds them worth it (radius.hpp). Greedy chose its own
    // controls, and a polynomial moves the whole space: one level for those.
    std::string why;
    const std::optional<TwoLevelPlan> plan = plan_levels(why);
    if (!correcting_) rep.levels_why = why;
    ProgressPhase fitting(options_.progress, "fit", 0, plan ? plan->seconds_two : rep.predicted.seconds_fit);
    if (plan)
      map = fit_two_levels(*plan, why);
    else
      map = b.fit(sources_, targets_, fit_, ids_);
    rep.max_boundary_error = worst(*map);
    rep.controls = nc;
  }
  return map;
}

void Morpher::gather_controls(const Included& included, const std::vector<Vec3>& displacements) {
  for (std::size_t i = 0; i < n_; ++i) {
    if (!included(std::uint32_t(i))) continue;
    sources_.push_back(mesh_.points[pres_.points[i]]);
    targets_.push_back(sources_.back() + displacements[i]);
    ids_.push_back(number(pres_.points[i]));
  }
}

void Morpher::gather_flat_controls(const Included& included, const std::vector<Vec3>& displacements) {
  const VolumeMesh& mesh = mesh_;
  const Prescribed& pres = pres_;
  const int a = flat_->axis;
  const double mid = 0.5 * (flat_->lo + flat_->hi);
  std::vector<std::uint32_t> order;
  for (std::uint32_t i = 0; i < n_; ++i)
    if (included(i)) order.push_back(i);
  const auto projected = [&](std::uint32_t i) {
    Vec3 p = mesh.points[pres.points[i]];
    p[a] = mid;
    return p;
  };
  const auto less = [&](std::uint32_t i, std::uint32_t j) {
    const Vec3 p = projected(i), q = projected(j);
    return std::lexicographical_compare(p.data(), p.data() + 3, q.data(), q.data() + 3);
  };
  std::sort(order.begin(), order.end(), less);
  for (std::size_t k = 0; k < order.size(); ++k) {
    const std::uint32_t i = order[k];
    const Vec3& d = displacements[i];
    if (std::abs(d[a]) > tol_)
      throw io::FileError(
          motion_.file + ": the mesh is 2-D (patch '" + flat_->patch + "' is empty), but point " +
          std::to_string(mesh.point_ids.empty() ? std::uint64_t(pres.points[i]) : mesh.point_ids[pres.points[i]]) +
          " moves out of its plane by " + std::to_string(d[a]));
    const Vec3 p = projected(i);
    if (!sources_.empty() && sources_.back() == p) {
      if ((targets_.back() - sources_.back() - d).norm() > tol_)
        throw io::FileError(motion_.file + ": the mesh is 2-D (patch '" + flat_->patch + "' is empty), but points " +
                            std::to_string(pres.points[order[k - 1]]) + " and " + std::to_string(pres.points[i]) +
                            " of its two planes move differently");
      continue;
    }
    sources_.push_back(p);
    targets_.push_back(p + d);
    ids_.push_back(number(pres.points[i]));
  }
}

// Every process's controls, in one order whatever the decomposition: the same R everywhere.
void Morpher::choose_radius(double largest) {
  std::vector<Vec3> moving_c, staying_c;
  for (std::size_t i = 0; i < sources_.size(); ++i)
    (targets_[i] != sources_[i] ? moving_c : staying_c).push_back(sources_[i]);
  moving_c = sorted_unique(b.gather(moving_c));
  staying_c = sorted_unique(b.gather(staying_c));
  const RadiusChoice c = detail::choose_radius(
      moving_c, staying_c,
      std::abs(options_.phase) * (options_.auto_displacement > 0 ? options_.auto_displacement : largest), size_,
      kAutoMemoryShare * fit_.memory_limit_bytes, fit_.polynomial == Polynomial::None, two_levels_possible_);
  fit_.radius = rep.radius = c.radius;
  rep.radius_why = c.why;
  std::ostringstream os;
  os << "radius auto: R = " << std::setprecision(6) << c.radius << ": " << c.why;
  note(os.str());
}

// Exact locality (polynomial none): a control that stays is fitted only where a moving one lies
// within R of it. Every source of the fit is then within R of a moving control, and its kernel
// reaches R further: a point 2R or farther from every moving control sums no term and keeps its
// coordinates bit for bit (the report's reach). Staying controls farther away carried
// coefficients of 1e-16 and moved the whole connected mesh by up to 4e-7 (a flow solver's
// residuals jumped 63x on such a mesh); they are placed exactly afterwards, as every prescribed
// point is.
void Morpher::cull_far_controls() {
  std::vector<Vec3>& sources = sources_;
  std::vector<Vec3>& targets = targets_;
  rep.reach = 2.0 * fit_.radius;
  std::vector<Vec3> moving;
  for (std::size_t i = 0; i < sources.size(); ++i)
    if (targets[i] != sources[i]) moving.push_back(sources[i]);
  const std::vector<Vec3> all_moving = b.gather(moving);
  std::size_t kept = sources.size();
  std::vector<Vec3> dropped;
  if (!all_moving.empty()) {
    kept = 0;
    const NeighborIndex near(all_moving, fit_.radius);
    for (std::size_t i = 0; i < sources.size(); ++i) {
      bool keep = targets[i] != sources[i];
      if (!keep) near.for_each_within(sources[i], [&](std::size_t, double) { keep = true; });
      if (!keep) {
        if (b.part()) dropped.push_back(sources[i]);
        continue;
      }
      sources[kept] = sources[i];
      targets[kept] = targets[i];
      ids_[kept] = ids_[i];
      ++kept;
    }
  }
  if (b.part()) {
    // A point on a processor boundary is a control of each part that holds it: counted once.
    std::vector<Vec3> all = b.gather(dropped);
    const auto less = [](const Vec3& a, const Vec3& c) {
      return std::lexicographical_compare(a.data(), a.data() + 3, c.data(), c.data() + 3);
    };
    std::sort(all.begin(), all.end(), less);
    rep.far_fixed = std::size_t(std::unique(all.begin(), all.end()) - all.begin());
  } else {
    rep.far_fixed = sources.size() - kept;
  }
  sources.resize(kept);
  targets.resize(kept);
  ids_.resize(kept);
}

// The prediction, before anything large is built (the fit checks its memory again).
void Morpher::predict_fit() {
  const std::vector<Vec3> all_sources = b.part() ? b.gather(sources_) : sources_;
  rep.predicted =
      predict(all_sources, mesh_.points, flat_ ? flat_->axis : -1, flat_ ? 0.5 * (flat_->lo + flat_->hi) : 0.0,
              fit_.radius, b.sum(double(mesh_.points.size())), b);
  const MorphPrediction& p = rep.predicted;
  std::ostringstream os;
  os.precision(3);
  os << "predicted: " << all_sources.size() << " controls with " << p.neighbours_per_control << " neighbours each and "
     << p.neighbours_per_point << " per point; the fit about " << p.bytes / kGiB << " GiB (of "
     << fit_.memory_limit_bytes / kGiB << " GiB left to it) and " << p.seconds_fit << " s, the evaluation "
     << p.seconds_evaluate << " s";
  note(os.str());
}

double Morpher::worst(FittedMapping& map) {
  const std::size_t nc = sources_.size();
  std::vector<Vec3> at(nc);
  map.apply(sources_, at, 1.0);
  err_.resize(nc);
  double e = 0;
  for (std::size_t i = 0; i < nc; ++i) e = std::max(e, err_[i] = (at[i] - targets_[i]).norm());
  return b.max(e);
}

bool Morpher::greedy(double largest, std::unique_ptr<FittedMapping>& map) {
  const MorphOptions& options = options_;
  const std::vector<Vec3>& sources = sources_;
  const std::vector<Vec3>& targets = targets_;
  const std::size_t nc = sources.size();
  ProgressPhase rounds(options.progress, "greedy", 0, 0);  // rounds counted; their number is not known
  const double limit = options.greedy * largest;
  // The budget: a share of the plain morph's predicted fit and evaluation. The fit's share is
  // refined by each round's own cost per matrix entry, once a round fits 1000 controls or more
  // (a small fit is mostly fixed costs).
  const double entries_all = b.sum(double(nc)) * (1 + rep.predicted.neighbours_per_control);
  double fit_all_seconds = rep.predicted.seconds_fit;
  double spent = 0;
  std::size_t rounds_here = 0;  // this fit's (a slip correction's greedy counts its own)
  std::vector<char> chosen(nc, 0);
  std::vector<std::uint32_t> subset;
  std::size_t first = 0;
  for (std::size_t i = 1; i < nc; ++i)
    if ((targets[i] - sources[i]).squaredNorm() > (targets[first] - sources[first]).squaredNorm()) first = i;
  if (nc > 0) {
    subset.push_back(std::uint32_t(first));
    chosen[first] = 1;
  }
  std::vector<std::uint32_t> by_error(nc);
  bool stopped = false;
  for (;;) {
    ++rep.greedy_rounds;
    ++rounds_here;
    rounds.advance(double(rep.greedy_rounds));
    const auto t_round = Clock::now();
    std::sort(subset.begin(), subset.end());
    std::vector<Vec3> s(subset.size()), t(subset.size());
    std::vector<std::uint64_t> u(subset.size());
    for (std::size_t k = 0; k < subset.size(); ++k) {
      s[k] = sources[subset[k]];
      t[k] = targets[subset[k]];
      u[k] = ids_[subset[k]];
    }
    map.reset();
    const auto t_fit_round = Clock::now();
    map = b.fit(s, t, fit_, u);
    const double fit_seconds = b.max(seconds_since(t_fit_round));
    rep.max_boundary_error = worst(*map);
    if (rep.max_boundary_error <= limit || b.max(double(subset.size() < nc)) == 0) break;
    const FitStats st = map->stats();
    const double entries = double(st.controls) + 2.0 * double(st.neighbor_pairs);
    if (st.controls >= 1000 && entries > 0) fit_all_seconds = fit_seconds / entries * entries_all;
    const double round_seconds = b.max(seconds_since(t_round));
    spent += round_seconds;
    const double budget = std::max(options.greedy_budget * (fit_all_seconds + rep.predicted.seconds_evaluate),
                                   options.greedy_budget_floor);
    // The next round fits more controls: it costs at least this one.
    if (spent + round_seconds > budget) {
      std::ostringstream os;
      os.precision(3);
      os << (correcting_ ? "in the slip correction's fit, after " : "after ") << rounds_here
         << (rounds_here == 1 ? " round (" : " rounds (") << subset.size() << " controls, error "
         << rep.max_boundary_error / largest << " of the largest displacement against " << options.greedy
         << "), greedy had spent " << spent << " s of its budget of " << budget << " s (" << options.greedy_budget
         << " x the plain fit and evaluation, predicted " << fit_all_seconds << " + " << rep.predicted.seconds_evaluate
         << " s): every control is fitted instead"
         << (correcting_ ? "" : (any_slip_ ? " (and in a slip correction's fit, if one follows)" : ""));
      rep.greedy_stopped = os.str();
      stopped = true;
      break;
    }
    std::iota(by_error.begin(), by_error.end(), 0u);
    std::sort(by_error.begin(), by_error.end(), [&](std::uint32_t a, std::uint32_t c) { return err_[a] > err_[c]; });
    SpacedSet spaced(fit_.radius);
    const std::size_t before = subset.size();
    for (const std::uint32_t i : by_error) {
      if (err_[i] <= limit) break;
      if (chosen[i] || !spaced.try_add(sources[i])) continue;
      chosen[i] = 1;
      subset.push_back(i);
    }
    // Only controls themselves miss the tolerance (it is below what the solve reaches): stop.
    if (b.max(double(subset.size() > before)) == 0) break;
  }
  rep.controls = subset.size();
  if (stopped && options.progress) options.progress->note("greedy stopped " + rep.greedy_stopped);
  return !stopped;
}

std::optional<TwoLevelPlan> Morpher::plan_levels(std::string& why) {
  const MorphOptions& options = options_;
  const std::size_t nc = sources_.size();
  std::optional<TwoLevelPlan> plan;
  if (!(two_levels_possible_ && nc > 0)) {
    why = options.levels == 1                   ? "asked for"
          : fit_.polynomial != Polynomial::None ? "one level: a polynomial moves the whole space"
          : options.greedy > 0                  ? "one level: greedy chooses its own controls"
          : !b.keeps_mappings()                 ? "one level: under mpirun"
                                                : "one level";
    return plan;
  }
  // The motion's fit was predicted for these very controls; a correction's are others.
  plan = plan_two_levels(sources_, targets_, fit_.radius, kAutoMemoryShare * fit_.memory_limit_bytes,
                         correcting_ ? -1.0 : rep.predicted.neighbours_per_control,
                         correcting_ ? 0.0 : rep.predicted.bytes);
  if (!correcting_) {
    rep.seconds_plain_predicted = plan->seconds_plain;
    rep.seconds_two_levels_predicted = plan->seconds_two;
  }
  std::ostringstream os;
  os.precision(3);
  // R / 4 against the boundary's spacing (which the plan finds only below R / 4).
  const auto under_spacing = [&] {
    os << "R / 4 = " << plan->spacing;
    if (plan->boundary_spacing < plan->spacing)
      os << " is under twice the boundary's spacing " << plan->boundary_spacing;
    else
      os << " is under the boundary's spacing";
  };
  if (options.levels == 2) {
    os << "asked for";
    if (plan->spacing < 2 * plan->boundary_spacing || plan->coarse.size() < 3) {
      os << "; ";
      under_spacing();
      os << " and the coarse level has " << plan->coarse.size() << " of the " << nc
         << " controls: the fine level carries the motion, and one level (--levels 1) gives better cells";
    }
  } else if (plan->worth_it && plan->plain_too_large) {
    os << "auto: one level would pass its memory budget (half of what --memory-limit leaves the fit)";
  } else if (plan->worth_it) {
    os << "auto: predicted " << plan->seconds_two << " s against " << plan->seconds_plain << " s in one level";
  } else {
    os << "auto: one level, predicted " << plan->seconds_plain
       << " s (two where one would pass its memory budget, or take " << kTwoLevelSeconds << " s or more and "
       << kTwoLevelGain << " x as long as two";
    if (plan->spacing < 2 * plan->boundary_spacing) {
      os << "; and ";
      under_spacing();
    }
    os << ")";
    plan.reset();
  }
  why = os.str();
  return plan;
}

std::unique_ptr<FittedMapping> Morpher::fit_two_levels(const TwoLevelPlan& plan, const std::string& why) {
  const std::vector<Vec3>& sources = sources_;
  const std::vector<Vec3>& targets = targets_;
  const std::size_t nc = sources.size();
  std::vector<Vec3> cs(plan.coarse.size()), ct(cs.size());
  std::vector<std::uint64_t> ci(cs.size());
  for (std::size_t k = 0; k < cs.size(); ++k) {
    cs[k] = sources[plan.coarse[k]];
    ct[k] = targets[plan.coarse[k]];
    ci[k] = ids_[plan.coarse[k]];
  }
  // The coarse level is held while the fine one is fitted: the fine fit gets what the coarse
  // one (its matrix, factor and evaluation lists, as resident memory shows them) leaves.
  const double held_before = io::resident_bytes();
  FitOptions coarse_options = fit_;
  coarse_options.memory_limit_bytes = std::clamp(process_bytes_ - held_before, 1.0, fit_.memory_limit_bytes);
  std::unique_ptr<FittedMapping> coarse = b.fit(cs, ct, coarse_options, ci);
  // What the coarse level leaves at every control: the fine level's targets.
  std::vector<Vec3> d(nc), fine_targets(nc);
  coarse->displacements(sources, d);
  for (std::size_t i = 0; i < nc; ++i) fine_targets[i] = targets[i] - d[i];
  FitOptions fine = fit_;
  fine.radius = plan.fine_radius;
  const double held = io::resident_bytes();
  fine.memory_limit_bytes =
      std::max(std::min(fit_.memory_limit_bytes - std::max(held - held_before, 0.0), process_bytes_ - held), 1.0);
  std::unique_ptr<FittedMapping> f;
  try {
    f = b.fit(sources, fine_targets, fine, ids_);
  } catch (const InvalidInput& e) {
    // Its messages name its own R, which the user never gave.
    std::ostringstream os;
    os.precision(6);
    os << "two levels: the fine level's fit at R = " << plan.fine_radius << " (1.75 x the boundary's spacing, "
       << "at most R / 4): " << e.what() << " (--levels 1 fits one level at R = " << fit_.radius << ")";
    throw InvalidInput(os.str());
  }
  auto map = std::make_unique<TwoLevelMapping>(std::move(coarse), std::move(f));
  if (!correcting_) {
    rep.levels = 2;
    rep.coarse_controls = cs.size();
    rep.coarse_spacing = plan.spacing;
    rep.fine_radius = plan.fine_radius;
  }
  std::ostringstream os;
  os.precision(3);
  os << (correcting_ ? "the slip correction's fit" : "the fit") << " in two levels: " << cs.size() << " of " << nc
     << (nc == 1 ? " control" : " controls") << ", no two closer than " << plan.spacing << ", at R = " << fit_.radius
     << ", then what they leave at every control at R = " << plan.fine_radius << " (1.75 x the boundary's spacing "
     << plan.boundary_spacing << ")";
  os << " (" << why << ")";
  note(os.str());
  return map;
}

}  // namespace csrbf::morph::detail
