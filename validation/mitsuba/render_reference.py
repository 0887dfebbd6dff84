#!/usr/bin/env python3
"""Render a Mitsuba 3 reference image with a per-pixel variance estimate.

Usage:
    python validation/mitsuba/render_reference.py SCENE.xml OUT.exr [--spp 4096]
        [--pass-spp 256] [--variant auto|llvm_ad_rgb|scalar_rgb|llvm_ad_spectral|scalar_spectral]
        [-D name=value ...]

The image is rendered in passes of ``--pass-spp`` samples per pixel, each with its own seed
(``seed_base + k``), and the passes are averaged (one render of w*h*spp samples is one
wavefront, so high spp must be split). The output EXR (float32, one part, PIZ compression as
Mitsuba writes it) has the channels

    R, G, B                         the mean radiance per pixel
    variance.R, variance.G, variance.B
                                    the per-pixel, per-channel variance of ONE sample

so the variance of the pixel mean is ``variance / spp``. With a box reconstruction filter every
sample lands in exactly one pixel, which is what makes this a per-sample variance. With other
filters (e.g. Mitsuba's default gaussian) every sample is splatted to the pixels within the
filter radius and a pixel's value is the weighted mean sum(w f) / sum(w). The squared values
are splatted through the same filter, so ``E_w[x^2] - E_w[x]^2`` is the weighted per-sample
variance sigma^2, and the variance of the pixel value is sigma^2 * K / spp with

    K = Kx(i) * Ky(j),   Kx(i) = int w(x - c_i)^2 dx / (int w(x - c_i) dx)^2

integrated over the part of the filter's footprint inside the image (samples are uniform in
the image at spp per unit area; K = 1 for the box filter, about 0.32 for the default gaussian
inside the image, larger at the border). The script multiplies the variance by K, so the
variance channels stay "per-sample-equivalent": spp x Var(pixel value), which is what penumbra
writes for every filter. K is computed by quadrature from Mitsuba's own filter (``rfilter.eval``,
which is what the image block of Mitsuba's JIT variants splats with).

Variance methods (``--variance``):

* ``rgb-moment`` (default for llvm/cuda variants): the scene's integrator is wrapped in a small
  Python integrator that outputs the squared RGB value of each sample as extra channels, so
  ``var = n/(n-1) * (E[x^2] - E[x]^2)`` per pixel and channel, with the moments pooled over all
  passes (n = total spp). Mitsuba's built-in ``moment`` integrator is not used because in
  3.9.1 it records its moments in CIE XYZ (AOVs ``nested.X/Y/Z``, ``m2_nested.X/Y/Z``), from
  which per-channel RGB variances cannot be recovered.
* ``passes`` (default for scalar variants, where a Python integrator runs per sample and is
  ~14x slower): ``var = pass_spp * sample variance of the pass means`` (unbiased, but with only
  ``passes - 1`` degrees of freedom per pixel). Needs at least 2 equal passes.

Metadata goes to a JSON manifest (default: ``manifest.json`` next to this script), keyed by the
output file name: scene, mitsuba_version, variant, spp, pass_spp, passes, width, height,
render_seconds, date, defines (plus path, scene_sha256, variance_method, seed_base,
image_mean, variance_mean). The EXR header also carries spp, mitsuba_version,
mitsuba_variant, render_seconds, variance_method and seed_base, so the file describes itself.
"""

import argparse
import datetime
import hashlib
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import mitsuba_util as mu  # noqa: E402

SCRIPT_DIR = os.path.dirname(os.path.abspath(__file__))
REPO_ROOT = os.path.dirname(os.path.dirname(SCRIPT_DIR))
CHANNELS = ["R", "G", "B", "variance.R", "variance.G", "variance.B"]


def rel_to_repo(path):
    """Path relative to the repository root if inside it, else absolute."""
    ap = os.path.abspath(path)
    try:
        rel = os.path.relpath(ap, REPO_ROOT)
    except ValueError:
        return ap
    return ap if rel.startswith("..") else rel


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scene", help="Mitsuba 3 XML scene")
    p.add_argument("out", help="output OpenEXR file")
    p.add_argument("--spp", type=int, default=4096, help="total samples per pixel (4096)")
    p.add_argument("--pass-spp", type=int, default=256, help="samples per pixel per pass (256)")
    p.add_argument("--variant", choices=mu.VARIANT_CHOICES, default="auto",
                   help="auto = llvm_ad_rgb if it works, else scalar_rgb")
    p.add_argument("--variance", choices=("auto", "rgb-moment", "passes"), default="auto",
                   help="variance estimator (auto: rgb-moment for JIT variants, passes for scalar)")
    p.add_argument("--seed-base", type=int, default=0, help="pass k uses seed seed_base + k")
    p.add_argument("-D", dest="defines", action="append", default=[], metavar="NAME=VALUE",
                   help="XML $NAME substitution (repeatable)")
    p.add_argument("--integrator", default=None, metavar="JSON",
                   help="render with this integrator (a mi.load_dict dictionary as JSON) "
                        "instead of the scene's")
    p.add_argument("--manifest", default=os.path.join(SCRIPT_DIR, "manifest.json"),
                   help="JSON manifest to update (default: manifest.json next to this script)")
    p.add_argument("--no-manifest", action="store_true", help="do not update the manifest")
    p.add_argument("--quiet", action="store_true", help="no per-pass progress")
    args = p.parse_args(argv)
    if args.spp < 1 or args.pass_spp < 1:
        p.error("--spp and --pass-spp must be positive")
    return args


def pass_sizes(spp, pass_spp):
    """Split spp into passes of pass_spp (the last one may be smaller)."""
    sizes = [pass_spp] * (spp // pass_spp)
    if spp % pass_spp:
        sizes.append(spp % pass_spp)
    return sizes


def render_passes(mi, scene, variant, method, sizes, seed_base, quiet, integrator=None):
    """Render all passes; returns (mean[H,W,3], var[H,W,3], seconds)."""
    if integrator is None:
        integrator = scene.integrator()
    if method == "rgb-moment":
        integrator = mu.make_rgb_moment_integrator(mi, integrator)
    total = sum(sizes)
    sum_x = None   # sum over passes of n_k * mean_k
    sum_x2 = None  # rgb-moment: sum of n_k * E_k[x^2];  passes: sum of mean_k^2
    t0 = time.perf_counter()
    for k, n in enumerate(sizes):
        tp = time.perf_counter()
        img = mu.to_numpy(mi.render(scene, integrator=integrator, seed=seed_base + k, spp=n))
        img = img.astype(np.float64)
        mean_k = img[..., 0:3]
        if sum_x is None:
            sum_x = np.zeros_like(mean_k)
            sum_x2 = np.zeros_like(mean_k)
        sum_x += n * mean_k
        if method == "rgb-moment":
            sum_x2 += n * img[..., 3:6]
        else:
            sum_x2 += mean_k * mean_k
        if not quiet:
            print(f"  pass {k + 1}/{len(sizes)}: {n} spp, seed {seed_base + k}, "
                  f"{time.perf_counter() - tp:.2f} s, mean {mean_k.reshape(-1, 3).mean(0)}",
                  file=sys.stderr, flush=True)
    seconds = time.perf_counter() - t0
    mean = sum_x / total
    if method == "rgb-moment":
        m2 = sum_x2 / total
        var = (m2 - mean * mean) * (total / (total - 1) if total > 1 else 1.0)
    else:
        p = len(sizes)
        n = sizes[0]
        # sample variance of the pass means (ddof=1) times the samples per pass
        var = (sum_x2 - p * mean * mean) / (p - 1) * n
    var = np.maximum(var, 0.0)  # E[x^2]-E[x]^2 can round to a tiny negative value
    return mean, var, seconds


def filter_variance_factor_1d(mi, rfilter, n):
    """Kx(i) for i in 0..n-1 (see the module docstring), by the composite Simpson rule on
    Mitsuba's own filter (rfilter.eval: the weights its JIT variants splat with), each side of
    the pixel centre integrated up to the radius or the image border."""
    if rfilter.class_name() == "BoxFilter":
        return np.ones(n)
    r = float(rfilter.radius())
    m = 2000  # Simpson intervals per side (even)
    simpson = np.ones(m + 1)
    simpson[1:-1:2] = 4.0
    simpson[2:-1:2] = 2.0

    def moments(length):
        xs = np.linspace(0.0, length, m + 1)
        w = np.array(rfilter.eval(mi.Float(xs)), dtype=np.float64)
        w[xs >= r] = 0.0
        h = length / m / 3.0
        return np.sum(simpson * w) * h, np.sum(simpson * w * w) * h

    out = np.empty(n)
    for i in range(n):
        c = i + 0.5
        left, right = moments(min(r, c)), moments(min(r, n - c))
        m1, m2 = left[0] + right[0], left[1] + right[1]
        out[i] = m2 / (m1 * m1)
    return out


def write_exr(mi, path, mean, var, metadata=None):
    """Write R,G,B,variance.R,variance.G,variance.B as float32 in one EXR part.

    ``metadata`` (name -> int, float or str) goes into the EXR header as attributes, so that a
    reference file says how it was made (penumbra's validation reads ``spp`` from it)."""
    data = np.ascontiguousarray(np.concatenate([mean, var], axis=-1).astype(np.float32))
    bmp = mi.Bitmap(data, mi.Bitmap.PixelFormat.MultiChannel, CHANNELS)
    header = bmp.metadata()
    for name, value in (metadata or {}).items():
        header[name] = value
    os.makedirs(os.path.dirname(os.path.abspath(path)) or ".", exist_ok=True)
    bmp.write(path)
    return data


def verify_exr(mi, path, data):
    """Read the file back (Mitsuba and a raw header parse) and check channels and values."""
    back = mi.Bitmap(path)
    names = [back.struct_()[i].name for i in range(back.channel_count())]
    arr = np.array(back)
    hdr = mu.exr_header(path)
    ok = (names == CHANNELS and arr.shape == data.shape and np.array_equal(arr, data)
          and not hdr["multipart"]
          and sorted(c for c, _ in hdr["channels"]) == sorted(CHANNELS)
          and all(t == 2 for _, t in hdr["channels"]))
    return ok, names, hdr


def file_sha256(path):
    """SHA-256 of a file's bytes (render_all.py compares it to decide what is up to date)."""
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def update_manifest(path, key, entry):
    manifest = {}
    if os.path.exists(path):
        with open(path) as f:
            manifest = json.load(f)
    manifest[key] = entry
    with open(path + ".tmp", "w") as f:
        json.dump(dict(sorted(manifest.items())), f, indent=2)
        f.write("\n")
    os.replace(path + ".tmp", path)


def main(argv=None):
    args = parse_args(argv)
    defines = mu.parse_defines(args.defines)
    mi, variant = mu.select_variant(args.variant)
    if not (variant.endswith("_rgb") or variant.endswith("_spectral")):
        raise SystemExit(f"only *_rgb and *_spectral variants are supported, got {variant}")
    method = args.variance
    if method == "auto":
        method = "rgb-moment" if mu.is_jit_variant(variant) else "passes"

    sizes = pass_sizes(args.spp, args.pass_spp)
    if method == "passes" and (len(sizes) < 2 or len(set(sizes)) != 1):
        raise SystemExit("--variance passes needs spp to be a multiple of pass-spp, "
                         "with at least 2 passes")

    scene = mu.load_scene(mi, args.scene, defines)
    width, height, rfilter = mu.film_info(scene)
    rf = scene.sensors()[0].film().rfilter()
    kx = filter_variance_factor_1d(mi, rf, width)
    ky = filter_variance_factor_1d(mi, rf, height)
    factor = ky[:, None, None] * kx[None, :, None]
    if rfilter != "BoxFilter":
        print(f"film filter {rfilter}: variance scaled by the per-pixel filter factor K "
              f"(interior {kx[width // 2] * ky[height // 2]:.4f})", file=sys.stderr)

    print(f"{args.scene}: {width}x{height}, {args.spp} spp in {len(sizes)} passes of "
          f"{args.pass_spp}, variant {variant}, variance {method}", file=sys.stderr)
    integrator = None
    if args.integrator is not None:
        integrator = mi.load_dict(json.loads(args.integrator))
        print(f"integrator replaced by {args.integrator}", file=sys.stderr)
    mean, var, seconds = render_passes(mi, scene, variant, method, sizes, args.seed_base,
                                       args.quiet, integrator)
    if method == "rgb-moment":
        # "passes" already measures spp x Var(pixel value) directly; the moments need K.
        var = var * factor
    data = write_exr(mi, args.out, mean, var, {
        "spp": args.spp,
        "mitsuba_version": mi.__version__,
        "mitsuba_variant": variant,
        "render_seconds": float(seconds),
        "variance_method": method,
        "seed_base": args.seed_base,
    })
    ok, names, hdr = verify_exr(mi, args.out, data)
    if not ok:
        raise SystemExit(f"EXR read-back check failed: channels {names}, header {hdr}")

    image_mean = data[..., 0:3].reshape(-1, 3).mean(0).astype(float).tolist()
    variance_mean = data[..., 3:6].reshape(-1, 3).mean(0).astype(float).tolist()
    entry = {
        "path": rel_to_repo(args.out),
        "scene": rel_to_repo(args.scene),
        "scene_sha256": file_sha256(args.scene),
        "mitsuba_version": mi.__version__,
        "variant": variant,
        "spp": args.spp,
        "pass_spp": args.pass_spp,
        "passes": len(sizes),
        "width": width,
        "height": height,
        "render_seconds": round(seconds, 3),
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "defines": defines,
        "integrator": args.integrator,
        "variance_method": method,
        "seed_base": args.seed_base,
        "image_mean": image_mean,
        "variance_mean": variance_mean,
        "rfilter": rfilter,
        "variance_filter_factor_interior": float(kx[width // 2] * ky[height // 2]),
    }
    if not args.no_manifest:
        update_manifest(args.manifest, os.path.basename(args.out), entry)
    print(json.dumps({"out": rel_to_repo(args.out), "channels": names,
                      "exr_compression": hdr["compression"], **entry}, indent=2))


if __name__ == "__main__":
    main()
