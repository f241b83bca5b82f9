// csrbf._io: csrbf's file functions, reached as csrbf.read_mesh and so on (csrbf/__init__.py imports
// this on first use of one of these names, so that `import csrbf` does not load VTK, assimp and CGNS):
// meshes, controls and deformation files, csrbf.morph, the scenes, and csrbf.FileError. The SpaceMap
// it returns and takes is the type csrbf._core registers (pybind11 shares it).
#include "csrbf/anim/scene.hpp"
#include "csrbf/errors.hpp"
#include "csrbf/io/controls.hpp"
#include "csrbf/io/deformation.hpp"
#include "csrbf/io/mesh.hpp"
#include "csrbf/io/scene.hpp"
#ifdef CSRBF_HAVE_MORPH
#include "csrbf/morph/job.hpp"
#endif
#include "csrbf/space_map.hpp"
#include "csrbf/units.hpp"
#include "arrays.hpp"
#include "points.hpp"

#include <nlohmann/json.hpp>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <sstream>

namespace py = pybind11;
using csrbf::Vec3;
using namespace csrbf_python;

namespace {

/// Polygons as a list of lists of vertex indices.
py::list polygons(const csrbf::PolygonList& list) {
  py::list out;
  for (const auto face : list) {
    py::list f;
    for (const std::uint32_t v : face) f.append(v);
    out.append(std::move(f));
  }
  return out;
}

/// A scene and its player together (the player borrows the scene).
struct ScenePlayer {
  std::unique_ptr<csrbf::anim::Scene> scene;
  std::unique_ptr<csrbf::anim::Player> player;
};

/// read_mesh, write_mesh, read_controls, the deformation files.
void bind_files(py::module_& m) {
  m.def(
      "read_mesh",
      [](const std::filesystem::path& path) {
        const auto mesh = csrbf::io::MeshDocument::load(path);
        return py::make_tuple(from_vec3(mesh.positions()), polygons(mesh.faces()));
      },
      py::arg("path"), "(positions (n, 3), faces as lists of vertex indices) of a mesh file");
  m.def(
      "write_mesh",
      [](const std::filesystem::path& template_path, const py::object& positions, const std::filesystem::path& path) {
        auto mesh = csrbf::io::MeshDocument::load(template_path);
        const auto p = to_vec3(positions, "positions");
        if (p.size() != mesh.positions().size())
          throw py::value_error("positions has " + std::to_string(p.size()) + " points but " + template_path.string() +
                                " has " + std::to_string(mesh.positions().size()));
        mesh.positions() = p;
        mesh.save(path);
      },
      py::arg("template"), py::arg("positions"), py::arg("path"),
      "Writes the mesh of `template` with new positions to `path` (format by extension, atomically)");
  m.def(
      "read_controls",
      [](const std::filesystem::path& path) {
        const auto c = csrbf::io::read_controls(path);
        return py::make_tuple(from_vec3(c.sources), from_vec3(c.destinations));
      },
      py::arg("path"), "(sources, destinations) of a controls text file");
  m.def(
      "read_deformation",
      [](const std::filesystem::path& path) {
        const auto d = csrbf::io::read_deformation(path);
        py::gil_scoped_release release;
        return d.fit();
      },
      py::arg("path"), "The SpaceMap of a deformation JSON file (without its active area: see apply_deformation)");
  m.def(
      "read_active_area",
      [](const std::filesystem::path& path) -> py::object {
        const auto d = csrbf::io::read_deformation(path);
        if (!d.area) return py::none();
        py::array_t<std::uint32_t> out(py::ssize_t(d.area->vertices.size()));
        std::copy(d.area->vertices.begin(), d.area->vertices.end(), out.mutable_data());
        return out;
      },
      py::arg("path"),
      "The active area of a deformation JSON file: the sorted vertex indices it moves, or None for every vertex");
  m.def(
      "apply_deformation",
      [](const std::filesystem::path& path, const py::object& positions, double phase) {
        csrbf::check_phase(phase);
        const auto d = csrbf::io::read_deformation(path);
        auto p = to_vec3(positions, "positions", true);
        if (d.area) csrbf::io::check_active_area(*d.area, p, path.string(), "positions");  // before the fit
        {
          py::gil_scoped_release release;
          csrbf::io::apply_deformation(d.fit(), d.area, p, phase);
        }
        return from_vec3(p);
      },
      py::arg("path"), py::arg("positions"), py::arg("phase") = 1.0,
      "The (n, 3) positions of a mesh's vertices moved as `csrbf deform --deformation` moves them: by the "
      "deformation file at `phase`, inside its active area only (the mesh must have the area's vertex count)");
  m.def(
      "write_deformation",
      [](const std::filesystem::path& path, const csrbf::SpaceMap& map) {
        csrbf::io::DeformationSpec d;
        d.options = csrbf::FitOptions{map.radius(), map.kernel(), map.polynomial()};
        d.sources.assign(map.sources().begin(), map.sources().end());
        d.destinations.assign(map.destinations().begin(), map.destinations().end());
        csrbf::io::write_deformation(path, d);
      },
      py::arg("path"), py::arg("map"), "Writes a SpaceMap as a deformation JSON file (atomically)");
}

#ifdef CSRBF_HAVE_MORPH
namespace mo = csrbf::morph;

bool is_path(const py::object& o) {
  return py::isinstance<py::str>(o) || py::isinstance<py::bytes>(o) || py::hasattr(o, "__fspath__");
}
std::string shown(const py::handle& o) { return py::repr(o).cast<std::string>().substr(0, 80); }

/// radius: a number > 0, "auto" or None (the motion's).
void set_radius(mo::MorphJob& job, const py::object& radius) {
  if (py::isinstance<py::str>(radius) && radius.cast<std::string>() == "auto") {
    job.radius_auto = true;
    return;
  }
  if (radius.is_none()) return;
  if (py::isinstance<py::bool_>(radius) ||
      (!py::isinstance<py::float_>(radius) && !py::isinstance<py::int_>(radius) && !py::hasattr(radius, "__float__")))
    throw py::type_error("radius must be a number > 0, \"auto\" or None, got " + shown(radius));
  try {
    job.radius = py::float_(radius).cast<double>();
  } catch (const py::error_already_set&) {
    throw py::value_error("radius must be a finite number > 0, got " + shown(radius));
  }
}

void set_greedy(mo::MorphJob& job, std::optional<double> greedy, const py::object& greedy_budget) {
  job.greedy = greedy;
  if (greedy_budget.is_none()) return;
  if (py::isinstance<py::bool_>(greedy_budget) ||
      (!py::isinstance<py::float_>(greedy_budget) && !py::isinstance<py::int_>(greedy_budget)))
    throw py::type_error("greedy_budget must be a number >= 0, got " + shown(greedy_budget));
  if (!greedy) throw py::value_error("greedy_budget: it bounds greedy's rounds, so give greedy= too");
  job.greedy_budget = greedy_budget.cast<double>();
}

/// time: "latest", a time (str or number) or None; a case's only.
void set_time(mo::MorphJob& job, const py::object& mesh, const py::object& time) {
  if (time.is_none()) return;
  if (!is_path(mesh)) throw py::value_error("time: mesh is an array of points, which has no time folders");
  if (py::isinstance<py::str>(time))
    job.time = time.cast<std::string>();
  else if (!py::isinstance<py::bool_>(time) && (py::isinstance<py::int_>(time) || py::isinstance<py::float_>(time)))
    job.time = py::str(time).cast<std::string>();
  else
    throw py::type_error("time must be \"latest\", a time (str or number) or None, got " + shown(time));
  if (job.time.empty()) throw py::value_error("time: '' names no time (\"latest\" or a time such as 0.5)");
}

/// levels: "auto", or an integer 1 or 2 of any integer type (numpy's too, through operator.index).
void set_levels(mo::MorphJob& job, const py::object& levels) {
  const std::string text = shown(levels);
  if (py::isinstance<py::str>(levels)) {
    if (levels.cast<std::string>() != "auto") throw py::value_error("levels must be \"auto\", 1 or 2, got " + text);
    job.levels = 0;
    return;
  }
  if (py::isinstance<py::bool_>(levels) || !py::hasattr(levels, "__index__"))
    throw py::type_error("levels must be \"auto\", 1 or 2, got " + text);
  const py::object v = py::module_::import("operator").attr("index")(levels);
  if (!v.equal(py::int_(1)) && !v.equal(py::int_(2)))
    throw py::value_error("levels must be \"auto\", 1 or 2, got " + text);
  job.levels = v.cast<int>();
}

/// The point indices of patches[name]: a 1-D integer array, each within the mesh's n points.
mo::Patch patch_of(const py::handle& key, const py::handle& value, std::size_t n) {
  mo::Patch p;
  if (!py::isinstance<py::str>(key)) throw py::type_error("patches: its keys are patch names (str), got " + shown(key));
  p.name = key.cast<std::string>();
  p.boundary = true;
  const py::array a = py::array::ensure(value);
  if (!a || a.ndim() != 1 || (a.size() > 0 && a.dtype().kind() != 'i' && a.dtype().kind() != 'u'))
    throw py::type_error("patches['" + p.name + "'] must be a 1-D array of point indices, got " + shown(value));
  const auto out_of_range = [&](py::ssize_t k, const std::string& v) {
    return py::value_error("patches['" + p.name + "'][" + std::to_string(k) + "] is " + v + ": mesh has " +
                           std::to_string(n) + " points");
  };
  if (a.size() > 0 && a.dtype().kind() == 'u' && a.itemsize() == 8) {
    const auto big = py::array_t<unsigned long long, py::array::c_style | py::array::forcecast>::ensure(a);
    for (py::ssize_t k = 0; k < big.size(); ++k)
      if (big.data()[k] >= n) throw out_of_range(k, std::to_string(big.data()[k]));
  }
  const auto idx = py::array_t<long long, py::array::c_style | py::array::forcecast>::ensure(a);
  for (py::ssize_t k = 0; k < idx.size(); ++k) {
    const long long i = idx.data()[k];
    if (i < 0 || std::size_t(i) >= n) throw out_of_range(k, std::to_string(i));
    p.points.push_back(std::uint32_t(i));
  }
  std::sort(p.points.begin(), p.points.end());
  p.points.erase(std::unique(p.points.begin(), p.points.end()), p.points.end());
  return p;
}

/// The mesh given as points, with patches of point indices.
mo::VolumeMesh cloud_of(const mo::MorphJob& job, const py::object& mesh, const std::optional<py::dict>& patches) {
  if (job.write)
    throw py::value_error(
        "output, in_place: mesh is an array of points, which has no file to write; the "
        "moved points are returned");
  if (!patches || patches->empty())
    throw py::value_error("patches: mesh is an array of points, so give patches={name: point indices}");
  mo::VolumeMesh cloud;
  cloud.points = to_vec3(mesh, "mesh");
  for (const auto& [key, value] : *patches) cloud.patches.push_back(patch_of(key, value, cloud.points.size()));
  return cloud;
}

/// A motion given as a dict, as the JSON of a motion file (numpy arrays allowed in it).
nlohmann::json motion_json(const py::object& motion) {
  const py::object dumps = py::module_::import("json").attr("dumps");
  const py::cpp_function plain([](const py::object& o) -> py::object {
    if (py::hasattr(o, "tolist")) return o.attr("tolist")();
    throw py::type_error("motion: " + shown(o) + " is not JSON");
  });
  std::string text;
  try {
    text = dumps(motion, py::arg("default") = plain, py::arg("allow_nan") = false).cast<std::string>();
  } catch (py::error_already_set& e) {
    if (!e.matches(PyExc_ValueError)) throw;
    throw py::value_error(
        "motion: a number in it is not finite (NaN or infinity): every number of a motion "
        "must be finite");
  }
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw py::value_error(std::string("motion: not a motion's JSON: ") + e.what());
  }
}

/// Points given: a patch's displacements may be rows (dx, dy, dz), one per index of the patch as given;
/// they become the file's rows [point, dx, dy, dz].
void index_displacement_rows(nlohmann::json& j, const py::dict& patches) {
  if (!j.is_object() || !j.contains("patches") || !j["patches"].is_object()) return;
  for (auto& [name, entry] : j["patches"].items()) {
    if (!entry.is_object() || !entry.contains("displacements") || !entry["displacements"].is_array()) continue;
    auto& rows = entry["displacements"];
    if (rows.empty() || !rows[0].is_array() || rows[0].size() != 3) continue;
    const py::str key(name);
    if (!patches.contains(key))
      throw py::value_error("motion: patches." + name +
                            ".displacements: rows (dx, dy, dz) belong to a patch given in patches=, and there is "
                            "no '" +
                            name + "'");
    const auto idx = py::array_t<long long, py::array::c_style | py::array::forcecast>::ensure(patches[key]);
    if (!idx || std::size_t(idx.size()) != rows.size())
      throw py::value_error("motion: patches." + name + ".displacements has " + std::to_string(rows.size()) +
                            " rows, patches['" + name + "'] " + std::to_string(idx ? idx.size() : 0) + " points");
    for (std::size_t k = 0; k < rows.size(); ++k) {
      if (!rows[k].is_array() || rows[k].size() != 3)
        throw py::value_error("motion: patches." + name + ".displacements[" + std::to_string(k) +
                              "] is not a row (dx, dy, dz)");
      rows[k].insert(rows[k].begin(), std::uint64_t(idx.data()[k]));  // checked >= 0 by patch_of
    }
  }
}

/// The motion: a file, or a dict of the same form.
void set_motion(mo::MorphJob& job, const py::object& motion, bool points_given,
                const std::optional<py::dict>& patches) {
  if (is_path(motion)) {
    job.motion = motion.cast<std::filesystem::path>();
    return;
  }
  if (!py::isinstance<py::dict>(motion))
    throw py::type_error("motion must be a motion file's path or a dict of its form, got " + shown(motion));
  nlohmann::json j = motion_json(motion);
  if (points_given) index_displacement_rows(j, *patches);
  try {
    job.motion_given = mo::motion_from_json(j, "motion", std::filesystem::current_path());
  } catch (const csrbf::io::FileError& e) {
    throw py::value_error(e.what());
  }
  job.motion = "motion (dict)";
}

/// The morph of a cloud of points (no file: the command's checks, then csrbf::morph::morph).
mo::MorphOutcome morph_points(const mo::MorphJob& job, const mo::VolumeMesh& cloud) {
  mo::MorphOutcome o;
  const mo::Motion mot = job.motion_given ? *job.motion_given : mo::read_motion(job.motion);
  mo::check_job(job);  // the command's checks of the options (radius, phase, greedy, memory)
  o.mesh = "points";
  o.motion = job.motion.string();
  o.format = "points";
  o.points = cloud.points.size();
  o.patches = cloud.patches.size();
  o.options = mo::morph_options(job, mot);
  try {
    py::gil_scoped_release release;
    o.result = mo::morph(cloud, mot, o.options);
  } catch (const csrbf::io::FileError& e) {
    throw py::value_error(e.what());
  }
  return o;
}

py::tuple morph_binding(const py::object& mesh, const py::object& motion,
                        const std::optional<std::filesystem::path>& output, bool in_place, const py::object& radius,
                        std::optional<std::string> kernel, std::optional<std::string> polynomial,
                        std::optional<double> greedy, double phase, const std::string& solver, bool force,
                        double memory_limit, const std::optional<py::dict>& patches, const py::object& greedy_budget,
                        const py::object& time, const py::object& levels) {
  mo::MorphJob job;
  job.in_place = in_place;
  job.write = output.has_value() || in_place;
  if (output) job.out = *output;
  set_radius(job, radius);
  if (kernel) job.kernel = named<csrbf::Kernel>(*kernel, "kernel");
  if (polynomial) job.polynomial = named<csrbf::Polynomial>(*polynomial, "polynomial");
  set_greedy(job, greedy, greedy_budget);
  set_time(job, mesh, time);
  set_levels(job, levels);
  job.solver = named<csrbf::Solver>(solver, "solver");
  job.phase = phase;
  job.force = force;
  job.memory_limit_bytes = memory_limit * csrbf::kGiB;
  const bool points_given = !is_path(mesh);
  mo::VolumeMesh cloud;
  if (points_given)
    cloud = cloud_of(job, mesh, patches);
  else if (patches)
    throw py::value_error("patches: only for a mesh given as an array of points");
  else
    job.mesh = mesh.cast<std::filesystem::path>();
  set_motion(job, motion, points_given, patches);
  mo::MorphOutcome o;
  if (points_given) {
    o = morph_points(job, cloud);
  } else {
    py::gil_scoped_release release;
    o = mo::run_job(job);
  }
  py::object report = py::module_::import("json").attr("loads")(mo::outcome_json(o));
  if (job.write && o.inverts && !o.written)
    throw py::value_error(job.mesh.string() + ": the morph inverts " +
                          std::to_string(o.after.inverted_cells() - o.before.inverted_cells()) +
                          " cells; the largest phase that inverts none is " + std::to_string(o.safe_phase) +
                          "; nothing written (force=True writes anyway)");
  return py::make_tuple(from_vec3(o.result.points), report);
}

void bind_morph(py::module_& m) {
  m.def("morph", &morph_binding, py::arg("mesh"), py::arg("motion"), py::arg("output") = py::none(),
        py::arg("in_place") = false, py::arg("radius") = py::none(), py::arg("kernel") = py::none(),
        py::arg("polynomial") = py::none(), py::arg("greedy") = py::none(), py::arg("phase") = 1.0,
        py::arg("solver") = "auto", py::arg("force") = false, py::arg("memory_limit") = 4.0,
        py::arg("patches") = py::none(), py::arg("greedy_budget") = py::none(), py::arg("time") = py::none(),
        py::arg("levels") = "auto",
        R"doc(Morphs a volume mesh, or a cloud of points, as `csrbf morph` does (docs/morphing.md).

Parameters
----------
mesh : str or os.PathLike or array_like (n, 3)
    An OpenFOAM case folder, a .vtu, .vtk, .msh or .cgns file; or the points themselves, whose
    boundaries ``patches`` names.
motion : str or os.PathLike or dict
    The motion JSON file, or a dict of its form: ``{"radius": 0.5, "patches": {"wall":
    {"translate": [0, 0.01, 0]}, "far": "fixed"}}``. A patch's ``"displacements"`` may be a file,
    rows ``[point, dx, dy, dz]``, or (points given) an (k, 3) array, one row per index of
    ``patches[name]`` in its order. numpy arrays may stand anywhere in the dict.
output : str or os.PathLike, optional
    A new case folder or file to write (None: nothing is written).
in_place : bool
    Rewrite the input.
radius : float or "auto", optional
    Overrides the motion's; "auto" (the default where neither gives one) picks R from the largest
    displacement, the boundary's spacing and ``memory_limit`` (``report["radius_why"]``).
kernel, polynomial : str, optional
    Override the motion's.
greedy : float, optional
    The greedy tolerance.
greedy_budget : float, optional
    With greedy: its rounds' budget, a share of the plain fit and evaluation (default 0.2); past
    it every control is fitted (``report["greedy_stopped"]``).
levels : "auto" or int
    The fit's levels, as ``--levels``: 1, every control at R; 2, a coarse fit at R of controls R/4
    apart, then what it leaves at every control at about 1.75 x the boundary's spacing
    (``report["two_levels"]``); "auto", two where one level would pass its memory budget, or is
    predicted to take 10 s or more and 4 times as long (``report["levels_why"]``).
time : str or float, optional
    OpenFOAM: the time whose mesh is morphed, ``"latest"`` or a time such as ``0.5``, as
    ``-time``; the moved points are written into that time's folder.
patches : dict of str to array_like of int, optional
    With points: each patch's point indices.

Returns
-------
points : ndarray (n, 3)
    The moved points.
report : dict
    The report of ``csrbf morph --json``: with a mesh, the quality before and after.

A morph that inverts cells writes nothing and raises ValueError, unless force=True; without an
output it only reports them (``report["safe_phase"]``). Bad arguments raise ValueError or
TypeError naming them; a bad file raises csrbf.FileError.

Examples
--------
>>> import numpy as np, csrbf
>>> g = np.stack(np.meshgrid(*[np.linspace(0, 1, 11)] * 3, indexing="ij"), -1).reshape(-1, 3)
>>> bottom, top = np.flatnonzero(g[:, 2] == 0), np.flatnonzero(g[:, 2] == 1)
>>> moved, report = csrbf.morph(g, {"radius": 0.5, "patches": {"bottom": {"translate": [0, 0, 0.05]},
...                                 "top": "fixed"}}, patches={"bottom": bottom, "top": top})
>>> float(moved[bottom, 2].max()), bool((moved[top] == g[top]).all())
(0.05, True)
)doc");
}
#endif

void bind_scene(py::module_& m) {
  py::class_<ScenePlayer>(m, "Scene", "An animation scene file (docs/scene-format.md), evaluated at any time")
      .def(py::init([](const std::filesystem::path& path) {
             auto sp = std::make_unique<ScenePlayer>();
             sp->scene = std::make_unique<csrbf::anim::Scene>(csrbf::io::read_scene(path));
             sp->player = std::make_unique<csrbf::anim::Player>(*sp->scene);
             return sp;
           }),
           py::arg("path"))
      .def_property_readonly("duration", [](const ScenePlayer& s) { return s.scene->duration; })
      .def_property_readonly("fps", [](const ScenePlayer& s) { return s.scene->fps; })
      .def_property_readonly("objects",
                             [](const ScenePlayer& s) {
                               std::vector<std::string> names;
                               for (const auto& o : s.scene->objects) names.push_back(o.name);
                               return names;
                             })
      .def(
          "positions",
          [](ScenePlayer& s, double t) {
            {
              py::gil_scoped_release release;
              s.player->evaluate(t);
            }
            py::list out;
            for (std::size_t o = 0; o < s.scene->objects.size(); ++o) out.append(from_vec3(s.player->positions(o)));
            return out;
          },
          py::arg("t"), "World positions of every object's vertices at time t: a list of (n, 3) arrays")
      .def(
          "faces", [](const ScenePlayer& s, std::size_t o) { return polygons(s.scene->objects.at(o).faces); },
          py::arg("object"));
}

}  // namespace

PYBIND11_MODULE(_io, m) {
  m.doc() = "csrbf's file functions (meshes, controls, deformations, morph, scenes): use them as csrbf.NAME";
  // csrbf._core registers SpaceMap (read_deformation returns one) and the translation of its errors.
  py::module_::import("csrbf._core");
  static py::exception<csrbf::io::FileError> file_error(m, "FileError", PyExc_OSError);
  // Tried before csrbf's own translator (registered later): a bad file is csrbf.FileError, an OSError.
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const csrbf::io::FileError& e) {
      file_error(e.what());
    }
  });

  bind_files(m);
#ifdef CSRBF_HAVE_MORPH
  bind_morph(m);
#endif
  bind_scene(m);
  // Named as users reach them (help(csrbf.read_mesh) says "in module csrbf", as pickle looks them up).
  for (const auto& item : m.attr("__dict__").cast<py::dict>()) {
    const std::string name = py::str(item.first).cast<std::string>();
    if (!name.empty() && name[0] != '_') py::reinterpret_borrow<py::object>(item.second).attr("__module__") = "csrbf";
  }
}
