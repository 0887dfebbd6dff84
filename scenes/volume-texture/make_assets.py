#!/usr/bin/env python3
"""Writes the assets of volume-texture.xml with Mitsuba 3.9.1's own writers (run once; the
outputs are committed): a 3-channel solid texture `bands.vol` (16^3, colour bands along
x, y and z), a 1-channel `rough.vol` (8^3, roughness rising along y), and the environment
map `sky.hdr` (RGBE), converted from scenes/textures/sky-64x32.exr.

Usage: .venv/bin/python scenes/volume-texture/make_assets.py
"""
import os

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")
HERE = os.path.dirname(os.path.abspath(__file__))

n = 16
z, y, x = np.meshgrid(*(np.arange(n) + 0.5,) * 3, indexing="ij")
bands = np.stack([
    0.15 + 0.7 * (np.sin(x * 0.8) * 0.5 + 0.5),
    0.15 + 0.6 * (y / n),
    0.1 + 0.8 * ((z.astype(int) // 4) % 2),
], axis=-1).astype(np.float32)
mi.VolumeGrid(bands).write(os.path.join(HERE, "bands.vol"))

m = 8
rough = np.repeat(np.linspace(0.05, 0.6, m, dtype=np.float32)[None, :, None], m, axis=0)
rough = np.repeat(rough, m, axis=2)[..., None]
mi.VolumeGrid(rough).write(os.path.join(HERE, "rough.vol"))

sky = mi.Bitmap(os.path.join(HERE, "..", "textures", "sky-64x32.exr"))
sky.convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, False).write(
    os.path.join(HERE, "sky.hdr"))
print("wrote bands.vol, rough.vol, sky.hdr")
