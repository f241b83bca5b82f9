// csrbf-cli-mpi: the command-line program (cli_main.cpp) with its ranks under mpirun
// (commands/distributed.cpp); the launcher `csrbf` runs it under mpirun.
#include "cli_main.hpp"
#include "commands/distributed.hpp"
#include "csrbf/mpi/runtime.hpp"

#include <optional>

namespace {

class MpiRanks final : public csrbf::cli::Ranks {
 public:
  bool start(int* argc, char*** argv) override {
    if (csrbf::mpi::launched_ranks() > 1) rt_.emplace(argc, argv);
    return rt_.has_value();
  }
  bool quiet() const override { return rt_->rank() != 0; }
  void barrier() override { MPI_Barrier(rt_->comm()); }
  int deform(const csrbf::cli::DeformArgs& a) override { return csrbf::cli::run_deform_distributed(*rt_, a); }
  int morph(const csrbf::cli::MorphArgs& a) override { return csrbf::cli::run_morph_distributed(a, *rt_); }

 private:
  std::optional<csrbf::mpi::Runtime> rt_;
};

}  // namespace

int main(int argc, char** argv) {
  MpiRanks ranks;
  return csrbf::cli::cli_main(argc, argv, &ranks);
}
