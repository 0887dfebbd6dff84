#!/usr/bin/env python3
"""Render the Mitsuba 3 reference of every landed scene in validation/scenes.toml.

Usage:
    .venv/bin/python validation/mitsuba/render_all.py [--force] [--scene NAME ...]
        [--dry-run] [--variant auto|llvm_ad_rgb|scalar_rgb]

For each scene with ``status = "landed"`` (or each ``--scene``, landed or not), this runs
render_reference.py's ``main`` with the scene's file, defines, ``reference`` path and
``reference_spp`` (passes of 256 spp with distinct seeds), which writes the EXR (R, G, B,
variance.R/G/B, float32; spp and Mitsuba version/variant in the header) and updates
validation/mitsuba/manifest.json.

A reference is up to date, and skipped unless ``--force``, when its EXR exists and its
manifest entry records the same scene file (path and SHA-256 of its bytes), the same defines,
the same spp and the installed Mitsuba version. Scenes render one after another (never two
Mitsuba renders at once: the machine has 2 cores).
"""

import argparse
import os
import sys
import tomllib

SCRIPT_DIR = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, SCRIPT_DIR)
import render_reference as rr  # noqa: E402

REPO_ROOT = rr.REPO_ROOT
SCENES_TOML = os.path.join(REPO_ROOT, "validation", "scenes.toml")
MANIFEST = os.path.join(SCRIPT_DIR, "manifest.json")


def load_scenes(path=SCENES_TOML):
    with open(path, "rb") as f:
        data = tomllib.load(f)
    scenes = data.get("scene", [])
    names = [s["name"] for s in scenes]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise SystemExit(f"{path}: duplicate scene names {sorted(dup)}")
    return scenes


def installed_mitsuba_version():
    import importlib.metadata

    try:
        return importlib.metadata.version("mitsuba")
    except importlib.metadata.PackageNotFoundError:
        return None


def why_stale(scene, manifest, mitsuba_version):
    """None if the reference is up to date, else the reason it is not."""
    out = os.path.join(REPO_ROOT, scene["reference"])
    if not os.path.exists(out):
        return "no reference file"
    entry = manifest.get(os.path.basename(out))
    if entry is None:
        return "no manifest entry"
    scene_path = os.path.join(REPO_ROOT, scene["file"])
    checks = [
        ("scene", entry.get("scene"), scene["file"]),
        ("scene_sha256", entry.get("scene_sha256"), rr.file_sha256(scene_path)),
        ("defines", entry.get("defines"), {k: str(v) for k, v in scene.get("defines", {}).items()}),
        ("spp", entry.get("spp"), scene["reference_spp"]),
        ("integrator", entry.get("integrator"), scene.get("mitsuba_integrator")),
        ("mitsuba_version", entry.get("mitsuba_version"), mitsuba_version),
    ]
    for name, have, want in checks:
        if have != want:
            return f"{name}: manifest has {have!r}, wanted {want!r}"
    return None


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--force", action="store_true", help="re-render even if up to date")
    p.add_argument("--scene", action="append", default=[], metavar="NAME",
                   help="only this scene (repeatable; also renders a pending scene)")
    p.add_argument("--dry-run", action="store_true", help="only say what would be rendered")
    p.add_argument("--variant", choices=("auto", "llvm_ad_rgb", "scalar_rgb"), default="auto")
    args = p.parse_args(argv)

    scenes = load_scenes()
    by_name = {s["name"]: s for s in scenes}
    unknown = [n for n in args.scene if n not in by_name]
    if unknown:
        raise SystemExit(f"unknown scene(s) {unknown}; known: {sorted(by_name)}")
    todo = [by_name[n] for n in args.scene] if args.scene else \
        [s for s in scenes if s["status"] == "landed" and "integrator" not in s]

    manifest = {}
    if os.path.exists(MANIFEST):
        import json
        with open(MANIFEST) as f:
            manifest = json.load(f)
    version = installed_mitsuba_version()

    for scene in todo:
        reason = "--force" if args.force else why_stale(scene, manifest, version)
        if reason is None:
            print(f"{scene['name']}: up to date", file=sys.stderr)
            continue
        variant = args.variant
        if scene.get("mode") == "spectral":
            # A spectral entry's reference comes from Mitsuba's spectral variant.
            variant = {"auto": "llvm_ad_spectral", "llvm_ad_rgb": "llvm_ad_spectral",
                       "scalar_rgb": "scalar_spectral"}[variant]
        cmd = [os.path.join(REPO_ROOT, scene["file"]), os.path.join(REPO_ROOT, scene["reference"]),
               "--spp", str(scene["reference_spp"]), "--variant", variant, "--quiet"]
        for k, v in scene.get("defines", {}).items():
            cmd += ["-D", f"{k}={v}"]
        if "mitsuba_integrator" in scene:
            cmd += ["--integrator", scene["mitsuba_integrator"]]
        if "mitsuba_variance" in scene:
            cmd += ["--variance", scene["mitsuba_variance"]]
        print(f"{scene['name']}: rendering ({reason}): render_reference.py "
              + " ".join(os.path.relpath(c, REPO_ROOT) if os.path.isabs(c) else c for c in cmd),
              file=sys.stderr, flush=True)
        if not args.dry_run:
            rr.main(cmd)


if __name__ == "__main__":
    main()
