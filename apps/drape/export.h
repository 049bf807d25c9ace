// Mesh export of one frame: OBJ, PLY and VTK XML (.vtu, plus a .pvd time series), with the
// vertices of every sheet in the paper's row-major order (eqs 2–3) and one quad per grid cell.
// Numbers are written in their shortest exact form, so reading a file back gives the state
// bit for bit. Every file is written to a temporary name and then renamed.
#pragma once

#include <drape/world.h>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <ostream>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace drape::app {

// Writes `file` through a temporary "<file>.tmp" in the same folder, renamed into place only
// after the body finished and the stream flushed. Throws std::runtime_error naming the file;
// an exception from the body passes through, and no temporary file is left either way.
void write_atomically(const std::filesystem::path& file, const std::function<void(std::ostream&)>& body);

template <class Real>
void write_obj(std::ostream& out, std::span<const SheetView<Real>> sheets, std::span<const std::string> names);
template <class Real>
void write_ply(std::ostream& out, std::span<const SheetView<Real>> sheets);
template <class Real>
void write_vtu(std::ostream& out, std::span<const SheetView<Real>> sheets);

struct PvdEntry {
  double time;       // s
  std::string file;  // relative to the .pvd
};
void write_pvd(std::ostream& out, std::span<const PvdEntry> entries);

// The points of one frame file (.obj, .ply or .vtu, as written above), read back exactly: a
// number parsed as Real gives the value that was written. Sheets one after another.
template <class Real>
struct FramePoints {
  std::vector<Real> x, y, z;
  // Points per sheet where the file says (OBJ objects, VTU pieces); empty for PLY, which
  // holds all sheets as one vertex list.
  std::vector<std::uint64_t> sheet_sizes;
};

// Reads a frame file chosen by its extension. Throws std::runtime_error naming the file (and
// the line for OBJ and PLY) and the problem.
template <class Real>
FramePoints<Real> read_frame(const std::filesystem::path& file);
// The same from the file's text; `extension` (".obj", ".ply", ".vtu") picks the format and
// `file` names the source in messages.
template <class Real>
FramePoints<Real> parse_frame(std::string_view text, std::string_view extension, const std::string& file);

}  // namespace drape::app
