#!/usr/bin/env python3
"""Tabulate Mitsuba 3's own BSDF values for penumbra's tests (tests/bsdf_mitsuba.rs).

For each BSDF configuration (an XML <bsdf> element, parsed by both renderers):
  e lines: eval (RGB, includes |cos θo|) and pdf at direction pairs (wi, wo), local frame
  s lines: a sample of a Dirac-delta lobe at (wi, u1, u2): wo, weight, eta
Directions come from a fixed numpy seed: uniform on the sphere, plus near-grazing ones.

Usage: python validation/mitsuba/bsdf_values.py [OUT]   (default tests/data/mitsuba_bsdf_values.txt)
Mitsuba 3.9.1, scalar_rgb variant, radiance mode.
"""
import os
import sys

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")
SCRIPT_DIR = os.path.dirname(os.path.abspath(__file__))
REPO_ROOT = os.path.dirname(os.path.dirname(SCRIPT_DIR))

# (name, xml, kind) with kind "eval" (smooth lobes: eval/pdf) or "delta" (sample weights)
CASES = [
    ("diffuse", '<bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.5, 0.8"/></bsdf>', "eval"),
    ("roughconductor-beckmann-0.1", '<bsdf type="roughconductor"><float name="alpha" value="0.1"/></bsdf>', "eval"),
    ("roughconductor-beckmann-0.5-Au", '<bsdf type="roughconductor"><float name="alpha" value="0.5"/><string name="material" value="Au"/></bsdf>', "eval"),
    ("roughconductor-ggx-0.3-Cu", '<bsdf type="roughconductor"><string name="distribution" value="ggx"/><float name="alpha" value="0.3"/><string name="material" value="Cu"/></bsdf>', "eval"),
    ("roughconductor-ggx-aniso", '<bsdf type="roughconductor"><string name="distribution" value="ggx"/><float name="alpha_u" value="0.05"/><float name="alpha_v" value="0.4"/><rgb name="eta" value="0.2, 0.9, 1.1"/><rgb name="k" value="3.9, 2.4, 2.1"/><rgb name="specular_reflectance" value="0.9, 0.8, 0.7"/></bsdf>', "eval"),
    ("roughconductor-beckmann-aniso", '<bsdf type="roughconductor"><float name="alpha_u" value="0.3"/><float name="alpha_v" value="0.1"/><string name="material" value="Al"/></bsdf>', "eval"),
    ("roughconductor-beckmann-novisible", '<bsdf type="roughconductor"><float name="alpha" value="0.3"/><boolean name="sample_visible" value="false"/></bsdf>', "eval"),
    ("roughconductor-ggx-1.0", '<bsdf type="roughconductor"><string name="distribution" value="ggx"/><float name="alpha" value="1.0"/><float name="eta" value="1.5"/><float name="k" value="0.0"/></bsdf>', "eval"),
    ("roughdielectric-beckmann-0.1", '<bsdf type="roughdielectric"><float name="alpha" value="0.1"/></bsdf>', "eval"),
    ("roughdielectric-ggx-0.3-water", '<bsdf type="roughdielectric"><string name="distribution" value="ggx"/><float name="alpha" value="0.3"/><string name="int_ior" value="water"/><rgb name="specular_transmittance" value="0.9, 0.7, 0.5"/></bsdf>', "eval"),
    ("roughdielectric-ggx-aniso", '<bsdf type="roughdielectric"><string name="distribution" value="ggx"/><float name="alpha_u" value="0.4"/><float name="alpha_v" value="0.1"/><float name="int_ior" value="2.4"/></bsdf>', "eval"),
    ("roughdielectric-ggx-novisible", '<bsdf type="roughdielectric"><string name="distribution" value="ggx"/><float name="alpha" value="0.5"/><boolean name="sample_visible" value="false"/><float name="int_ior" value="1.33"/><float name="ext_ior" value="1.5"/></bsdf>', "eval"),
    ("plastic-default", '<bsdf type="plastic"/>', "eval"),
    ("plastic-nonlinear", '<bsdf type="plastic"><rgb name="diffuse_reflectance" value="0.8, 0.3, 0.1"/><float name="int_ior" value="1.9"/><boolean name="nonlinear" value="true"/></bsdf>', "eval"),
    ("roughplastic-default", '<bsdf type="roughplastic"/>', "eval"),
    ("roughplastic-ggx-0.3-nonlinear", '<bsdf type="roughplastic"><string name="distribution" value="ggx"/><float name="alpha" value="0.3"/><rgb name="diffuse_reflectance" value="0.1, 0.6, 0.9"/><boolean name="nonlinear" value="true"/></bsdf>', "eval"),
    ("roughplastic-ggx-0.05-bk7", '<bsdf type="roughplastic"><string name="distribution" value="ggx"/><float name="alpha" value="0.05"/><string name="int_ior" value="bk7"/><rgb name="specular_reflectance" value="0.5, 0.5, 0.5"/></bsdf>', "eval"),
    ("roughplastic-beckmann-0.7", '<bsdf type="roughplastic"><float name="alpha" value="0.7"/><float name="int_ior" value="1.3"/></bsdf>', "eval"),
    ("roughplastic-ggx-0.3-diffuse-only", '<bsdf type="roughplastic"><string name="distribution" value="ggx"/><float name="alpha" value="0.3"/><float name="specular_reflectance" value="0"/></bsdf>', "eval"),
    ("roughplastic-ggx-0.3-specular-only", '<bsdf type="roughplastic"><string name="distribution" value="ggx"/><float name="alpha" value="0.3"/><float name="diffuse_reflectance" value="0"/></bsdf>', "eval"),
    ("twosided-roughconductor", '<bsdf type="twosided"><bsdf type="roughconductor"><string name="distribution" value="ggx"/><float name="alpha" value="0.3"/><string name="material" value="Ag"/></bsdf></bsdf>', "eval"),
    ("conductor-none", '<bsdf type="conductor"/>', "delta"),
    ("conductor-Au", '<bsdf type="conductor"><string name="material" value="Au"/></bsdf>', "delta"),
    ("conductor-eta-k", '<bsdf type="conductor"><rgb name="eta" value="0.2, 1.5, 3.0"/><rgb name="k" value="3.0, 0.0, 20.0"/><rgb name="specular_reflectance" value="0.5, 0.9, 1.0"/></bsdf>', "delta"),
    ("conductor-Cu", '<bsdf type="conductor"><string name="material" value="Cu"/></bsdf>', "delta"),
    ("dielectric-default", '<bsdf type="dielectric"/>', "delta"),
    ("dielectric-water-tint", '<bsdf type="dielectric"><string name="int_ior" value="water"/><rgb name="specular_reflectance" value="0.5, 0.6, 0.7"/><rgb name="specular_transmittance" value="0.9, 0.8, 0.7"/></bsdf>', "delta"),
    ("dielectric-diamond-in-water", '<bsdf type="dielectric"><string name="int_ior" value="diamond"/><string name="ext_ior" value="water"/></bsdf>', "delta"),
    ("thindielectric-default", '<bsdf type="thindielectric"/>', "delta"),
    ("plastic-specular", '<bsdf type="plastic"><rgb name="diffuse_reflectance" value="0.8, 0.3, 0.1"/></bsdf>', "delta"),
    # Adapters and textured parameters, looked up at uv = (0.5, 0.5) with dp/du = x, dp/dv = y
    # (texture paths relative to tests/, as penumbra's tests resolve them).
    ("textured-diffuse", '<bsdf type="diffuse"><texture type="bitmap" name="reflectance"><string name="filename" value="data/textures/rgb8.png"/></texture></bsdf>', "eval"),
    ("textured-roughconductor-alpha", '<bsdf type="roughconductor"><string name="distribution" value="ggx"/><texture type="bitmap" name="alpha"><string name="filename" value="data/textures/grey8.png"/><boolean name="raw" value="true"/></texture><string name="material" value="Au"/></bsdf>', "eval"),
    ("twosided-diffuse-roughconductor", '<bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.7, 0.2, 0.1"/></bsdf><bsdf type="roughconductor"><float name="alpha" value="0.2"/><string name="material" value="Cu"/></bsdf></bsdf>', "eval"),
    ("mask-roughconductor", '<bsdf type="mask"><float name="opacity" value="0.3"/><bsdf type="roughconductor"><string name="distribution" value="ggx"/><float name="alpha" value="0.25"/></bsdf></bsdf>', "eval"),
    ("mask-textured-diffuse", '<bsdf type="mask"><texture type="bitmap" name="opacity"><string name="filename" value="data/textures/grey8.png"/></texture><bsdf type="diffuse"/></bsdf>', "eval"),
    ("mask-pass-through", '<bsdf type="mask"><float name="opacity" value="0.3"/><bsdf type="conductor"/></bsdf>', "delta"),
    ("blendbsdf-diffuse-roughconductor", '<bsdf type="blendbsdf"><float name="weight" value="0.3"/><bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.6, 0.3"/></bsdf><bsdf type="roughconductor"><float name="alpha" value="0.15"/><string name="material" value="Al"/></bsdf></bsdf>', "eval"),
    ("blendbsdf-textured-weight", '<bsdf type="blendbsdf"><texture type="bitmap" name="weight"><string name="filename" value="data/textures/grey8.png"/></texture><bsdf type="roughplastic"/><bsdf type="roughdielectric"><float name="alpha" value="0.3"/></bsdf></bsdf>', "eval"),
    ("normalmap-tilted-roughconductor", '<bsdf type="normalmap"><texture type="rawconstant" name="normalmap"><vector name="value" x="0.7" y="0.4" z="0.9"/></texture><bsdf type="roughconductor"><string name="distribution" value="ggx"/><float name="alpha" value="0.3"/></bsdf></bsdf>', "eval"),
    ("normalmap-tilted-diffuse", '<bsdf type="normalmap"><texture type="rawconstant" name="normalmap"><vector name="value" x="0.3" y="0.6" z="0.8"/></texture><bsdf type="diffuse"/></bsdf>', "eval"),
    ("normalmap-textured-plastic", '<bsdf type="normalmap"><texture type="bitmap" name="normalmap"><string name="filename" value="data/textures/rgb8.png"/><boolean name="raw" value="true"/></texture><bsdf type="roughplastic"/></bsdf>', "eval"),
    ("bumpmap-roughconductor", '<bsdf type="bumpmap"><texture type="bitmap"><string name="filename" value="data/textures/grey8.png"/><boolean name="raw" value="true"/></texture><float name="scale" value="0.05"/><bsdf type="roughconductor"><float name="alpha" value="0.2"/></bsdf></bsdf>', "eval"),
    ("bumpmap-diffuse-twosided", '<bsdf type="bumpmap"><texture type="bitmap"><string name="filename" value="data/textures/ramp8.png"/><boolean name="raw" value="true"/></texture><float name="scale" value="0.2"/><bsdf type="twosided"><bsdf type="diffuse"/></bsdf></bsdf>', "eval"),
    ("roughplastic-beckmann-0.4-novisible", '<bsdf type="roughplastic"><float name="alpha" value="0.4"/><boolean name="sample_visible" value="false"/><rgb name="diffuse_reflectance" value="0.3, 0.6, 0.2"/></bsdf>', "eval"),
    # the glass of the torus scene (scenes/wild/ppglab-torus): nearly smooth, named IORs;
    # "narrow" adds pairs within ~0.01 rad of the reflected and refracted directions
    ("roughdielectric-beckmann-0.01-acrylic-narrow", '<bsdf type="roughdielectric"><string name="int_ior" value="acrylic glass"/><string name="ext_ior" value="air"/><float name="alpha" value="0.01"/></bsdf>', "eval"),
]


def load_bsdf(xml):
    return mi.load_string(xml.replace("<bsdf ", "<bsdf version=\"3.0.0\" ", 1))


def make_si(wi):
    si = mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(*wi)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    si.n = mi.Normal3f(0, 0, 1)
    si.uv = mi.Point2f(0.5, 0.5)
    si.dp_du = mi.Vector3f(1, 0, 0)
    si.dp_dv = mi.Vector3f(0, 1, 0)
    return si


def uniform_sphere(rng):
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def grazing(rng, z):
    phi = rng.uniform(0, 2 * np.pi)
    s = np.sqrt(1 - z * z)
    return np.array([s * np.cos(phi), s * np.sin(phi), z])


def fmt(v):
    return " ".join(f"{float(x):.9g}" for x in v)


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(REPO_ROOT, "tests/data/mitsuba_bsdf_values.txt")
    ctx = mi.BSDFContext()
    mi.file_resolver().prepend(os.path.join(REPO_ROOT, "tests"))
    lines = [f"# generated by validation/mitsuba/bsdf_values.py: Mitsuba {mi.__version__} scalar_rgb",
             "# e wi.xyz wo.xyz eval.rgb pdf | s wi.xyz u1 u2.xy wo.xyz weight.rgb eta"]
    for ci, (name, xml, kind) in enumerate(CASES):
        bsdf = load_bsdf(xml)
        rng = np.random.default_rng(1000 + ci)
        lines.append(f"case {name}")
        lines.append(f"xml {xml}")
        if kind == "eval":
            pairs = []
            for _ in range(40):
                wi, wo = uniform_sphere(rng), uniform_sphere(rng)
                if not any(k in name for k in ("twosided", "dielectric", "mask", "normalmap", "bumpmap", "blendbsdf")):
                    wi[2], wo[2] = abs(wi[2]), abs(wo[2])  # mostly the front side
                pairs.append((wi, wo))
            for _ in range(10):  # reflection-like pairs near the specular peak
                wi = uniform_sphere(rng)
                wi[2] = abs(wi[2])
                wo = np.array([-wi[0], -wi[1], wi[2]]) + 0.1 * rng.normal(size=3)
                pairs.append((wi, wo / np.linalg.norm(wo)))
            if "narrow" in name:  # around the peaks of a nearly smooth lobe
                eta = 1.49 / 1.000277
                for _ in range(30):
                    wi = uniform_sphere(rng)
                    if rng.uniform() < 0.5:
                        wo = np.array([-wi[0], -wi[1], wi[2]])
                    else:  # refraction through the interface z = 0
                        e = eta if wi[2] > 0 else 1 / eta
                        c = abs(wi[2])
                        k = 1 - (1 - c * c) / (e * e)
                        if k <= 0:
                            continue
                        wo = -wi / e + (c / e - np.sqrt(k)) * np.array([0, 0, np.sign(wi[2])])
                    wo = wo / np.linalg.norm(wo) + 0.01 * rng.normal(size=3)
                    pairs.append((wi, wo / np.linalg.norm(wo)))
            for z in [1e-3, 1e-2, 0.05]:
                pairs.append((grazing(rng, z), uniform_sphere(rng) * [1, 1, 1]))
                pairs.append((uniform_sphere(rng) * [1, 1, 1], grazing(rng, z)))
            for wi, wo in pairs:
                si = make_si(wi)
                f = bsdf.eval(ctx, si, mi.Vector3f(*wo))
                p = bsdf.pdf(ctx, si, mi.Vector3f(*wo))
                lines.append(f"e {fmt(wi)} {fmt(wo)} {fmt(f)} {float(p):.9g}")
        else:
            for _ in range(40):
                wi = uniform_sphere(rng)
                if "dielectric" not in name and "mask" not in name:
                    wi[2] = abs(wi[2])
                u1 = float(rng.uniform())
                u2 = rng.uniform(size=2)
                si = make_si(wi)
                bs, w = bsdf.sample(ctx, si, u1, mi.Point2f(*u2))
                if not mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta) or bs.pdf <= 0:
                    continue
                lines.append(f"s {fmt(wi)} {u1:.9g} {fmt(u2)} {fmt(bs.wo)} {fmt(w)} {float(bs.eta):.9g}")
    os.makedirs(os.path.dirname(out), exist_ok=True)
    with open(out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print(f"wrote {out}: {len(CASES)} cases", file=sys.stderr)


if __name__ == "__main__":
    main()
