//! The typed scene description: `scene::xml::load_str` followed by
//! `scene::description::from_xml`, for every supported plugin and parameter, Mitsuba's
//! defaults, and the errors for everything outside the supported subset.

use glam::{DMat4, DVec2, DVec3, DVec4};
use penumbra::camera::FovAxis;
use penumbra::sampler::SamplerKind;
use penumbra::scene::build::build;
use penumbra::scene::description::{
    from_xml, BsdfDesc, ColorDesc, EmitterDesc, FilterDesc, IntegratorDesc, SamplerDesc,
    SceneDescription, ShapeDesc, ShapeKind, SpectralDesc, TextureDesc, VolumeDesc, MAX_RESOLUTION,
};
use penumbra::scene::xml::load_str;
use penumbra::shape::ShapeGeometry;
use penumbra::spectrum::{ColorRole, SpectrumValue};
use std::path::{Path, PathBuf};

/// The path the scenes pretend to come from (it is never read).
const FILE: &str = "/virtual/dir/scene.xml";

/// A valid sensor: perspective, 32x24 box-filtered hdrfilm, no sampler.
const SENSOR: &str = r#"<sensor type="perspective">
    <float name="fov" value="45"/>
    <film type="hdrfilm">
        <integer name="width" value="32"/>
        <integer name="height" value="24"/>
        <rfilter type="box"/>
    </film>
</sensor>"#;

fn scene(body: &str) -> String {
    format!("<scene version=\"3.0.0\">\n{body}\n</scene>\n")
}

/// A scene with [`SENSOR`] followed by `body`.
fn with_sensor(body: &str) -> String {
    scene(&format!("{SENSOR}\n{body}"))
}

/// A scene whose sensor has the extra `props` and the film the extra `film_props`, and
/// whose film's children are `film_children`.
fn sensor_scene(props: &str, film_props: &str, film_children: &str) -> String {
    scene(&format!(
        r#"<sensor type="perspective">
    {props}
    <film type="hdrfilm">
        {film_props}
        {film_children}
    </film>
</sensor>"#
    ))
}

fn parse(xml: &str) -> penumbra::Result<SceneDescription> {
    let doc = load_str(xml, Path::new(FILE), &[])?;
    from_xml(&doc)
}

fn desc(xml: &str) -> SceneDescription {
    parse(xml).unwrap_or_else(|e| panic!("expected a valid scene, got: {e}\n{xml}"))
}

fn error(xml: &str) -> String {
    match parse(xml) {
        Ok(d) => panic!("expected an error, got {d:?}\n{xml}"),
        Err(e) => e.to_string(),
    }
}

/// The 1-based line of the first occurrence of `needle` in `xml`.
fn line_of(xml: &str, needle: &str) -> usize {
    let offset = xml
        .find(needle)
        .unwrap_or_else(|| panic!("{needle} not in {xml}"));
    1 + xml[..offset].matches('\n').count()
}

/// Asserts that the error of `xml` starts with the location of the line holding `at` and
/// contains every one of `parts`.
fn assert_error(xml: &str, at: &str, parts: &[&str]) {
    let message = error(xml);
    let location = format!("{FILE}:{}:", line_of(xml, at));
    assert!(
        message.starts_with(&location),
        "error should start with {location}: {message}"
    );
    for part in parts {
        assert!(
            message.contains(part),
            "error should contain {part:?}: {message}"
        );
    }
}

/// The only shape of a scene made of [`SENSOR`] and `shape`.
fn one_shape(shape: &str) -> ShapeDesc {
    let mut d = desc(&with_sensor(shape));
    assert_eq!(d.shapes.len(), 1);
    d.shapes.remove(0)
}

fn assert_mat(actual: DMat4, expected: DMat4) {
    assert!(
        actual.abs_diff_eq(expected, 1e-12),
        "got {actual:?}, expected {expected:?}"
    );
}

const PATH_DEFAULTS: IntegratorDesc = IntegratorDesc::Path {
    max_depth: -1,
    rr_depth: 5,
    hide_emitters: false,
};

// ---------------------------------------------------------------------------------------
// Integrator
// ---------------------------------------------------------------------------------------

#[test]
fn absent_integrator_is_path_with_defaults() {
    let d = desc(&scene(SENSOR));
    assert_eq!(d.integrator, PATH_DEFAULTS);
    assert!(d.shapes.is_empty());
}

#[test]
fn path_integrator_defaults() {
    let d = desc(&with_sensor(r#"<integrator type="path"/>"#));
    assert_eq!(d.integrator, PATH_DEFAULTS);
}

#[test]
fn path_integrator_parameters() {
    let d = desc(&with_sensor(
        r#"<integrator type="path">
    <integer name="max_depth" value="8"/>
    <integer name="rr_depth" value="3"/>
    <boolean name="hide_emitters" value="true"/>
</integrator>"#,
    ));
    assert_eq!(
        d.integrator,
        IntegratorDesc::Path {
            max_depth: 8,
            rr_depth: 3,
            hide_emitters: true
        }
    );
    // The boundaries: -1 (unbounded), 0 and rr_depth 1 are valid.
    for (max_depth, rr_depth) in [(-1, 1), (0, 1), (1, 100)] {
        let d = desc(&with_sensor(&format!(
            r#"<integrator type="path">
    <integer name="max_depth" value="{max_depth}"/>
    <integer name="rr_depth" value="{rr_depth}"/>
</integrator>"#
        )));
        assert_eq!(
            d.integrator,
            IntegratorDesc::Path {
                max_depth,
                rr_depth,
                hide_emitters: false
            }
        );
    }
}

#[test]
fn integrator_order_does_not_matter() {
    let d = desc(&scene(&format!(
        "{SENSOR}\n<integrator type=\"path\"><integer name=\"max_depth\" value=\"2\"/></integrator>"
    )));
    assert_eq!(
        d.integrator,
        IntegratorDesc::Path {
            max_depth: 2,
            rr_depth: 5,
            hide_emitters: false
        }
    );
}

#[test]
fn max_depth_below_minus_one_fails() {
    let xml = with_sensor(
        r#"<integrator type="path">
    <integer name="max_depth" value="-2"/>
</integrator>"#,
    );
    assert_error(
        &xml,
        "<integrator",
        &["max_depth", "<integrator type=\"path\">", "got -2"],
    );
}

#[test]
fn rr_depth_must_be_positive() {
    for value in ["0", "-1"] {
        let xml = with_sensor(&format!(
            r#"<integrator type="path">
    <integer name="rr_depth" value="{value}"/>
</integrator>"#
        ));
        assert_error(
            &xml,
            "<integrator",
            &[
                "rr_depth",
                "<integrator type=\"path\">",
                &format!("got {value}"),
            ],
        );
    }
}

#[test]
fn unknown_integrator_fails() {
    let xml = with_sensor(r#"<integrator type="pssmlt"/>"#);
    assert_error(
        &xml,
        "<integrator",
        &["unsupported plugin <integrator type=\"pssmlt\">"],
    );
}

#[test]
fn integrator_parameter_errors() {
    let xml = with_sensor(
        r#"<integrator type="path">
    <float name="max_depth" value="3"/>
</integrator>"#,
    );
    assert_error(
        &xml,
        "<float name=\"max_depth\"",
        &["parameter 'max_depth' of <integrator type=\"path\"> must be an integer, not float"],
    );
    // (Mitsuba's path reads samples_per_pass, deprecated; max_bounces is nobody's.)
    let xml = with_sensor(
        r#"<integrator type="path">
    <integer name="max_bounces" value="3"/>
</integrator>"#,
    );
    assert_error(
        &xml,
        "max_bounces",
        &["unknown parameter 'max_bounces' (integer) of <integrator type=\"path\">"],
    );
    let xml = with_sensor(
        r#"<integrator type="path">
    <float name="timeout" value="-2"/>
</integrator>"#,
    );
    assert_error(
        &xml,
        "<integrator",
        &["timeout of <integrator type=\"path\"> must be >= 0 seconds or -1"],
    );
    let xml = with_sensor(
        r#"<integrator type="path">
    <string name="hide_emitters" value="true"/>
</integrator>"#,
    );
    assert_error(
        &xml,
        "hide_emitters",
        &["parameter 'hide_emitters' of <integrator type=\"path\"> must be a boolean, not string"],
    );
}

#[test]
fn two_integrators_fail() {
    let xml = with_sensor("<integrator type=\"path\"/>\n<integrator type=\"path\"/>");
    let second = line_of(&xml, "<integrator") + 1;
    let message = error(&xml);
    assert!(
        message.starts_with(&format!("{FILE}:{second}:")),
        "{message}"
    );
    assert!(message.contains("at most one <integrator>"), "{message}");
}

// ---------------------------------------------------------------------------------------
// Sensor
// ---------------------------------------------------------------------------------------

#[test]
fn perspective_sensor_defaults() {
    let xml = scene(SENSOR);
    let s = desc(&xml).sensor;
    assert_eq!(s.fov, 45.0);
    assert_eq!(s.fov_axis, FovAxis::X);
    assert_eq!(s.near_clip, 0.01);
    assert_eq!(s.far_clip, 1e4);
    assert_eq!(s.to_world, DMat4::IDENTITY);
    assert_eq!(s.location.file, PathBuf::from(FILE));
    assert_eq!(s.location.line as usize, line_of(&xml, "<sensor"));
}

#[test]
fn perspective_sensor_parameters() {
    let xml = sensor_scene(
        r#"<float name="fov" value="39.3077"/>
    <float name="near_clip" value="0.001"/>
    <float name="far_clip" value="100"/>
    <float name="focus_distance" value="1000"/>
    <transform name="to_world">
        <lookat origin="0, 0, 3.9" target="0, 0, 0" up="0, 1, 0"/>
    </transform>"#,
        "",
        r#"<rfilter type="box"/>"#,
    );
    let s = desc(&xml).sensor;
    assert_eq!(s.fov, 39.3077);
    assert_eq!(s.near_clip, 0.001);
    assert_eq!(s.far_clip, 100.0);
    // Mitsuba's look_at: columns (left, up, dir, origin).
    let expected = DMat4::from_cols(
        DVec4::new(-1.0, 0.0, 0.0, 0.0),
        DVec4::new(0.0, 1.0, 0.0, 0.0),
        DVec4::new(0.0, 0.0, -1.0, 0.0),
        DVec4::new(0.0, 0.0, 3.9, 1.0),
    );
    assert_mat(s.to_world, expected);
}

#[test]
fn integer_fov_is_accepted_as_float() {
    let xml = sensor_scene(
        r#"<integer name="fov" value="60"/>"#,
        "",
        r#"<rfilter type="box"/>"#,
    );
    assert_eq!(desc(&xml).sensor.fov, 60.0);
}

#[test]
fn every_fov_axis() {
    for (name, axis) in [
        ("x", FovAxis::X),
        ("y", FovAxis::Y),
        ("diagonal", FovAxis::Diagonal),
        ("smaller", FovAxis::Smaller),
        ("larger", FovAxis::Larger),
    ] {
        let xml = sensor_scene(
            &format!(
                r#"<float name="fov" value="30"/>
    <string name="fov_axis" value="{name}"/>"#
            ),
            "",
            r#"<rfilter type="box"/>"#,
        );
        assert_eq!(desc(&xml).sensor.fov_axis, axis, "{name}");
    }
    let xml = sensor_scene(
        r#"<float name="fov" value="30"/>
    <string name="fov_axis" value="z"/>"#,
        "",
        r#"<rfilter type="box"/>"#,
    );
    assert_error(
        &xml,
        "fov_axis",
        &["fov_axis must be x, y, diagonal, smaller or larger, not 'z'"],
    );
}

#[test]
fn fov_defaults_to_mitsubas_focal_length() {
    // No fov: Mitsuba's default focal length of 50 mm on a 36 x 24 mm film, as a diagonal
    // field of view.
    let d = desc(&sensor_scene("", "", r#"<rfilter type="box"/>"#));
    let expected = 2.0 * (52f64.sqrt() * 6.0 / 100.0).atan().to_degrees();
    assert!((d.sensor.fov - expected).abs() < 1e-12, "{}", d.sensor.fov);
    assert_eq!(d.sensor.fov_axis, FovAxis::Diagonal);
    let xml = sensor_scene(
        r#"<string name="focal_length" value="wide"/>"#,
        "",
        r#"<rfilter type="box"/>"#,
    );
    assert_error(
        &xml,
        "<sensor",
        &["could not parse the focal length 'wide'"],
    );
}

#[test]
fn fov_must_lie_in_open_interval() {
    for fov in ["0", "180", "-10", "200"] {
        let xml = sensor_scene(
            &format!(r#"<float name="fov" value="{fov}"/>"#),
            "",
            r#"<rfilter type="box"/>"#,
        );
        assert_error(
            &xml,
            "<sensor",
            &[
                "fov of <sensor type=\"perspective\"> must lie in (0, 180) degrees",
                &format!("got {fov}"),
            ],
        );
    }
    for fov in ["0.001", "179.9"] {
        let xml = sensor_scene(
            &format!(r#"<float name="fov" value="{fov}"/>"#),
            "",
            r#"<rfilter type="box"/>"#,
        );
        assert_eq!(desc(&xml).sensor.fov, fov.parse::<f64>().unwrap());
    }
}

#[test]
fn clip_planes_are_checked() {
    let case = |props: &str| {
        sensor_scene(
            &format!("<float name=\"fov\" value=\"30\"/>\n    {props}"),
            "",
            r#"<rfilter type="box"/>"#,
        )
    };
    assert_error(
        &case(r#"<float name="near_clip" value="0"/>"#),
        "<sensor",
        &["near_clip of <sensor type=\"perspective\"> must be positive, got 0"],
    );
    assert_error(
        &case(r#"<float name="far_clip" value="-1"/>"#),
        "<sensor",
        &["far_clip of <sensor type=\"perspective\"> must be positive, got -1"],
    );
    assert_error(
        &case(r#"<float name="near_clip" value="5"/><float name="far_clip" value="5"/>"#),
        "<sensor",
        &["near_clip (5) must be less than far_clip (5)"],
    );
}

#[test]
fn sensor_errors() {
    let xml = scene(
        r#"<sensor type="radiancemeter">
    <float name="fov" value="30"/>
</sensor>"#,
    );
    assert_error(
        &xml,
        "<sensor",
        &["unsupported plugin <sensor type=\"radiancemeter\">"],
    );
    let xml = sensor_scene(
        r#"<float name="fov" value="30"/>
    <float name="aperture_radius" value="0.1"/>"#,
        "",
        r#"<rfilter type="box"/>"#,
    );
    assert_error(
        &xml,
        "aperture_radius",
        &["unknown parameter 'aperture_radius' (float) of <sensor type=\"perspective\">"],
    );
    let xml = sensor_scene(
        r#"<float name="fov" value="30"/>
    <float name="to_world" value="1"/>"#,
        "",
        r#"<rfilter type="box"/>"#,
    );
    assert_error(
        &xml,
        "to_world",
        &["parameter 'to_world' of <sensor type=\"perspective\"> must be a transform, not float"],
    );
    // Without a film: Mitsuba's default hdrfilm, 768x576 with the gaussian filter.
    let d = desc(&scene(
        r#"<sensor type="perspective">
    <float name="fov" value="30"/>
</sensor>"#,
    ));
    assert_eq!(
        (
            d.sensor.film.width,
            d.sensor.film.height,
            d.sensor.film.rfilter
        ),
        (768, 576, FilterDesc::Gaussian { stddev: 0.5 })
    );
    let xml = scene(
        r#"<sensor type="perspective">
    <float name="fov" value="30"/>
    <film type="hdrfilm"><rfilter type="box"/></film>
    <bsdf type="diffuse"/>
</sensor>"#,
    );
    assert_error(
        &xml,
        "<bsdf",
        &["<bsdf type=\"diffuse\"> cannot be nested in <sensor type=\"perspective\">"],
    );
}

#[test]
fn missing_sensor_fails() {
    let message = error(&scene(r#"<shape type="sphere"/>"#));
    assert!(message.contains("no <sensor>"), "{message}");
    let message = error(&scene(""));
    assert!(message.contains("no <sensor>"), "{message}");
}

/// Several sensors load, as in Mitsuba (sionna's scenes have four): the first is rendered
/// (Mitsuba's `mi.render` renders `scene.sensors()[0]`) unless another is selected.
#[test]
fn several_sensors_render_the_first_or_the_selected_one() {
    let second = SENSOR.replace(r#"value="45""#, r#"value="60""#);
    let mut d = desc(&scene(&format!("{SENSOR}\n{second}")));
    assert_eq!(d.sensors.len(), 2);
    assert_eq!(d.sensor.fov, 45.0);
    d.select_sensor(1).unwrap();
    assert_eq!(d.sensor.fov, 60.0);
    d.select_sensor(0).unwrap();
    assert_eq!(d.sensor.fov, 45.0);
    let e = d.select_sensor(2).unwrap_err().to_string();
    assert!(
        e.contains("sensor 2 does not exist: the scene has 2 sensors"),
        "{e}"
    );
}

// ---------------------------------------------------------------------------------------
// Film
// ---------------------------------------------------------------------------------------

#[test]
fn hdrfilm_defaults_and_size() {
    let xml = sensor_scene(
        r#"<float name="fov" value="30"/>"#,
        "",
        r#"<rfilter type="box"/>"#,
    );
    let film = desc(&xml).sensor.film;
    assert_eq!((film.width, film.height), (768, 576));
    assert_eq!(film.rfilter, FilterDesc::Box);
    let film = desc(&scene(SENSOR)).sensor.film;
    assert_eq!((film.width, film.height), (32, 24));
    let film = desc(&sensor_scene(
        r#"<float name="fov" value="30"/>"#,
        r#"<integer name="width" value="1"/><integer name="height" value="1"/>"#,
        r#"<rfilter type="box"><float name="radius" value="0.5"/></rfilter>"#,
    ))
    .sensor
    .film;
    assert_eq!((film.width, film.height), (1, 1));
    let max = MAX_RESOLUTION;
    let film = desc(&sensor_scene(
        r#"<float name="fov" value="30"/>"#,
        &format!(r#"<integer name="width" value="{max}"/><integer name="height" value="7"/>"#),
        r#"<rfilter type="box"/>"#,
    ))
    .sensor
    .film;
    assert_eq!((film.width, film.height), (max, 7));
}

/// Mitsuba's output-encoding parameters: every value Mitsuba accepts loads (float16 is
/// honoured, the others penumbra cannot write are warned about), the rest are refused.
#[test]
fn component_pixel_and_file_formats() {
    let film = |props: &str| {
        parse(&sensor_scene(
            r#"<float name="fov" value="30"/>"#,
            props,
            r#"<rfilter type="box"/>"#,
        ))
    };
    for (format, half) in [("float16", true), ("float32", false), ("FLOAT16", true)] {
        let d = film(&format!(
            r#"<string name="component_format" value="{format}"/>"#
        ))
        .unwrap();
        assert_eq!(d.sensor.film.half, half, "{format}");
        assert!(d.warnings.is_empty(), "{format}: {:?}", d.warnings);
    }
    assert!(
        !film("").unwrap().sensor.film.half,
        "penumbra writes float32 by default"
    );
    let d = film(r#"<string name="component_format" value="uint32"/>"#).unwrap();
    assert!(
        d.warnings[0].contains("'uint32' is written as float32"),
        "{:?}",
        d.warnings
    );
    let xml = sensor_scene(
        r#"<float name="fov" value="30"/>"#,
        r#"<string name="component_format" value="float64"/>"#,
        r#"<rfilter type="box"/>"#,
    );
    assert_error(
        &xml,
        "component_format",
        &["component_format must be float16, float32 or uint32, not 'float64'"],
    );
    assert!(film(r#"<string name="pixel_format" value="RGB"/>"#)
        .unwrap()
        .warnings
        .is_empty());
    for format in ["rgba", "luminance", "luminance_alpha", "xyz", "xyza"] {
        let d = film(&format!(
            r#"<string name="pixel_format" value="{format}"/>"#
        ))
        .unwrap();
        assert_eq!(d.warnings.len(), 1, "{format}");
        assert!(d.warnings[0].contains(&format!("pixel_format '{format}' is written as rgb")));
    }
    let xml = sensor_scene(
        r#"<float name="fov" value="30"/>"#,
        r#"<string name="pixel_format" value="cmyk"/>"#,
        r#"<rfilter type="box"/>"#,
    );
    assert_error(
        &xml,
        "pixel_format",
        &["pixel_format must be luminance, luminance_alpha, rgb, rgba, xyz or xyza, not 'cmyk'"],
    );
    // Bitterli's exporter writes file_format="openexr" in every scene.
    for format in ["openexr", "exr", "OpenEXR"] {
        let d = film(&format!(r#"<string name="file_format" value="{format}"/>"#)).unwrap();
        assert!(d.warnings.is_empty(), "{format}");
    }
    for format in ["rgbe", "pfm"] {
        let d = film(&format!(r#"<string name="file_format" value="{format}"/>"#)).unwrap();
        assert!(
            d.warnings[0].contains("written as OpenEXR"),
            "{:?}",
            d.warnings
        );
    }
    let xml = sensor_scene(
        r#"<float name="fov" value="30"/>"#,
        r#"<string name="file_format" value="png"/>"#,
        r#"<rfilter type="box"/>"#,
    );
    assert_error(
        &xml,
        "file_format",
        &["file_format must be openexr, pfm or rgbe, not 'png'"],
    );
    // `banner` is read and ignored (as in Mitsuba 3); `compensate` warns, as in Mitsuba.
    let d = film(r#"<boolean name="banner" value="false"/>"#).unwrap();
    assert!(d.warnings.is_empty());
    let d = film(r#"<boolean name="compensate" value="true"/>"#).unwrap();
    assert!(
        d.warnings[0].contains("'compensate' is ignored"),
        "{:?}",
        d.warnings
    );
}

/// The crop window: Mitsuba's defaults (the whole film), a window inside the film, and
/// windows that leave it or are empty refused.
#[test]
fn crop_window() {
    let film = |props: &str| {
        parse(&sensor_scene(
            r#"<float name="fov" value="30"/>"#,
            &format!(
                r#"<integer name="width" value="40"/><integer name="height" value="30"/>{props}"#
            ),
            r#"<rfilter type="box"/>"#,
        ))
    };
    let f = film("").unwrap().sensor.film;
    assert_eq!((f.crop_offset, f.crop_size), ((0, 0), (40, 30)));
    let f = film(
        r#"<integer name="crop_offset_x" value="5"/><integer name="crop_offset_y" value="7"/>
           <integer name="crop_width" value="20"/><integer name="crop_height" value="23"/>"#,
    )
    .unwrap()
    .sensor
    .film;
    assert_eq!((f.width, f.height), (40, 30));
    assert_eq!((f.crop_offset, f.crop_size), ((5, 7), (20, 23)));
    for bad in [
        r#"<integer name="crop_offset_x" value="21"/><integer name="crop_width" value="20"/>"#,
        r#"<integer name="crop_offset_y" value="1"/>"#,
        r#"<integer name="crop_width" value="0"/>"#,
        r#"<integer name="crop_offset_x" value="-1"/>"#,
    ] {
        let e = film(bad).unwrap_err().to_string();
        assert!(e.contains("invalid crop window"), "{bad}: {e}");
    }
}

#[test]
fn box_tent_and_gaussian_filters_are_accepted() {
    for filter in ["lanczos", "mitchell"] {
        let xml = sensor_scene(
            r#"<float name="fov" value="30"/>"#,
            "",
            &format!(r#"<rfilter type="{filter}"/>"#),
        );
        assert_error(
            &xml,
            "<rfilter",
            &[
                &format!("unsupported plugin <rfilter type=\"{filter}\">"),
                "box, tent and gaussian",
            ],
        );
    }
    let film = |children: &str| {
        desc(&sensor_scene(
            r#"<float name="fov" value="30"/>"#,
            "",
            children,
        ))
        .sensor
        .film
        .rfilter
    };
    // Mitsuba's default filter: gaussian with stddev 0.5.
    assert_eq!(film(""), FilterDesc::Gaussian { stddev: 0.5 });
    assert_eq!(
        film(r#"<rfilter type="gaussian"/>"#),
        FilterDesc::Gaussian { stddev: 0.5 }
    );
    assert_eq!(
        film(r#"<rfilter type="gaussian"><float name="stddev" value="0.25"/></rfilter>"#),
        FilterDesc::Gaussian { stddev: 0.25 }
    );
    assert_eq!(
        film(r#"<rfilter type="tent"/>"#),
        FilterDesc::Tent { radius: 1.0 }
    );
    assert_eq!(
        film(r#"<rfilter type="tent"><float name="radius" value="1.5"/></rfilter>"#),
        FilterDesc::Tent { radius: 1.5 }
    );
    let xml = sensor_scene(
        r#"<float name="fov" value="30"/>"#,
        "",
        r#"<rfilter type="box"><float name="radius" value="1"/></rfilter>"#,
    );
    assert_error(&xml, "<rfilter", &["default radius 0.5"]);
    let xml = sensor_scene(
        r#"<float name="fov" value="30"/>"#,
        "",
        r#"<rfilter type="box"/><rfilter type="box"/>"#,
    );
    assert_error(
        &xml,
        "<rfilter",
        &["a film can only have one reconstruction filter"],
    );
}

#[test]
fn bad_resolutions_are_refused() {
    for (name, value) in [
        ("width", "0"),
        ("height", "0"),
        ("width", "-1"),
        ("height", "-640"),
        ("width", "65537"),
        ("width", "1000000000"),
        ("height", "1000000000"),
        ("width", "9223372036854775807"),
    ] {
        let xml = sensor_scene(
            r#"<float name="fov" value="30"/>"#,
            &format!(r#"<integer name="{name}" value="{value}"/>"#),
            r#"<rfilter type="box"/>"#,
        );
        assert_error(
            &xml,
            "<film",
            &[&format!(
                "film {name} must be between 1 and {MAX_RESOLUTION}, got {value}"
            )],
        );
    }
}

#[test]
fn huge_pixel_counts_are_refused_before_allocating() {
    let xml = sensor_scene(
        r#"<float name="fov" value="30"/>"#,
        r#"<integer name="width" value="65536"/><integer name="height" value="65536"/>"#,
        r#"<rfilter type="box"/>"#,
    );
    assert_error(
        &xml,
        "<film",
        &[
            "film of 65536x65536 pixels exceeds the render_pixels limit of 67108864 pixels (raise \
           it with PENUMBRA_LIMITS=render_pixels=...)",
        ],
    );
}

#[test]
fn film_errors() {
    let xml = sensor_scene(
        r#"<float name="fov" value="30"/>"#,
        r#"<float name="width" value="32"/>"#,
        r#"<rfilter type="box"/>"#,
    );
    assert_error(
        &xml,
        "name=\"width\"",
        &["parameter 'width' of <film type=\"hdrfilm\"> must be an integer, not float"],
    );
    let xml = sensor_scene(
        r#"<float name="fov" value="30"/>"#,
        r#"<integer name="widht" value="32"/>"#,
        r#"<rfilter type="box"/>"#,
    );
    assert_error(
        &xml,
        "widht",
        &["unknown parameter 'widht' (integer) of <film type=\"hdrfilm\">"],
    );
    let xml = scene(
        r#"<sensor type="perspective">
    <float name="fov" value="30"/>
    <film type="ldrfilm"><rfilter type="box"/></film>
</sensor>"#,
    );
    assert_error(
        &xml,
        "<film",
        &["unsupported plugin <film type=\"ldrfilm\">"],
    );
}

// ---------------------------------------------------------------------------------------
// Sampler
// ---------------------------------------------------------------------------------------

#[test]
fn independent_sampler() {
    let absent = desc(&scene(SENSOR)).sensor.sampler;
    assert_eq!(
        absent,
        SamplerDesc {
            kind: SamplerKind::Independent,
            sample_count: 4,
            seed: 0
        }
    );
    let empty = desc(&sensor_scene(
        r#"<float name="fov" value="30"/><sampler type="independent"/>"#,
        "",
        r#"<rfilter type="box"/>"#,
    ))
    .sensor
    .sampler;
    assert_eq!(
        empty,
        SamplerDesc {
            kind: SamplerKind::Independent,
            sample_count: 4,
            seed: 0
        }
    );
    let given = desc(&sensor_scene(
        r#"<float name="fov" value="30"/>
    <sampler type="independent">
        <integer name="sample_count" value="64"/>
        <integer name="seed" value="1234"/>
    </sampler>"#,
        "",
        r#"<rfilter type="box"/>"#,
    ))
    .sensor
    .sampler;
    assert_eq!(
        given,
        SamplerDesc {
            kind: SamplerKind::Independent,
            sample_count: 64,
            seed: 1234
        }
    );
}

/// Mitsuba's samplers with their parameters, and penumbra's zsobol.
#[test]
fn mitsuba_samplers() {
    let sampler = |xml: &str| {
        desc(&sensor_scene(
            &format!("<float name=\"fov\" value=\"30\"/>\n    {xml}"),
            "",
            r#"<rfilter type="box"/>"#,
        ))
        .sensor
        .sampler
    };
    let cases = [
        (
            r#"<sampler type="stratified"><integer name="sample_count" value="10"/></sampler>"#,
            SamplerKind::Stratified { jitter: true },
            10,
        ),
        (
            r#"<sampler type="stratified"><boolean name="jitter" value="false"/></sampler>"#,
            SamplerKind::Stratified { jitter: false },
            4,
        ),
        (
            r#"<sampler type="multijitter"><boolean name="jitter" value="false"/></sampler>"#,
            SamplerKind::Multijitter { jitter: false },
            4,
        ),
        (
            r#"<sampler type="orthogonal"><integer name="strength" value="3"/><integer name="sample_count" value="49"/></sampler>"#,
            SamplerKind::Orthogonal {
                strength: 3,
                jitter: true,
            },
            49,
        ),
        (r#"<sampler type="ldsampler"/>"#, SamplerKind::LdSampler, 4),
        (
            r#"<sampler type="zsobol"><integer name="sample_count" value="64"/></sampler>"#,
            SamplerKind::ZSobol,
            64,
        ),
    ];
    for (xml, kind, sample_count) in cases {
        let d = sampler(xml);
        assert_eq!((d.kind, d.sample_count), (kind, sample_count), "{xml}");
    }
    // the built scene rounds the count as Mitsuba does, and says so
    let scene = build(&desc(&sensor_scene(
        r#"<float name="fov" value="30"/><sampler type="stratified"><integer name="sample_count" value="10"/></sampler>"#,
        "",
        r#"<rfilter type="box"/>"#,
    )))
    .unwrap();
    assert_eq!((scene.sample_count, scene.sampler.sample_count), (16, 16));
    assert!(scene
        .warnings
        .iter()
        .any(|w| w.contains("stratified sampler rounds sample_count 10 to 16")));
}

#[test]
fn sampler_errors() {
    let case = |sampler: &str| {
        sensor_scene(
            &format!("<float name=\"fov\" value=\"30\"/>\n    {sampler}"),
            "",
            r#"<rfilter type="box"/>"#,
        )
    };
    assert_error(
        &case(r#"<sampler type="halton"/>"#),
        "<sampler",
        &["unsupported plugin <sampler type=\"halton\">"],
    );
    assert_error(
        &case(r#"<sampler type="orthogonal"><integer name="strength" value="1"/></sampler>"#),
        "<sampler",
        &["strength must be between 2 and 8, got 1"],
    );
    assert_error(
        &case(r#"<sampler type="ldsampler"><boolean name="jitter" value="false"/></sampler>"#),
        "name=\"jitter\"",
        &["unknown parameter 'jitter' (boolean) of <sampler type=\"ldsampler\">"],
    );
    assert_error(
        &case(r#"<sampler type="independent"><integer name="sample_count" value="0"/></sampler>"#),
        "<sampler",
        &["sample_count must be between 1 and 4294967295, got 0"],
    );
    assert_error(
        &case(r#"<sampler type="independent"><integer name="seed" value="-1"/></sampler>"#),
        "<sampler",
        &["seed must be >= 0, got -1"],
    );
    assert_error(
        &case(r#"<sampler type="independent"><integer name="spp" value="4"/></sampler>"#),
        "name=\"spp\"",
        &["unknown parameter 'spp' (integer) of <sampler type=\"independent\">"],
    );
}

// ---------------------------------------------------------------------------------------
// Shapes
// ---------------------------------------------------------------------------------------

#[test]
fn simple_shapes_with_defaults() {
    for (plugin, kind) in [
        ("rectangle", ShapeKind::Rectangle),
        ("cube", ShapeKind::Cube),
        ("disk", ShapeKind::Disk),
        (
            "sphere",
            ShapeKind::Sphere {
                center: DVec3::ZERO,
                radius: 1.0,
            },
        ),
    ] {
        let xml = with_sensor(&format!(r#"<shape type="{plugin}"/>"#));
        let mut d = desc(&xml);
        let s = d.shapes.remove(0);
        assert_eq!(s.kind, kind);
        assert_eq!(s.to_world, DMat4::IDENTITY);
        assert!(!s.flip_normals);
        assert_eq!(s.bsdf, BsdfDesc::default_diffuse());
        assert_eq!(s.emitter, None);
        assert_eq!(s.location.line as usize, line_of(&xml, "<shape"));
    }
}

#[test]
fn default_bsdf_is_diffuse_one_half() {
    assert_eq!(
        BsdfDesc::default_diffuse(),
        BsdfDesc::diffuse(TextureDesc::value(0.5))
    );
}

#[test]
fn shapes_keep_document_order() {
    let d = desc(&with_sensor(
        r#"<shape type="cube"/>
<shape type="disk"/>
<shape type="rectangle"/>"#,
    ));
    let kinds: Vec<ShapeKind> = d.shapes.into_iter().map(|s| s.kind).collect();
    assert_eq!(
        kinds,
        [ShapeKind::Cube, ShapeKind::Disk, ShapeKind::Rectangle]
    );
}

#[test]
fn flip_normals_and_to_world() {
    for plugin in ["rectangle", "cube", "disk", "sphere"] {
        let s = one_shape(&format!(
            r#"<shape type="{plugin}">
    <boolean name="flip_normals" value="true"/>
    <transform name="to_world">
        <scale value="2"/>
        <translate value="1, 2, 3"/>
    </transform>
</shape>"#
        ));
        assert!(s.flip_normals, "{plugin}");
        let expected = DMat4::from_translation(DVec3::new(1.0, 2.0, 3.0))
            * DMat4::from_scale(DVec3::splat(2.0));
        assert_mat(s.to_world, expected);
    }
}

#[test]
fn sphere_center_and_radius() {
    let s = one_shape(
        r#"<shape type="sphere">
    <point name="center" x="1" y="-2" z="3.5"/>
    <float name="radius" value="2.5"/>
</shape>"#,
    );
    assert_eq!(
        s.kind,
        ShapeKind::Sphere {
            center: DVec3::new(1.0, -2.0, 3.5),
            radius: 2.5
        }
    );
    let s = one_shape(
        r#"<shape type="sphere">
    <point name="center" value="0, 1, 0"/>
    <integer name="radius" value="3"/>
</shape>"#,
    );
    assert_eq!(
        s.kind,
        ShapeKind::Sphere {
            center: DVec3::Y,
            radius: 3.0
        }
    );
}

#[test]
fn sphere_radius_must_be_positive() {
    for radius in ["0", "-1"] {
        let xml = with_sensor(&format!(
            r#"<shape type="sphere">
    <float name="radius" value="{radius}"/>
</shape>"#
        ));
        assert_error(
            &xml,
            "<shape",
            &[&format!(
                "radius of <shape type=\"sphere\"> must be positive, got {radius}"
            )],
        );
    }
}

#[test]
fn obj_shape() {
    let s = one_shape(
        r#"<shape type="obj">
    <string name="filename" value="meshes/bunny.obj"/>
</shape>"#,
    );
    assert_eq!(
        s.kind,
        ShapeKind::Obj {
            filename: PathBuf::from("/virtual/dir/meshes/bunny.obj"),
            face_normals: false,
            flip_tex_coords: true,
        }
    );
    let s = one_shape(
        r#"<shape type="obj">
    <string name="filename" value="/abs/mesh.obj"/>
    <boolean name="face_normals" value="true"/>
    <boolean name="flip_tex_coords" value="false"/>
    <boolean name="flip_normals" value="true"/>
    <transform name="to_world"><translate value="0, 0, -1"/></transform>
</shape>"#,
    );
    assert_eq!(
        s.kind,
        ShapeKind::Obj {
            filename: PathBuf::from("/abs/mesh.obj"),
            face_normals: true,
            flip_tex_coords: false,
        }
    );
    assert!(s.flip_normals);
    assert_eq!(s.to_world, DMat4::from_translation(DVec3::NEG_Z));
}

#[test]
fn obj_filename_is_relative_to_the_scene_file() {
    let xml = with_sensor(r#"<shape type="obj"><string name="filename" value="m.obj"/></shape>"#);
    let root = load_str(&xml, Path::new("relative/sub/s.xml"), &[]).unwrap();
    let d = from_xml(&root).unwrap();
    match &d.shapes[0].kind {
        ShapeKind::Obj { filename, .. } => {
            assert_eq!(filename, &PathBuf::from("relative/sub/m.obj"))
        }
        other => panic!("not an obj: {other:?}"),
    }
}

#[test]
fn obj_errors() {
    let xml = with_sensor(r#"<shape type="obj"/>"#);
    assert_error(&xml, "<shape", &["<shape type=\"obj\"> needs a 'filename'"]);
    let xml = with_sensor(
        r#"<shape type="obj">
    <string name="filename" value="a.obj"/>
    <string name="face_normals" value="yes"/>
</shape>"#,
    );
    assert_error(
        &xml,
        "face_normals",
        &["parameter 'face_normals' of <shape type=\"obj\"> must be a boolean, not string"],
    );
    let xml = with_sensor(
        r#"<shape type="obj">
    <float name="filename" value="1"/>
</shape>"#,
    );
    assert_error(
        &xml,
        "name=\"filename\"",
        &["parameter 'filename' of <shape type=\"obj\"> must be a string, not float"],
    );
}

#[test]
fn unknown_shape_plugins_fail() {
    for plugin in ["bsplinecurve", "linearcurve", "ellipsoids", "merge"] {
        let xml = with_sensor(&format!(r#"<shape type="{plugin}"/>"#));
        assert_error(
            &xml,
            "<shape",
            &[&format!("unsupported plugin <shape type=\"{plugin}\">")],
        );
    }
}

#[test]
fn unknown_shape_parameter_fails() {
    let xml = with_sensor(
        r#"<shape type="sphere">
    <float name="radiuss" value="2"/>
</shape>"#,
    );
    assert_error(
        &xml,
        "radiuss",
        &["unknown parameter 'radiuss' (float) of <shape type=\"sphere\">"],
    );
    // A parameter of another shape is unknown too.
    let xml = with_sensor(
        r#"<shape type="rectangle">
    <float name="radius" value="2"/>
</shape>"#,
    );
    assert_error(
        &xml,
        "name=\"radius\"",
        &["unknown parameter 'radius' (float) of <shape type=\"rectangle\">"],
    );
}

#[test]
fn wrong_property_types_fail() {
    for (property, parts) in [
        (
            r#"<string name="radius" value="2"/>"#,
            "parameter 'radius' of <shape type=\"sphere\"> must be a float, not string",
        ),
        (
            r#"<rgb name="center" value="1, 2, 3"/>"#,
            "parameter 'center' of <shape type=\"sphere\"> must be a point, not rgb",
        ),
        (
            r#"<integer name="flip_normals" value="1"/>"#,
            "parameter 'flip_normals' of <shape type=\"sphere\"> must be a boolean, not integer",
        ),
        (
            r#"<point name="to_world" value="1, 2, 3"/>"#,
            "parameter 'to_world' of <shape type=\"sphere\"> must be a transform, not point",
        ),
    ] {
        let xml = with_sensor(&format!(
            "<shape type=\"sphere\">\n    {property}\n</shape>"
        ));
        assert_error(&xml, property, &[parts]);
    }
}

#[test]
fn shape_children_errors() {
    let xml = with_sensor(
        r#"<shape type="sphere">
    <bsdf type="diffuse"/>
    <bsdf type="diffuse"/>
</shape>"#,
    );
    let second = line_of(&xml, "<bsdf") + 1;
    let message = error(&xml);
    assert!(
        message.starts_with(&format!("{FILE}:{second}:")),
        "{message}"
    );
    assert!(
        message.contains("<shape type=\"sphere\"> has more than one <bsdf>"),
        "{message}"
    );
    let xml = with_sensor(
        r#"<shape type="sphere">
    <emitter type="area"><rgb name="radiance" value="1"/></emitter>
    <emitter type="area"><rgb name="radiance" value="1"/></emitter>
</shape>"#,
    );
    let second = line_of(&xml, "<emitter") + 1;
    let message = error(&xml);
    assert!(
        message.starts_with(&format!("{FILE}:{second}:")),
        "{message}"
    );
    assert!(
        message.contains("<shape type=\"sphere\"> has more than one <emitter>"),
        "{message}"
    );
    let xml = with_sensor(
        r#"<shape type="sphere">
    <shape type="sphere"/>
</shape>"#,
    );
    let inner = line_of(&xml, "<shape") + 1;
    let message = error(&xml);
    assert!(
        message.starts_with(&format!("{FILE}:{inner}:")),
        "{message}"
    );
    assert!(
        message.contains("<shape type=\"sphere\"> cannot be nested in <shape type=\"sphere\">"),
        "{message}"
    );
}

// ---------------------------------------------------------------------------------------
// BSDFs
// ---------------------------------------------------------------------------------------

#[test]
fn diffuse_reflectance() {
    let s = one_shape(
        r#"<shape type="rectangle">
    <bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.4, 0.6"/></bsdf>
</shape>"#,
    );
    assert_eq!(
        s.bsdf,
        BsdfDesc::diffuse(TextureDesc::rgb(DVec3::new(0.2, 0.4, 0.6)))
    );
    let s = one_shape(
        r#"<shape type="rectangle">
    <bsdf type="diffuse"><float name="reflectance" value="0.25"/></bsdf>
</shape>"#,
    );
    assert_eq!(s.bsdf, BsdfDesc::diffuse(TextureDesc::value(0.25)));
    let s = one_shape(
        r#"<shape type="rectangle">
    <bsdf type="diffuse"><rgb name="reflectance" value="0.75"/></bsdf>
</shape>"#,
    );
    assert_eq!(
        s.bsdf,
        BsdfDesc::diffuse(TextureDesc::rgb(DVec3::splat(0.75)))
    );
    let s = one_shape(r#"<shape type="rectangle"><bsdf type="diffuse"/></shape>"#);
    assert_eq!(s.bsdf, BsdfDesc::default_diffuse());
}

#[test]
fn twosided_with_one_nested_bsdf_uses_it_on_both_sides() {
    let s = one_shape(
        r#"<shape type="rectangle">
    <bsdf type="twosided">
        <bsdf type="diffuse"><rgb name="reflectance" value="0.1, 0.2, 0.3"/></bsdf>
    </bsdf>
</shape>"#,
    );
    let inner = BsdfDesc::diffuse(TextureDesc::rgb(DVec3::new(0.1, 0.2, 0.3)));
    assert_eq!(
        s.bsdf,
        BsdfDesc::TwoSided {
            front: Box::new(inner.clone()),
            back: Box::new(inner)
        }
    );
}

#[test]
fn twosided_with_two_nested_bsdfs() {
    let s = one_shape(
        r#"<shape type="rectangle">
    <bsdf type="twosided">
        <bsdf type="diffuse"><rgb name="reflectance" value="0.1, 0.2, 0.3"/></bsdf>
        <bsdf type="diffuse"><float name="reflectance" value="0.9"/></bsdf>
    </bsdf>
</shape>"#,
    );
    assert_eq!(
        s.bsdf,
        BsdfDesc::TwoSided {
            front: Box::new(BsdfDesc::diffuse(TextureDesc::rgb(DVec3::new(
                0.1, 0.2, 0.3
            )))),
            back: Box::new(BsdfDesc::diffuse(TextureDesc::value(0.9))),
        }
    );
}

#[test]
fn twosided_errors() {
    let xml = with_sensor(r#"<shape type="rectangle"><bsdf type="twosided"/></shape>"#);
    assert_error(
        &xml,
        "<bsdf",
        &["<bsdf type=\"twosided\"> needs a nested <bsdf>"],
    );
    let xml = with_sensor(
        r#"<shape type="rectangle">
    <bsdf type="twosided">
        <bsdf type="diffuse"/>
        <bsdf type="diffuse"/>
        <bsdf type="diffuse"/>
    </bsdf>
</shape>"#,
    );
    let third = line_of(&xml, "<bsdf type=\"diffuse\"") + 2;
    let message = error(&xml);
    assert!(
        message.starts_with(&format!("{FILE}:{third}:")),
        "{message}"
    );
    assert!(
        message.contains("<bsdf type=\"diffuse\"> cannot be nested in <bsdf type=\"twosided\">"),
        "{message}"
    );
    let xml = with_sensor(
        r#"<shape type="rectangle">
    <bsdf type="twosided">
        <bsdf type="twosided"><bsdf type="diffuse"/></bsdf>
    </bsdf>
</shape>"#,
    );
    let inner = line_of(&xml, "<bsdf type=\"twosided\"") + 1;
    let message = error(&xml);
    assert!(
        message.starts_with(&format!("{FILE}:{inner}:")),
        "{message}"
    );
    assert!(
        message.contains("twosided BSDF cannot nest another twosided"),
        "{message}"
    );
    let xml = with_sensor(
        r#"<shape type="rectangle">
    <bsdf type="twosided">
        <float name="reflectance" value="0.5"/>
        <bsdf type="diffuse"/>
    </bsdf>
</shape>"#,
    );
    assert_error(
        &xml,
        "<float name=\"reflectance\"",
        &["unknown parameter 'reflectance' (float) of <bsdf type=\"twosided\">"],
    );
}

#[test]
fn referenced_bsdfs() {
    let d = desc(&with_sensor(
        r#"<bsdf type="diffuse" id="red">
    <rgb name="reflectance" value="0.8, 0.1, 0.1"/>
</bsdf>
<bsdf type="twosided" id="two">
    <ref id="red"/>
</bsdf>
<shape type="rectangle"><ref id="red"/></shape>
<shape type="cube"><ref id="two"/></shape>
<shape type="disk"><ref name="bsdf" id="red"/></shape>"#,
    ));
    let red = BsdfDesc::diffuse(TextureDesc::rgb(DVec3::new(0.8, 0.1, 0.1)));
    assert_eq!(d.shapes.len(), 3);
    assert_eq!(d.shapes[0].bsdf, red);
    assert_eq!(
        d.shapes[1].bsdf,
        BsdfDesc::TwoSided {
            front: Box::new(red.clone()),
            back: Box::new(red.clone())
        }
    );
    assert_eq!(d.shapes[2].bsdf, red);
}

#[test]
fn unknown_bsdf_plugins_fail() {
    for plugin in ["hair", "measured", "pplastic", "polarizer"] {
        let xml = with_sensor(&format!(
            "<shape type=\"sphere\">\n    <bsdf type=\"{plugin}\"/>\n</shape>"
        ));
        assert_error(
            &xml,
            "<bsdf",
            &[&format!("unsupported plugin <bsdf type=\"{plugin}\">")],
        );
    }
    // Declared at the top level and never used: still checked, as Mitsuba instantiates it.
    let xml = with_sensor(r#"<bsdf type="hair" id="unused"/>"#);
    assert_error(&xml, "<bsdf", &["unsupported plugin <bsdf type=\"hair\">"]);
    // Nested in a twosided.
    let xml = with_sensor(
        r#"<shape type="sphere">
    <bsdf type="twosided">
        <bsdf type="hair"/>
    </bsdf>
</shape>"#,
    );
    assert_error(
        &xml,
        "<bsdf type=\"hair\"",
        &["unsupported plugin <bsdf type=\"hair\">"],
    );
}

#[test]
fn bsdf_parameter_errors() {
    let xml = with_sensor(
        r#"<shape type="sphere">
    <bsdf type="diffuse">
        <string name="reflectance" value="red"/>
    </bsdf>
</shape>"#,
    );
    assert_error(
        &xml,
        "<string name=\"reflectance\"",
        &["parameter 'reflectance' of <bsdf type=\"diffuse\"> must be an rgb, float or spectrum, not string"],
    );
    let xml = with_sensor(
        r#"<shape type="sphere">
    <bsdf type="diffuse">
        <float name="alpha" value="0.1"/>
    </bsdf>
</shape>"#,
    );
    assert_error(
        &xml,
        "alpha",
        &["unknown parameter 'alpha' (float) of <bsdf type=\"diffuse\">"],
    );
    let xml = with_sensor(
        r#"<shape type="sphere">
    <bsdf type="diffuse">
        <texture type="bitmap" name="diffuse_reflectance"><string name="filename" value="a.png"/></texture>
    </bsdf>
</shape>"#,
    );
    assert_error(
        &xml,
        "<texture",
        &["<texture type=\"bitmap\"> cannot be nested in <bsdf type=\"diffuse\">"],
    );
}

// ---------------------------------------------------------------------------------------
// Emitters
// ---------------------------------------------------------------------------------------

#[test]
fn area_emitter_radiance() {
    let s = one_shape(
        r#"<shape type="rectangle">
    <emitter type="area"><rgb name="radiance" value="18.387, 13.9873, 6.75357"/></emitter>
</shape>"#,
    );
    assert_eq!(
        s.emitter,
        Some(EmitterDesc::Area {
            radiance: TextureDesc::color(ColorDesc {
                rgb: DVec3::new(18.387, 13.9873, 6.75357),
                spectral: SpectralDesc::D65(DVec3::new(18.387, 13.9873, 6.75357)),
            })
        })
    );
    // Mitsuba gives an emitter without a BSDF a black diffuse one.
    assert_eq!(s.bsdf, BsdfDesc::diffuse(TextureDesc::value(0.0)));
    let s = one_shape(
        r#"<shape type="sphere">
    <emitter type="area"><float name="radiance" value="3"/></emitter>
    <bsdf type="diffuse"><float name="reflectance" value="0"/></bsdf>
</shape>"#,
    );
    assert_eq!(
        s.emitter,
        Some(EmitterDesc::Area {
            // (a number an emitter reads is a D65 spectrum of that grey in spectral mode)
            radiance: TextureDesc::number(3.0, ColorRole::Emission)
        })
    );
    assert_eq!(s.bsdf, BsdfDesc::diffuse(TextureDesc::value(0.0)));
}

#[test]
fn area_emitter_errors() {
    let xml = with_sensor(
        r#"<shape type="rectangle">
    <emitter type="area"/>
</shape>"#,
    );
    assert_error(
        &xml,
        "<emitter",
        &["<emitter type=\"area\"> needs a 'radiance'"],
    );
    let xml = with_sensor(
        r#"<shape type="rectangle">
    <emitter type="area"><rgb name="radiance" value="1, -1, 1"/></emitter>
</shape>"#,
    );
    assert_error(&xml, "<emitter", &["radiance must not be negative"]);
    let xml = with_sensor(
        r#"<shape type="rectangle">
    <emitter type="area">
        <rgb name="radiance" value="1"/>
        <float name="scale" value="2"/>
    </emitter>
</shape>"#,
    );
    assert_error(
        &xml,
        "name=\"scale\"",
        &["unknown parameter 'scale' (float) of <emitter type=\"area\">"],
    );
    let xml = with_sensor(
        r#"<shape type="rectangle">
    <emitter type="area">
        <string name="radiance" value="bright"/>
    </emitter>
</shape>"#,
    );
    assert_error(
        &xml,
        "name=\"radiance\"",
        &["parameter 'radiance' of <emitter type=\"area\"> must be an rgb, float or spectrum, not string"],
    );
}

#[test]
fn unknown_emitters_fail() {
    // An emitter type outside the supported subset.
    let xml = with_sensor(r#"<emitter type="irradiancemeter"/>"#);
    assert_error(
        &xml,
        "<emitter",
        &["unsupported plugin <emitter type=\"irradiancemeter\">"],
    );
    // An area emitter at the scene level emits only through a shape that refers to it
    // (Mitsuba ignores it otherwise): a warning, not an error.
    let d = desc(&with_sensor(
        r#"<emitter type="area"><float name="radiance" value="1"/></emitter>"#,
    ));
    assert!(d.emitters.is_empty());
    assert!(
        d.warnings
            .iter()
            .any(|w| w.contains("not attached to any shape")),
        "{:?}",
        d.warnings
    );
    // A non-area emitter attached to a shape.
    let xml = with_sensor(
        r#"<shape type="sphere">
    <emitter type="point"/>
</shape>"#,
    );
    assert_error(
        &xml,
        "<emitter",
        &["unsupported plugin <emitter type=\"point\">"],
    );
}

#[test]
fn scene_level_emitters_and_their_defaults() {
    let d = desc(&with_sensor(
        r#"<emitter type="point"><point name="position" value="0, 1, 2"/><rgb name="intensity" value="3"/></emitter>
<emitter type="spot"/>
<emitter type="directional"><vector name="direction" value="0, -2, 0"/></emitter>
<emitter type="constant"><float name="radiance" value="0.5"/></emitter>"#,
    ));
    assert_eq!(
        d.emitters,
        vec![
            EmitterDesc::Point {
                position: DVec3::new(0.0, 1.0, 2.0),
                intensity: ColorDesc {
                    rgb: DVec3::splat(3.0),
                    spectral: SpectralDesc::D65(DVec3::splat(3.0))
                }
            },
            EmitterDesc::Spot {
                to_world: DMat4::IDENTITY,
                intensity: ColorDesc {
                    rgb: DVec3::ONE,
                    spectral: SpectralDesc::D65Scale(1.0)
                },
                cutoff_angle: 20.0,
                beam_width: 15.0,
                texture: None
            },
            EmitterDesc::Directional {
                direction: DVec3::new(0.0, -1.0, 0.0),
                irradiance: ColorDesc {
                    rgb: DVec3::ONE,
                    spectral: SpectralDesc::D65Scale(1.0)
                }
            },
            EmitterDesc::Constant {
                radiance: ColorDesc {
                    rgb: DVec3::splat(0.5),
                    spectral: SpectralDesc::D65(DVec3::splat(0.5))
                }
            },
        ]
    );
    // Two environment emitters are refused, as in Mitsuba.
    let xml = with_sensor(
        r#"<emitter type="constant"/>
<emitter type="envmap"><string name="filename" value="sky.exr"/></emitter>"#,
    );
    assert_error(
        &xml,
        "<emitter type=\"envmap\"",
        &["at most one environment emitter"],
    );
    let xml = with_sensor(r#"<emitter type="envmap"/>"#);
    assert_error(&xml, "<emitter", &["needs a 'filename'"]);
    let xml =
        with_sensor(r#"<emitter type="spot"><float name="beam_width" value="30"/></emitter>"#);
    assert_error(&xml, "<emitter", &["beam_width"]);
}

// ---------------------------------------------------------------------------------------
// The scene root
// ---------------------------------------------------------------------------------------

#[test]
fn scene_root_errors() {
    let xml = with_sensor(r#"<float name="scale" value="2"/>"#);
    assert_error(
        &xml,
        "name=\"scale\"",
        &["unknown parameter 'scale' (float) of <scene>"],
    );
    let xml = with_sensor(r#"<texture type="voronoi"/>"#);
    assert_error(
        &xml,
        "<texture",
        &["unsupported plugin <texture type=\"voronoi\">"],
    );
    let xml = with_sensor(r#"<film type="hdrfilm"><rfilter type="box"/></film>"#);
    assert_error(
        &xml,
        "<film type=\"hdrfilm\"><rfilter",
        &["<film type=\"hdrfilm\"> cannot be nested in <scene>"],
    );
}

#[test]
fn whole_scene_defaults_are_mitsubas() {
    // The smallest valid scene: only what penumbra requires.
    let xml = scene(
        r#"<sensor type="perspective">
    <float name="fov" value="40"/>
    <film type="hdrfilm"><rfilter type="box"/></film>
</sensor>
<shape type="sphere"/>"#,
    );
    let d = desc(&xml);
    assert_eq!(d.integrator, PATH_DEFAULTS);
    assert_eq!(d.sensor.fov_axis, FovAxis::X);
    assert_eq!((d.sensor.near_clip, d.sensor.far_clip), (0.01, 1e4));
    assert_eq!((d.sensor.film.width, d.sensor.film.height), (768, 576));
    assert_eq!(
        d.sensor.sampler,
        SamplerDesc {
            kind: SamplerKind::Independent,
            sample_count: 4,
            seed: 0
        }
    );
    assert_eq!(
        d.shapes[0].kind,
        ShapeKind::Sphere {
            center: DVec3::ZERO,
            radius: 1.0
        }
    );
    assert_eq!(d.shapes[0].bsdf, BsdfDesc::diffuse(TextureDesc::value(0.5)));
}

#[test]
fn defines_reach_the_description() {
    let xml = scene(
        r#"<default name="res" value="16"/>
<default name="spp" value="8"/>
<sensor type="perspective">
    <float name="fov" value="40"/>
    <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
    <film type="hdrfilm">
        <integer name="width" value="$res"/>
        <integer name="height" value="$res"/>
        <rfilter type="box"/>
    </film>
</sensor>"#,
    );
    let root = load_str(
        &xml,
        Path::new(FILE),
        &[("spp".to_string(), "2".to_string())],
    )
    .unwrap();
    let d = from_xml(&root).unwrap();
    assert_eq!((d.sensor.film.width, d.sensor.film.height), (16, 16));
    assert_eq!(d.sensor.sampler.sample_count, 2);
    let root = load_str(
        &xml,
        Path::new(FILE),
        &[("res".to_string(), "0".to_string())],
    )
    .unwrap();
    let message = from_xml(&root).unwrap_err().to_string();
    assert!(
        message.contains("film width must be between 1 and 65536, got 0"),
        "{message}"
    );
}

// ---------------------------------------------------------------------------------------
// Build-time checks
// ---------------------------------------------------------------------------------------

#[test]
fn uniformly_scaled_sphere_builds() {
    let d = desc(&with_sensor(
        r#"<shape type="sphere">
    <point name="center" value="1, 0, 0"/>
    <float name="radius" value="2"/>
    <transform name="to_world">
        <scale value="3"/>
        <rotate y="1" angle="90"/>
        <translate value="0, 5, 0"/>
    </transform>
</shape>"#,
    ));
    let scene = build(&d).unwrap();
    match &scene.shapes[0].geometry {
        ShapeGeometry::Sphere(s) => {
            assert!((s.radius - 6.0).abs() < 1e-12, "{}", s.radius);
            // (1,0,0) scaled by 3, rotated 90° about +y to (0,0,-3), moved up by 5.
            assert!(
                s.center.abs_diff_eq(DVec3::new(0.0, 5.0, -3.0), 1e-12),
                "{:?}",
                s.center
            );
        }
        _ => panic!("not a sphere"),
    }
}

#[test]
fn non_uniformly_scaled_sphere_fails_to_build() {
    let xml = with_sensor(
        r#"<shape type="sphere">
    <transform name="to_world">
        <scale value="1, 2, 1"/>
    </transform>
</shape>"#,
    );
    let d = desc(&xml);
    let message = match build(&d) {
        Ok(_) => panic!("a non-uniformly scaled sphere must not build"),
        Err(e) => e.to_string(),
    };
    let location = format!("{FILE}:{}:", line_of(&xml, "<shape"));
    assert!(message.starts_with(&location), "{message}");
    assert!(
        message.contains("sphere's to_world may only rotate, translate and scale uniformly"),
        "{message}"
    );
}

#[test]
fn zero_scaled_shapes_fail_to_build() {
    for plugin in ["rectangle", "cube", "disk", "sphere"] {
        let xml = with_sensor(&format!(
            r#"<shape type="{plugin}">
    <transform name="to_world"><scale value="0"/></transform>
</shape>"#
        ));
        let d = desc(&xml);
        let message = match build(&d) {
            Ok(_) => panic!("a zero-scaled {plugin} must not build"),
            Err(e) => e.to_string(),
        };
        let location = format!("{FILE}:{}:", line_of(&xml, "<shape"));
        assert!(message.starts_with(&location), "{plugin}: {message}");
    }
}

#[test]
fn build_warns_about_missing_emitters() {
    let d = desc(&with_sensor(
        r#"<integrator type="path"/><shape type="sphere"/>"#,
    ));
    let scene = build(&d).unwrap();
    assert_eq!(
        scene.warnings,
        ["the scene has no emitter: the image will be black"]
    );
    let d = desc(&with_sensor(
        r#"<integrator type="path"/><shape type="sphere"><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>"#,
    ));
    let scene = build(&d).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    assert_eq!(scene.emitters.len(), 1);
    assert_eq!((scene.width, scene.height), (32, 24));
    assert_eq!((scene.sample_count, scene.seed), (4, 0));
}

/// A scene without an integrator (Mitsuba's own test scenes have none: its harness passes
/// one) renders with `path` and its defaults, and says so until an integrator is chosen.
#[test]
fn a_scene_without_integrator_renders_with_path_and_says_so() {
    let d = desc(&with_sensor(
        r#"<shape type="sphere"><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>"#,
    ));
    assert!(d.integrator_missing);
    assert_eq!(
        d.integrator,
        IntegratorDesc::Path {
            max_depth: -1,
            rr_depth: 5,
            hide_emitters: false
        }
    );
    let scene = build(&d).unwrap();
    assert_eq!(scene.warnings.len(), 1);
    assert!(scene.warnings[0].starts_with("the scene has no <integrator>: rendering with path"));
    let mut chosen = d.clone();
    chosen.use_integrator("path").unwrap();
    let scene = build(&chosen).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let d = desc(&with_sensor(r#"<integrator type="path"/>"#));
    assert!(!d.integrator_missing);
}

/// The perspective sensor's principal point shift and the shutter times Mitsuba reads;
/// a spectral response function needs spectral rendering (refused, as in Mitsuba's RGB
/// variants).
#[test]
fn principal_point_shutter_and_srf() {
    let sensor = |plugin: &str, props: &str| {
        parse(&scene(&format!(
            r#"<sensor type="{plugin}">
    <float name="fov" value="30"/>
    <float name="aperture_radius" value="0.1"/>
    {props}
</sensor>"#
        )))
    };
    let d = sensor(
        "perspective",
        r#"<float name="principal_point_offset_x" value="0.25"/><float name="principal_point_offset_y" value="-0.125"/>"#,
    )
    .map_err(|e| e.to_string());
    let e = d.unwrap_err();
    assert!(e.contains("unknown parameter 'aperture_radius'"), "{e}");
    let d = parse(&scene(
        r#"<sensor type="perspective">
    <float name="fov" value="30"/>
    <float name="principal_point_offset_x" value="0.25"/>
    <float name="principal_point_offset_y" value="-0.125"/>
    <float name="shutter_open" value="0.5"/>
    <float name="shutter_close" value="1.5"/>
</sensor>"#,
    ))
    .unwrap();
    assert_eq!(d.sensor.principal_point, DVec2::new(0.25, -0.125));
    // Mitsuba's thin lens has no principal point: the parameter is unknown there.
    let e = sensor(
        "thinlens",
        r#"<float name="principal_point_offset_x" value="0.25"/>"#,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("unknown parameter 'principal_point_offset_x'"),
        "{e}"
    );
    let e = sensor(
        "thinlens",
        r#"<float name="shutter_open" value="2"/><float name="shutter_close" value="1"/>"#,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("must not be later than shutter_close"), "{e}");
    let e = sensor("thinlens", r#"<spectrum name="srf" value="1"/>"#)
        .unwrap_err()
        .to_string();
    assert!(e.contains("needs spectral rendering"), "{e}");
}

#[test]
fn thinlens_sensor_parameters() {
    let lens = |props: &str| {
        parse(&scene(&format!(
            r#"<sensor type="thinlens">
    <float name="fov" value="30"/>
    <float name="far_clip" value="50"/>
    {props}
</sensor>"#
        )))
        .map(|d| d.sensor.thin_lens)
    };
    assert_eq!(
        lens(r#"<float name="aperture_radius" value="0.1"/>"#).unwrap(),
        Some((0.1, 50.0)),
        "focus_distance defaults to far_clip, as in Mitsuba"
    );
    assert_eq!(
        lens(
            r#"<float name="aperture_radius" value="0"/><float name="focus_distance" value="2"/>"#
        )
        .unwrap(),
        Some((0.0, 2.0))
    );
    let e = lens("").unwrap_err().to_string();
    assert!(e.contains("needs an 'aperture_radius'"), "{e}");
    let e = lens(r#"<float name="aperture_radius" value="-1"/>"#)
        .unwrap_err()
        .to_string();
    assert!(e.contains("aperture_radius"), "{e}");
    assert_eq!(desc(&with_sensor("")).sensor.thin_lens, None);
}

// ---------------------------------------------------------------------------------------
// Mitsuba's file semantics added with its example scenes: spectra by role, black BSDFs on
// lights, direct and moment integrators, default sensors, shape groups.
// ---------------------------------------------------------------------------------------

/// [`desc`] of a scene with [`SENSOR`] and `body`.
fn desc_body(body: &str) -> SceneDescription {
    desc(&with_sensor(body))
}

/// [`error`] of a scene with [`SENSOR`] and `body`.
fn error_body(body: &str) -> String {
    error(&with_sensor(body))
}

fn close(a: DVec3, b: DVec3, tol: f64) -> bool {
    (a - b).abs().max_element() <= tol
}

/// A `<spectrum>` becomes RGB by the role of the parameter that reads it: reflectances are
/// D65-weighted and clamped, conductor IORs unbounded, emission not D65-weighted, and a
/// uniform spectrum on an emitter is not grey (Mitsuba's RGB variants imitate the spectral
/// ones). The values are Mitsuba's (tests/data/mitsuba_spectrum_values.txt).
#[test]
fn spectra_take_the_role_of_their_parameter() {
    let d = desc_body(
        r#"<shape type="sphere">
             <bsdf type="conductor">
               <spectrum name="eta" value="0.789"/>
               <spectrum name="k" value="400:1, 700:7"/>
             </bsdf>
             <emitter type="area"><spectrum name="radiance" value="0.5"/></emitter>
           </shape>
           <shape type="sphere">
             <bsdf type="diffuse"><spectrum name="reflectance" value="400:2, 700:2"/></bsdf>
           </shape>"#,
    );
    let bsdf = &d.shapes[0].bsdf;
    match (bsdf.plugin(), bsdf.param("eta"), bsdf.param("k")) {
        (Some("conductor"), Some(eta), Some(k)) => {
            let (eta, k) = (eta.constant_rgb().unwrap(), k.constant_rgb().unwrap());
            assert!(close(eta, DVec3::splat(0.789), 1e-7), "{eta}");
            assert!(k.z < k.x && k.x > 1.0, "unbounded, not clamped: {k}");
        }
        other => panic!("{other:?}"),
    }
    match &d.shapes[0].emitter {
        Some(EmitterDesc::Area { radiance }) => {
            // 0.5 · xyz_to_srgb(1, 1, 1), the f32 values Mitsuba stores.
            assert!(
                radiance.constant_rgb().is_some_and(|c| close(
                    c,
                    DVec3::new(0.602396965, 0.474145502, 0.454458028),
                    1e-7
                )),
                "{radiance:?}"
            );
        }
        _ => panic!("{bsdf:?}"),
    }
    match (
        d.shapes[1].bsdf.plugin(),
        d.shapes[1].bsdf.param("reflectance"),
    ) {
        (Some("diffuse"), Some(reflectance)) => {
            assert!(
                close(reflectance.constant_rgb().unwrap(), DVec3::ONE, 0.0),
                "clamped to 1: {reflectance:?}"
            )
        }
        _ => panic!("{:?}", d.shapes[1].bsdf),
    }
    assert!(
        d.warnings.iter().any(|w| w.contains("clamping")),
        "{:?}",
        d.warnings
    );
    // <rgb> reflectances outside [0, 1] are refused, as Mitsuba's srgb texture does; the
    // same on an emitter is fine.
    let e = error_body(
        r#"<shape type="sphere"><bsdf type="diffuse"><rgb name="reflectance" value="1.5, 0.2, 0.2"/></bsdf></shape>"#,
    );
    assert!(
        e.contains("invalid RGB reflectance") && e.contains("scene.xml:10:"),
        "{e}"
    );
    desc_body(
        r#"<shape type="sphere"><emitter type="area"><rgb name="radiance" value="15"/></emitter></shape>"#,
    );
    let e = error_body(
        r#"<shape type="sphere"><bsdf type="diffuse"><spectrum name="reflectance" value="500:1, 400:1"/></bsdf></shape>"#,
    );
    assert!(e.contains("<spectrum name=\"reflectance\">"), "{e}");
}

/// Mitsuba gives a shape with an emitter but no BSDF a black diffuse BSDF; other shapes
/// without a BSDF get diffuse 0.5.
#[test]
fn a_light_without_a_bsdf_is_black() {
    let d = desc_body(
        r#"<shape type="rectangle"><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>
           <shape type="rectangle"/>"#,
    );
    assert_eq!(d.shapes[0].bsdf, BsdfDesc::diffuse(TextureDesc::value(0.0)));
    assert_eq!(d.shapes[1].bsdf, BsdfDesc::diffuse(TextureDesc::value(0.5)));
}

#[test]
fn direct_and_moment_integrators() {
    let d = desc_body(r#"<integrator type="direct"/>"#);
    assert_eq!(
        d.integrator,
        IntegratorDesc::Direct {
            emitter_samples: 1,
            bsdf_samples: 1,
            hide_emitters: false
        }
    );
    assert!(!d.moment);
    let d = desc_body(
        r#"<integrator type="moment"><integrator type="direct"><integer name="shading_samples" value="3"/></integrator></integrator>"#,
    );
    assert!(d.moment);
    assert_eq!(
        d.integrator,
        IntegratorDesc::Direct {
            emitter_samples: 3,
            bsdf_samples: 3,
            hide_emitters: false
        }
    );
    let d = desc_body(
        r#"<integrator type="moment"><integrator type="path"><integer name="max_depth" value="2"/></integrator></integrator>"#,
    );
    assert!(d.moment && matches!(d.integrator, IntegratorDesc::Path { max_depth: 2, .. }));
    for (body, part) in [
        (
            r#"<integrator type="direct"><integer name="shading_samples" value="2"/><integer name="bsdf_samples" value="1"/></integrator>"#,
            "not both",
        ),
        (
            r#"<integrator type="direct"><integer name="emitter_samples" value="0"/><integer name="bsdf_samples" value="0"/></integrator>"#,
            "at least 1",
        ),
        (r#"<integrator type="moment"/>"#, "needs a nested"),
        (
            r#"<integrator type="moment"><integrator type="path"/><integrator type="direct"/></integrator>"#,
            "one nested integrator",
        ),
        (
            r#"<integrator type="pssmlt"/>"#,
            "unsupported plugin <integrator type=\"pssmlt\">",
        ),
    ] {
        let e = error_body(body);
        assert!(e.contains(part), "{body}: {e}");
    }
}

#[test]
fn sensors_with_mitsuba_defaults() {
    let d = from_xml(
        &load_str(
            r#"<scene version="3.0.0"><sensor type="perspective"><string name="focal_length" value="35mm"/></sensor></scene>"#,
            Path::new(FILE),
            &[],
        )
        .unwrap(),
    )
    .unwrap();
    let expected = 2.0
        * ((36.0f64 * 36.0 + 24.0 * 24.0).sqrt() / 70.0)
            .atan()
            .to_degrees();
    assert!((d.sensor.fov - expected).abs() < 1e-12);
    let d = from_xml(
        &load_str(
            r#"<scene version="3.0.0"><sensor type="orthographic"><float name="near_clip" value="1"/></sensor></scene>"#,
            Path::new(FILE),
            &[],
        )
        .unwrap(),
    )
    .unwrap();
    assert!(d.sensor.orthographic && d.sensor.near_clip == 1.0);
    let e = from_xml(
        &load_str(
            r#"<scene version="3.0.0"><sensor type="perspective"><float name="fov" value="30"/><string name="focal_length" value="20mm"/></sensor></scene>"#,
            Path::new(FILE),
            &[],
        )
        .unwrap(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("either a focal length"), "{e}");
}

#[test]
fn shape_groups_and_instances() {
    let d = desc_body(
        r#"<shape type="shapegroup" id="g">
             <shape type="sphere"/><shape type="rectangle"/>
           </shape>
           <shape type="instance"><ref id="g"/></shape>
           <shape type="instance"><ref id="g"/><transform name="to_world"><translate x="3"/></transform></shape>"#,
    );
    assert_eq!(d.shape_groups.len(), 1, "one group however many instances");
    assert_eq!(d.shape_groups[0].shapes.len(), 2);
    assert_eq!(d.shapes.len(), 2);
    assert!(d
        .shapes
        .iter()
        .all(|s| matches!(s.kind, ShapeKind::Instance { group: 0 })));
    for (body, part) in [
        (
            r#"<shape type="shapegroup" id="g"><shape type="sphere"><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape></shape>"#,
            "instancing of emitters",
        ),
        (
            r#"<shape type="instance"/>"#,
            "needs a <ref> to a shapegroup",
        ),
        (
            r#"<bsdf type="diffuse" id="b"/><shape type="instance"><ref id="b"/></shape>"#,
            "an instance takes one shapegroup",
        ),
        (
            r#"<shape type="sphere"><shape type="shapegroup"/></shape>"#,
            "cannot be nested",
        ),
    ] {
        let e = error_body(body);
        assert!(e.contains(part), "{body}: {e}");
    }
}

/// `phong` (Mitsuba 0.6's, penumbra's own in Mitsuba 3 files): its defaults, and the energy
/// bound kd + ks ≤ 1 and the exponent's range checked for constant values.
#[test]
fn phong_reads_its_parameters_and_refuses_energy_gain() {
    use penumbra::scene::description::BsdfDesc;
    let d = desc_body(r#"<shape type="sphere"><bsdf type="phong"/></shape>"#);
    match &d.shapes[0].bsdf {
        BsdfDesc::Table { plugin, params } if *plugin == "phong" => {
            let [exponent, diffuse_reflectance, specular_reflectance] = params.as_slice() else {
                panic!("phong has three parameters, got {params:?}");
            };
            assert_eq!(exponent.constant_scalar(), Some(30.0));
            assert_eq!(diffuse_reflectance.constant_rgb(), Some(DVec3::splat(0.5)));
            assert_eq!(specular_reflectance.constant_rgb(), Some(DVec3::splat(0.2)));
        }
        other => panic!("expected phong, got {other:?}"),
    }
    let e = error_body(
        r#"<shape type="sphere"><bsdf type="phong"><rgb name="diffuse_reflectance" value="0.5, 0.9, 0.5"/><rgb name="specular_reflectance" value="0.2"/></bsdf></shape>"#,
    );
    assert!(e.contains("exceeds 1"), "{e}");
    let e = error_body(
        r#"<shape type="sphere"><bsdf type="phong"><float name="exponent" value="-1"/></bsdf></shape>"#,
    );
    assert!(e.contains("exponent"), "{e}");
    // The range of phong's table: the message names the parameter, the range and the value.
    let e = error_body(
        r#"<shape type="sphere"><bsdf type="phong"><float name="exponent" value="2e5"/></bsdf></shape>"#,
    );
    assert!(
        e.contains("the exponent of <bsdf type=\"phong\"> must be in [0, 100000], got 200000"),
        "{e}"
    );
}

/// Parameters of Mitsuba's that only some values make meaningful: roughplastic's
/// `alpha_u`/`alpha_v` when equal (its isotropic alpha), srgb's `unbounded` (an <rgb> above
/// 1 accepted), gridvolume's `max_value` (kept for the majorant).
#[test]
fn equal_alphas_unbounded_srgb_and_max_value() {
    let shape = |bsdf: &str| {
        parse(&with_sensor(&format!(
            r#"<shape type="sphere"><bsdf type="roughplastic">{bsdf}</bsdf></shape>"#
        )))
    };
    let d =
        shape(r#"<float name="alpha_u" value="0.3"/><float name="alpha_v" value="0.3"/>"#).unwrap();
    let bsdf = &d.shapes[0].bsdf;
    assert_eq!(bsdf.plugin(), Some("roughplastic"));
    assert_eq!(bsdf.param("alpha"), Some(&TextureDesc::value(0.3)));
    let e = shape(r#"<float name="alpha_u" value="0.3"/><float name="alpha_v" value="0.2"/>"#)
        .unwrap_err()
        .to_string();
    assert!(e.contains("does not support anisotropic roughness"), "{e}");
    let srgb = |extra: &str| {
        parse(&with_sensor(&format!(
            r#"<shape type="sphere"><bsdf type="diffuse"><texture type="srgb" name="reflectance"><rgb name="color" value="1.5, 0.5, 0.2"/>{extra}</texture></bsdf></shape>"#
        )))
    };
    let e = srgb("").unwrap_err().to_string();
    assert!(e.contains("invalid RGB reflectance value"), "{e}");
    let d = srgb(r#"<boolean name="unbounded" value="true"/>"#).unwrap();
    let reflectance = d.shapes[0].bsdf.param("reflectance").unwrap();
    assert_eq!(reflectance.constant_rgb(), Some(DVec3::new(1.5, 0.5, 0.2)));
    let d = desc(&with_sensor(
        r#"<medium type="heterogeneous" id="m"><volume type="gridvolume" name="sigma_t"><string name="filename" value="g.vol"/><float name="max_value" value="7"/></volume></medium>
<shape type="sphere"><ref name="interior" id="m"/></shape>"#,
    ));
    let VolumeDesc::Grid { max_value, .. } = &d.media[0].sigma_t else {
        panic!("{:?}", d.media[0].sigma_t)
    };
    assert_eq!(*max_value, Some(7.0));
}

/// The kinds of parameter the BSDF tables read (issue 41), each with its defaults and its
/// refusals: choices, flags, IOR presets by name, conductor `material` presets, the
/// roughness pair, roughplastic's numeric alpha.
#[test]
fn table_kinds_read_as_mitsuba() {
    let bsdf = |b: &str| one_shape(&format!(r#"<shape type="sphere">{b}</shape>"#)).bsdf;
    let v = TextureDesc::value;
    // Every default of roughconductor, in table order: beckmann, alpha 0.1 (both axes),
    // sample_visible, the `none` material (η 0, k 1), specular_reflectance 1.
    assert_eq!(
        bsdf(r#"<bsdf type="roughconductor"/>"#),
        BsdfDesc::Table {
            plugin: "roughconductor",
            params: vec![v(0.0), v(0.1), v(0.1), v(1.0), v(0.0), v(1.0), v(1.0)],
        }
    );
    let b = bsdf(
        r#"<bsdf type="roughconductor"><string name="distribution" value="ggx"/><float name="alpha_u" value="0.2"/><float name="alpha_v" value="0.4"/><boolean name="sample_visible" value="false"/><string name="material" value="Au"/></bsdf>"#,
    );
    assert_eq!(b.param("distribution"), Some(&v(1.0)));
    assert_eq!(b.param("alpha_u"), Some(&v(0.2)));
    assert_eq!(b.param("alpha_v"), Some(&v(0.4)));
    assert_eq!(b.param("sample_visible"), Some(&v(0.0)));
    let au = |c: [f32; 3]| DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64);
    assert_eq!(
        b.param("eta").and_then(|t| t.constant_rgb()),
        Some(au([0.14303598, 0.37530708, 1.4420453]))
    );
    assert_eq!(
        b.param("k").and_then(|t| t.constant_rgb()),
        Some(au([3.982997, 2.3855565, 1.6033592]))
    );
    // Spectral mode renders the measured spectra behind those RGB values (Mitsuba's
    // data/ior/Au.eta.spd: 56 pairs from 298.757050 nm, where eta = 1.795).
    match b.param("eta") {
        Some(TextureDesc::Constant {
            spectral:
                SpectralDesc::Sampled(SpectrumValue::Sampled {
                    wavelengths,
                    values,
                }),
            ..
        }) => {
            assert_eq!(wavelengths.len(), 56);
            assert_eq!((wavelengths[0], values[0]), (298.757050, 1.795000));
        }
        other => panic!("Au eta is not a measured spectrum: {other:?}"),
    }
    // IORs: the defaults (bk7 inside, air outside) and a name.
    let d = bsdf(r#"<bsdf type="dielectric"><string name="ext_ior" value="water"/></bsdf>"#);
    assert_eq!(d.param("int_ior"), Some(&v(1.5046f32 as f64)));
    assert_eq!(d.param("ext_ior"), Some(&v(1.333f32 as f64)));
    assert_eq!(
        bsdf(r#"<bsdf type="plastic"/>"#).param("int_ior"),
        Some(&v(1.49f32 as f64))
    );
    assert_eq!(
        bsdf(r#"<bsdf type="roughplastic"><boolean name="nonlinear" value="true"/></bsdf>"#)
            .param("nonlinear"),
        Some(&v(1.0))
    );
    let refused = |b: &str, at: &str, parts: &[&str]| {
        assert_error(
            &with_sensor(&format!(r#"<shape type="sphere">{b}</shape>"#)),
            at,
            parts,
        )
    };
    refused(
        r#"<bsdf type="roughdielectric"><string name="distribution" value="phong"/></bsdf>"#,
        "phong",
        &["invalid distribution 'phong'", "\"beckmann\" or \"ggx\""],
    );
    refused(
        r#"<bsdf type="thindielectric"><string name="int_ior" value="glas"/></bsdf>"#,
        "glas",
        &["unknown int_ior 'glas'", "bk7"],
    );
    refused(
        r#"<bsdf type="plastic"><float name="ext_ior" value="-1"/></bsdf>"#,
        "plastic",
        &["ext_ior", "must be positive"],
    );
    refused(
        r#"<bsdf type="conductor"><string name="material" value="Au"/><float name="eta" value="2"/></bsdf>"#,
        "Au",
        &["either (eta, k) or material"],
    );
    refused(
        r#"<bsdf type="conductor"><string name="material" value="Gold"/></bsdf>"#,
        "Gold",
        &["unknown conductor material 'Gold'"],
    );
    refused(
        r#"<bsdf type="roughplastic"><texture type="bitmap" name="alpha"><string name="filename" value="a.png"/></texture></bsdf>"#,
        "roughplastic",
        &["must be a number, not a texture"],
    );
    refused(
        r#"<bsdf type="roughconductor"><float name="alpha" value="-0.1"/></bsdf>"#,
        "roughconductor",
        &["alpha_u", "finite and >= 0"],
    );
    refused(
        r#"<bsdf type="plastic"><string name="nonlinear" value="yes"/></bsdf>"#,
        "yes",
        &["nonlinear"],
    );
    // principled: `eta` absent is 0 (then `specular` stands for it), never with `specular`;
    // `has_spec_trans` is Mitsuba's get_flag of spec_trans, not a scene parameter.
    let p = bsdf(r#"<bsdf type="principled"/>"#);
    assert_eq!(p.param("eta"), Some(&v(0.0)));
    assert_eq!(p.param("specular"), Some(&v(0.5)));
    assert_eq!(p.param("has_spec_trans"), Some(&v(0.0)));
    let p = bsdf(
        r#"<bsdf type="principled"><float name="eta" value="1.33"/><float name="spec_trans" value="0.2"/></bsdf>"#,
    );
    assert_eq!(p.param("eta"), Some(&v(1.33)));
    assert_eq!(p.param("has_spec_trans"), Some(&v(1.0)));
    let p = bsdf(r#"<bsdf type="principled"><float name="spec_trans" value="0"/></bsdf>"#);
    assert_eq!(p.param("has_spec_trans"), Some(&v(0.0)));
    refused(
        r#"<bsdf type="principled"><float name="eta" value="1.5"/><float name="specular" value="0.3"/></bsdf>"#,
        "principled",
        &["either 'eta' or 'specular', not both"],
    );
    refused(
        r#"<bsdf type="principled"><float name="eta" value="-1.5"/></bsdf>"#,
        "principled",
        &["eta", "must be positive"],
    );
    refused(
        r#"<bsdf type="principled"><float name="specular" value="1.5"/></bsdf>"#,
        "principled",
        &["specular", "[0, 1]"],
    );
    refused(
        r#"<bsdf type="principled"><boolean name="has_spec_trans" value="true"/></bsdf>"#,
        "has_spec_trans",
        &["has_spec_trans"],
    );
    refused(
        r#"<bsdf type="principledthin"><float name="diffuse_transmittance_sampling_rate" value="-1"/></bsdf>"#,
        "principledthin",
        &["diffuse_transmittance_sampling_rate", "[0, inf]"],
    );
}
