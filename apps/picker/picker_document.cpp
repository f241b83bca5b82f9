#include "csrbf/geometry.hpp"
#include "picker_document.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

namespace csrbf::picker {

void Document::load_mesh(const std::filesystem::path& path) {
  io::MeshDocument m = io::MeshDocument::load(path);
  if (m.positions().empty()) throw io::FileError(path.string() + ": the mesh has no vertices");
  rest_ = m.positions();
  deformed_ = rest_;
  Vec3 lo = rest_.front(), hi = rest_.front();
  for (const auto& p : rest_) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  diagonal_ = (hi - lo).norm();
  if (!(diagonal_ > 0)) diagonal_ = 1.0;
  mesh_.emplace(std::move(m));
  mesh_path_ = path;
  state_ = State{};
  state_.radius = 0.05 * diagonal_;
}

Outcome Document::apply(const State& s) {
  Outcome out;
  using Clock = std::chrono::steady_clock;
  std::vector<Vec3> moved = rest_;
  std::optional<SpaceMap> fitted;
  try {
    if (!(s.radius > 0) || !std::isfinite(s.radius)) throw InvalidInput("the radius must be a positive number");
    for (std::size_t i = 0; i < s.region.size(); ++i)
      if (s.region[i] >= rest_.size() || (i > 0 && s.region[i] <= s.region[i - 1]))
        throw InvalidInput("the active area must hold sorted, unique vertex indices of the mesh");
    check_phase(s.phase);
    if (!s.controls.empty()) {
      std::vector<Vec3> src, dst;
      for (const auto& c : s.controls) {
        src.push_back(c.source);
        dst.push_back(c.destination);
      }
      const auto t0 = Clock::now();
      const SpaceMap& map = fitted.emplace(SpaceMap::fit(src, dst, FitOptions{s.radius, s.kernel, s.polynomial}));
      const auto t1 = Clock::now();
      // The same call as `csrbf deform --deformation` makes on the saved file: the same vertices.
      io::apply_deformation(map, area(s), moved, s.phase);
      out.fit_ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
      out.eval_ms = std::chrono::duration<double, std::milli>(Clock::now() - t1).count();
    }
  } catch (const std::exception& e) {
    out.ok = false;
    out.error = e.what();
    return out;
  }
  state_ = s;
  deformed_ = std::move(moved);
  map_ = std::move(fitted);
  return out;
}

FoldReport Document::folds() const {
  if (!map_) return FoldReport{};
  if (state_.region.empty()) return check_folds(*map_, rest_, {}, state_.phase);
  // As `csrbf info --check-folds` counts them for the saved file: the area's vertices, triangles
  // inside it and those across its edge.
  return check_folds_in_area(*map_, rest_, mesh_->faces(), state_.region, state_.phase);
}

std::vector<double> Document::displacement_magnitudes() const {
  std::vector<double> m(rest_.size());
  for (std::size_t i = 0; i < rest_.size(); ++i) m[i] = (deformed_[i] - rest_[i]).norm();
  return m;
}

io::DeformationSpec Document::deformation() const {
  io::DeformationSpec d;
  d.options = FitOptions{state_.radius, state_.kernel, state_.polynomial};
  for (const auto& c : state_.controls) {
    d.sources.push_back(c.source);
    d.destinations.push_back(c.destination);
  }
  d.area = area(state_);
  d.phase = state_.phase;  // what the user saw: csrbf deform with the file gives the same mesh
  return d;
}

std::optional<io::ActiveArea> Document::area(const State& s) const {
  if (s.region.empty()) return std::nullopt;
  return io::ActiveArea::of(rest_, s.region);
}

State Document::state_from(const io::DeformationSpec& spec, const std::string& where) const {
  State s = state_;
  s.controls.clear();
  for (std::size_t i = 0; i < spec.sources.size(); ++i)
    s.controls.push_back({spec.sources[i], spec.destinations[i], spec.sources[i] == spec.destinations[i]});
  s.radius = spec.options.radius;
  s.kernel = spec.options.kernel;
  s.polynomial = spec.options.polynomial;
  if (spec.phase) s.phase = *spec.phase;
  s.region.clear();
  if (spec.area) {
    io::check_active_area(*spec.area, rest_, where, mesh_path_.filename().string());
    s.region = spec.area->vertices;
  }
  return s;
}

double Document::propose_radius(const State& s) const {
  const std::size_t n = s.controls.size();
  if (n == 0) return s.radius;
  // Median nearest-neighbour spacing, brute force over at most 2000 sources (evenly taken).
  const std::size_t step = std::max<std::size_t>(1, n / 2000);
  std::vector<double> nearest;
  double longest = 0;
  for (std::size_t i = 0; i < n; ++i)
    longest = std::max(longest, (s.controls[i].destination - s.controls[i].source).norm());
  for (std::size_t i = 0; i < n; i += step) {
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t j = 0; j < n; ++j)
      if (j != i) {
        const double d = (s.controls[j].source - s.controls[i].source).norm();
        if (d > 0) best = std::min(best, d);
      }
    if (std::isfinite(best)) nearest.push_back(best);
  }
  double spacing = 0;
  if (!nearest.empty()) {
    std::nth_element(nearest.begin(), nearest.begin() + std::ptrdiff_t(nearest.size() / 2), nearest.end());
    spacing = nearest[nearest.size() / 2];
  }
  double r = 3.0 * std::max(spacing, longest);
  if (!(r > 0)) r = 0.05 * diagonal_;
  std::vector<Vec3> src, dst;
  for (const auto& c : s.controls) {
    src.push_back(c.source);
    dst.push_back(c.destination);
  }
  // Three significant digits, rounded up (a short number in the file, never below the fold-free one).
  const auto round_up = [](double x) {
    const int e = int(std::floor(std::log10(x))) - 2;
    return e < 0 ? std::ceil(x * std::pow(10.0, -e)) / std::pow(10.0, -e)
                 : std::ceil(x / std::pow(10.0, e)) * std::pow(10.0, e);
  };
  for (r = round_up(r); r < diagonal_; r = round_up(1.25 * r)) {
    const SpaceMap map = SpaceMap::fit(src, dst, FitOptions{r, s.kernel, s.polynomial});
    const FoldReport f = s.region.empty() ? check_folds(map, rest_, {}, 1.0)
                                          : check_folds_in_area(map, rest_, mesh_->faces(), s.region, 1.0);
    if (f.folded == 0 && f.edge_flipped == 0) break;
  }
  return r;
}

void Document::export_mesh(const std::filesystem::path& path) const {
  io::MeshDocument copy = io::MeshDocument::load(mesh_path_);
  copy.positions() = deformed_;
  copy.save(path);
}

double distance_to_mesh(const std::vector<Vec3>& pos, const PolygonList& faces, const Vec3& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& f : faces)
    for (std::size_t k = 1; k + 1 < f.size(); ++k)
      best = std::min(best, (closest_point_on_triangle(p, pos[f[0]], pos[f[k]], pos[f[k + 1]]) - p).norm());
  return best;
}

}  // namespace csrbf::picker
