#!/usr/bin/env python3
"""Loads every parameter of generate.py's list into the live Mitsuba (3.9.1).

Run by generate.py --check-with PYTHON (PYTHON must `import mitsuba`): it reads the
plugins as JSON on stdin and writes the outcomes as JSON on stdout.

For each plugin, a minimal valid object is loaded first (the plugin with the parameters it
requires, in a scene or a shape where it needs one; see WRAP and CHILDREN), in the first
variant where it loads (scalar_rgb, then the spectral, polarized and LLVM ones). Then each
parameter is added alone to it, with its example value (or, for string parameters with
listed values, each value in turn). Mitsuba throws on a property it did not read
("Found 1 unreferenced property ..."), so a load that succeeds proves the parameter is
read. An outcome is one of:

  accepted      the object loads with it
  refused       Mitsuba reads it but throws (the reason is kept: a conflict with another
                parameter, a variant it needs...)
  unreferenced  Mitsuba did not read it (the extraction would be wrong)
  not checked   the minimal object cannot be made here (why is kept)

Every file the objects need (a mesh, an image, a grid, a curve) is made in a temporary
folder, written <tmp> in the outcomes.
"""

import json
import os
import re
import shutil
import struct
import sys
import tempfile
import zlib

import numpy as np
import mitsuba as mi

VARIANTS = ["scalar_rgb", "scalar_spectral", "scalar_spectral_polarized", "llvm_ad_rgb"]

TAG = {"spectrum": "spectrum", "scene": "scene"}

# Nested objects the minimal object needs, as XML inside the plugin's element.
CHILDREN = {
    "bsdf/twosided": '<bsdf type="diffuse"/>',
    "bsdf/mask": '<bsdf type="diffuse"/>',
    "bsdf/normalmap": '<bsdf type="diffuse"/>',
    "bsdf/blendbsdf": '<bsdf type="diffuse"/><bsdf type="conductor"/>',
    "bsdf/bumpmap": '<texture type="checkerboard"/><bsdf type="diffuse"/>',
    "integrator/moment": '<integrator type="path" name="p"/>',
    "integrator/stokes": '<integrator type="path"/>',
    "phase/blendphase": '<phase type="isotropic"/><phase type="hg"/>',
    "shape/shapegroup": '<shape type="sphere"/>',
    "shape/merge": '<shape type="sphere"/><shape type="rectangle"/>',
    "shape/instance": '<ref id="group"/>',
    "sensor/batch": '<sensor type="perspective"/>',
    "sensor/distant": '<film type="hdrfilm"><integer name="width" value="1"/>'
                      '<integer name="height" value="1"/></film>',
    "sensor/radiancemeter": '<film type="hdrfilm"><integer name="width" value="1"/>'
                            '<integer name="height" value="1"/></film>',
}

# Where the plugin's element goes, when it cannot be the root of the file.
WRAP = {
    "emitter/area": '<shape type="rectangle" version="3.0.0">%s</shape>',
    "sensor/irradiancemeter": '<shape type="rectangle" version="3.0.0">%s</shape>',
    "shape/instance": '<scene version="3.0.0"><shape type="shapegroup" id="group">'
                      '<shape type="sphere"/></shape>%s</scene>',
}

# Properties the minimal object needs that are not single named parameters.
EXTRA = {
    "film/specfilm": '<spectrum name="srf" value="400:1, 700:1"/>',
}

# Nested objects standing for an `object` parameter, by plugin name.
OBJECTS = {
    "constvolume": '<volume type="constvolume" name="%s"/>',
    "bitmap": '<texture type="bitmap" name="%s"><string name="filename" value="<tmp>/image.exr"/></texture>',
    "sphere": '<shape type="sphere" name="%s"/>',
}


# One nested object of each tag, for the children Mitsuba's `props.objects()` loops take.
CHILD_SNIPPETS = {
    "bsdf": '<bsdf type="diffuse"/>',
    "emitter": '<emitter type="area"><float name="radiance" value="1"/></emitter>',
    "medium": '<medium type="homogeneous" name="%s"/>',
    "sensor": '<sensor type="irradiancemeter"/>',
    "texture": '<texture type="checkerboard" name="%s"/>',
    "film": '<film type="hdrfilm"/>',
    "sampler": '<sampler type="independent"/>',
    "rfilter": '<rfilter type="box"/>',
    "phase": '<phase type="isotropic"/>',
    "integrator": '<integrator type="path" name="%s"/>',
    "shape": '<shape type="sphere"/>',
}


def sphere_sdf():
    """An 8^3 signed distance grid of a sphere in the unit cube."""
    return np.fromfunction(
        lambda z, y, x: np.sqrt((x - 3.5) ** 2 + (y - 3.5) ** 2 + (z - 3.5) ** 2) / 8 - 0.3,
        (8, 8, 8)).astype(np.float32)[..., None]


def python_only_values():
    """Values only a Python dictionary can give, for (plugin, parameter): checked with
    mi.load_dict instead of the XML (they replace the plugin's `filename`)."""
    img = np.full((4, 4, 3), 0.5, dtype=np.float32)
    grid = np.full((4, 4, 4, 1), 0.5, dtype=np.float32)
    return {
        ("texture/bitmap", "data"): lambda: mi.TensorXf(img),
        ("texture/bitmap", "bitmap"): lambda: mi.Bitmap(img),
        ("emitter/envmap", "bitmap"): lambda: mi.Bitmap(np.full((4, 8, 3), 0.5, dtype=np.float32)),
        ("volume/gridvolume", "data"): lambda: mi.TensorXf(grid),
        ("volume/gridvolume", "grid"): lambda: mi.VolumeGrid(grid),
        ("shape/sdfgrid", "grid"): lambda: mi.TensorXf(sphere_sdf()),
    }


def make_files(tmp):
    """The files the minimal objects read."""
    with open(os.path.join(tmp, "mesh.obj"), "w") as f:
        f.write("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\n"
                "f 1/1/1 2/2/1 3/3/1\n")
    with open(os.path.join(tmp, "mesh.ply"), "w") as f:
        f.write("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    write_serialized(os.path.join(tmp, "mesh.serialized"))
    img = mi.Bitmap(np.full((4, 4, 3), 0.5, dtype=np.float32))
    img.write(os.path.join(tmp, "image.exr"))
    mi.Bitmap(np.full((4, 8, 3), 0.5, dtype=np.float32)).write(os.path.join(tmp, "env.exr"))
    mi.VolumeGrid(np.full((4, 4, 4, 1), 0.5, dtype=np.float32)).write(os.path.join(tmp, "grid.vol"))
    mi.VolumeGrid(sphere_sdf()).write(os.path.join(tmp, "sdf.vol"))
    with open(os.path.join(tmp, "curve.txt"), "w") as f:
        f.write("0 0 0 0.1\n0 0 1 0.1\n0 0 2 0.1\n0 0 3 0.1\n")
    # Ellipsoids: one, as a binary PLY (x y z nx ny nz, one extra, scale_*, rot_*).
    names = ["x", "y", "z", "nx", "ny", "nz", "opacity", "scale_0", "scale_1", "scale_2",
             "rot_0", "rot_1", "rot_2", "rot_3"]
    values = [0, 0, 0, 0, 0, 1, 1, -2, -2, -2, 1, 0, 0, 0]
    header = "ply\nformat binary_little_endian 1.0\nelement vertex 1\n"
    header += "".join("property float %s\n" % n for n in names) + "end_header\n"
    with open(os.path.join(tmp, "ellipsoids.ply"), "wb") as f:
        f.write(header.encode() + struct.pack("<%df" % len(values), *values))


def write_serialized(path):
    """One triangle in Mitsuba's serialized format (version 4, float, no extras)."""
    verts = [0, 0, 0, 1, 0, 0, 0, 1, 0]
    body = struct.pack("<I", 0x1000)  # flags: single precision
    body += "mesh".encode() + b"\0"
    body += struct.pack("<QQ", 3, 1)
    body += struct.pack("<9f", *verts) + struct.pack("<3I", 0, 1, 2)
    data = struct.pack("<HH", 0x041C, 4) + zlib.compress(body)
    data += struct.pack("<QI", 0, 1)  # the dictionary: offset of mesh 0, mesh count
    with open(path, "wb") as f:
        f.write(data)


def fmt(v):
    return repr(float(v)) if isinstance(v, float) else str(v)


def value_xml(name, kind, value, tmp):
    """The XML property (or nested object) giving `name` the value `value`."""
    if isinstance(value, str):
        value = value.replace("<tmp>", tmp)
    if kind == "boolean":
        return '<boolean name="%s" value="%s"/>' % (name, "true" if value else "false")
    if kind == "integer":
        return '<integer name="%s" value="%d"/>' % (name, value)
    if kind in ("float", "texture", "volume", "ior") and isinstance(value, (int, float)) \
            and not isinstance(value, bool):
        return '<float name="%s" value="%s"/>' % (name, fmt(value))
    if kind in ("string", "ior"):
        return '<string name="%s" value="%s"/>' % (name, value)
    if kind in ("rgb", "texture", "volume"):
        return '<rgb name="%s" value="%s"/>' % (name, ", ".join(fmt(x) for x in value))
    if kind in ("point", "vector"):
        return '<%s name="%s" x="%s" y="%s" z="%s"/>' % ((kind, name) + tuple(fmt(x) for x in value))
    if kind == "transform":
        return '<transform name="%s"><translate x="0" y="0" z="0"/></transform>' % name
    if kind == "spectrum":
        return '<spectrum name="%s" value="%s"/>' % (name, value)
    raise ValueError("no XML for %s of kind %s" % (name, kind))


def param_xml(p, value, tmp):
    if p["type"] == "object" or "example_object" in p:
        return OBJECTS[p["example_object"]].replace("<tmp>", tmp) % p["name"]
    return value_xml(p["name"], p["type"], value, tmp)


def element(plugin, props_xml, tmp, attrs=""):
    key = plugin["kind"] + "/" + plugin["name"]
    tag = TAG.get(plugin["kind"], plugin["kind"])
    body = props_xml + EXTRA.get(key, "").replace("<tmp>", tmp) + CHILDREN.get(key, "")
    if plugin["kind"] == "scene":
        return '<scene version="3.0.0"%s>%s</scene>' % (attrs, body)
    if key in WRAP:
        return WRAP[key] % ('<%s type="%s"%s>%s</%s>' % (tag, plugin["name"], attrs, body, tag))
    return '<%s type="%s" version="3.0.0"%s>%s</%s>' % (tag, plugin["name"], attrs, body, tag)


def clean(message, tmp):
    """The reason of an error, without file locations and temporary paths."""
    message = message.replace(tmp, "<tmp>")
    message = re.sub(r"\[[\w.]+:\d+\]\s*", "", message)
    parts = re.split(r"failed to instantiate \w+ plugin of type \"\w+\":\s*", message)
    message = parts[-1]
    message = re.sub(r"^Error while loading .*?: ", "", message)
    message = re.sub(r"\s+", " ", message).strip()
    return message[:300]


def load(xml):
    if os.environ.get("LIVE_CHECK_DEBUG"):
        print(mi.variant(), xml, file=sys.stderr, flush=True)
    mi.load_string(xml)


def outcome(plugin, props, tmp, name, variant, attrs=""):
    """accepted / unreferenced / refused (with why) of one load."""
    mi.set_variant(variant)
    try:
        load(element(plugin, props, tmp, attrs))
        return "accepted", None
    except Exception as e:  # noqa: BLE001 - Mitsuba raises RuntimeError and others
        msg = str(e)
        if "unreferenced propert" in msg and re.search(r'"%s"' % re.escape(name), msg):
            return "unreferenced", clean(msg, tmp)
        return "refused", clean(msg, tmp)


def check_plugin(plugin, tmp):
    key = plugin["kind"] + "/" + plugin["name"]
    params = {p["name"]: p for p in plugin["parameters"]}
    required = plugin.get("requires", {})

    def props_with(extra_name=None, extra_xml=""):
        """The required properties (less those the tested one replaces) + extra_xml."""
        xml = ""
        skip = set()
        if extra_name:
            p = params[extra_name]
            skip = {extra_name} | set(p.get("with", {})) | set(p.get("conflicts", []))
        for n, v in required.items():
            if n in skip:
                continue
            p = params[n]
            xml += param_xml(p, v, tmp)
        return xml + extra_xml

    # The minimal object: the first variant it loads in.
    variants = VARIANTS
    if plugin["source"].endswith(".py"):
        variants = ["llvm_ad_rgb"]
    base_variant, base_errors = None, []
    for v in variants:
        st, why = outcome(plugin, props_with(), tmp, "", v)
        if st == "accepted":
            base_variant = v
            break
        base_errors.append("%s: %s" % (v, why))
    result = {"plugin": {}, "parameters": {}}
    if base_variant is None:
        result["plugin"] = {"status": "not checked", "why": "; ".join(base_errors)}
        for p in plugin["parameters"]:
            result["parameters"][p["name"]] = {"status": "not checked",
                                               "why": "the plugin does not load here"}
        return result
    result["plugin"] = {"status": "loads", "variant": base_variant}
    # The id attribute (props.id()), which every object takes.
    st, why = outcome(plugin, props_with(), tmp, "", base_variant, ' id="an_id"')
    result["plugin"]["id"] = st if why is None else "%s: %s" % (st, why)
    others = [v for v in variants if v != base_variant]

    def try_param(p, value, with_=None):
        xml = param_xml(p, value, tmp)
        for n, v in (with_ or p.get("with", {})).items():
            xml += param_xml(params[n], v, tmp)
        first = None
        for v in [base_variant] + others:
            st, why = outcome(plugin, props_with(p["name"], xml), tmp, p["name"], v)
            if st == "accepted":
                return st, None, v
            if first is None:
                first = (st, why, v)
            if st == "unreferenced":
                break
        return first

    for p in plugin["parameters"]:
        if p.get("xml") is False:
            make = PYTHON_ONLY.get((key, p["name"]))
            if make is None:
                result["parameters"][p["name"]] = {"status": "not checked",
                                                   "why": "no XML form (Python dictionaries only)"}
                continue
            mi.set_variant(base_variant)
            try:
                mi.load_dict({"type": plugin["name"], p["name"]: make()})
                result["parameters"][p["name"]] = {"status": "accepted",
                                                   "why": "checked with mi.load_dict"}
            except Exception as e:  # noqa: BLE001
                result["parameters"][p["name"]] = {"status": "refused", "why": clean(str(e), tmp)}
            continue
        if "example" not in p and "example_object" not in p:
            result["parameters"][p["name"]] = {"status": "not checked", "why": "no example"}
            continue
        st, why, v = try_param(p, p.get("example"))
        r = {"status": st}
        if why:
            r["why"] = why
        if v != "scalar_rgb":
            r["variant"] = v
        if p.get("values") and p["type"] in ("string", "ior"):
            accepted, refused = [], []
            for value in list(dict.fromkeys(p["values"] + p.get("doc_values", []))):
                with_ = dict(p.get("with", {}), **p.get("values_with", {}))
                st2, why2, v2 = try_param(p, p.get("value_pattern", "{}").format(value), with_)
                if st2 == "accepted":
                    accepted.append(value)
                elif value in p["values"]:  # a doc's word that is no value is dropped
                    refused.append({"value": value, "why": why2})
            r["values"] = {"accepted": accepted, "refused": refused}
            if st != "accepted" and accepted:
                r = dict(r, status="accepted", example_refused=why)
                r.pop("why", None)
        result["parameters"][p["name"]] = r

    # Nested objects: one of each kind the loops over props.objects() take, added to the
    # minimal object (unless it has one already).
    for child in plugin.get("children", []):
        tag = child["object"]
        snippet = CHILD_SNIPPETS.get(tag)
        ident = tag + (":" + child["names"][0] if child.get("names") else "")
        if snippet is None:
            result.setdefault("children", {})[ident] = {"status": "not checked",
                                                        "why": "no snippet for it"}
            continue
        if "<%s " % tag.split(" ")[0] in CHILDREN.get(key, "") \
                or (tag.startswith("shape (") and "<ref " in CHILDREN.get(key, "")):
            result.setdefault("children", {})[ident] = {"status": "accepted",
                                                        "why": "the minimal object has one"}
            continue
        name = child["names"][0] if child.get("names") else "child"
        xml = snippet % name if "%s" in snippet else snippet
        st, why = outcome(plugin, props_with(None, xml), tmp, "", base_variant)
        r = {"status": st, "xml": xml}
        if why:
            r["why"] = why
        result.setdefault("children", {})[ident] = r

    # Documented names the extraction did not find: they should not be read.
    for name in plugin.get("documented_not_read", []):
        st, why = outcome(plugin, props_with(None, value_xml(name, "float", 0.5, tmp)), tmp,
                          name, base_variant)
        result.setdefault("documented_not_read", {})[name] = st
    return result


def main():
    plugins = json.load(sys.stdin)
    mi.set_variant("scalar_rgb")
    mi.set_log_level(mi.LogLevel.Error)
    tmp = tempfile.mkdtemp(prefix="mitsuba-params-")
    global PYTHON_ONLY
    PYTHON_ONLY = python_only_values()
    make_files(tmp)
    out = {"about": "mitsuba %s (pip), mi.load_string of each plugin with each parameter; "
                    "variants tried in order: %s" % (mi.__version__, ", ".join(VARIANTS)),
           "plugins": {}}
    for plugin in plugins:
        key = plugin["kind"] + "/" + plugin["name"]
        out["plugins"][key] = check_plugin(plugin, tmp)
        print("checked", key, file=sys.stderr)
    shutil.rmtree(tmp)
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
