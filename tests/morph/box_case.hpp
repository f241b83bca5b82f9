// A structured box of hexahedra written as an OpenFOAM polyMesh by the tests' own writer
// (independent of csrbf's): ASCII or binary, gzip'd or not, with patches xmin ... zmax.
#pragma once

#include <zlib.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

namespace csrbf::test {

struct BoxSpec {
  int nx = 4, ny = 3, nz = 2;
  double h = 0.5;
  bool binary = false, gzip = false;
  bool empty_patch = false;  ///< add a patch "nothing" with no faces
  /// Moves a point (i, j, k) before writing (identity by default).
  std::function<void(int, int, int, double&, double&, double&)> warp;
};

struct BoxMesh {
  std::vector<double> points;  // xyz
  std::vector<std::vector<std::uint32_t>> faces;
  std::vector<std::int32_t> owner, neighbour;
  std::vector<std::pair<std::string, std::size_t>> patches;  // name, faces
  int cells = 0;
};

inline BoxMesh make_box(const BoxSpec& s) {
  BoxMesh m;
  const auto P = [&](int i, int j, int k) { return std::uint32_t(i + (s.nx + 1) * (j + (s.ny + 1) * k)); };
  const auto C = [&](int i, int j, int k) { return i + s.nx * (j + s.ny * k); };
  for (int k = 0; k <= s.nz; ++k)
    for (int j = 0; j <= s.ny; ++j)
      for (int i = 0; i <= s.nx; ++i) {
        double x = i * s.h, y = j * s.h, z = k * s.h;
        if (s.warp) s.warp(i, j, k, x, y, z);
        m.points.insert(m.points.end(), {x, y, z});
      }
  // Faces normal to +x at i, +y at j, +z at k (right-handed loops).
  const auto fx = [&](int i, int j, int k) {
    return std::vector<std::uint32_t>{P(i, j, k), P(i, j + 1, k), P(i, j + 1, k + 1), P(i, j, k + 1)};
  };
  const auto fy = [&](int i, int j, int k) {
    return std::vector<std::uint32_t>{P(i, j, k), P(i, j, k + 1), P(i + 1, j, k + 1), P(i + 1, j, k)};
  };
  const auto fz = [&](int i, int j, int k) {
    return std::vector<std::uint32_t>{P(i, j, k), P(i + 1, j, k), P(i + 1, j + 1, k), P(i, j + 1, k)};
  };
  const auto flip = [](std::vector<std::uint32_t> f) { return std::vector<std::uint32_t>{f[0], f[3], f[2], f[1]}; };
  for (int k = 0; k < s.nz; ++k)
    for (int j = 0; j < s.ny; ++j)
      for (int i = 0; i < s.nx; ++i) {
        const int c = C(i, j, k);
        if (i + 1 < s.nx)
          m.faces.push_back(fx(i + 1, j, k)), m.owner.push_back(c), m.neighbour.push_back(C(i + 1, j, k));
        if (j + 1 < s.ny)
          m.faces.push_back(fy(i, j + 1, k)), m.owner.push_back(c), m.neighbour.push_back(C(i, j + 1, k));
        if (k + 1 < s.nz)
          m.faces.push_back(fz(i, j, k + 1)), m.owner.push_back(c), m.neighbour.push_back(C(i, j, k + 1));
      }
  const auto patch = [&](const char* name, auto each) {
    const std::size_t before = m.faces.size();
    each();
    m.patches.emplace_back(name, m.faces.size() - before);
  };
  patch("xmin", [&] {
    for (int k = 0; k < s.nz; ++k)
      for (int j = 0; j < s.ny; ++j) m.faces.push_back(flip(fx(0, j, k))), m.owner.push_back(C(0, j, k));
  });
  patch("xmax", [&] {
    for (int k = 0; k < s.nz; ++k)
      for (int j = 0; j < s.ny; ++j) m.faces.push_back(fx(s.nx, j, k)), m.owner.push_back(C(s.nx - 1, j, k));
  });
  patch("ymin", [&] {
    for (int k = 0; k < s.nz; ++k)
      for (int i = 0; i < s.nx; ++i) m.faces.push_back(flip(fy(i, 0, k))), m.owner.push_back(C(i, 0, k));
  });
  patch("ymax", [&] {
    for (int k = 0; k < s.nz; ++k)
      for (int i = 0; i < s.nx; ++i) m.faces.push_back(fy(i, s.ny, k)), m.owner.push_back(C(i, s.ny - 1, k));
  });
  patch("zmin", [&] {
    for (int j = 0; j < s.ny; ++j)
      for (int i = 0; i < s.nx; ++i) m.faces.push_back(flip(fz(i, j, 0))), m.owner.push_back(C(i, j, 0));
  });
  patch("zmax", [&] {
    for (int j = 0; j < s.ny; ++j)
      for (int i = 0; i < s.nx; ++i) m.faces.push_back(fz(i, j, s.nz)), m.owner.push_back(C(i, j, s.nz - 1));
  });
  if (s.empty_patch) m.patches.emplace_back("nothing", 0);
  m.cells = s.nx * s.ny * s.nz;
  return m;
}

inline std::string foam_header(const char* cls, const char* object, bool binary) {
  std::string h = "/* a test box */\nFoamFile\n{\n    version     2.0;\n    format      ";
  h += binary ? "binary" : "ascii";
  h += ";\n    class       ";
  h += cls;
  h += ";\n";
  if (binary) h += "    arch        \"LSB;label=32;scalar=64\";\n";
  h += "    object      ";
  h += object;
  h += ";\n}\n// * * * //\n\n";
  return h;
}

inline void write_file(const std::filesystem::path& p, const std::string& bytes, bool gz) {
  if (!gz) {
    std::ofstream(p, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
    return;
  }
  gzFile f = gzopen((p.string() + ".gz").c_str(), "wb");
  gzwrite(f, bytes.data(), unsigned(bytes.size()));
  gzclose(f);
}

template <class T>
std::string raw(const std::vector<T>& v) {
  return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

/// Writes the box as case/constant/polyMesh (and a system folder); returns the mesh written.
inline BoxMesh write_box_case(const std::filesystem::path& dir, const BoxSpec& s = {}) {
  const BoxMesh m = make_box(s);
  const auto poly = dir / "constant" / "polyMesh";
  std::filesystem::create_directories(poly);
  std::filesystem::create_directories(dir / "system");
  std::ofstream(dir / "system" / "controlDict")
      << "FoamFile { version 2.0; format ascii; class dictionary; object controlDict; }\n";
  char buf[128];
  std::string pts = foam_header("vectorField", "points", s.binary) + std::to_string(m.points.size() / 3) + "\n(";
  if (s.binary) {
    pts += raw(m.points);
  } else {
    pts += "\n";
    for (std::size_t i = 0; i < m.points.size(); i += 3) {
      std::snprintf(buf, sizeof buf, "(%.17g %.17g %.17g)\n", m.points[i], m.points[i + 1], m.points[i + 2]);
      pts += buf;
    }
  }
  pts += ")\n\n// end\n";
  write_file(poly / "points", pts, s.gzip);
  std::string faces;
  if (s.binary) {  // as OpenFOAM writes binary faces: a faceCompactList (offsets, then labels)
    std::vector<std::int32_t> start{0}, labels;
    for (const auto& f : m.faces) {
      labels.insert(labels.end(), f.begin(), f.end());
      start.push_back(std::int32_t(labels.size()));
    }
    faces = foam_header("faceCompactList", "faces", true) + std::to_string(start.size()) + "\n(" + raw(start) +
            ")\n\n" + std::to_string(labels.size()) + "\n(" + raw(labels) + ")\n";
  } else {
    faces = foam_header("faceList", "faces", false) + std::to_string(m.faces.size()) + "\n(\n";
    for (const auto& f : m.faces) {
      faces += std::to_string(f.size()) + "(";
      for (std::size_t i = 0; i < f.size(); ++i) {
        if (i) faces += ' ';
        faces += std::to_string(f[i]);
      }
      faces += ")\n";
    }
    faces += ")\n";
  }
  write_file(poly / "faces", faces, s.gzip);
  for (const auto& [name, list] :
       {std::pair<const char*, const std::vector<std::int32_t>*>{"owner", &m.owner}, {"neighbour", &m.neighbour}}) {
    std::string t = foam_header("labelList", name, s.binary) + std::to_string(list->size()) + "\n(";
    if (s.binary) {
      t += raw(*list);
    } else {
      t += "\n";
      for (const auto v : *list) t += std::to_string(v) + "\n";
    }
    t += ")\n";
    write_file(poly / name, t, s.gzip);
  }
  std::string b = foam_header("polyBoundaryMesh", "boundary", false) + std::to_string(m.patches.size()) + "\n(\n";
  std::size_t start = m.neighbour.size();
  for (const auto& [name, n] : m.patches) {
    b += "    " + name + "\n    {\n        type patch;\n        inGroups List<word> 1(walls);\n        nFaces " +
         std::to_string(n) + ";\n        startFace " + std::to_string(start) + ";\n    }\n";
    start += n;
  }
  b += ")\n";
  std::ofstream(poly / "boundary", std::ios::binary) << b;  // OpenFOAM writes boundary uncompressed
  return m;
}

}  // namespace csrbf::test
