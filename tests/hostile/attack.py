"""The hostile-case generator (issue 30): seeded mutations of every input csrbf reads (controls,
deformation and scene JSON, OBJ, PLY, OFF, legacy VTK, Gmsh, motion JSON) and of its options, each
run through the program with a time limit. Every case must end (no hang) with exit 0, 1 or 2, never
die of a signal, print no raw control character, leave no partial file and no output that is an
input, and change no input. Every deform and morph runs under a --memory-limit (0.25, 1 or the
default 4 GiB, unless the case sets its own), and its peak resident memory, csrbf's or any reading
child's, measured by wait4, stays within the limit plus 10 % (limits below 0.25 GiB, smaller than the
program itself with its libraries, are not measured).

    CSRBF_CLI=build/bin/csrbf CSRBF_SOURCE_DIR=. /usr/bin/python3 tests/hostile/attack.py [CASES] [SEED]

CTest runs 250 cases; `attack.py 2000` runs the full set (about five minutes on 2 cores).
"""
import hashlib
import json
import math
import os
import random
import shutil
import subprocess
import sys
import tempfile
import time

CLI = os.environ.get("CSRBF_CLI", "csrbf")
SOURCE = os.environ.get("CSRBF_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
EX = os.path.join(SOURCE, "examples")

NUMBERS = ["0", "-1", "1", "2", "3", "7", "42", "99", "255", "65536", "2147483647", "4294967296",
           "-2147483648", "18446744073709551615", "1e308", "1e-320", "nan", "inf", "-inf", "1e30", "0.5",
           "", "x", "\x00", "\x1b[2J", "1/2/3/4", "[", "{", "\"", "99999999999999999999"]


def digest(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def mutate_text(rng, text):
    """Replace, delete, duplicate or cut: tokens and lines, as a fuzzer would."""
    lines = text.split("\n")
    for _ in range(rng.randint(1, 4)):
        what = rng.random()
        i = rng.randrange(len(lines))
        if what < 0.55:
            parts = lines[i].split(" ")
            parts[rng.randrange(len(parts))] = rng.choice(NUMBERS)
            lines[i] = " ".join(parts)
        elif what < 0.7:
            del lines[i]
            if not lines:
                lines = [""]
        elif what < 0.85:
            lines.insert(i, lines[i])
        else:
            lines = lines[: i + 1]
            lines[-1] = lines[-1][: rng.randrange(len(lines[-1]) + 1)]
    return "\n".join(lines)


def mutate_json(rng, value, depth=0):
    if isinstance(value, dict) and value:
        k = rng.choice(list(value))
        r = rng.random()
        if r < 0.15:
            del value[k]
        elif r < 0.3:
            value[k + rng.choice(["", "\u0000", "\u001b", "_x"])] = value.pop(k)
        else:
            value[k] = mutate_json(rng, value[k], depth + 1)
        return value
    if isinstance(value, list) and value:
        i = rng.randrange(len(value))
        r = rng.random()
        if r < 0.2:
            del value[i]
        elif r < 0.3:
            value.append(value[i])
        else:
            value[i] = mutate_json(rng, value[i], depth + 1)
        return value
    return rng.choice([0, -1, 1e308, -1e308, 1e-320, 2 ** 64, "x", "\u001b", None, True, [], {}, [0, 0],
                       "../../../etc/passwd", "/dev/zero", 0.5, 3])


def legacy_vtk():
    return ("# vtk DataFile Version 4.2\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 double\n"
            "0 0 0 1 0 0 0 1 0 0 0 1 0 0 -1\nCELLS 2 10\n4 0 1 2 3\n4 0 2 1 4\nCELL_TYPES 2\n10\n10\n"
            "POINT_DATA 5\nSCALARS p int 1\nLOOKUP_TABLE default\n1 1 1 2 2\n")


def gmsh():
    return ("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n2\n2 1 \"base\"\n3 2 \"solid\"\n"
            "$EndPhysicalNames\n$Nodes\n5\n10 0 0 0\n11 1 0 0\n12 0 1 0\n13 0 0 1\n14 0 0 -1\n$EndNodes\n"
            "$Elements\n3\n1 2 2 1 1 10 11 12\n2 4 2 2 2 10 11 12 13\n3 4 2 2 2 10 12 11 14\n$EndElements\n")


def ply():
    return ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")


def run_case(argv, env, d, timeout):
    """Runs csrbf with argv; returns (exit code, output, peak RSS in KiB), or None when it hung."""
    log = os.path.join(d, ".log")
    with open(log, "wb") as out:
        p = subprocess.Popen([CLI] + argv, env=env, stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
    deadline = time.monotonic() + timeout
    while True:
        pid, status, usage = os.wait4(p.pid, os.WNOHANG)
        if pid:
            break
        if time.monotonic() > deadline:
            p.kill()
            os.wait4(p.pid, 0)
            os.remove(log)
            return None
        time.sleep(0.01)
    p.returncode = os.waitstatus_to_exitcode(status)
    with open(log, "rb") as f:
        text = f.read()
    os.remove(log)
    return p.returncode, text, usage.ru_maxrss


def memory_limit_gib(argv):
    """The --memory-limit a case runs under (GiB), or None when it is not a number CLI11 takes."""
    if "--memory-limit" not in argv:
        return 4.0
    try:
        v = float(argv[argv.index("--memory-limit") + 1])
    except (ValueError, IndexError):
        return None
    return v if math.isfinite(v) and v > 0 else None


def make_case(rng, d, k):
    """Writes the inputs of case k into d; returns (argv after csrbf, the inputs)."""
    kind = k % 10
    with open(os.path.join(EX, "fish.controls")) as f:
        controls = f.read()
    with open(os.path.join(EX, "fish.obj")) as f:
        obj = f.read()
    out = os.path.join(d, rng.choice(["out.obj", "out.ply", "out.gltf", "out.stl", "o\u001b.obj", "out.xyz"]))
    if kind == 0:  # controls
        p = os.path.join(d, "c.controls")
        open(p, "w", errors="surrogateescape").write(mutate_text(rng, controls))
        return ["deform", "--mesh", os.path.join(EX, "fish.obj"), "--controls", p, "--radius",
                rng.choice(["0.3", "1e-150", "1e150", "0.05", "5"]), "-o", out], [p]
    if kind == 1:  # mesh formats
        fmt = rng.choice(["obj", "ply", "off"])
        text = {"obj": obj, "ply": ply(), "off": "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"}[fmt]
        p = os.path.join(d, "m." + fmt)
        open(p, "w").write(mutate_text(rng, text))
        return ["deform", "--mesh", p, "--controls", os.path.join(EX, "fish.controls"), "--radius", "0.3",
                "-o", out], [p]
    if kind == 2:  # deformation JSON
        j = {"format": "csrbf-deformation", "version": 1, "kernel": "c2", "radius": 0.3, "polynomial": "none",
             "phase": 0.5, "sources": [[0.8, 0.6, 0.5], [0.5, 0.5, 0.5]],
             "destinations": [[0.8, 0.6, 0.55], [0.5, 0.5, 0.5]]}
        for _ in range(rng.randint(1, 3)):
            j = mutate_json(rng, j)
        p = os.path.join(d, "d.json")
        open(p, "w").write(json.dumps(j))
        return ["deform", "--mesh", os.path.join(EX, "fish.obj"), "--deformation", p, "-o", out], [p]
    if kind == 3:  # scene JSON, exported
        with open(os.path.join(EX, "fish.scene.json")) as f:
            j = json.load(f)
        for _ in range(rng.randint(1, 3)):
            j = mutate_json(rng, j)
        p = os.path.join(d, "s.json")
        open(p, "w").write(json.dumps(j))
        for n in os.listdir(EX):
            if n.startswith("fish") and not os.path.exists(os.path.join(d, n)):
                shutil.copy(os.path.join(EX, n), d)
        return ["export", p, "-o", os.path.join(d, rng.choice(["x.glb", "x.gltf", "fish.obj"]))], \
            [p] + [os.path.join(d, n) for n in os.listdir(d) if n.startswith("fish")]
    if kind in (4, 5):  # volume meshes: legacy VTK, Gmsh
        vtk = kind == 4
        p = os.path.join(d, "v.vtk" if vtk else "v.msh")
        open(p, "w").write(mutate_text(rng, legacy_vtk() if vtk else gmsh()))
        m = os.path.join(d, "m.json")
        motion = {"radius": 3, "patches": {"2" if vtk else "base": {"translate": [0, 0, 0.01]}}}
        if vtk:
            motion["patch_array"] = "p"
        open(m, "w").write(json.dumps(motion))
        return ["morph", p, "--motion", m, "-o", os.path.join(d, "o.vtk" if vtk else "o.msh")], [p, m]
    if kind == 6:  # motion JSON
        p = os.path.join(d, "v.msh")
        open(p, "w").write(gmsh())
        motion = {"radius": 3, "kernel": "c2", "polynomial": "none",
                  "patches": {"base": {"rotate": {"axis": [0, 0, 1], "degrees": 5, "origin": [0, 0, 0]}}}}
        for _ in range(rng.randint(1, 3)):
            motion = mutate_json(rng, motion)
        m = os.path.join(d, "m.json")
        open(m, "w").write(json.dumps(motion))
        return ["morph", p, "--motion", m, "-o", os.path.join(d, "o.msh")], [p, m]
    if kind == 7:  # options
        opts = ["--radius", rng.choice(NUMBERS[:20]), "--kernel", rng.choice(["c0", "c2", "c9", "\u001b"]),
                "--polynomial", rng.choice(["none", "linear", "constant", "cubic"]), "--phase",
                rng.choice(["0", "1", "0.5", "nan", "2", "-1"]), "--memory-limit",
                rng.choice(["4", "1e-6", "0", "nan", "1e7"]), "--solver", rng.choice(["auto", "cg", "lu", "mumps"])]
        rng.shuffle(opts)
        return ["deform", "--mesh", os.path.join(EX, "fish.obj"), "--controls", os.path.join(EX, "fish.controls"),
                "-o", out] + opts[: rng.randint(2, len(opts))], []
    if kind == 9:  # a fit too large for its limits: refused, or ended by --time-limit, or done within them
        n = rng.choice([2000, 8000, 20000])
        p = os.path.join(d, "big.controls")
        with open(p, "w") as f:
            for _ in range(n):
                x, y, z = rng.random(), rng.random(), rng.random()
                f.write("%.6f %.6f %.6f %.6f %.6f %.6f\n" % (x, y, z, x, y, z + 0.01 * rng.random()))
        return ["deform", "--mesh", os.path.join(EX, "fish.obj"), "--controls", p, "--radius",
                rng.choice(["0.05", "0.2", "0.5", "3"]), "--solver", rng.choice(["auto", "cholmod", "eigen", "envelope",
                                                                                  "cg"]),
                "--memory-limit", rng.choice(["0.25", "0.5", "1"]), "--time-limit", "20", "-o", out], [p]
    # kind 8: an output that is an input, by name or link
    shutil.copy(os.path.join(EX, "fish.obj"), os.path.join(d, "in.obj"))
    shutil.copy(os.path.join(EX, "fish.controls"), os.path.join(d, "in.controls"))
    target = rng.choice(["in.obj", "in.controls"])
    link = os.path.join(d, "link" + rng.choice([".obj", ".ply"]))
    if rng.random() < 0.5:
        os.symlink(os.path.join(d, target), link)
    else:
        os.link(os.path.join(d, target), link)
    return ["deform", "--mesh", os.path.join(d, "in.obj"), "--controls", os.path.join(d, "in.controls"),
            "--radius", "0.3", "-o", rng.choice([link, os.path.join(d, target)])], \
        [os.path.join(d, "in.obj"), os.path.join(d, "in.controls")]


def main():
    cases = int(sys.argv[1]) if len(sys.argv) > 1 else 250
    seed = int(sys.argv[2]) if len(sys.argv) > 2 else 30
    rng = random.Random(seed)
    env = dict(os.environ)
    env.pop("DISPLAY", None)
    env["CSRBF_PIPE_TIMEOUT"] = "5"
    failures = []
    peaks = []
    for k in range(cases):
        d = tempfile.mkdtemp(prefix="csrbf-attack-")
        try:
            argv, inputs = make_case(rng, d, k)
            if argv[0] in ("deform", "morph") and "--memory-limit" not in argv:
                argv += ["--memory-limit", rng.choice(["0.25", "1", "4"])]
            before = {p: digest(p) for p in inputs if os.path.isfile(p)}
            ran = run_case(argv, env, d, 120)
            if ran is None:
                failures.append((k, argv, "hung (120 s)"))
                continue
            code, text, peak_kib = ran
            problems = []
            if code not in (0, 1, 2):
                problems.append("exit %d" % code)
            limit = memory_limit_gib(argv)
            if argv[0] in ("deform", "morph") and limit is not None and limit >= 0.25 and \
                    peak_kib > 1.1 * limit * 1024 * 1024:
                problems.append("peak memory %.0f MiB over the %g GiB limit" % (peak_kib / 1024, limit))
            peaks.append(peak_kib)
            if any(b < 0x20 and b not in (0x0a, 0x09) or b == 0x7f for b in text):
                problems.append("a raw control character in the output")
            if code != 0 and b"csrbf: error: " not in text and b"csrbf: " not in text and code != 2:
                problems.append("a failure without a message")
            for p, h in before.items():
                if not os.path.isfile(p) or digest(p) != h:
                    problems.append("input %s changed" % os.path.basename(p))
            left = [n for n in os.listdir(d) if ".csrbf-partial-" in n]
            if left:
                problems.append("partials left: %s" % left)
            if problems:
                failures.append((k, argv, "; ".join(problems) + " | " + text[-300:].decode("utf-8", "replace")))
        finally:
            shutil.rmtree(d, ignore_errors=True)
    for k, argv, why in failures:
        print("case %d: csrbf %s\n  %s" % (k, " ".join(repr(a) for a in argv), why))
    print("attack: %d cases (seed %d), %d failed; peak memory of a case: largest %.0f MiB" %
          (cases, seed, len(failures), max(peaks, default=0) / 1024))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
