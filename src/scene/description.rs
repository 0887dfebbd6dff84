//! The typed scene description: plain data parsed from the generic XML tree, with Mitsuba's
//! defaults filled in and every plugin and parameter checked. No rendering types here.
//!
//! Anything outside the supported subset is an error naming the element, its plugin type and
//! its location; nothing is silently ignored.

use super::xml::{Child, Object, Value};
use crate::camera::FovAxis;
use crate::error::{Error, Location, Result};
use glam::{DMat4, DVec3};
use std::path::PathBuf;
use std::sync::Arc;

#[derive(Clone, Debug, PartialEq)]
pub struct SceneDescription {
    pub integrator: IntegratorDesc,
    pub sensor: SensorDesc,
    pub shapes: Vec<ShapeDesc>,
    /// Emitters declared at the scene level (point, spot, directional, constant, envmap).
    pub emitters: Vec<EmitterDesc>,
}

/// Mitsuba's `path` integrator. `max_depth` −1 means unbounded.
#[derive(Clone, Debug, PartialEq)]
pub enum IntegratorDesc {
    Path {
        max_depth: i64,
        rr_depth: i64,
        hide_emitters: bool,
    },
}

#[derive(Clone, Debug, PartialEq)]
pub struct SensorDesc {
    pub fov: f64,
    pub fov_axis: FovAxis,
    pub near_clip: f64,
    pub far_clip: f64,
    pub to_world: DMat4,
    pub film: FilmDesc,
    pub sampler: SamplerDesc,
    pub location: Location,
    /// `thinlens`: (aperture_radius, focus_distance); `None` for `perspective`.
    pub thin_lens: Option<(f64, f64)>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct FilmDesc {
    pub width: u32,
    pub height: u32,
    pub rfilter: FilterDesc,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FilterDesc {
    Box,
    Tent { radius: f64 },
    Gaussian { stddev: f64 },
}

#[derive(Clone, Debug, PartialEq)]
pub struct SamplerDesc {
    pub sample_count: u32,
    pub seed: u64,
}

#[derive(Clone, Debug, PartialEq)]
pub enum ShapeKind {
    Rectangle,
    Cube,
    Disk,
    Sphere {
        center: DVec3,
        radius: f64,
    },
    Obj {
        filename: PathBuf,
        face_normals: bool,
        flip_tex_coords: bool,
    },
}

#[derive(Clone, Debug, PartialEq)]
pub struct ShapeDesc {
    pub kind: ShapeKind,
    pub to_world: DMat4,
    pub flip_normals: bool,
    pub bsdf: BsdfDesc,
    pub emitter: Option<EmitterDesc>,
    pub location: Location,
}

#[derive(Clone, Debug, PartialEq)]
pub enum BsdfDesc {
    Diffuse {
        reflectance: DVec3,
    },
    TwoSided {
        front: Box<BsdfDesc>,
        back: Box<BsdfDesc>,
    },
    /// `conductor`: complex IOR (from `eta`/`k` or a named `material`).
    Conductor {
        eta: DVec3,
        k: DVec3,
        specular_reflectance: DVec3,
    },
    RoughConductor {
        distribution: MicrofacetDesc,
        eta: DVec3,
        k: DVec3,
        specular_reflectance: DVec3,
    },
    /// `dielectric`; IORs resolved to numbers (presets looked up).
    Dielectric {
        int_ior: f64,
        ext_ior: f64,
        specular_reflectance: DVec3,
        specular_transmittance: DVec3,
    },
    ThinDielectric {
        int_ior: f64,
        ext_ior: f64,
        specular_reflectance: DVec3,
        specular_transmittance: DVec3,
    },
    RoughDielectric {
        distribution: MicrofacetDesc,
        int_ior: f64,
        ext_ior: f64,
        specular_reflectance: DVec3,
        specular_transmittance: DVec3,
    },
    Plastic {
        int_ior: f64,
        ext_ior: f64,
        diffuse_reflectance: DVec3,
        specular_reflectance: DVec3,
        nonlinear: bool,
    },
    RoughPlastic {
        distribution: MicrofacetDesc,
        int_ior: f64,
        ext_ior: f64,
        diffuse_reflectance: DVec3,
        specular_reflectance: DVec3,
        nonlinear: bool,
    },
}

/// Microfacet distribution parameters shared by the rough BSDFs (Mitsuba's `distribution`,
/// `alpha` or `alpha_u`/`alpha_v`, `sample_visible`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MicrofacetDesc {
    pub kind: MicrofacetKind,
    pub alpha_u: f64,
    pub alpha_v: f64,
    pub sample_visible: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MicrofacetKind {
    Beckmann,
    Ggx,
}

impl BsdfDesc {
    /// Mitsuba's default for a shape without a BSDF: diffuse with reflectance 0.5.
    pub fn default_diffuse() -> Self {
        BsdfDesc::Diffuse {
            reflectance: DVec3::splat(0.5),
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub enum EmitterDesc {
    Area {
        radiance: DVec3,
    },
    Point {
        position: DVec3,
        intensity: DVec3,
    },
    Spot {
        to_world: DMat4,
        intensity: DVec3,
        /// Degrees.
        cutoff_angle: f64,
        beam_width: f64,
    },
    Directional {
        /// Unit direction in which the light travels (world).
        direction: DVec3,
        irradiance: DVec3,
    },
    Constant {
        radiance: DVec3,
    },
    EnvMap {
        filename: PathBuf,
        scale: f64,
        to_world: DMat4,
        location: Location,
    },
}

/// Largest image side accepted; larger ones are refused before allocating anything.
pub const MAX_RESOLUTION: u32 = 1 << 16;
/// Largest pixel count accepted (8192², whose f64 film takes 3.8 GB).
pub const MAX_PIXELS: u64 = 1 << 26;

/// `<tag type="plugin">` for messages.
fn describe(o: &Object) -> String {
    if o.plugin.is_empty() {
        format!("<{}>", o.tag)
    } else {
        format!("<{} type=\"{}\">", o.tag, o.plugin)
    }
}

/// Reads an object's properties by name, tracking which were used so that unknown ones are
/// reported.
struct Props<'a> {
    obj: &'a Object,
    used: Vec<bool>,
}

impl<'a> Props<'a> {
    fn new(obj: &'a Object) -> Self {
        Props {
            obj,
            used: vec![false; obj.properties.len()],
        }
    }

    fn take(&mut self, name: &str) -> Option<(&'a Value, &'a Location)> {
        let i = self.obj.properties.iter().position(|p| p.name == name)?;
        self.used[i] = true;
        let p = &self.obj.properties[i];
        Some((&p.value, &p.location))
    }

    fn wrong_type(&self, name: &str, v: &Value, loc: &Location, expected: &str) -> Error {
        Error::scene(
            loc,
            format!(
                "parameter '{name}' of {} must be {expected}, not {}",
                describe(self.obj),
                v.type_name()
            ),
        )
    }

    fn float(&mut self, name: &str, default: f64) -> Result<f64> {
        match self.take(name) {
            None => Ok(default),
            Some((Value::Float(x), _)) => Ok(*x),
            Some((Value::Integer(i), _)) => Ok(*i as f64),
            Some((v, loc)) => Err(self.wrong_type(name, v, loc, "a float")),
        }
    }

    fn int(&mut self, name: &str, default: i64) -> Result<i64> {
        match self.take(name) {
            None => Ok(default),
            Some((Value::Integer(i), _)) => Ok(*i),
            Some((v, loc)) => Err(self.wrong_type(name, v, loc, "an integer")),
        }
    }

    fn boolean(&mut self, name: &str, default: bool) -> Result<bool> {
        match self.take(name) {
            None => Ok(default),
            Some((Value::Boolean(b), _)) => Ok(*b),
            Some((v, loc)) => Err(self.wrong_type(name, v, loc, "a boolean")),
        }
    }

    fn string(&mut self, name: &str) -> Result<Option<(&'a str, &'a Location)>> {
        match self.take(name) {
            None => Ok(None),
            Some((Value::String(s), loc)) => Ok(Some((s.as_str(), loc))),
            Some((v, loc)) => Err(self.wrong_type(name, v, loc, "a string")),
        }
    }

    /// An RGB colour given as `<rgb>` or as one `<float>`.
    fn color(&mut self, name: &str) -> Result<Option<DVec3>> {
        match self.take(name) {
            None => Ok(None),
            Some((Value::Rgb(c), _)) => Ok(Some(*c)),
            Some((Value::Float(x), _)) => Ok(Some(DVec3::splat(*x))),
            Some((Value::Integer(i), _)) => Ok(Some(DVec3::splat(*i as f64))),
            Some((v, loc)) => Err(self.wrong_type(name, v, loc, "an rgb or float")),
        }
    }

    fn point(&mut self, name: &str, default: DVec3) -> Result<DVec3> {
        match self.take(name) {
            None => Ok(default),
            Some((Value::Point(p), _)) | Some((Value::Vector(p), _)) => Ok(*p),
            Some((v, loc)) => Err(self.wrong_type(name, v, loc, "a point")),
        }
    }

    fn transform(&mut self, name: &str) -> Result<DMat4> {
        match self.take(name) {
            None => Ok(DMat4::IDENTITY),
            Some((Value::Transform(m), _)) => Ok(*m),
            Some((v, loc)) => Err(self.wrong_type(name, v, loc, "a transform")),
        }
    }

    /// Fails on the first property that was never read.
    fn finish(self) -> Result<()> {
        for (p, used) in self.obj.properties.iter().zip(&self.used) {
            if !used {
                return Err(Error::scene(
                    &p.location,
                    format!(
                        "unknown parameter '{}' ({}) of {}",
                        p.name,
                        p.value.type_name(),
                        describe(self.obj)
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// The required `filename` string parameter, resolved relative to the directory of the file
/// that declares it (Mitsuba resolves relative to the scene file).
fn file_parameter(p: &mut Props, o: &Object) -> Result<PathBuf> {
    let (name, _) = p
        .string("filename")?
        .ok_or_else(|| Error::scene(&o.location, format!("{} needs a 'filename'", describe(o))))?;
    let base = o
        .location
        .file
        .parent()
        .map(PathBuf::from)
        .unwrap_or_default();
    Ok(base.join(name))
}

fn unsupported_plugin(o: &Object) -> Error {
    Error::scene(
        &o.location,
        format!(
            "unsupported plugin {}: penumbra does not implement it",
            describe(o)
        ),
    )
}

fn unexpected_child(parent: &Object, child: &Object) -> Error {
    Error::scene(
        &child.location,
        format!(
            "{} cannot be nested in {}",
            describe(child),
            describe(parent)
        ),
    )
}

fn positive(value: f64, what: &str, o: &Object) -> Result<f64> {
    if value > 0.0 && value.is_finite() {
        Ok(value)
    } else {
        Err(Error::scene(
            &o.location,
            format!("{what} of {} must be positive, got {value}", describe(o)),
        ))
    }
}

/// Converts the `<scene>` root of [`super::xml`] into a typed description.
pub fn from_xml(root: &Object) -> Result<SceneDescription> {
    if root.tag != "scene" {
        return Err(Error::scene(
            &root.location,
            "the root element must be <scene>",
        ));
    }
    Props::new(root).finish()?;
    let mut integrator = None;
    let mut sensor = None;
    let mut shapes = Vec::new();
    let mut emitters = Vec::new();
    for Child { object: o, .. } in &root.children {
        match o.tag.as_str() {
            "integrator" => {
                if integrator.is_some() {
                    return Err(Error::scene(
                        &o.location,
                        "a scene has at most one <integrator>",
                    ));
                }
                integrator = Some(integrator_desc(o)?);
            }
            "sensor" => {
                if sensor.is_some() {
                    return Err(Error::scene(
                        &o.location,
                        "penumbra renders scenes with exactly one <sensor>",
                    ));
                }
                sensor = Some(sensor_desc(o)?);
            }
            "shape" => shapes.push(shape_desc(o)?),
            "emitter" => {
                let e = scene_emitter_desc(o)?;
                let is_env = |e: &EmitterDesc| {
                    matches!(e, EmitterDesc::Constant { .. } | EmitterDesc::EnvMap { .. })
                };
                if is_env(&e) && emitters.iter().any(is_env) {
                    return Err(Error::scene(
                        &o.location,
                        "a scene has at most one environment emitter (constant or envmap)",
                    ));
                }
                emitters.push(e);
            }
            // Declared for later <ref>s; check them now so that errors surface even when
            // unreferenced, as Mitsuba instantiates them too.
            "bsdf" => {
                bsdf_desc(o)?;
            }
            _ => return Err(unexpected_child(root, o)),
        }
    }
    let sensor = sensor.ok_or_else(|| Error::scene(&root.location, "the scene has no <sensor>"))?;
    Ok(SceneDescription {
        integrator: integrator.unwrap_or(IntegratorDesc::Path {
            max_depth: -1,
            rr_depth: 5,
            hide_emitters: false,
        }),
        sensor,
        shapes,
        emitters,
    })
}

fn no_children(o: &Object) -> Result<()> {
    match o.children.first() {
        Some(c) => Err(unexpected_child(o, &c.object)),
        None => Ok(()),
    }
}

fn integrator_desc(o: &Object) -> Result<IntegratorDesc> {
    if o.plugin != "path" {
        return Err(unsupported_plugin(o));
    }
    no_children(o)?;
    let mut p = Props::new(o);
    let max_depth = p.int("max_depth", -1)?;
    let rr_depth = p.int("rr_depth", 5)?;
    let hide_emitters = p.boolean("hide_emitters", false)?;
    p.finish()?;
    if max_depth < -1 {
        return Err(Error::scene(
            &o.location,
            format!(
                "max_depth of {} must be -1 (unbounded) or >= 0, got {max_depth}",
                describe(o)
            ),
        ));
    }
    if rr_depth <= 0 {
        return Err(Error::scene(
            &o.location,
            format!("rr_depth of {} must be > 0, got {rr_depth}", describe(o)),
        ));
    }
    Ok(IntegratorDesc::Path {
        max_depth,
        rr_depth,
        hide_emitters,
    })
}

fn sensor_desc(o: &Object) -> Result<SensorDesc> {
    if o.plugin != "perspective" && o.plugin != "thinlens" {
        return Err(unsupported_plugin(o));
    }
    let mut p = Props::new(o);
    let aperture_radius = if o.plugin == "thinlens" {
        Some(p.float("aperture_radius", f64::NAN)?)
    } else {
        None
    };
    let fov = p.float("fov", f64::NAN)?;
    let fov_axis = match p.string("fov_axis")? {
        None => FovAxis::X,
        Some((s, loc)) => match s {
            "x" => FovAxis::X,
            "y" => FovAxis::Y,
            "diagonal" => FovAxis::Diagonal,
            "smaller" => FovAxis::Smaller,
            "larger" => FovAxis::Larger,
            _ => {
                return Err(Error::scene(
                    loc,
                    format!("fov_axis must be x, y, diagonal, smaller or larger, not '{s}'"),
                ))
            }
        },
    };
    let near_clip = p.float("near_clip", 0.01)?;
    let far_clip = p.float("far_clip", 1e4)?;
    // Mitsuba's projective cameras accept focus_distance (default: far_clip); a pinhole has
    // no use for it.
    let focus_distance = p.float("focus_distance", far_clip)?;
    let to_world = p.transform("to_world")?;
    p.finish()?;
    if fov.is_nan() {
        return Err(Error::scene(
            &o.location,
            format!("{} needs a 'fov' (degrees)", describe(o)),
        ));
    }
    if !(fov > 0.0 && fov < 180.0) {
        return Err(Error::scene(
            &o.location,
            format!(
                "fov of {} must lie in (0, 180) degrees, got {fov}",
                describe(o)
            ),
        ));
    }
    positive(near_clip, "near_clip", o)?;
    positive(far_clip, "far_clip", o)?;
    let thin_lens = match aperture_radius {
        None => None,
        Some(a) if a.is_nan() => {
            return Err(Error::scene(
                &o.location,
                format!("{} needs an 'aperture_radius'", describe(o)),
            ))
        }
        Some(a) => {
            if !(a >= 0.0 && a.is_finite()) {
                return Err(Error::scene(
                    &o.location,
                    format!("aperture_radius of {} must be >= 0, got {a}", describe(o)),
                ));
            }
            Some((a, positive(focus_distance, "focus_distance", o)?))
        }
    };
    if near_clip >= far_clip {
        return Err(Error::scene(
            &o.location,
            format!("near_clip ({near_clip}) must be less than far_clip ({far_clip})"),
        ));
    }
    let mut film = None;
    let mut sampler = None;
    for Child { object: c, .. } in &o.children {
        match c.tag.as_str() {
            "film" if film.is_none() => film = Some(film_desc(c)?),
            "sampler" if sampler.is_none() => sampler = Some(sampler_desc(c)?),
            _ => return Err(unexpected_child(o, c)),
        }
    }
    Ok(SensorDesc {
        fov,
        fov_axis,
        near_clip,
        far_clip,
        to_world,
        // Mitsuba's default film: hdrfilm 768x576 with the gaussian filter.
        film: film.unwrap_or(FilmDesc {
            width: 768,
            height: 576,
            rfilter: FilterDesc::Gaussian { stddev: 0.5 },
        }),
        sampler: sampler.unwrap_or(SamplerDesc {
            sample_count: 4,
            seed: 0,
        }),
        location: o.location.clone(),
        thin_lens,
    })
}

fn film_desc(o: &Object) -> Result<FilmDesc> {
    if o.plugin != "hdrfilm" {
        return Err(unsupported_plugin(o));
    }
    let mut p = Props::new(o);
    let width = p.int("width", 768)?;
    let height = p.int("height", 576)?;
    if let Some((f, loc)) = p.string("component_format")? {
        // The output is always float32 EXR; the other formats are accepted like Mitsuba.
        if !matches!(f, "float16" | "float32" | "uint32") {
            return Err(Error::scene(
                loc,
                format!("component_format must be float16, float32 or uint32, not '{f}'"),
            ));
        }
    }
    if let Some((f, loc)) = p.string("pixel_format")? {
        if f != "rgb" {
            return Err(Error::scene(
                loc,
                format!("pixel_format '{f}' is not supported (penumbra writes rgb)"),
            ));
        }
    }
    p.finish()?;
    for (name, v) in [("width", width), ("height", height)] {
        if v <= 0 || v > MAX_RESOLUTION as i64 {
            return Err(Error::scene(
                &o.location,
                format!("film {name} must be between 1 and {MAX_RESOLUTION}, got {v}"),
            ));
        }
    }
    if width as u64 * height as u64 > MAX_PIXELS {
        return Err(Error::scene(
            &o.location,
            format!("film of {width}x{height} pixels exceeds the limit of {MAX_PIXELS} pixels"),
        ));
    }
    let mut rfilter = None;
    for Child { object: c, .. } in &o.children {
        match c.tag.as_str() {
            "rfilter" if rfilter.is_none() => rfilter = Some(rfilter_desc(c)?),
            _ => return Err(unexpected_child(o, c)),
        }
    }
    // Mitsuba's default reconstruction filter.
    let rfilter = rfilter.unwrap_or(FilterDesc::Gaussian { stddev: 0.5 });
    Ok(FilmDesc {
        width: width as u32,
        height: height as u32,
        rfilter,
    })
}

fn rfilter_desc(c: &Object) -> Result<FilterDesc> {
    no_children(c)?;
    let mut fp = Props::new(c);
    let f = match c.plugin.as_str() {
        "box" => {
            let radius = fp.float("radius", 0.5)?;
            if radius != 0.5 {
                return Err(Error::scene(
                    &c.location,
                    "the box filter is supported with its default radius 0.5 only",
                ));
            }
            FilterDesc::Box
        }
        "tent" => FilterDesc::Tent {
            radius: positive(fp.float("radius", 1.0)?, "radius", c)?,
        },
        "gaussian" => FilterDesc::Gaussian {
            stddev: positive(fp.float("stddev", 0.5)?, "stddev", c)?,
        },
        _ => {
            return Err(Error::scene(
                &c.location,
                format!(
                    "unsupported plugin {}: penumbra supports the box, tent and gaussian filters",
                    describe(c)
                ),
            ))
        }
    };
    fp.finish()?;
    if let FilterDesc::Tent { radius: r } | FilterDesc::Gaussian { stddev: r } = f {
        // At most 15 pixels of reach per side: beyond that a filter is surely a mistake.
        let radius = if matches!(f, FilterDesc::Gaussian { .. }) {
            4.0 * r
        } else {
            r
        };
        if radius > 7.5 {
            return Err(Error::scene(
                &c.location,
                format!("the radius of {} must be at most 7.5 pixels", describe(c)),
            ));
        }
    }
    Ok(f)
}

fn sampler_desc(o: &Object) -> Result<SamplerDesc> {
    if o.plugin != "independent" {
        return Err(unsupported_plugin(o));
    }
    no_children(o)?;
    let mut p = Props::new(o);
    let sample_count = p.int("sample_count", 4)?;
    let seed = p.int("seed", 0)?;
    p.finish()?;
    if sample_count <= 0 || sample_count > u32::MAX as i64 {
        return Err(Error::scene(
            &o.location,
            format!(
                "sample_count must be between 1 and {}, got {sample_count}",
                u32::MAX
            ),
        ));
    }
    if seed < 0 {
        return Err(Error::scene(
            &o.location,
            format!("seed must be >= 0, got {seed}"),
        ));
    }
    Ok(SamplerDesc {
        sample_count: sample_count as u32,
        seed: seed as u64,
    })
}

fn shape_desc(o: &Object) -> Result<ShapeDesc> {
    let mut p = Props::new(o);
    let to_world = p.transform("to_world")?;
    let flip_normals = p.boolean("flip_normals", false)?;
    let kind = match o.plugin.as_str() {
        "rectangle" => ShapeKind::Rectangle,
        "cube" => ShapeKind::Cube,
        "disk" => ShapeKind::Disk,
        "sphere" => {
            let center = p.point("center", DVec3::ZERO)?;
            let radius = p.float("radius", 1.0)?;
            positive(radius, "radius", o)?;
            ShapeKind::Sphere { center, radius }
        }
        "obj" => ShapeKind::Obj {
            filename: file_parameter(&mut p, o)?,
            face_normals: p.boolean("face_normals", false)?,
            flip_tex_coords: p.boolean("flip_tex_coords", true)?,
        },
        _ => return Err(unsupported_plugin(o)),
    };
    p.finish()?;
    if !to_world.is_finite() {
        return Err(Error::scene(
            &o.location,
            format!("to_world of {} is not finite", describe(o)),
        ));
    }
    let mut bsdf = None;
    let mut emitter = None;
    for Child { object: c, .. } in &o.children {
        match c.tag.as_str() {
            "bsdf" if bsdf.is_none() => bsdf = Some(bsdf_desc(c)?),
            "emitter" if emitter.is_none() => emitter = Some(area_emitter_desc(c)?),
            "bsdf" | "emitter" => {
                return Err(Error::scene(
                    &c.location,
                    format!("{} has more than one <{}>", describe(o), c.tag),
                ))
            }
            _ => return Err(unexpected_child(o, c)),
        }
    }
    Ok(ShapeDesc {
        kind,
        to_world,
        flip_normals,
        bsdf: bsdf.unwrap_or_else(BsdfDesc::default_diffuse),
        emitter,
        location: o.location.clone(),
    })
}

fn bsdf_desc(o: &Arc<Object>) -> Result<BsdfDesc> {
    match o.plugin.as_str() {
        "diffuse" => {
            no_children(o)?;
            let mut p = Props::new(o);
            let reflectance = p.color("reflectance")?.unwrap_or(DVec3::splat(0.5));
            p.finish()?;
            Ok(BsdfDesc::Diffuse { reflectance })
        }
        "twosided" => {
            Props::new(o).finish()?;
            let mut nested = Vec::new();
            for Child { object: c, .. } in &o.children {
                if c.tag != "bsdf" || nested.len() == 2 {
                    return Err(unexpected_child(o, c));
                }
                if c.plugin == "twosided" {
                    return Err(Error::scene(
                        &c.location,
                        "a twosided BSDF cannot nest another twosided",
                    ));
                }
                nested.push(bsdf_desc(c)?);
            }
            let mut it = nested.into_iter();
            let front = it.next().ok_or_else(|| {
                Error::scene(
                    &o.location,
                    format!("{} needs a nested <bsdf>", describe(o)),
                )
            })?;
            let back = it.next().unwrap_or_else(|| front.clone());
            Ok(BsdfDesc::TwoSided {
                front: Box::new(front),
                back: Box::new(back),
            })
        }
        "conductor" | "roughconductor" => {
            no_children(o)?;
            let mut p = Props::new(o);
            let distribution = if o.plugin == "roughconductor" {
                Some(microfacet_desc(&mut p, o, true)?)
            } else {
                None
            };
            let (eta, k) = conductor_ior(&mut p, o)?;
            let specular_reflectance = p.color("specular_reflectance")?.unwrap_or(DVec3::ONE);
            p.finish()?;
            Ok(match distribution {
                None => BsdfDesc::Conductor {
                    eta,
                    k,
                    specular_reflectance,
                },
                Some(distribution) => BsdfDesc::RoughConductor {
                    distribution,
                    eta,
                    k,
                    specular_reflectance,
                },
            })
        }
        "dielectric" | "thindielectric" | "roughdielectric" => {
            no_children(o)?;
            let mut p = Props::new(o);
            let distribution = if o.plugin == "roughdielectric" {
                Some(microfacet_desc(&mut p, o, true)?)
            } else {
                None
            };
            let int_ior = ior(&mut p, o, "int_ior", "bk7")?;
            let ext_ior = ior(&mut p, o, "ext_ior", "air")?;
            let specular_reflectance = p.color("specular_reflectance")?.unwrap_or(DVec3::ONE);
            let specular_transmittance = p.color("specular_transmittance")?.unwrap_or(DVec3::ONE);
            p.finish()?;
            Ok(match (o.plugin.as_str(), distribution) {
                ("roughdielectric", Some(distribution)) => BsdfDesc::RoughDielectric {
                    distribution,
                    int_ior,
                    ext_ior,
                    specular_reflectance,
                    specular_transmittance,
                },
                ("thindielectric", _) => BsdfDesc::ThinDielectric {
                    int_ior,
                    ext_ior,
                    specular_reflectance,
                    specular_transmittance,
                },
                _ => BsdfDesc::Dielectric {
                    int_ior,
                    ext_ior,
                    specular_reflectance,
                    specular_transmittance,
                },
            })
        }
        "plastic" | "roughplastic" => {
            no_children(o)?;
            let mut p = Props::new(o);
            let distribution = if o.plugin == "roughplastic" {
                // Mitsuba's roughplastic is isotropic only.
                Some(microfacet_desc(&mut p, o, false)?)
            } else {
                None
            };
            let int_ior = ior(&mut p, o, "int_ior", "polypropylene")?;
            let ext_ior = ior(&mut p, o, "ext_ior", "air")?;
            let diffuse_reflectance = p.color("diffuse_reflectance")?.unwrap_or(DVec3::splat(0.5));
            let specular_reflectance = p.color("specular_reflectance")?.unwrap_or(DVec3::ONE);
            let nonlinear = p.boolean("nonlinear", false)?;
            p.finish()?;
            Ok(match distribution {
                None => BsdfDesc::Plastic {
                    int_ior,
                    ext_ior,
                    diffuse_reflectance,
                    specular_reflectance,
                    nonlinear,
                },
                Some(distribution) => BsdfDesc::RoughPlastic {
                    distribution,
                    int_ior,
                    ext_ior,
                    diffuse_reflectance,
                    specular_reflectance,
                    nonlinear,
                },
            })
        }
        _ => Err(unsupported_plugin(o)),
    }
}

/// An index of refraction given as a number or as one of Mitsuba's named presets.
fn ior(p: &mut Props, o: &Object, name: &str, default: &str) -> Result<f64> {
    let value = match p.take(name) {
        None => crate::bsdf::presets::ior(default).map(|v| v as f64),
        Some((Value::Float(x), _)) => Some(*x),
        Some((Value::Integer(i), _)) => Some(*i as f64),
        Some((Value::String(s), loc)) => Some(crate::bsdf::presets::ior(s).ok_or_else(|| {
            let names: Vec<&str> = crate::bsdf::presets::IOR_PRESETS
                .iter()
                .map(|(n, _)| *n)
                .collect();
            Error::scene(
                loc,
                format!(
                    "unknown {name} '{s}' of {}; valid names: {}",
                    describe(o),
                    names.join(", ")
                ),
            )
        })? as f64),
        Some((v, loc)) => return Err(p.wrong_type(name, v, loc, "a float or a material name")),
    };
    let value = value.unwrap_or(1.0);
    positive(value, name, o)
}

/// `eta` and `k` of a conductor: numbers/colours, or a named `material` (not both), as in
/// Mitsuba; the default `none` is the ideal mirror η = 0, k = 1.
fn conductor_ior(p: &mut Props, o: &Object) -> Result<(DVec3, DVec3)> {
    let material = p.string("material")?;
    let eta = p.color("eta")?;
    let k = p.color("k")?;
    match material {
        Some((name, loc)) if name != "none" => {
            if eta.is_some() || k.is_some() {
                return Err(Error::scene(
                    loc,
                    format!(
                        "{} should specify either (eta, k) or material, not both",
                        describe(o)
                    ),
                ));
            }
            let (e, kk) = crate::bsdf::presets::conductor(name).ok_or_else(|| {
                let names: Vec<&str> = crate::bsdf::presets::CONDUCTOR_PRESETS
                    .iter()
                    .map(|(n, _, _)| *n)
                    .collect();
                Error::scene(
                    loc,
                    format!(
                        "unknown conductor material '{name}' of {}; valid names: none, {}",
                        describe(o),
                        names.join(", ")
                    ),
                )
            })?;
            let v = |a: [f32; 3]| DVec3::new(a[0] as f64, a[1] as f64, a[2] as f64);
            Ok((v(e), v(kk)))
        }
        _ => {
            let eta = eta.unwrap_or(DVec3::ZERO);
            let k = k.unwrap_or(DVec3::ONE);
            if !(eta.is_finite()
                && k.is_finite()
                && eta.min_element() >= 0.0
                && k.min_element() >= 0.0)
            {
                return Err(Error::scene(
                    &o.location,
                    format!("eta and k of {} must be finite and >= 0", describe(o)),
                ));
            }
            Ok((eta, k))
        }
    }
}

/// Mitsuba's microfacet parameters: `distribution` (beckmann | ggx, default beckmann),
/// `alpha` (default 0.1) or, when `anisotropic` is allowed, both `alpha_u` and `alpha_v`;
/// `sample_visible` (default true). Roughness must be finite and >= 0 (Mitsuba accepts
/// negative values without meaning; penumbra refuses them).
fn microfacet_desc(p: &mut Props, o: &Object, anisotropic: bool) -> Result<MicrofacetDesc> {
    let kind = match p.string("distribution")? {
        None => MicrofacetKind::Beckmann,
        Some(("beckmann", _)) => MicrofacetKind::Beckmann,
        Some(("ggx", _)) => MicrofacetKind::Ggx,
        Some((s, loc)) => {
            return Err(Error::scene(
                loc,
                format!(
                    "invalid distribution '{s}' of {}: must be \"beckmann\" or \"ggx\"",
                    describe(o)
                ),
            ))
        }
    };
    let has_alpha = p.obj.properties.iter().any(|q| q.name == "alpha");
    let has_uv = p
        .obj
        .properties
        .iter()
        .any(|q| q.name == "alpha_u" || q.name == "alpha_v");
    let (alpha_u, alpha_v) = if has_uv {
        if !anisotropic {
            return Err(Error::scene(
                &o.location,
                format!(
                    "{} does not support anisotropic roughness (alpha_u/alpha_v); use alpha",
                    describe(o)
                ),
            ));
        }
        if has_alpha {
            return Err(Error::scene(
                &o.location,
                format!(
                    "{}: give either alpha or both alpha_u and alpha_v",
                    describe(o)
                ),
            ));
        }
        let u = p.float("alpha_u", f64::NAN)?;
        let v = p.float("alpha_v", f64::NAN)?;
        if u.is_nan() || v.is_nan() {
            return Err(Error::scene(
                &o.location,
                format!(
                    "{}: both alpha_u and alpha_v must be specified",
                    describe(o)
                ),
            ));
        }
        (u, v)
    } else {
        let a = p.float("alpha", 0.1)?;
        (a, a)
    };
    for (name, a) in [("alpha_u", alpha_u), ("alpha_v", alpha_v)] {
        if !(a >= 0.0 && a.is_finite()) {
            return Err(Error::scene(
                &o.location,
                format!(
                    "roughness {name} of {} must be finite and >= 0, got {a}",
                    describe(o)
                ),
            ));
        }
    }
    let sample_visible = p.boolean("sample_visible", true)?;
    Ok(MicrofacetDesc {
        kind,
        alpha_u,
        alpha_v,
        sample_visible,
    })
}

fn area_emitter_desc(o: &Object) -> Result<EmitterDesc> {
    if o.plugin != "area" {
        return Err(unsupported_plugin(o));
    }
    no_children(o)?;
    let mut p = Props::new(o);
    let radiance = p.color("radiance")?;
    p.finish()?;
    let radiance = radiance
        .ok_or_else(|| Error::scene(&o.location, format!("{} needs a 'radiance'", describe(o))))?;
    if radiance.min_element() < 0.0 {
        return Err(Error::scene(&o.location, "radiance must not be negative"));
    }
    Ok(EmitterDesc::Area { radiance })
}

fn scene_emitter_desc(o: &Object) -> Result<EmitterDesc> {
    no_children(o)?;
    let mut p = Props::new(o);
    let non_negative = |c: DVec3, what: &str| -> Result<DVec3> {
        if c.min_element() < 0.0 || !c.is_finite() {
            return Err(Error::scene(
                &o.location,
                format!("{what} of {} must be finite and not negative", describe(o)),
            ));
        }
        Ok(c)
    };
    let e = match o.plugin.as_str() {
        "point" => {
            let to_world = p.transform("to_world")?;
            let position = p.point("position", to_world.transform_point3(DVec3::ZERO))?;
            let intensity = p.color("intensity")?.unwrap_or(DVec3::ONE);
            EmitterDesc::Point {
                position,
                intensity: non_negative(intensity, "intensity")?,
            }
        }
        "spot" => {
            let to_world = p.transform("to_world")?;
            let intensity = p.color("intensity")?.unwrap_or(DVec3::ONE);
            let cutoff_angle = p.float("cutoff_angle", 20.0)?;
            let beam_width = p.float("beam_width", cutoff_angle * 0.75)?;
            if !(cutoff_angle > 0.0 && cutoff_angle <= 180.0) {
                return Err(Error::scene(
                    &o.location,
                    format!("cutoff_angle must lie in (0, 180] degrees, got {cutoff_angle}"),
                ));
            }
            if !(beam_width >= 0.0 && beam_width <= cutoff_angle) {
                return Err(Error::scene(
                    &o.location,
                    format!("beam_width must lie in [0, cutoff_angle], got {beam_width}"),
                ));
            }
            EmitterDesc::Spot {
                to_world,
                intensity: non_negative(intensity, "intensity")?,
                cutoff_angle,
                beam_width,
            }
        }
        "directional" => {
            let to_world = p.transform("to_world")?;
            let direction = p.point("direction", to_world.transform_vector3(DVec3::Z))?;
            let irradiance = p.color("irradiance")?.unwrap_or(DVec3::ONE);
            let direction = direction.try_normalize().ok_or_else(|| {
                Error::scene(
                    &o.location,
                    "the direction of a directional emitter is zero",
                )
            })?;
            EmitterDesc::Directional {
                direction,
                irradiance: non_negative(irradiance, "irradiance")?,
            }
        }
        "constant" => {
            let radiance = p.color("radiance")?.unwrap_or(DVec3::ONE);
            EmitterDesc::Constant {
                radiance: non_negative(radiance, "radiance")?,
            }
        }
        "envmap" => {
            let filename = file_parameter(&mut p, o)?;
            let scale = p.float("scale", 1.0)?;
            if !(scale >= 0.0 && scale.is_finite()) {
                return Err(Error::scene(
                    &o.location,
                    format!("scale of {} must be >= 0, got {scale}", describe(o)),
                ));
            }
            if let Some((f, loc)) = p.string("filter_type")? {
                if f != "bilinear" {
                    return Err(Error::scene(
                        loc,
                        format!("filter_type '{f}' is not supported (penumbra: bilinear)"),
                    ));
                }
            }
            EmitterDesc::EnvMap {
                filename,
                scale,
                to_world: p.transform("to_world")?,
                location: o.location.clone(),
            }
        }
        "area" => {
            return Err(Error::scene(
                &o.location,
                "an area emitter must be nested in a <shape>",
            ))
        }
        _ => return Err(unsupported_plugin(o)),
    };
    p.finish()?;
    Ok(e)
}
