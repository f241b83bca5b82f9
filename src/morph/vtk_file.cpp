// .vtu and legacy .vtk unstructured grids, through VTK's own readers and writers: every point and
// cell data array is kept, and so are the encoding (ASCII, binary, appended, the compressor) and
// the points' data type; only the coordinates change.
#include "child_reader.hpp"
#include "volume_formats.hpp"

#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/io/input_file.hpp"
#include "csrbf/units.hpp"

#include <vtkCellData.h>
#include <SMP/Common/vtkSMPToolsAPI.h>  // vtkSMPTools.h does not compile as C++20 (VTK 9.1)
#include <vtkCellType.h>
#include <vtkCellTypes.h>
#include <vtkCommand.h>
#include <vtkDataArray.h>
#include <vtkDoubleArray.h>
#include <vtkExecutive.h>
#include <vtkNew.h>
#include <vtkLogger.h>
#include <vtkOutputWindow.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkSmartPointer.h>
#include <vtkUnstructuredGrid.h>
#include <vtkUnstructuredGridReader.h>
#include <vtkUnstructuredGridWriter.h>
#include <vtkXMLUnstructuredGridReader.h>
#include <vtkXMLUnstructuredGridWriter.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <set>
#include <string_view>
#include <optional>

namespace fs = std::filesystem;

namespace csrbf::morph::detail {

namespace {

/// In a reader's child process (forked from a parent whose TBB threads the child does not have),
/// VTK's SMP tools must not use TBB: the pool copied from the parent waits for workers that do not
/// exist. vtkUnstructuredGrid::GetCellTypes hung so in Hostile.VtkFilesThatCrashOrLoseCellsAreErrors
/// (one full-suite run in three, when a write in the parent had started VTK's TBB workers).
void sequential_in_child() { vtk::detail::smp::vtkSMPToolsAPI::GetInstance().SetBackend("Sequential"); }

using io::FileError;

/// Collects the errors VTK reports on an algorithm (instead of printing them and going on).
/// What VTK said, for a user: its text is "ERROR: In FILE, line N\nvtkXReader (0x55c7...): WHAT\n\n"
/// (or "Generic Warning: ..."): WHAT's first line, at most 300 characters.
std::string vtk_said(std::string s) {
  const auto nl = s.find('\n');
  if (nl != std::string::npos && s.substr(0, nl).find(", line ") != std::string::npos) s.erase(0, nl + 1);
  const auto addr = s.find(" (0x");
  const auto close = addr == std::string::npos ? std::string::npos : s.find("): ", addr);
  if (close != std::string::npos && s.compare(0, 3, "vtk") == 0 && s.find(' ') == addr) s.erase(0, close + 3);
  s = s.substr(0, s.find('\n'));
  while (!s.empty() && s.back() == ' ') s.pop_back();
  return s.substr(0, 300);
}

class ErrorCatcher : public vtkCommand {
 public:
  static ErrorCatcher* New() { return new ErrorCatcher; }
  void Execute(vtkObject*, unsigned long, void* data) override {
    if (message.empty() && data) message = static_cast<const char*>(data);
  }
  std::string message;
};

/// VTK's readers report some failures only as a warning to the output window, and go on: a legacy
/// file's data array cut short ("Error reading ascii data. Possible mismatch of datasize with
/// declaration.") is read with its missing values uninitialised. While a reader runs, this window
/// keeps the first warning or error, which the read then throws.
class TextCatcher : public vtkOutputWindow {
 public:
  static TextCatcher* New() { return new TextCatcher; }
  void DisplayErrorText(const char* t) override { keep(t); }
  void DisplayWarningText(const char* t) override { keep(t); }
  void DisplayGenericWarningText(const char* t) override { keep(t); }
  std::string message;

 private:
  void keep(const char* t) {
    if (message.empty() && t) message = t;
  }
};

/// Installs a TextCatcher as VTK's output window for its lifetime. VTK also logs every error to
/// stderr itself (vtkLogger, with terminal colour codes and a dump of the failing request: found by
/// the attack on a hostile legacy file); that is switched off for good: what VTK says is caught here
/// and reported as csrbf's own error.
struct CatchVtkText {
  CatchVtkText() : old(vtkOutputWindow::GetInstance()) {
    vtkLogger::SetStderrVerbosity(vtkLogger::VERBOSITY_OFF);
    vtkOutputWindow::SetInstance(window);
  }
  ~CatchVtkText() { vtkOutputWindow::SetInstance(old); }
  CatchVtkText(const CatchVtkText&) = delete;
  CatchVtkText& operator=(const CatchVtkText&) = delete;
  vtkNew<TextCatcher> window;
  vtkSmartPointer<vtkOutputWindow> old;
};

/// The first bytes of a file, to read the encoding VTK does not report.
std::string head_of(const fs::path& p, std::size_t bytes) {
  std::ifstream in(p, std::ios::binary);
  std::string s(bytes, '\0');
  in.read(s.data(), std::streamsize(bytes));
  s.resize(std::size_t(in.gcount()));
  return s;
}

/// A count stated in the file's text (an XML attribute or a legacy keyword line), checked before
/// VTK allocates for it.
void check_count(const std::string& head, const std::string& key, std::size_t bytes_each, double limit,
                 const fs::path& file) {
  for (std::size_t at = head.find(key); at != std::string::npos; at = head.find(key, at + 1)) {
    std::size_t b = at + key.size();
    while (b < head.size() && (head[b] == '"' || head[b] == ' ' || head[b] == '=')) ++b;
    std::uint64_t n = 0;
    const auto r = std::from_chars(head.data() + b, head.data() + head.size(), n);
    if (r.ec == std::errc::result_out_of_range || (r.ec == std::errc() && double(n) * double(bytes_each) > limit))
      throw FileError(file.string() + ": " + key + " " + head.substr(b, std::size_t(r.ptr - head.data()) - b) +
                      " needs more than the " + std::to_string(std::uint64_t(limit)) + "-byte limit; refused");
  }
}

/// The values a .vtu's cell "types" arrays hold in the file (summed over its pieces), read from the
/// array's own length: ASCII tokens, or the byte count in a binary or appended block's header (for a
/// compressed block, its uncompressed size: (blocks - 1) x block size + the last block's size, as
/// vtkXMLDataParser reads it); empty where that cannot be told (an unknown layout). VTK reads only
/// NumberOfCells of them, and a file whose arrays hold more lost the cells past it.
std::optional<std::uint64_t> types_in_file(const std::string& t, bool uint64_headers, bool compressed) {
  const auto attr = [](const std::string& tag, const std::string& key) -> std::string {
    const auto at = tag.find(" " + key + "=\"");
    if (at == std::string::npos) return {};
    const auto b = at + key.size() + 3, e = tag.find('"', b);
    return e == std::string::npos ? std::string() : tag.substr(b, e - b);
  };
  const std::size_t header = uint64_headers ? 8 : 4;
  const auto decode = [](const std::string& text, std::size_t at, std::size_t bytes, std::string& out) {
    static constexpr std::string_view table = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::uint32_t acc = 0;
    int bits = 0;
    for (std::size_t i = at; i < text.size() && out.size() < bytes; ++i) {
      const char c = text[i];
      if (c == ' ' || c == '\n' || c == '\r' || c == '\t') continue;
      const auto v = table.find(c);
      if (v == std::string_view::npos) return false;
      acc = (acc << 6) | std::uint32_t(v);
      bits += 6;
      if (bits >= 8) {
        bits -= 8;
        out.push_back(char((acc >> bits) & 0xff));
      }
    }
    return out.size() == bytes;
  };
  const auto word = [&](const std::string& bytes, std::size_t i) {
    std::uint64_t n = 0;
    for (std::size_t k = 0; k < header; ++k)
      n |= std::uint64_t(static_cast<unsigned char>(bytes[i * header + k])) << (8 * k);
    return n;
  };
  // The data's size in bytes from a block header: one word, or [blocks, block size, last size, ...].
  const std::size_t header_bytes = compressed ? 3 * header : header;
  const auto count_of = [&](const std::string& bytes) -> std::optional<std::uint64_t> {
    if (!compressed) return word(bytes, 0);
    const std::uint64_t blocks = word(bytes, 0), size = word(bytes, 1), last = word(bytes, 2);
    if (blocks == 0) return 0;
    if (size > (std::uint64_t(1) << 40) || blocks > (std::uint64_t(1) << 20) || last > size) return std::nullopt;
    return (blocks - 1) * size + (last == 0 ? size : last);
  };
  std::uint64_t total = 0;
  bool any = false;
  for (std::size_t at = t.find("Name=\"types\""); at != std::string::npos; at = t.find("Name=\"types\"", at + 1)) {
    const auto open = t.rfind("<DataArray", at), close = t.find('>', at);
    if (open == std::string::npos || close == std::string::npos) return std::nullopt;
    const std::string tag = t.substr(open, close - open);
    const std::string type = attr(tag, "type"), format = attr(tag, "format");
    const std::size_t width = type == "UInt8" || type == "Int8"     ? 1
                              : type == "Int32" || type == "UInt32" ? 4
                              : type == "Int64" || type == "UInt64" ? 8
                                                                    : 0;
    if (width == 0) return std::nullopt;
    std::uint64_t values = 0;
    if (format == "ascii") {
      const auto end = t.find("</DataArray>", close);
      if (end == std::string::npos) return std::nullopt;
      bool in = false;
      for (std::size_t i = close + 1; i < end; ++i) {
        const bool space = t[i] == ' ' || t[i] == '\n' || t[i] == '\r' || t[i] == '\t';
        values += !space && !in;
        in = !space;
      }
    } else if (format == "binary") {
      std::string h;
      if (!decode(t, close + 1, header_bytes, h)) return std::nullopt;
      const auto bytes = count_of(h);
      if (!bytes) return std::nullopt;
      values = *bytes / width;
    } else if (format == "appended") {
      const auto data = t.find("<AppendedData");
      if (data == std::string::npos) return std::nullopt;
      const auto tag_end = t.find('>', data), mark = t.find('_', tag_end == std::string::npos ? data : tag_end);
      if (tag_end == std::string::npos || mark == std::string::npos) return std::nullopt;
      const std::string encoding = attr(t.substr(data, tag_end - data), "encoding");
      std::uint64_t offset = 0;
      const std::string off = attr(tag, "offset");
      if (std::from_chars(off.data(), off.data() + off.size(), offset).ec != std::errc()) return std::nullopt;
      std::string h;
      if (encoding == "raw") {
        if (offset > t.size() || mark + 1 + offset + header_bytes > t.size()) return std::nullopt;
        h = t.substr(mark + 1 + offset, header_bytes);
      } else if (!decode(t, mark + 1 + offset, header_bytes, h)) {
        return std::nullopt;
      }
      const auto bytes = count_of(h);
      if (!bytes) return std::nullopt;
      values = *bytes / width;
    } else {
      return std::nullopt;
    }
    total += values;
    any = true;
  }
  return any ? std::optional<std::uint64_t>(total) : std::nullopt;
}

class VtkFile final : public VolumeFile {
 public:
  VtkFile(const fs::path& path, const OpenOptions& o)
      : path_(path), memory_limit_(o.max_file_bytes), xml_(path.extension() == ".vtu") {
    io::check_readable(path, "a VTK unstructured grid");
    std::error_code ec;
    const double size = double(fs::file_size(path, ec));
    if (size > o.max_file_bytes)
      throw FileError(path.string() + ": " + std::to_string(std::uint64_t(size)) + " bytes, more than the limit of " +
                      std::to_string(std::uint64_t(o.max_file_bytes)));
    const std::string head = head_of(path, 1 << 16);
    if (xml_) {
      if (head.find("<VTKFile") == std::string::npos || head.find("UnstructuredGrid") == std::string::npos)
        throw FileError(path.string() + ": not a VTK XML unstructured grid (.vtu)");
      check_count(head, "NumberOfPoints", 24, o.max_file_bytes, path);
      check_count(head, "NumberOfCells", 16, o.max_file_bytes, path);
      appended_ = head.find("format=\"appended\"") != std::string::npos;
      ascii_ = !appended_ && head.find("format=\"binary\"") == std::string::npos;
      uint64_headers_ = head.find("header_type=\"UInt64\"") != std::string::npos;
      for (const char* c : {"vtkZLibDataCompressor", "vtkLZ4DataCompressor", "vtkLZMADataCompressor"})
        if (head.find(c) != std::string::npos) compressor_ = c;
    } else {
      if (head.rfind("# vtk DataFile", 0) != 0)
        throw FileError(path.string() + ": not a legacy VTK file (no '# vtk DataFile' line)");
      if (head.find("UNSTRUCTURED_GRID") == std::string::npos)
        throw FileError(path.string() + ": a legacy VTK file, but not an UNSTRUCTURED_GRID");
      ascii_ = head.find("\nASCII") != std::string::npos;
      legacy_42_ = head.rfind("# vtk DataFile Version 4", 0) == 0 || head.rfind("# vtk DataFile Version 3", 0) == 0 ||
                   head.rfind("# vtk DataFile Version 2", 0) == 0;
      // At least 2 bytes a coordinate in ASCII, 4 in binary; 2 a cell entry.
      check_count(head, "POINTS ", ascii_ ? 6 : 12, std::max(size, 1.0), path);
      check_count(head, "CELLS ", 2, std::max(size, 1.0), path);
      if (const auto at = head.find("CELLS "); at != std::string::npos) {  // CELLS n size: the size too
        std::uint64_t a = 0, b = 0;
        const char* q = head.data() + at + 6;
        const auto r = std::from_chars(q, head.data() + head.size(), a);
        if (r.ec == std::errc() && std::from_chars(r.ptr + 1, head.data() + head.size(), b).ec == std::errc() &&
            double(b) * 2.0 > std::max(size, 1.0) * 4.0)
          throw FileError(path.string() + ": CELLS " + std::to_string(a) + " " + std::to_string(b) +
                          " cannot fit in the " + std::to_string(std::uint64_t(size)) +
                          "-byte file (truncated, or a count that lies)");
      }
    }
    // VTK's readers trust the counts and offsets in the file, and crash (or allocate without
    // bound) on some that lie: they read in a child process, which checks the grid and passes it
    // back as VTK's own XML (trusted, as csrbf made it).
    const bool xml = xml_;
    // A legacy file's stated counts: VTK's reader drops cells it cannot read (a polyhedron without
    // its faces) without an error.
    const auto stated_legacy = [&](const char* key) -> long long {
      const auto at = head.find(std::string("\n") + key);
      if (xml || at == std::string::npos) return -1;
      long long v = -1;
      const char* b = head.data() + at + 1 + std::strlen(key);
      std::from_chars(b, head.data() + head.size(), v);
      return v;
    };
    // Version 5 states the count of cell offsets, one more than the cells.
    const bool offsets = head.rfind("# vtk DataFile Version 5", 0) == 0;
    const long long points_stated = stated_legacy("POINTS "), cells_line = stated_legacy("CELLS "),
                    cells_stated = cells_line - (offsets && cells_line > 0 ? 1 : 0);
    grid_ = parse_grid(detail::read_in_child(path, "VTK", o.max_file_bytes, [&] {
      sequential_in_child();
      auto g = read_grid(path, xml);
      check_cells(g);
      if (g && ((points_stated >= 0 && g->GetNumberOfPoints() != points_stated) ||
                (cells_stated >= 0 && g->GetNumberOfCells() != cells_stated)))
        throw io::FileError("the file states " + std::to_string(points_stated) + " points and " +
                            std::to_string(cells_stated) + " cells, but VTK read " +
                            std::to_string(g->GetNumberOfPoints()) + " and " + std::to_string(g->GetNumberOfCells()) +
                            " (a cell it cannot read, such as a polyhedron without its faces, or a count that "
                            "lies)");
      return serialize_grid(g);
    }));
    if (!grid_ || !grid_->GetPoints() || grid_->GetNumberOfPoints() == 0)
      throw FileError(path.string() + ": no points (empty, truncated or not an unstructured grid)");
    if (xml_) {  // VTK's reader gives what it could read of a truncated file without an error
      const auto stated = [&](const char* key) {
        std::uint64_t total = 0;
        const std::string k = std::string(key) + "=\"";
        for (std::size_t at = head.find(k); at != std::string::npos; at = head.find(k, at + 1)) {
          std::uint64_t v = 0;
          std::from_chars(head.data() + at + k.size(), head.data() + head.size(), v);
          total += v;
        }
        return total;
      };
      if (stated("NumberOfPoints") != std::uint64_t(grid_->GetNumberOfPoints()) ||
          stated("NumberOfCells") != std::uint64_t(grid_->GetNumberOfCells()))
        throw FileError(path.string() + ": the file states " + std::to_string(stated("NumberOfPoints")) +
                        " points and " + std::to_string(stated("NumberOfCells")) + " cells, but holds " +
                        std::to_string(grid_->GetNumberOfPoints()) + " and " +
                        std::to_string(grid_->GetNumberOfCells()) + " (truncated or corrupt)");
      // A NumberOfCells below what the cell arrays hold: VTK reads the stated count, and the cells
      // past it would be gone from the output.
      const auto types = types_in_file(io::read_input(path, "a VTK unstructured grid", o.max_file_bytes),
                                       uint64_headers_, !compressor_.empty());
      if (types && *types != std::uint64_t(grid_->GetNumberOfCells()))
        throw FileError(path.string() + ": NumberOfCells says " + std::to_string(grid_->GetNumberOfCells()) +
                        " cells, but its cell types array holds " + std::to_string(*types) +
                        " (cells would be lost; a count that lies)");
    }
    fill_mesh(o);
  }

  const VolumeMesh& mesh() const override { return mesh_; }
  std::string format() const override { return xml_ ? "vtu" : "vtk"; }
  std::string encoding() const override {
    if (!xml_) return ascii_ ? "ascii" : "binary";
    std::string e = ascii_ ? "ascii" : appended_ ? "appended" : "binary";
    if (!compressor_.empty() && !ascii_) e += ", " + compressor_;
    return e;
  }

  void write_copy(std::span<const Vec3> points, const fs::path& out) const override {
    check_copy_target(path_, out);
    write(points, out);
  }
  void write_in_place(std::span<const Vec3> points) const override { write(points, path_); }
  std::string patch_hint() const override {
    const std::string names = array_names(true);
    return names.empty() ? "; it has no integer point or cell data array" : "; its integer arrays: " + names;
  }

 private:
  /// An array that can name patches: one integer a point or cell.
  static bool names_patches(vtkDataArray* a) {
    return a && a->GetNumberOfComponents() == 1 && a->GetDataType() != VTK_FLOAT && a->GetDataType() != VTK_DOUBLE;
  }
  /// The point and cell data arrays' names, ", "-separated; only those that can name patches.
  std::string array_names(bool patch_arrays_only) const {
    std::string names;
    for (vtkFieldData* d :
         {static_cast<vtkFieldData*>(grid_->GetPointData()), static_cast<vtkFieldData*>(grid_->GetCellData())})
      for (int i = 0; i < d->GetNumberOfArrays(); ++i)
        if (d->GetArrayName(i) && (!patch_arrays_only || names_patches(d->GetArray(i))))
          names += (names.empty() ? "" : ", ") + std::string(d->GetArrayName(i));
    return names;
  }

  /// The grid as VTK's reader gives it; VTK's errors are thrown (in the reading child).
  static vtkSmartPointer<vtkUnstructuredGrid> read_grid(const fs::path& path, bool xml) {
    vtkNew<ErrorCatcher> errors;
    CatchVtkText text;
    vtkSmartPointer<vtkUnstructuredGrid> grid;
    if (xml) {
      vtkNew<vtkXMLUnstructuredGridReader> reader;
      reader->AddObserver(vtkCommand::ErrorEvent, errors);
      reader->GetExecutive()->AddObserver(vtkCommand::ErrorEvent, errors);
      reader->SetFileName(path.c_str());
      reader->Update();
      grid = reader->GetOutput();
    } else {
      vtkNew<vtkUnstructuredGridReader> reader;
      reader->AddObserver(vtkCommand::ErrorEvent, errors);
      reader->GetExecutive()->AddObserver(vtkCommand::ErrorEvent, errors);
      reader->SetFileName(path.c_str());
      reader->ReadAllScalarsOn();
      reader->ReadAllVectorsOn();
      reader->ReadAllNormalsOn();
      reader->ReadAllTensorsOn();
      reader->ReadAllColorScalarsOn();
      reader->ReadAllTCoordsOn();
      reader->ReadAllFieldsOn();
      reader->Update();
      grid = reader->GetOutput();
    }
    if (!errors->message.empty()) throw io::FileError(vtk_said(errors->message));
    if (!text.window->message.empty()) throw io::FileError(vtk_said(text.window->message));
    return grid;
  }

  /// Every cell of a type VTK knows, with the points its type needs (a hexahedron 8, a polyhedron
  /// its faces), naming points that exist; every point and cell data array one tuple a point or
  /// cell. VTK's reader drops or misreads cells that break these, and its writer would then write
  /// a mesh that has lost cells.
  static void check_cells(vtkUnstructuredGrid* g) {
    if (!g || !g->GetPoints()) return;  // reported by the caller
    const vtkIdType n = g->GetNumberOfPoints(), cells = g->GetNumberOfCells();
    for (vtkIdType c = 0; c < cells; ++c) {
      const int type = g->GetCellType(c);
      if (type <= VTK_EMPTY_CELL || type >= VTK_NUMBER_OF_CELL_TYPES ||
          std::string(vtkCellTypes::GetClassNameFromTypeId(type)) == "UnknownClass")
        throw io::FileError("cell " + std::to_string(c) + " has type " + std::to_string(type) +
                            ", which is not a VTK cell type");
      vtkIdType npts = 0;
      const vtkIdType* ids = nullptr;
      g->GetCellPoints(c, npts, ids);
      const int need = fixed_points(type);
      if (need > 0 && npts != need)
        throw io::FileError("cell " + std::to_string(c) + " of type " + std::to_string(type) + " (" +
                            vtkCellTypes::GetClassNameFromTypeId(type) + ") has " + std::to_string(npts) +
                            " points; its type has " + std::to_string(need));
      if (type == VTK_POLYHEDRON) {
        vtkIdType* faces = g->GetFaces(c);
        if (!faces || faces[0] < 4)
          throw io::FileError("cell " + std::to_string(c) + " is a polyhedron (type 42) without its faces");
      }
      for (vtkIdType k = 0; k < npts; ++k)
        if (ids[k] < 0 || ids[k] >= n)
          throw io::FileError("cell " + std::to_string(c) + " uses point " + std::to_string(ids[k]) +
                              ", but there are " + std::to_string(n) + " points (truncated, or a count that lies)");
    }
    for (vtkFieldData* d :
         {static_cast<vtkFieldData*>(g->GetPointData()), static_cast<vtkFieldData*>(g->GetCellData())})
      for (int i = 0; i < d->GetNumberOfArrays(); ++i) {
        vtkAbstractArray* a = d->GetAbstractArray(i);
        const vtkIdType want = d == g->GetPointData() ? n : cells;
        if (a && a->GetNumberOfTuples() != want)
          throw io::FileError(std::string(d == g->GetPointData() ? "point" : "cell") + " data array '" +
                              (a->GetName() ? a->GetName() : "") + "' has " + std::to_string(a->GetNumberOfTuples()) +
                              " values for " + std::to_string(want) + (d == g->GetPointData() ? " points" : " cells"));
      }
  }

  /// The points a cell of a fixed-size linear or quadratic type has; 0 for types of any size.
  static int fixed_points(int type) {
    switch (type) {
      case VTK_VERTEX:
        return 1;
      case VTK_LINE:
        return 2;
      case VTK_TRIANGLE:
        return 3;
      case VTK_PIXEL:
      case VTK_QUAD:
      case VTK_TETRA:
        return 4;
      case VTK_VOXEL:
      case VTK_HEXAHEDRON:
        return 8;
      case VTK_WEDGE:
        return 6;
      case VTK_PYRAMID:
        return 5;
      case VTK_QUADRATIC_EDGE:
        return 3;
      case VTK_QUADRATIC_TRIANGLE:
        return 6;
      case VTK_QUADRATIC_QUAD:
        return 8;
      case VTK_BIQUADRATIC_QUAD:
        return 9;
      case VTK_QUADRATIC_TETRA:
        return 10;
      case VTK_QUADRATIC_HEXAHEDRON:
        return 20;
      case VTK_TRIQUADRATIC_HEXAHEDRON:
        return 27;
      case VTK_QUADRATIC_WEDGE:
        return 15;
      case VTK_QUADRATIC_PYRAMID:
        return 13;
      default:
        return 0;
    }
  }

  /// A grid as VTK's XML, appended raw (exact, and quick to read back).
  static std::string serialize_grid(vtkUnstructuredGrid* g) {
    vtkNew<vtkXMLUnstructuredGridWriter> w;
    w->SetInputData(g);
    w->WriteToOutputStringOn();
    w->SetDataModeToAppended();
    w->EncodeAppendedDataOff();
    w->SetCompressorTypeToNone();
    w->SetHeaderTypeToUInt64();
    if (!w->Write()) throw io::FileError("the grid read could not be passed back");
    return w->GetOutputString();
  }
  static vtkSmartPointer<vtkUnstructuredGrid> parse_grid(const std::string& xml) {
    vtkNew<vtkXMLUnstructuredGridReader> r;
    r->ReadFromInputStringOn();
    r->SetInputString(xml);
    r->Update();
    return r->GetOutput();
  }

  void fill_mesh(const OpenOptions& o) {
    const vtkIdType n = grid_->GetNumberOfPoints();
    mesh_.points.resize(std::size_t(n));
    for (vtkIdType i = 0; i < n; ++i) {
      grid_->GetPoint(i, mesh_.points[std::size_t(i)].data());
      if (!mesh_.points[std::size_t(i)].allFinite())
        throw FileError(path_.string() + ": point " + std::to_string(i) + " has a coordinate that is not finite");
    }
    const vtkIdType cells = grid_->GetNumberOfCells();
    std::vector<std::uint32_t> corners;
    for (vtkIdType c = 0; c < cells; ++c) {
      const int type = grid_->GetCellType(c);
      vtkIdType npts = 0;
      const vtkIdType* ids = nullptr;
      grid_->GetCellPoints(c, npts, ids);
      int keep = 0;
      std::uint8_t as = std::uint8_t(type);
      switch (type) {
        case VTK_TETRA:
          keep = 4;
          break;
        case VTK_QUADRATIC_TETRA:
          keep = 4, as = VTK_TETRA;
          break;
        case VTK_HEXAHEDRON:
          keep = 8;
          break;
        case VTK_QUADRATIC_HEXAHEDRON:
        case VTK_TRIQUADRATIC_HEXAHEDRON:
          keep = 8, as = VTK_HEXAHEDRON;
          break;
        case VTK_WEDGE:
          keep = 6;
          break;
        case VTK_QUADRATIC_WEDGE:
          keep = 6, as = VTK_WEDGE;
          break;
        case VTK_PYRAMID:
          keep = 5;
          break;
        case VTK_QUADRATIC_PYRAMID:
          keep = 5, as = VTK_PYRAMID;
          break;
        case VTK_TRIANGLE:
          keep = 3;
          break;
        case VTK_QUADRATIC_TRIANGLE:
          keep = 3, as = VTK_TRIANGLE;
          break;
        case VTK_QUAD:
          keep = 4;
          break;
        case VTK_QUADRATIC_QUAD:
        case VTK_BIQUADRATIC_QUAD:
          keep = 4, as = VTK_QUAD;
          break;
        default:
          break;  // lines, vertices, polyhedra: moved, not measured
      }
      // Every point index and point count was checked in the reading child (check_cells).
      if (keep == 0) continue;
      corners.assign(ids, ids + keep);
      mesh_.cells.add(as, corners);
    }
    if (o.patch_array.empty()) return;  // no patches: the motion file must name the array
    vtkDataArray* array = grid_->GetPointData()->GetArray(o.patch_array.c_str());
    const bool on_points = array != nullptr;
    if (!array) array = grid_->GetCellData()->GetArray(o.patch_array.c_str());
    if (!array) {
      const std::string names = array_names(false);
      throw FileError(path_.string() + ": no point or cell data array named '" + o.patch_array +
                      "' (the motion file's patch_array); its arrays: " + (names.empty() ? "(none)" : names));
    }
    if (!names_patches(array))
      throw FileError(path_.string() + ": array '" + o.patch_array + "' must be one integer a " +
                      (on_points ? "point" : "cell") + " to name patches");
    std::map<long long, std::set<std::uint32_t>> groups;
    if (on_points) {
      for (vtkIdType i = 0; i < n; ++i) groups[static_cast<long long>(array->GetTuple1(i))].insert(std::uint32_t(i));
    } else {
      for (vtkIdType c = 0; c < cells; ++c) {
        vtkIdType npts = 0;
        const vtkIdType* ids = nullptr;
        grid_->GetCellPoints(c, npts, ids);
        auto& g = groups[static_cast<long long>(array->GetTuple1(c))];
        for (vtkIdType k = 0; k < npts; ++k) g.insert(std::uint32_t(ids[k]));
      }
    }
    for (const auto& [value, pts] : groups) {
      Patch p;
      p.name = std::to_string(value);
      p.points.assign(pts.begin(), pts.end());
      mesh_.patches.push_back(std::move(p));
    }
  }

  void write(std::span<const Vec3> points, const fs::path& target) const {
    // The grid is shared with its reader's output: a shallow copy with new points of the same type.
    vtkNew<vtkUnstructuredGrid> grid;
    grid->ShallowCopy(grid_);
    vtkNew<vtkPoints> pts;
    pts->SetDataType(grid_->GetPoints()->GetDataType());
    pts->SetNumberOfPoints(vtkIdType(points.size()));
    for (std::size_t i = 0; i < points.size(); ++i) pts->SetPoint(vtkIdType(i), points[i].data());
    grid->SetPoints(pts);
    io::write_atomically_via_folder(target, [&](const fs::path& path) {
      vtkNew<ErrorCatcher> errors;
      int ok = 0;
      if (xml_) {
        vtkNew<vtkXMLUnstructuredGridWriter> w;
        w->AddObserver(vtkCommand::ErrorEvent, errors);
        w->SetFileName(path.c_str());
        w->SetInputData(grid);
        if (ascii_)
          w->SetDataModeToAscii();
        else if (appended_)
          w->SetDataModeToAppended();
        else
          w->SetDataModeToBinary();
        if (uint64_headers_) w->SetHeaderTypeToUInt64();
        if (compressor_.empty())
          w->SetCompressorTypeToNone();
        else if (compressor_ == "vtkLZ4DataCompressor")
          w->SetCompressorTypeToLZ4();
        else if (compressor_ == "vtkLZMADataCompressor")
          w->SetCompressorTypeToLZMA();
        else
          w->SetCompressorTypeToZLib();
        ok = w->Write();
      } else {
        vtkNew<vtkUnstructuredGridWriter> w;
        w->AddObserver(vtkCommand::ErrorEvent, errors);
        w->SetFileName(path.c_str());
        w->SetInputData(grid);
        if (ascii_)
          w->SetFileTypeToASCII();
        else
          w->SetFileTypeToBinary();
        if (legacy_42_) w->SetFileVersion(vtkUnstructuredGridWriter::VTK_LEGACY_READER_VERSION_4_2);
        ok = w->Write();
      }
      std::error_code ec;
      if (!ok || !errors->message.empty() || fs::file_size(path, ec) == 0 || ec)
        throw FileError("cannot write '" + target.string() + "': VTK's writer failed" +
                        (errors->message.empty() ? std::string() : ": " + vtk_said(errors->message)));
      // Read back: the file written must hold every point and cell (a writer that drops cells
      // would otherwise go unnoticed).
      const bool xml = xml_;
      const std::string counts = detail::read_in_child(path, "VTK", memory_limit_, [&] {
        sequential_in_child();
        auto g = read_grid(path, xml);
        return std::to_string(g && g->GetPoints() ? g->GetNumberOfPoints() : 0) + " " +
               std::to_string(g ? g->GetNumberOfCells() : 0);
      });
      const std::string want =
          std::to_string(grid->GetNumberOfPoints()) + " " + std::to_string(grid->GetNumberOfCells());
      if (counts != want)
        throw FileError("cannot write '" + target.string() + "': read back, the file written holds " + counts +
                        " points and cells where " + want + " were written; nothing written");
    });
  }

  fs::path path_;
  double memory_limit_ = 4.0 * kGiB;
  bool xml_;
  bool ascii_ = false, appended_ = false, uint64_headers_ = false, legacy_42_ = false;
  std::string compressor_;
  vtkSmartPointer<vtkUnstructuredGrid> grid_;
  VolumeMesh mesh_;
};

}  // namespace

std::unique_ptr<VolumeFile> open_vtk(const fs::path& path, const OpenOptions& o) {
  return std::make_unique<VtkFile>(path, o);
}

}  // namespace csrbf::morph::detail
