"""Shared helpers for the Mitsuba 3 validation scripts (render_reference.py, time_mitsuba.py).

Only Mitsuba's public Python API, numpy and the standard library are used.

Call ``select_variant`` before anything else touches Mitsuba variant-specific types: it sets
``DRJIT_LIBLLVM_PATH`` (when the usual Debian libLLVM 19 exists and the variable is unset) and
picks ``llvm_ad_rgb`` or ``scalar_rgb``.
"""

import os
import struct
import sys

# Dr.Jit reads this when the LLVM backend is first initialised. libLLVM 15 from Debian crashes
# in Dr.Jit's code generation; 19 works (see the README, "Mitsuba on this machine").
DEFAULT_LIBLLVM = "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1"

VARIANT_CHOICES = ("auto", "llvm_ad_rgb", "scalar_rgb", "llvm_ad_spectral", "scalar_spectral")


def _setup_llvm_env():
    if "DRJIT_LIBLLVM_PATH" not in os.environ and os.path.exists(DEFAULT_LIBLLVM):
        os.environ["DRJIT_LIBLLVM_PATH"] = DEFAULT_LIBLLVM


def _llvm_works(mi):
    """Set llvm_ad_rgb and run a tiny kernel; False if LLVM cannot be used."""
    try:
        if "llvm_ad_rgb" not in mi.variants():
            return False
        mi.set_variant("llvm_ad_rgb")
        import drjit as dr
        import numpy as np

        x = mi.Float([1.0, 2.0, 3.0]) * 2.0 + 1.0
        dr.eval(x)
        return bool(np.allclose(np.array(x), [3.0, 5.0, 7.0]))
    except Exception as exc:  # noqa: BLE001 - any failure means "not usable"
        print(f"[mitsuba_util] llvm_ad_rgb unavailable: {exc}", file=sys.stderr)
        return False


def select_variant(requested="auto"):
    """Import Mitsuba, set and return the variant.

    ``auto``: ``llvm_ad_rgb`` if it loads and runs a test kernel, else ``scalar_rgb``.
    Returns ``(mi, variant_name)``.
    """
    _setup_llvm_env()
    import mitsuba as mi

    if requested == "auto":
        variant = "llvm_ad_rgb" if _llvm_works(mi) else "scalar_rgb"
    else:
        variant = requested
    mi.set_variant(variant)
    return mi, variant


def is_jit_variant(variant):
    return variant.startswith("llvm_") or variant.startswith("cuda_")


def parse_defines(items):
    """Turn ``["spp=16", "max_depth=3"]`` into a dict (values stay strings, as in XML)."""
    out = {}
    for item in items or []:
        if "=" not in item:
            raise SystemExit(f"-D expects name=value, got {item!r}")
        name, value = item.split("=", 1)
        name = name.strip()
        if not name:
            raise SystemExit(f"-D expects name=value, got {item!r}")
        out[name] = value.strip()
    return out


def load_scene(mi, path, defines):
    """``mi.load_file`` with XML ``$name`` substitutions from ``-D`` defines."""
    return mi.load_file(os.fspath(path), **defines)


def to_numpy(img):
    """Convert a rendered tensor to a float32 numpy array (H, W, C).

    In JIT variants this forces evaluation of the lazily recorded render, so call it inside
    any timed region.
    """
    import numpy as np

    arr = np.array(img, dtype=np.float32)
    if arr.ndim == 2:
        arr = arr[..., None]
    return arr


def film_info(scene):
    """Width, height and reconstruction-filter class name of the first sensor's film."""
    film = scene.sensors()[0].film()
    w, h = (int(v) for v in film.crop_size())
    rf = film.rfilter()
    rf_name = rf.class_name() if hasattr(rf, "class_name") else type(rf).__name__
    return w, h, rf_name


def make_rgb_moment_integrator(mi, nested):
    """Wrap ``nested`` so that each sample also records its squared RGB value.

    Mitsuba's own ``moment`` integrator records the first and second moments in CIE XYZ
    (AOV channels ``nested.X/Y/Z`` and ``m2_nested.X/Y/Z``), and XYZ second moments cannot be
    turned into per-channel RGB variances (that needs the cross moments). This wrapper keeps
    the nested integrator's RGB output as the film's R, G, B and adds three AOVs
    ``m2.R, m2.G, m2.B`` = the per-sample squares, which the film averages like any other
    channel. Efficient in JIT variants (the Python code is traced once); in scalar variants it
    is called per sample and is very slow.

    In ``*_spectral`` variants the sample is a spectrum at the ray's 4 wavelengths; the film
    turns ``weight * spectrum`` into linear sRGB with ``spectrum_to_srgb``, where ``weight`` is
    the sensor's wavelength weight (1 / pdf of ``sample_rgb_spectrum`` for a sensor without a
    response function, which is the case of every scene rendered here). The wrapper computes
    the same RGB of the sample to square it.
    """
    spectral = mi.is_spectral

    class RGBMomentIntegrator(mi.SamplingIntegrator):
        def __init__(self, nested_integrator):
            super().__init__(mi.Properties())
            self.nested = nested_integrator

        def sample(self, scene, sampler, ray, medium=None, active=True):
            spec, valid, aovs = self.nested.sample(scene, sampler, ray, medium, active)
            if spectral:
                weight = mi.UnpolarizedSpectrum(1.0) / mi.pdf_rgb_spectrum(ray.wavelengths)
                c = mi.spectrum_to_srgb(mi.unpolarized_spectrum(spec) * weight, ray.wavelengths)
            else:
                c = mi.Color3f(spec)
            return spec, valid, [c.x * c.x, c.y * c.y, c.z * c.z] + list(aovs)

        def aov_names(self):
            return ["m2.R", "m2.G", "m2.B"] + list(self.nested.aov_names())

        def to_string(self):
            return f"RGBMomentIntegrator[nested={self.nested}]"

    return RGBMomentIntegrator(nested)


def exr_header(path):
    """Parse an OpenEXR file's first header with the standard library only.

    Returns a dict: ``multipart`` (bool), ``tiled`` (bool), ``channels`` (list of
    ``(name, pixel_type)`` with pixel_type 0=uint, 1=half, 2=float), ``compression`` (int:
    0 none, 1 RLE, 2 ZIPS, 3 ZIP, 4 PIZ, 5 PXR24, 6 B44, 7 B44A, 8 DWAA, 9 DWAB) and
    ``attributes`` (names in file order).
    """
    with open(path, "rb") as f:
        data = f.read(1 << 20)
    magic, version = struct.unpack_from("<iI", data, 0)
    if magic != 20000630:
        raise ValueError(f"{path}: not an OpenEXR file")
    info = {
        "tiled": bool(version & 0x200),
        "multipart": bool(version & 0x1000),
        "channels": [],
        "compression": None,
        "attributes": [],
    }
    pos = 8

    def cstr(p):
        end = data.index(b"\0", p)
        return data[p:end].decode("latin-1"), end + 1

    while True:
        name, pos = cstr(pos)
        if name == "":
            break
        typ, pos = cstr(pos)
        (size,) = struct.unpack_from("<i", data, pos)
        pos += 4
        value = data[pos:pos + size]
        pos += size
        info["attributes"].append(name)
        if name == "channels" and typ == "chlist":
            p = 0
            while p < len(value) and value[p] != 0:
                end = value.index(b"\0", p)
                ch = value[p:end].decode("latin-1")
                (ptype,) = struct.unpack_from("<i", value, end + 1)
                info["channels"].append((ch, ptype))
                p = end + 1 + 16
        elif name == "compression":
            info["compression"] = value[0]
    return info
