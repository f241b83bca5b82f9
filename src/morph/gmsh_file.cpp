// Gmsh .msh 2.2 and 4.1, ASCII or binary, read through Gmsh's library (libgmsh): physical groups
// are the patches, node tags the point numbers. The output is the input with the coordinates of
// its $Nodes section replaced, every other byte kept (version, encoding, numbering, elements).
#include "child_reader.hpp"
#include "volume_formats.hpp"

#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/io/input_file.hpp"
#include "csrbf/morph/quality.hpp"

#include <dlfcn.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>
#include <vtkCellType.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <set>
#include <type_traits>
#include <unordered_map>

namespace fs = std::filesystem;

namespace csrbf::morph::detail {

namespace {

using io::FileError;

/// Gmsh's library, opened on first use (dlopen) through its C API: linked, its start-up (OpenCASCADE's
/// static initialisers) cost every csrbf command 0.17 s. The calls mirror the C++ API's and throw
/// its error text as a std::string, as it does.
namespace gm {

struct Api {
  void* lib = nullptr;
  void (*free_)(void*) = nullptr;
  void (*initialize)(int, char**, const int, int*) = nullptr;
  void (*option_set_number)(const char*, const double, int*) = nullptr;
  void (*clear_)(int*) = nullptr;
  void (*open_)(const char*, int*) = nullptr;
  void (*get_nodes)(size_t**, size_t*, double**, size_t*, double**, size_t*, const int, const int, const int, const int,
                    int*) = nullptr;
  void (*get_elements)(int**, size_t*, size_t***, size_t**, size_t*, size_t***, size_t**, size_t*, const int, const int,
                       int*) = nullptr;
  void (*get_element_properties)(const int, char**, int*, int*, int*, double**, size_t*, int*, int*) = nullptr;
  void (*get_physical_groups)(int**, size_t*, const int, int*) = nullptr;
  void (*get_physical_name)(const int, const int, char**, int*) = nullptr;
  void (*get_entities_for_physical_group)(const int, const int, int**, size_t*, int*) = nullptr;
  void (*last_error)(char**, int*) = nullptr;
};

const Api& api() {
  static const Api a = [] {
    Api x;
    for (const char* name : {CSRBF_GMSH_LIBRARY, "libgmsh.so.4.8", "libgmsh.so"}) {
      x.lib = ::dlopen(name, RTLD_NOW | RTLD_LOCAL);
      if (x.lib) break;
    }
    if (!x.lib) throw io::FileError(std::string("cannot load Gmsh's library (" CSRBF_GMSH_LIBRARY "): ") + ::dlerror());
    const auto get = [&](auto& f, const char* symbol) {
      f = reinterpret_cast<std::remove_reference_t<decltype(f)>>(::dlsym(x.lib, symbol));
      if (!f) throw io::FileError(std::string("Gmsh's library has no ") + symbol);
    };
    get(x.free_, "gmshFree");
    get(x.initialize, "gmshInitialize");
    get(x.option_set_number, "gmshOptionSetNumber");
    get(x.clear_, "gmshClear");
    get(x.open_, "gmshOpen");
    get(x.get_nodes, "gmshModelMeshGetNodes");
    get(x.get_elements, "gmshModelMeshGetElements");
    get(x.get_element_properties, "gmshModelMeshGetElementProperties");
    get(x.get_physical_groups, "gmshModelGetPhysicalGroups");
    get(x.get_physical_name, "gmshModelGetPhysicalName");
    get(x.get_entities_for_physical_group, "gmshModelGetEntitiesForPhysicalGroup");
    get(x.last_error, "gmshLoggerGetLastError");
    return x;
  }();
  return a;
}

void check(int ierr) {
  if (!ierr) return;
  char* e = nullptr;
  int ie = 0;
  api().last_error(&e, &ie);
  std::string text = e ? e : "error " + std::to_string(ierr);
  if (e) api().free_(e);
  throw text;
}

template <class T>
std::vector<T> take(T* p, size_t n) {
  std::vector<T> v(p, p + n);
  if (p) api().free_(p);
  return v;
}

void initialize() {
  int ierr = 0;
  api().initialize(0, nullptr, 0, &ierr);
  check(ierr);
}
void set_number(const char* name, double v) {
  int ierr = 0;
  api().option_set_number(name, v, &ierr);
  check(ierr);
}
void clear() {
  int ierr = 0;
  api().clear_(&ierr);
  check(ierr);
}
void open(const std::string& file) {
  int ierr = 0;
  api().open_(file.c_str(), &ierr);
  check(ierr);
}
void get_nodes(std::vector<std::size_t>& tags, std::vector<double>& coord, int dim, int tag, bool boundary) {
  size_t *t = nullptr, nt = 0, nc = 0, np = 0;
  double *c = nullptr, *p = nullptr;
  int ierr = 0;
  api().get_nodes(&t, &nt, &c, &nc, &p, &np, dim, tag, boundary, 0, &ierr);
  tags = take(t, nt);
  coord = take(c, nc);
  take(p, np);
  check(ierr);
}
void get_elements(std::vector<int>& types, std::vector<std::vector<std::size_t>>& elements,
                  std::vector<std::vector<std::size_t>>& nodes, int dim = -1, int tag = -1) {
  int* ty = nullptr;
  size_t nty = 0, **et = nullptr, *etn = nullptr, etnn = 0, **nt = nullptr, *ntn = nullptr, ntnn = 0;
  int ierr = 0;
  api().get_elements(&ty, &nty, &et, &etn, &etnn, &nt, &ntn, &ntnn, dim, tag, &ierr);
  types = take(ty, nty);
  elements.clear();
  nodes.clear();
  for (size_t i = 0; i < etnn; ++i) elements.push_back(take(et[i], etn[i]));
  for (size_t i = 0; i < ntnn; ++i) nodes.push_back(take(nt[i], ntn[i]));
  take(et, etnn);
  take(etn, etnn);
  take(nt, ntnn);
  take(ntn, ntnn);
  check(ierr);
}
void get_element_properties(int type, std::string& name, int& nodes, int& primary) {
  char* n = nullptr;
  int dim = 0, order = 0, ierr = 0;
  double* local = nullptr;
  size_t nl = 0;
  api().get_element_properties(type, &n, &dim, &order, &nodes, &local, &nl, &primary, &ierr);
  name = n ? n : "";
  if (n) api().free_(n);
  take(local, nl);
  check(ierr);
}
std::vector<std::pair<int, int>> get_physical_groups() {
  int* dt = nullptr;
  size_t n = 0;
  int ierr = 0;
  api().get_physical_groups(&dt, &n, -1, &ierr);
  const auto v = take(dt, n);
  check(ierr);
  std::vector<std::pair<int, int>> out;
  for (size_t i = 0; i + 1 < v.size(); i += 2) out.emplace_back(v[i], v[i + 1]);
  return out;
}
std::string get_physical_name(int dim, int tag) {
  char* n = nullptr;
  int ierr = 0;
  api().get_physical_name(dim, tag, &n, &ierr);
  std::string s = n ? n : "";
  if (n) api().free_(n);
  check(ierr);
  return s;
}
std::vector<int> get_entities_for_physical_group(int dim, int tag) {
  int* t = nullptr;
  size_t n = 0;
  int ierr = 0;
  api().get_entities_for_physical_group(dim, tag, &t, &n, &ierr);
  auto v = take(t, n);
  check(ierr);
  return v;
}

}  // namespace gm

void start_gmsh() {
  static bool started = false;
  if (started) return;
  gm::initialize();
  gm::set_number("General.Terminal", 0);
  gm::set_number("General.Verbosity", 0);
  started = true;
}

struct Header {
  double version = 0;
  bool binary = false;
};

/// $MeshFormat, and the node and element counts checked against the file's size before Gmsh
/// allocates for them (each node takes at least 8 bytes in ASCII, 24 in binary).
Header check_header(const fs::path& path, double max_bytes) {
  std::ifstream in(path, std::ios::binary);
  std::string head(1 << 16, '\0');
  in.read(head.data(), std::streamsize(head.size()));
  head.resize(std::size_t(in.gcount()));
  std::error_code ec;
  const double size = double(fs::file_size(path, ec));
  if (size > max_bytes)
    throw FileError(path.string() + ": " + std::to_string(std::uint64_t(size)) + " bytes, more than the limit of " +
                    std::to_string(std::uint64_t(max_bytes)));
  if (head.rfind("$MeshFormat", 0) != 0)
    throw FileError(path.string() + ": not a Gmsh mesh (no $MeshFormat at the start)");
  Header h;
  const char* p = head.data() + std::strlen("$MeshFormat");
  while (*p == '\n' || *p == '\r') ++p;
  const auto r = std::from_chars(p, head.data() + head.size(), h.version);
  if (r.ec != std::errc()) throw FileError(path.string() + ": $MeshFormat: no version number");
  if (h.version < 2.0 || h.version >= 5.0 || (h.version >= 3.0 && h.version < 4.0))
    throw FileError(path.string() + ": Gmsh format " + std::to_string(h.version) + ": csrbf reads 2.2 and 4.1");
  int file_type = 0;
  std::from_chars(r.ptr + 1, head.data() + head.size(), file_type);
  h.binary = file_type == 1;
  // Every section the mesh needs must end: Gmsh's reader takes a file cut short for a smaller mesh.
  {
    std::ifstream whole(path, std::ios::binary);
    std::string chunk(1 << 20, '\0'), carry;
    bool nodes = false, elements = false;
    while (whole) {
      whole.read(chunk.data(), std::streamsize(chunk.size()));
      const std::string part = carry + chunk.substr(0, std::size_t(whole.gcount()));
      nodes |= part.find("\n$EndNodes") != std::string::npos;
      elements |= part.find("\n$EndElements") != std::string::npos;
      carry = part.size() > 16 ? part.substr(part.size() - 16) : part;
    }
    if (!nodes || !elements)
      throw FileError(path.string() + ": no " + (nodes ? "$EndElements" : "$EndNodes") + " (truncated?)");
  }
  const auto at = head.find("$Nodes");
  if (at != std::string::npos) {
    const char* q = head.data() + at + 6;
    while (*q == '\n' || *q == '\r') ++q;
    std::uint64_t nodes = 0;
    if (h.version >= 4.0 && h.binary) {
      if (std::size_t(q - head.data()) + 32 <= head.size()) std::memcpy(&nodes, q + 8, 8);
    } else {
      std::uint64_t blocks = 0;
      const auto rr = std::from_chars(q, head.data() + head.size(), h.version >= 4.0 ? blocks : nodes);
      if (h.version >= 4.0 && rr.ec == std::errc()) std::from_chars(rr.ptr + 1, head.data() + head.size(), nodes);
    }
    if (double(nodes) * (h.binary ? 24.0 : 8.0) > size)
      throw FileError(path.string() + ": $Nodes says " + std::to_string(nodes) + " nodes, more than the " +
                      std::to_string(std::uint64_t(size)) + "-byte file can hold (truncated, or a count that lies)");
  }
  return h;
}

std::uint8_t vtk_type(const std::string& name) {
  if (name.rfind("Tetrahedron", 0) == 0) return VTK_TETRA;
  if (name.rfind("Hexahedron", 0) == 0) return VTK_HEXAHEDRON;
  if (name.rfind("Prism", 0) == 0) return VTK_WEDGE;
  if (name.rfind("Pyramid", 0) == 0) return VTK_PYRAMID;
  if (name.rfind("Triangle", 0) == 0) return VTK_TRIANGLE;
  if (name.rfind("Quadrilateral", 0) == 0) return VTK_QUAD;
  return 0;
}

class GmshFile final : public VolumeFile {
 public:
  GmshFile(const fs::path& path, const OpenOptions& o) : path_(path) {
    io::check_readable(path, "a Gmsh mesh");
    header_ = check_header(path, o.max_file_bytes);
    read_in_child(o.max_file_bytes);
    for (std::size_t i = 0; i < mesh_.point_ids.size(); ++i) index_.emplace(mesh_.point_ids[i], std::uint32_t(i));
  }

  const VolumeMesh& mesh() const override { return mesh_; }
  std::string format() const override { return "msh"; }
  std::string encoding() const override {
    return std::string("msh ") + (header_.version >= 4.0 ? "4.1" : "2.2") + (header_.binary ? " binary" : " ascii");
  }
  void write_copy(std::span<const Vec3> points, const fs::path& out) const override {
    check_copy_target(path_, out);
    write(points, out);
  }
  void write_in_place(std::span<const Vec3> points) const override { write(points, path_); }

 private:
  void read() {
    std::vector<std::size_t> tags;
    std::vector<double> coord;
    gm::get_nodes(tags, coord, -1, -1, false);
    if (tags.empty()) throw FileError(path_.string() + ": no nodes");
    auto& index = index_;
    index.reserve(tags.size());
    mesh_.points.resize(tags.size());
    mesh_.point_ids.resize(tags.size());
    for (std::size_t i = 0; i < tags.size(); ++i) {
      mesh_.points[i] = Vec3(coord[3 * i], coord[3 * i + 1], coord[3 * i + 2]);
      mesh_.point_ids[i] = tags[i];
      if (!index.emplace(tags[i], std::uint32_t(i)).second)
        throw FileError(path_.string() + ": node " + std::to_string(tags[i]) + " is defined twice");
    }
    std::vector<int> types;
    std::vector<std::vector<std::size_t>> element_tags, node_tags;
    gm::get_elements(types, element_tags, node_tags);
    std::vector<std::uint32_t> corners;
    for (std::size_t t = 0; t < types.size(); ++t) {
      std::string name;
      int nodes = 0, primary = 0;
      gm::get_element_properties(types[t], name, nodes, primary);
      const std::uint8_t vt = vtk_type(name);
      if (!vt) continue;  // points and lines: moved, not measured
      for (std::size_t e = 0; e < element_tags[t].size(); ++e) {
        corners.clear();
        for (int k = 0; k < primary; ++k) {
          const auto it = index.find(node_tags[t][e * std::size_t(nodes) + std::size_t(k)]);
          if (it == index.end())
            throw FileError(path_.string() + ": element " + std::to_string(element_tags[t][e]) + " uses node " +
                            std::to_string(node_tags[t][e * std::size_t(nodes) + std::size_t(k)]) +
                            ", which is not defined");
          corners.push_back(it->second);
        }
        mesh_.cells.add(vt, corners);
      }
    }
    orient_cells(mesh_.cells, mesh_.points);
    for (const auto& [dim, tag] : gm::get_physical_groups()) {
      Patch p;
      p.name = gm::get_physical_name(dim, tag);
      if (p.name.empty()) p.name = std::to_string(tag);
      p.type = "dim " + std::to_string(dim);
      std::set<std::uint32_t> pts;
      // The nodes of the group's elements (a 2.2 file gives Gmsh no topology, so the nodes
      // classified on an entity's boundary are not found from the entity).
      for (const int entity : gm::get_entities_for_physical_group(dim, tag)) {
        std::vector<int> ts;
        std::vector<std::vector<std::size_t>> et, nt;
        gm::get_elements(ts, et, nt, dim, entity);
        for (const auto& block : nt)
          for (const auto n : block) pts.insert(index.at(n));
        std::vector<std::size_t> own;
        std::vector<double> c;
        gm::get_nodes(own, c, dim, entity, true);
        for (const auto n : own) pts.insert(index.at(n));
      }
      p.points.assign(pts.begin(), pts.end());
      // Two groups of other dimensions may share a name: the points join under it.
      bool merged = false;
      for (auto& q : mesh_.patches)
        if (q.name == p.name) {
          std::set<std::uint32_t> all(q.points.begin(), q.points.end());
          all.insert(p.points.begin(), p.points.end());
          q.points.assign(all.begin(), all.end());
          merged = true;
        }
      if (!merged) mesh_.patches.push_back(std::move(p));
    }
  }

  /// Gmsh's library crashes on some corrupt files (a node count one short, a node tag past the
  /// nodes). It reads in a child process (child_reader.hpp), which sends the mesh back: a crash is
  /// then an error naming the file, never csrbf's own crash.
  void read_in_child(double max_bytes) {
    const std::string reply = detail::read_in_child(path_, "Gmsh", max_bytes, [&] {
      start_gmsh();
      gm::clear();
      gm::open(path_.string());
      read();
      return serialize();
    });
    deserialize(reply);
  }

  template <class T>
  static void put(std::string& s, const T& v) {
    s.append(reinterpret_cast<const char*>(&v), sizeof v);
  }
  template <class T>
  static void put_vector(std::string& s, const std::vector<T>& v) {
    put(s, std::uint64_t(v.size()));
    s.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  }
  std::string serialize() const {
    std::string s;
    put_vector(s, mesh_.points);
    put_vector(s, mesh_.point_ids);
    put_vector(s, mesh_.cells.type);
    put_vector(s, mesh_.cells.start);
    put_vector(s, mesh_.cells.points);
    put(s, std::uint64_t(mesh_.patches.size()));
    for (const Patch& p : mesh_.patches) {
      put_vector(s, std::vector<char>(p.name.begin(), p.name.end()));
      put_vector(s, std::vector<char>(p.type.begin(), p.type.end()));
      put_vector(s, p.points);
    }
    return s;
  }
  void deserialize(std::string_view s) {
    std::size_t at = 0;
    const auto get_u64 = [&] {
      if (at + 8 > s.size()) throw FileError(path_.string() + ": Gmsh's reader sent a short reply");
      std::uint64_t v;
      std::memcpy(&v, s.data() + at, 8);
      at += 8;
      return v;
    };
    const auto get = [&](auto& v) {
      using T = typename std::remove_reference_t<decltype(v)>::value_type;
      const std::uint64_t n = get_u64();
      if (n > (s.size() - at) / sizeof(T)) throw FileError(path_.string() + ": Gmsh's reader sent a short reply");
      v.resize(n);
      std::memcpy(static_cast<void*>(v.data()), s.data() + at, n * sizeof(T));
      at += n * sizeof(T);
    };
    get(mesh_.points);
    get(mesh_.point_ids);
    get(mesh_.cells.type);
    get(mesh_.cells.start);
    get(mesh_.cells.points);
    const std::uint64_t patches = get_u64();
    for (std::uint64_t k = 0; k < patches; ++k) {
      Patch p;
      std::vector<char> name, type;
      get(name);
      get(type);
      get(p.points);
      p.name.assign(name.begin(), name.end());
      p.type.assign(type.begin(), type.end());
      mesh_.patches.push_back(std::move(p));
    }
    // A group of one dimension below the mesh's (surfaces of a volume mesh) is a boundary.
    bool solid = false;
    for (const auto t : mesh_.cells.type)
      solid |= t == VTK_TETRA || t == VTK_HEXAHEDRON || t == VTK_WEDGE || t == VTK_PYRAMID;
    for (Patch& p : mesh_.patches) p.boundary = p.type == (solid ? "dim 2" : "dim 1");
  }

  /// The file with its $Nodes coordinates replaced: every other byte as it was (Gmsh's own writer
  /// renumbers the nodes of a 2.2 file and drops the elements outside physical groups).
  std::string rewritten(std::span<const Vec3> points) const {
    std::string t = io::read_input(path_, "a Gmsh mesh");
    const std::string name = path_.string();
    std::size_t at = t.rfind("$Nodes", 0) == 0 ? 0 : t.find("\n$Nodes");
    if (at == std::string::npos) throw FileError(name + ": no $Nodes section");
    at = t.find('\n', at + 1) + 1;
    std::size_t written = 0;
    const auto place = [&](std::uint64_t tag) -> const Vec3& {
      const auto it = index_.find(tag);
      if (it == index_.end()) throw FileError(name + ": $Nodes: node " + std::to_string(tag) + " was not read");
      ++written;
      return points[it->second];
    };
    const auto need = [&](std::size_t bytes) {
      if (at + bytes > t.size()) throw FileError(name + ": $Nodes ends early (the file changed since it was read?)");
    };
    char buf[64];
    // ASCII lines change length: the output is built by appending (out, with t copied up to `copied`),
    // never by replacing inside t, which moved the rest of the file for every node (a 42 MB mesh was
    // still being written after 8 minutes).
    std::string out;
    std::size_t copied = 0;
    // ASCII: the line's first three numbers after skip tokens are replaced where their value changed.
    const auto ascii_line = [&](std::size_t skip, const Vec3& p) {
      const std::size_t end = t.find('\n', at);
      if (end == std::string::npos) throw FileError(name + ": $Nodes ends early");
      std::string line;
      std::size_t i = at, token = 0;
      while (i < end) {
        if (t[i] == ' ' || t[i] == '\t' || t[i] == '\r') {
          line += t[i++];
          continue;
        }
        std::size_t e = i;
        while (e < end && t[e] != ' ' && t[e] != '\t' && t[e] != '\r') ++e;
        if (token >= skip && token < skip + 3) {
          double old = 0;
          std::from_chars(t.data() + i, t.data() + e, old);
          const double v = p[int(token - skip)];
          if (old == v && std::signbit(old) == std::signbit(v)) {
            line.append(t, i, e - i);
          } else {
            line.append(buf, std::size_t(std::to_chars(buf, buf + sizeof buf, v).ptr - buf));
          }
        } else {
          line.append(t, i, e - i);
        }
        ++token;
        i = e;
      }
      if (token < skip + 3) throw FileError(name + ": $Nodes: a line with fewer than 3 coordinates");
      if (out.empty()) out.reserve(t.size() + t.size() / 8);
      out.append(t, copied, at - copied);
      out += line;
      copied = end;
      at = end + 1;
    };
    const auto read_line_numbers = [&](std::size_t count) {
      const std::size_t end = t.find('\n', at);
      std::vector<std::uint64_t> v;
      const char* q = t.data() + at;
      for (std::size_t k = 0; k < count; ++k) {
        while (q < t.data() + end && (*q == ' ' || *q == '\t')) ++q;
        std::uint64_t x = 0;
        const auto r = std::from_chars(q, t.data() + end, x);
        if (r.ec != std::errc()) throw FileError(name + ": $Nodes: a malformed line");
        v.push_back(x);
        q = r.ptr;
      }
      at = end + 1;
      return v;
    };
    const auto put = [&](const Vec3& p) {
      need(24);
      std::memcpy(t.data() + at, p.data(), 24);
      at += 24;
    };
    if (header_.version < 4.0) {
      const std::uint64_t n = read_line_numbers(1)[0];
      for (std::uint64_t k = 0; k < n; ++k) {
        if (header_.binary) {
          need(4);
          std::int32_t tag;
          std::memcpy(&tag, t.data() + at, 4);
          at += 4;
          put(place(std::uint64_t(tag)));
        } else {
          std::uint64_t tag = 0;
          std::from_chars(t.data() + at, t.data() + t.size(), tag);
          ascii_line(1, place(tag));
        }
      }
    } else {
      std::uint64_t blocks = 0;
      if (header_.binary) {
        need(32);
        std::memcpy(&blocks, t.data() + at, 8);
        at += 32;
      } else {
        blocks = read_line_numbers(4)[0];
      }
      for (std::uint64_t b = 0; b < blocks; ++b) {
        std::int32_t dim = 0, parametric = 0;
        std::uint64_t n = 0;
        if (header_.binary) {
          need(20);
          std::memcpy(&dim, t.data() + at, 4);
          std::memcpy(&parametric, t.data() + at + 8, 4);
          std::memcpy(&n, t.data() + at + 12, 8);
          at += 20;
          need(8 * n);
          std::vector<std::uint64_t> tags(n);
          std::memcpy(tags.data(), t.data() + at, 8 * n);
          at += 8 * n;
          const std::size_t extra = parametric ? std::size_t(std::max(dim, 0)) : 0;
          for (std::uint64_t k = 0; k < n; ++k) {
            put(place(tags[k]));
            need(8 * extra);
            at += 8 * extra;
          }
        } else {
          const auto h = read_line_numbers(4);
          n = h[3];
          std::vector<std::uint64_t> tags;
          tags.reserve(n);
          for (std::uint64_t k = 0; k < n; ++k) tags.push_back(read_line_numbers(1)[0]);
          for (std::uint64_t k = 0; k < n; ++k) ascii_line(0, place(tags[k]));
        }
      }
    }
    if (written != points.size())
      throw FileError(name + ": $Nodes holds " + std::to_string(written) + " nodes, " + std::to_string(points.size()) +
                      " were read");
    if (copied == 0) return t;  // binary: rewritten in place
    out.append(t, copied, std::string::npos);
    return out;
  }

  void write(std::span<const Vec3> points, const fs::path& target) const {
    const std::string bytes = rewritten(points);
    io::write_atomically(target, [&](std::ostream& o) { o.write(bytes.data(), std::streamsize(bytes.size())); });
  }

  fs::path path_;
  Header header_;
  VolumeMesh mesh_;
  std::unordered_map<std::uint64_t, std::uint32_t> index_;  // node tag -> point
};

}  // namespace

std::unique_ptr<VolumeFile> open_gmsh(const fs::path& path, const OpenOptions& o) {
  return std::make_unique<GmshFile>(path, o);
}

}  // namespace csrbf::morph::detail
