// Mesh export of one frame: OBJ, PLY and VTK XML (.vtu, plus a .pvd time series), with the
// vertices of every sheet in the paper's row-major order (eqs 2–3) and one quad per grid cell.
// Numbers are written in their shortest exact form, so reading a file back gives the state
// bit for bit. Every file is written to a temporary name and then renamed.
#pragma once

#include <drape/world.h>

#include <filesystem>
#include <functional>
#include <ostream>
#include <span>
#include <string>
#include <vector>

namespace drape::app {

// Writes `file` through a temporary "<file>.tmp" in the same folder, renamed into place only
// after the body finished and the stream flushed. Throws std::runtime_error naming the file.
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

}  // namespace drape::app
