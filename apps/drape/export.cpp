// Mesh writers. Shortest round-trip numbers (std::to_chars) make export → import exact.
#include "export.h"

#include <cerrno>
#include <charconv>
#include <fstream>
#include <stdexcept>
#include <system_error>

namespace drape::app {

namespace {

template <class Real>
void put(std::ostream& out, Real v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.write(buf, r.ptr - buf);
}

template <class Real>
void put_point(std::ostream& out, const SheetView<Real>& s, std::size_t p) {
  put(out, s.x[p]);
  out << ' ';
  put(out, s.y[p]);
  out << ' ';
  put(out, s.z[p]);
}

// The quad of grid cell (i, j), counter-clockwise seen from the sheet's +z side.
template <class F>
void for_each_quad(std::uint32_t m, std::uint32_t n, std::uint64_t base, F emit) {
  const std::uint64_t cols = n + 1;
  for (std::uint64_t i = 0; i < m; ++i)
    for (std::uint64_t j = 0; j < n; ++j) {
      const std::uint64_t a = base + i * cols + j;
      emit(a, a + 1, a + cols + 1, a + cols);
    }
}

template <class Real>
const char* vtk_type() {
  return sizeof(Real) == 4 ? "Float32" : "Float64";
}

}  // namespace

void write_atomically(const std::filesystem::path& file, const std::function<void(std::ostream&)>& body) {
  std::filesystem::path tmp = file;
  tmp += ".tmp";
  // errno of the failing call names the cause (no space left, read-only file system, ...)
  auto reason = [] { return std::error_code(errno, std::generic_category()).message(); };
  {
    errno = 0;
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error("cannot create " + tmp.string() + ": " + reason());
    body(out);
    out.flush();
    if (!out) {
      const std::string why = reason();
      std::error_code ignored;
      std::filesystem::remove(tmp, ignored);
      throw std::runtime_error("cannot write " + tmp.string() + ": " + why);
    }
    out.close();  // the last buffered bytes reach the file system here
    if (out.fail()) {
      const std::string why = reason();
      std::error_code ignored;
      std::filesystem::remove(tmp, ignored);
      throw std::runtime_error("cannot write " + tmp.string() + ": " + why);
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, file, ec);
  if (ec) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw std::runtime_error("cannot rename " + tmp.string() + " to " + file.string() + ": " + ec.message());
  }
}

template <class Real>
void write_obj(std::ostream& out, std::span<const SheetView<Real>> sheets, std::span<const std::string> names) {
  out << "# drape frame: one object per sheet, vertices row-major (point (i, j) = i*(n+1)+j), quad faces\n";
  std::uint64_t base = 1;  // OBJ indices start at 1
  for (std::size_t k = 0; k < sheets.size(); ++k) {
    const auto& s = sheets[k];
    out << "o " << (k < names.size() ? names[k] : "sheet" + std::to_string(k)) << '\n';
    for (std::size_t p = 0; p < s.size(); ++p) {
      out << "v ";
      put_point(out, s, p);
      out << '\n';
    }
    for_each_quad(s.m, s.n, base, [&](auto a, auto b, auto c, auto d) {
      out << "f " << a << ' ' << b << ' ' << c << ' ' << d << '\n';
    });
    base += s.size();
  }
}

template <class Real>
void write_ply(std::ostream& out, std::span<const SheetView<Real>> sheets) {
  std::uint64_t vertices = 0, faces = 0;
  for (const auto& s : sheets) {
    vertices += s.size();
    faces += std::uint64_t(s.m) * s.n;
  }
  const char* type = sizeof(Real) == 4 ? "float" : "double";
  out << "ply\nformat ascii 1.0\ncomment drape frame: sheets one after another, vertices row-major\n"
      << "element vertex " << vertices << "\nproperty " << type << " x\nproperty " << type << " y\nproperty " << type
      << " z\nelement face " << faces << "\nproperty list uchar uint vertex_indices\nend_header\n";
  for (const auto& s : sheets)
    for (std::size_t p = 0; p < s.size(); ++p) {
      put_point(out, s, p);
      out << '\n';
    }
  std::uint64_t base = 0;
  for (const auto& s : sheets) {
    for_each_quad(s.m, s.n, base, [&](auto a, auto b, auto c, auto d) {
      out << "4 " << a << ' ' << b << ' ' << c << ' ' << d << '\n';
    });
    base += s.size();
  }
}

template <class Real>
void write_vtu(std::ostream& out, std::span<const SheetView<Real>> sheets) {
  out << "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
         "<UnstructuredGrid>\n";
  for (const auto& s : sheets) {  // one piece per sheet
    const std::uint64_t cells = std::uint64_t(s.m) * s.n;
    out << "<Piece NumberOfPoints=\"" << s.size() << "\" NumberOfCells=\"" << cells << "\">\n<Points>\n"
        << "<DataArray type=\"" << vtk_type<Real>() << "\" NumberOfComponents=\"3\" format=\"ascii\">\n";
    for (std::size_t p = 0; p < s.size(); ++p) {
      put_point(out, s, p);
      out << '\n';
    }
    out << "</DataArray>\n</Points>\n<PointData Vectors=\"velocity\">\n<DataArray type=\"" << vtk_type<Real>()
        << "\" Name=\"velocity\" NumberOfComponents=\"3\" format=\"ascii\">\n";
    for (std::size_t p = 0; p < s.size(); ++p) {
      put(out, s.vx[p]);
      out << ' ';
      put(out, s.vy[p]);
      out << ' ';
      put(out, s.vz[p]);
      out << '\n';
    }
    out << "</DataArray>\n</PointData>\n<Cells>\n<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n";
    for_each_quad(s.m, s.n, 0, [&](auto a, auto b, auto c, auto d) { out << a << ' ' << b << ' ' << c << ' ' << d << '\n'; });
    out << "</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n";
    for (std::uint64_t c = 1; c <= cells; ++c) out << 4 * c << '\n';
    out << "</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
    for (std::uint64_t c = 0; c < cells; ++c) out << "9\n";  // VTK_QUAD
    out << "</DataArray>\n</Cells>\n</Piece>\n";
  }
  out << "</UnstructuredGrid>\n</VTKFile>\n";
}

void write_pvd(std::ostream& out, std::span<const PvdEntry> entries) {
  out << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n";
  for (const auto& e : entries) {
    out << "<DataSet timestep=\"";
    put(out, e.time);
    out << "\" part=\"0\" file=\"" << e.file << "\"/>\n";
  }
  out << "</Collection>\n</VTKFile>\n";
}

template void write_obj<double>(std::ostream&, std::span<const SheetView<double>>, std::span<const std::string>);
template void write_obj<float>(std::ostream&, std::span<const SheetView<float>>, std::span<const std::string>);
template void write_ply<double>(std::ostream&, std::span<const SheetView<double>>);
template void write_ply<float>(std::ostream&, std::span<const SheetView<float>>);
template void write_vtu<double>(std::ostream&, std::span<const SheetView<double>>);
template void write_vtu<float>(std::ostream&, std::span<const SheetView<float>>);

}  // namespace drape::app
