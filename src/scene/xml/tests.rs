use super::*;
use glam::DVec4;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// Parses `xml` as if it came from `scene.xml` in the working directory.
fn parse(xml: &str) -> Result<Object> {
    load_str(xml, Path::new("scene.xml"), &[]).map(|d| d.root)
}

/// Wraps `body` in a `<scene>`.
fn scene(body: &str) -> String {
    format!("<scene version=\"3.0.0\">{body}</scene>")
}

/// The error message of parsing `xml`, which must fail.
fn error(xml: &str) -> String {
    match parse(xml) {
        Ok(object) => panic!("expected an error, got {object:?}"),
        Err(e) => e.to_string(),
    }
}

/// The value of property `name` of `object`.
fn prop<'o>(object: &'o Object, name: &str) -> &'o Value {
    &object
        .properties
        .iter()
        .find(|p| p.name == name)
        .unwrap_or_else(|| panic!("no property {name}"))
        .value
}

/// The first child object of the scene.
fn first(object: &Object) -> &Object {
    &object.children[0].object
}

/// The matrix of `<transform name="t">` with `ops` inside a shape.
fn transform(ops: &str) -> DMat4 {
    let xml = scene(&format!(
        "<shape type=\"a\"><transform name=\"t\">{ops}</transform></shape>"
    ));
    let root = parse(&xml).unwrap();
    match prop(first(&root), "t") {
        Value::Transform(m) => *m,
        other => panic!("not a transform: {other:?}"),
    }
}

fn transform_error(ops: &str) -> String {
    error(&scene(&format!(
        "<shape type=\"a\"><transform name=\"t\">{ops}</transform></shape>"
    )))
}

fn assert_mat(actual: DMat4, expected: DMat4) {
    assert!(
        actual.abs_diff_eq(expected, 1e-12),
        "expected {expected:?}, got {actual:?}"
    );
}

fn assert_vec(actual: DVec3, expected: DVec3) {
    assert!(
        actual.abs_diff_eq(expected, 1e-12),
        "expected {expected:?}, got {actual:?}"
    );
}

/// A scratch directory under the system temp dir, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> Self {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!(
            "penumbra-xml-test-{}-{name}-{n}",
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }

    fn write(&self, relative: &str, contents: impl AsRef<[u8]>) -> PathBuf {
        let path = self.0.join(relative);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).unwrap();
        }
        std::fs::write(&path, contents).unwrap();
        path
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn parses_every_property_type() {
    let xml = scene(
        r#"
        <shape type="sphere" id="s">
            <integer name="i" value=" -42 "/>
            <float name="f" value="1.5e-3"/>
            <boolean name="b1" value="TRUE"/>
            <boolean name="b2" value="false"/>
            <string name="s" value="hello world"/>
            <rgb name="c1" value="0.1 0.2 0.3"/>
            <rgb name="c2" value="0.1,0.2,0.3"/>
            <rgb name="c3" value="0.1, 0.2 ,0.3"/>
            <rgb name="c4" value="0.5"/>
            <point name="p1" x="1" z="3"/>
            <point name="p2" value="4 5 6"/>
            <vector name="v1"/>
            <vector name="v2" value="7,8,9"/>
            <vector name="v3" value="2"/>
            <transform name="t"/>
        </shape>"#,
    );
    let root = parse(&xml).unwrap();
    assert_eq!(root.tag, "scene");
    assert_eq!(root.plugin, "");
    let shape = first(&root);
    assert_eq!(shape.tag, "shape");
    assert_eq!(shape.plugin, "sphere");
    assert_eq!(shape.id.as_deref(), Some("s"));
    assert_eq!(prop(shape, "i"), &Value::Integer(-42));
    assert_eq!(prop(shape, "f"), &Value::Float(1.5e-3));
    assert_eq!(prop(shape, "b1"), &Value::Boolean(true));
    assert_eq!(prop(shape, "b2"), &Value::Boolean(false));
    assert_eq!(prop(shape, "s"), &Value::String("hello world".into()));
    for name in ["c1", "c2", "c3"] {
        assert_eq!(prop(shape, name), &Value::Rgb(DVec3::new(0.1, 0.2, 0.3)));
    }
    assert_eq!(prop(shape, "c4"), &Value::Rgb(DVec3::splat(0.5)));
    assert_eq!(prop(shape, "p1"), &Value::Point(DVec3::new(1.0, 0.0, 3.0)));
    assert_eq!(prop(shape, "p2"), &Value::Point(DVec3::new(4.0, 5.0, 6.0)));
    assert_eq!(prop(shape, "v1"), &Value::Vector(DVec3::ZERO));
    assert_eq!(prop(shape, "v2"), &Value::Vector(DVec3::new(7.0, 8.0, 9.0)));
    assert_eq!(prop(shape, "v3"), &Value::Vector(DVec3::splat(2.0)));
    assert_eq!(prop(shape, "t"), &Value::Transform(DMat4::IDENTITY));
    // Properties keep document order.
    let names: Vec<&str> = shape.properties.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names.first(), Some(&"i"));
    assert_eq!(names.last(), Some(&"t"));
    assert_eq!(names.len(), 15);
}

#[test]
fn type_names() {
    let values = [
        (Value::Integer(1), "integer"),
        (Value::Float(1.0), "float"),
        (Value::Boolean(true), "boolean"),
        (Value::String(String::new()), "string"),
        (Value::Rgb(DVec3::ZERO), "rgb"),
        (Value::Point(DVec3::ZERO), "point"),
        (Value::Vector(DVec3::ZERO), "vector"),
        (Value::Transform(DMat4::IDENTITY), "transform"),
    ];
    for (value, name) in values {
        assert_eq!(value.type_name(), name);
    }
}

#[test]
fn children_keep_order_names_and_locations() {
    let xml = "<scene version=\"3.0.0\">\n\
               <shape type=\"obj\">\n\
               \x20 <bsdf type=\"diffuse\" name=\"bsdf\"/>\n\
               \x20 <emitter type=\"area\"/>\n\
               \x20 <float name=\"x\" value=\"1\"/>\n\
               </shape>\n\
               <integrator type=\"path\"/>\n\
               </scene>";
    let root = parse(xml).unwrap();
    assert_eq!(root.location.line, 1);
    assert_eq!(root.location.col, 1);
    assert_eq!(root.location.file, PathBuf::from("scene.xml"));
    assert_eq!(root.children.len(), 2);
    let shape = first(&root);
    assert_eq!(shape.location.line, 2);
    assert_eq!(shape.children.len(), 2);
    assert_eq!(shape.children[0].name.as_deref(), Some("bsdf"));
    assert_eq!(shape.children[0].object.plugin, "diffuse");
    assert_eq!(shape.children[0].object.location.line, 3);
    assert_eq!(shape.children[0].object.location.col, 3);
    assert_eq!(shape.children[1].name, None);
    assert_eq!(shape.children[1].object.tag, "emitter");
    assert_eq!(shape.properties[0].location.line, 5);
    assert_eq!(shape.properties[0].location.col, 3);
    assert_eq!(root.children[1].object.tag, "integrator");
    assert_eq!(root.children[1].object.location.line, 7);
}

#[test]
fn all_object_tags_are_accepted() {
    let body: String = OBJECT_TAGS
        .iter()
        .map(|tag| format!("<{tag} type=\"x\"/>"))
        .collect();
    let root = parse(&scene(&body)).unwrap();
    let tags: Vec<&str> = root
        .children
        .iter()
        .map(|c| c.object.tag.as_str())
        .collect();
    assert_eq!(tags, OBJECT_TAGS);
}

#[test]
fn substitutes_defaults_and_overrides() {
    let xml = scene(
        r#"<default name="spp" value="16"/>
           <default name="res" value="64"/>
           <default name="spp" value="999"/>
           <default name="both" value="$spp-$res"/>
           <sampler type="$kind" id="s_$res">
               <integer name="sample_count" value="$spp"/>
               <integer name="res" value="$res"/>
               <string name="both" value="$both"/>
               <string name="suffix" value="a$res.b"/>
           </sampler>"#,
    );
    let overrides = vec![
        ("kind".to_string(), "wrong".to_string()),
        ("res".to_string(), "128".to_string()),
        ("kind".to_string(), "independent".to_string()),
    ];
    let root = load_str(&xml, Path::new("scene.xml"), &overrides)
        .unwrap()
        .root;
    let sampler = first(&root);
    // The last override of a name wins; overrides beat defaults; the first default wins.
    assert_eq!(sampler.plugin, "independent");
    assert_eq!(sampler.id.as_deref(), Some("s_128"));
    assert_eq!(prop(sampler, "sample_count"), &Value::Integer(16));
    assert_eq!(prop(sampler, "res"), &Value::Integer(128));
    assert_eq!(prop(sampler, "both"), &Value::String("16-128".into()));
    assert_eq!(prop(sampler, "suffix"), &Value::String("a128.b".into()));
}

#[test]
fn substitution_errors() {
    let e = error(&scene(r#"<integer name="a" value="$missing"/>"#));
    assert!(e.contains("undefined parameter \"$missing\""), "{e}");
    assert!(e.contains("scene.xml:1:"), "{e}");
    // The longest identifier is used: `$ab` is not `$a` followed by `b`.
    let e = error(&scene(
        r#"<default name="a" value="1"/><integer name="x" value="$ab"/>"#,
    ));
    assert!(e.contains("\"$ab\""), "{e}");
    let e = error(&scene(r#"<string name="x" value="cost: $ 5"/>"#));
    assert!(e.contains("\"$\" not followed"), "{e}");
    // Defaults apply to what follows them, as in Mitsuba.
    let e = error(&scene(
        r#"<integer name="x" value="$n"/><default name="n" value="1"/>"#,
    ));
    assert!(e.contains("undefined parameter \"$n\""), "{e}");
    // Substitution happens before number parsing.
    let e = error(&scene(
        r#"<default name="n" value="3.5"/><integer name="x" value="$n"/>"#,
    ));
    assert!(e.contains("could not parse integer value \"3.5\""), "{e}");
    let e = error(&scene(r#"<default name="a b" value="1"/>"#));
    assert!(e.contains("invalid parameter name"), "{e}");
    let e = error(&scene(r#"<default name="a"/>"#));
    assert!(e.contains("missing attribute \"value\""), "{e}");
}

#[test]
fn exponential_substitution_is_bounded() {
    let mut body = String::from(r#"<default name="p0" value="xxxxxxxxxxxxxxxx"/>"#);
    for i in 1..12 {
        let prev = format!("$p{}", i - 1);
        body.push_str(&format!(
            r#"<default name="p{i}" value="{}"/>"#,
            prev.repeat(16)
        ));
    }
    let e = error(&scene(&body));
    assert!(e.contains("substitution produces more than"), "{e}");
}

#[test]
fn resolves_refs_to_the_same_object() {
    let xml = scene(
        r#"<bsdf type="diffuse" id="mat"/>
           <shape type="sphere" id="a">
               <texture type="checkerboard" id="tex"/>
           </shape>
           <shape type="sphere">
               <ref id="mat" name="bsdf"/>
               <bsdf type="plastic"><ref id="tex" name="reflectance"/></bsdf>
               <ref id="a"/>
           </shape>
           <alias id="mat" as="mat2"/>
           <shape type="cube"><ref id="mat2"/></shape>"#,
    );
    let root = parse(&xml).unwrap();
    let mat = &root.children[0].object;
    let tex = &root.children[1].object.children[0].object;
    let user = &root.children[2].object;
    assert!(Arc::ptr_eq(&user.children[0].object, mat));
    assert_eq!(user.children[0].name.as_deref(), Some("bsdf"));
    let inner = &user.children[1].object;
    assert!(Arc::ptr_eq(&inner.children[0].object, tex));
    assert_eq!(inner.children[0].name.as_deref(), Some("reflectance"));
    assert!(Arc::ptr_eq(
        &user.children[2].object,
        &root.children[1].object
    ));
    assert_eq!(user.children[2].name, None);
    assert!(Arc::ptr_eq(
        &root.children[3].object.children[0].object,
        mat
    ));
}

#[test]
fn ref_errors() {
    let e = error(&scene(r#"<shape type="a"><ref id="nope"/></shape>"#));
    assert!(e.contains("unknown id \"nope\""), "{e}");
    assert!(e.contains("<ref id=\"nope\">"), "{e}");
    let e = error(&scene(r#"<shape type="a" id="me"><ref id="me"/></shape>"#));
    assert!(e.contains("cyclic reference"), "{e}");
    // A cycle through two objects, each referring to the other.
    let e = error(&scene(
        r#"<bsdf type="a" id="x"><ref id="y"/></bsdf><bsdf type="b" id="y"><ref id="x"/></bsdf>"#,
    ));
    assert!(e.contains("cyclic reference"), "{e}");
    let e = error(&scene(r#"<shape type="a"><ref/></shape>"#));
    assert!(e.contains("missing attribute \"id\""), "{e}");
    let e = error(&scene(r#"<alias id="x" as="y"/>"#));
    assert!(e.contains("unknown id \"x\""), "{e}");
    let e = error(&scene(
        r#"<alias id="a" as="b"/><alias id="b" as="a"/><shape type="s"><ref id="a"/></shape>"#,
    ));
    assert!(
        e.contains("duplicate id") || e.contains("cycle of aliases"),
        "{e}"
    );
}

/// Mitsuba resolves references after parsing: a reference may name an object declared later
/// in the file (Mitsuba's cbox-rgb.xml refers to an emitter declared after its shapes), and
/// through an alias declared before its target.
#[test]
fn forward_refs_resolve_to_the_later_object() {
    let root = parse(&scene(
        r#"<shape type="a"><ref id="later" name="bsdf"/><ref id="al"/></shape>
           <alias id="em" as="al"/>
           <bsdf type="b" id="later"/>
           <emitter type="area" id="em"/>"#,
    ))
    .unwrap();
    let shape = &root.children[0].object;
    assert!(Arc::ptr_eq(
        &shape.children[0].object,
        &root.children[1].object
    ));
    assert_eq!(shape.children[0].name.as_deref(), Some("bsdf"));
    assert!(Arc::ptr_eq(
        &shape.children[1].object,
        &root.children[2].object
    ));
    assert_eq!(shape.children[1].object.plugin, "area");
}

/// A long chain of references (each object refers to the next) is refused with one line
/// before it can exhaust the stack, however long the file.
#[test]
fn long_reference_chains_fail_cleanly() {
    let n = 5000;
    let mut body = String::new();
    for i in 0..n {
        body.push_str(&format!(
            r#"<bsdf type="b" id="b{i}"><ref id="b{}"/></bsdf>"#,
            i + 1
        ));
    }
    body.push_str(&format!(r#"<bsdf type="b" id="b{n}"/>"#));
    let e = error(&scene(&body));
    assert!(e.contains("levels deep"), "{e}");
    // A short chain is fine.
    parse(&scene(
        r#"<bsdf type="b" id="b0"><ref id="b1"/></bsdf><bsdf type="b" id="b1"><ref id="b2"/></bsdf><bsdf type="b" id="b2"/>"#,
    ))
    .unwrap();
}

#[test]
fn duplicate_ids_and_names_fail() {
    let e = error(&scene(
        "<bsdf type=\"a\" id=\"m\"/>\n<bsdf type=\"b\" id=\"m\"/>",
    ));
    assert!(e.contains("duplicate id \"m\""), "{e}");
    assert!(e.starts_with("scene.xml:2:1:"), "{e}");
    assert!(e.contains("first declared at scene.xml:1:"), "{e}");
    // Also when nested inside the first declaration.
    let e = error(&scene(
        r#"<shape type="a" id="m"><bsdf type="b" id="m"/></shape>"#,
    ));
    assert!(e.contains("duplicate id \"m\""), "{e}");
    let e = error(&scene(
        r#"<bsdf type="a" id="m"/><bsdf type="b" id="n"/><alias id="n" as="m"/>"#,
    ));
    assert!(e.contains("duplicate id \"m\""), "{e}");
    let e = error(&scene(
        r#"<shape type="a"><float name="r" value="1"/><float name="r" value="2"/></shape>"#,
    ));
    assert!(e.contains("duplicate name \"r\""), "{e}");
    let e = error(&scene(
        r#"<shape type="a"><rgb name="c" value="1"/><texture type="t" name="c"/></shape>"#,
    ));
    assert!(e.contains("duplicate name \"c\""), "{e}");
    let e = error(&scene(r#"<shape type="a" id="_x"/>"#));
    assert!(e.contains("leading underscores"), "{e}");
    let e = error(&scene(
        r#"<shape type="a"><float name="_x" value="1"/></shape>"#,
    ));
    assert!(e.contains("leading underscores"), "{e}");
}

/// Mitsuba's file resolver: `<path>` folders (relative to the file, latest first), then the
/// scene's directory; an `<include>` also searches the including file's directory, and what
/// an included file adds with `<path>` ends with it.
#[test]
fn path_elements_feed_the_file_resolver() {
    let dir = TempDir::new("path");
    dir.write("common/meshes/m.obj", "v 0 0 0");
    dir.write("other/meshes/m.obj", "v 0 0 0");
    dir.write(
        "common/frag.xml",
        r#"<scene version="3.0.0"><bsdf type="x" id="f"/></scene>"#,
    );
    dir.write(
        "scenes/inc/inner.xml",
        r#"<scene version="3.0.0"><path value="../../other"/><bsdf type="y" id="g"/></scene>"#,
    );
    let main = dir.write(
        "scenes/main.xml",
        scene(
            r#"<path value="../common"/>
               <include filename="frag.xml"/>
               <include filename="inc/inner.xml"/>"#,
        ),
    );
    let doc = load_file(&main, &[]).unwrap();
    assert_eq!(doc.root.children.len(), 2);
    let paths = doc.resolver.paths();
    assert_eq!(paths[0], dir.0.join("scenes/../common"));
    assert_eq!(paths[1], dir.0.join("scenes"));
    // The included file's <path> did not outlive it.
    assert!(!paths.iter().any(|p| p.ends_with("other")), "{paths:?}");
    assert_eq!(
        doc.resolver.resolve(Path::new("meshes/m.obj")),
        dir.0.join("scenes/../common/meshes/m.obj")
    );
    // Refused: a missing folder, and <path> below the scene root.
    let bad = dir.write("scenes/bad.xml", scene(r#"<path value="nowhere"/>"#));
    let e = load_file(&bad, &[]).unwrap_err().to_string();
    assert!(e.contains("folder") && e.contains("not found"), "{e}");
    assert!(
        e.contains("bad.xml:1:") && e.contains("scenes/nowhere"),
        "{e}"
    );
    let nested = dir.write(
        "scenes/nested.xml",
        scene(r#"<shape type="a"><path value="../common"/></shape>"#),
    );
    let e = load_file(&nested, &[]).unwrap_err().to_string();
    assert!(e.contains("directly inside <scene>"), "{e}");
}

#[test]
fn includes_relative_paths_sharing_defaults_and_ids() {
    let dir = TempDir::new("include");
    dir.write(
        "sub/inc.xml",
        r#"<scene version="3.0.0">
             <bsdf type="diffuse" id="mat"><float name="r" value="$r"/></bsdf>
             <include filename="deeper.xml"/>
           </scene>"#,
    );
    dir.write(
        "sub/deeper.xml",
        "<scene version=\"3.0.0\">\n<emitter type=\"constant\" id=\"env\"/></scene>",
    );
    dir.write(
        "sub/props.xml",
        r#"<scene version="3.0.0"><float name="radius" value="2"/></scene>"#,
    );
    dir.write("sub/single.xml", r#"<film type="hdrfilm"/>"#);
    let main = dir.write(
        "main.xml",
        scene(
            r#"<default name="r" value="0.5"/>
               <default name="sub" value="sub"/>
               <include filename="$sub/inc.xml"/>
               <shape type="sphere">
                   <ref id="mat" name="bsdf"/>
                   <include filename="sub/props.xml"/>
               </shape>
               <sensor type="perspective"><include filename="sub/single.xml"/></sensor>"#,
        ),
    );
    let root = load_file(&main, &[]).unwrap().root;
    let tags: Vec<&str> = root
        .children
        .iter()
        .map(|c| c.object.tag.as_str())
        .collect();
    assert_eq!(tags, ["bsdf", "emitter", "shape", "sensor"]);
    let mat = &root.children[0].object;
    assert_eq!(prop(mat, "r"), &Value::Float(0.5));
    assert_eq!(mat.location.file, dir.0.join("sub/inc.xml"));
    assert_eq!(mat.location.line, 2);
    let env = &root.children[1].object;
    assert_eq!(env.location.file, dir.0.join("sub/deeper.xml"));
    assert_eq!(env.location.line, 2);
    let shape = &root.children[2].object;
    assert!(Arc::ptr_eq(&shape.children[0].object, mat));
    assert_eq!(prop(shape, "radius"), &Value::Float(2.0));
    let sensor = &root.children[3].object;
    assert_eq!(sensor.children[0].object.plugin, "hdrfilm");

    // Ids are shared across files: a duplicate in an included file fails.
    let dup = dir.write(
        "dup.xml",
        scene(r#"<bsdf type="a" id="env"/><include filename="sub/deeper.xml"/>"#),
    );
    let e = load_file(&dup, &[]).unwrap_err().to_string();
    assert!(e.contains("duplicate id \"env\""), "{e}");
    assert!(e.contains("deeper.xml:2:1"), "{e}");
}

#[test]
fn cyclic_includes_fail() {
    let dir = TempDir::new("cycle");
    dir.write("b.xml", scene(r#"<include filename="a.xml"/>"#));
    let a = dir.write("a.xml", scene(r#"<include filename="b.xml"/>"#));
    let e = load_file(&a, &[]).unwrap_err().to_string();
    assert!(e.contains("cyclic include"), "{e}");
    assert!(e.contains("a.xml -> "), "{e}");
    assert!(e.contains("b.xml -> "), "{e}");
    assert!(e.ends_with("a.xml"), "{e}");
    assert!(
        e.starts_with(&dir.0.join("b.xml").display().to_string()),
        "{e}"
    );

    let own = dir.write("self.xml", scene(r#"<include filename="self.xml"/>"#));
    let e = load_file(&own, &[]).unwrap_err().to_string();
    assert!(e.contains("cyclic include"), "{e}");
}

#[test]
fn include_depth_is_capped() {
    let dir = TempDir::new("depth");
    for i in 0..40 {
        dir.write(
            &format!("f{i}.xml"),
            scene(&format!(r#"<include filename="f{}.xml"/>"#, i + 1)),
        );
    }
    dir.write("f40.xml", scene(""));
    let e = load_file(&dir.0.join("f0.xml"), &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("include depth limit"), "{e}");
}

#[test]
fn include_errors() {
    let dir = TempDir::new("include-errors");
    let main = dir.write("main.xml", scene("\n<include filename=\"missing.xml\"/>"));
    let e = load_file(&main, &[]).unwrap_err().to_string();
    assert!(e.contains("main.xml:2:1"), "{e}");
    assert!(e.contains("cannot read included file"), "{e}");
    assert!(e.contains("missing.xml"), "{e}");

    dir.write("bad.xml", "<scene version=\"3.0.0\"><shape>");
    let main = dir.write("main2.xml", scene(r#"<include filename="bad.xml"/>"#));
    match load_file(&main, &[]) {
        Err(Error::Xml { path, .. }) => assert_eq!(path, dir.0.join("bad.xml")),
        other => panic!("expected an XML error, got {other:?}"),
    }
    let e = error(&scene(r#"<include/>"#));
    assert!(e.contains("missing attribute \"filename\""), "{e}");
    let e = error(&scene(
        r#"<shape type="a"><transform name="t"><include filename="x.xml"/></transform></shape>"#,
    ));
    assert!(e.contains("<include filename=\"x.xml\">"), "{e}");
}

#[test]
fn file_errors() {
    let dir = TempDir::new("files");
    let missing = dir.0.join("nope.xml");
    match load_file(&missing, &[]) {
        Err(Error::Io { path, .. }) => assert_eq!(path, missing),
        other => panic!("expected an I/O error, got {other:?}"),
    }
    let mut bytes = scene("<shape type=\"a\"/>\n").into_bytes();
    bytes.splice(10..10, [0xff, 0xfe]);
    let latin = dir.write("latin.xml", bytes);
    match load_file(&latin, &[]) {
        Err(e @ Error::Xml { .. }) => assert!(e.to_string().contains("not valid UTF-8")),
        other => panic!("expected an XML error, got {other:?}"),
    }
}

#[test]
fn translate_then_rotate() {
    let m = transform(r#"<translate x="1"/><rotate z="1" angle="90"/>"#);
    // T = R * Tr: (1,0,0) -> (2,0,0) -> (0,2,0).
    assert_vec(m.transform_point3(DVec3::X), DVec3::new(0.0, 2.0, 0.0));
    assert_mat(
        m,
        DMat4::from_cols(
            DVec4::new(0.0, 1.0, 0.0, 0.0),
            DVec4::new(-1.0, 0.0, 0.0, 0.0),
            DVec4::new(0.0, 0.0, 1.0, 0.0),
            DVec4::new(0.0, 1.0, 0.0, 1.0),
        ),
    );
    // The other order: (1,0,0) -> (0,1,0) -> (1,1,0).
    let m = transform(r#"<rotate value="0 0 1" angle="90"/><translate value="1 0 0"/>"#);
    assert_vec(m.transform_point3(DVec3::X), DVec3::new(1.0, 1.0, 0.0));
    // Right-handed rotation about x: y goes to z.
    let m = transform(r#"<rotate x="1" angle="90"/>"#);
    assert_vec(m.transform_vector3(DVec3::Y), DVec3::Z);
    let m = transform(r#"<translate value="1, 2, 3"/><translate y="-2"/>"#);
    assert_vec(m.transform_point3(DVec3::ZERO), DVec3::new(1.0, 0.0, 3.0));
}

/// Mitsuba does not normalise a rotation axis: `rotate` is cos θ I + (1 − cos θ) a aᵀ +
/// sin θ [a]× with the axis as written. The matrix of Mitsuba's hello.xml (axis 0, 1, 1,
/// 15°), as Mitsuba 3.9.1 prints it (`mi.ScalarTransform4f().rotate([0, 1, 1], 15)`), and an
/// axis of length 5.
#[test]
fn rotation_axes_are_not_normalised_as_in_mitsuba() {
    let m = transform(r#"<rotate x="0.0" y="1.0" z="1.0" angle="15"/>"#);
    let expected = DMat4::from_cols(
        DVec4::new(0.965926, 0.258819, -0.258819, 0.0),
        DVec4::new(-0.258819, 1.0, 0.0340742, 0.0),
        DVec4::new(0.258819, 0.0340742, 1.0, 0.0),
        DVec4::W,
    );
    assert!(m.abs_diff_eq(expected, 1e-6), "{m:?}");
    // cos 90° = 0: a aᵀ + [a]×, so x goes to 5 y.
    let m = transform(r#"<rotate value="0 0 5" angle="90"/>"#);
    assert_vec(m.transform_vector3(DVec3::X), DVec3::new(0.0, 5.0, 0.0));
    assert_vec(m.transform_vector3(DVec3::Z), DVec3::new(0.0, 0.0, 25.0));
    // The parser warns about it.
    let doc = load_str(
        &scene(
            r#"<shape type="a"><transform name="t"><rotate y="2" angle="10"/></transform></shape>"#,
        ),
        Path::new("scene.xml"),
        &[],
    )
    .unwrap();
    assert!(
        doc.warnings
            .iter()
            .any(|w| w.contains("does not normalise")),
        "{:?}",
        doc.warnings
    );
}

#[test]
fn translate_and_scale_order_follows_mitsuba() {
    let ts = transform(r#"<translate x="1"/><scale value="2"/>"#);
    let st = transform(r#"<scale value="2"/><translate x="1"/>"#);
    // T = M * T: the later operation applies last.
    assert_mat(
        ts,
        DMat4::from_scale(DVec3::splat(2.0)) * DMat4::from_translation(DVec3::X),
    );
    assert_mat(
        st,
        DMat4::from_translation(DVec3::X) * DMat4::from_scale(DVec3::splat(2.0)),
    );
    assert_vec(ts.transform_point3(DVec3::ZERO), DVec3::new(2.0, 0.0, 0.0));
    assert_vec(st.transform_point3(DVec3::ZERO), DVec3::new(1.0, 0.0, 0.0));
    assert_ne!(ts, st);
}

#[test]
fn scale_forms() {
    let diag = |x: f64, y: f64, z: f64| DMat4::from_scale(DVec3::new(x, y, z));
    assert_mat(transform(r#"<scale value="2"/>"#), diag(2.0, 2.0, 2.0));
    assert_mat(transform(r#"<scale value="1 2 3"/>"#), diag(1.0, 2.0, 3.0));
    assert_mat(transform(r#"<scale x="2"/>"#), diag(2.0, 1.0, 1.0));
    assert_mat(transform(r#"<scale y="3" z="4"/>"#), diag(1.0, 3.0, 4.0));
    assert_mat(transform(r#"<scale/>"#), DMat4::IDENTITY);
}

#[test]
fn matrix_is_row_major() {
    let m = transform(r#"<matrix value="1 2 3 4  5 6 7 8  9 10 11 12  13 14 15 16"/>"#);
    assert_eq!(m.row(0), DVec4::new(1.0, 2.0, 3.0, 4.0));
    assert_eq!(m.row(3), DVec4::new(13.0, 14.0, 15.0, 16.0));
    assert_eq!(m.w_axis, DVec4::new(4.0, 8.0, 12.0, 16.0));
    let m = transform(r#"<matrix value="1,0,0,5, 0,1,0,6, 0,0,1,7, 0,0,0,1"/>"#);
    assert_vec(m.transform_point3(DVec3::ZERO), DVec3::new(5.0, 6.0, 7.0));
    let m = transform(r#"<matrix value="1 2 3 4 5 6 7 8 9"/>"#);
    assert_eq!(m.row(0), DVec4::new(1.0, 2.0, 3.0, 0.0));
    assert_eq!(m.row(2), DVec4::new(7.0, 8.0, 9.0, 0.0));
    assert_eq!(m.row(3), DVec4::new(0.0, 0.0, 0.0, 1.0));
}

#[test]
fn lookat_columns() {
    let m = transform(r#"<lookat origin="1 2 3" target="1 2 4" up="0 1 0"/>"#);
    assert_mat(
        m,
        DMat4::from_cols(DVec4::X, DVec4::Y, DVec4::Z, DVec4::new(1.0, 2.0, 3.0, 1.0)),
    );
    // dir = +x, up = +z: left = up x dir = +y, new_up = dir x left = +z.
    let m = transform(r#"<lookat origin="0, 0, 0" target="5, 0, 0" up="0, 0, 3"/>"#);
    assert_mat(m, DMat4::from_cols(DVec4::Y, DVec4::Z, DVec4::X, DVec4::W));
    // Without `up`, one is chosen: the frame stays orthonormal and looks along dir.
    let m = transform(r#"<lookat origin="0 0 0" target="0 3 4"/>"#);
    assert_vec(m.z_axis.truncate(), DVec3::new(0.0, 0.6, 0.8));
    assert!((m.x_axis.truncate().length() - 1.0).abs() < 1e-12);
    assert!(m.x_axis.truncate().dot(m.z_axis.truncate()).abs() < 1e-12);
    // A lookat after a translate is applied after it.
    let m = transform(r#"<translate x="1"/><lookat origin="0 0 0" target="5 0 0" up="0 0 1"/>"#);
    assert_vec(m.transform_point3(DVec3::ZERO), DVec3::new(0.0, 1.0, 0.0));
}

#[test]
fn transform_errors() {
    let e = transform_error(r#"<rotate angle="30"/>"#);
    assert!(e.contains("zero rotation axis"), "{e}");
    assert!(e.contains("<rotate>"), "{e}");
    let e = transform_error(r#"<rotate x="1"/>"#);
    assert!(e.contains("missing attribute \"angle\""), "{e}");
    let e = transform_error(r#"<lookat origin="1 1 1" target="1 1 1" up="0 1 0"/>"#);
    assert!(e.contains("target coincides with origin"), "{e}");
    let e = transform_error(r#"<lookat origin="0 0 0" target="0 2 0" up="0 1 0"/>"#);
    assert!(e.contains("parallel"), "{e}");
    let e = transform_error(r#"<lookat origin="0 0" target="0 2 0"/>"#);
    assert!(e.contains("exactly 3 components"), "{e}");
    let e = transform_error(r#"<matrix value="1 2 3"/>"#);
    assert!(e.contains("16 (or 9) values"), "{e}");
    let e = transform_error(r#"<translate x="nan"/>"#);
    assert!(e.contains("non-finite"), "{e}");
    let e = transform_error(r#"<scale value="1 2"/>"#);
    assert!(e.contains("1 or 3 components"), "{e}");
    let e = transform_error(r#"<translate value="1 2 3" x="1"/>"#);
    assert!(e.contains("cannot be mixed"), "{e}");
    let e = transform_error(r#"<scale value="1e200"/><scale value="1e200"/>"#);
    assert!(e.contains("non-finite"), "{e}");
    let e = transform_error(r#"<float name="x" value="1"/>"#);
    assert!(
        e.contains("unexpected <float name=\"x\"> inside <transform name=\"t\">"),
        "{e}"
    );
    let e = transform_error(r#"<translate><scale/></translate>"#);
    assert!(e.contains("cannot appear inside <translate>"), "{e}");
    let e = transform_error("junk");
    assert!(e.contains("unexpected text \"junk\""), "{e}");
    let e = error(&scene(r#"<shape type="a"><translate x="1"/></shape>"#));
    assert!(e.contains("outside of a <transform>"), "{e}");
    let e = error(&scene(
        r#"<shape type="a"><lookat origin="0 0 0" target="0 0 1"/></shape>"#,
    ));
    assert!(e.contains("outside of a <transform>"), "{e}");
    let e = error(&scene(r#"<shape type="a"><transform/></shape>"#));
    assert!(e.contains("missing attribute \"name\""), "{e}");
}

#[test]
fn value_errors() {
    let cases = [
        (
            r#"<integer name="a" value="3.5"/>"#,
            "could not parse integer value \"3.5\"",
        ),
        (
            r#"<integer name="a" value="9223372036854775808"/>"#,
            "could not parse integer",
        ),
        (r#"<integer name="a" value=""/>"#, "could not parse integer"),
        (
            r#"<float name="a" value="nan"/>"#,
            "non-finite floating point value \"nan\"",
        ),
        (r#"<float name="a" value="-inf"/>"#, "non-finite"),
        (r#"<float name="a" value="1e999"/>"#, "non-finite"),
        (
            r#"<float name="a" value="1.0f"/>"#,
            "could not parse floating point value",
        ),
        (
            r#"<boolean name="a" value="yes"/>"#,
            "could not parse boolean value \"yes\"",
        ),
        (
            r#"<rgb name="a" value="1 2"/>"#,
            "one or three values, found 2",
        ),
        (
            r#"<rgb name="a" value="1 2 3 4"/>"#,
            "one or three values, found 4",
        ),
        (
            r#"<rgb name="a" value="1 x 3"/>"#,
            "could not parse floating point value \"x\"",
        ),
        (
            r#"<point name="a" value="1 2 3" y="1"/>"#,
            "cannot be mixed",
        ),
        (r#"<float name="a"/>"#, "missing attribute \"value\""),
        (r#"<float value="1"/>"#, "missing attribute \"name\""),
        (r#"<float name="" value="1"/>"#, "empty name"),
        (
            r#"<float name="a" value="1" vlaue="2"/>"#,
            "unexpected attribute \"vlaue\"",
        ),
        (
            r#"<string name="a" value="x"><string name="b" value="y"/></string>"#,
            "cannot appear inside <string name=\"a\">",
        ),
        (
            r#"<float name="a" value="1">2</float>"#,
            "unexpected text \"2\"",
        ),
    ];
    for (body, expected) in cases {
        let e = error(&scene(&format!("<shape type=\"s\">{body}</shape>")));
        assert!(e.contains(expected), "{body}: {e}");
        // The offending element is named, with its location.
        let tag = body.split([' ', '>']).next().unwrap_or_default();
        assert!(
            e.contains(&format!("{tag} name=")) || e.contains(&format!("{tag}>")),
            "{body}: {e}"
        );
        assert!(e.starts_with("scene.xml:1:"), "{body}: {e}");
    }
}

#[test]
fn structure_errors() {
    let e = error(&scene(r#"<shape/>"#));
    assert!(e.contains("missing attribute \"type\" in <shape>"), "{e}");
    let e = error(&scene(r#"<shape type=""/>"#));
    assert!(e.contains("empty \"type\""), "{e}");
    let e = error(&scene(r#"<shape type="a" color="red"/>"#));
    assert!(e.contains("unexpected attribute \"color\""), "{e}");
    let e = error("<scene>\n</scene>");
    assert!(e.contains("missing attribute \"version\""), "{e}");
    assert!(e.starts_with("scene.xml:1:1:"), "{e}");
    let e = error(r#"<scene version="three"/>"#);
    assert!(e.contains("could not parse version"), "{e}");
    let e = error(r#"<scene version="3.0.0" foo="1"/>"#);
    assert!(e.contains("unexpected attribute \"foo\""), "{e}");
    let e = error(r#"<shape type="a"/>"#);
    assert!(e.contains("root element must be <scene>"), "{e}");
    let e = error(&scene("<foo/>"));
    assert!(e.contains("unknown tag <foo> in <scene>"), "{e}");
    let e = error(&scene(r#"<shape type="a"><lights type="x"/></shape>"#));
    assert!(
        e.contains("unknown object tag <lights type=\"x\"> in <shape type=\"a\">"),
        "{e}"
    );
    let e = error(&scene("<scene version=\"3.0.0\"/>"));
    assert!(e.contains("can only be the root element"), "{e}");
    let e = error(&scene("hello"));
    assert!(e.contains("unexpected text \"hello\" in <scene>"), "{e}");
    let e = error(r#"<scene version="3.0.0" xmlns="urn:x"/>"#);
    assert!(e.contains("namespaced"), "{e}");
    // Comments, processing instructions and whitespace are fine.
    let root = parse(&scene("<!-- c --> <?pi x?>\n\t<shape type=\"a\"/>")).unwrap();
    assert_eq!(root.children.len(), 1);
    assert!(parse(&scene("")).unwrap().children.is_empty());
}

#[test]
fn errors_name_the_element_and_its_line() {
    let xml = "<scene version=\"3.0.0\">\n\
               \x20 <bsdf type=\"diffuse\">\n\
               \x20   <color name=\"reflectance\" value=\"0.5\"/>\n\
               \x20 </bsdf>\n\
               </scene>\n";
    assert_eq!(
        error(xml),
        "scene.xml:3:5: unknown property tag <color name=\"reflectance\"> in <bsdf type=\"diffuse\">"
    );
    let xml = "<scene version=\"3.0.0\">\n\n\n<shape type=\"a\">\n<integer name=\"n\" value=\"x\"/></shape></scene>";
    let e = error(xml);
    assert!(e.starts_with("scene.xml:5:1: "), "{e}");
    assert!(e.contains("<integer name=\"n\">"), "{e}");
    // Columns count characters, not bytes.
    let xml = "<scene version=\"3.0.0\"><!-- é --><foo/></scene>";
    assert!(error(xml).starts_with("scene.xml:1:34:"), "{}", error(xml));
}

#[test]
fn malformed_xml_fails() {
    for xml in [
        "",
        "not xml",
        "<scene version=\"3.0.0\"><shape type=\"a\"></scene>",
        "<scene version=\"3.0.0\"><shape type=\"a\"",
        "<scene version=\"3.0.0\">",
        "<scene version=\"3.0.0\" version=\"3.0.0\"/>",
        "<scene version=\"3.0.0\"/><scene version=\"3.0.0\"/>",
        "<!DOCTYPE scene [<!ENTITY a \"b\">]><scene version=\"3.0.0\"/>",
        "<scene version=\"3.0.0\">&bogus;</scene>",
    ] {
        match parse(xml) {
            Err(Error::Xml { path, message }) => {
                assert_eq!(path, PathBuf::from("scene.xml"));
                assert!(!message.is_empty());
            }
            other => panic!("{xml:?}: expected an XML error, got {other:?}"),
        }
    }
}

#[test]
fn deep_nesting_fails_quickly() {
    let start = Instant::now();
    let depth = 1_000_000;
    let open = "<shape type=\"a\">".repeat(depth);
    let truncated = format!("<scene version=\"3.0.0\">{open}");
    assert!(parse(&truncated).is_err());
    let closed = format!("{truncated}{}</scene>", "</shape>".repeat(depth));
    let e = error(&closed);
    assert!(e.contains("nested more than"), "{e}");
    assert!(start.elapsed() < Duration::from_secs(2));

    // Deeper than the object limit but within the XML pre-check.
    let depth = 100;
    let xml = format!(
        "<scene version=\"3.0.0\">{}{}</scene>",
        "<shape type=\"a\">".repeat(depth),
        "</shape>".repeat(depth)
    );
    let e = error(&xml);
    assert!(e.contains("nested more than 64 levels"), "{e}");
    // Just within the limit is fine.
    let depth = 63;
    let xml = format!(
        "<scene version=\"3.0.0\">{}{}</scene>",
        "<shape type=\"a\">".repeat(depth),
        "</shape>".repeat(depth)
    );
    assert!(parse(&xml).is_ok());
    // Markup inside comments, CDATA and attribute values does not count.
    let xml = scene(&format!(
        "<!-- {} --><shape type=\"a&gt;\"><string name=\"s\" value=\"<\"/></shape>",
        "<a>".repeat(1000)
    ));
    assert!(matches!(parse(&xml), Err(Error::Xml { .. })));
    let xml = scene(&format!(
        "<!-- {} --><shape type=\"a>\"><string name=\"s\" value=\"/>\"/></shape>",
        "<a>".repeat(1000)
    ));
    assert!(parse(&xml).is_ok());
}

#[test]
fn too_many_attributes_fail_quickly() {
    let attributes: String = (0..100_000).map(|i| format!(" a{i}=\"\"")).collect();
    let xml = format!("<scene version=\"3.0.0\"{attributes}/>");
    match parse(&xml) {
        Err(Error::Xml { message, .. }) => {
            assert!(message.contains("more than 256 attributes"), "{message}")
        }
        other => panic!("expected an XML error, got {other:?}"),
    }
}

#[test]
fn upgrades_old_scenes_like_mitsuba() {
    let xml = r#"<scene version="0.6.0">
        <shape type="sphere" id="_s">
            <float name="someValueX" value="1"/>
            <bsdf type="diffuse"><rgb name="diffuseReflectance" value="0.5"/></bsdf>
        </shape>
        <default name="camelCase" value="2"/>
        <sensor type="perspective">
            <integer name="x" value="$camelCase"/>
            <transform name="toWorld">
                <lookAt origin="0 0 0" target="0 0 1" up="0 1 0"/>
            </transform>
        </sensor>
    </scene>"#;
    let root = parse(xml).unwrap();
    let shape = first(&root);
    assert_eq!(shape.id.as_deref(), Some("ID_s__UPGR"));
    assert_eq!(prop(shape, "some_value_x"), &Value::Float(1.0));
    assert_eq!(
        prop(&shape.children[0].object, "reflectance"),
        &Value::Rgb(DVec3::splat(0.5))
    );
    let sensor = &root.children[1].object;
    assert_eq!(prop(sensor, "x"), &Value::Integer(2));
    assert_eq!(prop(sensor, "to_world"), &Value::Transform(DMat4::IDENTITY));
    // Current files are left alone.
    let e = error(&scene(
        r#"<shape type="a"><transform name="t"><lookAt/></transform></shape>"#,
    ));
    assert!(e.contains("<lookAt>"), "{e}");
    assert_eq!(camel_to_snake("aBcD"), "a_bcD");
    assert_eq!(camel_to_snake("toWorld"), "to_world");
    assert_eq!(camel_to_snake("intIOR"), "int_ior");
    assert_eq!(camel_to_snake(""), "");
}

#[test]
fn mangled_input_never_panics() {
    let xml = scene(
        r#"<default name="d" value="1"/>
           <bsdf type="diffuse" id="m"><rgb name="c" value="0.1, 0.2, 0.3"/></bsdf>
           <shape type="obj" name="s"><ref id="m" name="bsdf"/><boolean name="b" value="true"/>
             <transform name="to_world"><translate value="1 $d 3"/><rotate y="1" angle="45"/>
             <scale x="2"/><matrix value="1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1"/>
             <lookat origin="0,0,1" target="0,0,0" up="0,1,0"/></transform>
             <point name="p" x="1"/><integer name="i" value="$d"/><!-- note -->
           </shape>"#,
    );
    assert!(parse(&xml).is_ok());
    let bytes = xml.as_bytes();
    for end in 0..bytes.len() {
        let _ = parse(xml.get(..end).unwrap_or_default());
    }
    for i in 0..bytes.len() {
        for replacement in [b'<', b'>', b'"', b'$'] {
            let mut mangled = bytes.to_vec();
            mangled[i] = replacement;
            let text = String::from_utf8(mangled).unwrap();
            let _ = parse(&text);
        }
    }
}
