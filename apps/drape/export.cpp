// Mesh writers. Shortest round-trip numbers (std::to_chars) make export → import exact.
#include "export.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string_view>
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
    try {
      body(out);
    } catch (...) {  // a body that gives up leaves no temporary file behind
      out.close();
      std::error_code ignored;
      std::filesystem::remove(tmp, ignored);
      throw;
    }
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

namespace {

// Reads the numbers of a frame file, remembering the line for messages.
class Cursor {
 public:
  Cursor(std::string_view text, std::string file) : text_(text), file_(std::move(file)) {}

  bool done() const { return pos_ >= text_.size(); }
  std::size_t line() const { return std::size_t(std::count(text_.begin(), text_.begin() + pos_, '\n')) + 1; }
  [[noreturn]] void fail(const std::string& problem) const {
    throw std::runtime_error(file_ + ":" + std::to_string(line()) + ": " + problem);
  }
  // The rest of the current line (without '\n'); moves to the next line.
  std::string_view next_line() {
    const std::size_t end = std::min(text_.find('\n', pos_), text_.size());
    const std::string_view l = text_.substr(pos_, end - pos_);
    pos_ = std::min(end + 1, text_.size());
    return l;
  }
  std::size_t pos() const { return pos_; }
  void seek(std::size_t pos) { pos_ = pos; }
  std::size_t find(std::string_view what) const { return text_.find(what, pos_); }

  template <class T>
  T number(std::string_view what) {
    while (pos_ < text_.size() && (text_[pos_] == ' ' || text_[pos_] == '\t' || text_[pos_] == '\r' || text_[pos_] == '\n'))
      ++pos_;
    T v{};
    const auto r = std::from_chars(text_.data() + pos_, text_.data() + text_.size(), v);
    if (r.ec != std::errc()) fail("expected " + std::string(what));
    pos_ = std::size_t(r.ptr - text_.data());
    return v;
  }

 private:
  std::string_view text_;
  std::string file_;
  std::size_t pos_ = 0;
};

template <class Real>
void read_point(Cursor& c, FramePoints<Real>& f) {
  f.x.push_back(c.number<Real>("a coordinate"));
  f.y.push_back(c.number<Real>("a coordinate"));
  f.z.push_back(c.number<Real>("a coordinate"));
}

// "v x y z" lines; "o NAME" starts the next sheet; faces and comments are skipped.
template <class Real>
void read_obj(Cursor& c, FramePoints<Real>& f) {
  while (!c.done()) {
    const std::size_t start = c.pos();
    const std::string_view l = c.next_line();
    if (l.rfind("o ", 0) == 0) {
      f.sheet_sizes.push_back(0);
    } else if (l.rfind("v ", 0) == 0) {
      if (f.sheet_sizes.empty()) f.sheet_sizes.push_back(0);
      c.seek(start + 2);
      read_point(c, f);
      ++f.sheet_sizes.back();
      c.next_line();
    }
  }
}

// ASCII PLY: "element vertex N" in the header, then N lines "x y z".
template <class Real>
void read_ply(Cursor& c, FramePoints<Real>& f) {
  if (c.next_line() != "ply") c.fail("not a PLY file (no \"ply\" first line)");
  std::uint64_t vertices = 0;
  bool has_vertices = false;
  for (;;) {
    if (c.done()) c.fail("no end_header");
    const std::string_view l = c.next_line();
    if (l == "end_header") break;
    if (l.rfind("format ", 0) == 0 && l != "format ascii 1.0") c.fail("only ASCII PLY is read");
    if (l.rfind("element vertex ", 0) == 0) {
      const auto r = std::from_chars(l.data() + 15, l.data() + l.size(), vertices);
      if (r.ec != std::errc()) c.fail("bad vertex count");
      has_vertices = true;
    }
  }
  if (!has_vertices) c.fail("no \"element vertex\" in the header");
  for (std::uint64_t p = 0; p < vertices; ++p) read_point(c, f);
}

// VTK XML: per <Piece NumberOfPoints="N">, the first DataArray after <Points> holds 3N numbers.
template <class Real>
void read_vtu(Cursor& c, FramePoints<Real>& f) {
  const std::string_view piece = "<Piece NumberOfPoints=\"";
  for (std::size_t at = c.find(piece); at != std::string_view::npos; at = c.find(piece)) {
    c.seek(at + piece.size());
    const auto points = c.number<std::uint64_t>("NumberOfPoints");
    const std::size_t array = c.find("<Points>");
    if (array == std::string_view::npos) c.fail("a Piece without <Points>");
    c.seek(array);
    const std::size_t data = c.find("<DataArray");
    if (data == std::string_view::npos) c.fail("<Points> without a DataArray");
    c.seek(data);
    const std::size_t open_end = c.find(">");
    if (open_end == std::string_view::npos) c.fail("unfinished DataArray tag");
    c.seek(open_end + 1);
    for (std::uint64_t p = 0; p < points; ++p) read_point(c, f);
    f.sheet_sizes.push_back(points);
  }
  if (f.sheet_sizes.empty()) c.fail("no <Piece> with points");
  if (c.find("</VTKFile>") == std::string_view::npos) c.fail("incomplete file (no </VTKFile> after the pieces)");
}

}  // namespace

template <class Real>
FramePoints<Real> parse_frame(std::string_view text, std::string_view extension, const std::string& file) {
  Cursor c(text, file);
  FramePoints<Real> f;
  if (extension == ".obj")
    read_obj(c, f);
  else if (extension == ".ply")
    read_ply(c, f);
  else if (extension == ".vtu")
    read_vtu(c, f);
  else
    throw std::runtime_error(file + ": unknown frame format (expected .obj, .ply or .vtu)");
  return f;
}

template <class Real>
FramePoints<Real> read_frame(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error(file.string() + ": cannot read the file");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_frame<Real>(text.str(), file.extension().string(), file.string());
}

template FramePoints<double> parse_frame<double>(std::string_view, std::string_view, const std::string&);
template FramePoints<float> parse_frame<float>(std::string_view, std::string_view, const std::string&);
template FramePoints<double> read_frame<double>(const std::filesystem::path&);
template FramePoints<float> read_frame<float>(const std::filesystem::path&);

template void write_obj<double>(std::ostream&, std::span<const SheetView<double>>, std::span<const std::string>);
template void write_obj<float>(std::ostream&, std::span<const SheetView<float>>, std::span<const std::string>);
template void write_ply<double>(std::ostream&, std::span<const SheetView<double>>);
template void write_ply<float>(std::ostream&, std::span<const SheetView<float>>);
template void write_vtu<double>(std::ostream&, std::span<const SheetView<double>>);
template void write_vtu<float>(std::ostream&, std::span<const SheetView<float>>);

}  // namespace drape::app
