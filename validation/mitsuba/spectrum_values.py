#!/usr/bin/env python3
"""Tabulate the RGB values Mitsuba 3 stores for <spectrum> properties, for penumbra's tests
(src/spectrum.rs reads tests/data/mitsuba_spectrum_values.txt).

Every spectrum goes through a tiny XML scene string (mi.load_string), the path penumbra
parses, once per role in which a plugin reads a colour:
  reflectance  <bsdf type="diffuse">      reflectance          (Properties::get_texture)
  unbounded    <bsdf type="conductor">    eta (k gets the same) (get_unbounded_texture)
  emission     <emitter type="constant">  radiance             (get_emissive_texture)
and the stored value is read back with mi.traverse (a Color3f of the 'srgb' texture, or the
float of a 'uniform' texture, written here three times).

Cross-checks (the script stops with an AssertionError if one fails):
  - llvm_ad_rgb stores bit-identical values to scalar_rgb;
  - an area emitter on a rectangle stores the same radiance as the constant emitter;
  - mi.load_dict with {'type': 'spectrum', 'value': ...} (or 'filename') gives the same values
    as the XML path (for files, load_dict uses a different reader, spectrum_from_file, which
    agrees on the well-formed test file).
The last column records whether Mitsuba logged "Spectrum: clamping out-of-gamut color".

Usage: python validation/mitsuba/spectrum_values.py [OUT]
       (default tests/data/mitsuba_spectrum_values.txt; run from anywhere)
Mitsuba 3.9.1, variants scalar_rgb and llvm_ad_rgb.
"""
import math
import os
import sys

SCRIPT_DIR = os.path.dirname(os.path.abspath(__file__))
REPO_ROOT = os.path.dirname(os.path.dirname(SCRIPT_DIR))
sys.path.insert(0, SCRIPT_DIR)

import mitsuba_util  # noqa: E402

mitsuba_util._setup_llvm_env()  # libLLVM 19 for llvm_ad_rgb, before Dr.Jit starts

import mitsuba as mi  # noqa: E402
import numpy as np  # noqa: E402

CBOX_WHITE = (
    "400:0.343, 404:0.445, 408:0.551, 412:0.624, 416:0.665, 420:0.687, 424:0.708, 428:0.723, "
    "432:0.715, 436:0.71, 440:0.745, 444:0.758, 448:0.739, 452:0.767, 456:0.777, 460:0.765, "
    "464:0.751, 468:0.745, 472:0.748, 476:0.729, 480:0.745, 484:0.757, 488:0.753, 492:0.75, "
    "496:0.746, 500:0.747, 504:0.735, 508:0.732, 512:0.739, 516:0.734, 520:0.725, 524:0.721, "
    "528:0.733, 532:0.725, 536:0.732, 540:0.743, 544:0.744, 548:0.748, 552:0.728, 556:0.716, "
    "560:0.733, 564:0.726, 568:0.713, 572:0.74, 576:0.754, 580:0.764, 584:0.752, 588:0.736, "
    "592:0.734, 596:0.741, 600:0.74, 604:0.732, 608:0.745, 612:0.755, 616:0.751, 620:0.744, "
    "624:0.731, 628:0.733, 632:0.744, 636:0.731, 640:0.712, 644:0.708, 648:0.729, 652:0.73, "
    "656:0.727, 660:0.707, 664:0.703, 668:0.729, 672:0.75, 676:0.76, 680:0.751, 684:0.739, "
    "688:0.724, 692:0.73, 696:0.74, 700:0.737"
)
CBOX_RED = (
    "400:0.04, 404:0.046, 408:0.048, 412:0.053, 416:0.049, 420:0.05, 424:0.053, 428:0.055, "
    "432:0.057, 436:0.056, 440:0.059, 444:0.057, 448:0.061, 452:0.061, 456:0.06, 460:0.062, "
    "464:0.062, 468:0.062, 472:0.061, 476:0.062, 480:0.06, 484:0.059, 488:0.057, 492:0.058, "
    "496:0.058, 500:0.058, 504:0.056, 508:0.055, 512:0.056, 516:0.059, 520:0.057, 524:0.055, "
    "528:0.059, 532:0.059, 536:0.058, 540:0.059, 544:0.061, 548:0.061, 552:0.063, 556:0.063, "
    "560:0.067, 564:0.068, 568:0.072, 572:0.08, 576:0.09, 580:0.099, 584:0.124, 588:0.154, "
    "592:0.192, 596:0.255, 600:0.287, 604:0.349, 608:0.402, 612:0.443, 616:0.487, 620:0.513, "
    "624:0.558, 628:0.584, 632:0.62, 636:0.606, 640:0.609, 644:0.651, 648:0.612, 652:0.61, "
    "656:0.65, 660:0.638, 664:0.627, 668:0.62, 672:0.63, 676:0.628, 680:0.642, 684:0.639, "
    "688:0.657, 692:0.639, 696:0.635, 700:0.642"
)
CBOX_GREEN = (
    "400:0.092, 404:0.096, 408:0.098, 412:0.097, 416:0.098, 420:0.095, 424:0.095, 428:0.097, "
    "432:0.095, 436:0.094, 440:0.097, 444:0.098, 448:0.096, 452:0.101, 456:0.103, 460:0.104, "
    "464:0.107, 468:0.109, 472:0.112, 476:0.115, 480:0.125, 484:0.14, 488:0.16, 492:0.187, "
    "496:0.229, 500:0.285, 504:0.343, 508:0.39, 512:0.435, 516:0.464, 520:0.472, 524:0.476, "
    "528:0.481, 532:0.462, 536:0.447, 540:0.441, 544:0.426, 548:0.406, 552:0.373, 556:0.347, "
    "560:0.337, 564:0.314, 568:0.285, 572:0.277, 576:0.266, 580:0.25, 584:0.23, 588:0.207, "
    "592:0.186, 596:0.171, 600:0.16, 604:0.148, 608:0.141, 612:0.136, 616:0.13, 620:0.126, "
    "624:0.123, 628:0.121, 632:0.122, 636:0.119, 640:0.114, 644:0.115, 648:0.117, 652:0.117, "
    "656:0.118, 660:0.12, 664:0.122, 668:0.128, 672:0.132, 676:0.139, 680:0.144, 684:0.146, "
    "688:0.15, 692:0.152, 696:0.157, 700:0.159"
)
# 1 nm steps over the whole CIE range (471 entries): exercises the interval search.
DENSE = ", ".join(
    f"{wl}:{0.5 + 0.4 * math.sin(wl / 23.0):.6g}" for wl in range(360, 831)
)

# (name, "value" | "file", value attribute or file path relative to the repository)
SPECTRA = [
    ("cbox-white", "value", CBOX_WHITE),
    ("cbox-red", "value", CBOX_RED),
    ("cbox-green", "value", CBOX_GREEN),
    ("cbox-light-reflectance", "value", "400:0.78, 500:0.78, 600:0.78, 700:0.78"),
    ("cbox-light-radiance", "value", "400:0, 500:8, 600:15.6, 700:18.4"),
    ("uniform-0.5", "value", "0.5"),
    ("uniform-0.789", "value", "0.789"),
    ("uniform-1.5", "value", "1.5"),
    ("uniform-negative", "value", "-0.25"),
    ("uniform-17", "value", "17"),
    # Out of gamut: RGB (-1.46, 1.19, 3.89) before clamping; [0,1] when bounded, >= 0 otherwise.
    ("out-of-gamut-tilt", "value", "400:5, 700:-3"),
    # Above 1 but not negative: only the bounded role clamps.
    ("bright-flat", "value", "360:2, 830:2"),
    # A narrow green band: negative red and blue in every role.
    ("narrow-green", "value", "515:0, 520:1, 530:1, 535:0"),
    # Narrower than the visible range (blue only: clamped).
    ("narrow-blue", "value", "400:0.5, 500:0.6"),
    ("narrow-mid", "value", "550:0.5, 560:0.5"),
    # Wider than the CIE range, flat: the part outside [360, 830] contributes nothing.
    ("wide-flat", "value", "300:1, 900:1"),
    ("full-range-flat", "value", "360:1, 830:1"),
    # Entirely outside the CIE range: black.
    ("outside-range", "value", "200:1, 300:1"),
    ("irregular", "value", "380:0.1, 390.5:0.3, 455:0.2, 456:0.9, 601.25:0.4, 780:0.05"),
    # Separators and number forms Mitsuba accepts: spaces only, doubled ':' and ',', '+', '.5'.
    ("separators", "value", "400:0.5 450::0.25,,500:0.6  +550:.7, 6e2:+0.8"),
    ("emitter-bright", "value", "400:100, 550:250, 700:80"),
    ("dense-1nm", "value", DENSE),
    ("spd-file", "file", "tests/data/spectrum_sample.spd"),
]


class Capture(mi.Appender):
    """Collects Mitsuba's log messages, to see whether a load logged a clamping warning."""

    def __init__(self):
        super().__init__()
        self.messages = []

    def append(self, level, text):
        self.messages.append(text)

    def log_progress(self, *args):
        pass


def spectrum_xml(name, kind, text):
    if kind == "value":
        return f'<spectrum name="{name}" value="{text}"/>'
    return f'<spectrum name="{name}" filename="{os.path.join(REPO_ROOT, text)}"/>'


def spectrum_dict(kind, text):
    """The load_dict form of the same spectrum (tokenised as Properties::Spectrum does)."""
    if kind == "file":
        return {"type": "spectrum", "filename": os.path.join(REPO_ROOT, text)}
    tokens = [t for t in text.replace(",", " ").split(" ") if t]
    if len(tokens) == 1 and ":" not in tokens[0]:
        return {"type": "spectrum", "value": float(tokens[0])}
    pairs = []
    for token in tokens:
        wl, v = [p for p in token.split(":") if p]
        pairs.append((float(wl), float(v)))
    return {"type": "spectrum", "value": pairs}


def rgb_of(value):
    """Stored texture value (Color3f or uniform float, scalar or LLVM) as three float32s."""
    a = np.array(value, dtype=np.float32).ravel()
    if a.size == 1:
        a = np.repeat(a, 3)
    assert a.size == 3, a
    return a


def load_role(role, spec_xml):
    if role == "reflectance":
        obj = mi.load_string(f'<bsdf version="3.0.0" type="diffuse">{spec_xml("reflectance")}</bsdf>')
        return mi.traverse(obj)["reflectance.value"]
    if role == "unbounded":
        obj = mi.load_string(
            f'<bsdf version="3.0.0" type="conductor">{spec_xml("eta")}{spec_xml("k")}</bsdf>'
        )
        return mi.traverse(obj)["eta.value"]
    if role == "emission":
        obj = mi.load_string(f'<emitter version="3.0.0" type="constant">{spec_xml("radiance")}</emitter>')
        return mi.traverse(obj)["radiance.value"]
    if role == "emission-area":
        obj = mi.load_string(
            f'<shape version="3.0.0" type="rectangle"><emitter type="area">{spec_xml("radiance")}'
            "</emitter></shape>"
        )
        return mi.traverse(obj)["emitter.radiance.value"]
    raise ValueError(role)


def load_role_dict(role, spec):
    if role == "reflectance":
        obj = mi.load_dict({"type": "diffuse", "reflectance": spec})
        return mi.traverse(obj)["reflectance.value"]
    if role == "unbounded":
        obj = mi.load_dict({"type": "conductor", "eta": spec, "k": spec})
        return mi.traverse(obj)["eta.value"]
    if role == "emission":
        obj = mi.load_dict({"type": "constant", "radiance": spec})
        return mi.traverse(obj)["radiance.value"]
    raise ValueError(role)


ROLES = ("reflectance", "unbounded", "emission")


def main():
    out_path = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        REPO_ROOT, "tests", "data", "mitsuba_spectrum_values.txt"
    )
    capture = Capture()
    results = {}  # (variant, name, role) -> (rgb, warned)
    for variant in ("scalar_rgb", "llvm_ad_rgb"):
        mi.set_variant(variant)
        logger = mi.logger()
        logger.clear_appenders()
        logger.add_appender(capture)
        for name, kind, text in SPECTRA:
            spec_xml = lambda prop, kind=kind, text=text: spectrum_xml(prop, kind, text)  # noqa: E731
            for role in ROLES:
                capture.messages.clear()
                rgb = rgb_of(load_role(role, spec_xml))
                warned = any("clamping out-of-gamut" in m for m in capture.messages)
                results[(variant, name, role)] = (rgb, warned)
                if role == "emission":
                    area = rgb_of(load_role("emission-area", spec_xml))
                    assert np.array_equal(area, rgb), (name, "area vs constant", area, rgb)
                via_dict = rgb_of(load_role_dict(role, spectrum_dict(kind, text)))
                assert np.array_equal(via_dict, rgb), (variant, name, role, "dict vs XML", via_dict, rgb)

    lines = [
        "# generated by validation/mitsuba/spectrum_values.py: Mitsuba "
        f"{mi.MI_VERSION}, scalar_rgb (llvm_ad_rgb checked bit-identical)",
        "# command: .venv/bin/python validation/mitsuba/spectrum_values.py",
        "# spectrum <name> value <value attribute>  |  spectrum <name> file <path from the repository root>",
        "# <role> <r> <g> <b> <warned>   stored float32 RGB (%.9g, exact) and whether Mitsuba logged",
        "#   'Spectrum: clamping out-of-gamut color'; role = reflectance (diffuse reflectance),",
        "#   unbounded (conductor eta), emission (constant/area radiance)",
    ]
    for name, kind, text in SPECTRA:
        lines.append(f"spectrum {name} {kind} {text}")
        for role in ROLES:
            rgb, warned = results[("scalar_rgb", name, role)]
            rgb_llvm, warned_llvm = results[("llvm_ad_rgb", name, role)]
            assert np.array_equal(rgb, rgb_llvm) and warned == warned_llvm, (name, role, rgb, rgb_llvm)
            values = " ".join("%.9g" % float(c) for c in rgb)
            lines.append(f"{role} {values} {int(warned)}")
    with open(out_path, "w") as f:
        f.write("\n".join(lines) + "\n")
    print(f"wrote {len(SPECTRA)} spectra x {len(ROLES)} roles to {out_path}")


if __name__ == "__main__":
    main()
