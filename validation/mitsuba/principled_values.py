#!/usr/bin/env python3
"""Tabulate Mitsuba 3's `principled` and `principledthin` BSDF values for penumbra's tests
(tests/bsdf_mitsuba.rs, `principled_bsdfs_match_mitsuba_values`).

For each parameter set (a <bsdf> element that Mitsuba loads, and the same parameters as
plain key=value pairs for penumbra's PrincipledParams / PrincipledThinParams):
  e lines: eval (RGB, includes |cos θo|) and pdf at direction pairs (wi, wo), local frame.
Directions come from a fixed numpy seed: uniform on the sphere (both sides: these BSDFs see
both), pairs near the mirror direction, near the transmitted direction (refracted through
the macro-normal for `principled`, straight through for the thin sheet), near-grazing ones.

Mitsuba's llvm_ad_rgb variant (the one the reference renders use): where its scalar variant
differs (principled with spec_trans = 1 and sheen > 0: scalar_rgb drops the sheen with the
diffuse lobe), penumbra follows the vectorised variants. With --variant scalar_rgb those
cases are left out.

Usage: python validation/mitsuba/principled_values.py [--variant llvm_ad_rgb|scalar_rgb] [OUT]
       (default tests/data/mitsuba_principled_values.txt). Radiance mode.
"""
import argparse
import os
import sys

import numpy as np

SCRIPT_DIR = os.path.dirname(os.path.abspath(__file__))
REPO_ROOT = os.path.dirname(os.path.dirname(SCRIPT_DIR))
sys.path.insert(0, SCRIPT_DIR)
import mitsuba_util as mu  # noqa: E402

# (name, plugin, parameters): floats, or 3-tuples for base_color. Each lobe alone, then
# combinations, anisotropy, transmission from both sides, IOR corner cases, sampling rates.
P = "principled"
T = "principledthin"
CASES = [
    ("principled-default", P, {}),
    ("principled-diffuse-only", P, {"base_color": (0.8, 0.4, 0.2), "roughness": 0.9, "specular": 0.0}),
    ("principled-flatness", P, {"base_color": (0.3, 0.6, 0.9), "roughness": 0.6, "flatness": 0.7, "specular": 0.0}),
    ("principled-metallic", P, {"base_color": (0.9, 0.6, 0.3), "roughness": 0.3, "metallic": 1.0}),
    ("principled-spec-tint", P, {"base_color": (0.2, 0.5, 0.9), "roughness": 0.25, "spec_tint": 0.8, "specular": 0.8}),
    ("principled-sheen", P, {"base_color": (0.7, 0.2, 0.4), "sheen": 1.0, "sheen_tint": 0.5, "specular": 0.0}),
    ("principled-clearcoat-only", P, {"base_color": (0.0, 0.0, 0.0), "clearcoat": 1.0, "clearcoat_gloss": 0.5, "specular": 0.0}),
    ("principled-clearcoat-glossy", P, {"clearcoat": 0.5, "clearcoat_gloss": 0.9, "roughness": 0.7}),
    ("principled-anisotropic", P, {"base_color": (0.6, 0.6, 0.3), "anisotropic": 0.8, "roughness": 0.4, "metallic": 0.5}),
    ("principled-smooth", P, {"roughness": 0.05, "metallic": 0.3}),
    ("principled-spec-trans", P, {"base_color": (0.9, 0.8, 0.5), "spec_trans": 1.0, "roughness": 0.3, "eta": 1.33}),
    ("principled-spec-trans-partial", P, {"spec_trans": 0.6, "roughness": 0.5, "specular": 0.7, "metallic": 0.2, "anisotropic": 0.4}),
    ("principled-spec-trans-eta-below-1", P, {"spec_trans": 0.7, "roughness": 0.4, "eta": 0.8, "spec_tint": 0.5, "base_color": (0.5, 0.9, 0.3)}),
    ("principled-spec-trans-eta-1", P, {"spec_trans": 0.5, "roughness": 0.4, "eta": 1.0}),
    ("principled-spec-trans-specular-0", P, {"spec_trans": 0.5, "roughness": 0.4, "specular": 0.0}),
    ("principled-spec-trans-1-sheen", P, {"spec_trans": 1.0, "sheen": 1.0, "sheen_tint": 0.3, "base_color": (0.4, 0.8, 0.6)}),
    ("principled-all", P, {"base_color": (0.9, 0.3, 0.1), "roughness": 0.35, "anisotropic": 0.6, "metallic": 0.3,
                           "spec_trans": 0.4, "specular": 0.6, "spec_tint": 0.4, "sheen": 0.3, "sheen_tint": 0.2,
                           "flatness": 0.3, "clearcoat": 0.6, "clearcoat_gloss": 0.3}),
    ("principled-sampling-rates", P, {"clearcoat": 0.7, "spec_trans": 0.3, "diffuse_reflectance_sampling_rate": 0.3,
                                      "main_specular_sampling_rate": 2.0, "clearcoat_sampling_rate": 0.5}),
    ("principledthin-default", T, {}),
    ("principledthin-docs", T, {"base_color": (0.7, 0.1, 0.1), "roughness": 0.15, "spec_tint": 0.1, "anisotropic": 0.5,
                                "spec_trans": 0.8, "diff_trans": 0.3, "eta": 1.33}),
    ("principledthin-diff-trans-only", T, {"base_color": (0.2, 0.9, 0.4), "diff_trans": 2.0}),
    ("principledthin-diffuse-sheen", T, {"diff_trans": 1.0, "sheen": 1.0, "sheen_tint": 0.5, "flatness": 0.5,
                                         "roughness": 0.8, "base_color": (0.6, 0.5, 0.1)}),
    ("principledthin-spec-trans-1", T, {"spec_trans": 1.0, "roughness": 0.6, "eta": 2.0}),
    ("principledthin-eta-0.5", T, {"spec_trans": 0.5, "roughness": 0.7, "eta": 0.5, "spec_tint": 0.7,
                                   "base_color": (0.3, 0.3, 0.9)}),
    ("principledthin-sampling-rates", T, {"spec_trans": 0.5, "diff_trans": 0.8, "roughness": 0.3,
                                          "specular_reflectance_sampling_rate": 0.5,
                                          "specular_transmittance_sampling_rate": 2.0,
                                          "diffuse_reflectance_sampling_rate": 0.7,
                                          "diffuse_transmittance_sampling_rate": 1.5}),
]

# Cases whose values differ between Mitsuba's scalar and vectorised variants.
JIT_ONLY = {"principled-spec-trans-1-sheen"}


def xml_of(plugin, params):
    items = []
    for k, v in params.items():
        if isinstance(v, tuple):
            items.append(f'<rgb name="{k}" value="{v[0]}, {v[1]}, {v[2]}"/>')
        else:
            items.append(f'<float name="{k}" value="{v}"/>')
    return f'<bsdf type="{plugin}">' + "".join(items) + "</bsdf>"


def params_line(params):
    out = []
    for k, v in params.items():
        out.append(f"{k}={v[0]},{v[1]},{v[2]}" if isinstance(v, tuple) else f"{k}={v}")
    return " ".join(out)


def uniform_sphere(rng):
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def grazing(rng, z):
    phi = rng.uniform(0, 2 * np.pi)
    s = np.sqrt(1 - z * z)
    return np.array([s * np.cos(phi), s * np.sin(phi), z])


def refracted(wi, eta):
    """wi refracted through the macro-normal (None under total internal reflection)."""
    e = eta if wi[2] > 0 else 1 / eta
    c = abs(wi[2])
    s2 = (1 - c * c) / (e * e)
    if s2 >= 1:
        return None
    t = -wi / e
    t[2] = -np.sign(wi[2]) * np.sqrt(1 - s2)
    return t / np.linalg.norm(t)


def direction_pairs(rng, plugin, params):
    transmissive = params.get("spec_trans", 0) > 0 or params.get("diff_trans", 0) > 0
    # Without transmission `principled` is black from behind: most pairs on the front there.
    one_sided = plugin == P and not transmissive
    pairs = []
    for k in range(60):
        wi, wo = uniform_sphere(rng), uniform_sphere(rng)
        if one_sided and k < 45:
            wi[2] = abs(wi[2])
            if k < 30:
                wo[2] = abs(wo[2])
        pairs.append((wi, wo))
    for k in range(15):  # near the mirror direction, from either side
        wi = uniform_sphere(rng)
        if one_sided and k < 12:
            wi[2] = abs(wi[2])
        wo = np.array([-wi[0], -wi[1], wi[2]]) + 0.1 * rng.normal(size=3)
        pairs.append((wi, wo / np.linalg.norm(wo)))
    if transmissive:
        for _ in range(20):  # near the transmitted direction
            wi = uniform_sphere(rng)
            if plugin == T:
                center = -wi
            else:
                eta = params.get("eta")
                if eta is None:
                    s = params.get("specular", 0.5) or 1e-3
                    eta = 2 / (1 - np.sqrt(0.08 * s)) - 1
                center = refracted(wi, eta)
                if center is None:
                    center = np.array([-wi[0], -wi[1], -wi[2]])
            wo = center + 0.1 * rng.normal(size=3)
            pairs.append((wi, wo / np.linalg.norm(wo)))
    for z in [1e-3, 1e-2, 0.05, -0.05]:
        pairs.append((grazing(rng, z), uniform_sphere(rng)))
        pairs.append((uniform_sphere(rng), grazing(rng, z)))
    return pairs


def evaluate(mi, jit, bsdf, pairs):
    ctx = mi.BSDFContext()
    wi = np.array([p[0] for p in pairs], dtype=np.float32)
    wo = np.array([p[1] for p in pairs], dtype=np.float32)
    if jit:
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(wi[:, 0], wi[:, 1], wi[:, 2])
        si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
        si.n = mi.Normal3f(0, 0, 1)
        w = mi.Vector3f(wo[:, 0], wo[:, 1], wo[:, 2])
        f = np.array(bsdf.eval(ctx, si, w)).reshape(3, -1).T
        p = np.array(bsdf.pdf(ctx, si, w)).reshape(-1)
        return wi, wo, f, p
    fs, ps = [], []
    for a, b in zip(wi, wo):
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*a)
        si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
        si.n = mi.Normal3f(0, 0, 1)
        w = mi.Vector3f(*b)
        fs.append(list(bsdf.eval(ctx, si, w)))
        ps.append(float(bsdf.pdf(ctx, si, w)))
    return wi, wo, np.array(fs), np.array(ps)


def fmt(v):
    return " ".join(f"{float(x):.9g}" for x in v)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--variant", choices=("llvm_ad_rgb", "scalar_rgb"), default="llvm_ad_rgb")
    ap.add_argument("out", nargs="?", default=os.path.join(REPO_ROOT, "tests/data/mitsuba_principled_values.txt"))
    args = ap.parse_args()
    mi, variant = mu.select_variant(args.variant)
    jit = mu.is_jit_variant(variant)
    lines = [f"# generated by validation/mitsuba/principled_values.py: Mitsuba {mi.__version__} {variant}",
             "# case NAME | xml <bsdf> | params key=value (penumbra's *Params fields) |"
             " e wi.xyz wo.xyz eval.rgb pdf"]
    for ci, (name, plugin, params) in enumerate(CASES):
        if not jit and name in JIT_ONLY:
            print(f"skipping {name}: scalar_rgb differs from the vectorised variants", file=sys.stderr)
            continue
        xml = xml_of(plugin, params)
        bsdf = mi.load_string(xml.replace("<bsdf ", '<bsdf version="3.0.0" ', 1))
        rng = np.random.default_rng(2000 + ci)
        wi, wo, f, p = evaluate(mi, jit, bsdf, direction_pairs(rng, plugin, params))
        lines += [f"case {name}", f"xml {xml}", f"params {plugin} {params_line(params)}".rstrip()]
        for k in range(len(p)):
            lines.append(f"e {fmt(wi[k])} {fmt(wo[k])} {fmt(f[k])} {float(p[k]):.9g}")
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print(f"wrote {args.out}: {len(CASES)} cases ({variant})", file=sys.stderr)


if __name__ == "__main__":
    main()
