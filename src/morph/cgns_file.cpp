// CGNS unstructured zones through the CGNS library: boundary conditions and their families are the
// patches. The output is a byte copy of the input whose GridCoordinates are overwritten, in their
// own data type: every other node of the tree is kept.
#include "volume_formats.hpp"

#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/error.hpp"
#include "csrbf/io/input_file.hpp"
#include "csrbf/morph/quality.hpp"

#include <cgnslib.h>
#include <vtkCellType.h>

#include <map>
#include <set>

namespace fs = std::filesystem;

namespace csrbf::morph::detail {

namespace {

using io::FileError;

/// A CGNS file open for reading or modifying, closed on scope exit.
class Handle {
 public:
  Handle(const fs::path& p, int mode, const std::string& what) {
    if (cg_open(p.c_str(), mode, &fn_) != CG_OK)
      throw FileError(what + ": the CGNS library cannot open it: " + cg_get_error());
  }
  ~Handle() {
    if (fn_ >= 0) cg_close(fn_);
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  int close() {
    const int r = cg_close(fn_);
    fn_ = -1;
    return r;
  }
  int fn() const { return fn_; }

 private:
  int fn_ = -1;
};

/// VTK's cell type and the number of corners of a CGNS element type (0 for others).
std::pair<std::uint8_t, int> cell_of(CGNS_ENUMT(ElementType_t) t) {
  switch (t) {
    case CGNS_ENUMV(TETRA_4):
    case CGNS_ENUMV(TETRA_10):
      return {VTK_TETRA, 4};
    case CGNS_ENUMV(PYRA_5):
    case CGNS_ENUMV(PYRA_13):
    case CGNS_ENUMV(PYRA_14):
      return {VTK_PYRAMID, 5};
    case CGNS_ENUMV(PENTA_6):
    case CGNS_ENUMV(PENTA_15):
    case CGNS_ENUMV(PENTA_18):
      return {VTK_WEDGE, 6};
    case CGNS_ENUMV(HEXA_8):
    case CGNS_ENUMV(HEXA_20):
    case CGNS_ENUMV(HEXA_27):
      return {VTK_HEXAHEDRON, 8};
    case CGNS_ENUMV(TRI_3):
    case CGNS_ENUMV(TRI_6):
      return {VTK_TRIANGLE, 3};
    case CGNS_ENUMV(QUAD_4):
    case CGNS_ENUMV(QUAD_8):
    case CGNS_ENUMV(QUAD_9):
      return {VTK_QUAD, 4};
    default:
      return {0, 0};
  }
}

struct Zone {
  int base, zone;
  std::size_t first, count;  // its points in the mesh
  CGNS_ENUMT(DataType_t) type = CGNS_ENUMV(RealDouble);
};

// What the reading of a file's zones shares: the open file, the mesh it fills, and the patches
// gathered from every zone's boundary conditions.
struct CgnsRead {
  int fn;
  std::string file;  // the path, for messages
  const OpenOptions& o;
  VolumeMesh& mesh;
  std::map<std::string, std::set<std::uint32_t>> patches;
  std::set<std::string> bcs;  // the boundary conditions' own names (the others are their families)

  void check(int r, const std::string& what) const {
    if (r != CG_OK) throw FileError(file + ": " + what + ": " + cg_get_error());
  }
};

// One unstructured zone as it is read: where its points sit in the mesh, and its elements by id.
struct ZoneRead {
  Zone zone;
  std::string where;  // the file and the zone, for messages
  std::size_t nv = 0;
  int ncoords = 0;
  std::map<cgsize_t, std::vector<std::uint32_t>> elements;  // each element's corners, for the boundary conditions
};

/// The zone's vertices, appended to the mesh's points.
ZoneRead read_zone_points(CgnsRead& r, int b, int z, int phys_dim) {
  const int fn = r.fn;
  CGNS_ENUMT(ZoneType_t) zt;
  r.check(cg_zone_type(fn, b, z, &zt), "zone " + std::to_string(z));
  char zname[64] = {};
  cgsize_t size[9] = {};
  r.check(cg_zone_read(fn, b, z, zname, size), "zone " + std::to_string(z));
  const std::string where = r.file + ": zone '" + zname + "'";
  if (zt != CGNS_ENUMV(Unstructured)) throw FileError(where + ": a structured zone (csrbf reads unstructured zones)");
  const std::size_t nv = std::size_t(size[0]);
  if (double(nv) * 24.0 > r.o.max_file_bytes || double(r.mesh.points.size() + nv) >= 4294967295.0)
    throw FileError(where + ": " + std::to_string(nv) + " vertices pass the memory limit");
  ZoneRead zr{Zone{b, z, r.mesh.points.size(), nv}, where, nv, 0, {}};
  Zone& zone = zr.zone;
  int ncoords = 0;
  r.check(cg_ncoords(fn, b, z, &ncoords), where + ": coordinates");
  char cname[64] = {};
  if (ncoords >= 1) r.check(cg_coord_info(fn, b, z, 1, &zone.type, cname), where + ": coordinates");
  r.mesh.points.resize(zone.first + nv, Vec3::Zero());
  std::vector<double> buf(nv);
  for (int c = 0; c < 3; ++c) {
    const char* name = c == 0 ? "CoordinateX" : c == 1 ? "CoordinateY" : "CoordinateZ";
    cgsize_t lo = 1, hi = cgsize_t(nv);
    if (cg_coord_read(fn, b, z, name, CGNS_ENUMV(RealDouble), &lo, &hi, buf.data()) != CG_OK) {
      if (c == 2 && ncoords == 2 && phys_dim == 2) break;  // a 2-D base: z stays 0
      throw FileError(where + ": no " + name + ": " + cg_get_error());
    }
    for (std::size_t i = 0; i < nv; ++i) {
      if (!std::isfinite(buf[i]))
        throw FileError(where + ": vertex " + std::to_string(i + 1) + " has a coordinate that is not finite");
      r.mesh.points[zone.first + i][c] = buf[i];
    }
  }
  zr.ncoords = ncoords;
  return zr;
}

/// Sections: cells, and each element's corners by its id for the boundary conditions.
void read_sections(CgnsRead& r, ZoneRead& zr) {
  const int fn = r.fn, b = zr.zone.base, z = zr.zone.zone;
  const std::string& where = zr.where;
  const std::size_t nv = zr.nv;
  int sections = 0;
  r.check(cg_nsections(fn, b, z, &sections), where + ": sections");
  for (int s = 1; s <= sections; ++s) {
    char sname[64] = {};
    CGNS_ENUMT(ElementType_t) et;
    cgsize_t start = 0, end = 0;
    int nbndry = 0, parent = 0;
    r.check(cg_section_read(fn, b, z, s, sname, &et, &start, &end, &nbndry, &parent),
            where + ": section " + std::to_string(s));
    cgsize_t data = 0;
    r.check(cg_ElementDataSize(fn, b, z, s, &data), where + ": section '" + sname + "'");
    if (double(data) * 4.0 > r.o.max_file_bytes || data < 0 || end < start)
      throw FileError(where + ": section '" + std::string(sname) + "': " + std::to_string(data) +
                      " entries pass the limit");
    std::vector<cgsize_t> conn(static_cast<std::size_t>(data));
    if (et == CGNS_ENUMV(NGON_n) || et == CGNS_ENUMV(NFACE_n)) continue;  // polyhedra: moved, not measured
    r.check(cg_elements_read(fn, b, z, s, conn.data(), nullptr), where + ": section '" + sname + "'");
    std::size_t at = 0;
    for (cgsize_t e = start; e <= end; ++e) {
      CGNS_ENUMT(ElementType_t) t = et;
      if (et == CGNS_ENUMV(MIXED)) {
        if (at >= conn.size()) throw FileError(where + ": section '" + std::string(sname) + "' ends early");
        t = CGNS_ENUMT(ElementType_t)(conn[at++]);
      }
      int npe = 0;
      if (cg_npe(t, &npe) != CG_OK || npe <= 0 || at + std::size_t(npe) > conn.size())
        throw FileError(where + ": section '" + std::string(sname) + "': element " + std::to_string(e) +
                        " has an unknown type or ends early");
      std::vector<std::uint32_t> nodes(static_cast<std::size_t>(npe));
      for (int k = 0; k < npe; ++k) {
        const cgsize_t v = conn[at + std::size_t(k)];
        if (v < 1 || std::size_t(v) > nv)
          throw FileError(where + ": section '" + std::string(sname) + "': element " + std::to_string(e) +
                          " uses vertex " + std::to_string(v) + ", but the zone has " + std::to_string(nv));
        nodes[std::size_t(k)] = std::uint32_t(zr.zone.first + std::size_t(v) - 1);
      }
      at += std::size_t(npe);
      const auto [vt, corners] = cell_of(t);
      if (vt) r.mesh.cells.add(vt, std::span(nodes).first(std::size_t(corners)));
      zr.elements[e] = std::move(nodes);
    }
  }
}

/// Boundary conditions: by vertex, or by element (face centres).
void read_boundary_conditions(CgnsRead& r, const ZoneRead& zr) {
  const int fn = r.fn, b = zr.zone.base, z = zr.zone.zone;
  const std::string& where = zr.where;
  const std::size_t nv = zr.nv;
  const auto& elements = zr.elements;
  int bocos = 0;
  r.check(cg_nbocos(fn, b, z, &bocos), where + ": boundary conditions");
  for (int bc = 1; bc <= bocos; ++bc) {
    char bname[64] = {};
    CGNS_ENUMT(BCType_t) btype;
    CGNS_ENUMT(PointSetType_t) ptset;
    cgsize_t npnts = 0, nlist = 0;
    int normal_index[3] = {};
    CGNS_ENUMT(DataType_t) ndt;
    int ndataset = 0;
    r.check(cg_boco_info(fn, b, z, bc, bname, &btype, &ptset, &npnts, normal_index, &nlist, &ndt, &ndataset),
            where + ": boundary condition " + std::to_string(bc));
    CGNS_ENUMT(GridLocation_t) loc = CGNS_ENUMV(Vertex);
    cg_boco_gridlocation_read(fn, b, z, bc, &loc);
    if (npnts < 0 || double(npnts) * 4.0 > r.o.max_file_bytes)
      throw FileError(where + ": boundary condition '" + bname + "' is too large");
    std::vector<cgsize_t> pnts(static_cast<std::size_t>(npnts));
    r.check(cg_boco_read(fn, b, z, bc, pnts.data(), nullptr),
            where + ": boundary condition '" + std::string(bname) + "'");
    std::vector<cgsize_t> ids;
    const bool range = ptset == CGNS_ENUMV(PointRange) || ptset == CGNS_ENUMV(ElementRange);
    if (range && pnts.size() == 2) {
      const double span = double(pnts[1]) - double(pnts[0]) + 1;
      if (pnts[0] < 1 || span < 1 || span > double(nv) + double(elements.empty() ? 0 : elements.rbegin()->first))
        throw FileError(where + ": boundary condition '" + std::string(bname) + "' ranges over " +
                        std::to_string(pnts[0]) + " to " + std::to_string(pnts[1]) +
                        ", past the zone's vertices and elements");
      for (cgsize_t i = pnts[0]; i <= pnts[1]; ++i) ids.push_back(i);
    } else {
      ids = pnts;
    }
    const bool by_element =
        ptset == CGNS_ENUMV(ElementList) || ptset == CGNS_ENUMV(ElementRange) || (loc != CGNS_ENUMV(Vertex));
    std::set<std::uint32_t> pts;
    for (const cgsize_t id : ids) {
      if (by_element) {
        const auto it = elements.find(id);
        if (it == elements.end())
          throw FileError(where + ": boundary condition '" + std::string(bname) + "' names element " +
                          std::to_string(id) + ", which no section holds");
        pts.insert(it->second.begin(), it->second.end());
      } else {
        if (id < 1 || std::size_t(id) > nv)
          throw FileError(where + ": boundary condition '" + std::string(bname) + "' names vertex " +
                          std::to_string(id) + ", but the zone has " + std::to_string(nv));
        pts.insert(std::uint32_t(zr.zone.first + std::size_t(id) - 1));
      }
    }
    r.patches[bname].insert(pts.begin(), pts.end());
    r.bcs.insert(bname);
    char family[64] = {};
    if (cg_goto(fn, b, "Zone_t", z, "ZoneBC_t", 1, "BC_t", bc, "end") == CG_OK && cg_famname_read(family) == CG_OK &&
        family[0] && std::string(family) != bname)
      r.patches[family].insert(pts.begin(), pts.end());
  }
}

class CgnsFile final : public VolumeFile {
 public:
  CgnsFile(const fs::path& path, const OpenOptions& o) : path_(path) {
    io::check_readable(path, "a CGNS mesh");
    Handle h(path, CG_MODE_READ, path.string());
    CgnsRead r{h.fn(), path.string(), o, mesh_, {}, {}};
    const int fn = r.fn;
    int bases = 0;
    r.check(cg_nbases(fn, &bases), "reading the bases");
    if (bases < 1) throw FileError(path.string() + ": no CGNS base");
    for (int b = 1; b <= bases; ++b) {
      int zones = 0, cell_dim = 0, phys_dim = 0;
      char bname_[64] = {};
      r.check(cg_base_read(fn, b, bname_, &cell_dim, &phys_dim), "reading base " + std::to_string(b));
      r.check(cg_nzones(fn, b, &zones), "reading the zones");
      for (int z = 1; z <= zones; ++z) {
        ZoneRead zr = read_zone_points(r, b, z, phys_dim);
        zone_dims_[zones_.size()] = zr.ncoords;
        read_sections(r, zr);
        read_boundary_conditions(r, zr);
        zones_.push_back(zr.zone);
      }
    }
    if (mesh_.points.empty()) throw FileError(path.string() + ": no unstructured zone with vertices");
    for (auto& [name, pts] : r.patches) {
      Patch p;
      p.name = name;
      p.points.assign(pts.begin(), pts.end());
      p.boundary = r.bcs.count(name) > 0;
      mesh_.patches.push_back(std::move(p));
    }
    orient_cells(mesh_.cells, mesh_.points);
  }

  const VolumeMesh& mesh() const override { return mesh_; }
  std::string format() const override { return "cgns"; }
  std::string encoding() const override {
    return zones_.empty() || zones_[0].type == CGNS_ENUMV(RealDouble) ? "double" : "single";
  }
  void write_copy(std::span<const Vec3> points, const fs::path& out) const override {
    check_copy_target(path_, out);
    write(points, out);
  }
  void write_in_place(std::span<const Vec3> points) const override { write(points, path_); }

 private:
  void write(std::span<const Vec3> points, const fs::path& target) const {
    io::write_atomically_via_folder(target, [&](const fs::path& path) {
      std::error_code ec;
      fs::copy_file(path_, path, ec);
      if (ec) throw FileError("cannot write '" + target.string() + "': " + ec.message());
      Handle h(path, CG_MODE_MODIFY, "cannot write '" + target.string() + "'");
      for (std::size_t zi = 0; zi < zones_.size(); ++zi) {
        const Zone& z = zones_[zi];
        const int dims = zone_dims_.at(zi);
        for (int c = 0; c < std::min(dims, 3); ++c) {
          const char* name = c == 0 ? "CoordinateX" : c == 1 ? "CoordinateY" : "CoordinateZ";
          int index = 0;
          int r;
          if (z.type == CGNS_ENUMV(RealSingle)) {
            std::vector<float> v(z.count);
            for (std::size_t i = 0; i < z.count; ++i) v[i] = float(points[z.first + i][c]);
            r = cg_coord_write(h.fn(), z.base, z.zone, z.type, name, v.data(), &index);
          } else {
            std::vector<double> v(z.count);
            for (std::size_t i = 0; i < z.count; ++i) v[i] = points[z.first + i][c];
            r = cg_coord_write(h.fn(), z.base, z.zone, CGNS_ENUMV(RealDouble), name, v.data(), &index);
          }
          if (r != CG_OK) throw FileError("cannot write '" + target.string() + "': " + cg_get_error());
        }
      }
      if (h.close() != CG_OK) throw FileError("cannot write '" + target.string() + "': " + cg_get_error());
    });
  }

  fs::path path_;
  std::vector<Zone> zones_;
  std::map<std::size_t, int> zone_dims_;
  VolumeMesh mesh_;
};

}  // namespace

std::unique_ptr<VolumeFile> open_cgns(const fs::path& path, const OpenOptions& o) {
  return std::make_unique<CgnsFile>(path, o);
}

}  // namespace csrbf::morph::detail
