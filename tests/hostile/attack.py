"""The hostile-case generator (issue 30): seeded mutations of every input csrbf reads (controls,
deformation and scene JSON, OBJ, PLY, OFF, legacy VTK, Gmsh, motion JSON) and of its options, each
run through the program with a time limit. Every case must end (no hang) with exit 0, 1 or 2, never
die of a signal, print no raw control character, leave no partial file and no output that is an
input, and change no input. Every deform, morph and export runs under a --memory-limit (0.25, 1 or the
default 4 GiB, unless the case sets its own), and its peak resident memory, csrbf's or any reading
child's, measured by wait4, stays within the limit plus 10 % (limits below 0.25 GiB, smaller than the
program itself with its libraries, are not measured).

Beyond the inputs, one case in 14 of each of these:
- faults: a good deform, export or morph under a full disk (`ulimit -f`), an address-space limit,
  SIGINT, SIGTERM, SIGHUP or SIGKILL at a random moment, or three copies racing for one new output:
  every output that exists equals the one a clean run writes, and a failed or interrupted run leaves
  no output and (but for SIGKILL) no partial;
- Python: csrbf.SpaceMap and its calls with hostile arrays, dtypes, shapes, radii and limits: only
  ValueError, TypeError, MemoryError, OverflowError or OSError, never a crash;
- MPI (when mpirun is found): mutated controls and meshes under `mpirun -np 2`;
- GUIs (when CSRBF_COMPOSER, CSRBF_PICKER and a DISPLAY are given): mutated scenes and meshes opened
  by csrbf-composer and csrbf-picker with --screenshot: exit 0, 1 or 2, never a crash.

    CSRBF_CLI=build/bin/csrbf CSRBF_SOURCE_DIR=. /usr/bin/python3 tests/hostile/attack.py [CASES] [SEED]

CTest runs 200 cases (CI's 40 minutes); `attack.py 2000` runs the full set (about five minutes on 2 cores).
"""
import hashlib
import json
import math
import os
import random
import shutil
import signal
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


def run_case(argv, env, d, timeout, program=None, signal_after=None):
    """Runs csrbf with argv (or the command `program`); returns (exit code, output, peak RSS in KiB),
    or None when it hung. signal_after: (seconds, signal) sent to it then, if it still runs."""
    log = os.path.join(d, ".log")
    with open(log, "wb") as out:
        p = subprocess.Popen(program or [CLI] + argv, env=env, stdout=out, stderr=subprocess.STDOUT,
                             stdin=subprocess.DEVNULL)
    deadline = time.monotonic() + timeout
    if signal_after:
        time.sleep(signal_after[0])
        os.kill(p.pid, signal_after[1])  # not p.send_signal, whose poll() would reap it before wait4
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


COMPOSER = os.environ.get("CSRBF_COMPOSER")
PICKER = os.environ.get("CSRBF_PICKER")
PYTHONPATH = os.environ.get("CSRBF_PYTHONPATH")
MPIRUN = shutil.which("mpirun")


def partials(d):
    return [n for n in os.listdir(d) if ".csrbf-partial-" in n]


def good_command(rng, d):
    """A command that succeeds, with its inputs in d: (argv after csrbf, its output, the inputs)."""
    which = rng.choice(["deform", "export", "morph"])
    if which == "deform":
        out = os.path.join(d, rng.choice(["o.obj", "o.ply", "o.glb", "o.stl"]))
        return ["deform", "--mesh", os.path.join(EX, "fish.obj"), "--controls", os.path.join(EX, "fish.controls"),
                "--radius", "0.3", "-o", out], out, []
    if which == "export":
        for n in os.listdir(EX):
            if n.startswith("fish"):
                shutil.copy(os.path.join(EX, n), d)
        return ["export", os.path.join(d, "fish.scene.json"), "-o", os.path.join(d, "x.glb")], \
            os.path.join(d, "x.glb"), [os.path.join(d, n) for n in os.listdir(d) if n.startswith("fish")]
    p, m = os.path.join(d, "v.msh"), os.path.join(d, "m.json")
    open(p, "w").write(gmsh())
    open(m, "w").write(json.dumps({"radius": 3, "patches": {"base": {"translate": [0, 0, 0.01]}}}))
    return ["morph", p, "--motion", m, "-o", os.path.join(d, "o.msh")], os.path.join(d, "o.msh"), [p, m]


def fault_case(rng, d, env):
    """A good command under a fault; returns (argv, problems, output)."""
    argv, out, inputs = good_command(rng, d)
    clean = run_case(argv, env, d, 120)
    if clean is None or clean[0] != 0 or not os.path.isfile(out):
        return argv, ["the clean run failed: %r" % (clean and clean[1][-300:])], b""
    reference = digest(out)
    os.remove(out)
    before = {p: digest(p) for p in inputs}
    fault = rng.choice(["disk", "vlimit", "signal", "kill", "race"])
    problems = []
    text = b""
    if fault == "race":
        procs = [subprocess.Popen([CLI] + argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
                 for _ in range(3)]
        results = [(p.wait(timeout=120), p.stdout.read()) for p in procs]
        text = b"".join(t for _, t in results)
        if not any(c == 0 for c, _ in results):
            problems.append("no racer succeeded: %r" % [c for c, _ in results])
        for c, t in results:
            if c not in (0, 1):
                problems.append("a racer ended with %d" % c)
    else:
        program, after = None, None
        if fault in ("disk", "vlimit"):
            limit = "ulimit -f %d" % rng.choice([1, 4, 16, 64]) if fault == "disk" else "ulimit -v %d" % rng.choice(
                [300000, 600000, 1000000])  # below about 230000 KiB csrbf's libraries cannot be loaded
            program = ["bash", "-c", limit + '; exec "$0" "$@"', CLI] + argv
        else:
            sig = signal.SIGKILL if fault == "kill" else rng.choice([signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
            after = (rng.uniform(0.0, 0.25), sig)
        ran = run_case(argv, env, d, 120, program, after)
        if ran is None:
            return argv + ["(" + fault + ")"], ["hung (120 s)"], b""
        code, text, _ = ran
        allowed = {0, 1} if program else {0, 1, -after[1], 128 + after[1]}
        if code not in allowed:
            problems.append("exit %d under %s" % (code, fault))
        if code != 0 and os.path.exists(out) and digest(out) != reference:
            problems.append("a failed run left an output that differs from the clean run's")
        if fault != "kill" and code != 0 and os.path.exists(out) and code not in (130, 143, 129, -2, -15, -1):
            problems.append("a failed run (exit %d) left an output" % code)
        if fault != "kill" and partials(d):
            problems.append("partials left: %s" % partials(d))
        argv = argv + ["(" + fault + ")"]
    if os.path.exists(out) and digest(out) != reference:
        problems.append("the output differs from the clean run's")
    for p, h in before.items():
        if not os.path.isfile(p) or digest(p) != h:
            problems.append("input %s changed" % os.path.basename(p))
    return argv, problems, text


PYTHON_ATTACK = r"""
import sys, numpy as np, csrbf
rng = np.random.default_rng(int(sys.argv[1]))
bad = [np.zeros((0, 3)), np.zeros((5, 2)), np.zeros((3, 3, 1)), np.array([[np.nan, 0, 0]]),
       np.array([[1e308, 1e308, 1e308], [0, 0, 0]]), np.ones((4, 3), dtype=np.float16),
       np.ones((4, 3), dtype=np.complex128), np.array([[0, 0, 0], [1, 1, 1]], dtype=object),
       np.ones((6, 3))[::2], [[0, 0, 0], [1, 1]], "points", None, np.ones((4, 3), dtype=np.int64),
       np.asfortranarray(np.ones((4, 3))), rng.random((50, 3)), np.array([[0, 0, 0], [0, 0, 0.0]]),
       np.full((3, 3), np.inf)]
radii = [0, -1, float("nan"), float("inf"), 1e-320, 1e300, "x", None, 0.3, 2, [1]]
limits = [0, -1, float("nan"), 1e7, 1e-9, 4, "x"]
def attempt(f):
    try:
        f()
    except (ValueError, TypeError, MemoryError, OverflowError, OSError):
        pass
for _ in range(int(sys.argv[2])):
    s = bad[rng.integers(len(bad))]
    t = bad[rng.integers(len(bad))] if rng.random() < 0.5 else (s + 0.01 if isinstance(s, np.ndarray) and s.dtype != object else s)
    kw = dict(radius=radii[rng.integers(len(radii))], kernel=["c0", "c2", "c9", "", 3][rng.integers(5)],
              polynomial=["none", "linear", "x"][rng.integers(3)])
    if rng.random() < 0.5:
        kw["memory_limit"] = limits[rng.integers(len(limits))]
    m = None
    try:
        m = csrbf.SpaceMap(s, t, **kw)
    except (ValueError, TypeError, MemoryError, OverflowError, OSError):
        continue
    q = bad[rng.integers(len(bad))]
    attempt(lambda: m(q))
    attempt(lambda: m(q, phase=[float("nan"), 2, -1, 0.5, "x"][rng.integers(5)]))
    attempt(lambda: m(q, out=bad[rng.integers(len(bad))]))
    attempt(lambda: m.jacobian(q) if hasattr(m, "jacobian") else None)
print("done")
"""


def special_case(rng, d, k, env):
    """Cases 10 to 13 of every 14: faults, Python, MPI and the GUIs; returns (argv, problems, output),
    or None when the tool it needs is missing."""
    kind = k % 14
    if kind == 10:
        return fault_case(rng, d, env)
    if kind == 11:
        if not PYTHONPATH:
            return None
        py = dict(env, PYTHONPATH=PYTHONPATH)
        argv = ["python", str(rng.randrange(1 << 30)), "20"]
        ran = run_case([], py, d, 120, [sys.executable, "-c", PYTHON_ATTACK, argv[1], argv[2]])
        if ran is None:
            return argv, ["hung (120 s)"], b""
        code, text, _ = ran
        return argv, ([] if code == 0 and b"done" in text else ["exit %d" % code]), b""
    if kind == 12:
        if not MPIRUN:
            return None
        argv, inputs = make_case(rng, d, rng.choice([0, 4, 5, 6]))
        before = {p: digest(p) for p in inputs if os.path.isfile(p)}
        mpi = dict(env, HWLOC_COMPONENTS="-gl", OMPI_MCA_rmaps_base_oversubscribe="1")
        ran = run_case(argv, mpi, d, 120, [MPIRUN, "--allow-run-as-root", "-np", "2", CLI] + argv)
        if ran is None:
            return ["mpirun"] + argv, ["hung (120 s)"], b""
        code, text, _ = ran
        problems = [] if code in (0, 1, 2) else ["exit %d" % code]
        problems += ["input %s changed" % os.path.basename(p) for p, h in before.items() if digest(p) != h]
        if partials(d):
            problems.append("partials left: %s" % partials(d))
        return ["mpirun", "-np", "2"] + argv, problems, text
    if not (COMPOSER and PICKER and os.environ.get("DISPLAY")):
        return None
    gui = dict(env, DISPLAY=os.environ["DISPLAY"], XDG_DATA_HOME=os.path.join(d, "xdg"))
    shot = os.path.join(d, "shot.png")
    if rng.random() < 0.5:
        argv, inputs = make_case(rng, d, 3)  # a mutated scene
        program = [COMPOSER, "--screenshot", shot, "--size", "400x300", argv[1]]
    else:
        p = os.path.join(d, "m.obj")
        with open(os.path.join(EX, "fish.obj")) as f:
            open(p, "w").write(mutate_text(rng, f.read()))
        inputs = [p]
        program = [PICKER, p, "--screenshot", shot, "--size", "400x300"]
    before = {q: digest(q) for q in inputs if os.path.isfile(q)}
    ran = run_case([], gui, d, 120, program)
    if ran is None:
        return program, ["hung (120 s)"], b""
    code, text, _ = ran
    problems = [] if code in (0, 1, 2) else ["exit %d" % code]
    problems += ["input %s changed" % os.path.basename(q) for q, h in before.items() if digest(q) != h]
    return [os.path.basename(program[0])] + program[1:], problems, text


def main():
    cases = int(sys.argv[1]) if len(sys.argv) > 1 else 250
    seed = int(sys.argv[2]) if len(sys.argv) > 2 else 30
    rng = random.Random(seed)
    env = dict(os.environ)
    env.pop("DISPLAY", None)
    env["CSRBF_PIPE_TIMEOUT"] = "5"
    failures = []
    peaks = []
    tally = [0, 0, 0, 0]  # faults, Python, MPI, GUIs
    for k in range(cases):
        d = tempfile.mkdtemp(prefix="csrbf-attack-")
        try:
            if k % 14 >= 10:
                special = special_case(rng, d, k, env)
                if special is not None:
                    argv, problems, text = special
                    tally[k % 14 - 10] += 1
                    if any(b < 0x20 and b not in (0x0a, 0x09) or b == 0x7f for b in text):
                        problems.append("a raw control character in the output")
                    if problems:
                        failures.append((k, argv, "; ".join(problems) + " | " +
                                         text[-300:].decode("utf-8", "replace")))
                    continue
            argv, inputs = make_case(rng, d, k % 14)
            if argv[0] in ("deform", "morph", "export") and "--memory-limit" not in argv:
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
            if argv[0] in ("deform", "morph", "export") and limit is not None and limit >= 0.25 and \
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
    print("attack: %d cases (seed %d; %d faults, %d Python, %d MPI, %d GUI), %d failed; peak memory of a case: "
          "largest %.0f MiB" % (cases, seed, tally[0], tally[1], tally[2], tally[3], len(failures), max(peaks, default=0) / 1024))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
