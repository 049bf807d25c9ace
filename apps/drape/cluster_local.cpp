// A cluster of one process: the build without MPI. No MPI code at all.
#include <stdexcept>
#include <string>

#include "cluster.h"

namespace drape::app {

Cluster::Cluster() {
  if (const int ranks = launched_ranks(); ranks > 1)
    throw std::runtime_error("this drape was built without MPI (libopenmpi-dev was not found when it was built), but "
                             "was started as one of " + std::to_string(ranks) +
                             " MPI ranks: each would run every case. Run it without mpirun, or rebuild with MPI");
}
Cluster::~Cluster() = default;

std::vector<std::string> Cluster::gather(std::size_t, const std::vector<std::string>& mine) const { return mine; }

int Cluster::max_over_ranks(int value) const { return value; }

}  // namespace drape::app
