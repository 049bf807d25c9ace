// Huge pages for large blocks (aligned.h).
#include "aligned.h"

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace drape::detail {

void large_pages(void* p, std::size_t bytes) noexcept {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  // On a virtual machine most of a large sheet's or a factor's first substep went to page
  // faults (implicit_euler's first step, docs/integrators.md); a refused hint costs nothing.
  (void)madvise(p, bytes, MADV_HUGEPAGE);
#else
  (void)p;
  (void)bytes;
#endif
}

}  // namespace drape::detail
