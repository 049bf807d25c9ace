// The contact stage's memory as words, for checkpoints (contacts.h, write_contact_memory).
#include <algorithm>
#include <bit>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "contacts.h"

namespace drape::detail {

namespace {

// Bumped whenever the words below change. Layout 1 gave every list entry a word of its own;
// layout 2 packs entries of 4 bytes or less (indices, flags, floats) two to a word, first
// in the low half, and keeps doubles one to a word; layout 3 adds each kept set's skips
// (KeptContacts::until) and every sheet's travel; layout 4 each pair's last substep in the
// world's list (PairContacts::present_at). All four are read.
constexpr std::uint64_t kLayout = 4, kSkips = 3, kPacked = 2, kOneEntryAWord = 1;
constexpr std::uint32_t kNone = ~std::uint32_t(0);

[[noreturn]] void bad(const std::string& problem) { throw std::invalid_argument("drape: contact memory " + problem); }

template <class Real>
std::uint64_t bits(Real v) {
  if constexpr (std::is_same_v<Real, float>)
    return std::bit_cast<std::uint32_t>(v);
  else
    return std::bit_cast<std::uint64_t>(v);
}

// Whether entries of type T share words (layout 2): all but doubles.
template <class T>
constexpr bool kHalfWord = sizeof(T) <= 4;

template <class Real>
class Words {
 public:
  std::vector<std::uint64_t> out;
  bool packed = true;
  void word(std::uint64_t v) { out.push_back(v); }
  void doubles(const std::vector<double>& values) {  // one to a word, whatever Real is
    out.push_back(values.size());
    for (double v : values) out.push_back(std::bit_cast<std::uint64_t>(v));
  }
  template <class T>
  void list(const T& values) {
    using V = typename T::value_type;
    out.push_back(values.size());
    if constexpr (kHalfWord<V>) {
      if (!packed) {
        for (V v : values) out.push_back(bits32(v));
        return;
      }
      for (std::size_t e = 0; e < values.size(); e += 2)
        out.push_back(bits32(values[e]) | (e + 1 < values.size() ? std::uint64_t(bits32(values[e + 1])) << 32 : 0));
    } else {
      for (V v : values) out.push_back(bits<Real>(v));
    }
  }

 private:
  template <class V>
  static std::uint32_t bits32(V v) {
    if constexpr (std::is_floating_point_v<V>)
      return std::bit_cast<std::uint32_t>(v);
    else
      return v;
  }
};

// Bounds-checked: a count read from the memory is checked against what is left before
// anything is allocated for it.
template <class Real>
class Reading {
 public:
  explicit Reading(std::span<const std::uint64_t> in) : in_(in) {}
  bool packed = true;  // layout 2; false for layout 1, one entry a word
  std::uint64_t word(const char* what) {
    if (pos_ >= in_.size()) bad(std::string("ends before ") + what);
    return in_[pos_++];
  }
  std::uint32_t u32(const char* what) {
    const std::uint64_t v = word(what);
    if (v > kNone) bad(std::string(what) + " out of range");
    return std::uint32_t(v);
  }
  Real real(const char* what) {
    const std::uint64_t v = word(what);
    if constexpr (std::is_same_v<Real, float>) {
      if (v > kNone) bad(std::string(what) + " is not a float");
      return std::bit_cast<float>(std::uint32_t(v));
    } else {
      return std::bit_cast<double>(v);
    }
  }
  template <class T>
  void list(T& values, const char* what) {
    using V = typename T::value_type;
    const std::uint64_t count = word(what);
    const bool halves = packed && kHalfWord<V>;
    const std::uint64_t words = halves ? count / 2 + count % 2 : count;
    if (words > in_.size() - pos_) bad(std::string(what) + " claims more entries than it holds");
    values.resize(count);
    if (halves) {
      for (std::size_t e = 0; e < count; e += 2) {
        const std::uint64_t w = word(what);
        if (e + 1 == count && (w >> 32) != 0) bad(std::string(what) + " has bits past its last entry");
        values[e] = entry<V>(std::uint32_t(w), what);
        if (e + 1 < count) values[e + 1] = entry<V>(std::uint32_t(w >> 32), what);
      }
      return;
    }
    for (auto& v : values) {
      if constexpr (std::is_floating_point_v<V>)
        v = real(what);
      else if constexpr (sizeof(V) == 1)
        v = std::uint8_t(word(what) != 0);
      else
        v = u32(what);
    }
  }
  void doubles(std::vector<double>& values, const char* what) {
    const std::uint64_t count = word(what);
    if (count > in_.size() - pos_) bad(std::string(what) + " claims more entries than it holds");
    values.resize(count);
    for (double& v : values) v = std::bit_cast<double>(word(what));
  }
  bool done() const { return pos_ == in_.size(); }

 private:
  // One entry of a packed word's half.
  template <class V>
  static V entry(std::uint32_t half, const char* what) {
    if constexpr (std::is_floating_point_v<V>)
      return std::bit_cast<float>(half);
    else if constexpr (sizeof(V) == 1) {
      if (half > 1) bad(std::string(what) + " has a flag that is neither 0 nor 1");
      return V(half);
    } else
      return half;
  }

  std::span<const std::uint64_t> in_;
  std::size_t pos_ = 0;
};

// Whether first corner `c` is a cell of sheet s (so c + n + 2 is still a point).
template <class Real>
bool is_cell(std::uint32_t c, const Sheet<Real>& s) {
  const std::uint32_t row = s.topology->n + 1;
  return c / row < s.topology->m && c % row < s.topology->n;
}

template <class Real>
void check_cells(const std::vector<std::uint32_t>& cells, const Sheet<Real>& s, bool none_allowed, const char* what) {
  for (std::uint32_t c : cells)
    if (!(is_cell(c, s) || (none_allowed && c == kNone))) bad(std::string(what) + " names a cell the sheet lacks");
}

template <class Real>
void check_candidates(const Candidates& c, const Sheet<Real>& query, const Sheet<Real>& other) {
  if (c.begin.size() != c.count.size() || (!c.begin.empty() && c.begin.size() != query.size()))
    bad("candidate lists do not fit their sheet");
  for (std::size_t p = 0; p < c.begin.size(); ++p)
    if (std::uint64_t(c.begin[p]) + c.count[p] > c.cell.size()) bad("candidate list runs past its cells");
  check_cells(c.cell, other, false, "a candidate list");
}

template <class Real>
void check_kept(const KeptContacts& k, const Sheet<Real>& query, const Sheet<Real>& other) {
  if (k.point.size() != k.cell.size()) bad("kept set has points and cells of different counts");
  for (std::uint32_t p : k.point)
    if (p >= query.size()) bad("kept set names a point the sheet lacks");
  check_cells(k.cell, other, false, "a kept set");
  if (k.block_begin.empty() != k.open.empty() || (!k.open.empty() && k.block_begin.size() != k.open.size() + 1))
    bad("kept set's blocks do not match");
  for (std::size_t b = 0; b < k.block_begin.size(); ++b)
    if (k.block_begin[b] > k.point.size() || (b > 0 && k.block_begin[b] < k.block_begin[b - 1]))
      bad("kept set's blocks are out of order");
}

}  // namespace

template <class Real>
std::vector<std::uint64_t> write_contact_memory(const std::vector<PairContacts<Real>>& pair_work,
                                                std::span<const Sheet<Real>* const> sheets, int layout) {
  if (layout < 1 || layout > int(kLayout)) bad("cannot be written in layout " + std::to_string(layout));
  Words<Real> w;
  const bool travelled =
      std::any_of(sheets.begin(), sheets.end(), [](const Sheet<Real>* s) { return !s->travel_from.x.empty(); });
  // a world that never coupled sheets carries nothing
  if (pair_work.empty() && (layout < 3 || !travelled)) return {};
  w.packed = layout != int(kOneEntryAWord);
  w.word(std::uint64_t(layout));
  w.word(sizeof(Real));
  w.word(sheets.size());
  w.word(pair_work.size());
  const Vec3Array<Real> none;
  const std::vector<Real> no_clearance;
  const Candidates no_lists;
  const KeptContacts no_set;
  const std::vector<std::uint32_t> no_guesses;
  for (const PairContacts<Real>& p : pair_work) {
    const bool known = p.a < sheets.size() && p.b < sheets.size();
    // Lists made for other sheets than the pair's are never read again (made_for fails and
    // the pair searches), so they are written as none; so are guesses for other grids.
    const bool kept = known && p.kept_a == sheets[p.a] && p.kept_b == sheets[p.b] &&
                      p.kept_topology_a == sheets[p.a]->topology.get() &&
                      p.kept_topology_b == sheets[p.b]->topology.get();
    const bool guessed =
        known && p.guessed_a == sheets[p.a]->topology.get() && p.guessed_b == sheets[p.b]->topology.get();
    w.word(p.a);
    w.word(p.b);
    w.word((kept ? 1u : 0u) | (guessed ? 2u : 0u) | (p.kept_exact ? 4u : 0u));
    w.word(bits(p.skin));
    w.word(p.kept_for);
    w.word(p.since_full);
    w.word(p.resting);
    w.word(p.searches);
    w.word(std::uint64_t(std::int64_t(p.decided) + 1));
    if (layout >= 4) w.word(p.present_at);
    for (const KeptPositions<Real>* at : {&p.made_at_a, &p.made_at_b}) {
      const Vec3Array<Real>& v = kept ? at->get() : none;
      w.list(v.x);
      w.list(v.y);
      w.list(v.z);
    }
    w.list(kept ? p.clearance : no_clearance);
    for (const Candidates* c : {&p.a_near_b, &p.b_near_a}) {
      const Candidates& l = kept ? *c : no_lists;
      w.list(l.begin);
      w.list(l.count);
      w.list(l.cell);
    }
    for (const KeptContacts* k : {&p.a_on_b, &p.b_on_a}) {
      const KeptContacts& s = kept ? *k : no_set;
      w.list(s.point);
      w.list(s.cell);
      w.list(s.open);
      w.list(s.block_begin);
      if (layout >= 3) w.doubles(s.until);
    }
    w.list(guessed ? p.last_a : no_guesses);
    w.list(guessed ? p.last_b : no_guesses);
  }
  if (layout >= 3)
    for (const Sheet<Real>* s : sheets) {
      w.word(std::bit_cast<std::uint64_t>(s->travel));
      w.list(s->travel_from.x);
      w.list(s->travel_from.y);
      w.list(s->travel_from.z);
    }
  return std::move(w.out);
}

template <class Real>
void read_contact_memory(std::span<const std::uint64_t> memory, std::span<const Sheet<Real>* const> sheets,
                         std::vector<PairContacts<Real>>& pair_work, std::vector<SheetTravel<Real>>& travel,
                         std::uint64_t present_at) {
  Reading<Real> in(memory);
  const std::uint64_t layout = in.word("its layout");
  if (layout != kLayout && layout != kSkips && layout != kPacked && layout != kOneEntryAWord)
    bad("has another layout than this drape writes");
  in.packed = layout != kOneEntryAWord;
  if (in.word("its precision") != sizeof(Real)) bad("was written by a world of the other precision");
  if (in.word("its sheet count") != sheets.size()) bad("was written for another number of sheets");
  const std::uint64_t pairs = in.word("its pair count");
  if (pairs > memory.size()) bad("claims more pairs than it holds");
  std::vector<PairContacts<Real>> read(pairs);
  for (PairContacts<Real>& p : read) {
    p.a = in.u32("a pair's first sheet");
    p.b = in.u32("a pair's second sheet");
    if (p.a > p.b || p.b >= sheets.size()) bad("names a pair of sheets the world lacks");
    const Sheet<Real>& a = *sheets[p.a];
    const Sheet<Real>& b = *sheets[p.b];
    const std::uint64_t flags = in.word("a pair's flags");
    if (flags > 7) bad("has unknown pair flags");
    p.kept_exact = (flags & 4) != 0;
    p.skin = in.real("a pair's skin");
    p.kept_for = in.u32("a pair's kept count");
    p.since_full = in.u32("a pair's substeps since a full search");
    p.resting = in.u32("a pair's resting count");
    p.searches = in.word("a pair's search count");
    const std::uint64_t decided = in.word("a pair's decision");
    if (decided > 2) bad("has an unknown decision");
    p.decided = static_cast<signed char>(std::int64_t(decided) - 1);
    p.present_at = layout >= 4 ? in.word("a pair's last substep present") : present_at;
    for (auto [kept_at, sheet] : {std::pair{&p.made_at_a, &a}, std::pair{&p.made_at_b, &b}}) {
      Vec3Array<Real>* at = &kept_at->to_write();
      in.list(at->x, "positions lists were made at");
      in.list(at->y, "positions lists were made at");
      in.list(at->z, "positions lists were made at");
      if (at->x.size() != at->y.size() || at->x.size() != at->z.size() ||
          (!at->x.empty() && at->x.size() != sheet->size()))
        bad("holds positions that do not fit their sheet");
    }
    in.list(p.clearance, "clearances");
    for (Candidates* c : {&p.a_near_b, &p.b_near_a}) {
      in.list(c->begin, "candidate lists");
      in.list(c->count, "candidate lists");
      in.list(c->cell, "candidate lists");
    }
    check_candidates(p.a_near_b, a, b);
    check_candidates(p.b_near_a, b, a);
    for (KeptContacts* k : {&p.a_on_b, &p.b_on_a}) {
      in.list(k->point, "kept sets");
      in.list(k->cell, "kept sets");
      in.list(k->open, "kept sets");
      in.list(k->block_begin, "kept sets");
      if (layout >= 3) {
        in.doubles(k->until, "kept sets' skips");
        if (k->until.size() != k->point.size()) bad("kept set has points and skips of different counts");
      } else {
        k->until.assign(k->point.size(), -std::numeric_limits<double>::infinity());  // every entry walks
      }
    }
    check_kept(p.a_on_b, a, b);
    check_kept(p.b_on_a, b, a);
    in.list(p.last_a, "guesses");
    in.list(p.last_b, "guesses");
    if ((!p.last_a.empty() && p.last_a.size() != a.size()) || (!p.last_b.empty() && p.last_b.size() != b.size()))
      bad("holds guesses that do not fit their sheet");
    check_cells(p.last_a, b, true, "a guess");
    check_cells(p.last_b, a, true, "a guess");
    if (flags & 1) {
      p.kept_a = &a;
      p.kept_b = &b;
      p.kept_topology_a = a.topology.get();
      p.kept_topology_b = b.topology.get();
    }
    if (flags & 2) {
      p.guessed_a = a.topology.get();
      p.guessed_b = b.topology.get();
    }
  }
  std::vector<SheetTravel<Real>> travelled;
  if (layout >= 3) {
    travelled.resize(sheets.size());
    for (std::size_t k = 0; k < sheets.size(); ++k) {
      SheetTravel<Real>& t = travelled[k];
      t.travel = std::bit_cast<double>(in.word("a sheet's travel"));
      in.list(t.from.x, "a sheet's travel");
      in.list(t.from.y, "a sheet's travel");
      in.list(t.from.z, "a sheet's travel");
      if (!(t.travel >= 0) || t.from.x.size() != t.from.y.size() || t.from.x.size() != t.from.z.size() ||
          (!t.from.x.empty() && t.from.x.size() != sheets[k]->size()))
        bad("holds a travel that does not fit its sheet");
    }
  }
  if (!in.done()) bad(layout >= 3 ? "has words after its last sheet" : "has words after its last pair");
  pair_work = std::move(read);
  travel = std::move(travelled);
}

#define DRAPE_CONTACT_MEMORY(Real)                                                                             \
  template std::vector<std::uint64_t> write_contact_memory<Real>(const std::vector<PairContacts<Real>>&,      \
                                                                 std::span<const Sheet<Real>* const>, int);   \
  template void read_contact_memory<Real>(std::span<const std::uint64_t>, std::span<const Sheet<Real>* const>, \
                                          std::vector<PairContacts<Real>>&, std::vector<SheetTravel<Real>>&, \
                                          std::uint64_t);
DRAPE_CONTACT_MEMORY(double)
DRAPE_CONTACT_MEMORY(float)
#undef DRAPE_CONTACT_MEMORY

}  // namespace drape::detail
