// Runs a test body once per instruction set this CPU supports, with every Highway
// dispatch of the engine (the row sweep, obstacles, contacts) sent to it.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "simd/kernels.h"

namespace drape::test {

// Runs body once per instruction set, widest first, with the kernels dispatched to it; the
// widest is back in use afterwards, whatever body did.
template <class Body>
void for_each_target(Body body) {
  const std::vector<std::int64_t> targets = detail::simd::supported_targets();
  ASSERT_FALSE(targets.empty());
  struct Restore {
    ~Restore() { detail::simd::use_target(0); }
  } restore;
  for (std::int64_t t : targets) {
    detail::simd::use_target(t);
    SCOPED_TRACE(detail::simd::target_name());
    body(t);
  }
}

}  // namespace drape::test
