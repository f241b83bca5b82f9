#include "csrbf/mpi/backends.hpp"

#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/io/input_file.hpp"
#include "csrbf/morph/job.hpp"
#include "csrbf/morph/openfoam.hpp"
#include "csrbf/morph/volume_file.hpp"
#include "csrbf/mpi/runtime.hpp"

#include <algorithm>
#include <cctype>
#include <climits>
#include <fstream>
#include <cstdio>
#include <iostream>
#include <numeric>
#include <string>

namespace fs = std::filesystem;

namespace csrbf::mpi {

using morph::caught;

namespace {

enum Op : int { kFit = 1, kApply = 2, kDisplacements = 3, kStats = 4, kDone = 5 };

struct Command {
  int op = 0, code = 0, kernel = 0, polynomial = 0, solver = 0, generation = 0;
  double radius = 0, memory = 0, phase = 0;
};

void broadcast(MPI_Comm comm, Command& c) { MPI_Bcast(&c, int(sizeof c), MPI_BYTE, 0, comm); }

/// A control as rank 0 scatters it: its id, source and target.
struct ControlPacket {
  std::uint64_t id = 0;
  double s[3] = {0, 0, 0}, t[3] = {0, 0, 0};
};

int checked_count(std::size_t n, const char* what) {
  if (n > std::size_t(INT_MAX))
    throw ResourceLimit(std::string("one rank's share of the ") + what + " (" + std::to_string(n) +
                        " values) passes what one MPI message carries: use more ranks");
  return int(n);
}

/// Where each rank's share lies in root's array, in bytes, for MPI_Scatterv and MPI_Gatherv.
struct Layout {
  std::vector<int> counts, displs;
  explicit Layout(int ranks) : counts(static_cast<std::size_t>(ranks), 0), displs(counts.size(), 0) {}
  /// counts[r] values of `size` bytes for rank r; returns the values in all.
  std::size_t fill(const std::vector<std::size_t>& values, std::size_t size, const char* what) {
    std::size_t off = 0;
    for (std::size_t r = 0; r < counts.size(); ++r) {
      counts[r] = checked_count(values[r] * size, what);
      displs[r] = checked_count(off * size, what);
      off += values[r];
    }
    return off;
  }
};

/// Root's string, on every rank.
void broadcast(MPI_Comm comm, std::string& s) {
  long long n = static_cast<long long>(s.size());
  MPI_Bcast(&n, 1, MPI_LONG_LONG, 0, comm);
  s.resize(std::size_t(n));
  MPI_Bcast(s.data(), int(n), MPI_CHAR, 0, comm);
}

/// Root's values per rank (in rank order, counts[r] each), scattered; every rank's own share.
template <class T>
std::vector<T> scatter(MPI_Comm comm, const std::vector<T>& all, const std::vector<std::size_t>& counts,
                       std::size_t& bytes) {
  int rank = 0, size = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  Layout l(size);
  if (rank == 0) bytes += (l.fill(counts, sizeof(T), "scattered data") - counts[0]) * sizeof(T);
  int mine = 0;
  MPI_Scatter(l.counts.data(), 1, MPI_INT, &mine, 1, MPI_INT, 0, comm);
  std::vector<T> out(std::size_t(mine) / sizeof(T));
  MPI_Scatterv(all.data(), l.counts.data(), l.displs.data(), MPI_BYTE, out.data(), mine, MPI_BYTE, 0, comm);
  return out;
}

/// Every rank's values gathered on root in rank order (counts known there).
template <class T>
void gather(MPI_Comm comm, const std::vector<T>& mine, std::vector<T>& all, const std::vector<std::size_t>& counts,
            std::size_t& bytes) {
  int rank = 0, size = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  Layout l(size);
  if (rank == 0) {
    all.resize(l.fill(counts, sizeof(T), "gathered data"));
  } else {
    bytes += mine.size() * sizeof(T);
  }
  MPI_Gatherv(mine.data(), checked_count(mine.size() * sizeof(T), "gathered data"), MPI_BYTE, all.data(),
              l.counts.data(), l.displs.data(), MPI_BYTE, 0, comm);
}

std::vector<RankStats> gather_stats(MPI_Comm comm, RankStats mine) {
  int rank = 0, size = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  mine.rank = rank;
  mine.peak_bytes = peak_memory_bytes();
  std::vector<RankStats> all(static_cast<std::size_t>(size));
  MPI_Allgather(&mine, int(sizeof mine), MPI_BYTE, all.data(), int(sizeof mine), MPI_BYTE, comm);
  return all;
}

FitOptions options_of(const Command& c) {
  FitOptions o;
  o.radius = c.radius;
  o.kernel = Kernel(c.kernel);
  o.polynomial = Polynomial(c.polynomial);
  o.memory_limit_bytes = c.memory;
  return o;
}

/// The points of one apply, in rank order: each rank evaluates its share, rank 0 puts them back.
void evaluate_share(MPI_Comm comm, DistributedMap& map, int op, double phase, const std::vector<Vec3>& all,
                    const std::vector<std::size_t>& counts, std::vector<Vec3>& result) {
  std::size_t& bytes = map.rank_stats().bytes_sent;
  const std::vector<Vec3> mine = scatter(comm, all, counts, bytes);
  std::vector<Vec3> out(mine.size());
  if (op == kApply)
    map.apply(mine, out, phase);
  else
    map.displacements(mine, out);
  gather(comm, out, result, counts, bytes);
}

}  // namespace

int exit_code_of(const std::exception_ptr& e) {
  try {
    std::rethrow_exception(e);
  } catch (const morph::JobError&) {
    return 2;
  } catch (const Failure& f) {
    return f.exit_code();
  } catch (...) {
    return 1;
  }
}

// ---- ScatterBackend --------------------------------------------------------------------------

class ScatterMapping final : public morph::FittedMapping {
 public:
  ScatterMapping(ScatterBackend& b, int generation) : b_(b), generation_(generation) {}
  void apply(std::span<const Vec3> in, std::span<Vec3> out, double phase) override { run(kApply, in, out, phase); }
  void displacements(std::span<const Vec3> in, std::span<Vec3> out) override { run(kDisplacements, in, out, 1.0); }
  FitStats stats() const override {
    FitStats s;
    s.controls = b_.stats_.controls;
    s.solver = b_.stats_.solver == DistributedSolver::Cg ? Solver::Cg : Solver::Cholmod;
    s.iterations = b_.stats_.iterations;
    s.fell_back = b_.stats_.fell_back;
    s.residual_relative = b_.stats_.residual_relative;
    return s;
  }

 private:
  void run(int op, std::span<const Vec3> in, std::span<Vec3> out, double phase) {
    if (generation_ != b_.generation_ || !b_.map_)
      throw csrbf::Error("csrbf::mpi: a mapping used after a later fit replaced it");
    int size = 1;
    MPI_Comm_size(b_.comm_, &size);
    // The points by part (a counting sort by the partition's regions).
    std::vector<int> part(in.size());
    std::vector<std::size_t> counts(static_cast<std::size_t>(size), 0);
    for (std::size_t i = 0; i < in.size(); ++i) ++counts[std::size_t(part[i] = b_.partition_->part_of(in[i]))];
    std::vector<std::size_t> next(static_cast<std::size_t>(size), 0);
    for (int r = 1; r < size; ++r) next[std::size_t(r)] = next[std::size_t(r - 1)] + counts[std::size_t(r - 1)];
    std::vector<std::uint32_t> order(in.size());
    std::vector<Vec3> sorted(in.size());
    for (std::size_t i = 0; i < in.size(); ++i) {
      const std::size_t k = next[std::size_t(part[i])]++;
      order[k] = std::uint32_t(i);
      sorted[k] = in[i];
    }
    std::vector<int>().swap(part);
    Command c;
    c.op = op;
    c.phase = phase;
    c.generation = generation_;
    broadcast(b_.comm_, c);
    std::vector<Vec3> result;
    evaluate_share(b_.comm_, *b_.map_, op, phase, sorted, counts, result);
    for (std::size_t k = 0; k < result.size(); ++k) out[order[k]] = result[k];
  }
  ScatterBackend& b_;
  int generation_;
};

ScatterBackend::ScatterBackend(MPI_Comm comm, DistributedSolver solver, std::span<const Vec3> balance)
    : comm_(comm), solver_(solver), balance_(balance.begin(), balance.end()) {}

ScatterBackend::~ScatterBackend() { finish(1); }

void ScatterBackend::finish(int exit_code) noexcept {
  if (finished_) return;
  finished_ = true;
  Command c;
  c.op = kDone;
  c.code = exit_code;
  broadcast(comm_, c);
}

std::unique_ptr<morph::FittedMapping> ScatterBackend::fit(std::span<const Vec3> sources, std::span<const Vec3> targets,
                                                          const FitOptions& options,
                                                          std::span<const std::uint64_t> ids) {
  int size = 1;
  MPI_Comm_size(comm_, &size);
  if (sources.size() != targets.size()) throw InvalidInput("control points: sources and targets differ in number");
  if (!partition_) partition_ = rcb_partition(balance_, sources, size);
  std::vector<Vec3>().swap(balance_);
  std::vector<std::size_t> counts(static_cast<std::size_t>(size), 0);
  std::vector<int> part(sources.size());
  for (std::size_t i = 0; i < sources.size(); ++i) ++counts[std::size_t(part[i] = partition_->part_of(sources[i]))];
  std::vector<std::size_t> next(static_cast<std::size_t>(size), 0);
  for (int r = 1; r < size; ++r) next[std::size_t(r)] = next[std::size_t(r - 1)] + counts[std::size_t(r - 1)];
  std::vector<ControlPacket> all(sources.size());
  for (std::size_t i = 0; i < sources.size(); ++i) {
    ControlPacket& p = all[next[std::size_t(part[i])]++];
    p.id = ids.empty() ? i : ids[i];
    for (int c = 0; c < 3; ++c) {
      p.s[c] = sources[i][c];
      p.t[c] = targets[i][c];
    }
  }
  Command c;
  c.op = kFit;
  c.kernel = int(options.kernel);
  c.polynomial = int(options.polynomial);
  c.solver = int(solver_);
  c.radius = options.radius;
  c.memory = options.memory_limit_bytes;
  c.generation = ++generation_;
  broadcast(comm_, c);
  map_.reset();
  std::size_t bytes = 0;
  const std::vector<ControlPacket> mine = scatter(comm_, all, counts, bytes);
  std::vector<Vec3> s(mine.size()), t(mine.size());
  std::vector<std::uint64_t> u(mine.size());
  for (std::size_t i = 0; i < mine.size(); ++i) {
    s[i] = Vec3(mine[i].s[0], mine[i].s[1], mine[i].s[2]);
    t[i] = Vec3(mine[i].t[0], mine[i].t[1], mine[i].t[2]);
    u[i] = mine[i].id;
  }
  FitOptions o = options_of(c);
  o.solver = options.solver;
  map_ = DistributedMap::fit(comm_, s, t, o, solver_, u);
  map_->rank_stats().bytes_sent += bytes;
  stats_ = map_->stats();
  return std::make_unique<ScatterMapping>(*this, generation_);
}

std::vector<RankStats> ScatterBackend::rank_stats() {
  Command c;
  c.op = kStats;
  broadcast(comm_, c);
  return gather_stats(comm_, map_ ? map_->rank_stats() : RankStats{});
}

int serve(MPI_Comm comm) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  std::optional<DistributedMap> map;
  for (;;) {
    Command c;
    broadcast(comm, c);
    try {
      switch (c.op) {
        case kFit: {
          map.reset();
          std::size_t bytes = 0;
          const std::vector<ControlPacket> mine = scatter(comm, std::vector<ControlPacket>(), {}, bytes);
          std::vector<Vec3> s(mine.size()), t(mine.size());
          std::vector<std::uint64_t> u(mine.size());
          for (std::size_t i = 0; i < mine.size(); ++i) {
            s[i] = Vec3(mine[i].s[0], mine[i].s[1], mine[i].s[2]);
            t[i] = Vec3(mine[i].t[0], mine[i].t[1], mine[i].t[2]);
            u[i] = mine[i].id;
          }
          try {
            map = DistributedMap::fit(comm, s, t, options_of(c), DistributedSolver(c.solver), u);
          } catch (const Failure&) {  // every rank has it; rank 0 reports
          }
          break;
        }
        case kApply:
        case kDisplacements: {
          std::vector<Vec3> none;
          if (!map) throw csrbf::Error("an evaluation without a fit");
          try {
            evaluate_share(comm, *map, c.op, c.phase, {}, {}, none);
          } catch (const Failure&) {
          }
          break;
        }
        case kStats:
          gather_stats(comm, map ? map->rank_stats() : RankStats{});
          break;
        case kDone:
          return c.code;
        default:
          throw csrbf::Error("unknown command " + std::to_string(c.op) + " from rank 0");
      }
    } catch (const std::exception& e) {
      // Not agreed with the other ranks: they may wait for this one in a collective. Report, then
      // end the whole job.
      std::cerr << "csrbf: error (rank " << rank << "): " << e.what() << '\n';
      MPI_Abort(comm, 1);
    }
  }
}

// ---- DecomposedBackend -----------------------------------------------------------------------

namespace {

/// Keeps its figures in the backend's (sink) after each evaluation: the mapping ends with the morph.
class DecomposedMapping final : public morph::FittedMapping {
 public:
  DecomposedMapping(DistributedMap map, RankStats& sink) : map_(std::move(map)), sink_(sink) {
    sink_ = map_.rank_stats();
  }
  void apply(std::span<const Vec3> in, std::span<Vec3> out, double phase) override {
    map_.apply(in, out, phase);
    sink_ = map_.rank_stats();
  }
  void displacements(std::span<const Vec3> in, std::span<Vec3> out) override {
    map_.displacements(in, out);
    sink_ = map_.rank_stats();
  }
  FitStats stats() const override {
    FitStats s;
    s.controls = map_.stats().controls;
    s.solver = map_.stats().solver == DistributedSolver::Cg ? Solver::Cg : Solver::Cholmod;
    s.iterations = map_.stats().iterations;
    s.fell_back = map_.stats().fell_back;
    s.residual_relative = map_.stats().residual_relative;
    return s;
  }
  DistributedMap map_;
  RankStats& sink_;
};

}  // namespace

Decomposition find_decomposition(const fs::path& mesh) {
  Decomposition d;
  std::error_code ec;
  if (fs::is_directory(mesh, ec)) {
    for (int n = 0;; ++n) {
      const fs::path p = mesh / ("processor" + std::to_string(n));
      if (!fs::is_directory(p, ec)) break;
      d.parts.push_back(p);
    }
    // Every processor folder, consecutive, and as many as decomposePar was asked for.
    std::size_t highest = 0;
    bool any = false;
    for (const auto& e : fs::directory_iterator(mesh, ec)) {
      const std::string name = e.path().filename().string();
      if (name.rfind("processor", 0) != 0 || name.size() == 9) continue;
      const std::string digits = name.substr(9);
      if (digits.find_first_not_of("0123456789") != std::string::npos || digits.size() > 9) continue;
      any = true;
      highest = std::max<std::size_t>(highest, std::stoul(digits));
    }
    if (!any) return d;
    if (d.parts.size() != highest + 1)
      throw io::FileError((mesh / ("processor" + std::to_string(d.parts.size()))).string() +
                          ": missing, but the case has processor" + std::to_string(highest) +
                          " (a decomposed case has processor0 to processorN-1)");
    const fs::path dict = mesh / "system" / "decomposeParDict";
    if (fs::is_regular_file(dict, ec)) {
      const std::string t = io::read_input(dict, "a decomposeParDict", 16.0 * (1 << 20));
      const std::size_t at = t.find("numberOfSubdomains");
      if (at != std::string::npos) {
        std::size_t i = at + 18;
        while (i < t.size() && std::isspace(static_cast<unsigned char>(t[i]))) ++i;
        std::size_t j = i;
        while (j < t.size() && std::isdigit(static_cast<unsigned char>(t[j]))) ++j;
        if (j > i && j - i < 10 && std::stoul(t.substr(i, j - i)) != d.parts.size())
          throw io::FileError(dict.string() + ": numberOfSubdomains " + t.substr(i, j - i) + ", but the case has " +
                              std::to_string(d.parts.size()) +
                              " processor folders: a processor folder is missing, or the case was decomposed "
                              "again differently");
      }
    }
    d.kind = Decomposition::Kind::OpenFoam;
    d.root = mesh;
    return d;
  }
  std::string ext = mesh.extension().string();
  for (auto& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (ext != ".pvtu") return d;
  d.kind = Decomposition::Kind::Pvtu;
  d.root = mesh;
  d.pvtu_text = io::read_input(mesh, "a parallel VTK file", 64.0 * (1 << 20));
  // <Piece Source="name.vtu"/>, the quotes either kind.
  const std::string& t = d.pvtu_text;
  for (std::size_t at = t.find("<Piece"); at != std::string::npos; at = t.find("<Piece", at + 6)) {
    const std::size_t end = t.find('>', at);
    const std::size_t src = t.find("Source", at);
    if (end == std::string::npos || src == std::string::npos || src > end)
      throw io::FileError(mesh.string() + ": a <Piece> without a Source attribute");
    const std::size_t q = t.find_first_of("\"'", src);
    const std::size_t q2 = q == std::string::npos ? q : t.find(t[q], q + 1);
    if (q == std::string::npos || q2 == std::string::npos || q2 > end)
      throw io::FileError(mesh.string() + ": a <Piece> whose Source is not quoted");
    const fs::path piece = t.substr(q + 1, q2 - q - 1);
    if (piece.empty() || piece.is_absolute())
      throw io::FileError(mesh.string() + ": piece '" + piece.string() + "': a path relative to the .pvtu's folder");
    d.parts.push_back(mesh.parent_path() / piece);
  }
  if (d.parts.empty()) throw io::FileError(mesh.string() + ": no <Piece Source=...> entries");
  return d;
}

DecomposedBackend::DecomposedBackend(MPI_Comm comm, DistributedSolver solver, Decomposition decomposition)
    : comm_(comm), solver_(solver), d_(std::move(decomposition)) {}

std::unique_ptr<morph::FittedMapping> DecomposedBackend::fit(std::span<const Vec3> sources,
                                                             std::span<const Vec3> targets, const FitOptions& options,
                                                             std::span<const std::uint64_t> ids) {
  auto m = std::make_unique<DecomposedMapping>(
      DistributedMap::fit(comm_, sources, targets, options, solver_, ids, true), last_);
  stats_ = m->map_.stats();
  return m;
}

double DecomposedBackend::max(double local) {
  double out = 0;
  MPI_Allreduce(&local, &out, 1, MPI_DOUBLE, MPI_MAX, comm_);
  return out;
}

void DecomposedBackend::max(std::span<double> values) {
  if (values.size() > std::size_t(INT_MAX)) throw ResourceLimit("more values than one MPI reduction takes");
  MPI_Allreduce(MPI_IN_PLACE, values.data(), int(values.size()), MPI_DOUBLE, MPI_MAX, comm_);
}

double DecomposedBackend::sum(double local) {
  double out = 0;
  MPI_Allreduce(&local, &out, 1, MPI_DOUBLE, MPI_SUM, comm_);
  return out;
}

static_assert(sizeof(Vec3) == 3 * sizeof(double));

std::vector<Vec3> DecomposedBackend::gather(std::span<const Vec3> local) {
  int size = 1;
  MPI_Comm_size(comm_, &size);
  const double mine = double(local.size()) * 3;
  std::vector<double> counts(std::size_t(size), 0.0);
  MPI_Allgather(&mine, 1, MPI_DOUBLE, counts.data(), 1, MPI_DOUBLE, comm_);
  std::vector<int> n(static_cast<std::size_t>(size)), at(static_cast<std::size_t>(size));
  double total = 0;
  for (std::size_t r = 0; r < counts.size(); ++r) {
    if (total + counts[r] > double(INT_MAX)) throw ResourceLimit("more points than one MPI gather takes");
    n[r] = int(counts[r]);
    at[r] = int(total);
    total += counts[r];
  }
  std::vector<Vec3> all(std::size_t(total) / 3);
  MPI_Allgatherv(local.data(), int(mine), MPI_DOUBLE, all.data(), n.data(), at.data(), MPI_DOUBLE, comm_);
  return all;
}

void DecomposedBackend::agree(std::exception_ptr local) { mpi::agree(comm_, local, exit_code_of); }

fs::path DecomposedBackend::mesh_path(const fs::path&) {
  int rank = 0;
  MPI_Comm_rank(comm_, &rank);
  return d_.parts.at(std::size_t(rank));
}

void DecomposedBackend::write_copy(const morph::VolumeFile& file, std::span<const Vec3> points, const fs::path& out) {
  if (d_.kind == Decomposition::Kind::Pvtu) {
    write_pieces_copy(file, points, out);
    return;
  }
  int rank = 0;
  MPI_Comm_rank(comm_, &rank);
  std::unique_ptr<io::Partial> partial;
  std::string where;
  agree(caught([&] {
    if (!file.foam()) throw io::FileError("a decomposed OpenFOAM case has OpenFOAM parts");
    if (rank != 0) return;
    std::error_code ec;
    const fs::path root = fs::weakly_canonical(d_.root, ec), target = fs::weakly_canonical(fs::absolute(out), ec);
    const auto [r_end, t_it] = std::mismatch(root.begin(), root.end(), target.begin(), target.end());
    if (r_end == root.end())
      throw io::FileError("cannot write '" + out.string() + "': it is inside the case '" + d_.root.string() +
                          "' being copied");
    partial = std::make_unique<io::Partial>(out, io::Partial::Kind::Folder);
    fs::copy(d_.root, partial->path(), fs::copy_options::recursive | fs::copy_options::copy_symlinks, ec);
    if (ec) throw io::FileError("cannot copy '" + d_.root.string() + "' to '" + out.string() + "': " + ec.message());
    where = partial->path().string();
  }));
  broadcast(comm_, where);
  agree(caught([&] {
    morph::write_openfoam_points_into(*file.foam(), points, fs::path(where) / d_.parts[std::size_t(rank)].filename());
  }));
  agree(caught([&] {
    if (rank == 0) partial->commit_new(out);
  }));
}

/// A .pvtu's copy: out (a new .pvtu) and a new folder beside it named after it (out without its
/// extension) that holds the pieces, each written by its rank; rank 0 writes the .pvtu last, its
/// text the input's with the pieces' new paths. Both appear only when every piece is written.
void DecomposedBackend::write_pieces_copy(const morph::VolumeFile& file, std::span<const Vec3> points,
                                          const fs::path& out) {
  int rank = 0;
  MPI_Comm_rank(comm_, &rank);
  const fs::path folder = out.parent_path() / out.stem();
  std::unique_ptr<io::Partial> partial;
  std::string where;
  agree(caught([&] {
    if (rank != 0) return;
    std::string ext = out.extension().string();
    for (auto& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    if (ext != ".pvtu") throw morph::JobError("output " + out.string() + ": a .pvtu's copy is a .pvtu");
    std::error_code ec;
    if (fs::symlink_status(folder, ec).type() != fs::file_type::not_found)
      throw io::FileError("cannot write '" + out.string() + "': its pieces' folder '" + folder.string() + "' exists");
    partial = std::make_unique<io::Partial>(folder, io::Partial::Kind::Folder);
    where = partial->path().string();
  }));
  broadcast(comm_, where);
  agree(caught([&] { file.write_copy(points, fs::path(where) / d_.parts[std::size_t(rank)].filename()); }));
  agree(caught([&] {
    if (rank != 0) return;
    // The input's text with each Source replaced, in order.
    std::string text = d_.pvtu_text;
    std::size_t k = 0;
    for (std::size_t at = text.find("<Piece"); at != std::string::npos; at = text.find("<Piece", at + 6), ++k) {
      const std::size_t src = text.find("Source", at);
      const std::size_t q = text.find_first_of("\"'", src);
      const std::size_t q2 = text.find(text[q], q + 1);
      const std::string name = (fs::path(folder.filename()) / d_.parts[k].filename()).generic_string();
      text.replace(q + 1, q2 - q - 1, name);
    }
    io::Partial header(out, io::Partial::Kind::File);
    {
      std::ofstream o(header.path(), std::ios::binary | std::ios::trunc);
      o << text;
      o.close();
      std::error_code ec;
      if (!o || fs::file_size(header.path(), ec) != text.size())
        throw io::FileError("cannot write '" + out.string() + "': the disk did not take all of it");
    }
    partial->commit_new(folder);
    try {
      header.commit_new(out);
    } catch (...) {
      std::error_code ec;
      fs::remove_all(folder, ec);  // csrbf's own pieces, just made
      throw;
    }
  }));
}

void DecomposedBackend::write_in_place(const morph::VolumeFile& file, std::span<const Vec3> points) {
  // Three agreed steps, so that the parts change all together or not at all:
  // 1. each part's new file is staged beside it, and the old one kept by a second name (a hard link);
  // 2. each staged file is renamed over its part; where any rank could not, the others put their old
  //    file back;
  // 3. the old files' second names are removed.
  int rank = 0;
  MPI_Comm_rank(comm_, &rank);
  const fs::path target = file.foam() ? file.foam()->points_file.target : d_.parts.at(std::size_t(rank));
  // A time folder whose mesh was constant's gets its first points file: there is no old one to keep.
  std::error_code exists_ec;
  const bool fresh = !fs::exists(fs::symlink_status(target, exists_ec));
  const fs::path kept = target.parent_path() / (".csrbf-old-" + target.filename().string());
  fs::path staged;
  std::unique_ptr<io::Partial> staged_foam;  // an OpenFOAM part's: a partial file of csrbf's own
  bool linked = false, renamed = false;
  const auto tidy = [&] {
    std::error_code ec;
    if (!staged_foam && !staged.empty() && !renamed) fs::remove(staged, ec);
    staged_foam.reset();  // removes it where not committed
    if (linked) fs::remove(kept, ec);
  };
  const std::exception_ptr e1 = caught([&] {
    if (file.foam()) {
      staged_foam = morph::stage_openfoam_points(*file.foam(), points);
      staged = staged_foam->path();
    } else {
      staged = target.parent_path() / (".csrbf-new-" + target.filename().string());
      std::error_code ec;
      fs::remove(staged, ec);  // a stale one of csrbf's, from a run that was killed
      file.write_copy(points, staged);
    }
    std::error_code ec;
    if (fresh) return;
    fs::remove(kept, ec);
    fs::create_hard_link(target, kept, ec);
    if (ec)
      throw io::FileError("cannot write '" + target.string() + "': cannot keep the old file (" + ec.message() + ")");
    linked = true;
  });
  try {
    agree(e1);
  } catch (...) {
    tidy();
    throw;
  }
  const std::exception_ptr e2 = caught([&] {
    if (staged_foam) {
      morph::commit_openfoam_points(*file.foam(), *staged_foam);
    } else {
      std::error_code ec;
      fs::rename(staged, target, ec);
      if (ec) throw io::FileError("cannot write '" + target.string() + "': " + ec.message());
    }
    renamed = true;
  });
  try {
    agree(e2);
  } catch (...) {
    if (renamed) {  // put the old file back (or take away the first one, which this run made)
      std::error_code ec;
      if (fresh) {
        fs::remove(target, ec);
      } else {
        fs::rename(kept, target, ec);
        if (!ec) linked = false;
      }
    }
    tidy();
    throw;
  }
  tidy();
}

std::vector<RankStats> DecomposedBackend::rank_stats() { return gather_stats(comm_, last_); }

}  // namespace csrbf::mpi
