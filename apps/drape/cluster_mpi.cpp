// The cluster as MPI ranks (compiled only when CMake found MPI). MPI is joined only when a
// launcher started the program, so `drape sweep` run by itself never initialises MPI.
#include <mpi.h>

#include <cstdint>
#include <cstring>
#include <stdexcept>

#include "cluster.h"

namespace drape::app {

namespace {

void check(int code, const char* what) {
  if (code != MPI_SUCCESS) throw std::runtime_error(std::string("MPI: ") + what + " failed");
}

}  // namespace

Cluster::Cluster() {
  if (launched_ranks() == 0) return;
  int provided = 0;
  // Only the main thread calls MPI; TBB's workers never do.
  check(MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided), "MPI_Init_thread");
  joined_ = true;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
  MPI_Comm node;
  check(MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, rank_, MPI_INFO_NULL, &node), "MPI_Comm_split_type");
  MPI_Comm_size(node, &local_size_);
  MPI_Comm_free(&node);
}

Cluster::~Cluster() {
  if (joined_) MPI_Finalize();
}

// Each rank sends its payloads as one buffer: per payload a 64-bit length, then its bytes.
std::vector<std::string> Cluster::gather(std::size_t total, const std::vector<std::string>& mine) const {
  if (size_ == 1) return mine;
  std::string packed;
  for (const std::string& p : mine) {
    const std::uint64_t n = p.size();
    packed.append(reinterpret_cast<const char*>(&n), sizeof n);
    packed += p;
  }
  const int bytes = int(packed.size());
  const auto ranks = static_cast<std::size_t>(size_);
  std::vector<int> counts(ranks), offsets(ranks);
  check(MPI_Gather(&bytes, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, MPI_COMM_WORLD), "MPI_Gather");
  std::string all;
  if (rank_ == 0) {
    long long sum = 0;
    for (int r = 0; r < size_; ++r) {
      offsets[std::size_t(r)] = int(sum);
      sum += counts[std::size_t(r)];
    }
    if (sum > 0x7fffffff) throw std::runtime_error("MPI: the results of this plan exceed 2 GiB at rank 0");
    all.resize(std::size_t(sum));
  }
  check(MPI_Gatherv(packed.data(), bytes, MPI_CHAR, all.data(), counts.data(), offsets.data(), MPI_CHAR, 0,
                    MPI_COMM_WORLD),
        "MPI_Gatherv");
  if (rank_ != 0) return {};
  std::vector<std::string> out(total);
  for (int r = 0; r < size_; ++r) {
    std::size_t at = std::size_t(offsets[std::size_t(r)]);
    const std::size_t end = at + std::size_t(counts[std::size_t(r)]);
    for (std::size_t k = std::size_t(r); k < total; k += std::size_t(size_)) {
      std::uint64_t n = 0;
      if (end - at < sizeof n) throw std::runtime_error("MPI: rank " + std::to_string(r) + " sent too few results");
      std::memcpy(&n, all.data() + at, sizeof n);
      at += sizeof n;
      if (end - at < n) throw std::runtime_error("MPI: rank " + std::to_string(r) + " sent a truncated result");
      out[k].assign(all.data() + at, n);
      at += n;
    }
  }
  return out;
}

int Cluster::max_over_ranks(int value) const {
  if (size_ == 1) return value;
  int result = value;
  check(MPI_Allreduce(&value, &result, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD), "MPI_Allreduce");
  return result;
}

}  // namespace drape::app
