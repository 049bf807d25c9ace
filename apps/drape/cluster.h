// The processes a sweep or a batch is spread over: the ranks of an MPI job when the program
// was started by mpirun (or another MPI launcher) and built with MPI, else this one process.
// Cases are dealt out round-robin: case k of a plan belongs to rank k mod size(). Each rank
// runs its own cases with its cores (TBB); rank 0 gathers every result in case order, so
// what it writes does not depend on how many ranks there were. Two implementations of this
// header: cluster_mpi.cpp (MPI found at build time) and cluster_local.cpp (one process).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

namespace drape::app {

// Ranks an MPI launcher started this program among, from the environment it gives each rank
// (OpenMPI's mpirun: OMPI_COMM_WORLD_SIZE; MPICH's and Slurm's PMI: PMI_SIZE); 0 when none did.
inline int launched_ranks() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE"})
    if (const char* v = std::getenv(name)) return std::max(1, std::atoi(v));
  return 0;
}

class Cluster {
 public:
  // Joins the MPI job when the launcher's environment says there is one; throws
  // std::runtime_error when there is one but this program was built without MPI (every rank
  // would otherwise run the whole plan).
  Cluster();
  ~Cluster();
  Cluster(const Cluster&) = delete;
  Cluster& operator=(const Cluster&) = delete;

  int rank() const { return rank_; }
  int size() const { return size_; }
  bool is_root() const { return rank_ == 0; }
  // Ranks on this machine: they share its cores.
  int local_size() const { return local_size_; }
  // Worker threads of this rank for `requested`: itself when positive; for 0 (all cores),
  // this machine's cores shared evenly by its ranks (0 again when the rank is alone on it).
  int threads(int requested) const {
    if (requested > 0 || local_size_ == 1) return requested;
    return std::max(1, int(std::thread::hardware_concurrency()) / local_size_);
  }

  // Cases k < total that this rank runs, in order: rank, rank + size, ...
  std::vector<std::size_t> my_cases(std::size_t total) const {
    std::vector<std::size_t> cases;
    for (std::size_t k = std::size_t(rank_); k < total; k += std::size_t(size_)) cases.push_back(k);
    return cases;
  }
  // `mine` holds one payload per case of my_cases(total), in that order. Rank 0 gets all
  // `total` payloads in case order; every other rank gets an empty vector.
  std::vector<std::string> gather(std::size_t total, const std::vector<std::string>& mine) const;
  // The largest of every rank's `value`, on every rank.
  int max_over_ranks(int value) const;

 private:
  int rank_ = 0, size_ = 1, local_size_ = 1;
  [[maybe_unused]] bool joined_ = false;  // MPI was initialised here (cluster_mpi.cpp only)
};

}  // namespace drape::app
