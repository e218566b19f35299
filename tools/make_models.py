#!/usr/bin/env python3
"""Writes the small test/demo models in recordings/models (our own geometry, no third-party data):
cube.obj (unit cube centred at the origin), sphere.ply (icosphere, radius 1, 642 vertices),
torus.gltf (major radius 1, minor 0.35, embedded buffer). Re-running reproduces the files byte for byte."""
import base64
import math
import os
import struct
import sys

out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "recordings", "models")
os.makedirs(out, exist_ok=True)

# Cube: 24 vertices (flat normals), 12 triangles, CCW from outside.
faces = [((1, 0, 0), (0, 1, 0), (0, 0, 1)), ((-1, 0, 0), (0, 0, 1), (0, 1, 0)), ((0, 1, 0), (0, 0, 1), (1, 0, 0)),
         ((0, -1, 0), (1, 0, 0), (0, 0, 1)), ((0, 0, 1), (1, 0, 0), (0, 1, 0)), ((0, 0, -1), (0, 1, 0), (1, 0, 0))]
with open(os.path.join(out, "cube.obj"), "w") as f:
    f.write("# mrgi unit cube, centred at the origin, side 1\n")
    vi = 1
    for fi, (n, u, v) in enumerate(faces):
        for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            p = [0.5 * n[k] + 0.5 * su * u[k] + 0.5 * sv * v[k] for k in range(3)]
            f.write("v %g %g %g\n" % tuple(p))
        f.write("vn %g %g %g\n" % n)
    for fi in range(6):
        a = 4 * fi + 1
        f.write("f %d//%d %d//%d %d//%d\n" % (a, fi + 1, a + 1, fi + 1, a + 2, fi + 1))
        f.write("f %d//%d %d//%d %d//%d\n" % (a, fi + 1, a + 2, fi + 1, a + 3, fi + 1))

# Icosphere.
t = (1 + 5 ** 0.5) / 2
verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
         (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
verts = [tuple(c / math.sqrt(sum(x * x for x in v)) for c in v) for v in verts]
tris = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6),
        (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10),
        (8, 6, 7), (9, 8, 1)]
for _ in range(3):
    cache = {}
    def mid(a, b):
        key = (min(a, b), max(a, b))
        if key not in cache:
            m = [(verts[a][k] + verts[b][k]) / 2 for k in range(3)]
            n = math.sqrt(sum(x * x for x in m))
            verts.append(tuple(x / n for x in m))
            cache[key] = len(verts) - 1
        return cache[key]
    nt = []
    for a, b, c in tris:
        ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
        nt += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
    tris = nt
with open(os.path.join(out, "sphere.ply"), "w") as f:
    f.write("ply\nformat ascii 1.0\ncomment mrgi icosphere radius 1\nelement vertex %d\n" % len(verts))
    f.write("property float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\n")
    f.write("element face %d\nproperty list uchar int vertex_indices\nend_header\n" % len(tris))
    for v in verts:
        f.write("%.6f %.6f %.6f %.6f %.6f %.6f\n" % (v + v))
    for a, b, c in tris:
        f.write("3 %d %d %d\n" % (a, b, c))

# Torus (z is the symmetry axis), glTF 2.0 with an embedded buffer.
R, r, nu, nv = 1.0, 0.35, 32, 16
pos, nor, idx = [], [], []
for i in range(nu):
    u = 2 * math.pi * i / nu
    for j in range(nv):
        v = 2 * math.pi * j / nv
        n = (math.cos(u) * math.cos(v), math.sin(u) * math.cos(v), math.sin(v))
        pos.append(((R + r * math.cos(v)) * math.cos(u), (R + r * math.cos(v)) * math.sin(u), r * math.sin(v)))
        nor.append(n)
for i in range(nu):
    for j in range(nv):
        a, b = i * nv + j, ((i + 1) % nu) * nv + j
        c, d = ((i + 1) % nu) * nv + (j + 1) % nv, i * nv + (j + 1) % nv
        idx += [a, b, c, a, c, d]
blob = b"".join(struct.pack("<3f", *p) for p in pos) + b"".join(struct.pack("<3f", *n) for n in nor)
blob += b"".join(struct.pack("<I", i) for i in idx)
nvtx = len(pos)
lo = [min(p[k] for p in pos) for k in range(3)]
hi = [max(p[k] for p in pos) for k in range(3)]
import json
gltf = {
    "asset": {"version": "2.0", "generator": "mrgi tools/make_models.py"},
    "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2}]}],
    "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
    "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 12 * nvtx},
                    {"buffer": 0, "byteOffset": 12 * nvtx, "byteLength": 12 * nvtx},
                    {"buffer": 0, "byteOffset": 24 * nvtx, "byteLength": 4 * len(idx)}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": nvtx, "type": "VEC3", "min": lo, "max": hi},
                  {"bufferView": 1, "componentType": 5126, "count": nvtx, "type": "VEC3"},
                  {"bufferView": 2, "componentType": 5125, "count": len(idx), "type": "SCALAR"}],
}
with open(os.path.join(out, "torus.gltf"), "w") as f:
    json.dump(gltf, f, indent=1)
    f.write("\n")
print("wrote cube.obj, sphere.ply (%d vertices), torus.gltf (%d vertices) to %s" % (len(verts), nvtx, out))
