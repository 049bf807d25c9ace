// Checkpoints: the full state of a World in one binary file, written atomically and read
// back all-or-nothing. The engine only hands out its state (BasicWorld::set_state and
// friends); this file format and every byte of I/O live here, in the apps.
//
// Layout, every number little-endian:
//   "DRAPECKP"                      8 bytes, magic
//   u32 format version              checkpoint_format_version
//   u32 precision                   bytes per stored value: 4 (WorldF) or 8 (World)
//   u64 fingerprint                 of the definitions the world was built from (0: none)
//   u64 step count
//   f64 dt, f64 gravity x, y, z
//   u32 length + bytes              integrator name (integrator_name), at most 64 bytes
//   u32 sheet count
//   per sheet, in the order the sheets were added:
//     u32 m, u32 n, u64 memory count
//     x, y, z, vx, vy, vz           (m+1)(n+1) values each, row-major as in eqs (2)-(3)
//     integrator memory             memory count values
//     u64 unconverged solves, u32 last solve's iterations, f64 its relative residual,
//     u32 converged (0 or 1)        World::solver_stats (format 2 on)
//   u64 word count + u64 words      World::contact_memory (format 3 on): the contact
//                                   stage's kept sets, so sheets in contact resume bit for
//                                   bit; a format 2 file has none and its run searches afresh
//   u64 FNV-1a 64 of every byte before it
#pragma once

#include <drape/world.h>

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace drape {

inline constexpr std::uint32_t checkpoint_format_version = 3;
// The oldest format this drape still reads (format 2: no contact memory).
inline constexpr std::uint32_t checkpoint_oldest_version = 2;

// A checkpoint in memory, parsed and checked but not applied to any world. Values are held
// as double whatever the precision: float -> double -> float is exact.
struct Checkpoint {
  struct SheetRecord {
    std::uint32_t m = 0, n = 0;
    std::vector<double> x, y, z, vx, vy, vz;
    std::vector<double> integrator_memory;
    World::SolverStats solver;  // the implicit solves' counters
  };
  std::uint32_t precision = 8;
  // The program's fingerprint of what it built the world from (e.g. FNV-1a of the scene
  // file), so a resume can refuse a checkpoint of another scene with the same grid sizes.
  // 0: none recorded; the engine never looks at it.
  std::uint64_t fingerprint = 0;
  std::uint64_t step_count = 0;
  double dt = 0;
  Vec3 gravity{};
  Integrator integrator = Integrator::SemiImplicitEuler;
  std::vector<SheetRecord> sheets;
  std::vector<std::uint64_t> contact_memory;  // World::contact_memory; empty: search afresh
};

template <class Real>
Checkpoint capture_checkpoint(const BasicWorld<Real>& world, std::uint64_t fingerprint = 0);

// Puts a checkpoint into a world built from the same definitions. Every check (precision,
// sheet count, each sheet's m×n, gravity) is made before anything is changed; on a mismatch
// it throws std::runtime_error naming `source` and the problem, and the world is untouched.
template <class Real>
void apply_checkpoint(const Checkpoint& checkpoint, BasicWorld<Real>& world, const std::string& source);

std::vector<unsigned char> encode_checkpoint(const Checkpoint& checkpoint);
// Parses a whole file image. Throws std::runtime_error "checkpoint <source>: <problem>"
// for a short, corrupted, foreign or other-version file; never returns a partial result.
Checkpoint decode_checkpoint(std::span<const unsigned char> bytes, const std::string& source);

// Writes the world's state to `path` atomically: a temporary file next to it, fsync, then
// rename over `path`. On any failure it throws std::runtime_error naming the file and the
// reason, removes the temporary file, and leaves an existing `path` as it was.
template <class Real>
void save_checkpoint(const BasicWorld<Real>& world, const std::filesystem::path& path, std::uint64_t fingerprint = 0);

// Reads, checks and applies `path` to `world`; all-or-nothing (see apply_checkpoint).
// A non-zero `fingerprint` must equal the one the checkpoint was saved with.
template <class Real>
void load_checkpoint(const std::filesystem::path& path, BasicWorld<Real>& world, std::uint64_t fingerprint = 0);

std::uint64_t fnv1a64(std::span<const unsigned char> bytes);

}  // namespace drape
