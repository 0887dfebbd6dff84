#!/usr/bin/env python3
"""Tabulate Mitsuba 3's own `bitmap` texture lookups for penumbra's tests (src/texture/bitmap.rs).

Writes the small test images under tests/data/textures/ (deterministic: fixed numpy seeds; the
PNG and BMP files are encoded here byte by byte, the JPEG and EXR files by mi.Bitmap), then
loads each in Mitsuba as

    mi.load_dict({'type': 'bitmap', 'filename': F, 'raw': R, 'filter_type': FI,
                  'wrap_mode': W, 'format': FO, 'to_uv': T})

and records tex.mean(), the stored resolution and channel count, and tex.eval(si) /
tex.eval_1(si) at uv points: every texel centre, texel edges and corners, points outside
[0, 1] (negative, beyond 1, several periods away), exact integers, and random points. The
suite's real textures (validation/mitsuba-suite/common/textures/) are sampled at random
points only.

Output lines:
  case NAME FILE RAW FILTER WRAP FORMAT CHANNELS WIDTH HEIGHT MEAN m00 m01 m02 m10 m11 m12
  p u v r g b e1     (3-channel data)
  p u v y            (1-channel data: eval = (y, y, y), eval_1 = y; the script asserts it)
where FILE is relative to the repository root, (m..) are the rows of the 2D affine to_uv
(u' = m00 u + m01 v + m02, v' = m10 u + m11 v + m12: Mitsuba keeps entries (0,0), (0,1),
(0,3), (1,0), (1,1), (1,3) of the 4x4 transform), (r, g, b) = eval, e1 = eval_1. Floats are
printed with 9 significant digits (f32 round-trips exactly).

Every filter and wrap mode is exercised on a few images; the others get the default
(bilinear, repeat), (nearest, clamp) and, for 8/16-bit data, raw with (bilinear, mirror).

Usage: python validation/mitsuba/bitmap_lookups.py [OUT]
       (default tests/data/mitsuba_bitmap_lookups.txt)
Mitsuba 3.9.1, scalar_rgb variant.
"""
import os
import struct
import sys
import zlib

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")
mi.set_log_level(mi.LogLevel.Error)  # silence "pixels exceed the [0, 1] range"

SCRIPT_DIR = os.path.dirname(os.path.abspath(__file__))
REPO_ROOT = os.path.dirname(os.path.dirname(SCRIPT_DIR))
TEX_DIR = os.path.join(REPO_ROOT, "tests", "data", "textures")
SUITE_DIR = os.path.join(REPO_ROOT, "validation", "mitsuba-suite", "common", "textures")


# ---------------------------------------------------------------------------------------------
# Image writers


def png_chunk(kind, data):
    c = struct.pack(">I", len(data)) + kind + data
    return c + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def write_png(name, w, h, color_type, depth, rows, plte=None, trns=None):
    """rows: one bytes object per row, already packed at `depth` bits per sample."""
    raw = b"".join(b"\x00" + r for r in rows)
    data = b"\x89PNG\r\n\x1a\n"
    data += png_chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, depth, color_type, 0, 0, 0))
    if plte is not None:
        data += png_chunk(b"PLTE", plte)
    if trns is not None:
        data += png_chunk(b"tRNS", trns)
    data += png_chunk(b"IDAT", zlib.compress(raw, 9)) + png_chunk(b"IEND", b"")
    with open(os.path.join(TEX_DIR, name), "wb") as f:
        f.write(data)
    return name


def pack_bits(values, depth):
    """Packs small integers MSB first, as PNG does for depths below 8."""
    out, acc, n = [], 0, 0
    for v in values:
        acc = (acc << depth) | int(v)
        n += depth
        if n == 8:
            out.append(acc)
            acc, n = 0, 0
    if n:
        out.append(acc << (8 - n))
    return bytes(out)


def write_bmp(name, pixels, bpp, top_down=False, palette=None):
    """pixels: (h, w, c) uint8 in file channel order (B, G, R[, A] for 24/32 bpp)."""
    h, w = pixels.shape[:2]
    row = pixels.reshape(h, -1).astype(np.uint8)
    pad = (-row.shape[1]) % 4
    rows = [bytes(row[y]) + b"\x00" * pad for y in range(h)]
    if not top_down:
        rows = rows[::-1]
    body = b"".join(rows)
    pal = b"" if palette is None else bytes(palette)
    offset = 14 + 40 + len(pal)
    header = b"BM" + struct.pack("<IHHI", offset + len(body), 0, 0, offset)
    info = struct.pack("<IiiHHIIiiII", 40, w, -h if top_down else h, 1, bpp, 0, len(body),
                       2835, 2835, len(pal) // 4, 0)
    with open(os.path.join(TEX_DIR, name), "wb") as f:
        f.write(header + info + pal + body)
    return name


def write_mi(name, array, pixel_format=None, quality=None):
    b = mi.Bitmap(array) if pixel_format is None else mi.Bitmap(array, pixel_format=pixel_format)
    path = os.path.join(TEX_DIR, name)
    if quality is None:
        b.write(path)
    else:
        b.write(path, quality=quality)
    return name


def make_images():
    """Returns [(name, kind)], kind in {'int', 'float'} (raw matters only for 'int')."""
    os.makedirs(TEX_DIR, exist_ok=True)
    rng = np.random.default_rng(2026)
    u8 = lambda *shape: rng.integers(0, 256, shape, dtype=np.uint16).astype(np.uint8)
    u16 = lambda *shape: rng.integers(0, 65536, shape, dtype=np.uint32).astype(np.uint16)
    out = []
    w, h = 4, 3
    # 8-bit PNGs: grey, grey+alpha, RGB, RGBA (alpha includes 0 and partial values)
    g = u8(h, w)
    g[0, 0], g[2, 3] = 0, 255
    out.append((write_png("grey8.png", w, h, 0, 8, [bytes(r) for r in g]), "int"))
    ya = np.stack([u8(h, w), u8(h, w)], -1)
    ya[0, 0, 1], ya[1, 1, 1] = 0, 128
    out.append((write_png("ya8.png", w, h, 4, 8, [bytes(r.ravel()) for r in ya]), "int"))
    rgb = u8(h, w, 3)
    out.append((write_png("rgb8.png", w, h, 2, 8, [bytes(r.ravel()) for r in rgb]), "int"))
    rgba = u8(h, w, 4)
    rgba[0, :, 3] = [0, 64, 128, 255]
    out.append((write_png("rgba8.png", w, h, 6, 8, [bytes(r.ravel()) for r in rgba]), "int"))
    # 16-bit PNGs (big-endian samples)
    g16 = u16(h, w)
    out.append((write_png("grey16.png", w, h, 0, 16, [r.astype(">u2").tobytes() for r in g16]), "int"))
    rgb16 = u16(h, w, 3)
    out.append((write_png("rgb16.png", w, h, 2, 16, [r.astype(">u2").tobytes() for r in rgb16]), "int"))
    rgba16 = u16(h, w, 4)
    out.append((write_png("rgba16.png", w, h, 6, 16, [r.astype(">u2").tobytes() for r in rgba16]), "int"))
    # palette (4-bit indices, 5 entries, tRNS on two of them) and 2-bit grey with a tRNS key
    plte = bytes(u8(5 * 3))
    idx = rng.integers(0, 5, (h, w))
    out.append((write_png("palette4.png", w, h, 3, 4, [pack_bits(r, 4) for r in idx],
                          plte=plte, trns=bytes([0, 100])), "int"))
    g2 = rng.integers(0, 4, (h, w))
    out.append((write_png("grey2.png", w, h, 0, 2, [pack_bits(r, 2) for r in g2],
                          trns=struct.pack(">H", 1)), "int"))
    # every 8-bit code (the sRGB decode of each) and 512 random 16-bit codes, one row each
    out.append((write_png("ramp8.png", 256, 1, 0, 8, [bytes(range(256))]), "int"))
    codes = np.concatenate([[0, 1, 2, 255, 256, 32767, 32768, 65534, 65535], u16(247)])
    out.append((write_png("ramp16.png", 256, 1, 0, 16, [codes.astype(">u2").tobytes()]), "int"))
    # sub-2x2 images (Mitsuba pads them to 2x2 by replicating the last row / column)
    out.append((write_png("one_pixel.png", 1, 1, 2, 8, [bytes([200, 30, 90])]), "int"))
    col = u8(3, 1)
    out.append((write_png("column.png", 1, 3, 0, 8, [bytes(r) for r in col]), "int"))
    # JPEG (libjpeg through mi.Bitmap: RGB with chroma subsampling, and one-component grey)
    yy, xx = np.mgrid[0:12, 0:16]
    smooth = np.stack([xx * 15, yy * 20, (xx + yy) * 8], -1) + rng.integers(0, 30, (12, 16, 3))
    out.append((write_mi("rgb.jpg", np.clip(smooth, 0, 255).astype(np.uint8), quality=90), "int"))
    out.append((write_mi("grey.jpg", np.clip(xx * 12 + yy * 5 + rng.integers(0, 40, (12, 16)),
                                              0, 255).astype(np.uint8)[..., None], quality=85), "int"))
    # BMP (Mitsuba's reader: 40-byte header, uncompressed; 8 bpp is read as grey, the
    # palette ignored; 16 bpp as grey + alpha; 24 and 32 bpp as BGR[A])
    bw = 5
    pal = np.zeros((256, 4), np.uint8)
    pal[:, :3] = u8(256, 3)
    out.append((write_bmp("pal8.bmp", u8(h, bw, 1), 8, palette=pal.ravel()), "int"))
    out.append((write_bmp("ya16.bmp", u8(h, bw, 2), 16), "int"))
    out.append((write_bmp("bgr24.bmp", u8(h, bw, 3), 24), "int"))
    out.append((write_bmp("bgra32_topdown.bmp", u8(h, bw, 4), 32, top_down=True), "int"))
    # EXR: float RGB beyond [0, 1] and negative, half RGBA, float Y, half YA, float XYZ
    f = (rng.standard_normal((h, w, 3)) * 2 + 0.5).astype(np.float32)
    out.append((write_mi("rgb_f32.exr", f), "float"))
    out.append((write_mi("rgba_f16.exr", (rng.random((h, w, 4)) * 3).astype(np.float16)), "float"))
    out.append((write_mi("y_f32.exr", (rng.random((h, w, 1)) * 4 - 1).astype(np.float32)), "float"))
    out.append((write_mi("ya_f16.exr", rng.random((h, w, 2)).astype(np.float16)), "float"))
    out.append((write_mi("xyz_f32.exr", rng.random((h, w, 3)).astype(np.float32),
                         pixel_format=mi.Bitmap.PixelFormat.XYZ), "float"))
    return out


# ---------------------------------------------------------------------------------------------
# Lookups


def f32(x):
    return float(np.float32(x))


def uv_points(w, h, rng, dense):
    pts = []
    if dense:
        pts += [((i + 0.5) / w, (j + 0.5) / h) for j in range(h) for i in range(w)]
        pts += [(i / w, 0.3) for i in range(w + 1)] + [(0.6, j / h) for j in range(h + 1)]
    pts += [(0.0, 0.0), (1.0, 1.0), (-1.0, 2.0), (1.0, 0.0), (0.25, 1.0)]
    pts += [(-1.3, 0.4), (2.6, -0.45), (-0.01, 1.01), (1.01, -0.01), (-2.45, -3.2),
            (5.125, 7.9), (-0.5 / w, -0.5 / h), (1 + 0.5 / w, 1 + 0.5 / h)]
    pts += [tuple(p) for p in rng.uniform(-2.0, 3.0, (6, 2))]
    pts += [tuple(p) for p in rng.uniform(0.0, 1.0, (4, 2))]
    return [(f32(u), f32(v)) for u, v in pts]


def g(x):
    return f"{x:.9g}"


def run_case(lines, name, rel, raw, filt, wrap, fmt, to_uv, points):
    d = {"type": "bitmap", "filename": os.path.join(REPO_ROOT, rel), "raw": raw,
         "filter_type": filt, "wrap_mode": wrap, "format": fmt}
    m = np.identity(4)
    if to_uv is not None:
        d["to_uv"] = to_uv
        m = np.array(to_uv.matrix, dtype=np.float64)
    tex = mi.load_dict(d)
    res = tex.resolution()
    data = mi.traverse(tex)["data"]
    channels = data.shape[2]
    rows = [m[0, 0], m[0, 1], m[0, 3], m[1, 0], m[1, 1], m[1, 3]]
    lines.append(" ".join(["case", name, rel, str(int(raw)), filt, wrap, fmt, str(channels),
                           str(res[0]), str(res[1]), g(tex.mean())] + [g(f32(x)) for x in rows]))
    si = mi.SurfaceInteraction3f()
    for u, v in points:
        si.uv = mi.Point2f(u, v)
        c = tex.eval(si)
        e1 = tex.eval_1(si)
        if channels == 1:
            assert c[0] == c[1] == c[2] == e1
            lines.append(" ".join(["p", g(u), g(v), g(e1)]))
        else:
            lines.append(" ".join(["p", g(u), g(v), g(c[0]), g(c[1]), g(c[2]), g(e1)]))


def main():
    out_path = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        REPO_ROOT, "tests", "data", "mitsuba_bitmap_lookups.txt")
    images = make_images()
    rng = np.random.default_rng(7)
    lines = ["# generated by validation/mitsuba/bitmap_lookups.py: Mitsuba 3.9.1 scalar_rgb",
             "# command: python validation/mitsuba/bitmap_lookups.py",
             "# see the script's docstring for the record format"]
    combos = [(f, w) for f in ("bilinear", "nearest") for w in ("repeat", "mirror", "clamp")]
    for name, kind in images:
        rel = os.path.join("tests", "data", "textures", name)
        b = mi.Bitmap(os.path.join(REPO_ROOT, rel))
        w, h = b.size()
        stem = name.replace(".", "_")
        if name.startswith("ramp"):
            # the decode of every stored code: nearest lookups at the texel centres
            pts = [(f32((i + 0.5) / w), 0.5) for i in range(w)]
            for raw in (False, True):
                run_case(lines, f"{stem}-raw{int(raw)}", rel, raw, "nearest", "clamp", "auto",
                         None, pts)
            if name == "ramp16.png":
                run_case(lines, f"{stem}-variant", rel, False, "nearest", "clamp", "variant",
                         None, pts)
            continue
        # every filter and wrap mode for a few images, the default and one other for the rest
        full = name in ("grey8.png", "rgb8.png", "column.png", "rgb_f32.exr")
        for filt, wrap in combos if full else (("bilinear", "repeat"), ("nearest", "clamp")):
            pts = uv_points(w, h, rng, dense=True)
            run_case(lines, f"{stem}-{filt}-{wrap}", rel, False, filt, wrap, "auto", None, pts)
        if kind == "int":
            for filt, wrap in (("bilinear", "mirror"),):
                pts = uv_points(w, h, rng, dense=True)
                run_case(lines, f"{stem}-raw-{filt}-{wrap}", rel, True, filt, wrap, "auto",
                         None, pts)
    # storage formats (`format`): variant and float16 for 8-bit data, variant for 16-bit,
    # float16 for float data; uint8 only from 8-bit data (Mitsuba dithers when it quantises
    # 16-bit or float data to 8 bits, which cannot be reproduced point by point)
    for name, fmt, raw in (("rgb8.png", "variant", False), ("rgb8.png", "float16", False),
                           ("rgb8.png", "variant", True), ("rgb16.png", "variant", False),
                           ("grey16.png", "float16", True), ("rgb_f32.exr", "float16", False),
                           ("rgb_f32.exr", "variant", False), ("ya8.png", "uint8", False)):
        rel = os.path.join("tests", "data", "textures", name)
        w, h = mi.Bitmap(os.path.join(REPO_ROOT, rel)).size()
        stem = name.replace(".", "_")
        run_case(lines, f"{stem}-format-{fmt}-raw{int(raw)}", rel, raw, "bilinear", "repeat",
                 fmt, None, uv_points(w, h, rng, dense=True))
    # to_uv: scale, translate, rotate, a general 4x4 whose z row and column must be ignored
    T = mi.ScalarTransform4f
    general = T(mi.ScalarMatrix4f([[1.5, 0.25, 7.0, -0.3], [-0.5, 2.0, 9.0, 0.6],
                                   [3.0, 4.0, 5.0, 6.0], [0.1, 0.2, 0.3, 1.0]]))
    for tname, tr in (("scale", T().scale([5.0, 3.0, 1.0])),
                      ("translate", T().translate([0.3, -0.7, 2.0])),
                      ("rotate", T().rotate([0, 0, 1], 30.0)),
                      ("general", general)):
        for name in ("rgb8.png", "rgb_f32.exr"):
            rel = os.path.join("tests", "data", "textures", name)
            w, h = mi.Bitmap(os.path.join(REPO_ROOT, rel)).size()
            stem = name.replace(".", "_")
            run_case(lines, f"{stem}-to_uv-{tname}", rel, False, "bilinear", "repeat", "auto", tr,
                     uv_points(w, h, rng, dense=False))
    # the suite's textures (random points; the large ones sampled sparsely)
    for name, raw, fmt in (("carrot.png", False, "auto"), ("leaf_mask.png", False, "auto"),
                           ("flower.bmp", False, "auto"), ("museum.exr", False, "auto"),
                           ("wood.jpg", False, "auto"), ("floor_tiles_bumpmap.png", True, "auto"),
                           ("floor_tiles_normalmap.jpg", True, "variant")):
        rel = os.path.join("validation", "mitsuba-suite", "common", "textures", name)
        w, h = mi.Bitmap(os.path.join(REPO_ROOT, rel)).size()
        stem = name.replace(".", "_")
        for filt, wrap in (("bilinear", "repeat"), ("nearest", "mirror"), ("bilinear", "clamp")):
            run_case(lines, f"{stem}-{filt}-{wrap}", rel, raw, filt, wrap, fmt, None,
                     uv_points(w, h, rng, dense=False))
    with open(out_path, "w") as f:
        f.write("\n".join(lines) + "\n")
    print(f"wrote {out_path}: {sum(l.startswith('case') for l in lines)} cases, "
          f"{sum(l.startswith('p ') for l in lines)} lookups")


if __name__ == "__main__":
    main()
