"""Records Mitsuba 3.9.1's spectral-mode values for tests/spectral.rs.

Run with a Python environment holding mitsuba==3.9.1 and numpy:
    python tests/data/spectral/record.py > tests/data/spectral/mitsuba_values.txt

Every line is `tag field...`, numbers printed with 9 significant digits (f32 round trip):
- `upsample class r g b mean v...`: `srgb_model_mean(srgb_model_fetch(rgb))` and
  `srgb_model_eval` of the same coefficients at the 12 wavelengths of the `wavelengths` line.
- `colour r g b X Y Z`: CIE XYZ (Y of the unit spectrum = 1) of the same upsampled spectrum
  under D65, integrated on a 1 nm grid (trapezoid) with Mitsuba's `cie1931_xyz` and `cie_d65`.
- `sample u wavelength weight pdf`: `sample_rgb_spectrum(u)` and `pdf_rgb_spectrum` there.
- `convert v0..v3 l0..l3 r g b x y z luminance`: `spectrum_to_srgb`, `spectrum_to_xyz`,
  `luminance` of four values at four wavelengths.
- `d65 r g b scale v...`: the `d65` spectrum plugin with that `color` (`-` for none) and
  `scale`, evaluated at the 12 wavelengths.
- `irregular n w... v... | v(at 12 wavelengths)` and `regular n min max v... | ...`: the list
  plugins at the 12 wavelengths.
Nothing of Mitsuba's coefficient table is recorded, only evaluated spectra.
"""
import numpy as np
import mitsuba as mi

mi.set_variant("scalar_spectral")
assert mi.__version__ == "3.9.1", mi.__version__


def f(x):
    return "%.9g" % float(x)


WL = [[360.0, 400.5, 455.0, 500.0], [532.1, 555.0, 600.0, 650.7], [700.0, 750.0, 800.0, 830.0]]
print("wavelengths", " ".join(f(w) for s in WL for w in s))


def at12(eval4):
    out = []
    for s in WL:
        out.extend(eval4(mi.Spectrum(s)))
    return out


rng = np.random.default_rng(43)
colours = []
colours += [("grey", (v, v, v)) for v in (0.0, 0.001, 0.18, 0.5, 0.9, 0.999, 1.0)]
colours += [("primary", c) for c in ((1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (0, 1, 1), (1, 0, 1))]
colours += [("clamped", c) for c in ((1.2, -0.1, 0.5), (2.0, 2.0, 0.3), (-0.5, 0.2, 0.2))]
colours += [("boundary", c) for c in ((0.95, 0.02, 0.01), (0.01, 0.9, 0.95), (0.02, 0.03, 0.97),
                                      (0.6, 0.0, 0.3), (0.0, 0.45, 0.2), (0.8, 0.75, 0.0))]
colours += [("nearwhite", c) for c in ((0.95, 1.0, 1.0), (1.0, 0.97, 0.99), (0.99, 0.99, 0.93))]
colours += [("dark", c) for c in ((0.001, 0.002, 0.0005), (0.004, 0.001, 0.003), (0.02, 0.01, 0.015))]
colours += [("random", tuple(c)) for c in rng.random((200, 3))]
# Random colours with one channel at or near zero (near the boundary of the reachable set).
for c in rng.random((40, 3)):
    c[rng.integers(3)] = rng.choice([0.0, 1e-3])
    colours.append(("edge", tuple(c)))

# D65-weighted linear sRGB of a spectrum: 1 nm trapezoid over [360, 830] nm with Mitsuba's
# cie1931_xyz and cie_d65, normalised so that the unit spectrum has Y = 1.
GRID = np.arange(360.0, 831.0, 1.0)
CMF = np.array([list(mi.cie1931_xyz(float(w))) for w in GRID]) * np.array(
    [mi.cie_d65(float(w)) for w in GRID])[:, None]
CMF[0] *= 0.5
CMF[-1] *= 0.5
CMF /= CMF[:, 1].sum()


def d65_colour(coeff):
    s = []
    for i in range(0, len(GRID), 4):
        chunk = list(GRID[i:i + 4])
        n = len(chunk)
        s.extend(list(mi.srgb_model_eval(coeff, mi.Spectrum(chunk + [830.0] * (4 - n))))[:n])
    return np.array(s) @ CMF


for cls, c in colours:
    c = tuple(np.float32(x) for x in c)
    coeff = mi.srgb_model_fetch(mi.Color3f(*[float(x) for x in c]))
    mean = mi.srgb_model_mean(coeff)
    vals = at12(lambda w: mi.srgb_model_eval(coeff, w))
    print("upsample", cls, " ".join(f(x) for x in c), f(mean), " ".join(f(v) for v in vals))
    print("colour", " ".join(f(x) for x in c), " ".join(f(x) for x in d65_colour(coeff)))

for u in np.concatenate([np.linspace(0.0, 1.0, 41), rng.random(40)]):
    u = float(np.float32(u))
    wl, weight = mi.sample_rgb_spectrum(u)
    print("sample", f(u), f(wl), f(weight), f(mi.pdf_rgb_spectrum(wl)))

convert_cases = [([1, 1, 1, 1], s) for s in WL]
convert_cases += [([1, 1, 1, 1], [450.0, 550.0, 650.0, 359.0])]
for _ in range(12):
    v = rng.random(4) * 3
    w = 360 + rng.random(4) * 470
    convert_cases.append((list(v), list(w)))
for v, w in convert_cases:
    v = [float(np.float32(x)) for x in v]
    w = [float(np.float32(x)) for x in w]
    rgb = mi.spectrum_to_srgb(mi.Spectrum(v), mi.Spectrum(w))
    xyz = mi.spectrum_to_xyz(mi.Spectrum(v), mi.Spectrum(w))
    lum = mi.luminance(mi.Spectrum(v), mi.Spectrum(w))
    print("convert", " ".join(f(x) for x in v + w), " ".join(f(x) for x in list(rgb) + list(xyz)), f(lum))

si = mi.SurfaceInteraction3f()


def texture_at12(tex):
    def ev(w):
        si.wavelengths = w
        return tex.eval(si)
    return at12(ev)


d65_cases = [(None, 1.0), (None, 2.5), ((1.0, 1.0, 1.0), 1.0), ((10.0, 10.0, 10.0), 1.0),
             ((17.0, 12.0, 4.0), 1.0), ((0.5, 0.2, 0.9), 3.0),
             ((5.0, 0.0, 0.0), 1.0), ((0.2, 0.8, 0.1), 0.5)]
# A black colour is refused by Mitsuba 3.9.1 here (its scale becomes 0 and the D65 table
# "has no probability mass"), so it is not recorded.
for c, s in d65_cases:
    d = {"type": "d65", "scale": s}
    if c is not None:
        d["color"] = mi.ScalarColor3f(*c)
    tex = mi.load_dict(d)
    vals = texture_at12(tex)
    cs = "- - -" if c is None else " ".join(f(x) for x in c)
    print("d65", cs, f(s), " ".join(f(v) for v in vals))

irr = [([400.0, 450.0, 600.0, 700.0], [0.2, 0.6, 0.4, 0.9]),
       ([380.0, 381.0, 500.0, 780.0], [1.0, 0.5, 0.25, 0.75])]
for w, v in irr:
    tex = mi.load_dict({"type": "irregular", "wavelengths": ", ".join(map(str, w)),
                        "values": ", ".join(map(str, v))})
    vals = texture_at12(tex)
    print("irregular", len(w), " ".join(f(x) for x in w + v), "|", " ".join(f(x) for x in vals))
reg = [(400.0, 700.0, [0.2, 0.6, 0.4, 0.9]), (360.0, 830.0, [1.0, 0.0, 0.5])]
for lo, hi, v in reg:
    tex = mi.load_dict({"type": "regular", "wavelength_min": lo, "wavelength_max": hi,
                        "values": ", ".join(map(str, v))})
    vals = texture_at12(tex)
    print("regular", len(v), f(lo), f(hi), " ".join(f(x) for x in v), "|", " ".join(f(x) for x in vals))
