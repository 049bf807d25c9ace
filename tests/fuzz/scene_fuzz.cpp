// libFuzzer target for the scene reader: any byte string must either load or be refused
// with one SceneError; ASan/UBSan catch every memory or arithmetic fault on the way.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "scene.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    const drape::app::Scene scene = drape::app::parse_scene(text, "fuzz input");
    (void)drape::app::estimated_bytes(scene);
  } catch (const drape::app::SceneError&) {
    // refused with a message: the outcome we want for bad input
  }
  return 0;
}
