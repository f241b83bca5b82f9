// Gmsh .msh 2.2 and 4.1, ASCII or binary, through Gmsh's library (libgmsh): physical groups are
// the patches, node tags the point numbers; the output keeps the version and the encoding.
#include "volume_formats.hpp"

#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/morph/quality.hpp"

#include <gmsh.h>
#include <vtkCellType.h>

#include <charconv>
#include <cstring>
#include <fstream>
#include <mutex>
#include <set>
#include <unordered_map>

namespace fs = std::filesystem;

namespace csrbf::morph::detail {

namespace {

using io::FileError;

/// Gmsh's library has one global model: one file at a time in this process.
std::mutex& gmsh_lock() {
  static std::mutex m;
  return m;
}

void start_gmsh() {
  static bool started = false;
  if (started) return;
  gmsh::initialize();
  gmsh::option::setNumber("General.Terminal", 0);
  gmsh::option::setNumber("General.Verbosity", 0);
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
  if (head.rfind("$MeshFormat", 0) != 0) throw FileError(path.string() + ": not a Gmsh mesh (no $MeshFormat at the start)");
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
    std::lock_guard<std::mutex> lock(gmsh_lock());
    start_gmsh();
    gmsh::clear();
    try {
      gmsh::open(path.string());
      read();
    } catch (const std::string& e) {
      gmsh::clear();
      throw FileError(path.string() + ": Gmsh cannot read it: " + e);
    } catch (const FileError&) {
      gmsh::clear();
      throw;
    }
    gmsh::clear();
  }

  const VolumeMesh& mesh() const override { return mesh_; }
  std::string format() const override { return "msh"; }
  std::string encoding() const override {
    return std::string("msh ") + (header_.version >= 4.0 ? "4.1" : "2.2") + (header_.binary ? " binary" : " ascii");
  }
  void write_copy(std::span<const Vec3> points, const fs::path& out) const override {
    io::check_output_path(out);
    std::error_code ec;
    if (fs::exists(out, ec)) throw FileError("cannot write '" + out.string() + "': it exists (use --in-place to rewrite the input)");
    write(points, out);
  }
  void write_in_place(std::span<const Vec3> points) const override { write(points, path_); }

 private:
  void read() {
    std::vector<std::size_t> tags;
    std::vector<double> coord, param;
    gmsh::model::mesh::getNodes(tags, coord, param, -1, -1, false, false);
    if (tags.empty()) throw FileError(path_.string() + ": no nodes");
    std::unordered_map<std::size_t, std::uint32_t> index;
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
    gmsh::model::mesh::getElements(types, element_tags, node_tags, -1, -1);
    std::vector<std::uint32_t> corners;
    for (std::size_t t = 0; t < types.size(); ++t) {
      std::string name;
      int dim = 0, order = 0, nodes = 0, primary = 0;
      std::vector<double> local;
      gmsh::model::mesh::getElementProperties(types[t], name, dim, order, nodes, local, primary);
      const std::uint8_t vt = vtk_type(name);
      if (!vt) continue;  // points and lines: moved, not measured
      for (std::size_t e = 0; e < element_tags[t].size(); ++e) {
        corners.clear();
        for (int k = 0; k < primary; ++k) {
          const auto it = index.find(node_tags[t][e * std::size_t(nodes) + std::size_t(k)]);
          if (it == index.end())
            throw FileError(path_.string() + ": element " + std::to_string(element_tags[t][e]) + " uses node " +
                            std::to_string(node_tags[t][e * std::size_t(nodes) + std::size_t(k)]) + ", which is not defined");
          corners.push_back(it->second);
        }
        mesh_.cells.add(vt, corners);
      }
    }
    orient_cells(mesh_.cells, mesh_.points);
    gmsh::vectorpair groups;
    gmsh::model::getPhysicalGroups(groups, -1);
    for (const auto& [dim, tag] : groups) {
      Patch p;
      gmsh::model::getPhysicalName(dim, tag, p.name);
      if (p.name.empty()) p.name = std::to_string(tag);
      p.type = "dim " + std::to_string(dim);
      std::set<std::uint32_t> pts;
      std::vector<int> entities;
      gmsh::model::getEntitiesForPhysicalGroup(dim, tag, entities);
      for (const int entity : entities) {
        std::vector<std::size_t> nt;
        std::vector<double> c, pc;
        gmsh::model::mesh::getNodes(nt, c, pc, dim, entity, true, false);
        for (const auto n : nt) pts.insert(index.at(n));
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

  void write(std::span<const Vec3> points, const fs::path& target) const {
    io::write_atomically_via_folder(target, [&](const fs::path& path) {
      std::lock_guard<std::mutex> lock(gmsh_lock());
      start_gmsh();
      gmsh::clear();
      try {
        gmsh::open(path_.string());
        for (std::size_t i = 0; i < points.size(); ++i)
          gmsh::model::mesh::setNode(mesh_.point_ids[i], {points[i].x(), points[i].y(), points[i].z()}, {});
        gmsh::option::setNumber("Mesh.MshFileVersion", header_.version >= 4.0 ? 4.1 : 2.2);
        gmsh::option::setNumber("Mesh.Binary", header_.binary ? 1 : 0);
        gmsh::option::setNumber("Mesh.SaveAll", 1);
        gmsh::write(path.string());
      } catch (const std::string& e) {
        gmsh::clear();
        throw FileError("cannot write '" + target.string() + "': Gmsh: " + e);
      }
      gmsh::clear();
      std::error_code ec;
      if (fs::file_size(path, ec) == 0 || ec) throw FileError("cannot write '" + target.string() + "': Gmsh wrote nothing");
    });
  }

  fs::path path_;
  Header header_;
  VolumeMesh mesh_;
};

}  // namespace

std::unique_ptr<VolumeFile> open_gmsh(const fs::path& path, const OpenOptions& o) { return std::make_unique<GmshFile>(path, o); }

}  // namespace csrbf::morph::detail
