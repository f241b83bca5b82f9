#!/usr/bin/env python3
"""Writes a 2-D O-mesh around a NACA 0012 airfoil (chord 1, one cell thick in z) as an OpenFOAM
case (case/constant/polyMesh and the system files checkMesh needs) and as a Gmsh 2.2 mesh
(airfoil.msh: hexahedra in the physical volume "fluid", quadrilaterals in the physical surfaces
"airfoil", "farfield" and "frontAndBack"). Made here, from the NACA formula: no mesh is copied from
another project.

    /usr/bin/python3 examples/airfoil/make_airfoil.py [OUT_FOLDER]   (default: next to this script)

Cells: N_AROUND around the airfoil times N_OUT outwards, hexahedra; patches: airfoil (wall),
farfield (patch), frontAndBack (empty)."""
import math
import os
import sys

N_AROUND, N_OUT = 96, 40
FARFIELD = 20.0          # radius of the outer circle, in chords, about the mid-chord
FIRST = 0.004            # thickness of the first cell layer on the airfoil
HALF_DEPTH = 0.05        # z from -HALF_DEPTH to +HALF_DEPTH
CLUSTER = 0.9            # 0: uniform along the chord, 1: cosine (dense at both edges)
BLEND = 0.25             # how far the mesh lines keep to the surface normal

BANNER = r"""/*--------------------------------*- C++ -*----------------------------------*\
  csrbf example: NACA 0012 O-mesh, written by examples/airfoil/make_airfoil.py
\*---------------------------------------------------------------------------*/
"""


def thickness(x):
    # NACA 0012 half thickness, with the closed trailing edge coefficient -0.1036.
    return 0.6 * (0.2969 * math.sqrt(x) - 0.1260 * x - 0.3516 * x**2 + 0.2843 * x**3 - 0.1036 * x**4)


def chord_position(u):
    # u from 0 (trailing edge) to 1 (leading edge): cosine clustering at the leading edge, blended
    # with uniform spacing so that the cells at the sharp trailing edge are not needlessly thin.
    return CLUSTER * 0.5 * (1 + math.cos(math.pi * u)) + (1 - CLUSTER) * (1 - u)


def airfoil_point(i):
    t = i / N_AROUND
    if t < 0.5:  # upper surface, trailing edge to leading edge
        x = chord_position(2 * t)
        return x, thickness(x)
    x = chord_position(2 - 2 * t)  # lower surface, leading edge to trailing edge
    return x, -thickness(x)


def line_point(i, f):
    # The mesh line from airfoil point i to the far field, at fraction f of the way: a quadratic
    # Bezier curve that leaves the surface along its normal and meets the outer circle at uniform
    # angles, so near-wall cells are orthogonal and far cells even.
    ax, ay = airfoil_point(i)
    px, py = airfoil_point((i - 1) % N_AROUND)
    nx_, ny_ = airfoil_point((i + 1) % N_AROUND)
    tx, ty = nx_ - px, ny_ - py
    n = math.hypot(tx, ty)
    th = 2 * math.pi * i / N_AROUND
    cx, cy = 0.5 + FARFIELD * math.cos(th), FARFIELD * math.sin(th)
    reach = BLEND * math.hypot(cx - ax, cy - ay)
    bx, by = ax + reach * ty / n, ay - reach * tx / n
    return ((1 - f)**2 * ax + 2 * f * (1 - f) * bx + f * f * cx, (1 - f)**2 * ay + 2 * f * (1 - f) * by + f * f * cy)


def growth():
    # Layer thicknesses FIRST * g^k, k < N_OUT, summing to 1 (fractions of the way out): bisection on g.
    lo, hi = 1.0, 2.0
    for _ in range(200):
        g = 0.5 * (lo + hi)
        total = FIRST * (g**N_OUT - 1) / (g - 1) / (FARFIELD - 0.5)
        lo, hi = (g, hi) if total < 1 else (lo, g)
    g = 0.5 * (lo + hi)
    f, out = 0.0, [0.0]
    for k in range(N_OUT):
        f += FIRST * g**k / (FARFIELD - 0.5)
        out.append(f)
    return [v / out[-1] for v in out]


def header(cls, obj, note=None):
    s = BANNER + "FoamFile\n{\n    version     2.0;\n    format      ascii;\n"
    s += "    class       %s;\n" % cls
    if note:
        s += '    note        "%s";\n' % note
    s += '    location    "constant/polyMesh";\n' if obj in ("points", "faces", "owner", "neighbour", "boundary") else ""
    s += "    object      %s;\n}\n" % obj
    s += "// * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * * //\n\n"
    return s


def mesh():
    f = growth()
    pts = []
    for k, z in enumerate((-HALF_DEPTH, HALF_DEPTH)):
        for j in range(N_OUT + 1):
            for i in range(N_AROUND):
                pts.append(line_point(i, f[j]) + (z,))
    layer = N_AROUND * (N_OUT + 1)

    def p(i, j, k):
        return k * layer + j * N_AROUND + (i % N_AROUND)

    def cell(i, j):
        return j * N_AROUND + (i % N_AROUND)

    def centre(c):
        j, i = divmod(c, N_AROUND)
        q = [pts[p(a, b, k)] for a in (i, i + 1) for b in (j, j + 1) for k in (0, 1)]
        return tuple(sum(v[d] for v in q) / 8 for d in range(3))

    def normal(face):
        # Newell's area vector of a planar quadrilateral.
        n = [0.0, 0.0, 0.0]
        for a in range(len(face)):
            u, v = pts[face[a]], pts[face[(a + 1) % len(face)]]
            n[0] += (u[1] - v[1]) * (u[2] + v[2])
            n[1] += (u[2] - v[2]) * (u[0] + v[0])
            n[2] += (u[0] - v[0]) * (u[1] + v[1])
        return n

    def oriented(face, frm, to):
        # The face's normal must point from frm to to.
        n = normal(face)
        d = [to[k] - frm[k] for k in range(3)]
        return face if sum(n[k] * d[k] for k in range(3)) > 0 else face[::-1]

    def face_centre(face):
        return tuple(sum(pts[v][d] for v in face) / len(face) for d in range(3))

    internal = []
    for j in range(N_OUT):
        for i in range(N_AROUND):
            c = cell(i, j)
            # to the next cell around (wrapping) and to the next cell out
            nb = [(cell(i + 1, j), [p(i + 1, j, 0), p(i + 1, j + 1, 0), p(i + 1, j + 1, 1), p(i + 1, j, 1)])]
            if j + 1 < N_OUT:
                nb.append((cell(i, j + 1), [p(i, j + 1, 0), p(i + 1, j + 1, 0), p(i + 1, j + 1, 1), p(i, j + 1, 1)]))
            for n, face in nb:
                own, nei = min(c, n), max(c, n)
                internal.append((own, nei, oriented(face, centre(own), centre(nei))))
    internal.sort(key=lambda e: (e[0], e[1]))
    patches = []
    airfoil = [(cell(i, 0), [p(i, 0, 0), p(i + 1, 0, 0), p(i + 1, 0, 1), p(i, 0, 1)]) for i in range(N_AROUND)]
    far = [(cell(i, N_OUT - 1), [p(i, N_OUT, 0), p(i + 1, N_OUT, 0), p(i + 1, N_OUT, 1), p(i, N_OUT, 1)])
           for i in range(N_AROUND)]
    fb = []
    for j in range(N_OUT):
        for i in range(N_AROUND):
            for k in (0, 1):
                fb.append((cell(i, j), [p(i, j, k), p(i + 1, j, k), p(i + 1, j + 1, k), p(i, j + 1, k)]))
    fb.sort(key=lambda e: e[0])
    for name, kind, faces in (("airfoil", "wall", airfoil), ("farfield", "patch", far), ("frontAndBack", "empty", fb)):
        out = []
        for own, face in faces:
            out.append((own, oriented(face, centre(own), face_centre(face))))
        patches.append((name, kind, out))
    return pts, internal, patches


def write_case(root):
    pts, internal, patches = mesh()
    poly = os.path.join(root, "constant", "polyMesh")
    os.makedirs(poly, exist_ok=True)
    os.makedirs(os.path.join(root, "system"), exist_ok=True)
    faces = [f for _, _, f in internal] + [f for _, _, fs in patches for _, f in fs]
    owner = [o for o, _, _ in internal] + [o for _, _, fs in patches for o, _ in fs]
    cells = N_AROUND * N_OUT
    note = "nPoints:%d  nCells:%d  nFaces:%d  nInternalFaces:%d" % (len(pts), cells, len(faces), len(internal))

    def fmt(v):
        return repr(round(v, 12) + 0.0)

    with open(os.path.join(poly, "points"), "w") as o:
        o.write(header("vectorField", "points"))
        o.write("%d\n(\n" % len(pts))
        o.writelines("(%s %s %s)\n" % (fmt(x), fmt(y), fmt(z)) for x, y, z in pts)
        o.write(")\n")
    with open(os.path.join(poly, "faces"), "w") as o:
        o.write(header("faceList", "faces"))
        o.write("%d\n(\n" % len(faces))
        o.writelines("%d(%s)\n" % (len(f), " ".join(map(str, f))) for f in faces)
        o.write(")\n")
    for name, values in (("owner", owner), ("neighbour", [n for _, n, _ in internal])):
        with open(os.path.join(poly, name), "w") as o:
            o.write(header("labelList", name, note))
            o.write("%d\n(\n" % len(values))
            o.writelines("%d\n" % v for v in values)
            o.write(")\n")
    with open(os.path.join(poly, "boundary"), "w") as o:
        o.write(header("polyBoundaryMesh", "boundary"))
        o.write("%d\n(\n" % len(patches))
        start = len(internal)
        for name, kind, fs in patches:
            o.write("    %s\n    {\n        type            %s;\n" % (name, kind))
            if kind == "wall":
                o.write("        inGroups        1(wall);\n")
            o.write("        nFaces          %d;\n        startFace       %d;\n    }\n" % (len(fs), start))
            start += len(fs)
        o.write(")\n")
    system = {
        "controlDict": "application simpleFoam;\nstartFrom startTime;\nstartTime 0;\nstopAt endTime;\nendTime 1;\n"
                       "deltaT 1;\nwriteControl timeStep;\nwriteInterval 1;\nwriteFormat ascii;\nwritePrecision 12;\n"
                       "writeCompression off;\ntimeFormat general;\ntimePrecision 6;\nrunTimeModifiable false;\n",
        "fvSchemes": "ddtSchemes { default steadyState; }\ngradSchemes { default Gauss linear; }\n"
                     "divSchemes { default none; }\nlaplacianSchemes { default Gauss linear corrected; }\n"
                     "interpolationSchemes { default linear; }\nsnGradSchemes { default corrected; }\n",
        "fvSolution": "solvers { }\nSIMPLE { nNonOrthogonalCorrectors 0; }\n",
    }
    for name, body in system.items():
        with open(os.path.join(root, "system", name), "w") as o:
            o.write(BANNER + "FoamFile\n{\n    version     2.0;\n    format      ascii;\n    class       dictionary;\n"
                    '    location    "system";\n    object      %s;\n}\n\n' % name + body)


def write_msh(path):
    """The same mesh as Gmsh 2.2 ASCII: node tags are the OpenFOAM point numbers + 1."""
    pts, internal, patches = mesh()
    layer = N_AROUND * (N_OUT + 1)

    def p(i, j, k):
        return k * layer + j * N_AROUND + (i % N_AROUND) + 1

    elements = []
    names = {"airfoil": 1, "farfield": 2, "frontAndBack": 3, "fluid": 4}
    for name, _, faces in patches:
        for _, face in faces:
            elements.append((3, names[name], [v + 1 for v in face]))
    for j in range(N_OUT):
        for i in range(N_AROUND):
            # Gmsh's (and VTK's) corner order, bottom face anticlockwise seen from +z.
            bottom = [p(i, j, 0), p(i, j + 1, 0), p(i + 1, j + 1, 0), p(i + 1, j, 0)]
            elements.append((5, names["fluid"], bottom + [v + layer for v in bottom]))
    with open(path, "w") as o:
        o.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n%d\n" % len(names))
        for name, tag in names.items():
            o.write('%d %d "%s"\n' % (3 if name == "fluid" else 2, tag, name))
        o.write("$EndPhysicalNames\n$Nodes\n%d\n" % len(pts))
        o.writelines("%d %r %r %r\n" % (k + 1, round(x, 12) + 0.0, round(y, 12) + 0.0, z) for k, (x, y, z) in enumerate(pts))
        o.write("$EndNodes\n$Elements\n%d\n" % len(elements))
        for k, (kind, tag, nodes) in enumerate(elements):
            o.write("%d %d 2 %d %d %s\n" % (k + 1, kind, tag, tag, " ".join(map(str, nodes))))
        o.write("$EndElements\n")


if __name__ == "__main__":
    here = os.path.dirname(os.path.abspath(__file__))
    out = sys.argv[1] if len(sys.argv) > 1 else here
    write_case(os.path.join(out, "case"))
    write_msh(os.path.join(out, "airfoil.msh"))
