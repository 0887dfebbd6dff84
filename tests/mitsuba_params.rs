//! Mitsuba's parameter lists against penumbra's (issue 39): for every plugin penumbra
//! supports, every parameter Mitsuba 3.9.1 reads is accepted.
//!
//! The lists are tests/data/mitsuba_params.json, extracted once from Mitsuba 3.9.1's sources
//! (tag v3.9.1) and checked against the live Mitsuba by validation/mitsuba-params/generate.py
//! (how, and how to regenerate: validation/mitsuba-params/README.md). Each parameter is set
//! alone, to a value Mitsuba accepts (the data's `example`, with the parameters it needs
//! beside it, `with`), in a minimal valid scene holding its plugin, and the scene's
//! description must be made without an error. A parameter penumbra does not read is
//! refused as an "unknown parameter"; any other error is reported too, as it would hide
//! whether the name is known (a value penumbra refuses, a plugin it refuses).
//!
//! Not checked: parameters with no XML form (Python dictionaries' tensors and bitmaps) and
//! those Mitsuba itself refuses (an area light's `to_world`).

use penumbra::scene::description::from_xml;
use penumbra::scene::xml::load_str;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;

const DATA: &str = include_str!("data/mitsuba_params.json");

/// The path the scenes pretend to come from (never read; no file is opened).
const FILE: &str = "/virtual/dir/scene.xml";
/// Where the data's example files (`<tmp>/mesh.obj`...) are said to be.
const FILES: &str = "/virtual/files";

/// A sensor for the scenes whose plugin is elsewhere.
const SENSOR: &str = r#"<sensor type="perspective"><float name="fov" value="45"/>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/>
    <rfilter type="box"/></film></sensor>"#;

/// Marks where a plugin's element goes in its scene.
const HERE: &str = "@ELEMENT@";

fn data() -> Value {
    serde_json::from_str(DATA).expect("tests/data/mitsuba_params.json is JSON")
}

fn parse(xml: &str) -> Result<(), String> {
    let doc = load_str(xml, Path::new(FILE), &[]).map_err(|e| e.to_string())?;
    from_xml(&doc).map(|_| ()).map_err(|e| e.to_string())
}

fn s<'a>(v: &'a Value, key: &str) -> &'a str {
    v[key]
        .as_str()
        .unwrap_or_else(|| panic!("no string {key} in {v}"))
}

// ---------------------------------------------------------------------------------------
// Values
// ---------------------------------------------------------------------------------------

fn number(v: &Value) -> String {
    let x = v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"));
    format!("{x:?}")
}

/// Nested objects standing for an object-valued parameter (the data's `example_object`).
fn object_xml(plugin: &str, name: &str) -> String {
    match plugin {
        "constvolume" => format!(r#"<volume type="constvolume" name="{name}"/>"#),
        "bitmap" => format!(
            r#"<texture type="bitmap" name="{name}"><string name="filename" value="{FILES}/image.exr"/></texture>"#
        ),
        other => panic!("no XML for an example object of plugin {other}"),
    }
}

/// The XML property giving `name` (a parameter of kind `ty`, see the data's `types`) the
/// value `v`.
fn value_xml(name: &str, ty: &str, v: &Value) -> String {
    match (ty, v) {
        ("boolean", Value::Bool(b)) => format!(r#"<boolean name="{name}" value="{b}"/>"#),
        ("integer", Value::Number(n)) => format!(r#"<integer name="{name}" value="{n}"/>"#),
        ("float" | "texture" | "volume" | "ior", Value::Number(_)) => {
            format!(r#"<float name="{name}" value="{}"/>"#, number(v))
        }
        ("string" | "ior", Value::String(text)) => format!(
            r#"<string name="{name}" value="{}"/>"#,
            text.replace("<tmp>", FILES)
        ),
        ("rgb" | "texture" | "volume", Value::Array(c)) => format!(
            r#"<rgb name="{name}" value="{}"/>"#,
            c.iter().map(number).collect::<Vec<_>>().join(", ")
        ),
        ("point" | "vector", Value::Array(c)) => format!(
            r#"<{ty} name="{name}" x="{}" y="{}" z="{}"/>"#,
            number(&c[0]),
            number(&c[1]),
            number(&c[2])
        ),
        ("transform", _) => {
            format!(r#"<transform name="{name}"><translate x="0" y="0" z="0"/></transform>"#)
        }
        ("spectrum", Value::String(text)) => {
            format!(r#"<spectrum name="{name}" value="{text}"/>"#)
        }
        _ => panic!("no XML for parameter {name} of kind {ty} with value {v}"),
    }
}

/// The XML setting parameter `p` (an entry of the data) to `v`.
fn param_xml(p: &Value, v: &Value) -> String {
    let name = s(p, "name");
    match p["example_object"].as_str() {
        Some(plugin) => object_xml(plugin, name),
        None => value_xml(name, s(p, "type"), v),
    }
}

// ---------------------------------------------------------------------------------------
// Minimal scenes
// ---------------------------------------------------------------------------------------

/// How one plugin goes into a minimal valid scene.
struct Context {
    /// The scene, with [`HERE`] where the plugin's element goes.
    scene: String,
    /// Attributes of the element besides `type` (` name=".."`, ` id=".."`).
    attrs: &'static str,
    /// Nested objects the element needs, after its properties.
    children: &'static str,
    /// Properties penumbra needs that Mitsuba does not (name, XML), besides the data's
    /// `requires`.
    extra: Vec<(&'static str, String)>,
}

fn in_scene(body: &str) -> String {
    format!("<scene version=\"3.0.0\">\n{body}\n</scene>\n")
}

/// The minimal scene of every plugin penumbra supports; `None` for the others.
fn context(kind: &str, name: &str) -> Option<Context> {
    let with_sensor = |body: &str| in_scene(&format!("{SENSOR}\n{body}"));
    let medium_scene = |medium: &str| {
        in_scene(&format!(
            "<integrator type=\"volpath\"/>\n{SENSOR}\n<shape type=\"sphere\"><bsdf type=\"null\"/>{medium}</shape>"
        ))
    };
    let mut c = Context {
        scene: String::new(),
        attrs: "",
        children: "",
        extra: Vec::new(),
    };
    c.scene = match kind {
        "scene" => HERE.to_string(),
        "integrator" => {
            c.children = match name {
                "moment" => r#"<integrator type="path"/>"#,
                _ => "",
            };
            with_sensor(HERE)
        }
        "sensor" => {
            c.children = r#"<film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/></film>"#;
            in_scene(HERE)
        }
        "film" => in_scene(&format!(
            r#"<sensor type="perspective"><float name="fov" value="45"/>{HERE}</sensor>"#
        )),
        "rfilter" => in_scene(&format!(
            r#"<sensor type="perspective"><float name="fov" value="45"/><film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/>{HERE}</film></sensor>"#
        )),
        "sampler" => in_scene(&format!(
            r#"<sensor type="perspective"><float name="fov" value="45"/>{HERE}<film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/></film></sensor>"#
        )),
        "bsdf" => {
            c.children = match name {
                "twosided" | "mask" | "normalmap" => r#"<bsdf type="diffuse"/>"#,
                "blendbsdf" => r#"<bsdf type="diffuse"/><bsdf type="conductor"/>"#,
                "bumpmap" => r#"<texture type="checkerboard"/><bsdf type="diffuse"/>"#,
                _ => "",
            };
            with_sensor(&format!(r#"<shape type="rectangle">{HERE}</shape>"#))
        }
        // Mitsuba's spectra are textures: both go where a BSDF reads a texture.
        "texture" | "spectrum" => {
            c.attrs = r#" name="reflectance""#;
            if name == "volume" {
                // Optional in Mitsuba (a null volume), needed by penumbra.
                c.extra.push((
                    "volume",
                    r#"<volume type="constvolume" name="volume"/>"#.into(),
                ));
            }
            with_sensor(&format!(
                r#"<shape type="rectangle"><bsdf type="diffuse">{HERE}</bsdf></shape>"#
            ))
        }
        "shape" => match name {
            "shapegroup" => {
                c.attrs = r#" id="group""#;
                c.children = r#"<shape type="sphere"/>"#;
                with_sensor(&format!(
                    r#"{HERE}<shape type="instance"><ref id="group"/></shape>"#
                ))
            }
            "instance" => {
                c.children = r#"<ref id="group"/>"#;
                with_sensor(&format!(
                    r#"<shape type="shapegroup" id="group"><shape type="sphere"/></shape>{HERE}"#
                ))
            }
            _ => with_sensor(HERE),
        },
        "medium" => {
            c.attrs = r#" name="interior""#;
            medium_scene(HERE)
        }
        "volume" => {
            c.attrs = r#" name="sigma_t""#;
            medium_scene(&format!(
                r#"<medium type="heterogeneous" name="interior">{HERE}</medium>"#
            ))
        }
        "phase" => medium_scene(&format!(
            r#"<medium type="homogeneous" name="interior">{HERE}</medium>"#
        )),
        "emitter" if name == "area" => {
            // penumbra needs the radiance Mitsuba defaults to 1.
            c.extra.push((
                "radiance",
                r#"<rgb name="radiance" value="1, 1, 1"/>"#.into(),
            ));
            with_sensor(&format!(r#"<shape type="rectangle">{HERE}</shape>"#))
        }
        "emitter" => with_sensor(HERE),
        _ => return None,
    };
    Some(c)
}

/// The scene holding `plugin` with its required properties, less those named in `skip`,
/// plus `props` and `children` (XML), and the element's attributes plus `attrs`.
fn scene_with(
    plugin: &Value,
    c: &Context,
    skip: &[&str],
    props: &str,
    children: &str,
    attrs: &str,
) -> String {
    let kind = s(plugin, "kind");
    let name = s(plugin, "name");
    let mut body = String::new();
    let params: BTreeMap<&str, &Value> = plugin["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| (s(p, "name"), p))
        .collect();
    if let Some(required) = plugin["requires"].as_object() {
        for (n, v) in required {
            if !skip.contains(&n.as_str()) {
                body += &param_xml(params[n.as_str()], v);
            }
        }
    }
    for (n, xml) in &c.extra {
        if !skip.contains(n) {
            body += xml;
        }
    }
    body += props;
    body += c.children;
    body += children;
    let element = if kind == "scene" {
        format!("<scene version=\"3.0.0\"{attrs}>{body}\n{SENSOR}</scene>")
    } else {
        let tag = if kind == "spectrum" { "texture" } else { kind };
        format!(r#"<{tag} type="{name}"{}{attrs}>{body}</{tag}>"#, c.attrs)
    };
    c.scene.replace(HERE, &element)
}

// ---------------------------------------------------------------------------------------
// The check
// ---------------------------------------------------------------------------------------

/// Why one parameter (or nested object) is not accepted.
#[derive(Debug)]
struct Failure {
    plugin: String,
    parameter: String,
    kind: String,
    /// "unknown parameter", or what else went wrong.
    error: String,
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        let class = if self.error.contains("unknown parameter") {
            "UNKNOWN"
        } else {
            "ERROR"
        };
        write!(
            f,
            "{:<22} {:<34} {:<10} {class}: {}",
            self.plugin, self.parameter, self.kind, self.error
        )
    }
}

fn key(plugin: &Value) -> String {
    format!("{}/{}", s(plugin, "kind"), s(plugin, "name"))
}

/// The plugins of the data penumbra supports.
fn supported(data: &Value) -> Vec<&Value> {
    data["plugins"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["penumbra"].as_bool() == Some(true))
        .collect()
}

/// The minimal scene of `plugin` loads without the parameter (else nothing can be said of
/// its parameters).
fn check_context(plugin: &Value) -> Result<Context, Failure> {
    let fail = |error: String| Failure {
        plugin: key(plugin),
        parameter: "(the plugin itself)".into(),
        kind: String::new(),
        error,
    };
    let c = context(s(plugin, "kind"), s(plugin, "name"))
        .ok_or_else(|| fail("no minimal scene for it in tests/mitsuba_params.rs".into()))?;
    let xml = scene_with(plugin, &c, &[], "", "", "");
    parse(&xml).map_err(|e| fail(format!("{e}\n{xml}")))?;
    Ok(c)
}

/// Parameter `p` of `plugin` set to its example value.
fn check_param(plugin: &Value, c: &Context, p: &Value) -> Result<(), Failure> {
    let name = s(p, "name");
    let mut xml = param_xml(p, &p["example"]);
    let mut skip = vec![name];
    if let Some(with) = p["with"].as_object() {
        let params = plugin["parameters"].as_array().unwrap();
        for (n, v) in with {
            let q = params.iter().find(|q| s(q, "name") == n).unwrap();
            xml += &param_xml(q, v);
            skip.push(n);
        }
    }
    if let Some(conflicts) = p["conflicts"].as_array() {
        skip.extend(conflicts.iter().map(|c| c.as_str().unwrap()));
    }
    let scene = scene_with(plugin, c, &skip, &xml, "", "");
    parse(&scene).map_err(|error| Failure {
        plugin: key(plugin),
        parameter: name.into(),
        kind: s(p, "type").into(),
        error,
    })
}

/// Whether `p` is one the check covers: it has an XML form and Mitsuba accepts it in its
/// RGB variant (scalar_rgb, the one penumbra follows; `mitsuba_variant` names the other
/// variant a parameter needs, e.g. a sensor's spectral `srf`).
fn checked(p: &Value) -> bool {
    p["xml"].as_bool() != Some(false)
        && p["mitsuba"].as_str() != Some("refused")
        && p["mitsuba_variant"].is_null()
}

/// Every failure of the supported plugins' parameters, and how many were checked.
fn parameter_failures(data: &Value) -> (Vec<Failure>, usize) {
    let mut failures = Vec::new();
    let mut count = 0;
    for plugin in supported(data) {
        let c = match check_context(plugin) {
            Ok(c) => c,
            Err(f) => {
                failures.push(f);
                continue;
            }
        };
        for p in plugin["parameters"].as_array().unwrap() {
            if !checked(p) {
                continue;
            }
            count += 1;
            if let Err(f) = check_param(plugin, &c, p) {
                failures.push(f);
            }
        }
    }
    (failures, count)
}

fn report(what: &str, failures: &[Failure], count: usize) -> String {
    let unknown = failures
        .iter()
        .filter(|f| f.error.contains("unknown parameter"))
        .count();
    let mut text = format!(
        "{} of {count} {what} Mitsuba 3.9.1 reads are not accepted ({unknown} unknown, {} other errors):\n",
        failures.len(),
        failures.len() - unknown
    );
    for f in failures {
        // One line each: the error's first line (a failing context prints its scene after).
        let first = f.error.lines().next().unwrap_or("");
        text += &format!(
            "{}\n",
            Failure {
                error: first.into(),
                ..clone(f)
            }
        );
    }
    text
}

fn clone(f: &Failure) -> Failure {
    Failure {
        plugin: f.plugin.clone(),
        parameter: f.parameter.clone(),
        kind: f.kind.clone(),
        error: f.error.clone(),
    }
}

#[test]
fn every_parameter_mitsuba_reads_is_accepted() {
    let data = data();
    let (failures, count) = parameter_failures(&data);
    assert!(count > 200, "only {count} parameters checked");
    assert!(
        failures.is_empty(),
        "{}",
        report("parameters", &failures, count)
    );
}

/// One nested object of each kind Mitsuba's plugins take from their children (a shape's
/// `interior` medium, an emitter's medium, a film's reconstruction filter...), where
/// Mitsuba accepts it, added to the minimal scene (the data's `example`).
#[test]
fn every_nested_object_mitsuba_reads_is_accepted() {
    let data = data();
    let mut failures = Vec::new();
    let mut count = 0;
    let mut refused_unsupported = 0;
    for plugin in supported(&data) {
        let Ok(c) = check_context(plugin) else {
            continue; // reported by every_parameter_mitsuba_reads_is_accepted
        };
        for child in plugin["children"].as_array().unwrap() {
            // Children the minimal scene has already, and those Mitsuba refuses, are not
            // added (no `example`).
            let (Some("accepted"), Some(xml)) =
                (child["mitsuba"].as_str(), child["example"].as_str())
            else {
                continue;
            };
            // One the minimal scene holds already (a sensor's film) is checked by it.
            let tag = s(child, "object");
            if c.children.contains(&format!("<{tag} ")) {
                continue;
            }
            count += 1;
            let scene = scene_with(plugin, &c, &[], "", xml, "");
            if let Err(error) = parse(&scene) {
                // A nested plugin penumbra does not implement (a shape's irradiancemeter
                // sensor) is refused as such, not as an unknown parameter; and Mitsuba's
                // sdfgrid documents that it "cannot be used as an area emitter" (its
                // sample_position returns nothing), which penumbra refuses at load.
                let child_plugin = xml
                    .split("type=\"")
                    .nth(1)
                    .and_then(|t| t.split('"').next())
                    .unwrap_or("");
                let unsupported_child = !data["plugins"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .any(|p| s(p, "name") == child_plugin && p["penumbra"] == true);
                if unsupported_child
                    && error.contains(&format!(
                        "unsupported plugin <{tag} type=\"{child_plugin}\">"
                    ))
                {
                    refused_unsupported += 1;
                    continue;
                }
                if key(plugin) == "shape/sdfgrid"
                    && tag == "emitter"
                    && error.contains("cannot carry an emitter")
                {
                    refused_unsupported += 1;
                    continue;
                }
                failures.push(Failure {
                    plugin: key(plugin),
                    parameter: xml.into(),
                    kind: "object".into(),
                    error,
                });
            }
        }
    }
    assert!(count > 20, "only {count} nested objects checked");
    assert!(
        failures.is_empty(),
        "{}",
        report("nested objects", &failures, count)
    );
    // the nine shapes' irradiancemeters and the sdfgrid's emitter
    assert_eq!(refused_unsupported, 10);
}

/// Every object takes the XML attribute `id` (Mitsuba's props.id(); the data's
/// `attributes`), whether or not anything refers to it.
#[test]
fn every_supported_plugin_takes_an_id() {
    let data = data();
    let mut failures = Vec::new();
    for plugin in supported(&data) {
        let Ok(c) = check_context(plugin) else {
            continue; // reported by every_parameter_mitsuba_reads_is_accepted
        };
        if c.attrs.contains(" id=") || plugin["mitsuba"]["id"] != "accepted" {
            continue;
        }
        let scene = scene_with(plugin, &c, &[], "", "", r#" id="an_id""#);
        if let Err(error) = parse(&scene) {
            failures.push(Failure {
                plugin: key(plugin),
                parameter: "id=\"an_id\"".into(),
                kind: "attribute".into(),
                error,
            });
        }
    }
    let count = supported(&data).len();
    assert!(
        failures.is_empty(),
        "{}",
        report("plugins' id attributes", &failures, count)
    );
}

// ---------------------------------------------------------------------------------------
// The check itself
// ---------------------------------------------------------------------------------------

fn plugin<'a>(data: &'a Value, key_: &str) -> &'a Value {
    data["plugins"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| key(p) == key_)
        .unwrap_or_else(|| panic!("{key_} not in the data"))
}

fn parameter<'a>(plugin: &'a Value, name: &str) -> &'a Value {
    plugin["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| s(p, "name") == name)
        .unwrap_or_else(|| panic!("{name} not a parameter of {}", key(plugin)))
}

/// The check passes for parameters penumbra reads (hdrfilm's width, a sphere's radius,
/// a diffuse reflectance).
#[test]
fn the_check_passes_a_parameter_penumbra_reads() {
    let data = data();
    for (k, name) in [
        ("film/hdrfilm", "width"),
        ("shape/sphere", "radius"),
        ("bsdf/diffuse", "reflectance"),
    ] {
        let p = plugin(&data, k);
        let c = check_context(p).unwrap_or_else(|f| panic!("{f}"));
        check_param(p, &c, parameter(p, name)).unwrap_or_else(|f| panic!("{f}"));
    }
}

/// The check fails, as an unknown parameter, for a name Mitsuba does not have.
#[test]
fn the_check_fails_a_made_up_parameter() {
    let data = data();
    let film = plugin(&data, "film/hdrfilm");
    let c = check_context(film).unwrap_or_else(|f| panic!("{f}"));
    let made_up: Value = serde_json::json!({
        "name": "not_a_mitsuba_parameter", "type": "integer", "example": 3
    });
    let failure = check_param(film, &c, &made_up).expect_err("a made-up name is accepted");
    assert!(
        failure
            .error
            .contains("unknown parameter 'not_a_mitsuba_parameter'"),
        "{failure}"
    );
}

/// The data is Mitsuba 3.9.1's, covers every plugin penumbra supports (each has a minimal
/// scene here), and marks no plugin penumbra refuses as supported.
#[test]
fn the_data_covers_every_supported_plugin() {
    let data = data();
    assert_eq!(data["mitsuba_version"], "3.9.1");
    assert_eq!(data["mitsuba_source"]["tag"], "v3.9.1");
    let mut supported: Vec<String> = supported(&data).into_iter().map(key).collect();
    let mut expected = vec![
        "integrator/path",
        "integrator/volpath",
        "integrator/volpathmis",
        "integrator/direct",
        "integrator/moment",
        "integrator/ptracer",
        "integrator/aov",
        "sensor/perspective",
        "sensor/thinlens",
        "sensor/orthographic",
        "film/hdrfilm",
        "rfilter/gaussian",
        "rfilter/tent",
        "rfilter/box",
        "sampler/independent",
        "sampler/stratified",
        "sampler/multijitter",
        "sampler/orthogonal",
        "sampler/ldsampler",
        "bsdf/diffuse",
        "bsdf/conductor",
        "bsdf/roughconductor",
        "bsdf/dielectric",
        "bsdf/thindielectric",
        "bsdf/roughdielectric",
        "bsdf/plastic",
        "bsdf/roughplastic",
        "bsdf/principled",
        "bsdf/principledthin",
        "bsdf/twosided",
        "bsdf/mask",
        "bsdf/blendbsdf",
        "bsdf/normalmap",
        "bsdf/bumpmap",
        "bsdf/null",
        "texture/bitmap",
        "texture/checkerboard",
        "texture/mesh_attribute",
        "texture/volume",
        "spectrum/rawconstant",
        "spectrum/srgb",
        "spectrum/uniform",
        "shape/rectangle",
        "shape/cube",
        "shape/disk",
        "shape/sphere",
        "shape/cylinder",
        "shape/obj",
        "shape/ply",
        "shape/serialized",
        "shape/sdfgrid",
        "shape/shapegroup",
        "shape/instance",
        "medium/homogeneous",
        "medium/heterogeneous",
        "volume/constvolume",
        "volume/gridvolume",
        "phase/isotropic",
        "phase/hg",
        "emitter/area",
        "emitter/point",
        "emitter/spot",
        "emitter/projector",
        "emitter/directional",
        "emitter/constant",
        "emitter/envmap",
        "scene/scene",
    ];
    supported.sort();
    expected.sort();
    assert_eq!(supported, expected);
    let total: usize = data["plugins"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["parameters"].as_array().unwrap().len())
        .sum();
    assert!(data["plugins"].as_array().unwrap().len() > 100 && total > 500);
}
