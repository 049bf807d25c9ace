// One pool of handles for every kind of object the world hands out (sheets, obstacles,
// constraints): a slot index plus a generation that grows when the slot is freed, so a
// stale handle is recognised and a freed slot is reused. The owner keeps its objects in a
// vector indexed like the pool (`acquire` may ask it to grow) and its own list of live
// slots in whatever order it steps them. `Tag` is the kind of the handles it gives out.
#pragma once

#include <cstdint>
#include <vector>

#include <drape/types.h>

namespace drape::detail {

template <class Tag>
class IdPool {
 public:
  // A free slot: the most recently released one, else a new one at index size() − 1.
  std::uint32_t acquire() {
    if (!free_.empty()) {
      const std::uint32_t index = free_.back();
      free_.pop_back();
      live_[index] = true;
      return index;
    }
    generations_.push_back(0);
    live_.push_back(true);
    return static_cast<std::uint32_t>(generations_.size() - 1);
  }
  // Frees a live slot; every handle to it goes stale.
  void release(std::uint32_t index) {
    ++generations_[index];
    live_[index] = false;
    free_.push_back(index);
  }
  std::size_t size() const { return generations_.size(); }

  Id<Tag> id(std::uint32_t index) const {
    return {index, generations_[index]};
  }
  bool contains(Id<Tag> id) const {
    return id.index < generations_.size() && live_[id.index] && generations_[id.index] == id.generation;
  }
  std::vector<Id<Tag>> ids(const std::vector<std::uint32_t>& indices) const {
    std::vector<Id<Tag>> out;
    out.reserve(indices.size());
    for (std::uint32_t index : indices) out.push_back(id(index));
    return out;
  }

 private:
  std::vector<std::uint32_t> generations_, free_;
  std::vector<bool> live_;
};

}  // namespace drape::detail
