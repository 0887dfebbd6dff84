"""Compares penumbra's fitted sigmoid-polynomial table with the one Mitsuba 3.9.1 ships.

Measurement only: reads Mitsuba's installed `data/srgb.coeff` at run time (nothing of it is
stored in penumbra) and penumbra's table as written by
`cargo run --release --example spectral_table -- TABLE.bin`, evaluates both spectra at every
entry at 360, 370, ..., 830 nm, and prints the largest differences by class of entry:

- reproduced: Mitsuba's spectrum reproduces the entry's colour under D65 (every channel within
  1e-3, integrated here on the 5 nm CIE grid), so the 3-parameter spectrum is unique;
- out of reach: it does not (saturated colours at the gamut boundary), where the result is
  wherever the damped optimiser stopped.

Run: /path/to/mitsuba-venv/bin/python compare_table.py TABLE.bin
"""
import os
import sys

import numpy as np
import mitsuba as mi

mi.set_variant("scalar_spectral")
RES = 64

path = os.path.join(os.path.dirname(mi.__file__), "data", "srgb.coeff")
raw = open(path, "rb").read()
assert raw[:4] == b"SPEC"
res = int(np.frombuffer(raw[4:8], np.uint32)[0])
assert res == RES
scale = np.frombuffer(raw[8 : 8 + 4 * res], np.float32)
n = 3 * res**3 * 3
theirs = np.frombuffer(raw[8 + 4 * res : 8 + 4 * res + 4 * n], np.float32).reshape(3, res, res, res, 3)
ours = np.fromfile(sys.argv[1], dtype="<f4").reshape(3, res, res, res, 3)

lam = np.arange(360.0, 831.0, 10.0, dtype=np.float32)


def spectra(c):
    x = (c[..., 0:1] * lam + c[..., 1:2]) * lam + c[..., 2:3]
    return np.maximum(0.0, 0.5 * x / np.sqrt(x * x + 1.0) + 0.5)


# D65-weighted sRGB matching functions on the 5 nm grid (trapezoid), for the colour test.
grid = np.arange(360.0, 831.0, 5.0)
xyz = np.array([list(mi.cie1931_xyz(float(w))) for w in grid])
d65 = np.array([mi.cie_d65(float(w)) for w in grid])
M = np.array([[3.240479, -1.537150, -0.498535], [-0.969256, 1.875991, 0.041556], [0.055648, -0.204043, 1.057311]])
wts = np.full(len(grid), 5.0)
wts[0] = wts[-1] = 2.5
cmf = (xyz * (d65 * wts)[:, None]) @ M.T  # (grid, 3)
cmf /= (xyz[:, 1] * d65 * wts).sum()


def colour(c):
    x = (c[..., 0:1] * grid + c[..., 1:2]) * grid + c[..., 2:3]
    s = np.maximum(0.0, 0.5 * x / np.sqrt(x * x + 1.0) + 0.5)
    return s @ cmf


# Target colour of each entry.
k = np.arange(res)
b = scale[None, :, None, None]
xr = (np.arange(res, dtype=np.float32) / np.float32(res - 1))[None, None, None, :]
yr = (np.arange(res, dtype=np.float32) / np.float32(res - 1))[None, None, :, None]
target = np.zeros((3, res, res, res, 3))
for l in range(3):
    target[l, ..., l] = np.broadcast_to(b, (1, res, res, res))[0]
    target[l, ..., (l + 1) % 3] = (xr * b)[0]
    target[l, ..., (l + 2) % 3] = (yr * b)[0]

reached = np.abs(colour(theirs.astype(np.float64)) - target).max(axis=-1) < 1e-3
ds = np.abs(spectra(ours) - spectra(theirs)).max(axis=-1)
dc = np.abs(colour(ours.astype(np.float64)) - colour(theirs.astype(np.float64))).max(axis=-1)
# Classes by where the entry sits (the same rule as tests/spectral.rs):
z = np.broadcast_to(b, ds.shape)
second = np.broadcast_to(np.maximum(xr, yr), ds.shape)
dark = z < 0.05
edge = (z >= 0.9) & (second >= 0.9) & ~dark
rest = ~dark & ~edge
for name, mask in [
    ("well-conditioned (z >= 0.05, not bright edge), reproduced", rest & reached),
    ("well-conditioned, out of reach", rest & ~reached),
    ("bright edge (z >= 0.9, second channel >= 0.9 z)", edge),
    ("dark (z < 0.05)", dark),
    ("all", np.ones_like(reached)),
]:
    d = ds[mask]
    print(
        f"{name}: entries {mask.sum()}  spectrum |diff| max {d.max():.3g}  "
        f"p99.9 {np.percentile(d, 99.9):.3g}  p50 {np.percentile(d, 50):.3g}  "
        f"colour |diff| max {dc[mask].max():.3g}"
    )
worst = np.unravel_index(np.argmax(ds), ds.shape)
print("worst entry (block, k, j, i):", worst, "target", target[worst], "ours", ours[worst], "theirs", theirs[worst])

# By brightness of the entry (largest channel): where the differences sit.
print("by brightness index k (largest channel = scale[k]):")
for lo, hi in [(0, 4), (4, 8), (8, 16), (16, 32), (32, 48), (48, 64)]:
    d = ds[:, lo:hi]
    r = reached[:, lo:hi]
    print(
        f"  k {lo:2d}-{hi - 1:2d} (z {scale[lo]:.2e}-{scale[hi - 1]:.3f}): max {d.max():.3g} "
        f"p99.9 {np.percentile(d, 99.9):.3g} frac>1e-3 {np.mean(d > 1e-3):.4f} "
        f"out-of-reach max {d[~r].max() if (~r).any() else 0:.3g}"
    )
