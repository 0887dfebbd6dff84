use super::*;
use glam::DVec4;
use std::sync::atomic::{AtomicUsize, Ordering};

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
            <point name="p1" x="1" y="" z="3"/>
            <point name="p2" value="4 5 6"/>
            <vector name="v1" x="0" y="0" z="0"/>
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
    // As in Mitsuba, `$a` is replaced wherever it appears: `$ab` is `1b` here.
    let e = error(&scene(
        r#"<default name="a" value="1"/><integer name="x" value="$ab"/>"#,
    ));
    assert!(e.contains("could not parse integer value \"1b\""), "{e}");
    let e = error(&scene(r#"<string name="x" value="cost: $ 5"/>"#));
    assert!(e.contains("undefined parameter \"$\""), "{e}");
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
    let e = error(&scene(r#"<default name="" value="1"/>"#));
    assert!(e.contains("the name must be non-empty"), "{e}");
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
    assert!(e.contains("alias source id \"x\" not found"), "{e}");
}

/// Mitsuba resolves references after parsing: a reference may name an object declared later
/// in the file (Mitsuba's cbox-rgb.xml refers to an emitter declared after its shapes), also
/// through an alias declared later (the alias itself must follow its target).
#[test]
fn forward_refs_resolve_to_the_later_object() {
    let root = parse(&scene(
        r#"<shape type="a"><ref id="later" name="bsdf"/><ref id="al"/></shape>
           <bsdf type="b" id="later"/>
           <emitter type="area" id="em"/>
           <alias id="em" as="al"/>"#,
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
    assert!(
        e.contains("alias destination id \"m\" already exists"),
        "{e}"
    );
    let e = error(&scene(
        r#"<shape type="a"><float name="r" value="1"/><float name="r" value="2"/></shape>"#,
    ));
    assert!(e.contains("duplicate name \"r\""), "{e}");
    let e = error(&scene(
        r#"<shape type="a"><texture type="t" name="c"/><rgb name="c" value="1"/></shape>"#,
    ));
    assert!(e.contains("duplicate name \"c\""), "{e}");
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
    assert!(e.contains("directly inside the root element"), "{e}");
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
        r#"<scene version="3.0.0"><float name="radius" value="2"/><texture type="t" name="tex"/></scene>"#,
    );
    dir.write(
        "sub/single.xml",
        r#"<film type="hdrfilm" version="3.0.0"/>"#,
    );
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
    // An included <scene> brings its objects, not its properties (Mitsuba 3.9.1).
    assert!(shape.properties.is_empty(), "{:?}", shape.properties);
    assert_eq!(shape.children[1].name.as_deref(), Some("tex"));
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
    assert!(
        e.contains("included file") && e.contains("not found"),
        "{e}"
    );
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
    assert!(e.contains("exactly 1 or 3 elements"), "{e}");
    let e = transform_error(r#"<translate value="1 2 3" x="1"/>"#);
    assert!(e.contains("cannot mix"), "{e}");
    let e = transform_error(r#"<scale value="1e200"/>"#);
    assert!(e.contains("exceeds the single-precision range"), "{e}");
    let e = transform_error(r#"<scale value="1e20"/><scale value="1e20"/>"#);
    assert!(e.contains("beyond single precision"), "{e}");
    let e = transform_error(r#"<float name="x" value="1"/>"#);
    assert!(
        e.contains("unexpected <float name=\"x\"> inside <transform>"),
        "{e}"
    );
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
        (r#"<point name="a" value="1 2 3" y="1"/>"#, "cannot mix"),
        (r#"<float name="a"/>"#, "missing attribute \"value\""),
        (r#"<float value="1"/>"#, "missing attribute \"name\""),
        (
            r#"<float name="a" value="1" vlaue="2"/>"#,
            "unexpected attribute \"vlaue\"",
        ),
        (
            r#"<string name="a" value="x"><string name="b" value="y"/></string>"#,
            "cannot appear inside <string name=\"a\">",
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
    assert!(e.contains("invalid version number \"three\""), "{e}");
    let e = error(r#"<scene version="3.0.0" foo="1"/>"#);
    assert!(e.contains("unexpected attribute \"foo\""), "{e}");
    // Mitsuba looks for the version first, on whatever the root is.
    let e = error(r#"<shape type="a"/>"#);
    assert!(
        e.contains("missing attribute \"version\" in root element <shape>"),
        "{e}"
    );
    let e = error(r#"<shape type="a" version="3.0.0"/>"#);
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
    // There are no namespaces: `xmlns` is an attribute like any other, `a:shape` a tag.
    let e = error(r#"<scene version="3.0.0" xmlns="urn:x"/>"#);
    assert!(e.contains("unexpected attribute \"xmlns\""), "{e}");
    let e = error(&scene(r#"<a:shape type="x"/>"#));
    assert!(e.contains("unknown object tag <a:shape type=\"x\">"), "{e}");
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

/// What pugixml refuses (each checked against Mitsuba 3.9.1, which names the same problem).
#[test]
fn malformed_xml_fails() {
    let cases = [
        ("", "No document element found"),
        ("not xml", "No document element found"),
        ("<!-- only a comment -->", "No document element found"),
        (
            "<scene version=\"3.0.0\"><shape type=\"a\"></scene>",
            "Start-end tags mismatch",
        ),
        (
            "<scene version=\"3.0.0\"></ scene>",
            "Start-end tags mismatch",
        ),
        ("</scene>", "Start-end tags mismatch"),
        (
            "<scene version=\"3.0.0\"/></extra>",
            "Start-end tags mismatch",
        ),
        ("<scene version=\"3.0.0\">", "Start-end tags mismatch"),
        (
            "<scene version=\"3.0.0\"><shape type=\"a\"",
            "Error parsing start element tag",
        ),
        (
            "<scene version=\"3.0.0\"/><bad",
            "Error parsing start element tag",
        ),
        (
            "<scene version=\"3.0.0\"/ >",
            "Error parsing start element tag",
        ),
        (
            "<scene version=\"3.0.0\" a=\"1\"b=\"2\"/>",
            "Error parsing element attribute",
        ),
        ("<scene version=3.0.0/>", "Error parsing element attribute"),
        (
            "<scene version=\"3.0.0\" a/>",
            "Error parsing element attribute",
        ),
        (
            "<scene version=\"3.0.0/>",
            "Error parsing element attribute",
        ),
        (
            "<scene version=\"3.0.0\"></scene x>",
            "Error parsing end element tag",
        ),
        (
            "<scene version=\"3.0.0\"><!-- x</scene>",
            "Error parsing comment",
        ),
        (
            "<scene version=\"3.0.0\"><!- x --></scene>",
            "Error parsing comment",
        ),
        (
            "<scene version=\"3.0.0\"><![CDATA[ x</scene>",
            "Error parsing CDATA section",
        ),
        (
            "<scene version=\"3.0.0\"><![CDAT[x]]></scene>",
            "Error parsing CDATA section",
        ),
        (
            "<scene version=\"3.0.0\"><?pi x</scene>",
            "processing instruction",
        ),
        (
            "<scene version=\"3.0.0\"><? x?></scene>",
            "processing instruction",
        ),
        (
            "<scene version=\"3.0.0\"><!DOCTYPE x></scene>",
            "Error parsing document type declaration",
        ),
        (
            "<!DOCTYPE x [ <a> ]><scene version=\"3.0.0\"/>",
            "Error parsing document type declaration",
        ),
        (
            "<!DOCTYPE x [ \"open ]><scene version=\"3.0.0\"/>",
            "Error parsing document type declaration",
        ),
        (
            "<scene version=\"3.0.0\"><1a/></scene>",
            "Could not determine tag type",
        ),
        (
            "<scene version=\"3.0.0\">a < b</scene>",
            "Could not determine tag type",
        ),
        (
            "<scene version=\"3.0.0\"><!FOO></scene>",
            "Could not determine tag type",
        ),
        (
            "<scene version=\"3.0.0\"/><",
            "Could not determine tag type",
        ),
    ];
    for (xml, expected) in cases {
        match parse(xml) {
            Err(Error::Xml { path, message }) => {
                assert_eq!(path, PathBuf::from("scene.xml"));
                assert!(message.contains(expected), "{xml:?}: {message}");
                assert!(message.contains("(at 1:"), "{xml:?}: {message}");
            }
            other => panic!("{xml:?}: expected an XML error, got {other:?}"),
        }
    }
}

#[test]
fn deep_nesting_fails_quickly() {
    // No wall-clock bound (timed unit tests flake on loaded machines): a reader quadratic in
    // the depth would take hours on a million levels.
    let depth = 1_000_000;
    let open = "<shape type=\"a\">".repeat(depth);
    let truncated = format!("<scene version=\"3.0.0\">{open}");
    assert!(parse(&truncated).is_err());
    let closed = format!("{truncated}{}</scene>", "</shape>".repeat(depth));
    let e = error(&closed);
    assert!(e.contains("nested more than"), "{e}");

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
    // Markup inside comments, CDATA and attribute values does not count (and `<` is fine in
    // an attribute value, as pugixml reads it).
    let xml = scene(&format!(
        "<!-- {} --><![CDATA[{}]]><shape type=\"a&gt;\"><string name=\"s\" value=\"<\"/></shape>",
        "<a>".repeat(1000),
        "<a>".repeat(1000)
    ));
    let root = parse(&xml).unwrap();
    assert_eq!(first(&root).plugin, "a>");
    assert_eq!(prop(first(&root), "s"), &Value::String("<".into()));
    let xml = scene(&format!(
        "<!-- {} --><shape type=\"a>\"><string name=\"s\" value=\"/>\"/></shape>",
        "<a>".repeat(1000)
    ));
    assert!(parse(&xml).is_ok());
    // The reader's own bound, below the scene's.
    let xml = format!("{}{}", "<a>".repeat(200), "</a>".repeat(200));
    match parse(&xml) {
        Err(Error::Xml { message, .. }) => {
            assert!(
                message.contains("nested more than 128 levels deep"),
                "{message}"
            )
        }
        other => panic!("expected an XML error, got {other:?}"),
    }
}

/// pugixml does not look for repeated attributes, so neither does penumbra: many of them
/// take linear time, and the first one counts.
#[test]
fn many_repeated_attributes_are_read_quickly() {
    // As above, no wall-clock bound: a quadratic scan of 200,000 attributes takes hours.
    let repeated = " value=\"2\"".repeat(200_000);
    let xml = scene(&format!(
        "<shape type=\"a\"><float name=\"f\" value=\"1\"{repeated}/></shape>"
    ));
    let root = parse(&xml).unwrap();
    assert_eq!(prop(first(&root), "f"), &Value::Float(1.0));
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
             <point name="p" x="1" y="0" z="$d"/><integer name="i" value="$d"/><!-- note -->
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

// ---------------------------------------------------------------------------------------
// The XML syntax as pugixml (Mitsuba 3.9.1's XML library) reads it. Every expectation below
// was checked against Mitsuba 3.9.1 (`mi.parser.parse_string`).
// ---------------------------------------------------------------------------------------

/// The mitsuba-blender exporter's header (NVIDIA sionna's published scenes): a comment whose
/// lines start with `--`, which strict XML forbids and pugixml accepts.
#[test]
fn comments_may_contain_double_dashes() {
    let xml = "<!--\n-- SPDX-FileCopyrightText: Copyright (c) 2021 Someone. All rights reserved.\n\
               -- SPDX-License-Identifier: Apache-2.0\n  -->\n\
               <scene version=\"2.1.0\">\n<!-- a -- b --->\n<shape type=\"a\"/>\n</scene>\n";
    let root = parse(xml).unwrap();
    assert_eq!(root.children.len(), 1);
    // Locations still count from the file's first byte.
    assert_eq!(root.location.line, 5);
    assert_eq!(first(&root).location.line, 7);
}

/// An XML declaration (with any encoding name), a byte order mark, a DOCTYPE with an internal
/// subset (whose entities are not expanded), and processing instructions anywhere.
#[test]
fn declarations_bom_doctype_and_processing_instructions_are_skipped() {
    let xml = "\u{feff}<?xml version=\"1.0\" encoding=\"utf-8\"?>\n\
               <!DOCTYPE scene [ <!ENTITY a \"b\"> <!-- c --> <?p x?> <![IGNORE[ x ]]> ]>\n\
               <scene version=\"3.0.0\"><?xml version=\"1.0\"?><shape type=\"&a;\"/></scene>";
    let root = parse(xml).unwrap();
    assert_eq!(first(&root).plugin, "&a;");
    assert_eq!(root.location.line, 3);
}

/// Mitsuba ignores every node but elements: text (with `&`, `>` or unknown entities in it)
/// and CDATA sections, wherever they are, also inside properties and transforms.
#[test]
fn text_and_cdata_are_ignored_everywhere() {
    let xml = scene(
        r#"hello &bogus; & > ]]> <![CDATA[ <foo/> ]]>
           <shape type="a">text<float name="f" value="1">2</float>
               <transform name="t">junk<translate x="1">inner</translate></transform>
           </shape>"#,
    );
    let root = parse(&xml).unwrap();
    let shape = first(&root);
    assert_eq!(prop(shape, "f"), &Value::Float(1.0));
    assert_eq!(
        prop(shape, "t"),
        &Value::Transform(DMat4::from_translation(DVec3::X))
    );
}

/// pugixml's attribute values: the five entities and character references are decoded, any
/// other `&` stays, `<` is allowed, tabs and line breaks become spaces (CR LF one space), a
/// decoded NUL ends the value; `&#9;` is a real tab, which does not separate numbers.
#[test]
fn attribute_values_decode_like_pugixml() {
    let xml = scene(
        "<shape type=\"a\">\
         <string name=\"e\" value=\"&#x41;&#65;&#x;&#X41;&amp&lt;&quot;&apos;&gt;&bogus;a<b\"/>\
         <string name=\"w\" value=\"a\r\nb\rc\td\ne\"/>\
         <string name=\"n\" value=\"a&#0;b\"/>\
         <string name='q' value='a\"b'/>\
         <rgb name=\"c\" value=\"1\n2\t3\"/>\
         </shape>",
    );
    let root = parse(&xml).unwrap();
    let shape = first(&root);
    assert_eq!(
        prop(shape, "e"),
        &Value::String("AA&#x;&#X41;&amp<\"'>&bogus;a<b".into())
    );
    assert_eq!(prop(shape, "w"), &Value::String("a b c d e".into()));
    assert_eq!(prop(shape, "n"), &Value::String("a".into()));
    assert_eq!(prop(shape, "q"), &Value::String("a\"b".into()));
    assert_eq!(prop(shape, "c"), &Value::Rgb(DVec3::new(1.0, 2.0, 3.0)));
    let e = error(&scene(
        r#"<shape type="a"><rgb name="c" value="1&#9;2 3"/></shape>"#,
    ));
    // (Messages escape control characters, to stay one line.)
    assert!(
        e.contains("could not parse floating point value \"1\\t2\""),
        "{e}"
    );
}

/// pugixml keeps repeated attributes: the first one is the value, and every one is checked
/// (an unknown name is refused, an undefined `$name` too).
#[test]
fn repeated_attributes_keep_the_first() {
    let root = parse(&scene(r#"<shape type="a" type="b"/>"#)).unwrap();
    assert_eq!(first(&root).plugin, "a");
    let e = error(&scene(r#"<shape type="a" foo="1" foo="2"/>"#));
    assert!(e.contains("unexpected attribute \"foo\""), "{e}");
    let e = error(&scene(r#"<shape type="a" type="$nope"/>"#));
    assert!(e.contains("undefined parameter \"$nope\""), "{e}");
    // The root's first `version` counts.
    let root = parse(
        r#"<scene version="1.0.0" version="3.0.0"><float name="maxDepth" value="1"/></scene>"#,
    )
    .unwrap();
    assert_eq!(root.properties[0].name, "max_depth");
}

/// Only the first top-level element is the document: text and later elements around it are
/// skipped (the later ones must still be well-formed), and a NUL byte ends the document.
#[test]
fn only_the_first_top_level_element_counts() {
    let root =
        parse("junk & > <scene version=\"3.0.0\"/> more <scene version=\"x\"><foo/></scene>")
            .unwrap();
    assert!(root.children.is_empty());
    assert!(matches!(
        parse("<scene version=\"3.0.0\"/><later>"),
        Err(Error::Xml { .. })
    ));
    let root = parse("<scene version=\"3.0.0\"><shape type=\"a\"/></scene>\0<junk").unwrap();
    assert_eq!(root.children.len(), 1);
    assert!(matches!(
        parse("<scene version=\"3.0.0\">\0</scene>"),
        Err(Error::Xml { .. })
    ));
    // Names are whatever pugixml reads as one: `a.b-c` is an (unknown) tag, not an error.
    let e = error(&scene("<a.b-c/>"));
    assert!(e.contains("unknown tag <a.b-c>"), "{e}");
    // Spaces around `=` and before `>` or `/>`.
    let root = parse("<scene version = \"3.0.0\" ><shape type=\"a\" /></scene >").unwrap();
    assert_eq!(root.children.len(), 1);
}

/// pugixml's encodings: UTF-16 and UTF-32 (by byte order mark or a leading `<`), Latin-1
/// when the declaration says so, UTF-8 otherwise, where bytes that are not UTF-8 are fine in
/// what is skipped; penumbra refuses them in names and values.
#[test]
fn encodings_like_pugixml() {
    let dir = TempDir::new("encodings");
    let text = "<scene version=\"3.0.0\"><shape type=\"\u{e9}\"/></scene>";
    let mut utf16 = vec![0xFF, 0xFE];
    utf16.extend(text.encode_utf16().flat_map(u16::to_le_bytes));
    let utf16_be: Vec<u8> = text.encode_utf16().flat_map(u16::to_be_bytes).collect();
    let utf32: Vec<u8> = text
        .chars()
        .flat_map(|c| (c as u32).to_le_bytes())
        .collect();
    let mut latin1 = b"<?xml version=\"1.0\" encoding=\"ISO-8859-1\"?>\n".to_vec();
    latin1.extend(text.chars().map(|c| c as u8));
    let mut latin1_name = b"<?xml version='1.0' encoding='LATIN1'?>".to_vec();
    latin1_name.extend(text.chars().map(|c| c as u8));
    for (name, bytes) in [
        ("utf16.xml", utf16),
        ("utf16be.xml", utf16_be),
        ("utf32.xml", utf32),
        ("latin1.xml", latin1),
        ("latin1b.xml", latin1_name),
    ] {
        let path = dir.write(name, bytes);
        let root = load_file(&path, &[]).unwrap().root;
        assert_eq!(first(&root).plugin, "\u{e9}", "{name}");
    }
    let path = dir.write(
        "comment.xml",
        b"<scene version=\"3.0.0\"><!-- J\xe9r\xf4me -->x\xff<shape type=\"a\"/></scene>",
    );
    assert_eq!(load_file(&path, &[]).unwrap().root.children.len(), 1);
    let path = dir.write(
        "value.xml",
        b"<scene version=\"3.0.0\">\n<shape type=\"a\xe9\"/></scene>",
    );
    let e = load_file(&path, &[]).unwrap_err().to_string();
    assert!(e.contains("not valid UTF-8") && e.contains("line 2"), "{e}");
}

// ---------------------------------------------------------------------------------------
// Versions and the upgrade of files older than 2.0.0 (parser.cpp `transform_upgrade`,
// `upgrade_from_v1`, `camel_to_underscore_case`; test_parser.py test39 and test59).
// ---------------------------------------------------------------------------------------

/// The name of the first property of the first child of `xml`'s scene.
fn first_property_name(xml: &str) -> String {
    let root = parse(xml).unwrap();
    first(&root).properties[0].name.clone()
}

/// Mitsuba's `util::Version`: three parts split at `.` and spaces (empty parts dropped), each
/// read by `std::stoul` (digits first, the rest ignored, a sign allowed, the low 32 bits kept).
/// test_parser.py test06 refuses `invalid`, `1.2` and `1.2.4.5`.
#[test]
fn version_numbers_parse_like_mitsuba() {
    let with = |version: &str| {
        format!(
            r#"<scene version="{version}"><shape type="a"><float name="maxDepth" value="1"/></shape></scene>"#
        )
    };
    for (version, upgraded) in [
        ("0.6.0", true),
        ("1.9.9", true),
        (" 1..2.3 ", true),
        ("1 0 0", true),
        ("4294967296.0.0", true),
        ("2.0.0", false),
        ("3a.0.0", false),
        ("+3.0.0", false),
        ("-1.0.0", false),
    ] {
        let name = first_property_name(&with(version));
        let expected = if upgraded { "max_depth" } else { "maxDepth" };
        assert_eq!(name, expected, "version {version:?}");
    }
    for version in [
        "invalid",
        "1.2",
        "1.2.4.5",
        "3.x.0",
        "",
        "99999999999999999999.0.0",
    ] {
        let e = error(&with(version));
        assert!(e.contains("invalid version number"), "{version:?}: {e}");
    }
    // Mitsuba reads the version before substituting anything.
    let e = load_str(
        r#"<scene version="$v"/>"#,
        Path::new("scene.xml"),
        &[("v".to_string(), "3.0.0".to_string())],
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("invalid version number \"$v\""), "{e}");
}

/// Every file needs a `version` on its root, included files too, whatever the root is.
#[test]
fn every_file_needs_a_version() {
    let dir = TempDir::new("versions");
    dir.write("film.xml", r#"<film type="hdrfilm"/>"#);
    let main = dir.write(
        "main.xml",
        scene(r#"<sensor type="p"><include filename="film.xml"/></sensor>"#),
    );
    let e = load_file(&main, &[]).unwrap_err().to_string();
    assert!(
        e.contains("film.xml:1:1")
            && e.contains("missing attribute \"version\" in root element <film>"),
        "{e}"
    );
    dir.write("film.xml", r#"<film type="hdrfilm" version="three"/>"#);
    let e = load_file(&main, &[]).unwrap_err().to_string();
    assert!(e.contains("invalid version number \"three\""), "{e}");
}

#[test]
fn camel_to_underscore_follows_mitsuba() {
    use super::upgrade::camel_to_underscore as c;
    // Each capital after a lowercase letter starts a word, with the capitals right after it.
    assert_eq!(c("maxDepth"), "max_depth");
    assert_eq!(c("toWorld"), "to_world");
    assert_eq!(c("sampleCount"), "sample_count");
    assert_eq!(c("aBcD"), "a_bc_d");
    assert_eq!(c("intIOR"), "int_ior");
    assert_eq!(c("fooBAR"), "foo_bar");
    assert_eq!(c("aBCdEf"), "a_bcd_ef");
    assert_eq!(c("someValueX"), "some_value_x");
    // Not after a digit, a capital, '_' or at the start.
    assert_eq!(c("x2Y"), "x2Y");
    assert_eq!(c("ABc"), "ABc");
    assert_eq!(c("a_B"), "a_B");
    assert_eq!(c("Width"), "Width");
    assert_eq!(c("uv2World"), "uv2World");
    assert_eq!(c("already_snake"), "already_snake");
    assert_eq!(c(""), "");
    // Non-ASCII letters are neither lowercase nor capitals.
    assert_eq!(c("\u{e9}A"), "\u{e9}A");
    assert_eq!(c("a\u{c9}"), "a\u{c9}");
}

/// test_parser.py test39: a 1.0.0 file's property names (and child names, reference names,
/// the scene's own entries) become snake_case; a 3.0.0 file's do not. Ids, `<default>` names
/// and tags are left alone (`<lookAt>` stays unknown).
#[test]
fn old_files_rename_properties_and_children() {
    let xml = r#"<scene version="1.0.0">
        <default name="camelCase" value="2"/>
        <float name="someThing" value="1"/>
        <bsdf type="x" id="_mat" name="myBsdf"/>
        <shape type="sphere" id="myShape">
            <float name="myRadius" value="$camelCase"/>
            <float name="someValue" value="2.0"/>
            <ref id="_mat" name="bsdfRef"/>
            <transform name="toWorld"><translate x="1"/></transform>
        </shape>
    </scene>"#;
    let root = parse(xml).unwrap();
    assert_eq!(root.properties[0].name, "some_thing");
    assert_eq!(root.children[0].name.as_deref(), Some("my_bsdf"));
    assert_eq!(root.children[0].object.id.as_deref(), Some("_mat"));
    let shape = &root.children[1].object;
    assert_eq!(shape.id.as_deref(), Some("myShape"));
    assert_eq!(prop(shape, "my_radius"), &Value::Float(2.0));
    assert_eq!(prop(shape, "some_value"), &Value::Float(2.0));
    assert!(matches!(prop(shape, "to_world"), Value::Transform(_)));
    assert_eq!(shape.children[0].name.as_deref(), Some("bsdf_ref"));
    assert!(Arc::ptr_eq(
        &shape.children[0].object,
        &root.children[0].object
    ));
    let new = xml.replace("1.0.0", "3.0.0");
    let root = parse(&new).unwrap();
    assert_eq!(
        prop(&root.children[1].object, "myRadius"),
        &Value::Float(2.0)
    );
    assert_eq!(root.children[0].name.as_deref(), Some("myBsdf"));
    let e = error(
        r#"<scene version="0.6.0"><shape type="a"><transform name="toWorld"><lookAt origin="0 0 0" target="0 0 1"/></transform></shape></scene>"#,
    );
    assert!(e.contains("unexpected <lookAt>"), "{e}");
}

/// A rename whose new name is taken does not happen (Mitsuba's `rename_property` fails
/// silently), in document order.
#[test]
fn old_names_that_collide_are_kept() {
    let xml = r#"<scene version="1.0.0"><shape type="a">
        <float name="maxDepth" value="1"/><float name="max_depth" value="2"/>
        <float name="fooBar" value="3"/><float name="fooBAR" value="4"/>
    </shape></scene>"#;
    let root = parse(xml).unwrap();
    let names: Vec<&str> = first(&root)
        .properties
        .iter()
        .map(|p| p.name.as_str())
        .collect();
    assert_eq!(names, ["maxDepth", "max_depth", "foo_bar", "fooBAR"]);
}

/// test_parser.py test39: `diffuse_reflectance` becomes `reflectance` in a `diffuse` plugin
/// (after the camelCase pass, so `diffuseReflectance` too, properties and children alike),
/// unless `reflectance` is there already; other plugins keep it.
#[test]
fn old_diffuse_reflectance_becomes_reflectance() {
    let root = parse(
        r#"<scene version="1.0.0">
            <bsdf type="diffuse"><rgb name="diffuseReflectance" value="0.5 0.3 0.1"/></bsdf>
            <bsdf type="diffuse"><texture type="bitmap" name="diffuse_reflectance"/></bsdf>
            <bsdf type="diffuse"><rgb name="diffuse_reflectance" value="1"/><rgb name="reflectance" value="0"/></bsdf>
            <bsdf type="plastic"><rgb name="diffuseReflectance" value="1"/></bsdf>
        </scene>"#,
    )
    .unwrap();
    let obj = |i: usize| &root.children[i].object;
    assert_eq!(
        prop(obj(0), "reflectance"),
        &Value::Rgb(DVec3::new(0.5, 0.3, 0.1))
    );
    assert_eq!(obj(1).children[0].name.as_deref(), Some("reflectance"));
    assert_eq!(prop(obj(2), "diffuse_reflectance"), &Value::Rgb(DVec3::ONE));
    assert_eq!(prop(obj(2), "reflectance"), &Value::Rgb(DVec3::ZERO));
    assert_eq!(obj(3).properties[0].name, "diffuse_reflectance");
    // Not in current files.
    let root = parse(&scene(
        r#"<bsdf type="diffuse"><rgb name="diffuse_reflectance" value="1"/></bsdf>"#,
    ))
    .unwrap();
    assert_eq!(first(&root).properties[0].name, "diffuse_reflectance");
}

/// test_parser.py test59: `uoffset`, `voffset`, `uscale`, `vscale` become
/// `to_uv` = scale(2, 4, 1) · translate(0.5, −0.25, 0); integers count as numbers; any other
/// type, or a `to_uv` already there, is an error; `uOffset` is `u_offset`, not converted.
#[test]
fn old_uv_offsets_become_to_uv() {
    let root = parse(
        r#"<scene version="1.9.0"><texture type="bitmap">
            <float name="uscale" value="2.0"/>
            <integer name="vscale" value="4"/>
            <float name="uoffset" value="0.5"/>
            <float name="voffset" value="-0.25"/>
            <string name="filename" value="texture.jpg"/>
        </texture></scene>"#,
    )
    .unwrap();
    let tex = first(&root);
    let names: Vec<&str> = tex.properties.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["filename", "to_uv"]);
    let expected = DMat4::from_scale(DVec3::new(2.0, 4.0, 1.0))
        * DMat4::from_translation(DVec3::new(0.5, -0.25, 0.0));
    assert_eq!(prop(tex, "to_uv"), &Value::Transform(expected));
    let root = parse(
        r#"<scene version="1.0.0"><texture type="bitmap"><float name="uOffset" value="2"/><float name="voffset" value="3"/></texture></scene>"#,
    )
    .unwrap();
    let tex = first(&root);
    assert_eq!(prop(tex, "u_offset"), &Value::Float(2.0));
    assert_eq!(
        prop(tex, "to_uv"),
        &Value::Transform(DMat4::from_translation(DVec3::new(0.0, 3.0, 0.0)))
    );
    let e = error(
        r#"<scene version="1.0.0"><texture type="bitmap"><string name="uscale" value="2"/></texture></scene>"#,
    );
    assert!(
        e.contains("\"uscale\" has the wrong type (expected float, got string)"),
        "{e}"
    );
    let e = error(
        r#"<scene version="1.0.0"><texture type="bitmap"><float name="uoffset" value="2"/><float name="to_uv" value="1"/></texture></scene>"#,
    );
    assert!(e.contains("\"to_uv\" was specified multiple times"), "{e}");
    // Current files keep them as they are.
    let root = parse(&scene(
        r#"<texture type="bitmap"><float name="uscale" value="2"/></texture>"#,
    ))
    .unwrap();
    assert_eq!(prop(first(&root), "uscale"), &Value::Float(2.0));
}

/// The version is per file: an object is upgraded by its own file's version, and the names
/// of what an included `<scene>` brings follow the including file.
#[test]
fn the_upgrade_is_per_file() {
    let dir = TempDir::new("upgrade");
    let fragment =
        r#"<bsdf type="diffuse" name="fooBar"><float name="someValue" value="1"/></bsdf>"#;
    dir.write(
        "old.xml",
        format!("<scene version=\"0.5.0\">{fragment}</scene>"),
    );
    dir.write(
        "new.xml",
        format!("<scene version=\"3.0.0\">{fragment}</scene>"),
    );
    dir.write(
        "old_object.xml",
        r#"<bsdf type="diffuse" version="0.5.0"><float name="someValue" value="1"/></bsdf>"#,
    );
    let load = |version: &str, file: &str| {
        let main = dir.write(
            "main.xml",
            format!(
                "<scene version=\"{version}\"><shape type=\"s\"><include filename=\"{file}\" name=\"myInclude\"/></shape></scene>"
            ),
        );
        let root = load_file(&main, &[]).unwrap().root;
        let shape = first(&root).clone();
        let child = &shape.children[0];
        (
            child.name.clone().unwrap_or_default(),
            child.object.properties[0].name.clone(),
        )
    };
    assert_eq!(
        load("3.0.0", "old.xml"),
        ("fooBar".into(), "some_value".into())
    );
    assert_eq!(
        load("1.0.0", "new.xml"),
        ("foo_bar".into(), "someValue".into())
    );
    assert_eq!(
        load("3.0.0", "old_object.xml"),
        ("myInclude".into(), "some_value".into())
    );
    assert_eq!(
        load("1.0.0", "old_object.xml"),
        ("my_include".into(), "some_value".into())
    );
}

// ---------------------------------------------------------------------------------------
// `$name` substitution and `<default>` (test_parser.py test26-28, test60, test66).
// ---------------------------------------------------------------------------------------

/// Parses `xml` with `overrides` and returns the string property `s` of the first child.
fn substituted(xml: &str, overrides: &[(&str, &str)]) -> Result<String> {
    let overrides: Vec<(String, String)> = overrides
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    let root = load_str(xml, Path::new("scene.xml"), &overrides)?.root;
    match prop(first(&root), "s") {
        Value::String(s) => Ok(s.clone()),
        other => panic!("not a string: {other:?}"),
    }
}

fn string_s(value: &str) -> String {
    scene(&format!(
        r#"<shape type="a"><string name="s" value="{value}"/></shape>"#
    ))
}

/// Mitsuba replaces each parameter's `$name` wherever it occurs, longest names first, and
/// what a replacement brings in is replaced by the parameters after it.
#[test]
fn substitution_follows_mitsuba() {
    let s = |value: &str, overrides: &[(&str, &str)]| substituted(&string_s(value), overrides);
    // test27: several in one value, next to other text.
    assert_eq!(
        s(
            "$prefix_$suffix_$prefix",
            &[("prefix", "start"), ("suffix", "end")]
        )
        .unwrap(),
        "start_end_start"
    );
    // `$a` is found inside `$ab`; with both defined, the longer wins.
    assert_eq!(s("$ab", &[("a", "1")]).unwrap(), "1b");
    assert_eq!(s("$ab $a", &[("a", "1"), ("ab", "2")]).unwrap(), "2 1");
    // A value naming a shorter parameter is replaced further; a longer one is not.
    assert_eq!(s("$long", &[("long", "$s"), ("s", "5")]).unwrap(), "5");
    let e = s("$s", &[("s", "$long"), ("long", "5")])
        .unwrap_err()
        .to_string();
    assert!(e.contains("undefined parameter \"$long\""), "{e}");
    // test66: `\$` is a literal `$` (and a backslash before it is the escape).
    assert_eq!(
        s(r"\$50 for $count items", &[("count", "10")]).unwrap(),
        "$50 for 10 items"
    );
    assert_eq!(s(r"Cost: \$100", &[]).unwrap(), "Cost: $100");
    assert_eq!(s(r"a\$", &[]).unwrap(), "a$");
    assert_eq!(s(r"\\$", &[]).unwrap(), r"\$");
    assert_eq!(s(r"\$x", &[("x", "1")]).unwrap(), "$x");
    // Backslashes elsewhere stay.
    assert_eq!(s(r"C:\path\$x", &[("x", "1")]).unwrap(), r"C:\path$x");
    assert_eq!(s(r"C:\path", &[]).unwrap(), r"C:\path");
    // A `$` that no parameter claims is an error, with the name after it.
    for (value, name) in [
        ("a$", "$"),
        ("cost $ 5", "$"),
        ("$missing_1x", "$missing_1x"),
    ] {
        let e = s(value, &[]).unwrap_err().to_string();
        assert!(
            e.contains(&format!("undefined parameter \"{name}\"")),
            "{value}: {e}"
        );
    }
}

/// test60: a `<default>` of any non-empty name; the first one wins, an override beats it;
/// it applies to what follows; its own value is substituted where it stands.
#[test]
fn defaults_follow_mitsuba() {
    let xml = |defaults: &str, value: &str| {
        scene(&format!(
            r#"{defaults}<shape type="a"><string name="s" value="{value}"/></shape>"#
        ))
    };
    let with = |d: &str, v: &str, o: &[(&str, &str)]| substituted(&xml(d, v), o);
    let two = r#"<default name="x" value="1"/><default name="x" value="2"/>"#;
    assert_eq!(with(two, "$x", &[]).unwrap(), "1");
    assert_eq!(with(two, "$x", &[("x", "9")]).unwrap(), "9");
    assert_eq!(
        with(r#"<default name="a b" value="1"/>"#, "$a b", &[]).unwrap(),
        "1"
    );
    assert_eq!(
        with(r#"<default name="a-b" value="1"/>"#, "$a-b", &[]).unwrap(),
        "1"
    );
    assert_eq!(
        with(
            r#"<default name="n" value="x"/><default name="m" value="$n$n"/>"#,
            "$m",
            &[]
        )
        .unwrap(),
        "xx"
    );
    let e = with(r#"<default name="p" value="$q"/>"#, "", &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("undefined parameter \"$q\""), "{e}");
    let e = with(r#"<default name="" value="test"/>"#, "", &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("the name must be non-empty"), "{e}");
    let e = with(r#"<default name="n" value="v" extra="1"/>"#, "", &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("unexpected attribute \"extra\""), "{e}");
    // Names and types are substituted like any attribute (test26).
    let root = load_str(
        &scene(r#"<default name="n" value="radius"/><shape type="$t" id="$t"><float name="$n" value="1"/></shape>"#),
        Path::new("scene.xml"),
        &[("t".to_string(), "sphere".to_string())],
    )
    .unwrap()
    .root;
    assert_eq!(first(&root).plugin, "sphere");
    assert_eq!(first(&root).id.as_deref(), Some("sphere"));
    assert_eq!(prop(first(&root), "radius"), &Value::Float(1.0));
}

/// test28: an override that the scene never uses: Mitsuba refuses it by default; penumbra
/// warns (see the module documentation), also when a `<default>` of that name exists but no
/// `$name` uses it.
#[test]
fn unused_overrides_are_reported() {
    let xml = scene(r#"<default name="x" value="1"/><shape type="a"/>"#);
    let overrides = [
        ("x".to_string(), "2".to_string()),
        ("unused".to_string(), "3".to_string()),
    ];
    let doc = load_str(&xml, Path::new("scene.xml"), &overrides).unwrap();
    assert!(
        doc.warnings.iter().any(|w| w.contains("unused parameters")
            && w.contains("$x=2")
            && w.contains("$unused=3")),
        "{:?}",
        doc.warnings
    );
    let used = scene(r#"<shape type="$x"/>"#);
    let doc = load_str(&used, Path::new("scene.xml"), &overrides[..1]).unwrap();
    assert!(doc.warnings.is_empty(), "{:?}", doc.warnings);
}

// ---------------------------------------------------------------------------------------
// Names, ids, references and aliases (test_parser.py test11, test15, test29, test50,
// test59_alias_support, test61).
// ---------------------------------------------------------------------------------------

/// Mitsuba 3.9.1 does not restrict names or ids: leading underscores are fine, an empty
/// property name is a name, an empty object or reference name is no name, an empty id no id.
#[test]
fn names_and_ids_are_not_restricted() {
    let root = parse(&scene(
        r#"<shape type="a" id="_x"><float name="_r" value="1"/><float name="" value="2"/>
           <bsdf type="b" name=""/><ref id="_x2" name=""/></shape>
           <bsdf type="c" id="_x2"/><bsdf type="d" id=""/><bsdf type="e" id=""/>
           <shape type="f"><ref id="_x"/><boolean name="10" value="true"/></shape>"#,
    ))
    .unwrap();
    let shape = first(&root);
    assert_eq!(shape.id.as_deref(), Some("_x"));
    assert_eq!(prop(shape, "_r"), &Value::Float(1.0));
    assert_eq!(prop(shape, ""), &Value::Float(2.0));
    assert_eq!(shape.children[0].name, None);
    assert_eq!(shape.children[1].name, None);
    assert_eq!(root.children[2].object.id, None);
    assert!(Arc::ptr_eq(
        &root.children[4].object.children[0].object,
        &root.children[0].object
    ));
    assert_eq!(prop(&root.children[4].object, "10"), &Value::Boolean(true));
    // An empty id is not found by a reference (test50's message, in penumbra's words).
    let e = error(&scene(r#"<shape type="a"><ref id=""/></shape>"#));
    assert!(e.contains("unknown id \"\""), "{e}");
}

/// In Mitsuba a property (or named reference or transform) needs a new name, while a nested
/// object whose name is used replaces that entry where it stands (`Properties::set(.., false)`):
/// the last object of a name wins. penumbra warns about it.
#[test]
fn a_later_object_replaces_an_entry_of_its_name() {
    let doc = load_str(
        &scene(
            r#"<shape type="a">
                 <bsdf type="x" name="b"/><float name="f" value="1"/><bsdf type="y" name="b"/>
                 <rgb name="c" value="1"/><texture type="t" name="c"/>
                 <transform name="t"/><bsdf type="z" name="t"/>
               </shape>"#,
        ),
        Path::new("scene.xml"),
        &[],
    )
    .unwrap();
    let shape = first(&doc.root);
    let children: Vec<(Option<&str>, &str)> = shape
        .children
        .iter()
        .map(|c| (c.name.as_deref(), c.object.plugin.as_str()))
        .collect();
    assert_eq!(
        children,
        [(Some("b"), "y"), (Some("c"), "t"), (Some("t"), "z")]
    );
    let names: Vec<&str> = shape.properties.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["f"]);
    assert_eq!(doc.warnings.len(), 3, "{:?}", doc.warnings);
    assert!(doc.warnings[0].contains("replaces the earlier entry named \"b\""));
    // The replaced object is still parsed: its id stays declared.
    let root = parse(&scene(
        r#"<shape type="a"><bsdf type="x" id="first" name="b"/><bsdf type="y" name="b"/></shape>
           <shape type="s"><ref id="first"/></shape>"#,
    ))
    .unwrap();
    assert_eq!(root.children[1].object.children[0].object.plugin, "x");
    for body in [
        r#"<integer name="a" value="1"/><integer name="a" value="1"/>"#,
        r#"<bsdf type="y" name="b"/><rgb name="b" value="1"/>"#,
        r#"<bsdf type="x" name="t"/><ref id="m" name="t"/>"#,
        r#"<ref id="m" name="t"/><ref id="m" name="t"/>"#,
        r#"<transform name="t"/><transform name="t"/>"#,
    ] {
        let e = error(&scene(&format!(
            r#"<bsdf type="d" id="m"/><shape type="s">{body}</shape>"#
        )));
        assert!(e.contains("duplicate name"), "{body}: {e}");
    }
    // Unnamed references to one object are fine.
    let root = parse(&scene(
        r#"<bsdf type="d" id="x"/><shape type="s"><ref id="x"/><ref id="x"/></shape>"#,
    ))
    .unwrap();
    assert_eq!(root.children[1].object.children.len(), 2);
}

/// test59_alias_support: an alias names an id declared before it; its own id must be new;
/// it may name another alias; references through it give the same object.
#[test]
fn aliases_follow_mitsuba() {
    let root = parse(&scene(
        r#"<bsdf type="diffuse" id="mat_original"/>
           <alias id="mat_original" as="mat_alias"/>
           <alias id="mat_alias" as="mat_3"/>
           <shape type="sphere"><ref id="mat_original" name="bsdf"/></shape>
           <shape type="cube"><ref id="mat_alias" name="bsdf"/><ref id="mat_3"/></shape>"#,
    ))
    .unwrap();
    let mat = &root.children[0].object;
    assert!(Arc::ptr_eq(
        &root.children[1].object.children[0].object,
        mat
    ));
    assert!(Arc::ptr_eq(
        &root.children[2].object.children[0].object,
        mat
    ));
    assert!(Arc::ptr_eq(
        &root.children[2].object.children[1].object,
        mat
    ));
    let e = error(&scene(r#"<alias id="nonexistent" as="mat_alias"/>"#));
    assert!(
        e.contains("alias source id \"nonexistent\" not found"),
        "{e}"
    );
    let e = error(&scene(r#"<alias id="m" as="m2"/><bsdf type="d" id="m"/>"#));
    assert!(e.contains("alias source id \"m\" not found"), "{e}");
    let e = error(&scene(
        r#"<bsdf type="diffuse" id="mat1"/><bsdf type="diffuse" id="mat2"/><alias id="mat1" as="mat2"/>"#,
    ));
    assert!(
        e.contains("alias destination id \"mat2\" already exists"),
        "{e}"
    );
    let e = error(&scene(r#"<bsdf type="d" id="m"/><alias id="m" as="m"/>"#));
    assert!(
        e.contains("alias destination id \"m\" already exists"),
        "{e}"
    );
    let e = error(&scene(
        r#"<bsdf type="d" id="m"/><alias id="m" as="m2"/><bsdf type="e" id="m2"/>"#,
    ));
    assert!(e.contains("duplicate id \"m2\""), "{e}");
    let e = error(&scene(r#"<bsdf type="d" id="m"/><alias id="m"/>"#));
    assert!(e.contains("missing attribute \"as\""), "{e}");
    let e = error(&scene(
        r#"<bsdf type="d" id="m"/><alias id="m" as="x" name="y"/>"#,
    ));
    assert!(e.contains("unexpected attribute \"name\""), "{e}");
}

/// The root's `id`: a reference to it is a cycle (the scene contains it), another object with
/// it a duplicate.
#[test]
fn the_scene_root_may_have_an_id_and_a_name() {
    let root = parse(
        r#"<scene version="3.0.0" id="root" name="n" type="scene"><bsdf type="d" id="x"/></scene>"#,
    )
    .unwrap();
    assert_eq!(root.children.len(), 1);
    let e = error(
        r#"<scene version="3.0.0" id="root"><shape type="a"><ref id="root"/></shape></scene>"#,
    );
    assert!(e.contains("cyclic reference"), "{e}");
    let e = error(r#"<scene version="3.0.0" id="root"><shape type="a" id="root"/></scene>"#);
    assert!(e.contains("duplicate id \"root\""), "{e}");
    let root =
        parse(r#"<scene version="3.0.0" id="root"><alias id="root" as="r2"/></scene>"#).unwrap();
    assert!(root.children.is_empty());
    // penumbra knows no scene plugin but `scene`.
    let e = error(r#"<scene version="3.0.0" type="foo"/>"#);
    assert!(e.contains("unknown scene plugin \"foo\""), "{e}");
}

/// test61: cycles through references, in any number of steps.
#[test]
fn reference_cycles_fail() {
    for body in [
        r#"<shape type="sphere" id="shape1"><ref id="shape1" name="child"/></shape>"#,
        r#"<shape type="sphere" id="shape1"><ref id="shape2" name="child"/></shape>
           <shape type="cube" id="shape2"><ref id="shape1" name="child"/></shape>"#,
        r#"<shape type="sphere" id="A"><ref id="B" name="child"/></shape>
           <shape type="cube" id="B"><ref id="C" name="child"/></shape>
           <shape type="cube" id="C"><ref id="A" name="child"/></shape>"#,
    ] {
        let e = error(&scene(body));
        assert!(e.contains("cyclic reference"), "{body}: {e}");
    }
}

// ---------------------------------------------------------------------------------------
// Includes (test_parser.py test31-37, test63_resource_path_management).
// ---------------------------------------------------------------------------------------

/// test31-34 and 36: an included file whose root is an object contributes that object (named
/// by the include's `name`, its own id kept); an included `<scene>` contributes its objects,
/// nested includes too; parameters reach included files, and their defaults stay.
#[test]
fn includes_bring_objects_as_mitsuba_does() {
    let dir = TempDir::new("includes");
    dir.write(
        "sub/shape.xml",
        r#"<shape type="rectangle" version="3.5.0" id="rect" name="ignored">
             <float name="width" value="2.0"/><include filename="deep.xml"/>
           </shape>"#,
    );
    dir.write(
        "sub/deep.xml",
        r#"<shape type="sphere" version="3.5.0"><float name="radius" value="$radius"/></shape>"#,
    );
    dir.write(
        "fragment.xml",
        r#"<scene version="3.5.0" id="dropped">
             <shape type="sphere" id="sphere_$suffix"/><shape type="cube"/>
             <default name="late" value="7"/>
           </scene>"#,
    );
    let main = dir.write(
        "main.xml",
        scene(
            r#"<shape type="rectangle"><float name="width" value="5.0"/></shape>
               <include filename="sub/shape.xml" name="named"/>
               <include filename="fragment.xml"/>
               <bsdf type="d" id="dropped"><float name="f" value="$late"/></bsdf>"#,
        ),
    );
    let overrides = [
        ("radius".to_string(), "2.5".to_string()),
        ("suffix".to_string(), "test".to_string()),
    ];
    let root = load_file(&main, &overrides).unwrap().root;
    let plugins: Vec<&str> = root
        .children
        .iter()
        .map(|c| c.object.plugin.as_str())
        .collect();
    assert_eq!(plugins, ["rectangle", "rectangle", "sphere", "cube", "d"]);
    let included = &root.children[1];
    assert_eq!(included.name.as_deref(), Some("named"));
    assert_eq!(included.object.id.as_deref(), Some("rect"));
    let deep = &included.object.children[0].object;
    assert_eq!(prop(deep, "radius"), &Value::Float(2.5));
    assert_eq!(root.children[2].object.id.as_deref(), Some("sphere_test"));
    // The fragment's default outlives it, and its root id did not (no duplicate).
    assert_eq!(prop(&root.children[4].object, "f"), &Value::Float(7.0));
    // test33: a relative include is found from the including file's folder.
    let nested = dir.write("sub/nested.xml", scene(r#"<include filename="deep.xml"/>"#));
    let root = load_file(&nested, &overrides[..1]).unwrap().root;
    assert_eq!(first(&root).plugin, "sphere");
}

/// Mitsuba merges only the objects of an included `<scene>`: its properties and references
/// are dropped (a reference there is not even resolved); penumbra warns. Objects of the
/// fragment replace same-named entries of the including element.
#[test]
fn included_scene_properties_and_references_are_dropped() {
    let dir = TempDir::new("drop");
    dir.write(
        "props.xml",
        r#"<scene version="3.0.0"><float name="radius" value="2"/><ref id="nowhere" name="bsdf"/>
             <bsdf type="x" name="named"/><bsdf type="y"/></scene>"#,
    );
    let main = dir.write(
        "main.xml",
        scene(r#"<shape type="sphere"><bsdf type="old" name="named"/><include filename="props.xml"/></shape>"#),
    );
    let doc = load_file(&main, &[]).unwrap();
    let shape = first(&doc.root);
    assert!(shape.properties.is_empty(), "{:?}", shape.properties);
    let children: Vec<(Option<&str>, &str)> = shape
        .children
        .iter()
        .map(|c| (c.name.as_deref(), c.object.plugin.as_str()))
        .collect();
    assert_eq!(children, [(Some("named"), "x"), (None, "y")]);
    let warnings = doc.warnings.join("\n");
    assert!(
        warnings.contains("property \"radius\" directly inside an included <scene> is ignored"),
        "{warnings}"
    );
    assert!(
        warnings.contains(
            "<ref id=\"nowhere\" name=\"bsdf\"> directly inside an included <scene> is ignored"
        ),
        "{warnings}"
    );
    assert!(
        warnings.contains("replaces the earlier entry named \"named\""),
        "{warnings}"
    );
    // Their errors are still errors.
    dir.write(
        "bad.xml",
        r#"<scene version="3.0.0"><float name="r" value="x"/></scene>"#,
    );
    let main = dir.write("main2.xml", scene(r#"<include filename="bad.xml"/>"#));
    let e = load_file(&main, &[]).unwrap_err().to_string();
    assert!(
        e.contains("could not parse floating point value \"x\""),
        "{e}"
    );
}

/// The roots Mitsuba accepts in an included file: an object (with `version`, `type`, `id`,
/// `name`), a `<scene>`, or an object without `type`, which Mitsuba takes for a scene; not a
/// property or another element (their `version` is an unexpected attribute).
#[test]
fn included_roots_follow_mitsuba() {
    let dir = TempDir::new("roots");
    dir.write(
        "typeless.xml",
        r#"<shape version="3.0.0"><bsdf type="a"/><bsdf type="b"/></shape>"#,
    );
    dir.write(
        "float.xml",
        r#"<float name="x" value="1" version="3.0.0"/>"#,
    );
    dir.write("odd.xml", r#"<shape type="s" version="3.0.0" extra="1"/>"#);
    dir.write("scene_type.xml", r#"<scene version="3.0.0" type="other"/>"#);
    let load = |file: &str| {
        let main = dir.write(
            "main.xml",
            scene(&format!(
                r#"<shape type="s"><include filename="{file}"/></shape>"#
            )),
        );
        load_file(&main, &[])
    };
    let root = load("typeless.xml").unwrap().root;
    assert_eq!(first(&root).children.len(), 2);
    let e = load("float.xml").unwrap_err().to_string();
    assert!(
        e.contains("float.xml:1:1") && e.contains("unexpected attribute \"version\""),
        "{e}"
    );
    let e = load("odd.xml").unwrap_err().to_string();
    assert!(e.contains("unexpected attribute \"extra\""), "{e}");
    let e = load("scene_type.xml").unwrap_err().to_string();
    assert!(e.contains("unknown scene plugin \"other\""), "{e}");
}

/// Ids across includes: each included file has its own ids while it is parsed (an alias
/// there cannot name the including file's ids), then they join the scene's (a duplicate is
/// an error); an included `<scene>`'s own id is dropped with it.
#[test]
fn ids_across_includes_follow_mitsuba() {
    let dir = TempDir::new("ids");
    dir.write(
        "alias.xml",
        r#"<scene version="3.0.0"><alias id="m" as="m2"/></scene>"#,
    );
    dir.write(
        "own.xml",
        r#"<scene version="3.0.0" id="own"><bsdf type="b" id="n"/><alias id="n" as="n2"/><alias id="own" as="own2"/></scene>"#,
    );
    dir.write(
        "dup.xml",
        r#"<scene version="3.0.0" id="x"><bsdf type="b" id="x"/></scene>"#,
    );
    dir.write(
        "clash.xml",
        r#"<scene version="3.0.0"><bsdf type="b" id="m"/></scene>"#,
    );
    let load = |body: &str| {
        let main = dir.write("main.xml", scene(body));
        load_file(&main, &[])
    };
    let e = load(r#"<bsdf type="d" id="m"/><include filename="alias.xml"/>"#)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("alias.xml:1:24") && e.contains("alias source id \"m\" not found"),
        "{e}"
    );
    // The file's own ids, and aliases of them, are fine; its root id and that alias are gone.
    let root = load(
        r#"<bsdf type="d" id="own"/><include filename="own.xml"/><shape type="s"><ref id="n2"/></shape>"#,
    )
    .unwrap()
    .root;
    assert!(Arc::ptr_eq(
        &root.children[2].object.children[0].object,
        &root.children[1].object
    ));
    let e = load(r#"<include filename="own.xml"/><shape type="s"><ref id="own2"/></shape>"#)
        .unwrap_err()
        .to_string();
    assert!(e.contains("unknown id \"own2\""), "{e}");
    let e = load(r#"<include filename="dup.xml"/>"#)
        .unwrap_err()
        .to_string();
    assert!(e.contains("duplicate id \"x\""), "{e}");
    let e = load(r#"<bsdf type="d" id="m"/><include filename="clash.xml"/>"#)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("clash.xml:1:24") && e.contains("duplicate id \"m\""),
        "{e}"
    );
}

/// test35: a missing file, no `filename`; `name` is the only other attribute; an include
/// takes no child elements; at most 15 files deep (Mitsuba's `max_include_depth`).
#[test]
fn include_limits_and_errors_follow_mitsuba() {
    let dir = TempDir::new("include-limits");
    let e = error(&scene(r#"<include filename="nonexistent.xml"/>"#));
    assert!(e.contains("not found"), "{e}");
    let e = error(&scene(r#"<include/>"#));
    assert!(e.contains("missing attribute \"filename\""), "{e}");
    let e = error(&scene(r#"<include filename="x.xml" foo="1"/>"#));
    assert!(e.contains("unexpected attribute \"foo\""), "{e}");
    dir.write("leaf.xml", scene(""));
    let main = dir.write(
        "main.xml",
        scene(r#"<include filename="leaf.xml"><shape type="a"/></include>"#),
    );
    let e = load_file(&main, &[]).unwrap_err().to_string();
    assert!(e.contains("cannot appear inside <include"), "{e}");
    // A chain of 15 files loads, 16 do not.
    let chain = |files: usize| {
        for i in 0..files - 1 {
            dir.write(
                &format!("c{i}.xml"),
                scene(&format!(r#"<include filename="c{}.xml"/>"#, i + 1)),
            );
        }
        dir.write(
            &format!("c{}.xml", files - 1),
            scene(r#"<bsdf type="end"/>"#),
        );
        load_file(&dir.0.join("c0.xml"), &[])
    };
    assert_eq!(first(&chain(15).unwrap().root).plugin, "end");
    let e = chain(16).unwrap_err().to_string();
    assert!(e.contains("include depth limit of 15"), "{e}");
}

/// test63: `<path>` must be a direct child of its file's root element (an included object's
/// too) and name something that exists.
#[test]
fn path_follows_mitsuba() {
    let dir = TempDir::new("paths");
    dir.write("data/image.png", "x");
    dir.write(
        "object.xml",
        r#"<shape type="s" version="3.0.0"><path value="data"/></shape>"#,
    );
    let main = dir.write(
        "main.xml",
        scene(r#"<path value="data/image.png"/><include filename="object.xml"/>"#),
    );
    let doc = load_file(&main, &[]).unwrap();
    assert_eq!(doc.resolver.paths()[0], dir.0.join("data/image.png"));
    let e = error(&scene(r#"<shape type="sphere"><path value="."/></shape>"#));
    assert!(
        e.contains("can only appear directly inside the root element"),
        "{e}"
    );
    let bad = dir.write("bad.xml", scene(r#"<path value="nonexistent_directory"/>"#));
    let e = load_file(&bad, &[]).unwrap_err().to_string();
    assert!(
        e.contains("folder") && e.contains("nonexistent_directory\" not found"),
        "{e}"
    );
}

// ---------------------------------------------------------------------------------------
// Structure, values and transforms (test_parser.py test03, test07, test12-18, test21,
// test38, test40-45).
// ---------------------------------------------------------------------------------------

/// test12-14: an element that takes no children refuses child elements (what is inside a
/// transform operation is ignored, as Mitsuba never looks); test38: unknown attributes.
#[test]
fn leaf_elements_refuse_child_elements() {
    for body in [
        r#"<integer name="value" value="1"><shape type="ply"/></integer>"#,
        r#"<integer name="value" value="1"><float name="value" value="1"/></integer>"#,
        r#"<ref id="m"><float name="a" value="1"/></ref>"#,
        r#"<string name="a" value="x"><string name="b" value="y"/></string>"#,
    ] {
        let e = error(&scene(&format!(
            r#"<bsdf type="d" id="m"/><shape type="ply">{body}</shape>"#
        )));
        assert!(e.contains("cannot appear inside"), "{body}: {e}");
    }
    for body in [
        r#"<default name="n" value="v"><foo/></default>"#,
        r#"<bsdf type="d" id="m"/><alias id="m" as="n"><foo/></alias>"#,
    ] {
        let e = error(&scene(body));
        assert!(e.contains("<foo> cannot appear inside"), "{body}: {e}");
    }
    let e = transform_error(r#"<integer name="value" value="10"/>"#);
    assert!(
        e.contains("unexpected <integer name=\"value\"> inside <transform>"),
        "{e}"
    );
    let m = transform(r#"<translate x="1"><scale value="5"/><junk/></translate>"#);
    assert_mat(m, DMat4::from_translation(DVec3::X));
    for body in [
        r#"<vector name="position" x="1" y="2" z="3" foo="bar"/>"#,
        r#"<float name="radius" value="1.0" invalid="true"/>"#,
        r#"<transform name="t" foo="1"/>"#,
        r#"<ref id="m" foo="1"/>"#,
    ] {
        let e = error(&scene(&format!(
            r#"<bsdf type="d" id="m"/><shape type="sphere">{body}</shape>"#
        )));
        assert!(e.contains("unexpected attribute"), "{body}: {e}");
    }
    let e = error(&scene(r#"<shape type="sphere" unknown="value"/>"#));
    assert!(e.contains("unexpected attribute \"unknown\""), "{e}");
}

/// Mitsuba's number syntax (`string::stof`, `std::from_chars`), test03, test16, test18.
#[test]
fn numbers_parse_like_mitsuba() {
    let value = |tag: &str, text: &str| -> Result<Value> {
        let root = parse(&scene(&format!(
            r#"<shape type="a"><{tag} name="v" value="{text}"/></shape>"#
        )))?;
        Ok(prop(first(&root), "v").clone())
    };
    let float = |text: &str| value("float", text);
    for (text, expected) in [
        ("2.5", 2.5),
        ("-3.25", -3.25),
        (" 1.5 ", 1.5),
        ("\t1.5\t", 1.5),
        ("+1", 1.0),
        ("+-1", -1.0),
        ("1.", 1.0),
        (".5", 0.5),
        ("1E+2", 100.0),
        ("", 0.0),
        ("   ", 0.0),
        ("1e-400", 0.0),
    ] {
        assert_eq!(float(text).unwrap(), Value::Float(expected), "{text:?}");
    }
    for text in [
        "foo", "1.0f", "0x10", "1,5", "++1", "-+1", "1e", ".", "-", "+", "1 2", "&#10;1",
    ] {
        let e = float(text).unwrap_err().to_string();
        assert!(
            e.contains("could not parse floating point value"),
            "{text:?}: {e}"
        );
    }
    // Mitsuba accepts these; penumbra refuses non-finite numbers (see the module docs).
    for text in ["inf", "-Infinity", "nan", "1e999"] {
        let e = float(text).unwrap_err().to_string();
        assert!(e.contains("non-finite"), "{text:?}: {e}");
    }
    let integer = |text: &str| value("integer", text);
    for (text, expected) in [
        ("16", 16),
        (" 5 ", 5),
        ("&#10;5&#10;", 5),
        ("-0", 0),
        ("007", 7),
    ] {
        assert_eq!(integer(text).unwrap(), Value::Integer(expected), "{text:?}");
    }
    assert_eq!(
        integer("-9223372036854775808").unwrap(),
        Value::Integer(i64::MIN)
    );
    for text in [
        "+5",
        "1e3",
        "",
        "9223372036854775808",
        "5 5",
        "0x1",
        "3.5",
        "-",
    ] {
        let e = integer(text).unwrap_err().to_string();
        assert!(e.contains("could not parse integer value"), "{text:?}: {e}");
    }
    let boolean = |text: &str| value("boolean", text);
    assert_eq!(boolean("TrUe").unwrap(), Value::Boolean(true));
    assert_eq!(boolean("FALSE").unwrap(), Value::Boolean(false));
    for text in [" true", "a", "1", "yes"] {
        let e = boolean(text).unwrap_err().to_string();
        assert!(e.contains("must be \"true\" or \"false\""), "{text:?}: {e}");
    }
    let rgb = |text: &str| value("rgb", text);
    assert_eq!(
        rgb("1,,2 ,3").unwrap(),
        Value::Rgb(DVec3::new(1.0, 2.0, 3.0))
    );
    assert_eq!(rgb("0.5").unwrap(), Value::Rgb(DVec3::splat(0.5)));
    for text in ["", "1 2", "1 2 3 4"] {
        let e = rgb(text).unwrap_err().to_string();
        assert!(e.contains("one or three values"), "{text:?}: {e}");
    }
    assert_eq!(value("string", "").unwrap(), Value::String(String::new()));
}

/// test07, test17, test21: `<point>` and `<vector>` take `value` (one or three numbers) or all
/// of `x`, `y` and `z` (an empty one is 0); `<float>` needs `name` and `value`.
#[test]
fn points_and_vectors_need_all_components() {
    let root = parse(&scene(
        r#"<shape type="foo">
             <vector name="direction" value="1 0 0"/><point name="position" value="0 2 -1"/>
             <vector name="up" x="0" y="1" z="0"/><point name="p" x="" y="1" z="2"/>
             <point name="q" value="3"/>
           </shape>"#,
    ))
    .unwrap();
    let shape = first(&root);
    assert_eq!(prop(shape, "direction"), &Value::Vector(DVec3::X));
    assert_eq!(
        prop(shape, "position"),
        &Value::Point(DVec3::new(0.0, 2.0, -1.0))
    );
    assert_eq!(prop(shape, "up"), &Value::Vector(DVec3::Y));
    assert_eq!(prop(shape, "p"), &Value::Point(DVec3::new(0.0, 1.0, 2.0)));
    assert_eq!(prop(shape, "q"), &Value::Point(DVec3::splat(3.0)));
    for (body, expected) in [
        (
            r#"<point name="p" x="1" z="3"/>"#,
            "missing attribute \"y\" in <point name=\"p\">",
        ),
        (r#"<vector name="v"/>"#, "missing attribute \"x\""),
        (
            r#"<vector name="10" value="1, 2, 3" x="4"/>"#,
            "cannot mix \"value\" and \"x\"/\"y\"/\"z\"",
        ),
        (
            r#"<point name="p" value=""/>"#,
            "exactly 1 or 3 elements, found 0",
        ),
        (
            r#"<point x="1" y="2" z="3"/>"#,
            "missing attribute \"name\"",
        ),
        (r#"<float name="radius"/>"#, "missing attribute \"value\""),
        (r#"<float value="1.0"/>"#, "missing attribute \"name\""),
    ] {
        let e = error(&scene(&format!(r#"<shape type="a">{body}</shape>"#)));
        assert!(e.contains(expected), "{body}: {e}");
    }
}

/// test40-44: operations compose as `T = M · T`, with Mitsuba's forms of each; an empty
/// component is 0 (also in `<scale>`), an empty `up` is a chosen one; test45: operations
/// outside a `<transform>` are refused.
#[test]
fn transform_operations_follow_mitsuba() {
    let m = transform(
        r#"<translate x="1" y="0" z="0"/><rotate angle="90" x="0" y="1" z="0"/><scale value="2"/><translate x="0" y="1" z="0"/>"#,
    );
    let expected = DMat4::from_translation(DVec3::Y)
        * DMat4::from_scale(DVec3::splat(2.0))
        * mitsuba_rotate(DVec3::Y, 90.0)
        * DMat4::from_translation(DVec3::X);
    assert_mat(m, expected);
    // test43: a row-major matrix equal to a rotation by 90 degrees about y.
    let m = transform(r#"<matrix value="0 0 1 0  0 1 0 0  -1 0 0 0  0 0 0 1"/>"#);
    assert_mat(m, mitsuba_rotate(DVec3::Y, 90.0));
    let e = transform_error(r#"<matrix value="1 2 3 4 5"/>"#);
    assert!(e.contains("16 (or 9) values, found 5"), "{e}");
    assert_mat(transform(r#"<translate x=""/>"#), DMat4::IDENTITY);
    assert_mat(
        transform(r#"<scale x="" y="2"/>"#),
        DMat4::from_scale(DVec3::new(0.0, 2.0, 1.0)),
    );
    assert_mat(
        transform(r#"<rotate value="0 0 1" angle="90"/>"#),
        mitsuba_rotate(DVec3::Z, 90.0),
    );
    assert_mat(transform(r#"<rotate z="1" angle=""/>"#), DMat4::IDENTITY);
    // Mitsuba's choice of `up` for a direction along z, as Mitsuba 3.9.1 prints it.
    let m = transform(r#"<lookat origin="0 0 0" target="0 0 1" up=""/>"#);
    assert_mat(m, DMat4::from_cols(-DVec4::Y, DVec4::X, DVec4::Z, DVec4::W));
    // Only an exactly parallel `up` leaves no frame, as in Mitsuba.
    let m = transform(r#"<lookat origin="0 0 0" target="0 1 0" up="0 1 1e-12"/>"#);
    assert_vec(m.z_axis.truncate(), DVec3::Y);
    let e = transform_error(r#"<lookat origin="0 0 0" target="0 1 0" up="0 2 0"/>"#);
    assert!(e.contains("parallel"), "{e}");
    let e = transform_error(r#"<lookat origin="0 0 0" target="0 1 0" up="0 1"/>"#);
    assert!(e.contains("exactly 3 components, found 2"), "{e}");
    let e = transform_error(r#"<lookat target="0 1 0"/>"#);
    assert!(e.contains("missing attribute \"origin\""), "{e}");
    let e = transform_error(r#"<rotate x="0" angle="1"/>"#);
    assert!(e.contains("zero rotation axis"), "{e}");
    let e = transform_error(r#"<rotate x="1" angle="a"/>"#);
    assert!(
        e.contains("could not parse floating point value \"a\""),
        "{e}"
    );
    let e = transform_error(r#"<translate x="1" w="2"/>"#);
    assert!(e.contains("unexpected attribute \"w\""), "{e}");
    let e = error(&scene(
        r#"<shape type="sphere"><translate x="1" y="0" z="0"/></shape>"#,
    ));
    assert!(e.contains("outside of a <transform>"), "{e}");
}

/// Many `<default>`s are read in linear time (Mitsuba's sorted list, kept in buckets by name
/// length), and `$` values cannot make the substitution scan without bound.
#[test]
fn many_parameters_are_bounded() {
    // No wall-clock bound (a timed unit test flakes on a loaded machine: 15.9 s at load 10
    // against a 10 s limit): a quadratic regression over 200,000 defaults takes hours here,
    // and the text scanned for `$` references is bounded by the scan budget, asserted below.
    let defaults: String = (0..200_000)
        .map(|i| format!(r#"<default name="d{i}" value="{i}"/>"#))
        .collect();
    let xml = scene(&format!(
        r#"{defaults}<default name="d0" value="again"/><shape type="$d199999"><string name="s" value="$d0"/></shape>"#
    ));
    let root = parse(&xml).unwrap();
    assert_eq!(first(&root).plugin, "199999");
    assert_eq!(prop(first(&root), "s"), &Value::String("0".into()));
    // Each value with a `$` is searched once per parameter: 200000 parameters times 100
    // values of 2000 bytes is more than the scan budget.
    let long = format!("$d0{}", "x".repeat(2000));
    let values: String = (0..100)
        .map(|i| format!(r#"<string name="s{i}" value="{long}"/>"#))
        .collect();
    let e = error(&scene(&format!(
        r#"{defaults}<shape type="a">{values}</shape>"#
    )));
    assert!(e.contains("scans too much text"), "{e}");
}

/// test05 and test09: pugixml's error position, and a document of only a declaration.
#[test]
fn xml_errors_are_located_like_pugixml() {
    let xml = "<scene version=\"3.0.0\">\n    <shape type=\"sphere\">\n        <float name=\"radius\" value=\"1.0\"\n    </shape>\n</scene>";
    match parse(xml) {
        Err(Error::Xml { message, .. }) => {
            assert_eq!(message, "Error parsing start element tag (at 4:5)")
        }
        other => panic!("expected an XML error, got {other:?}"),
    }
    match parse("<?xml version=\"1.0\"?>") {
        Err(Error::Xml { message, .. }) => {
            assert!(
                message.starts_with("No document element found"),
                "{message}"
            )
        }
        other => panic!("expected an XML error, got {other:?}"),
    }
}

/// test23: `<spectrum>` takes one number or increasing wavelength:value pairs.
#[test]
fn spectrum_properties_follow_mitsuba() {
    use crate::spectrum::SpectrumValue;
    let root = parse(&scene(
        r#"<phase type="foo"><spectrum name="u" value="0.5"/><spectrum name="s" value="400:0.1 500:0.5 600:0.9"/></phase>"#,
    ))
    .unwrap();
    let phase = first(&root);
    assert_eq!(
        prop(phase, "u"),
        &Value::Spectrum(SpectrumValue::Uniform(0.5))
    );
    assert_eq!(
        prop(phase, "s"),
        &Value::Spectrum(SpectrumValue::parse("400:0.1, 500:0.5, 600:0.9").unwrap())
    );
    assert!(matches!(
        prop(phase, "s"),
        Value::Spectrum(SpectrumValue::Sampled { .. })
    ));
    for value in ["400:0.5", "500:0.5, 400:0.1, 600:0.9", "foo bar"] {
        let e = error(&scene(&format!(
            r#"<spectrum name="value" value="{value}"/>"#
        )));
        assert!(e.contains("<spectrum name=\"value\">"), "{value}: {e}");
    }
    let e = error(&scene(r#"<spectrum name="v" value="1" filename="x.spd"/>"#));
    assert!(e.contains("either a \"value\" or a \"filename\""), "{e}");
    let e = error(&scene(r#"<spectrum name="v"/>"#));
    assert!(e.contains("either a \"value\" or a \"filename\""), "{e}");
}

/// Random documents, made of XML's significant pieces (and bytes that are not UTF-8) or of
/// elements with random tags, attributes and values, load or fail with one line, never
/// panic, and take linear time.
#[test]
fn random_markup_never_panics() {
    const PIECES: &[&[u8]] = &[
        b"<",
        b">",
        b"/",
        b"/>",
        b"</",
        b"!--",
        b"-->",
        b"--",
        b"<![CDATA[",
        b"]]>",
        b"<?",
        b"?>",
        b"<!DOCTYPE",
        b"[",
        b"]",
        b"\"",
        b"'",
        b"=",
        b"&",
        b"&#x4",
        b"&#10;",
        b"&#1",
        b";",
        b"&amp;",
        b" ",
        b"\n",
        b"\r",
        b"\t",
        b"\0",
        b"\xff",
        b"\xc3\xa9",
        b"\xef\xbb\xbf",
        b"scene",
        b"version=\"3.0.0\"",
        b"<scene version=\"3.0.0\">",
        b"</scene>",
        b"shape",
        b"type=\"a\"",
        b"<shape type=\"a\">",
        b"</shape>",
        b"name=\"n\"",
        b"value=\"",
        b"$",
        b"xml",
        b"a:b",
    ];
    const TAGS: &[&str] = &[
        "shape",
        "bsdf",
        "float",
        "integer",
        "boolean",
        "string",
        "rgb",
        "point",
        "vector",
        "spectrum",
        "transform",
        "translate",
        "rotate",
        "scale",
        "matrix",
        "lookat",
        "ref",
        "alias",
        "default",
        "path",
        "scene",
        "foo",
    ];
    const ATTRIBUTES: &[&str] = &[
        "name", "type", "value", "id", "x", "y", "z", "angle", "origin", "target", "up", "as",
        "version", "filename",
    ];
    const VALUES: &[&str] = &[
        "1", "0", " ", ",", "&#1", "&#10;", "&#x41;", "&#0;", "$d", "\\$", "$", "a", "maxDepth",
        "uscale", "diffuse", "-", "e5", "nan", "1e308", "0 0 1", "\u{e9}",
    ];
    let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 33) as usize
    };
    fn element(out: &mut String, depth: usize, next: &mut dyn FnMut() -> usize) {
        let tag = TAGS[next() % TAGS.len()];
        out.push('<');
        out.push_str(tag);
        for _ in 0..next() % 4 {
            out.push_str(&format!(" {}=\"", ATTRIBUTES[next() % ATTRIBUTES.len()]));
            for _ in 0..next() % 4 {
                out.push_str(VALUES[next() % VALUES.len()]);
            }
            out.push('"');
        }
        if depth < 3 && next().is_multiple_of(2) {
            out.push('>');
            for _ in 0..next() % 4 {
                element(out, depth + 1, next);
            }
            out.push_str(&format!("</{tag}>"));
        } else {
            out.push_str("/>");
        }
    }
    let (mut loaded, mut refused) = (0, 0);
    for i in 0..100_000 {
        let doc = if i % 2 == 0 {
            let mut doc = Vec::new();
            for _ in 0..next() % 48 {
                doc.extend_from_slice(PIECES[next() % PIECES.len()]);
            }
            doc
        } else {
            let version = ["3.0.0", "1.0.0"][next() % 2];
            let mut doc = format!(r#"<scene version="{version}"><default name="d" value="1"/>"#);
            for _ in 0..next() % 6 {
                element(&mut doc, 0, &mut next);
            }
            doc.push_str("</scene>");
            doc.into_bytes()
        };
        match load_bytes(&doc, Path::new("scene.xml"), &[]) {
            Ok(_) => loaded += 1,
            Err(e) => {
                let line = e.to_string();
                assert!(!line.is_empty() && !line.contains(['\n', '\r']), "{line:?}");
                refused += 1;
            }
        }
    }
    // Both outcomes are reached (the seed is fixed, so these counts are too).
    assert!(
        loaded > 1000 && refused > 50_000,
        "{loaded} loaded, {refused} refused"
    );
}
