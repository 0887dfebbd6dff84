#!/usr/bin/env python3
"""Mitsuba 3.9.1's own image means against the suite's references (issue 44).

For each suite scene given, renders it with Mitsuba's scalar_rgb exactly as the suite test
renders it with penumbra (spp = 2e6 / pixels, seed 0, the scene's integrator) and prints the
relative difference of the image mean from the reference's, per channel, and its z with the
standard error from the reference's per-sample variance.

    python3 -m venv venv && venv/bin/pip install mitsuba==3.9.1 numpy
    cd validation/mitsuba-suite/tests/scenes
    ../../../../venv/bin/python ../../../suite-means/mitsuba_means.py bsdf_spheres/test_constant_path.xml ...

tests/mitsuba_suite.rs lists the scene-channels where Mitsuba itself is off its reference
(MITSUBA_OFFSETS) with the relative differences this script printed.
"""
import os
import sys

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")
for path in sys.argv[1:]:
    folder, name = os.path.dirname(path), os.path.basename(path)[:-4]
    base, integrator = name.rsplit("_", 1)
    ref = np.array(mi.Bitmap(f"{folder}/refs/{base}_ref_rgb.exr"))[..., :3].astype(np.float64)
    var = np.array(mi.Bitmap(f"{folder}/refs/{base}_ref_rgb_var.exr"))[..., :3].astype(np.float64)
    pixels = ref.shape[0] * ref.shape[1]
    spp = int(2e6 // pixels)
    scene = mi.load_file(path, spp=spp, integrator=integrator)
    img = np.array(mi.render(scene, seed=0, spp=spp)).astype(np.float64)[..., :3]
    se = np.sqrt(var.reshape(-1, 3).sum(0) / spp) / pixels
    ref_mean = ref.reshape(-1, 3).mean(0)
    diff = img.reshape(-1, 3).mean(0) - ref_mean
    print(name, "spp", spp, "rel %", np.round(100 * diff / ref_mean, 3), "z", np.round(diff / se, 2))
