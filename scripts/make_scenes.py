#!/usr/bin/python3
"""Writes the bundled animation scenes and what they need (examples/):

- fish.scene.json: the fish swims along an S-shaped Kochanek-Bartels path, turning with it; its tail
  swings left and right, its mouth opens and its dorsal fin bends, each on its own schedule. The four
  deformations share the 92 sources of fish.controls (fish-*.controls: one group's displacements
  each, the other sources pinned) and are summed, so with every phase at 1 they make fish.controls.
- face.scene.json: the face smiles and raises its brows (face.controls, R = 0.2) while the head turns.
- ball.scene.json: a ball bounces inside a box (box.obj, 386 vertices) whose walls dent where it hits:
  a built-in contact deformation, refitted every frame (C2 kernel, R = 0.4).
- box.obj, sphere.obj, checker.png.

Run with Debian's python3 from the repository root: /usr/bin/python3 scripts/make_scenes.py
"""
import json
import math
import os
import struct
import zlib

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples")


def write(name, text):
    with open(os.path.join(ROOT, name), "w") as f:
        f.write(text)


def box_obj(seg=8):
    """The unit box with seg x seg quads a face, 386 vertices for seg = 8; groups 'walls' and 'front' (z = 1)."""
    index = {}
    verts = []
    for z in range(seg + 1):
        for y in range(seg + 1):
            for x in range(seg + 1):
                if x in (0, seg) or y in (0, seg) or z in (0, seg):
                    index[(x, y, z)] = len(verts)
                    verts.append((x / seg, y / seg, z / seg))
    walls, front = [], []
    for axis in range(3):
        for side in (0, seg):
            u, v = (axis + 1) % 3, (axis + 2) % 3
            for a in range(seg):
                for b in range(seg):
                    quad = []
                    for da, db in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        p = [0, 0, 0]
                        p[axis] = side
                        p[u] = a + da
                        p[v] = b + db
                        quad.append(index[tuple(p)])
                    if side == 0:
                        quad.reverse()  # outward normals
                    (front if axis == 2 and side == seg else walls).append(quad)
    lines = ["# unit box, %d x %d quads a face, %d vertices (scripts/make_scenes.py)" % (seg, seg, len(verts))]
    lines += ["v %.6f %.6f %.6f" % v for v in verts]
    lines.append("g walls")
    lines += ["f " + " ".join(str(k + 1) for k in q) for q in walls]
    lines.append("g front")
    lines += ["f " + " ".join(str(k + 1) for k in q) for q in front]
    return "\n".join(lines) + "\n", len(verts)


def sphere_obj(radius=0.2, rings=16, around=24):
    verts = [(0.0, radius, 0.0)]
    for i in range(1, rings):
        th = math.pi * i / rings
        for j in range(around):
            ph = 2 * math.pi * j / around
            verts.append((radius * math.sin(th) * math.cos(ph), radius * math.cos(th), radius * math.sin(th) * math.sin(ph)))
    verts.append((0.0, -radius, 0.0))
    south = len(verts) - 1

    def vid(i, j):
        return 1 + (i - 1) * around + j % around

    faces = [(0, vid(1, j + 1), vid(1, j)) for j in range(around)]
    for i in range(1, rings - 1):
        for j in range(around):
            faces.append((vid(i, j), vid(i, j + 1), vid(i + 1, j + 1), vid(i + 1, j)))
    faces += [(south, vid(rings - 1, j), vid(rings - 1, j + 1)) for j in range(around)]
    lines = ["# sphere of radius %g at the origin (scripts/make_scenes.py)" % radius]
    lines += ["v %.6f %.6f %.6f" % v for v in verts]
    lines += ["f " + " ".join(str(k + 1) for k in f) for f in faces]
    return "\n".join(lines) + "\n"


def png(width, height, pixel):
    rows = b"".join(b"\x00" + bytes(c for x in range(width) for c in pixel(x, y)) for y in range(height))

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(rows, 9)) + chunk(b"IEND", b""))


def fish_controls():
    """Splits fish.controls by its '# group' comments into one file a moving group, all sources kept."""
    groups, rows, current = [], [], None
    with open(os.path.join(ROOT, "fish.controls")) as f:
        for line in f:
            line = line.strip()
            if line.startswith("# ") and len(line.split()) == 2:
                current = line[2:]
                continue
            if not line or line.startswith("#"):
                continue
            rows.append((current, [float(t) for t in line.split()]))
    for name, sign, label in (("tail", 1, "tail-left"), ("tail", -1, "tail-right"), ("mouth", 1, "mouth"),
                              ("fin", 1, "fin")):
        out = ["# fish.controls with only the %s moving (%s), every other source pinned; R = 0.3" % (name, label)]
        for group, (sx, sy, sz, dx, dy, dz) in rows:
            if group == name:
                dx, dy, dz = sx + sign * (dx - sx), sy + sign * (dy - sy), sz + sign * (dz - sz)
            else:
                dx, dy, dz = sx, sy, sz
            out.append("%.6f %.6f %.6f %.6f %.6f %.6f" % (sx, sy, sz, dx, dy, dz))
        groups.append(label)
        write("fish-%s.controls" % label, "\n".join(out) + "\n")
    return groups


def keys(times_phases):
    return [{"time": round(t, 4), "phase": p} for t, p in times_phases]


def fish_scene():
    duration = 8.0
    path, turn = [], []
    for k in range(5):
        z = 0.3 * math.sin(k * math.pi / 2)
        path.append({"time": 2.0 * k, "position": [round(1.2 - 0.6 * k, 4), 0.5, round(z, 4)]})
        # Heading along the path: the fish's nose points to -x; its velocity is (-0.6, 0, dz/dk).
        yaw = math.degrees(math.atan2(0.3 * math.pi / 2 * math.cos(k * math.pi / 2), 0.6))
        turn.append({"time": 2.0 * k, "axis": [0, 1, 0], "angle": round(yaw, 3)})
    beat = 0.8  # one tail beat: left, centre, right, centre
    left, right = [], []
    t = 0.0
    while t < duration + 1e-9:
        left += [(t, 0.0), (t + beat / 4, 1.0), (t + beat / 2, 0.0)]
        right += [(t + beat / 2 + 0.001, 0.0), (t + 3 * beat / 4, 1.0), (t + beat - 0.001, 0.0)]
        t += beat
    mouth = [(2.0 * k + d, p) for k in range(4) for d, p in ((0.0, 0.0), (0.5, 1.0), (1.0, 0.0))]
    fin = [(1.0 * k, 0.0 if k % 2 == 0 else 1.0) for k in range(9)]
    return {
        "format": "csrbf-scene", "version": 1,
        "duration": duration, "fps": 25,
        "background": [0.05, 0.12, 0.22],
        "camera": {"position": [0.0, 1.6, 2.6], "focal_point": [0.0, 0.45, 0.0], "view_angle": 45},
        "lights": [{"headlight": True, "intensity": 0.6},
                   {"position": [1.0, 3.0, 2.0], "color": [1.0, 0.95, 0.85], "intensity": 0.7}],
        "objects": [{
            "name": "fish", "mesh": "fish.obj", "color": [0.95, 0.55, 0.15], "specular": 0.4,
            "trajectory": {"ends": "natural", "keys": path},
            "orientation": {"interpolation": "squad", "keys": turn},
            "parts": [{
                "name": "body", "combine": "sum",
                "deformations": [
                    {"name": "tail left", "controls": "fish-tail-left.controls", "radius": 0.3,
                     "phase": {"easing": "smooth", "keys": keys(left)}},
                    {"name": "tail right", "controls": "fish-tail-right.controls", "radius": 0.3,
                     "phase": {"easing": "smooth", "keys": keys(right)}},
                    {"name": "mouth", "controls": "fish-mouth.controls", "radius": 0.3,
                     "phase": {"easing": "smooth", "keys": keys(mouth)}},
                    {"name": "fin", "controls": "fish-fin.controls", "radius": 0.3,
                     "phase": {"easing": "smooth", "keys": keys(fin)}}]}]}]}


def face_scene():
    return {
        "format": "csrbf-scene", "version": 1,
        "duration": 4.0, "fps": 25,
        "background": [0.12, 0.12, 0.14],
        "camera": {"position": [0.5, 0.55, 2.6], "focal_point": [0.5, 0.5, 0.5], "view_angle": 30},
        "objects": [{
            "name": "head", "mesh": "face.obj", "color": [0.93, 0.76, 0.65], "specular": 0.15,
            "orientation": {"interpolation": "squad", "keys": [
                {"time": 0.0, "axis": [0, 1, 0], "angle": -20},
                {"time": 2.0, "axis": [0, 1, 0], "angle": 10},
                {"time": 4.0, "axis": [0, 1, 0], "angle": -20}]},
            "parts": [{
                "name": "skin",
                "deformations": [{
                    "name": "smile", "controls": "face.controls", "radius": 0.2,
                    "phase": {"easing": "smooth", "keys": keys([(0.0, 0.0), (1.2, 1.0), (2.6, 1.0), (3.8, 0.0)])}}]}]}]}


def ball_scene():
    r = 0.2
    lo, hi = r - 0.05, 1 - r + 0.05  # the ball presses 0.05 into a wall
    stops = [(0.5, lo, 0.5), (hi, 0.55, 0.4), (0.55, hi, 0.6), (lo, 0.5, 0.45), (0.45, 0.5, lo),
             (0.6, lo, 0.55), (hi, 0.45, 0.5), (0.5, 0.55, 0.5 + 0.15), (0.5, lo, 0.5)]
    track = [{"time": round(0.5 * k, 3), "position": [round(c, 4) for c in p], "continuity": -1}
             for k, p in enumerate(stops)]
    return {
        "format": "csrbf-scene", "version": 1,
        "duration": 0.5 * (len(stops) - 1), "fps": 25,
        "background": [0.1, 0.1, 0.12],
        "camera": {"position": [1.3, 1.5, 3.0], "focal_point": [0.5, 0.45, 0.5], "view_angle": 35},
        "objects": [
            {"name": "box", "mesh": "box.obj", "color": [0.75, 0.78, 0.85], "specular": 0.3,
             "parts": [
                 {"name": "walls",
                  "deformations": [{"name": "dents", "contact": {"collider": "ball", "collider_radius": r},
                                    "radius": 0.4, "kernel": "c2"}]},
                 {"name": "front glass", "group": "front", "color": [0.7, 0.85, 1.0], "opacity": 0.25}]},
            {"name": "ball", "mesh": "sphere.obj", "color": [1.0, 0.55, 0.5], "specular": 0.6,
             "texture": "checker.png", "texture_mapping": "sphere",
             "trajectory": {"ends": "natural", "keys": track}}]}


def main():
    text, n = box_obj()
    assert n == 386, n
    write("box.obj", text)
    write("sphere.obj", sphere_obj())
    with open(os.path.join(ROOT, "checker.png"), "wb") as f:
        f.write(png(128, 128, lambda x, y: (240, 240, 230) if (x // 16 + y // 16) % 2 == 0 else (200, 30, 30)))
    fish_controls()
    for name, scene in (("fish", fish_scene()), ("face", face_scene()), ("ball", ball_scene())):
        write(name + ".scene.json", json.dumps(scene, indent=1) + "\n")


if __name__ == "__main__":
    main()
