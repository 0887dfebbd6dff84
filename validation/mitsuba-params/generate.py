#!/usr/bin/env python3
"""The parameters Mitsuba 3.9.1 reads, plugin by plugin, extracted from its sources.

    python3 validation/mitsuba-params/generate.py MITSUBA_SRC \
        [--check-with .venv/bin/python] [-o tests/data/mitsuba_params.json]

MITSUBA_SRC is an unpacked Mitsuba 3.9.1 source tree (the folders `src/` and `include/`
of the tag v3.9.1). The extraction uses the standard library only: it reads every
plugin's C++ (or Python) source, the base classes its constructor chains to, and the
helpers it hands its properties to, and lists every property name read with
`props.get<T>`, `get_texture`, `get_volume`, `get_emissive_texture`,
`get_unbounded_texture`, `texture`, `has_property`, `mark_queried`, `get_any`, `try_get`
or `type`, with the kind of value, the default (the C++ expression as written), the
string values the source compares against, and the first sentence of the parameter's
documentation. What a regular expression cannot get right is set right by the explicit,
commented tables below (CORRECTIONS and friends).

With --check-with PYTHON (an interpreter that can `import mitsuba`), every parameter is
then loaded into the live Mitsuba, alone in a minimal valid object of its plugin (see
live_check.py), and the outcome is recorded: `accepted` (loads without Mitsuba's
"unreferenced property" error), `refused` (Mitsuba reads it but throws, with the reason),
`unreferenced` (not read: the extraction would be wrong), or `not checked` (with why).
Every listed string value is checked the same way.

The output is deterministic: sorted plugins and parameters, no timestamps, no temporary
paths.
"""

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile

MITSUBA_VERSION = "3.9.1"
MITSUBA_TAG = "v3.9.1"
# `git rev-parse v3.9.1^{commit}` in github.com/mitsuba-renderer/mitsuba3.
MITSUBA_COMMIT = "478e193a183c21723f4a8251afc3ad29a8da4c5e"

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))

# Folder of src/ -> the plugin kind (the XML tag; spectra are <spectrum type=..> objects,
# which Mitsuba instantiates as textures).
KIND_OF_FOLDER = {
    "bsdfs": "bsdf",
    "emitters": "emitter",
    "films": "film",
    "integrators": "integrator",
    "media": "medium",
    "phase": "phase",
    "rfilters": "rfilter",
    "samplers": "sampler",
    "sensors": "sensor",
    "shapes": "shape",
    "spectra": "spectrum",
    "textures": "texture",
    "volumes": "volume",
}

# The plugins penumbra implements (README.md, "Supported Mitsuba 3 subset", and
# src/scene/description/*.rs). texture/volume is listed because penumbra is adding it.
# `scene/scene` is the root <scene> element, whose properties Mitsuba reads too.
PENUMBRA_SUPPORTS = {
    "scene": ["scene"],
    "integrator": ["path", "volpath", "volpathmis", "direct", "moment", "ptracer", "aov"],
    "sensor": ["perspective", "thinlens", "orthographic"],
    "film": ["hdrfilm"],
    "rfilter": ["gaussian", "tent", "box"],
    "sampler": ["independent", "stratified", "multijitter", "orthogonal", "ldsampler"],
    "bsdf": [
        "diffuse", "conductor", "roughconductor", "dielectric", "thindielectric",
        "roughdielectric", "plastic", "roughplastic", "principled", "principledthin",
        "twosided", "mask", "blendbsdf", "normalmap", "bumpmap", "null",
    ],
    "texture": ["bitmap", "checkerboard", "mesh_attribute", "volume"],
    "spectrum": ["rawconstant", "srgb", "uniform"],
    "shape": [
        "rectangle", "cube", "disk", "sphere", "cylinder", "obj", "ply", "serialized",
        "sdfgrid", "shapegroup", "instance",
    ],
    "medium": ["homogeneous", "heterogeneous"],
    "volume": ["constvolume", "gridvolume"],
    "phase": ["isotropic", "hg"],
    "emitter": ["area", "point", "spot", "projector", "directional", "constant", "envmap"],
}

# ---------------------------------------------------------------------------------------
# Value kinds
# ---------------------------------------------------------------------------------------

# C++ template argument of props.get<T> / get_any<T> / try_get<T> -> the kind of value.
CPP_TYPES = {
    "bool": "boolean",
    "int": "integer", "int32_t": "integer", "uint32_t": "integer", "size_t": "integer",
    "int64_t": "integer", "uint64_t": "integer", "ScalarInt32": "integer",
    "ScalarUInt32": "integer", "ScalarSize": "integer",
    "float": "float", "double": "float", "ScalarFloat": "float",
    "std::string": "string", "std::string_view": "string",
    "ScalarColor3f": "rgb", "Color3f": "rgb", "ScalarColor3d": "rgb",
    "ScalarPoint3f": "point", "ScalarPoint3d": "point", "Point3f": "point",
    "ScalarVector3f": "vector", "ScalarVector3d": "vector", "Vector3f": "vector",
    "ScalarAffineTransform4f": "transform", "ScalarAffineTransform3f": "transform",
    "ScalarTransform4f": "transform", "ScalarAffineTransform4d": "transform",
    "ref<Object>": "object", "ref<Volume>": "object",
    "Properties::Spectrum": "spectrum",
    "TensorXf": "tensor", "TensorXf32": "tensor",
}

# The accessors that read a texture-valued parameter (a number, an <rgb>, a <spectrum> or
# a nested/referenced <texture>), with how Mitsuba converts an <rgb> or <spectrum>.
TEXTURE_ACCESSORS = {
    "get_texture": "reflectance",  # bounded: an <rgb> outside [0, 1] is an error
    "texture": "reflectance",
    "get_emissive_texture": "emission",  # an illuminant spectrum
    "get_unbounded_texture": "unbounded",
}

TYPE_DOC = {
    "boolean": "<boolean>",
    "integer": "<integer>",
    "float": "<float> (an <integer> is accepted too)",
    "string": "<string>",
    "rgb": "<rgb> (a colour read as is, props.get<Color3f>)",
    "spectrum": "<spectrum value=..> (props.try_get<Properties::Spectrum>)",
    "texture": "a texture: <float>, <rgb>, <spectrum> or a nested/referenced <texture>; "
               "`role` says how Mitsuba converts colours (reflectance: bounded to [0, 1]; "
               "emission: an illuminant; unbounded: as given)",
    "volume": "a volume: <float>, <rgb>, <spectrum> or a nested/referenced <volume>",
    "point": "<point> (a <vector> is accepted too)",
    "vector": "<vector> (a <point> is accepted too)",
    "transform": "<transform>",
    "object": "a nested or referenced object (`object` says which)",
    "tensor": "a tensor (Python dictionaries only: mi.TensorXf; no XML form)",
    "pointer": "a memory address as an integer (Blender's exporter only)",
    "bitmap": "an mi.Bitmap object (Python dictionaries only)",
    "ior": "a <float> or a <string> naming a material of Mitsuba's IOR table",
}

# ---------------------------------------------------------------------------------------
# Corrections: what the regular expressions cannot know. Every entry says why.
# ---------------------------------------------------------------------------------------

# Per plugin ("kind/name") and parameter: fields merged into the extracted entry.
#   type/object/role: the kind of value when the accessor does not say (has_property,
#       mark_queried, props.type) or says it wrongly;
#   values: the allowed string values when they are not literal comparisons in the
#       source; example: a valid value to load it with (when the default is not one);
#   with: other parameters Mitsuba needs set together with this one;
#   xml: False for values only a Python dictionary can give;
#   note: a dependency on other parameters, or what Mitsuba does with it.
CORRECTIONS = {
    "film/hdrfilm": {
        # Defaults that are expressions (768 and 576, the crop the whole film): examples
        # that make a crop inside a 768x576 film.
        "width": {"example": 64}, "height": {"example": 48},
        "crop_width": {"example": 16}, "crop_height": {"example": 16},
        "crop_offset_x": {"example": 0}, "crop_offset_y": {"example": 0},
        # props.mark_queried("banner"): accepted and ignored ("no banner in Mitsuba 3").
        "banner": {"type": "boolean", "example": False,
                   "note": "marked as read and ignored (Mitsuba 0.6's banner)"},
        # Only marked as read, with a warning that it was removed.
        "compensate": {"type": "boolean", "example": False,
                       "note": "marked as read and ignored, with a warning (removed)"},
    },
    "film/specfilm": {
        "width": {"example": 64}, "height": {"example": 48},
        "crop_width": {"example": 16}, "crop_height": {"example": 16},
        "crop_offset_x": {"example": 0}, "crop_offset_y": {"example": 0},
        "compensate": {"type": "boolean", "example": False,
                       "note": "marked as read and ignored, with a warning (removed)"},
    },
    "sensor/perspective": {
        # parse_fov() reads `fov` without a default (a perspective camera without it uses
        # focal_length's default 50mm).
        "fov": {"example": 45.0, "conflicts": ["focal_length"]},
        "focal_length": {"example": "50mm", "conflicts": ["fov"],
                         "note": "a string '<x>mm'; ignored when fov is given (an error with it)"},
        "fov_axis": {"note": "read only together with fov", "with": {"fov": 45.0}},
    },
    "sensor/thinlens": {
        "fov": {"example": 45.0, "conflicts": ["focal_length"]},
        "focal_length": {"example": "50mm", "conflicts": ["fov"],
                         "note": "a string '<x>mm'; an error together with fov"},
        "fov_axis": {"note": "read only together with fov", "with": {"fov": 45.0}},
        "aperture_radius": {"example": 0.1},
    },
    "emitter/projector": {
        "fov": {"example": 45.0, "conflicts": ["focal_length"]},
        "focal_length": {"example": "50mm", "conflicts": ["fov"],
                         "note": "a string '<x>mm'; an error together with fov"},
        "fov_axis": {"note": "read only together with fov", "with": {"fov": 45.0}},
    },
    "emitter/area": {
        "to_world": {"note": "read by the Endpoint base class; the area light throws if it "
                             "is given (it inherits its shape's transform)"},
    },
    "emitter/point": {
        "to_world": {"conflicts": ["position"],
                     "note": "either to_world or position, not both"},
        "position": {"example": [0.0, 0.0, 0.0], "conflicts": ["to_world"]},
    },
    "emitter/directional": {
        "to_world": {"conflicts": ["direction"],
                     "note": "either to_world or direction, not both"},
        "direction": {"example": [0.0, 0.0, 1.0], "conflicts": ["to_world"]},
    },
    "emitter/spot": {
        # get_texture("texture", 1.f): a constant texture is refused (it must vary).
        "texture": {"note": "must be spatially varying (e.g. a bitmap); a constant belongs "
                            "in intensity", "example_object": "bitmap"},
        "beam_width": {"example": 15.0},
    },
    "emitter/envmap": {
        "bitmap": {"type": "bitmap", "xml": False,
                   "note": "an mi.Bitmap instead of filename (Python only)"},
    },
    "emitter/timed_sunsky": {
        # Its default is start_year + 1.
        "end_year": {"example": 2026},
    },
    "emitter/sunsky": {
        "sun_direction": {"conflicts": ["latitude", "longitude", "timezone", "year", "month",
                                        "day", "hour", "minute", "second"],
                          "note": "either sun_direction or the location and time"},
    },
    "bsdf/conductor": {
        # complex_ior_from_file() opens data/ior/<material>.{eta,k}.spd: the names are
        # the table of the plugin's documentation (checked one by one below), + "none".
        "material": {"values_from": "conductor_materials",
                     "note": "a measured metal; used unless eta is given"},
        "eta": {"note": "with k; replaces material"},
        "k": {"note": "read only when eta is given or material is none"},
    },
    "bsdf/roughconductor": {
        "material": {"values_from": "conductor_materials",
                     "note": "a measured metal; used unless eta is given"},
        "eta": {"note": "with k; replaces material"},
        "k": {"note": "read only when eta is given or material is none"},
        "alpha_u": {"with": {"alpha_v": 0.2}, "conflicts": ["alpha"],
                    "note": "anisotropic roughness: alpha_u and alpha_v together, not with alpha"},
        "alpha_v": {"with": {"alpha_u": 0.2}, "conflicts": ["alpha"],
                    "note": "anisotropic roughness: alpha_u and alpha_v together, not with alpha"},
    },
    "bsdf/roughdielectric": {
        "alpha_u": {"with": {"alpha_v": 0.2}, "conflicts": ["alpha"],
                    "note": "anisotropic roughness: alpha_u and alpha_v together, not with alpha"},
        "alpha_v": {"with": {"alpha_u": 0.2}, "conflicts": ["alpha"],
                    "note": "anisotropic roughness: alpha_u and alpha_v together, not with alpha"},
    },
    "bsdf/roughplastic": {
        # MicrofacetDistribution(props) reads alpha_u/alpha_v, and roughplastic then
        # refuses an anisotropic distribution.
        "alpha_u": {"example": 0.2, "with": {"alpha_v": 0.2},
                    "note": "read by MicrofacetDistribution; roughplastic throws on "
                            "anisotropic roughness, so only alpha_u == alpha_v loads"},
        "alpha_v": {"example": 0.2, "with": {"alpha_u": 0.2},
                    "note": "read by MicrofacetDistribution; roughplastic throws on "
                            "anisotropic roughness, so only alpha_u == alpha_v loads"},
    },
    "bsdf/pplastic": {
        "alpha_u": {"with": {"alpha_v": 0.2}, "conflicts": ["alpha"],
                    "note": "anisotropic roughness: alpha_u and alpha_v together, not with alpha"},
        "alpha_v": {"with": {"alpha_u": 0.2}, "conflicts": ["alpha"],
                    "note": "anisotropic roughness: alpha_u and alpha_v together, not with alpha"},
        "eta": {"conflicts": ["int_ior", "ext_ior"]},
        # `props.has_property("ext_iot")` (sic) in the check that eta is not given with
        # int_ior/ext_ior: a typo in Mitsuba, never read, so not a parameter.
        "ext_iot": {"drop": "a typo of ext_ior in Mitsuba's has_property() check; never read"},
    },
    "bsdf/principled": {
        "eta": {"example": 1.5, "conflicts": ["specular"],
                "note": "either eta or specular, not both"},
        "specular": {"conflicts": ["eta"], "note": "either eta or specular, not both"},
    },
    "bsdf/twosided": {
        "allow_transmission": {"note": "read only after the nested BSDFs; false refuses a "
                                       "transmissive nested BSDF"},
    },
    "bsdf/hair": {
        "sigma_a": {"conflicts": ["eumelanin", "pheomelanin"],
                    "note": "absorption directly, instead of eumelanin/pheomelanin"},
    },
    "bsdf/measured": {"filename": {"example": "<tmp>/missing.bsdf"}},
    "bsdf/measured_polarized": {"filename": {"example": "<tmp>/missing.pbsdf"}},
    "texture/bitmap": {
        "bitmap": {"type": "bitmap", "xml": False,
                   "note": "an mi.Bitmap instead of filename (Python only)"},
        "data": {"xml": False, "note": "a tensor instead of filename (Python only)"},
        "format": {"note": "uint8 is refused in spectral variants"},
    },
    "texture/volume": {
        "volume": {"object": "volume", "example_object": "constvolume"},
    },
    "texture/mesh_attribute": {
        "name": {"example": "vertex_color",
                 "note": "must start with vertex_ or face_"},
    },
    "volume/gridvolume": {
        "grid": {"type": "object", "object": "VolumeGrid", "xml": False,
                 "note": "an mi.VolumeGrid instead of filename (Python only)"},
        "data": {"xml": False, "note": "a tensor instead of filename (Python only)"},
        "max_value": {"example": 1.0},
    },
    "shape/sdfgrid": {
        "grid": {"xml": False, "note": "a tensor instead of filename (Python only)"},
    },
    "shape/ellipsoids": {
        "data": {"xml": False}, "centers": {"xml": False}, "scales": {"xml": False},
        "quaternions": {"xml": False},
    },
    "shape/ellipsoidsmesh": {
        "data": {"xml": False}, "centers": {"xml": False}, "scales": {"xml": False},
        "quaternions": {"xml": False},
        "shell": {"also": ["object"], "values": ["default", "box", "ico_sphere", "uv_sphere"]},
    },
    "sensor/distant": {
        # props.type("target"): a point, or a shape object.
        "target": {"type": "point", "also": ["object"], "example": [0.0, 0.0, 0.0]},
        "direction": {"conflicts": ["to_world"], "note": "either direction or to_world"},
        "to_world": {"conflicts": ["direction"], "note": "either direction or to_world"},
    },
    "sensor/radiancemeter": {
        "origin": {"with": {"direction": [0.0, 0.0, 1.0]}, "conflicts": ["to_world"],
                   "note": "origin and direction together, instead of to_world"},
        "direction": {"with": {"origin": [0.0, 0.0, 0.0]}, "conflicts": ["to_world"],
                      "note": "origin and direction together, instead of to_world"},
        "to_world": {"conflicts": ["origin", "direction"]},
    },
    "sensor/irradiancemeter": {
        "to_world": {"note": "read by the Endpoint base class; the irradiance meter throws "
                             "if it is given (it inherits its shape's transform)"},
    },
    "phase/sggx": {"S": {"object": "volume", "example_object": "constvolume"}},
    "phase/blendphase": {"weight": {"example": 0.5}},
    "phase/tabphase": {"values": {"example": "0.5, 1.0, 1.5"}},
    "spectrum/rawconstant": {
        # props.type("value") switches between a vector and a float.
        "value": {"type": "float", "also": ["vector"], "example": 0.5},
    },
    "spectrum/srgb": {"color": {"example": [0.5, 0.5, 0.5]},
                      "unbounded": {"note": "allows a colour outside [0, 1]"}},
    "spectrum/uniform": {"value": {"example": 0.5}},
    "spectrum/blackbody": {"temperature": {"example": 5000.0}},
    "spectrum/d65": {"color": {"example": [0.5, 0.5, 0.5]}},
    "spectrum/irregular": {
        "value": {"type": "spectrum", "example": "500:0.5, 600:0.5",
                  "conflicts": ["wavelengths", "values"]},
        "wavelengths": {"example": "500, 600", "with": {"values": "0.5, 0.5"}},
        "values": {"example": "0.5, 0.5", "with": {"wavelengths": "500, 600"}},
    },
    "spectrum/regular": {
        "value": {"type": "spectrum", "example": "500:0.5, 600:0.5",
                  "conflicts": ["values", "wavelength_min", "wavelength_max"]},
        "values": {"example": "0.5, 0.5",
                   "with": {"wavelength_min": 500.0, "wavelength_max": 600.0}},
        "wavelength_min": {"example": 500.0,
                           "with": {"values": "0.5, 0.5", "wavelength_max": 600.0}},
        "wavelength_max": {"example": 600.0,
                           "with": {"values": "0.5, 0.5", "wavelength_min": 500.0}},
    },
    "integrator/aov": {
        # The comma-separated "name:type" list; the types are the source's comparisons of
        # item[1] (see AOV_TYPES below).
        "aovs": {"example": "dd:depth", "values_from": "aov_types", "value_pattern": "dd:{}",
                 "note": "a comma-separated list of name:type pairs; `values` are the types "
                         "(a value without its name: crashes Mitsuba)"},
    },
    "integrator/direct": {
        "shading_samples": {"conflicts": ["emitter_samples", "bsdf_samples"]},
        "emitter_samples": {"conflicts": ["shading_samples"]},
        "bsdf_samples": {"conflicts": ["shading_samples"]},
    },
    "scene/scene": {
        # Scene() marks the kd-tree and Embree options as read; their kinds are those of
        # ShapeKDTree() and the Embree backend, which read them (see SCENE_SOURCES).
        "kd_stop_prims": {"example": 8},
        "kd_max_depth": {"example": 16},
        "kd_min_max_bins": {"example": 128},
        "kd_exact_primitive_threshold": {"example": 65536},
    },
    # Blender's exporter hands over memory addresses (int64) and its mesh's header:
    # nothing an XML file can give.
    "shape/blender": {"*": {"xml": False}},
}

# What a parameter does, in one line, where the plugin's documentation table does not say
# (mostly the base classes' parameters, which no plugin documents): written from the
# source, by the class that reads it (or "kind/plugin.name" for one plugin).
SEMANTICS = {
    "Endpoint.to_world": "placement of the emitter or sensor (object to world)",
    "Emitter.sampling_weight": "relative probability of picking this emitter for emitter "
                               "sampling (Scene builds its emitter distribution from these)",
    "Sensor.shutter_open": "time the shutter opens (ray times are sampled in "
                           "[shutter_open, shutter_close]: motion blur)",
    "Sensor.shutter_close": "time the shutter closes (default 0: no motion blur)",
    "Sensor.srf": "spectral response function of the sensor (spectral variants only; "
                  "the RGB variants throw)",
    "ProjectiveCamera.near_clip": "distance of the near clipping plane",
    "ProjectiveCamera.far_clip": "distance of the far clipping plane",
    "ProjectiveCamera.focus_distance": "distance of the focal plane (default far_clip; used "
                                       "by thinlens)",
    "Film.width": "width of the film in pixels",
    "Film.height": "height of the film in pixels",
    "Film.crop_width": "width of the rendered sub-rectangle (default: the whole film)",
    "Film.crop_height": "height of the rendered sub-rectangle (default: the whole film)",
    "Film.crop_offset_x": "left edge of the rendered sub-rectangle, in pixels",
    "Film.crop_offset_y": "top edge of the rendered sub-rectangle, in pixels",
    "Film.sample_border": "also sample a border of the filter's radius outside the film, so "
                          "that edge pixels get their whole filter footprint",
    "Shape.to_world": "placement of the shape (object to world)",
    "Shape.silhouette_sampling_weight": "relative probability of sampling this shape's "
                                        "silhouette (projective AD integrators only)",
    "Mesh.face_normals": "use the faces' geometric normals instead of the vertex normals "
                         "(flat shading)",
    "Mesh.flip_normals": "flip the normals (the shape's inside and outside swap)",
    "Integrator.timeout": "stop rendering after this many seconds (-1: no limit)",
    "Integrator.hide_emitters": "directly visible emitters are black",
    "SamplingIntegrator.block_size": "side of the image blocks rendered in parallel "
                                     "(rounded up to a power of two; 0: automatic)",
    "SamplingIntegrator.samples_per_pass": "render in passes of this many samples per "
                                           "pixel (deprecated, with a warning)",
    "MonteCarloIntegrator.max_depth": "longest path depth (-1: unbounded)",
    "MonteCarloIntegrator.rr_depth": "depth at which Russian roulette starts",
    "AdjointIntegrator.samples_per_pass": "render in passes of this many samples per pixel",
    "AdjointIntegrator.max_depth": "longest path depth (-1: unbounded)",
    "AdjointIntegrator.rr_depth": "depth at which Russian roulette starts",
    "Sampler.sample_count": "samples per pixel",
    "Sampler.seed": "seed of the sampler's random numbers",
    "Medium.sample_emitters": "next-event estimation inside the medium",
    "Volume.to_world": "placement of the volume's unit cube (object to world)",
    "scene.allow_thread_reordering": "let the JIT (CUDA/OptiX) reorder threads by shape "
                                     "and BSDF; no effect in CPU variants",
    "scene.compact_acceleration_structures": "compact the OptiX/Metal acceleration "
                                             "structures (less memory); CPU: no effect",
    "scene_embree.embree_use_robust_intersections": "Embree's robust intersection mode "
                                                    "(RTC_SCENE_FLAG_ROBUST)",
    "kdtree.kd_intersection_cost": "kd-tree SAH cost of a primitive intersection",
    "kdtree.kd_traversal_cost": "kd-tree SAH cost of a traversal step",
    "kdtree.kd_empty_space_bonus": "kd-tree SAH bonus factor for empty leaves",
    "kdtree.kd_stop_prims": "kd-tree: stop splitting below this many primitives",
    "kdtree.kd_max_depth": "kd-tree: maximum depth",
    "kdtree.kd_min_max_bins": "kd-tree: number of min-max bins of the SAH build",
    "kdtree.kd_clip": "kd-tree: clip primitives to the node bounds (perfect splits)",
    "kdtree.kd_retract_bad_splits": "kd-tree: retract splits that did not pay off",
    "kdtree.kd_exact_primitive_threshold": "kd-tree: below this many primitives, build "
                                           "with exact SAH evaluation",
    "film/hdrfilm.banner": "ignored (marked as read: Mitsuba 0.6 scenes have it)",
    "film/hdrfilm.compensate": "ignored, with a warning (Kahan summation was removed)",
    "film/specfilm.compensate": "ignored, with a warning (Kahan summation was removed)",
    "spectrum/srgb.unbounded": "allow a colour outside [0, 1] instead of throwing",
    "volume/gridvolume.max_value": "the grid's maximum (the majorant of delta tracking) "
                                   "instead of the computed one",
    "emitter/constant.to_world": "read by Endpoint; a uniform background does not change",
    "shape/shapegroup.to_world": "read by the Shape base class; the group's shapes are "
                                 "placed by its instances' to_world",
    "bsdf/roughplastic.alpha_u": "anisotropic roughness, read by MicrofacetDistribution; "
                                 "roughplastic throws unless alpha_u == alpha_v (then it "
                                 "is alpha)",
    "bsdf/roughplastic.alpha_v": "anisotropic roughness, read by MicrofacetDistribution; "
                                 "roughplastic throws unless alpha_u == alpha_v (then it "
                                 "is alpha)",
}

# The value a `filename` takes in the examples, by plugin; the live check creates these
# files (a small mesh, image, grid, curve...) in a temporary folder, written <tmp>/...
FILENAMES = {
    "shape/obj": "<tmp>/mesh.obj",
    "shape/ply": "<tmp>/mesh.ply",
    "shape/serialized": "<tmp>/mesh.serialized",
    "shape/sdfgrid": "<tmp>/sdf.vol",
    "shape/bsplinecurve": "<tmp>/curve.txt",
    "shape/linearcurve": "<tmp>/curve.txt",
    "shape/ellipsoids": "<tmp>/ellipsoids.ply",
    "shape/ellipsoidsmesh": "<tmp>/ellipsoids.ply",
    "texture/bitmap": "<tmp>/image.exr",
    "emitter/envmap": "<tmp>/env.exr",
    "volume/gridvolume": "<tmp>/grid.vol",
    "bsdf/measured": "<tmp>/missing.bsdf",
    "bsdf/measured_polarized": "<tmp>/missing.pbsdf",
}

# Parameters a plugin cannot be made without (read without a default, or a file), with
# the values the minimal objects of the live check use; the data lists them per plugin.
REQUIRES = {
    "shape/obj": {"filename": "<tmp>/mesh.obj"},
    "shape/ply": {"filename": "<tmp>/mesh.ply"},
    "shape/serialized": {"filename": "<tmp>/mesh.serialized"},
    "shape/sdfgrid": {"filename": "<tmp>/sdf.vol"},
    "shape/bsplinecurve": {"filename": "<tmp>/curve.txt"},
    "shape/linearcurve": {"filename": "<tmp>/curve.txt"},
    "shape/ellipsoids": {"filename": "<tmp>/ellipsoids.ply"},
    "shape/ellipsoidsmesh": {"filename": "<tmp>/ellipsoids.ply"},
    "texture/bitmap": {"filename": "<tmp>/image.exr"},
    "emitter/envmap": {"filename": "<tmp>/env.exr"},
    "volume/gridvolume": {"filename": "<tmp>/grid.vol"},
    "bsdf/measured": {"filename": "<tmp>/missing.bsdf"},
    "bsdf/measured_polarized": {"filename": "<tmp>/missing.pbsdf"},
    "sensor/thinlens": {"aperture_radius": 0.1},
    "integrator/aov": {"aovs": "dd:depth"},
    "texture/mesh_attribute": {"name": "vertex_color"},
    "spectrum/srgb": {"color": [0.5, 0.5, 0.5]},
    "spectrum/uniform": {"value": 0.5},
    "spectrum/blackbody": {"temperature": 5000.0},
    "spectrum/rawconstant": {"value": 0.5},
    "spectrum/irregular": {"wavelengths": "500, 600", "values": "0.5, 0.5"},
    "spectrum/regular": {"values": "0.5, 0.5", "wavelength_min": 500.0, "wavelength_max": 600.0},
    "bsdf/blendbsdf": {"weight": 0.5},
    "bsdf/normalmap": {"normalmap": 0.5},
    "phase/blendphase": {"weight": 0.5},
    "phase/sggx": {"S": None},
    "phase/tabphase": {"values": "0.5, 1.0, 1.5"},
}

# Parameters read through a loop over the properties or under a computed name: not one
# name each, so listed here as patterns, by hand from the source.
DYNAMIC = {
    "film/specfilm": [{
        "pattern": "<any name>", "type": "texture",
        "note": "every <spectrum> or texture property is a sensor response function, its "
                "name the channel's (for (auto &prop : props))"}],
    "shape/ellipsoids": [{
        "pattern": "<any name>", "type": "tensor", "xml": False,
        "note": "every property left unread is a per-ellipsoid attribute tensor "
                "(props.unqueried(), Python only)"}],
    "shape/ellipsoidsmesh": [{
        "pattern": "<any name>", "type": "tensor", "xml": False,
        "note": "every property left unread is a per-ellipsoid attribute tensor "
                "(props.unqueried(), Python only)"}],
    "shape/blender": [{
        "pattern": "vertex_<name>", "type": "pointer", "xml": False,
        "note": "vertex colour layers (Blender's exporter)"}],
}

# Calls that hand `props` to a function whose reads count as the plugin's: name ->
# (file, a regular expression of the definition's start). lookup_ior is handled apart
# (its parameter name is an argument). Any other call f(props...) is reported as a
# warning, to be added here.
HELPERS = {
    "parse_fov": ("src/render/sensor.cpp", r"double parse_fov\(const Properties &props"),
    "MicrofacetDistribution": ("include/mitsuba/render/microfacet.h",
                               r"MicrofacetDistribution\(const Properties &props"),
    # sunsky.h's records read `prefix + "name"`; timed_sunsky makes them without a prefix.
    "LocationRecord": ("include/mitsuba/render/sunsky.h",
                       r"explicit LocationRecord\(const Properties& props"),
    "DateTimeRecord": ("include/mitsuba/render/sunsky.h",
                       r"explicit DateTimeRecord\(const Properties& props"),
}
# Calls f(props) that read nothing more (constructors of the base or of copies, or helpers
# whose reads are in the same file or a scanned local header).
IGNORED_CALLS = {
    "Base", "Texture", "m_props", "EllipsoidsData", "get_flag", "Impl", "create_object",
    "ImplType", "RawConstantTextureImpl", "BitmapTextureImpl", "DistantSensorImpl",
    "VolpathMisIntegratorImpl", "JitObject", "PCG32Sampler", "Properties", "id",
}

# Base classes that read nothing (their constructors only take props.id()).
# The others are found in include/mitsuba/render/*.h and src/render/*.cpp.
BASE_CONSTRUCTOR_FILES = [
    "src/render/shape.cpp", "src/render/mesh.cpp", "src/render/endpoint.cpp",
    "src/render/emitter.cpp", "src/render/sensor.cpp", "src/render/film.cpp",
    "src/render/bsdf.cpp", "src/render/texture.cpp", "src/render/medium.cpp",
    "src/render/integrator.cpp", "src/render/sampler.cpp", "src/render/phase.cpp",
    "src/render/volume.cpp", "src/render/shapegroup.cpp", "src/core/rfilter.cpp",
    "include/mitsuba/render/sunsky.h", "src/render/python/integrator_v.cpp",
]

# The root <scene>: Scene() + the kd-tree (CPU scalar variants) and Embree backends,
# which read the options Scene() marks as read.
SCENE_SOURCES = [
    ("src/render/scene.cpp", r"Scene<Float, Spectrum>::Scene\(const Properties &props\)"),
    ("src/render/kdtree.cpp",
     r"ShapeKDTree<Float, Spectrum>::ShapeKDTree\(const Properties &props\)"),
    ("src/render/scene_embree.inl", r"void EmbreeAccel<Float, Spectrum>::init\(Scene<Float, Spectrum> \*scene,\s*const Properties &props\)"),
]

# Nested objects found by `for (auto &prop : props.objects())` loops: the C++ class a
# child is tried as -> its XML tag (and plugin, when one plugin).
CHILD_CLASSES = {
    "Emitter": "emitter", "Sensor": "sensor", "BSDF": "bsdf", "Medium": "medium",
    "Texture": "texture", "Film": "film", "Sampler": "sampler",
    "ReconstructionFilter": "rfilter", "Shape": "shape", "Mesh": "shape",
    "ShapeGroup_": "shape (shapegroup)", "PhaseFunction": "phase", "Volume": "volume",
    "Integrator": "integrator",
}

# Python plugins (AD integrators): file -> registered name, and their Python bases.
PY_PLUGIN_DIR = "src/python/python/ad/integrators"


# ---------------------------------------------------------------------------------------
# C++ text helpers
# ---------------------------------------------------------------------------------------

def read(root, rel):
    with open(os.path.join(root, rel), encoding="utf-8") as f:
        return f.read()


def strip_comments(text):
    """The text with // and /* */ comments blanked (newlines kept, so offsets and line
    numbers stay), string and character literals untouched."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c == '"' or c == "'":
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == "\\" else 1
            out.append(text[i:j + 1])
            i = j + 1
        elif text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        else:
            out.append(c)
            i += 1
    return "".join(out)


def matching(text, i, open_ch="(", close_ch=")"):
    """Index just past the bracket closing the one at text[i]."""
    depth = 0
    j = i
    while j < len(text):
        c = text[j]
        if c == '"':
            j += 1
            while j < len(text) and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
        elif c == open_ch:
            depth += 1
        elif c == close_ch:
            depth -= 1
            if depth == 0:
                return j + 1
        j += 1
    return len(text)


def body_after(text, start):
    """The {...} block that follows offset `start` (a function's body)."""
    i = text.find("{", start)
    return text[i:matching(text, i, "{", "}")], i


def line_of(text, offset):
    return text.count("\n", 0, offset) + 1


def clean_expr(expr):
    return re.sub(r"\s+", " ", expr).strip()


# props.<accessor><T>("name" ...
READ_RE = re.compile(
    r"\b(?:m_)?props\s*\.\s*(?P<acc>get|get_texture|get_volume|get_emissive_texture|"
    r"get_unbounded_texture|texture|has_property|mark_queried|get_any|try_get|type)\s*"
    r"(?:<(?P<targ>[^;(){}]*?)>)?\s*\(\s*(?:prefix\s*\+\s*)?\"(?P<name>[^\"]+)\"\s*(?P<rest>[,)])")
# A read whose name is not a literal: a loop over the properties, or a computed name.
NONLITERAL_READ_RE = re.compile(
    r"\b(?:m_)?props\s*\.\s*(?:get|get_texture|get_volume|get_emissive_texture|"
    r"get_unbounded_texture|texture|has_property|mark_queried|get_any|try_get|type)\s*"
    r"(?:<[^;(){}]*?>)?\s*\(\s*(?!\s*(?:prefix\s*\+\s*)?\")(?P<arg>[^,)]*)")
# Non-literal reads already accounted for: (plugin, argument) -> where it is described.
NONLITERAL_KNOWN = {
    ("film/specfilm", "prop.name("): "DYNAMIC",
    ("shape/ellipsoids", "key"): "DYNAMIC",
    ("shape/ellipsoidsmesh", "key"): "DYNAMIC",
    ("shape/blender", "s"): "DYNAMIC (and the required names it loops over, read below)",
    ("bsdf/principled", "name"): "get_flag(name, props), called with literal names",
    ("bsdf/principledthin", "name"): "get_flag(name, props), called with literal names",
}
LOOKUP_IOR_RE = re.compile(r"\blookup_ior\(\s*props\s*,\s*\"(?P<name>\w+)\"\s*,\s*(?P<default>[^)]*)\)")
CALL_WITH_PROPS_RE = re.compile(
    r"\b(?P<fn>[A-Za-z_]\w*)\s*(?:<[^;(){}]*>)?\s*(?:\w+\s*)?[({]\s*props\s*[,)}]")


def extract_reads(text, origin):
    """Every literal-named property read in `text` (comments stripped)."""
    reads = []
    for m in READ_RE.finditer(text):
        default = None
        if m.group("rest") == ",":
            open_paren = text.rfind("(", 0, m.end())
            close = matching(text, open_paren)
            default = clean_expr(text[m.end():close - 1])
        reads.append({
            "name": m.group("name"), "acc": m.group("acc"),
            "targ": clean_expr(m.group("targ") or ""), "default": default,
            "origin": origin, "offset": m.start(), "text": text,
        })
    for m in LOOKUP_IOR_RE.finditer(text):
        reads.append({
            "name": m.group("name"), "acc": "lookup_ior", "targ": "",
            "default": clean_expr(m.group("default")), "origin": origin,
            "offset": m.start(), "text": text,
        })
    return reads


def compared_values(text, read):
    """The string literals the variable holding a string read is compared against
    (`var == "x"`, `var != "x"`), and whether it is lower-cased first."""
    # The statement holding the read: from the previous ';', '{' or '}' to the next ';'.
    start = max(text.rfind(";", 0, read["offset"]), text.rfind("{", 0, read["offset"]),
                text.rfind("}", 0, read["offset"])) + 1
    end = text.find(";", read["offset"])
    stmt = text[start:end]
    m = re.search(r"(\w+)\s*=\s*[^=]", stmt)
    lower = "to_lower" in stmt
    if not m:
        return [], lower
    var = m.group(1)
    values = re.findall(r"\b%s\s*[!=]=\s*\"([^\"]*)\"" % re.escape(var), text)
    values += re.findall(r"\"([^\"]*)\"\s*[!=]=\s*%s\b" % re.escape(var), text)
    return values, lower


# ---------------------------------------------------------------------------------------
# Documentation (the `.. pluginparameters::` tables of the /**! ... */ docstrings)
# ---------------------------------------------------------------------------------------

DOC_TYPE_RE = re.compile(r"\|(\w+)\||:paramtype:`(\w+)`|``(\w+)``")


def rst_text(s):
    s = re.sub(r":(?:monosp|paramtype|math|ref|num):`([^`<]*?)(?:\s*<[^>]*>)?`", r"\1", s)
    s = re.sub(r"\|(true|false)\|", r"\1", s)
    s = re.sub(r"\|(\w+)\|", r"\1", s)
    s = s.replace("``", "").replace("\\\\", "\\")
    return re.sub(r"\s+", " ", s).strip()


def first_sentence(s):
    m = re.match(r"(.+?[.!?])(\s|$)", s)
    return m.group(1) if m else s


def doc_tables(raw_text):
    """name -> {types, doc, monosp, internal, exposed} from the plugin's docstring tables."""
    docs = {}
    for block in re.findall(r"/\*\*!(.*?)\*/", raw_text, re.S):
        docs.update(parse_doc_block(block))
    # Python plugins: the class docstring.
    for block in re.findall(r'"""(.*?)"""', raw_text, re.S):
        if "pluginparameters" in block:
            docs.update(parse_doc_block(block))
    return docs


def parse_doc_block(block):
    docs = {}
    for table in re.split(r"\.\. pluginparameters::", block)[1:]:
        # The table ends at the first line that is not indented.
        lines = []
        for line in table.split("\n")[1:]:
            if line.strip() and not line.startswith(" "):
                break
            lines.append(line)
        rows, row = [], None
        for line in lines:
            m = re.match(r"\s*\*\s+-\s+(.*)", line)
            if m:
                row = [m.group(1)]
                rows.append(row)
                continue
            m = re.match(r"\s+-\s+(.*)", line)
            if m and row is not None:
                row.append(m.group(1))
            elif row is not None and line.strip() and not line.strip().startswith(":"):
                row[-1] += " " + line.strip()
        for row in rows:
            names = [n.strip() for n in re.sub(r"\(.*?\)", "", row[0]).split(",")]
            type_cell = row[1] if len(row) > 1 else ""
            desc = row[2] if len(row) > 2 else ""
            flags = row[3] if len(row) > 3 else ""
            types = [t for g in DOC_TYPE_RE.findall(type_cell) for t in g if t]
            internal = "``" in type_cell and "|" not in type_cell
            for name in names:
                name = rst_text(name)
                if not re.fullmatch(r"[A-Za-z_][\w]*", name):
                    continue
                docs[name] = {
                    "types": types,
                    "doc": first_sentence(rst_text(desc)),
                    "monosp": re.findall(r":monosp:`([^`]+)`", desc),
                    "internal": internal,
                    "exposed": "exposed" in flags,
                }
    return docs


# ---------------------------------------------------------------------------------------
# Sources: plugins, base classes, helpers
# ---------------------------------------------------------------------------------------

def plugin_files(root):
    """(kind, name, relative path) of every C++ plugin, from the add_plugin() lines."""
    plugins = []
    for folder, kind in KIND_OF_FOLDER.items():
        cmake = read(root, "src/%s/CMakeLists.txt" % folder)
        for name, source in re.findall(r"add_plugin\(\s*(\w+)\s+(\w+\.cpp)\s*\)", cmake):
            plugins.append((kind, name, "src/%s/%s" % (folder, source)))
    return plugins


def class_parents(root):
    """C++ class -> its parent, from the class declarations of the render headers and of
    every plugin source."""
    parents = {}
    files = [os.path.join("include/mitsuba/render", f)
             for f in os.listdir(os.path.join(root, "include/mitsuba/render")) if f.endswith(".h")]
    files.append("include/mitsuba/core/rfilter.h")
    files.append("src/render/python/integrator_v.cpp")
    for rel in files:
        text = strip_comments(read(root, rel))
        for m in re.finditer(
                r"class\s+(?:MI_EXPORT_LIB\s+)?(\w+)(?:\s+final)?\s*:\s*public\s+(\w+)\s*<", text):
            parents.setdefault(m.group(1), m.group(2))
    return parents


def base_constructor_reads(root):
    """Base class -> (reads of its constructor, parent it chains to or None, children)."""
    out = {}
    for rel in BASE_CONSTRUCTOR_FILES:
        text = strip_comments(read(root, rel))
        for m in re.finditer(
                r"(?:MI_VARIANT\s+)?(?:(\w+)<Float, Spectrum>::)?(\w+)\s*\(const Properties\s*&\s*props(?:, ObjectType type)?\)\s*(:[^{;]*)?\{",
                text):
            cls = m.group(2)
            if m.group(1) and m.group(1) != cls:
                continue
            if rel.endswith(".h") or rel.endswith("integrator_v.cpp"):
                if cls not in ("BaseSunskyEmitter", "CppADIntegrator"):
                    continue
            body, _ = body_after(text, m.end() - 1)
            init = m.group(3) or ""
            chains = bool(re.search(r"\b(Base|\w+<Float, Spectrum>)\(\s*props", init))
            entry = out.setdefault(cls, {"reads": [], "chains": chains, "children": []})
            entry["chains"] = entry["chains"] or chains
            entry["reads"] += extract_reads(body, cls)
            entry["children"] += children_of(body)
            entry["file"] = rel
    return out


def helper_reads(root):
    out = {}
    for name, (rel, start) in HELPERS.items():
        text = strip_comments(read(root, rel))
        m = re.search(start, text)
        # From the signature on: the records read in their initialiser lists.
        body, at = body_after(text, m.end())
        out[name] = extract_reads(text[m.start():at + len(body)], name)
    return out


def children_of(text):
    """Nested objects a `for (auto &prop : props.objects())` loop takes: (tag, name)."""
    found = []
    for m in re.finditer(r"for\s*\(\s*auto\s*&\s*prop\s*:\s*props\.objects\(\)\s*\)", text):
        body, _ = body_after(text, m.end())
        # Each `try_get<X>()` branch, with the names it compares prop.name() against.
        tries = list(re.finditer(r"(?:try_get|dynamic_cast)<\s*(\w+)\s*\*?\s*>", body))
        for i, t in enumerate(tries):
            end = tries[i + 1].start() if i + 1 < len(tries) else len(body)
            names = re.findall(r"prop\.name\(\)\s*==\s*\"(\w+)\"", body[t.end():end])
            found.append((t.group(1), names))
        if not tries:
            found.append(("Object", []))
    return found


def local_headers(root, rel, text):
    folder = os.path.dirname(rel)
    headers = []
    for inc in re.findall(r'#include\s+"([\w.]+\.h)"', text):
        path = os.path.join(folder, inc)
        if os.path.exists(os.path.join(root, path)):
            headers.append(path)
    return headers


# ---------------------------------------------------------------------------------------
# Building the entries
# ---------------------------------------------------------------------------------------

def kind_of_read(read):
    acc, targ = read["acc"], read["targ"]
    if acc in TEXTURE_ACCESSORS:
        return "texture", TEXTURE_ACCESSORS[acc]
    if acc == "get_volume":
        return "volume", None
    if acc == "lookup_ior":
        return "ior", None
    if acc in ("get", "get_any", "try_get"):
        if targ in CPP_TYPES:
            return CPP_TYPES[targ], None
        if not targ and read["default"] is not None:
            return literal_kind(read["default"]), None
        if targ:
            raise SystemExit("unknown C++ type %r for %s (%s): add it to CPP_TYPES"
                             % (targ, read["name"], read["origin"]))
    return None, None


def literal_kind(expr):
    if expr in ("true", "false"):
        return "boolean"
    if re.fullmatch(r"-?\d+", expr):
        return "integer"
    if re.fullmatch(r"-?[\d.]+(e-?\d+)?f?", expr):
        return "float"
    if expr.startswith('"'):
        return "string"
    return None


def literal_value(expr, kind):
    """The default as a JSON value, when it is a plain literal of the kind."""
    if expr is None:
        return None
    expr = expr.strip()
    if expr in ("MI_CIE_MIN", "MI_CIE_MAX"):
        # include/mitsuba/core/spectrum.h: the CIE 1931 tables' range, 360-830 nm.
        return 360.0 if expr == "MI_CIE_MIN" else 830.0
    if re.fullmatch(r"\((?:uint32_t|size_t)\)\s*-1", expr):
        return None  # "unset" (the largest unsigned value): no example from it
    m = re.fullmatch(r"\((?:float|double|int)\)\s*(.*)", expr)
    if m:
        expr = m.group(1)
    if kind in ("point", "vector"):
        m = re.fullmatch(r"Scalar(?:Point|Vector)3f\((.*)\)|(-?[\d.]+)f?", expr)
        if m:
            parts = [x.strip().rstrip("f") for x in (m.group(1) or m.group(2)).split(",")]
            try:
                v = [float(x) for x in parts]
            except ValueError:
                return None
            return v * 3 if len(v) == 1 else v
    try:
        if kind == "boolean" and expr in ("true", "false"):
            return expr == "true"
        if kind == "integer" and re.fullmatch(r"-?\d+", expr):
            return int(expr)
        if kind in ("float", "texture", "volume", "ior") and re.fullmatch(r"-?[\d.]+(e-?\d+)?f?", expr):
            return float(expr.rstrip("f"))
        if kind in ("string", "ior") and re.fullmatch(r'"[^"]*"', expr):
            return expr[1:-1]
    except ValueError:
        return None
    return None


def default_example(kind, role):
    return {
        "boolean": False, "integer": 1, "float": 0.5, "string": "",
        "rgb": [0.5, 0.5, 0.5], "texture": 0.5 if role != "emission" else 1.0,
        "volume": 0.5, "point": [0.0, 0.0, 0.0], "vector": [0.0, 0.0, 1.0],
        "transform": "identity", "spectrum": "0.5", "ior": 1.5,
    }.get(kind)


def merge_reads(reads, own_doc):
    """One entry per name from all reads of it (the plugin's, its bases', its helpers')."""
    by_name = {}
    for r in reads:
        by_name.setdefault(r["name"], []).append(r)
    params = {}
    for name, rs in by_name.items():
        kinds = []
        role = None
        default = None
        accessors = []
        origins = []
        values, lower = [], False
        for r in rs:
            k, ro = kind_of_read(r)
            if k and k not in kinds:
                kinds.append(k)
            role = role or ro
            if r["default"] is not None and default is None:
                default = r["default"]
            if r["acc"] not in accessors:
                accessors.append(r["acc"])
            if r["origin"] not in origins:
                origins.append(r["origin"])
            if k == "string" or r["acc"] == "lookup_ior":
                v, lo = compared_values(r["text"], r)
                values += [x for x in v if x not in values]
                values = list(dict.fromkeys(values))
                lower = lower or lo
        # get<float> with a lookup_ior fallback is one "ior" parameter.
        if "ior" in kinds:
            kinds = ["ior"]
        entry = {
            "name": name,
            "type": kinds[0] if kinds else None,
            "read_by": origins,
            "accessors": sorted(accessors),
        }
        if len(kinds) > 1:
            entry["also"] = kinds[1:]
        if role:
            entry["role"] = role
        if default is not None:
            entry["default"] = default
        if values:
            entry["values"] = values
        if lower:
            entry["case_insensitive"] = True
        d = own_doc.get(name)
        if d:
            entry["doc"] = d["doc"]
            if entry.get("values") and d["monosp"]:
                extra = [v for v in d["monosp"] if re.fullmatch(r"[\w\-]+", v)]
                entry["doc_values"] = extra
        params[name] = entry
    return params


# Names the extraction finds that are not parameters (see CORRECTIONS' "drop").
DROPPED = {}


def apply_corrections(key, params, ior_names, conductor_materials, aov_types):
    fixes = CORRECTIONS.get(key, {})
    for name, fix in fixes.items():
        if name == "*":  # every parameter the plugin itself reads
            for p in params.values():
                if p["read_by"] == [key.split("/")[1]]:
                    p.update(fix)
            continue
        if name not in params:
            raise SystemExit("correction for %s.%s, which is not read" % (key, name))
        p = params[name]
        fix = dict(fix)
        if "drop" in fix:
            dropped = params.pop(name)
            DROPPED.setdefault(key, []).append({"name": name, "why": fix["drop"],
                                                "accessors": dropped["accessors"]})
            continue
        src = fix.pop("values_from", None)
        if src == "conductor_materials":
            p["values"] = ["none"] + conductor_materials
        elif src == "aov_types":
            p["values"] = aov_types
        p.update(fix)
    for p in params.values():
        if p["type"] == "ior":
            p["values"] = ior_names
            # Checked with the other index set apart (some plugins refuse equal ones).
            other = {"int_ior": "ext_ior", "ext_ior": "int_ior"}.get(p["name"])
            if other in params:
                p["values_with"] = {other: 1.234}
        if p["type"] is None:
            raise SystemExit("no type for %s.%s: add a correction" % (key, p["name"]))


def add_semantics(key, params):
    """`semantics` (SEMANTICS) for the parameters the plugin's documentation leaves out."""
    for p in params.values():
        specific = SEMANTICS.get("%s.%s" % (key, p["name"]))
        if specific:
            p["semantics"] = specific
            continue
        if "doc" in p:
            continue
        for cls in p["read_by"]:
            if "%s.%s" % (cls, p["name"]) in SEMANTICS:
                p["semantics"] = SEMANTICS["%s.%s" % (cls, p["name"])]
                break


def finish_examples(key, params):
    for p in params.values():
        if "example" in p or p.get("xml") is False:
            continue
        name, kind = p["name"], p["type"]
        if name == "filename":
            p["example"] = FILENAMES.get(key, "<tmp>/missing")
            continue
        if kind == "object":
            continue
        v = literal_value(p.get("default"), kind)
        if kind == "string" and p.get("values"):
            if v is None or v not in p["values"]:
                v = p["values"][0]
        if v is None:
            v = default_example(kind, p.get("role"))
        p["example"] = v


def python_plugins(root):
    """The AD integrators written in Python: their props.get('x', default) reads, through
    their Python base classes down to the C++ SamplingIntegrator."""
    folder = os.path.join(root, PY_PLUGIN_DIR)
    classes = {}
    registered = []
    sources = {}
    for f in sorted(os.listdir(folder)):
        if not f.endswith(".py"):
            continue
        rel = os.path.join(PY_PLUGIN_DIR, f)
        text = read(root, rel)
        sources[rel] = text
        for m in re.finditer(r"^class (\w+)\(([\w.]+)\):", text, re.M):
            start = m.end()
            nxt = re.search(r"^class ", text[start:], re.M)
            body = text[start:start + nxt.start()] if nxt else text[start:]
            classes[m.group(1)] = (m.group(2).split(".")[-1], body, rel)
        for m in re.finditer(r"register_integrator\(\"(\w+)\",\s*lambda props:\s*(\w+)\(props\)\)", text):
            registered.append((m.group(1), m.group(2), rel))
    out = []
    for name, cls, rel in registered:
        reads, chain = [], []
        c = cls
        while c in classes:
            parent, body, crel = classes[c]
            init = re.search(r"def __init__\(self, props\):(.*?)(?=\n    def |\Z)", body, re.S)
            if init:
                for m in re.finditer(
                        r"props\.get\(\s*['\"](\w+)['\"]\s*(?:,\s*([^)]*))?\)", init.group(1)):
                    reads.append(py_read(m, c, init.group(1)))
                for m in re.finditer(r"props\.has_property\(\s*['\"](\w+)['\"]\s*\)", init.group(1)):
                    reads.append({"name": m.group(1), "acc": "has_property", "targ": "",
                                  "default": None, "origin": c, "py_values": []})
            chain.append(c)
            c = parent
        # CppADIntegrator is the C++ SamplingIntegrator's trampoline.
        chain += ["SamplingIntegrator", "Integrator"]
        out.append((name, rel, chain, reads, sources[rel]))
    return out


def py_read(m, cls, body):
    name, default = m.group(1), (m.group(2) or "").strip() or None
    if default is not None and re.fullmatch(r"'[^']*'", default):
        default = '"%s"' % default[1:-1]
    values = []
    var = re.search(r"(self\.\w+|\w+)\s*=\s*(?:int\()?\s*props\.get\(\s*['\"]%s['\"]" % name, body)
    if var:
        lst = re.search(r"%s not in \[([^\]]*)\]" % re.escape(var.group(1)), body)
        if lst:
            values = re.findall(r"['\"](\w+)['\"]", lst.group(1))
    kind = None
    if default is not None:
        if default in ("True", "False"):
            kind = "boolean"
            default = default.lower()
        elif re.fullmatch(r"-?\d+", default):
            kind = "integer"
        elif re.fullmatch(r"-?[\d.]+", default):
            kind = "float"
        elif re.fullmatch(r"\".*\"", default):
            kind = "string"
        elif default == "None":
            default = None
    return {"name": name, "acc": "get", "targ": "", "default": default, "origin": cls,
            "py_kind": kind, "py_values": values}


# ---------------------------------------------------------------------------------------
# The whole extraction
# ---------------------------------------------------------------------------------------

def extract(root):
    version = read(root, "include/mitsuba/mitsuba.h")
    found = tuple(re.search(r"#define MI_VERSION_%s (\d+)" % k, version).group(1)
                  for k in ("MAJOR", "MINOR", "PATCH"))
    if ".".join(found) != MITSUBA_VERSION:
        raise SystemExit("%s is Mitsuba %s, not %s" % (root, ".".join(found), MITSUBA_VERSION))

    parents = class_parents(root)
    bases = base_constructor_reads(root)
    helpers = helper_reads(root)
    warnings = []

    ior_text = strip_comments(read(root, "include/mitsuba/render/ior.h"))
    ior_names = re.findall(r"\{\s*\"([^\"]+)\",\s*[\d.]+f?\s*\}", ior_text)
    conductor_doc = read(root, "src/bsdfs/conductor.cpp")
    table = conductor_doc[conductor_doc.find(".. figtable::"):]
    table = table[:table.find("*/")]
    conductor_materials = []
    for v in re.findall(r":paramtype:`([^`]+)`", table):
        if v not in conductor_materials:
            conductor_materials.append(v)
    aov_types = re.findall(r"item\[1\]\s*==\s*\"(\w+)\"", read(root, "src/integrators/aov.cpp"))

    def chain_reads(cls, seen):
        """Reads and children of base class `cls` and its ancestors."""
        reads, children, names = [], [], []
        while cls and cls not in seen:
            seen.add(cls)
            names.append(cls)
            b = bases.get(cls)
            if b:
                reads += b["reads"]
                children += [(c, n, cls) for c, n in b["children"]]
                if not b["chains"]:
                    break
            cls = parents.get(cls)
            if cls == "JitObject":
                break
        return reads, children, names

    plugins = []
    for kind, name, rel in plugin_files(root):
        key = "%s/%s" % (kind, name)
        raw = read(root, rel)
        text = strip_comments(raw)
        texts = [(text, name)]
        for h in local_headers(root, rel, raw):
            texts.append((strip_comments(read(root, h)), name))
        reads, children = [], []
        for t, origin in texts:
            reads += extract_reads(t, origin)
            children += [(c, n, name) for c, n in children_of(t)]
        # Constructors taking props: which base do they chain to?
        base_classes = []
        for m in re.finditer(r"\b(\w+)\s*\(const Properties\s*&\s*props\)\s*(:\s*([^{]*))?\{", text):
            cls = m.group(1)
            decl = re.search(r"class\s+%s(?:\s+final)?\s*:\s*public\s+(\w+)\s*<" % cls, text)
            if not decl:
                continue
            init = m.group(3) or ""
            if re.search(r"\b(Base|%s)\(\s*props" % decl.group(1), init):
                if decl.group(1) not in base_classes:
                    base_classes.append(decl.group(1))
        base_names = []
        for b in base_classes:
            r, c, names = chain_reads(b, set())
            reads += r
            children += c
            base_names += [n for n in names if n not in base_names]
        # Helpers handed the properties.
        for m in CALL_WITH_PROPS_RE.finditer(text):
            fn = m.group("fn")
            if fn in HELPERS:
                reads += helpers[fn]
            elif fn not in IGNORED_CALLS and fn != "lookup_ior" and not fn.endswith("Impl"):
                warnings.append("%s: %s(props) at line %d is not a known helper"
                                % (key, fn, line_of(text, m.start())))
        for t, _ in texts:
            for m in NONLITERAL_READ_RE.finditer(t):
                arg = m.group("arg").strip()
                if (key, arg) not in NONLITERAL_KNOWN:
                    warnings.append("%s: a read of a computed name (%s) at line %d: describe it "
                                    "in DYNAMIC and NONLITERAL_KNOWN" % (key, arg, line_of(t, m.start())))
        docs = doc_tables(raw)
        params = merge_reads(reads, docs)
        plugins.append(make_plugin(kind, name, rel, base_names, params, children, docs,
                                   ior_names, conductor_materials, aov_types, warnings))

    # The root <scene>.
    reads = []
    for rel, start in SCENE_SOURCES:
        text = strip_comments(read(root, rel))
        m = re.search(start, text)
        body, at = body_after(text, m.end())
        # From the signature on: ShapeKDTree reads three in its initialiser list.
        reads += extract_reads(text[m.start():at + len(body)], rel.split("/")[-1].split(".")[0])
    params = merge_reads(reads, {})
    plugins.append(make_plugin("scene", "scene", "src/render/scene.cpp", ["Scene"], params,
                               [("Object", [], "Scene")], {}, ior_names,
                               conductor_materials, aov_types, warnings))

    # Python plugins.
    for name, rel, chain, preads, raw in python_plugins(root):
        key = "integrator/%s" % name
        reads = []
        for b in ("SamplingIntegrator",):
            r, _, _ = chain_reads(b, set())
            reads += r
        params = merge_reads(reads, {})
        docs = doc_tables(raw)
        for r in preads:
            entry = params.get(r["name"], {"name": r["name"], "read_by": [], "accessors": []})
            entry["read_by"] = [r["origin"]] + [o for o in entry["read_by"] if o != r["origin"]]
            entry["accessors"] = sorted(set(entry["accessors"]) | {r["acc"]})
            if r.get("py_kind"):
                entry["type"] = r["py_kind"]
            elif "type" not in entry:
                entry["type"] = "integer"  # sppc/sppp/sppi: sample counts, default None
            if r["default"] is not None:
                entry["default"] = r["default"]
            if r.get("py_values"):
                entry["values"] = r["py_values"]
            if r["name"] in docs:
                entry["doc"] = docs[r["name"]]["doc"]
            params[r["name"]] = entry
        plugins.append(make_plugin("integrator", name, rel, chain, params, [], docs,
                                   ior_names, conductor_materials, aov_types, warnings))
    return plugins, warnings


def make_plugin(kind, name, rel, base_names, params, children, docs, ior_names,
                conductor_materials, aov_types, warnings):
    key = "%s/%s" % (kind, name)
    apply_corrections(key, params, ior_names, conductor_materials, aov_types)
    add_semantics(key, params)
    finish_examples(key, params)
    for p in params.values():
        if p["type"] in ("tensor", "pointer", "bitmap"):
            p["xml"] = False
        p.setdefault("xml", True)
    documented = sorted(n for n, d in docs.items()
                        if n not in params and not d["internal"] and n != "Nested")
    kids = []
    for cls, names, origin in children:
        tag = CHILD_CLASSES.get(cls, "any object" if cls in ("Object", "Base") else cls)
        if cls == "Base":
            tag = "texture" if kind == "spectrum" else kind
        for n in names or [None]:
            entry = {"object": tag, "read_by": origin}
            if n:
                entry["names"] = [n]
            if entry not in kids:
                kids.append(entry)
    plugin = {
        "kind": kind,
        "name": name,
        "source": rel,
        "bases": base_names,
        "penumbra": name in PENUMBRA_SUPPORTS.get(kind, []),
        "parameters": [params[n] for n in sorted(params)],
        "children": sorted(kids, key=lambda k: (k["object"], k.get("names", []))),
    }
    if key in REQUIRES:
        plugin["requires"] = {n: (v if v is not None else params[n].get("example"))
                              for n, v in REQUIRES[key].items()}
    if key in DYNAMIC:
        plugin["dynamic"] = DYNAMIC[key]
    if documented:
        plugin["documented_not_read"] = documented
    if key in DROPPED:
        plugin["not_parameters"] = DROPPED[key]
    return plugin


# ---------------------------------------------------------------------------------------
# Live check and output
# ---------------------------------------------------------------------------------------

def live_check(python, plugins):
    script = os.path.join(HERE, "live_check.py")
    proc = subprocess.run([python, script], input=json.dumps(plugins), capture_output=True,
                          text=True, cwd=REPO)
    if proc.returncode != 0:
        sys.stderr.write(proc.stderr)
        raise SystemExit("live_check.py failed")
    return json.loads(proc.stdout)


def dumps(out):
    """JSON with one line per parameter and per child, for readable diffs."""
    one = lambda v: json.dumps(v, ensure_ascii=False, sort_keys=False)
    lines = ["{"]
    top = [k for k in out if k != "plugins"]
    for k in top:
        lines.append("  %s: %s," % (one(k), one(out[k])))
    lines.append('  "plugins": [')
    for i, p in enumerate(out["plugins"]):
        lines.append("    {")
        keys = list(p)
        for j, k in enumerate(keys):
            comma = "," if j + 1 < len(keys) else ""
            if k in ("parameters", "children", "dynamic", "not_parameters") and p[k]:
                lines.append("      %s: [" % one(k))
                for n, q in enumerate(p[k]):
                    lines.append("        %s%s" % (one(q), "," if n + 1 < len(p[k]) else ""))
                lines.append("      ]%s" % comma)
            else:
                lines.append("      %s: %s%s" % (one(k), one(p[k]), comma))
        lines.append("    }%s" % ("," if i + 1 < len(out["plugins"]) else ""))
    lines.append("  ]")
    lines.append("}")
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("mitsuba_src", help="Mitsuba 3.9.1 source tree (with src/ and include/)")
    ap.add_argument("--check-with", metavar="PYTHON",
                    help="an interpreter that imports mitsuba 3.9.1, to check the list live")
    ap.add_argument("-o", "--output", default=os.path.join(REPO, "tests/data/mitsuba_params.json"))
    args = ap.parse_args()

    plugins, warnings = extract(args.mitsuba_src)
    for w in warnings:
        print("warning:", w, file=sys.stderr)
    for p in plugins:
        for q in p["parameters"]:
            q.pop("text", None)
    plugins.sort(key=lambda p: (p["kind"], p["name"]))
    checked = None
    if args.check_with:
        checked = live_check(args.check_with, plugins)
        for p in plugins:
            res = checked["plugins"][p["kind"] + "/" + p["name"]]
            p["mitsuba"] = res["plugin"]
            for c in p["children"]:
                ident = c["object"] + (":" + c["names"][0] if c.get("names") else "")
                r = res.get("children", {}).get(ident)
                if r:
                    c["mitsuba"] = r["status"]
                    if "why" in r:
                        c["mitsuba_why"] = r["why"]
                    if "xml" in r:
                        c["example"] = r["xml"]
            if "documented_not_read" in res:
                # Documented names (mostly mi.traverse() parameters): should be unreferenced.
                p["documented_not_read"] = dict(sorted(res["documented_not_read"].items()))
            for q in p["parameters"]:
                r = res["parameters"].get(q["name"])
                if r:
                    q["mitsuba"] = r["status"]
                    if "variant" in r:
                        q["mitsuba_variant"] = r["variant"]
                    if "why" in r:
                        q["mitsuba_why"] = r["why"]
                    if "values" in r:
                        q["values"] = r["values"]["accepted"]
                        if r["values"]["refused"]:
                            q["refused_values"] = r["values"]["refused"]
                q.pop("doc_values", None)
    # The command as run (the source tree's path as given: see README.md for the tree).
    command = "python3 validation/mitsuba-params/generate.py %s" % args.mitsuba_src
    if args.check_with:
        command += " --check-with %s" % args.check_with
    out = {
        "about": "The parameters Mitsuba %s reads, per plugin, extracted from its sources "
                 "and checked against the live Mitsuba. Made by "
                 "validation/mitsuba-params/generate.py; see its README.md." % MITSUBA_VERSION,
        "mitsuba_version": MITSUBA_VERSION,
        "mitsuba_source": {"repository": "https://github.com/mitsuba-renderer/mitsuba3",
                           "tag": MITSUBA_TAG, "commit": MITSUBA_COMMIT},
        "command": command,
        "checked_live": checked["about"] if checked else None,
        "types": TYPE_DOC,
        "attributes": {
            "id": "every object's XML attribute id=\"..\" (props.id(), read by JitObject's "
                  "constructor); not a property: <string name=\"id\"> is unreferenced. "
                  "`mitsuba.id` per plugin: the minimal object loads with an id."},
        "plugins": plugins,
    }
    with open(args.output, "w", encoding="utf-8") as f:
        f.write(dumps(out))
    n = sum(len(p["parameters"]) for p in plugins)
    print("%d plugins, %d parameters -> %s" % (len(plugins), n, args.output), file=sys.stderr)


if __name__ == "__main__":
    main()
