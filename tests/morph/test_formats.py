"""csrbf morph on Gmsh, VTK and CGNS meshes, judged by those formats' own tools: Gmsh's Python API
(python3-gmsh) reads every morphed .msh with its physical groups and a positive minimum SICN; VTK
(python3-vtk9) reads every .vtu and .vtk with all its arrays; python3-meshio reads every output.

    CSRBF_CLI=build/bin/csrbf CSRBF_MAKE_CGNS=build/bin/make_cgns_box /usr/bin/python3 -m unittest -v test_formats
"""
import json
import os
import subprocess
import unittest

from morph_case import MorphCase

import gmsh
import meshio
import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy

CLI = os.environ.get("CSRBF_CLI", "csrbf")
MAKE_CGNS = os.environ.get("CSRBF_MAKE_CGNS", "make_cgns_box")
LIFT = 0.04  # the bottom's translation


def run(args):
    return subprocess.run(args, capture_output=True, text=True, timeout=600)


def make_gmsh_box(path, version, binary, hexes=False):
    """A unit box, tetrahedra (or hexahedra by extrusion), physical surfaces bottom and top and the
    volume fluid, written by Gmsh itself."""
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("box")
    if hexes:
        p = [gmsh.model.geo.addPoint(x, y, 0, 0.2) for x, y in ((0, 0), (1, 0), (1, 1), (0, 1))]
        lines = [gmsh.model.geo.addLine(p[i], p[(i + 1) % 4]) for i in range(4)]
        loop = gmsh.model.geo.addCurveLoop(lines)
        base = gmsh.model.geo.addPlaneSurface([loop])
        for c in lines:
            gmsh.model.geo.mesh.setTransfiniteCurve(c, 6)
        gmsh.model.geo.mesh.setTransfiniteSurface(base)
        gmsh.model.geo.mesh.setRecombine(2, base)
        out = gmsh.model.geo.extrude([(2, base)], 0, 0, 1, numElements=[5], recombine=True)
        gmsh.model.geo.synchronize()
        top, volume = out[0][1], out[1][1]
        bottom = base
    else:
        volume = gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
        gmsh.model.occ.synchronize()
        bottom, top = 5, 6
        gmsh.option.setNumber("Mesh.CharacteristicLengthMax", 0.25)
    gmsh.model.addPhysicalGroup(2, [bottom], 1)
    gmsh.model.setPhysicalName(2, 1, "bottom")
    gmsh.model.addPhysicalGroup(2, [top], 2)
    gmsh.model.setPhysicalName(2, 2, "top")
    gmsh.model.addPhysicalGroup(3, [volume], 3)
    gmsh.model.setPhysicalName(3, 3, "fluid")
    gmsh.model.mesh.generate(3)
    gmsh.option.setNumber("Mesh.MshFileVersion", version)
    gmsh.option.setNumber("Mesh.Binary", 1 if binary else 0)
    gmsh.write(path)
    gmsh.finalize()


def read_gmsh(path):
    """Nodes by tag, physical groups, element counts and the minimum SICN, through Gmsh."""
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.open(path)
    tags, coord, _ = gmsh.model.mesh.getNodes(-1, -1, False, False)
    nodes = dict(zip(tags.tolist(), coord.reshape(-1, 3)))
    groups = {}
    for dim, tag in gmsh.model.getPhysicalGroups():
        pts = set()
        for e in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
            pts.update(gmsh.model.mesh.getNodes(dim, e, True, False)[0].tolist())
        groups[gmsh.model.getPhysicalName(dim, tag)] = pts
    types, elements, _ = gmsh.model.mesh.getElements(-1, -1)
    counts = {int(t): len(e) for t, e in zip(types, elements)}
    gmsh.plugin.setNumber("AnalyseMeshQuality", "ICNMeasure", 1)
    gmsh.plugin.setNumber("AnalyseMeshQuality", "CreateView", 1)
    gmsh.plugin.run("AnalyseMeshQuality")
    sicn = min(min(v[0] for v in gmsh.view.getModelData(t, 0)[2]) for t in gmsh.view.getTags())
    gmsh.finalize()
    return nodes, groups, counts, sicn


def read_vtk(path):
    reader = vtk.vtkXMLUnstructuredGridReader() if path.endswith(".vtu") else vtk.vtkUnstructuredGridReader()
    reader.SetFileName(path)
    if not path.endswith(".vtu"):
        reader.ReadAllScalarsOn()
        reader.ReadAllVectorsOn()
        reader.ReadAllFieldsOn()
    reader.Update()
    grid = reader.GetOutput()
    arrays = {}
    for kind, data in (("point", grid.GetPointData()), ("cell", grid.GetCellData())):
        for i in range(data.GetNumberOfArrays()):
            arrays[(kind, data.GetArrayName(i))] = vtk_to_numpy(data.GetArray(i)).copy()
    return vtk_to_numpy(grid.GetPoints().GetData()).astype(float), grid.GetNumberOfCells(), arrays, \
        grid.GetPoints().GetDataType()


class Formats(MorphCase):

    def morph(self, src, out, motion, *extra):
        r = run([CLI, "morph", src, "-o", out, "--motion", motion, "--json", *extra])
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        return json.loads(r.stdout)

    def test_gmsh_meshes_keep_version_encoding_and_groups(self):
        motion = self.motion({"radius": 0.7, "patches": {"bottom": {"translate": [0, 0, LIFT]}, "top": "fixed"}})
        for version, binary, hexes in ((4.1, False, False), (4.1, True, False), (2.2, False, False), (2.2, True, True),
                                       (4.1, False, True)):
            with self.subTest(version=version, binary=binary, hexes=hexes):
                src = os.path.join(self.tmp, "box-%s-%d-%d.msh" % (version, binary, hexes))
                out = src.replace(".msh", "-morphed.msh")
                make_gmsh_box(src, version, binary, hexes)
                report = self.morph(src, out, motion)
                self.assertEqual(report["encoding"], "msh %s %s" % (version, "binary" if binary else "ascii"))
                self.assertEqual(report["quality"]["after"]["inverted_cells"], 0)
                with open(src, "rb") as f, open(out, "rb") as g:
                    a, b = f.read(), g.read()
                self.assertTrue(b.startswith(b"$MeshFormat\n%s %d 8" % (str(version).encode(), int(binary))), b[:40])
                # Every byte outside $Nodes is kept, and so is the section's size in binary.
                self.assertEqual(a[:a.index(b"$Nodes")], b[:b.index(b"$Nodes")])
                self.assertEqual(a[a.index(b"$EndNodes"):], b[b.index(b"$EndNodes"):])
                if binary:
                    self.assertEqual(len(a), len(b))
                nodes0, groups0, counts0, sicn0 = read_gmsh(src)
                nodes1, groups1, counts1, sicn1 = read_gmsh(out)
                self.assertEqual(sorted(nodes0), sorted(nodes1))
                self.assertEqual(groups0, groups1)
                self.assertEqual(counts0, counts1)
                self.assertGreater(sicn0, 0)
                self.assertGreater(sicn1, 0)
                moved = 0
                for tag in groups0["bottom"]:
                    self.assertLess(np.abs(nodes1[tag] - nodes0[tag] - [0, 0, LIFT]).max(), 1e-12)
                for tag in groups0["top"] - groups0["bottom"]:
                    self.assertTrue(np.array_equal(nodes1[tag], nodes0[tag]))
                for tag in set(nodes0) - groups0["bottom"] - groups0["top"]:
                    moved += not np.array_equal(nodes1[tag], nodes0[tag])
                self.assertGreater(moved, 0)
                m = meshio.read(out)
                self.assertEqual(len(m.points), len(nodes0))

    def test_bundled_airfoil_msh_pitches(self):
        here = os.path.join(os.environ.get("CSRBF_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", "..")),
                            "examples", "airfoil")
        out = os.path.join(self.tmp, "pitched.msh")
        report = self.morph(os.path.join(here, "airfoil.msh"), out, os.path.join(here, "motion.json"))
        self.assertEqual(report["cells"], 3840)
        self.assertEqual(report["quality"]["after"]["inverted_cells"], 0)
        nodes0, groups0, counts0, sicn0 = read_gmsh(os.path.join(here, "airfoil.msh"))
        nodes1, groups1, counts1, sicn1 = read_gmsh(out)
        self.assertEqual(groups0, groups1)
        self.assertEqual(counts0, counts1)
        self.assertGreater(sicn1, 0)
        for tag in groups0["farfield"]:
            self.assertTrue(np.array_equal(nodes0[tag], nodes1[tag]))

    def test_gmsh_displacements_use_node_tags(self):
        src = os.path.join(self.tmp, "box.msh")
        make_gmsh_box(src, 4.1, False)
        nodes, groups, _, _ = read_gmsh(src)
        with open(os.path.join(self.tmp, "lift.txt"), "w") as f:
            for tag in sorted(groups["bottom"]):
                f.write("%d 0 0 %r\n" % (tag, LIFT * nodes[tag][0]))
        motion = self.motion({"radius": 0.7, "patches": {"bottom": {"displacements": "lift.txt"}, "top": "fixed"}})
        out = os.path.join(self.tmp, "lifted.msh")
        self.morph(src, out, motion)
        after, _, _, sicn = read_gmsh(out)
        for tag in groups["bottom"]:
            self.assertAlmostEqual(after[tag][2], LIFT * nodes[tag][0], delta=1e-14)
        self.assertGreater(sicn, 0)
        with open(os.path.join(self.tmp, "lift.txt"), "a") as f:
            f.write("999999 0 0 0\n")
        r = run([CLI, "morph", src, "-o", os.path.join(self.tmp, "x.msh"), "--motion", motion])
        self.assertEqual(r.returncode, 1)
        self.assertIn("lift.txt:%d: point 999999 is not a node of the mesh" % (len(groups["bottom"]) + 1), r.stderr)
        self.assertFalse(os.path.exists(os.path.join(self.tmp, "x.msh")))

    def vtk_inputs(self):
        """The Gmsh box as .vtu (ascii, binary, appended+zlib) and .vtk (ascii, binary), through VTK's
        writers, with the cell array gmsh_physical naming the patches and a point array to keep."""
        src = os.path.join(self.tmp, "box.msh")
        make_gmsh_box(src, 4.1, False)
        m = meshio.read(src)
        grid = vtk.vtkUnstructuredGrid()
        pts = vtk.vtkPoints()
        pts.SetDataTypeToDouble()
        for p in m.points:
            pts.InsertNextPoint(*p)
        grid.SetPoints(pts)
        physical = vtk.vtkIntArray()
        physical.SetName("gmsh_physical")
        kinds = {"triangle": vtk.VTK_TRIANGLE, "tetra": vtk.VTK_TETRA}
        for block, tags in zip(m.cells, m.cell_data["gmsh:physical"]):
            for cell, tag in zip(block.data, tags):
                ids = vtk.vtkIdList()
                for v in cell:
                    ids.InsertNextId(int(v))
                grid.InsertNextCell(kinds[block.type], ids)
                physical.InsertNextValue(int(tag))
        grid.GetCellData().AddArray(physical)
        temperature = vtk.vtkDoubleArray()
        temperature.SetName("temperature")
        for i in range(len(m.points)):
            temperature.InsertNextValue(300.0 + i)
        grid.GetPointData().AddArray(temperature)
        out = []
        for name, mode in (("ascii.vtu", "ascii"), ("binary.vtu", "binary"), ("appended.vtu", "appended")):
            w = vtk.vtkXMLUnstructuredGridWriter()
            w.SetFileName(os.path.join(self.tmp, name))
            w.SetInputData(grid)
            getattr(w, "SetDataModeTo" + mode.capitalize())()
            w.Write()
            out.append(os.path.join(self.tmp, name))
        for name, binary in (("ascii.vtk", False), ("binary.vtk", True)):
            w = vtk.vtkUnstructuredGridWriter()
            w.SetFileName(os.path.join(self.tmp, name))
            w.SetInputData(grid)
            w.SetFileTypeToBinary() if binary else w.SetFileTypeToASCII()
            if binary:
                w.SetFileVersion(42)  # meshio 7.0 reads VTK 9's default 5.1 legacy binary wrongly
            w.Write()
            out.append(os.path.join(self.tmp, name))
        return out

    def test_vtk_grids_keep_arrays_and_encoding(self):
        motion = self.motion({"radius": 0.7, "patch_array": "gmsh_physical",
                              "patches": {"1": {"translate": [0, 0, LIFT]}, "2": "fixed"}})
        for src in self.vtk_inputs():
            with self.subTest(src=os.path.basename(src)):
                out = src.replace("box", "out").replace(".vt", "-morphed.vt")
                out = os.path.join(self.tmp, "morphed-" + os.path.basename(src))
                report = self.morph(src, out, motion)
                self.assertEqual(len(meshio.read(src).points), report["points"])
                p0, n0, a0, t0 = read_vtk(src)
                p1, n1, a1, t1 = read_vtk(out)
                self.assertEqual(n0, n1)
                self.assertEqual(t0, t1)
                self.assertEqual(sorted(a0), sorted(a1))
                for k in a0:
                    self.assertTrue(np.array_equal(a0[k], a1[k]), k)
                bottom = np.isclose(p0[:, 2], 0.0)
                top = np.isclose(p0[:, 2], 1.0)
                self.assertLess(np.abs(p1[bottom] - p0[bottom] - [0, 0, LIFT]).max(), 1e-12)
                self.assertTrue(np.array_equal(p1[top], p0[top]))
                self.assertGreater(report["quality"]["after"]["cells"]["min_scaled_jacobian"], 0)
                if src.endswith(".vtu"):
                    with open(src, "rb") as f, open(out, "rb") as g:
                        a, b = f.read(400), g.read(400)
                    for marker in (b'format="ascii"', b'format="binary"', b'format="appended"', b"vtkZLibDataCompressor"):
                        self.assertEqual(marker in a, marker in b, marker)
                else:
                    with open(src, "rb") as f, open(out, "rb") as g:
                        self.assertEqual(f.read(200).split(b"\n")[2], g.read(200).split(b"\n")[2])
                m = meshio.read(out)
                self.assertEqual(len(m.points), len(p0))
        r = run([CLI, "morph", os.path.join(self.tmp, "ascii.vtu"), "-o", os.path.join(self.tmp, "x.vtu"), "--motion",
                 self.motion({"radius": 0.7, "patches": {"1": "fixed"}})])
        self.assertEqual(r.returncode, 1)
        self.assertIn("patch_array", r.stderr)
        r = run([CLI, "morph", os.path.join(self.tmp, "ascii.vtu"), "-o", os.path.join(self.tmp, "x.vtu"), "--motion",
                 self.motion({"radius": 0.7, "patch_array": "nope", "patches": {"1": "fixed"}})])
        self.assertEqual(r.returncode, 1)
        self.assertIn("its arrays: temperature, gmsh_physical", r.stderr)
        self.assertFalse(os.path.exists(os.path.join(self.tmp, "x.vtu")))

    def test_cgns_is_read_back_by_meshio(self):
        src = os.path.join(self.tmp, "box.cgns")
        self.assertEqual(run([MAKE_CGNS, src, "5", "double", "tets"]).returncode, 0)
        motion = self.motion({"radius": 0.6, "patches": {"bottom": {"translate": [0, 0, LIFT]}, "lid": "fixed"}})
        out = os.path.join(self.tmp, "morphed.cgns")
        report = self.morph(src, out, motion)
        self.assertEqual(report["quality"]["after"]["cells"]["tetrahedra"], 750)
        self.assertEqual(report["quality"]["after"]["inverted_cells"], 0)
        a, b = meshio.read(src), meshio.read(out)
        bottom = np.isclose(a.points[:, 2], 0.0)
        top = np.isclose(a.points[:, 2], 1.0)
        self.assertLess(np.abs(b.points[bottom] - a.points[bottom] - [0, 0, LIFT]).max(), 1e-12)
        self.assertTrue(np.array_equal(b.points[top], a.points[top]))
        self.assertTrue(np.array_equal(a.cells_dict["tetra"], b.cells_dict["tetra"]))


if __name__ == "__main__":
    unittest.main()
