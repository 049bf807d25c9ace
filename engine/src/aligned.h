// Memory for the engine's arrays: cache-line aligned, and large blocks on huge pages.
#pragma once

#include <cstddef>
#include <memory>
#include <new>
#include <utility>

namespace drape::detail {

// Blocks of at least this many bytes (a large sheet's arrays, a Cholesky factor's panels)
// start on a huge page boundary and ask for huge pages.
inline constexpr std::size_t huge_block = std::size_t(2) << 20;

// A hint that the block's pages be huge (Linux: transparent huge pages where
// /sys/kernel/mm/transparent_hugepage/enabled is `madvise` or `always`), so its first touch
// faults once per 2 MiB instead of once per 4 KiB and a sweep over it misses the TLB less.
// Only a hint: where the system refuses or has none, nothing changes.
void large_pages(void* p, std::size_t bytes) noexcept;

// Allocates on 64-byte boundaries, so a sweep streams whole cache lines and no 64-byte
// vector access straddles two of them (the machine-ceiling benchmark showed the sweep of a
// sheet beyond the caches losing a third of its speed to misaligned arrays), and blocks of
// huge_block bytes or more on huge pages (above).

template <class T>
struct CacheAligned {
  using value_type = T;
  static constexpr std::size_t alignment = 64;
  CacheAligned() = default;
  template <class U>
  constexpr CacheAligned(const CacheAligned<U>&) noexcept {}
  static constexpr std::size_t alignment_for(std::size_t bytes) { return bytes >= huge_block ? huge_block : alignment; }
  T* allocate(std::size_t n) {
    const std::size_t bytes = n * sizeof(T);
    void* p = ::operator new(bytes, std::align_val_t(alignment_for(bytes)));
    if (bytes >= huge_block) large_pages(p, bytes);
    return static_cast<T*>(p);
  }
  void deallocate(T* p, std::size_t n) noexcept { ::operator delete(p, std::align_val_t(alignment_for(n * sizeof(T)))); }
  friend bool operator==(const CacheAligned&, const CacheAligned&) { return true; }
};

// std::allocator whose value-initialisation leaves the element uninitialised: growing a
// buffer that is written before it is read (resize to make room) then costs no fill.
template <class T>
struct Uninitialised : std::allocator<T> {
  template <class U>
  struct rebind {
    using other = Uninitialised<U>;
  };
  Uninitialised() = default;
  template <class U>
  constexpr Uninitialised(const Uninitialised<U>&) noexcept {}
  template <class U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

}  // namespace drape::detail
