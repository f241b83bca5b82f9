"""csrbf export judged by the consumers' own tools (CTest export_consumers, label "consumer"):

- the Khronos glTF-Validator (npm gltf-validator, installed into the build folder) finds no errors
  in any example, as .glb or .gltf;
- Blender (Debian's, headless) imports each with its shape keys and actions;
- the page of --html, opened in headless Chromium, draws the same silhouette as `csrbf animate` at
  the same times with the same camera (mask overlap >= 0.9);
- bad input gets a clear error, its exit status, and nothing written.

Environment: CSRBF_CLI (the program), CSRBF_SOURCE_DIR, CSRBF_NODE_MODULES (gltf-validator's folder).
"""
import json
import os
import shutil
import subprocess
import tempfile
import unittest

import numpy as np
from images import png

CLI = os.environ["CSRBF_CLI"]
SOURCE = os.environ["CSRBF_SOURCE_DIR"]
NODE_MODULES = os.environ["CSRBF_NODE_MODULES"]
EXAMPLES = os.path.join(SOURCE, "examples")
SCENES = ["fish", "face", "ball"]
COMPACT_SCENES = ["fish", "face", "ball"]
with open(os.path.join(EXAMPLES, "checker.png"), "rb") as _f:
    CHECKER = _f.read()

# Blender 3.4's glTF importer (Debian 12) still says np.bool, which numpy 1.24 removed: the alias is
# put back before the import, or no mesh imports at all.
BLENDER_SCRIPT = r"""
import bpy, json, sys
import numpy
if not hasattr(numpy, "bool"):
    numpy.bool = bool
path = sys.argv[sys.argv.index("--") + 1]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=path)
out = {"objects": {}, "actions": [a.name for a in bpy.data.actions], "frame_end": bpy.context.scene.frame_end}
for o in bpy.data.objects:
    keys = o.data.shape_keys if o.type == "MESH" else None
    out["objects"][o.name] = {
        "type": o.type,
        "parent": o.parent.name if o.parent else None,
        "shape_keys": [k.name for k in keys.key_blocks] if keys else [],
        "moves": bool(o.animation_data and o.animation_data.action),
        "keys_animated": bool(keys and keys.animation_data and keys.animation_data.action),
        "materials": [m.name for m in o.data.materials] if o.type == "MESH" else [],
    }
print("CSRBF-JSON " + json.dumps(out))
"""


def run(args, **kw):
    return subprocess.run(args, capture_output=True, text=True, timeout=kw.pop("timeout", 300), **kw)


def mask(image, background):
    """Pixels that are not the background (the objects' silhouette)."""
    return np.abs(image - np.asarray(background) * 255.0).sum(axis=2) > 40


class Export(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="csrbf-export-")
        cls.reports = {}
        for s in SCENES:
            for ext in (".glb", ".gltf"):
                out = os.path.join(cls.tmp, s + ext)
                args = [CLI, "export", os.path.join(EXAMPLES, s + ".scene.json"), "-o", out, "--json"]
                if ext == ".glb":
                    args += ["--html", os.path.join(cls.tmp, s + "-page")]
                p = run(args)
                assert p.returncode == 0, p.stderr
                cls.reports[s + ext] = json.loads(p.stdout)
        # CSRBF_deformation (issue 33): with the morph targets as fallback, and alone.
        for s in COMPACT_SCENES:
            for flag, suffix in (("--compact", "-compact"), ("--compact=only", "-only")):
                out = os.path.join(cls.tmp, s + suffix + ".glb")
                p = run([CLI, "export", os.path.join(EXAMPLES, s + ".scene.json"), "-o", out, "--json", flag])
                assert p.returncode == 0, p.stderr
                cls.reports[s + suffix + ".glb"] = json.loads(p.stdout)

        # Compressed by meshoptimizer (EXT_meshopt_compression), with and without the extension.
        for s in SCENES:
            for flags, suffix in ((["--meshopt"], "-meshopt"), (["--meshopt", "--compact=only"], "-only-meshopt"),
                                  (["--quantize"], "-quantized"), (["--quantize", "--meshopt"], "-quantized-meshopt")):
                out = os.path.join(cls.tmp, s + suffix + ".glb")
                p = run([CLI, "export", os.path.join(EXAMPLES, s + ".scene.json"), "-o", out, "--json"] + flags)
                assert p.returncode == 0, p.stderr
                cls.reports[s + suffix + ".glb"] = json.loads(p.stdout)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def test_khronos_validator_finds_no_errors(self):
        files = [os.path.join(self.tmp, s + ext) for s in SCENES for ext in (".glb", ".gltf")]
        files += [os.path.join(self.tmp, s + "-page", s + ".glb") for s in SCENES]
        files += [os.path.join(self.tmp, s + suffix + ".glb") for s in COMPACT_SCENES for suffix in ("-compact", "-only")]
        files += [os.path.join(self.tmp, s + suffix + ".glb") for s in SCENES
                  for suffix in ("-meshopt", "-only-meshopt", "-quantized", "-quantized-meshopt")]
        p = run(["node", os.path.join(SOURCE, "tests", "export", "validate.js"), NODE_MODULES] + files)
        print(p.stdout)
        self.assertEqual(p.returncode, 0, p.stdout + p.stderr)
        self.assertEqual(p.stdout.count(" 0 errors, 0 warnings"), len(files), p.stdout)

    def test_report_sizes(self):
        for s in SCENES:
            r = self.reports[s + ".glb"]
            self.assertEqual(r["bytes"], os.path.getsize(os.path.join(self.tmp, s + ".glb")))
            # Far less than every frame's vertices, as the paper says of game engines.
            self.assertLess(r["bytes"], r["frame_vertex_bytes"] / 4, s)
            self.assertGreater(r["csrbf_bytes"], 0)
            self.assertLessEqual(r["max_active_targets"], 8)
        self.assertTrue(any(p["baked"] for p in self.reports["ball.glb"]["parts"]))
        # CSRBF_deformation: the extension's bytes against the targets' it replaces, and the files.
        for s in COMPACT_SCENES:
            c, o = self.reports[s + "-compact.glb"]["compact"], self.reports[s + "-only.glb"]
            self.assertGreater(c["replaced_target_bytes"], 0)
            self.assertLess(2 * c["compact_bytes"], c["replaced_target_bytes"], s)
            self.assertLess(o["bytes"], self.reports[s + ".glb"]["bytes"], s)
            print(f"{s}: targets {c['replaced_target_bytes']} B -> extension {c['compact_bytes']} B; "
                  f"glb {self.reports[s + '.glb']['bytes']} -> --compact=only {o['bytes']}")

    def test_blender_imports_shape_keys_and_actions(self):
        # --compact files too: Blender does not know CSRBF_deformation and plays the fallback targets.
        # And the quantized files (Blender 3.4 reads KHR_mesh_quantization; not EXT_meshopt_compression).
        for file in SCENES + [s + "-compact" for s in COMPACT_SCENES] + [s + "-quantized" for s in SCENES]:
            s = file.split("-")[0]
            p = run(["blender", "-b", "--factory-startup", "--python-expr", BLENDER_SCRIPT, "--",
                     os.path.join(self.tmp, file + ".glb")])
            lines = [l for l in p.stdout.splitlines() if l.startswith("CSRBF-JSON ")]
            self.assertEqual(len(lines), 1, p.stdout[-3000:] + p.stderr[-3000:])
            got = json.loads(lines[0][len("CSRBF-JSON "):])
            with open(os.path.join(EXAMPLES, s + ".scene.json")) as f:
                scene = json.load(f)
            report = self.reports[file + ".glb"]
            # The same vertices and targets as the export without --compact.
            plain = self.reports[s + ".glb"]["objects"]
            self.assertEqual([(o["vertices"], o["targets"]) for o in report["objects"]],
                             [(o["vertices"], o["targets"]) for o in plain])
            for o, r in zip(scene["objects"], report["objects"]):
                b = got["objects"].get(o["name"])
                self.assertIsNotNone(b, f"{s}: Blender has no object {o['name']}: {list(got['objects'])}")
                self.assertEqual(b["type"], "MESH")
                self.assertEqual(b["parent"], o["name"] + " pivot")
                if r["targets"]:
                    self.assertEqual(len(b["shape_keys"]), r["targets"] + 1, b["shape_keys"])  # and Basis
                    self.assertTrue(b["keys_animated"], f"{s}/{o['name']}: shape keys without an action")
                if "trajectory" in o:
                    self.assertTrue(got["objects"][o["name"] + " pivot"]["moves"])
            if s == "fish":
                self.assertEqual(got["objects"]["fish"]["shape_keys"], ["Basis", "tail left", "tail right", "mouth", "fin"])
            self.assertIn("camera", got["objects"])

    def test_page_draws_what_animate_draws(self):
        """The page in headless Chromium against csrbf animate, same camera and size, same times."""
        size = (640, 480)
        for s, times in (("fish", (0.0, 2.0, 5.3)), ("face", (1.0, 2.2)), ("ball", (0.5, 1.48, 3.0))):
            with open(os.path.join(EXAMPLES, s + ".scene.json")) as f:
                scene = json.load(f)
            background = scene.get("background", [0.1, 0.1, 0.15])
            for t in times:
                frames = os.path.join(self.tmp, f"{s}-{int(t * 1000)}ms-frames")
                p = run([CLI, "animate", os.path.join(EXAMPLES, s + ".scene.json"), "-o", frames + "/",
                         "--from", str(t), "--to", str(t), "--size", f"{size[0]}x{size[1]}"])
                self.assertEqual(p.returncode, 0, p.stderr)
                shot = os.path.join(self.tmp, f"{s}-{int(t * 1000)}ms-page.png")
                page = os.path.join(self.tmp, s + "-page", "index.html")
                p = run(["chromium", "--headless", "--no-sandbox", "--disable-gpu", "--use-gl=swiftshader",
                         "--enable-unsafe-swiftshader", "--hide-scrollbars", f"--window-size={size[0]},{size[1]}",
                         "--virtual-time-budget=30000", f"--screenshot={shot}",
                         f"file://{page}?t={t}&ui=0"], timeout=120)
                self.assertTrue(os.path.exists(shot), p.stderr[-2000:])
                a = mask(png(os.path.join(frames, "frame_00000.png")), background)
                b = mask(png(shot), background)
                self.assertEqual(a.shape, b.shape)
                self.assertGreater(a.sum(), 500, f"{s} at {t}: animate drew almost nothing")
                overlap = (a & b).sum() / (a | b).sum()
                print(f"{s} t = {t}: silhouette overlap {overlap:.3f} ({a.sum()} / {b.sum()} pixels)")
                self.assertGreaterEqual(overlap, 0.9, f"{s} at t = {t}")

    def test_bad_input_writes_nothing(self):
        d = tempfile.mkdtemp(dir=self.tmp)
        out = os.path.join(d, "x.glb")
        fish = os.path.join(EXAMPLES, "fish.scene.json")
        cases = [
            ([os.path.join(d, "none.scene.json"), "-o", out], 1, "none.scene.json"),
            ([fish, "-o", os.path.join(d, "no", "such", "x.glb")], 1, "no/such"),
            ([fish, "-o", os.path.join(d, "x.obj")], 2, "must end in .glb or .gltf"),
            ([fish, "-o", out, "--bake", "sometimes"], 2, "--bake"),
            ([fish, "-o", out, "--compact=sometimes"], 2, "--compact: expected no value"),
            ([fish, "-o", out, "--compact", "--quantize"], 2, "--quantize with --compact"),
            ([fish, "-o", out, "--fps", "0"], 2, "--fps"),
            ([fish, "-o", out, "--html", self.tmp], 2, "exists"),
            ([os.path.join(EXAMPLES, "ball.scene.json"), "-o", out, "--bake", "never"], 1, "'walls' needs baking"),
        ]
        for args, status, words in cases:
            p = run([CLI, "export"] + args)
            self.assertEqual(p.returncode, status, f"{args}: {p.stderr}")
            self.assertIn(words, p.stderr, args)
            self.assertEqual(sorted(os.listdir(d)), [], args)
        # A texture that is not an image (a scene of our own), and one cut short.
        with open(os.path.join(EXAMPLES, "ball.scene.json")) as f:
            scene = json.load(f)
        for name, data in (("bad.png", b"not an image at all"),
                           ("cut.png", CHECKER[:200]), ("cut-late.png", CHECKER[:-20])):
            sd = tempfile.mkdtemp(dir=self.tmp)
            for f in os.listdir(EXAMPLES):
                if f.endswith(".obj"):
                    shutil.copy(os.path.join(EXAMPLES, f), sd)
            with open(os.path.join(sd, name), "wb") as f:
                f.write(data)
            scene["objects"][1]["texture"] = name
            with open(os.path.join(sd, "s.scene.json"), "w") as f:
                json.dump(scene, f)
            p = run([CLI, "export", os.path.join(sd, "s.scene.json"), "-o", out])
            self.assertEqual(p.returncode, 1, p.stderr)
            self.assertIn(name, p.stderr)
            self.assertEqual(sorted(os.listdir(d)), [])
        # A read-only folder: an error naming it, nothing left behind.
        if os.geteuid() != 0:
            os.chmod(d, 0o500)
            p = run([CLI, "export", fish, "-o", out])
            os.chmod(d, 0o700)
            self.assertEqual(p.returncode, 1, p.stderr)


if __name__ == "__main__":
    unittest.main()
