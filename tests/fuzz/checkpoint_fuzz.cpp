// libFuzzer target for the checkpoint reader: any byte string must either decode or be
// refused with std::runtime_error; ASan/UBSan catch every memory or arithmetic fault.
#include "checkpoint.h"

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

namespace {

// The shape of the worlds checkpoint_seeds writes, so decoded seeds also reach
// apply_checkpoint's checks and the world's set_state.
drape::World& target_world() {
  static drape::World world = [] {
    drape::World w;
    drape::SheetDef a, b;
    a.m = a.n = 1;
    b.m = 2;
    b.n = 3;
    w.add_sheet(a);
    w.add_sheet(b);
    return w;
  }();
  return world;
}

void decode_and_apply(std::span<const unsigned char> bytes) {
  try {
    const drape::Checkpoint c = drape::decode_checkpoint(bytes, "fuzz input");
    if (c.precision == sizeof(double)) drape::apply_checkpoint(c, target_world(), "fuzz input");
  } catch (const std::runtime_error&) {
    // refused with a message: the outcome we want for bad input
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const unsigned char> bytes(data, size);
  decode_and_apply(bytes);
  // Mutations almost never keep the checksum right, so the parser behind it would go
  // unexplored: try each input a second time with its checksum repaired.
  if (size >= 8) {
    std::vector<unsigned char> sealed(bytes.begin(), bytes.end());
    const std::uint64_t sum = drape::fnv1a64(std::span(sealed).first(size - 8));
    for (int i = 0; i < 8; ++i) sealed[size - 8 + i] = static_cast<unsigned char>(sum >> (8 * i));
    decode_and_apply(sealed);
  }
  return 0;
}
