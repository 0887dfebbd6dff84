#!/usr/bin/env python3
"""Print Mitsuba 3.9.1's surface parameterisation (uv, dp/du, shading frame) at ray hits on
every kind of shape, for tests/mitsuba_files.rs (anisotropic BSDFs follow the shading frame's
tangent, which Mitsuba takes from dp/du).

    .venv/bin/python validation/mitsuba/frames.py > tests/data/mitsuba_frames.txt

The scene is tests/data/frames.xml (read by both); rays start at the origin, where its sensor
sits, so penumbra's camera-relative coordinates equal the world's.
"""
import os
import sys

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")
HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
SCENE = os.path.join(REPO, "tests", "data", "frames.xml")

TARGETS = {
    "sphere": (-3, 5, 0),
    "disk": (0, 5, 0),
    "rectangle": (3, 5, 0),
    "cube": (-3, 5, 3),
    "obj": (0, 5, 3),
    "cylinder": (3, 5, 3),
    "instance": (0, 5, -3),
    "ply": (3, 5, -3),
}

scene = mi.load_file(SCENE)
rng = np.random.default_rng(7)
print("# Mitsuba", mi.__version__, "scalar_rgb: python validation/mitsuba/frames.py")
print("# name ox oy oz dx dy dz | t px py pz ngx ngy ngz nsx nsy nsz ssx ssy ssz u v dpdux dpduy dpduz")
for name, c in TARGETS.items():
    for k in range(12):
        target = np.array(c, dtype=float) + rng.uniform(-0.6, 0.6, 3)
        d = target / np.linalg.norm(target)
        ray = mi.Ray3f(mi.Point3f(0, 0, 0), mi.Vector3f(*d))
        si = scene.ray_intersect(ray)
        head = f"{name} 0 0 0 {d[0]:.9g} {d[1]:.9g} {d[2]:.9g} |"
        if not si.is_valid():
            print(head, "miss")
            continue
        vals = [si.t, *si.p, *si.n, *si.sh_frame.n, *si.sh_frame.s, *si.uv, *si.dp_du]
        print(head, " ".join(f"{float(v):.9g}" for v in vals))
