// Checkpoint encoding, checking and atomic file I/O (format in checkpoint.h).
#include "checkpoint.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string_view>
#include <system_error>

namespace drape {

namespace {

constexpr std::array<unsigned char, 8> magic{'D', 'R', 'A', 'P', 'E', 'C', 'K', 'P'};
constexpr std::size_t max_integrator_name = 64;
constexpr std::uint32_t max_grid = std::uint32_t(1) << 31;  // as validate(SheetDef)

[[noreturn]] void fail(const std::string& source, const std::string& problem) {
  throw std::runtime_error("checkpoint " + source + ": " + problem);
}

std::string system_error(const char* what, const std::string& file) {
  return std::string(what) + " " + file + ": " + std::strerror(errno);
}

// Little-endian writer; the file is the same on any host.
class Writer {
 public:
  void u32(std::uint32_t v) { put(v, 4); }
  void u64(std::uint64_t v) { put(v, 8); }
  void f64(double v) { u64(std::bit_cast<std::uint64_t>(v)); }
  void real(double v, std::uint32_t precision) {
    if (precision == 4)
      u32(std::bit_cast<std::uint32_t>(static_cast<float>(v)));
    else
      f64(v);
  }
  void bytes(std::span<const unsigned char> b) { out.insert(out.end(), b.begin(), b.end()); }
  std::vector<unsigned char> out;

 private:
  void put(std::uint64_t v, int count) {
    for (int i = 0; i < count; ++i) out.push_back(static_cast<unsigned char>(v >> (8 * i)));
  }
};

// Bounds-checked reader: every read first checks that the bytes are there, so a short or
// lying file can neither read past the end nor make us allocate more than it holds.
class Reader {
 public:
  Reader(std::span<const unsigned char> bytes, const std::string& source) : bytes_(bytes), source_(source) {}

  void need(std::uint64_t count, const char* what) const {
    if (count > remaining())
      fail(source_, std::string("truncated: ") + what + " needs " + std::to_string(count) + " bytes at offset " +
                        std::to_string(pos_) + ", only " + std::to_string(remaining()) + " left");
  }
  // For counts read from the file: fails unless count items of item_size bytes are present.
  void need_items(std::uint64_t count, std::uint64_t item_size, const char* what) const {
    if (count > remaining() / item_size)
      fail(source_, std::string("truncated: ") + what + " at offset " + std::to_string(pos_) + " claims " +
                        std::to_string(count) + " items, only " + std::to_string(remaining()) + " bytes left");
  }
  std::uint64_t remaining() const { return bytes_.size() - pos_; }
  std::size_t position() const { return pos_; }

  std::uint32_t u32(const char* what) { return static_cast<std::uint32_t>(get(4, what)); }
  std::uint64_t u64(const char* what) { return get(8, what); }
  double f64(const char* what) { return std::bit_cast<double>(u64(what)); }
  double real(std::uint32_t precision, const char* what) {
    if (precision == 4) return std::bit_cast<float>(u32(what));
    return f64(what);
  }
  std::span<const unsigned char> take(std::size_t count, const char* what) {
    need(count, what);
    auto s = bytes_.subspan(pos_, count);
    pos_ += count;
    return s;
  }

 private:
  std::uint64_t get(int count, const char* what) {
    need(count, what);
    std::uint64_t v = 0;
    for (int i = 0; i < count; ++i) v |= std::uint64_t(bytes_[pos_ + i]) << (8 * i);
    pos_ += count;
    return v;
  }
  std::span<const unsigned char> bytes_;
  const std::string& source_;
  std::size_t pos_ = 0;
};

// Header bytes before the first sheet, with an empty integrator name.
constexpr std::size_t min_header = 8 + 4 + 4 + 8 + 8 + 8 + 24 + 4 + 4;
constexpr std::size_t checksum_size = 8;

void read_values(Reader& in, std::uint32_t precision, std::uint64_t count, std::vector<double>& out, const char* what) {
  in.need_items(count, precision, what);  // before allocating: count comes from the file
  out.resize(count);
  for (double& v : out) v = in.real(precision, what);
}

// Closes a descriptor on every path out of a scope.
struct Fd {
  int fd = -1;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

std::vector<unsigned char> read_file(const std::filesystem::path& path) {
  Fd file{::open(path.c_str(), O_RDONLY | O_CLOEXEC)};
  if (file.fd < 0) fail(path.string(), system_error("cannot open", path.string()));
  struct stat st {};
  if (::fstat(file.fd, &st) != 0) fail(path.string(), system_error("cannot stat", path.string()));
  if (S_ISDIR(st.st_mode)) fail(path.string(), "is a directory, not a checkpoint file");
  std::vector<unsigned char> bytes;
  std::array<unsigned char, 1 << 16> buffer;
  for (;;) {
    const ssize_t got = ::read(file.fd, buffer.data(), buffer.size());
    if (got < 0 && errno == EINTR) continue;
    if (got < 0) fail(path.string(), system_error("cannot read", path.string()));
    if (got == 0) break;
    bytes.insert(bytes.end(), buffer.begin(), buffer.begin() + got);
  }
  return bytes;
}

void write_all(int fd, std::span<const unsigned char> bytes) {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t put = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (put < 0 && errno == EINTR) continue;
    if (put < 0) throw std::system_error(errno, std::generic_category());
    done += static_cast<std::size_t>(put);
  }
}

// Temporary file in the same directory (rename is atomic only within one file system),
// fsync'd before the rename so a crash leaves either the old file or the whole new one.
void write_file_atomically(const std::filesystem::path& path, std::span<const unsigned char> bytes) {
  const std::string target = path.string();
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) fail(target, "cannot write: the path is a directory");
  const std::string temp = target + ".partial";
  Fd file{::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644)};
  if (file.fd < 0) fail(target, system_error("cannot create", temp));
  try {
    write_all(file.fd, bytes);
    if (::fsync(file.fd) != 0) throw std::system_error(errno, std::generic_category());
    const int fd = file.fd;
    file.fd = -1;
    if (::close(fd) != 0) throw std::system_error(errno, std::generic_category());
    if (::rename(temp.c_str(), target.c_str()) != 0) throw std::system_error(errno, std::generic_category());
  } catch (const std::system_error& e) {
    ::unlink(temp.c_str());
    fail(target, std::string("cannot write: ") + std::strerror(e.code().value()));
  }
  // Make the rename itself durable; a directory that cannot be fsync'd is not an error.
  const std::filesystem::path dir = path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  Fd d{::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC)};
  if (d.fd >= 0) ::fsync(d.fd);
}

}  // namespace

std::uint64_t fnv1a64(std::span<const unsigned char> bytes) {
  // Every step, xor with a byte then multiply by an odd prime, is a bijection of the
  // state, so any single changed byte always changes the result.
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (unsigned char b : bytes) {
    h ^= b;
    h *= 0x100000001b3ull;
  }
  return h;
}

template <class Real>
Checkpoint capture_checkpoint(const BasicWorld<Real>& world, std::uint64_t fingerprint) {
  Checkpoint c;
  c.precision = sizeof(Real);
  c.fingerprint = fingerprint;
  c.step_count = world.step_count();
  c.dt = world.def().dt;
  c.gravity = world.def().gravity;
  c.integrator = world.def().integrator;
  for (SheetId id : world.sheets()) {
    const SheetView<Real> v = world.view(id);
    const std::span<const Real> memory = world.integrator_memory(id);
    Checkpoint::SheetRecord& s = c.sheets.emplace_back();
    s.m = v.m;
    s.n = v.n;
    s.x.assign(v.x.begin(), v.x.end());
    s.y.assign(v.y.begin(), v.y.end());
    s.z.assign(v.z.begin(), v.z.end());
    s.vx.assign(v.vx.begin(), v.vx.end());
    s.vy.assign(v.vy.begin(), v.vy.end());
    s.vz.assign(v.vz.begin(), v.vz.end());
    s.integrator_memory.assign(memory.begin(), memory.end());
    const auto stats = world.solver_stats(id);
    s.solver = {stats.iterations, stats.relative_residual, stats.converged, stats.unconverged_solves};
  }
  c.contact_memory = world.contact_memory();
  return c;
}

template <class Real>
void apply_checkpoint(const Checkpoint& c, BasicWorld<Real>& world, const std::string& source) {
  if (c.precision != sizeof(Real))
    fail(source, "holds " + std::to_string(c.precision * 8) + "-bit values, the world uses " +
                     std::to_string(sizeof(Real) * 8) + "-bit ones");
  const std::vector<SheetId> ids = world.sheets();
  if (ids.size() != c.sheets.size())
    fail(source, "holds " + std::to_string(c.sheets.size()) + " sheets, the world has " + std::to_string(ids.size()));
  for (std::size_t k = 0; k < ids.size(); ++k) {
    const SheetView<Real> v = world.view(ids[k]);
    const Checkpoint::SheetRecord& s = c.sheets[k];
    for (const auto* values : {&s.x, &s.y, &s.z, &s.vx, &s.vy, &s.vz})
      if (values->size() != point_count(s.m, s.n))
        fail(source, "sheet " + std::to_string(k) + " holds a state of the wrong size for its grid");
    if (v.m != c.sheets[k].m || v.n != c.sheets[k].n)
      fail(source, "sheet " + std::to_string(k) + " is " + std::to_string(c.sheets[k].m) + "x" +
                       std::to_string(c.sheets[k].n) + " cells, the world's is " + std::to_string(v.m) + "x" +
                       std::to_string(v.n));
  }
  if (!(c.gravity == world.def().gravity)) fail(source, "was written with another gravity than the world's");
  if (!(c.dt > 0) || !std::isfinite(c.dt)) fail(source, "dt must be positive and finite");

  // Convert first (the only step that allocates), then change the world.
  struct Converted {
    std::vector<Real> x, y, z, vx, vy, vz, memory;
  };
  auto narrow = [](const std::vector<double>& from) { return std::vector<Real>(from.begin(), from.end()); };
  std::vector<Converted> converted;
  converted.reserve(c.sheets.size());
  for (const Checkpoint::SheetRecord& s : c.sheets)
    converted.push_back({narrow(s.x), narrow(s.y), narrow(s.z), narrow(s.vx), narrow(s.vy), narrow(s.vz),
                         narrow(s.integrator_memory)});

  // The only setter that can still refuse (it checks the memory against the sheets), so
  // first: a refusal leaves the world untouched.
  try {
    world.set_contact_memory(c.contact_memory);
  } catch (const std::invalid_argument& e) {
    fail(source, e.what());
  }
  world.set_dt(c.dt);
  world.set_integrator(c.integrator);
  world.set_step_count(c.step_count);
  for (std::size_t k = 0; k < ids.size(); ++k) {
    const Converted& s = converted[k];
    world.set_state(ids[k], SheetView<Real>{c.sheets[k].m, c.sheets[k].n, s.x, s.y, s.z, s.vx, s.vy, s.vz});
    world.set_integrator_memory(ids[k], s.memory);
    const World::SolverStats& stats = c.sheets[k].solver;
    world.set_solver_stats(ids[k], {stats.iterations, stats.relative_residual, stats.converged, stats.unconverged_solves});
  }
}

std::vector<unsigned char> encode_checkpoint(const Checkpoint& c) {
  Writer out;
  out.bytes(magic);
  out.u32(checkpoint_format_version);
  out.u32(c.precision);
  out.u64(c.fingerprint);
  out.u64(c.step_count);
  out.f64(c.dt);
  out.f64(c.gravity.x);
  out.f64(c.gravity.y);
  out.f64(c.gravity.z);
  const std::string_view name = integrator_name(c.integrator);
  out.u32(static_cast<std::uint32_t>(name.size()));
  out.bytes({reinterpret_cast<const unsigned char*>(name.data()), name.size()});
  out.u32(static_cast<std::uint32_t>(c.sheets.size()));
  for (const Checkpoint::SheetRecord& s : c.sheets) {
    out.u32(s.m);
    out.u32(s.n);
    out.u64(s.integrator_memory.size());
    for (const auto* values : {&s.x, &s.y, &s.z, &s.vx, &s.vy, &s.vz, &s.integrator_memory})
      for (double v : *values) out.real(v, c.precision);
    out.u64(s.solver.unconverged_solves);
    out.u32(static_cast<std::uint32_t>(s.solver.iterations));
    out.f64(s.solver.relative_residual);
    out.u32(s.solver.converged ? 1 : 0);
  }
  out.u64(c.contact_memory.size());
  for (std::uint64_t word : c.contact_memory) out.u64(word);
  out.u64(fnv1a64(out.out));
  return std::move(out.out);
}

Checkpoint decode_checkpoint(std::span<const unsigned char> bytes, const std::string& source) {
  const std::size_t head = std::min(bytes.size(), magic.size());
  if (!std::equal(bytes.begin(), bytes.begin() + head, magic.begin()))
    fail(source, "not a drape checkpoint (it does not start with \"DRAPECKP\")");
  if (bytes.size() < min_header + checksum_size)
    fail(source, "truncated: " + std::to_string(bytes.size()) + " bytes, shorter than any checkpoint (" +
                     std::to_string(min_header + checksum_size) + ")");
  Reader in(bytes.first(bytes.size() - checksum_size), source);
  in.take(magic.size(), "magic");
  // The version comes before the checksum: another version may lay out even that differently.
  const std::uint32_t version = in.u32("format version");
  if (version < checkpoint_oldest_version || version > checkpoint_format_version)
    fail(source, "format version " + std::to_string(version) + ", this drape reads versions " +
                     std::to_string(checkpoint_oldest_version) + " to " + std::to_string(checkpoint_format_version));
  Reader tail(bytes.last(checksum_size), source);
  if (tail.u64("checksum") != fnv1a64(bytes.first(bytes.size() - checksum_size)))
    fail(source, "checksum mismatch: the file is corrupted or truncated");

  Checkpoint c;
  c.precision = in.u32("precision");
  if (c.precision != 4 && c.precision != 8)
    fail(source, "precision must be 4 or 8 bytes per value (got " + std::to_string(c.precision) + ")");
  c.fingerprint = in.u64("fingerprint");
  c.step_count = in.u64("step count");
  c.dt = in.f64("dt");
  c.gravity.x = in.f64("gravity");
  c.gravity.y = in.f64("gravity");
  c.gravity.z = in.f64("gravity");
  const std::uint32_t name_size = in.u32("integrator name length");
  if (name_size > max_integrator_name) fail(source, "integrator name longer than 64 bytes");
  const auto name_bytes = in.take(name_size, "integrator name");
  const std::string name(name_bytes.begin(), name_bytes.end());
  const std::optional<Integrator> integrator = integrator_from_name(name);
  if (!integrator) fail(source, "unknown integrator \"" + name + "\"");
  c.integrator = *integrator;
  const std::uint32_t sheets = in.u32("sheet count");
  // Each sheet takes at least 16 bytes, so a lying count cannot make us reserve much.
  in.need_items(sheets, 16, "sheets");
  c.sheets.resize(sheets);
  for (Checkpoint::SheetRecord& s : c.sheets) {
    s.m = in.u32("sheet m");
    s.n = in.u32("sheet n");
    if (s.m >= max_grid || s.n >= max_grid) fail(source, "sheet grid size out of range");
    const std::uint64_t points = std::uint64_t(s.m + 1) * std::uint64_t(s.n + 1);
    const std::uint64_t memory = in.u64("integrator memory count");
    for (auto* values : {&s.x, &s.y, &s.z, &s.vx, &s.vy, &s.vz}) read_values(in, c.precision, points, *values, "sheet state");
    read_values(in, c.precision, memory, s.integrator_memory, "integrator memory");
    s.solver.unconverged_solves = in.u64("unconverged solves");
    const std::uint32_t iterations = in.u32("solve iterations");
    if (iterations > std::uint32_t(std::numeric_limits<int>::max())) fail(source, "solve iterations out of range");
    s.solver.iterations = int(iterations);
    s.solver.relative_residual = in.f64("solve residual");
    const std::uint32_t converged = in.u32("solve converged");
    if (converged > 1) fail(source, "solve converged must be 0 or 1");
    s.solver.converged = converged == 1;
  }
  if (version >= 3) {
    const std::uint64_t words = in.u64("contact memory word count");
    in.need_items(words, 8, "contact memory");
    c.contact_memory.resize(words);
    for (std::uint64_t& word : c.contact_memory) word = in.u64("contact memory");
  }
  if (in.remaining() != 0)
    fail(source, std::to_string(in.remaining()) + " unexpected bytes after the last sheet at offset " +
                     std::to_string(in.position()));
  return c;
}

template <class Real>
void save_checkpoint(const BasicWorld<Real>& world, const std::filesystem::path& path, std::uint64_t fingerprint) {
  write_file_atomically(path, encode_checkpoint(capture_checkpoint(world, fingerprint)));
}

template <class Real>
void load_checkpoint(const std::filesystem::path& path, BasicWorld<Real>& world, std::uint64_t fingerprint) {
  const std::vector<unsigned char> bytes = read_file(path);
  const Checkpoint c = decode_checkpoint(bytes, path.string());
  if (fingerprint != 0 && c.fingerprint != fingerprint)
    fail(path.string(), "was written for other definitions (fingerprint " + std::to_string(c.fingerprint) +
                            ", expected " + std::to_string(fingerprint) + "): it belongs to another scene");
  apply_checkpoint(c, world, path.string());
}

template Checkpoint capture_checkpoint<double>(const BasicWorld<double>&, std::uint64_t);
template Checkpoint capture_checkpoint<float>(const BasicWorld<float>&, std::uint64_t);
template void apply_checkpoint<double>(const Checkpoint&, BasicWorld<double>&, const std::string&);
template void apply_checkpoint<float>(const Checkpoint&, BasicWorld<float>&, const std::string&);
template void save_checkpoint<double>(const BasicWorld<double>&, const std::filesystem::path&, std::uint64_t);
template void save_checkpoint<float>(const BasicWorld<float>&, const std::filesystem::path&, std::uint64_t);
template void load_checkpoint<double>(const std::filesystem::path&, BasicWorld<double>&, std::uint64_t);
template void load_checkpoint<float>(const std::filesystem::path&, BasicWorld<float>&, std::uint64_t);

}  // namespace drape
