// libFuzzer target for the frame readers `drape render DIR` uses (OBJ, PLY, VTU): any byte
// string must either parse or be refused with std::runtime_error; ASan/UBSan catch every
// memory or arithmetic fault. The first byte picks the format, the rest is the file's text.
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string_view>

#include "export.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  constexpr std::string_view formats[] = {".obj", ".ply", ".vtu"};
  const std::string_view extension = formats[data[0] % 3];
  const std::string_view text(reinterpret_cast<const char*>(data + 1), size - 1);
  try {
    if (data[0] & 4)
      drape::app::parse_frame<float>(text, extension, "fuzz input");
    else
      drape::app::parse_frame<double>(text, extension, "fuzz input");
  } catch (const std::runtime_error&) {
    // refused with a message: the outcome we want for bad input
  }
  return 0;
}
