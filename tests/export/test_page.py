"""The page of `csrbf export --html` in headless Chromium (SwiftShader, WebGL2, three.js from npm):
CSRBF_deformation played in the vertex shader (CTest export_page, label "consumer").

- The shader's deformed vertices, read back from a float render target, equal `csrbf deform` at the
  same phase within 1e-5 of the mesh's bounding box diagonal, and its normals the exact J^-T n;
- every example's deformations, played by the shader, equal the morph targets the same file holds
  (the fallback: base plus the weighted targets, summed in JavaScript) at several times;
- screenshots of the two paths match (kept in CSRBF_SCREENSHOT_DIR to be looked at);
- the page warns where an engine would drop morph targets, and plays them all itself.

The engine example, csrbf-play-glb, plays the same glb on the CPU from the file alone: its vertices
equal csrbf deform's and its normals the shader's.

Environment: CSRBF_CLI, CSRBF_PLAY_GLB, CSRBF_SOURCE_DIR, CSRBF_SCREENSHOT_DIR (optional).
"""
import base64
import html
import json
import os
import re
import shutil
import subprocess
import tempfile
import unittest

import numpy as np
from images import png

CLI = os.environ["CSRBF_CLI"]
SOURCE = os.environ["CSRBF_SOURCE_DIR"]
SHOTS = os.environ.get("CSRBF_SCREENSHOT_DIR", "")
PLAY = os.environ["CSRBF_PLAY_GLB"]  # examples/engine/play_glb.cpp
WEB = os.environ["CSRBF_WEB_DIR"]  # the built three.js plugin (build/web/csrbf_deformation.js)
EXAMPLES = os.path.join(SOURCE, "examples")
SIZE = (640, 480)


def run(args, **kw):
    return subprocess.run(args, capture_output=True, text=True, timeout=kw.pop("timeout", 300), **kw)


def chromium(url, *, screenshot=None, dump=False, budget=60000):
    """Headless Chromium on url. Its virtual time budget is what it waits for the page's work (the
    glb's asynchronous load); virtual time runs ahead while the page is idle, so a large budget
    costs nothing. A run that Chromium still cuts short (a loaded machine: the page's title is not
    yet "ready", "error" or "done") is run again, at most twice, and says so."""
    args = ["chromium", "--headless", "--no-sandbox", "--disable-gpu", "--use-gl=swiftshader",
            "--enable-unsafe-swiftshader", "--hide-scrollbars", f"--window-size={SIZE[0]},{SIZE[1]}",
            f"--virtual-time-budget={budget}"]
    if screenshot:
        args.append(f"--screenshot={screenshot}")
    if dump:
        args.append("--dump-dom")
    for attempt in range(3):
        p = run(args + [url], timeout=300)
        if not dump or re.search(r"<title>(ready|error|done)</title>", p.stdout):
            return p
        print(f"chromium: {url}: the page had not finished (attempt {attempt + 1}); run again")
    return p


def element(dom, name):
    m = re.search(r'<pre id="' + name + r'" class="out">(.*?)</pre>', dom, re.S)
    return html.unescape(m.group(1)) if m else ""


def floats(b64):
    return np.frombuffer(base64.b64decode(b64), dtype=np.float32).reshape(-1, 3).astype(np.float64)


def read_obj(path):
    v, vn = [], []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                v.append([float(x) for x in line.split()[1:4]])
            elif line.startswith("vn "):
                vn.append([float(x) for x in line.split()[1:4]])
    return np.array(v), np.array(vn)


def angles(a, b):
    a = a / np.linalg.norm(a, axis=1, keepdims=True)
    b = b / np.linalg.norm(b, axis=1, keepdims=True)
    return np.arccos(np.clip((a * b).sum(axis=1), -1, 1))


class Page(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="csrbf-page-")
        if SHOTS:
            os.makedirs(SHOTS, exist_ok=True)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def export(self, scene, name, *flags):
        page = os.path.join(self.tmp, name)
        p = run([CLI, "export", scene, "-o", page + ".glb", "--html", page, "--json"] + list(flags))
        self.assertEqual(p.returncode, 0, p.stderr)
        return os.path.join(page, "index.html"), json.loads(p.stdout)

    def readback(self, page, t):
        p = chromium(f"file://{page}?t={t}&ui=0&readback=1", dump=True)
        out = element(p.stdout, "readback")
        self.assertTrue(out, p.stdout[-2000:] + p.stderr[-2000:])
        return json.loads(out)

    def test_shader_equals_csrbf_deform_at_the_same_phase(self):
        # The fish bent by fish.controls (R = 0.3) at phase 0.37 the whole time, written as the
        # extension alone; the shader's vertices against `csrbf deform --phase 0.37`.
        with open(os.path.join(EXAMPLES, "fish.scene.json")) as f:
            scene = json.load(f)
        scene["duration"] = 1.0
        fish = scene["objects"][0]
        for k in ("trajectory", "orientation"):
            fish.pop(k, None)
        fish["mesh"] = os.path.join(EXAMPLES, "fish.obj")
        for kernel in ("c2", "c4"):
            fish["parts"] = [{"name": "body", "combine": "sum", "deformations": [{
                "name": "bend", "controls": os.path.join(EXAMPLES, "fish.controls"), "radius": 0.3, "kernel": kernel,
                "phase": {"easing": "linear", "keys": [{"time": 0.0, "phase": 0.37}, {"time": 1.0, "phase": 0.37}]}}]}]
            path = os.path.join(self.tmp, f"bend-{kernel}.scene.json")
            with open(path, "w") as f:
                json.dump(scene, f)
            page, report = self.export(path, f"bend-{kernel}", "--compact=only")
            self.assertEqual(report["objects"][0]["compact"]["deformations"], 1, report)
            got = self.readback(page, 0.5)["fish"]
            deformed = os.path.join(self.tmp, f"bend-{kernel}.obj")
            p = run([CLI, "deform", "--mesh", fish["mesh"], "--controls", os.path.join(EXAMPLES, "fish.controls"),
                     "--radius", "0.3", "--kernel", kernel, "--phase", "0.37", "-o", deformed])
            self.assertEqual(p.returncode, 0, p.stderr)
            rest, _ = read_obj(fish["mesh"])
            want, want_normals = read_obj(deformed)
            # The glb's vertices are the OBJ's, in an order of the exporter's: matched by rest position.
            glb_rest = floats(got["rest"])
            index = {tuple(np.float32(v)): i for i, v in enumerate(rest)}
            order = np.array([index[tuple(np.float32(v))] for v in glb_rest])
            diagonal = np.linalg.norm(rest.max(axis=0) - rest.min(axis=0))
            error = np.abs(floats(got["positions"]) - want[order]).max() / diagonal
            moved = np.abs(want - rest).max() / diagonal
            print(f"{kernel}: shader against csrbf deform: {error:.2e} of the diagonal (the deformation moves up to {moved:.3f})")
            self.assertGreater(moved, 0.01)
            self.assertLessEqual(error, 1e-5)
            # The engine example (csrbf::render::GltfRuntime, double) from the glb alone: its vertices,
            # and its exact normals J^-T n against the shader's.
            frame = os.path.join(self.tmp, f"bend-{kernel}-cpu.obj")
            p = run([PLAY, page.replace("index.html", f"bend-{kernel}.glb"), "--obj", frame, "--time", "0.5"])
            self.assertEqual(p.returncode, 0, p.stderr)
            self.assertIn("mesh 'fish': 977 vertices", p.stdout)
            cpu, cpu_normals = read_obj(frame)
            self.assertEqual(cpu.shape, want.shape)
            self.assertLessEqual(np.abs(cpu - want[order]).max() / diagonal, 1e-6)
            a = np.degrees(angles(floats(got["normals"]), cpu_normals))
            print(f"{kernel}: the shader's normals against the CPU runtime's J^-T n: median {np.median(a):.1e} deg, "
                  f"max {a.max():.1e} deg")
            self.assertLess(a.max(), 0.01)

    def six_at_once(self):
        """The fish with six deformations at phase 0.5 at once, each a morph target with normals."""
        with open(os.path.join(EXAMPLES, "fish.scene.json")) as f:
            scene = json.load(f)
        fish = scene["objects"][0]
        fish["mesh"] = os.path.join(EXAMPLES, "fish.obj")
        half = {"easing": "linear", "keys": [{"time": 0.0, "phase": 0.5}, {"time": scene["duration"], "phase": 0.5}]}
        six = [(c, 0.3) for c in ("fish-tail-left", "fish-tail-right", "fish-mouth", "fish-fin", "fish")] + [("fish", 0.5)]
        fish["parts"] = [{"name": "body", "combine": "sum", "deformations": [
            {"name": f"d{k}", "controls": os.path.join(EXAMPLES, c + ".controls"), "radius": r, "phase": half}
            for k, (c, r) in enumerate(six)]}]
        path = os.path.join(self.tmp, "six.scene.json")
        with open(path, "w") as f:
            json.dump(scene, f)
        return path

    def composed(self):
        """The fish's tail, then its fin on the result (T2 o T1, a Compose part): two stages."""
        with open(os.path.join(EXAMPLES, "fish.scene.json")) as f:
            scene = json.load(f)
        scene.update(duration=1.0, fps=10)
        fish = scene["objects"][0]
        fish["mesh"] = os.path.join(EXAMPLES, "fish.obj")
        for k in ("trajectory", "orientation"):
            fish.pop(k, None)
        def deformation(name, at):
            return {"name": name, "controls": os.path.join(EXAMPLES, f"fish-{name}.controls"), "radius": 0.3,
                    "phase": {"easing": "linear", "keys": [{"time": 0.0, "phase": 0.0}, {"time": at, "phase": 1.0},
                                                           {"time": 1.0, "phase": 0.2}]}}
        fish["parts"] = [{"name": "body", "combine": "compose",
                          "deformations": [deformation("tail-left", 0.4), deformation("fin", 0.7)]}]
        path = os.path.join(self.tmp, "composed.scene.json")
        with open(path, "w") as f:
            json.dump(scene, f)
        return path

    def test_shader_equals_the_morph_targets_of_every_example(self):
        scenes = [(os.path.join(EXAMPLES, s + ".scene.json"), s, times)
                  for s, times in (("fish", (0.1, 1.0, 5.3)), ("face", (1.0, 2.2)), ("ball", (0.5, 1.48)))]
        # The composed fish at frame times, where its baked targets are exact: the shader's stages.
        # And the fish compressed by meshoptimizer (three.js's MeshoptDecoder reads it).
        scenes += [(self.six_at_once(), "six", (1.0,)), (self.composed(), "composed", (0.5, 0.8)),
                   (os.path.join(EXAMPLES, "fish.scene.json"), "fish-meshopt", (1.0,))]
        for path, s, times in scenes:
            flags = ["--compact"] + (["--meshopt"] if s.endswith("-meshopt") else [])
            page, report = self.export(path, s + "-compact", *flags)
            if not any(o.get("compact", {}).get("deformations") for o in report["objects"]):
                print(f"{s}: nothing written as CSRBF_deformation")
                continue
            for t in times:
                got = self.readback(page, t)
                self.assertTrue(got, f"{s}: no mesh played by the shader")
                for name, g in got.items():
                    rest = floats(g["rest"])
                    diagonal = np.linalg.norm(rest.max(axis=0) - rest.min(axis=0))
                    error = np.abs(floats(g["positions"]) - floats(g["targets"])).max() / diagonal
                    moved = np.abs(floats(g["targets"]) - rest).max() / diagonal
                    a = np.degrees(angles(floats(g["normals"]), floats(g["target_normals"])))
                    print(f"{s} t = {t} '{name}': shader against the targets {error:.2e} of the diagonal "
                          f"(moved {moved:.3f}); normals against the targets' blend: median {np.median(a):.2f} deg")
                    self.assertGreater(moved, 0.01, f"{s} '{name}' at t = {t}: nothing moves")
                    self.assertLessEqual(error, 1e-5, f"{s} '{name}' at t = {t}")

    def test_screenshots_of_both_paths_match(self):
        # The six: three.js r111 played 4 of these 6 targets; the current release plays them all.
        for scene, s, t in ((os.path.join(EXAMPLES, "fish.scene.json"), "fish", 1.0),
                            (os.path.join(EXAMPLES, "face.scene.json"), "face", 2.2), (self.six_at_once(), "six", 1.0)):
            page, _ = self.export(scene, s + "-shots", "--compact")
            shots = {}
            for path in ("shader", "targets"):
                shot = os.path.join(SHOTS or self.tmp, f"page-{s}-{path}.png")
                if os.path.exists(shot):
                    os.remove(shot)
                p = chromium(f"file://{page}?t={t}&ui=0&path={path}", screenshot=shot)
                self.assertTrue(os.path.exists(shot), p.stderr[-2000:])
                shots[path] = png(shot)
            a, b = shots["shader"], shots["targets"]
            with open(scene) as f:
                background = np.asarray(json.load(f).get("background", [0.1, 0.1, 0.15])) * 255.0
            ma = np.abs(a - background).sum(axis=2) > 40
            mb = np.abs(b - background).sum(axis=2) > 40
            overlap = (ma & mb).sum() / (ma | mb).sum()
            differ = (np.abs(a - b).max(axis=2) > 24).mean()
            print(f"{s} t = {t}: shader against targets, silhouettes overlap {overlap:.4f}, "
                  f"{100 * differ:.2f}% of pixels differ by more than 24 levels")
            self.assertGreater(ma.sum(), 2000)
            self.assertGreaterEqual(overlap, 0.99, s)
            self.assertLess(differ, 0.01, s)

    def test_a_web_developers_uses_of_the_module(self):
        """page_api.html: csrbf_deformation.js as an application uses three.js around it."""
        page, _ = self.export(os.path.join(EXAMPLES, "fish.scene.json"), "fish-api", "--compact=only")
        folder = os.path.dirname(page)
        shutil.copy(os.path.join(SOURCE, "tests", "export", "page_api.html"), folder)
        p = chromium(f"file://{folder}/page_api.html", dump=True)
        m = re.search(r'<pre id="result">(.*?)</pre>', p.stdout, re.S)
        self.assertIsNotNone(m, p.stdout[-2000:] + p.stderr[-2000:])
        r = json.loads(html.unescape(m.group(1)))
        print(json.dumps(r))
        self.assertEqual(r["errors"], [])
        self.assertGreater(r["pixels"], 1000)
        self.assertLess(r["iou_between_times"], 0.5)  # the fish moves between t = 1 and 2.5
        # An unlit material the application sets: the rest shape until attach(mesh), then deformed.
        self.assertLess(r["iou_basic_without_attach"], 0.95)
        self.assertGreater(r["iou_basic"], 0.99)
        # A clone plays its own time, alone and beside its original; userData stays small.
        self.assertGreater(r["iou_clone"], 0.99)
        self.assertGreater(r["iou_original_after_clone"], 0.99)
        self.assertGreater(r["iou_both"], 0.99)
        self.assertLess(r["clone_userdata_bytes"], 1000)
        # dispose() frees the deformation's seven textures.
        self.assertEqual(r["t_before_dispose"] - r["t_after_deformation_dispose"], 7)
        self.assertTrue(r["of_after_dispose"])

    def test_malformed_data_is_an_error_on_the_page(self):
        """Hostile CSRBF_deformation data: the page names the field (#error, title "error"); it never
        draws NaN or a wrong mesh as if all were well."""
        page, _ = self.export(os.path.join(EXAMPLES, "fish.scene.json"), "fish-hostile", "--compact=only")
        folder = os.path.dirname(page)
        with open(os.path.join(folder, "fish-hostile.glb"), "rb") as f:
            glb = f.read()
        length = int.from_bytes(glb[12:16], "little")
        doc, rest = json.loads(glb[20:20 + length]), glb[20 + length:]

        def ext(d):
            return d["meshes"][0]["extensions"]["CSRBF_deformation"]["deformations"][0]
        cases = [
            (lambda d: ext(d)["terms"][0].update(weight=-1), "weight -1 is not a morph weight"),
            (lambda d: ext(d).update(kernel="__proto__"), 'kernel "__proto__" is not C0'),
            (lambda d: ext(d).update(radius="0.3"), 'radius "0.3" is not a number'),
            (lambda d: ext(d).update(radius=1e-39), "radius 1e-39 is not a number in [1e-18, 1e18]"),
            (lambda d: ext(d).update(groups=[0]), "has groups but the mesh has no _CSRBF_GROUP"),
            (lambda d: ext(d).update(stage=2 ** 24), "stage 16777216 is not in 0..65535"),
            (lambda d: ext(d)["terms"][0].update(polynomial=[0, 0, 0] + [3e38] * 9), "polynomial is not 12 numbers"),
        ]
        for edit, says in cases:
            d = json.loads(json.dumps(doc))
            edit(d)
            text = json.dumps(d).encode()
            text += b" " * (-len(text) % 4)
            body = len(text).to_bytes(4, "little") + b"JSON" + text + rest
            data = b"glTF" + (2).to_bytes(4, "little") + (12 + len(body)).to_bytes(4, "little") + body
            with open(os.path.join(folder, "scene.glb.js"), "w") as f:
                f.write('window.CSRBF_GLB = "' + base64.b64encode(data).decode() + '";\n')
            p = chromium(f"file://{page}?t=1&ui=0", dump=True)
            title = re.search(r"<title>(.*?)</title>", p.stdout, re.S)
            error = re.search(r'<div id="error">(.*?)</div>', p.stdout, re.S)
            self.assertEqual(title.group(1) if title else None, "error", says)
            self.assertIn(says, html.unescape(error.group(1)) if error else "", says)

    def test_the_shader_file_is_the_modules_shader(self):
        # web/csrbf_deformation.glsl (for engines) is the text the built csrbf_deformation.js runs: the
        # module is made of web/csrbf_deformation.js.in and the shader's one source when csrbf is built.
        with open(os.path.join(SOURCE, "web", "csrbf_deformation.glsl")) as f:
            glsl = f.read()
        with open(os.path.join(WEB, "csrbf_deformation.js")) as f:
            js = f.read()
        with open(os.path.join(SOURCE, "web", "csrbf_deformation.js.in")) as f:
            self.assertEqual(f.read().count("@CSRBF_GLSL@"), 1)
        m = re.search(r"// BEGIN CSRBF_GLSL\nexport const CSRBF_GLSL = `(.*?)`;\n// END CSRBF_GLSL", js, re.S)
        self.assertIsNotNone(m)
        self.assertEqual(m.group(1), glsl)

    def test_the_page_warns_where_an_engine_would_drop_targets(self):
        for path, name, most in ((self.six_at_once(), "six-warn", 6), (os.path.join(EXAMPLES, "face.scene.json"), "face-warn", 1)):
            page, report = self.export(path, name)
            self.assertEqual(report["max_active_targets"], most)
            p = chromium(f"file://{page}?t=1&ui=0", dump=True)
            m = re.search(r'<div id="warning">(.*?)</div>', p.stdout, re.S)
            self.assertIsNotNone(m, p.stdout[-2000:])
            said = html.unescape(m.group(1))
            print(f"{name}: {most} targets at once; the page says: {said or '(nothing)'}")
            if most > 4:  # normals are morphed: 4 in engines with the old limit
                self.assertIn(f"{most} morph targets at once", said)
                self.assertIn("drops some", said)
            else:
                self.assertEqual(said, "")

if __name__ == "__main__":
    unittest.main()
