//! The typed scene description: plain data parsed from the generic XML tree, with Mitsuba's
//! defaults filled in and every plugin and parameter checked. No rendering types here.
//!
//! Anything outside the supported subset is an error naming the element, its plugin type and
//! its location; nothing is silently ignored.

//!
//! One file per concern: [`integrator`], [`sensor`] (sensor, film, filter, sampler), [`shape`],
//! [`bsdf`] and [`emitter`]; this file holds the scene root and the property reader they
//! share.

mod bsdf;
mod color;
mod emitter;
mod integrator;
mod medium;
mod sensor;
mod shape;
mod texture;

pub use bsdf::*;
pub use color::{ColorDesc, SpectralDesc};
pub use emitter::*;
pub use integrator::*;
pub use medium::*;
pub use sensor::*;
pub use shape::*;
pub use texture::{BitmapDesc, TextureDesc};

use super::resolver::FileResolver;
use super::xml::{Child, Document, Object, Value};
use crate::error::{Error, Location, Result};
use crate::spectrum::ColorRole;
use glam::{DMat4, DVec3};
use std::cell::RefCell;
use std::path::{Path, PathBuf};
use std::sync::Arc;

#[derive(Clone, Debug, PartialEq)]
pub struct SceneDescription {
    pub integrator: IntegratorDesc,
    /// The integrator was wrapped in Mitsuba's `moment` integrator, which adds the second
    /// moment of the samples to the output: penumbra then writes the variance channels, as
    /// `render --variance` does.
    pub moment: bool,
    /// The integrator's `timeout` (Mitsuba's render-time limit), in seconds: the CLI's
    /// default `--time-limit`.
    pub timeout: Option<f64>,
    /// The file has no `<integrator>`: `integrator` is `path` with its defaults.
    pub integrator_missing: bool,
    /// The sensor that is rendered: the file's first, as Mitsuba's `mi.render` renders
    /// `scene.sensors()[0]`, unless [`SceneDescription::select_sensor`] chose another.
    pub sensor: SensorDesc,
    /// Every sensor of the file, in document order (at least one).
    pub sensors: Vec<SensorDesc>,
    pub shapes: Vec<ShapeDesc>,
    /// The shape groups that `instance` shapes refer to (by index).
    pub shape_groups: Vec<ShapeGroupDesc>,
    /// Emitters declared at the scene level (point, spot, directional, constant, envmap).
    pub emitters: Vec<EmitterDesc>,
    /// Their `sampling_weight`s, in the same order.
    pub emitter_weights: Vec<f64>,
    /// The participating media that shapes (`interior`, `exterior`) and the sensor refer to.
    pub media: Vec<MediumDesc>,
    /// Things the user should know that are not errors (clamped spectra, unused emitters).
    pub warnings: Vec<String>,
    /// The mode the scene is rendered in: chosen by the user (`--mode`), not by the file;
    /// RGB unless set. The build makes each colour parameter's RGB or spectral form of it.
    pub mode: crate::spectrum::Mode,
    /// The first construct that only spectral mode renders (a `blackbody` spectrum, which
    /// Mitsuba's RGB variants refuse too), named with its location; RGB mode refuses it.
    pub spectral_only: Option<String>,
}

impl SceneDescription {
    /// Renders with `kind` instead of the file's integrator, which lends it its depths
    /// ([`IntegratorDesc::switched_to`]; the CLI's `--integrator`).
    pub fn use_integrator(&mut self, kind: &str) -> Result<()> {
        self.integrator = self.integrator.switched_to(kind)?;
        self.integrator_missing = false;
        Ok(())
    }

    /// Renders the file's sensor number `index` (from 0, in document order) instead of the
    /// first (the CLI's `--sensor N`).
    pub fn select_sensor(&mut self, index: usize) -> Result<()> {
        match self.sensors.get(index) {
            Some(s) => {
                self.sensor = s.clone();
                Ok(())
            }
            None => Err(Error::Invalid(format!(
                "sensor {index} does not exist: the scene has {} sensor{} (numbered from 0)",
                self.sensors.len(),
                if self.sensors.len() == 1 { "" } else { "s" }
            ))),
        }
    }

    /// Every file the scene reads when it is built (meshes, grids, environment maps), in
    /// description order; shape groups' files once each.
    pub fn files(&self) -> Vec<&Path> {
        let shapes = self
            .shapes
            .iter()
            .chain(self.shape_groups.iter().flat_map(|g| g.shapes.iter()));
        let mut files: Vec<&Path> = shapes
            .filter_map(|s| match &s.kind {
                ShapeKind::Obj { filename, .. }
                | ShapeKind::Ply { filename, .. }
                | ShapeKind::Serialized { filename, .. }
                | ShapeKind::SdfGrid { filename, .. } => Some(filename.as_path()),
                _ => None,
            })
            .collect();
        let shapes = self
            .shapes
            .iter()
            .chain(self.shape_groups.iter().flat_map(|g| g.shapes.iter()));
        for s in shapes {
            s.bsdf.files(&mut files);
            if let Some(e) = &s.emitter {
                e.files(&mut files);
            }
        }
        for e in &self.emitters {
            e.files(&mut files);
        }
        for m in &self.media {
            for v in [&m.sigma_t, &m.albedo] {
                if let VolumeDesc::Grid { filename, .. } = v {
                    files.push(filename.as_path());
                }
            }
        }
        files.sort();
        files.dedup();
        files
    }
}

/// The warning of a scene without an `<integrator>` (rendered with `path`), until another
/// integrator is chosen ([`SceneDescription::use_integrator`]).
pub const NO_INTEGRATOR_WARNING: &str =
    "the scene has no <integrator>: rendering with path (max_depth -1, rr_depth 5); Mitsuba's mi.render needs one passed in";

/// Largest image side accepted; larger ones are refused before allocating anything. (The
/// largest pixel count is the `render_pixels` limit of [`crate::limits`].)
pub const MAX_RESOLUTION: u32 = 1 << 16;

/// `<tag type="plugin">` for messages.
pub(super) fn describe(o: &Object) -> String {
    if o.plugin.is_empty() {
        format!("<{}>", o.tag)
    } else {
        format!("<{} type=\"{}\">", o.tag, o.plugin)
    }
}

/// Reads an object's properties by name, tracking which were used so that unknown ones are
/// reported.
pub(super) struct Props<'a> {
    obj: &'a Object,
    used: Vec<bool>,
    /// Warnings met while reading (clamped spectra); see [`Props::take_warnings`].
    warnings: Vec<String>,
}

impl<'a> Props<'a> {
    pub(super) fn new(obj: &'a Object) -> Self {
        Props {
            obj,
            used: vec![false; obj.properties.len()],
            warnings: Vec::new(),
        }
    }

    pub(super) fn take(&mut self, name: &str) -> Option<(&'a Value, &'a Location)> {
        let i = self.obj.properties.iter().position(|p| p.name == name)?;
        self.used[i] = true;
        let p = &self.obj.properties[i];
        Some((&p.value, &p.location))
    }

    /// The value of `name`, without marking it read.
    pub(super) fn peek(&self, name: &str) -> Option<&'a Value> {
        self.obj
            .properties
            .iter()
            .find(|p| p.name == name)
            .map(|p| &p.value)
    }

    /// Marks `name` as unread again (a reader that looked at a property and leaves it to
    /// another one).
    pub(super) fn untake(&mut self, name: &str) {
        if let Some(i) = self.obj.properties.iter().position(|p| p.name == name) {
            self.used[i] = false;
        }
    }

    pub(super) fn wrong_type(
        &self,
        name: &str,
        v: &Value,
        loc: &Location,
        expected: &str,
    ) -> Error {
        Error::scene(
            loc,
            format!(
                "parameter '{name}' of {} must be {expected}, not {}",
                describe(self.obj),
                v.type_name()
            ),
        )
    }

    pub(super) fn float(&mut self, name: &str, default: f64) -> Result<f64> {
        match self.take(name) {
            None => Ok(default),
            Some((Value::Float(x), _)) => Ok(*x),
            Some((Value::Integer(i), _)) => Ok(*i as f64),
            Some((v, loc)) => Err(self.wrong_type(name, v, loc, "a float")),
        }
    }

    pub(super) fn int(&mut self, name: &str, default: i64) -> Result<i64> {
        match self.take(name) {
            None => Ok(default),
            Some((Value::Integer(i), _)) => Ok(*i),
            Some((v, loc)) => Err(self.wrong_type(name, v, loc, "an integer")),
        }
    }

    pub(super) fn boolean(&mut self, name: &str, default: bool) -> Result<bool> {
        match self.take(name) {
            None => Ok(default),
            Some((Value::Boolean(b), _)) => Ok(*b),
            Some((v, loc)) => Err(self.wrong_type(name, v, loc, "a boolean")),
        }
    }

    pub(super) fn string(&mut self, name: &str) -> Result<Option<(&'a str, &'a Location)>> {
        match self.take(name) {
            None => Ok(None),
            Some((Value::String(s), loc)) => Ok(Some((s.as_str(), loc))),
            Some((v, loc)) => Err(self.wrong_type(name, v, loc, "a string")),
        }
    }

    /// A colour given as `<rgb>`, one `<float>`/`<integer>` or a `<spectrum>`, as the RGB
    /// Mitsuba's RGB variants use when a plugin reads it in `role` (see
    /// [`crate::spectrum`]): spectra are integrated (a clamped out-of-gamut one adds a
    /// warning), and an `<rgb>` reflectance outside [0, 1] is an error, as in Mitsuba.
    ///
    /// The spectrum Mitsuba's spectral variants make of the same value comes with it (see
    /// [`ColorDesc`]).
    pub(super) fn color(&mut self, name: &str, role: ColorRole) -> Result<Option<ColorDesc>> {
        let spectral = match self.peek(name) {
            Some(Value::Rgb(c)) => SpectralDesc::rgb(*c, role),
            Some(Value::Float(x)) => SpectralDesc::number(*x, role),
            Some(Value::Integer(i)) => SpectralDesc::number(*i as f64, role),
            Some(Value::Spectrum(sp)) => SpectralDesc::spectrum(sp),
            _ => SpectralDesc::uniform(0.0),
        };
        Ok(self
            .color_rgb(name, role)?
            .map(|rgb| ColorDesc { rgb, spectral }))
    }

    fn color_rgb(&mut self, name: &str, role: ColorRole) -> Result<Option<DVec3>> {
        match self.take(name) {
            None => Ok(None),
            Some((Value::Rgb(c), loc)) => {
                if role == ColorRole::Reflectance
                    && (c.min_element() < 0.0 || c.max_element() > 1.0)
                {
                    return Err(Error::scene(
                        loc,
                        format!(
                            "invalid RGB reflectance value {} {} {} for '{name}' of {}: must be in [0, 1] (Mitsuba refuses it too; use a <float> or a <spectrum> for an unbounded value)",
                            c.x,
                            c.y,
                            c.z,
                            describe(self.obj)
                        ),
                    ));
                }
                Ok(Some(*c))
            }
            Some((Value::Float(x), _)) => Ok(Some(DVec3::splat(*x))),
            Some((Value::Integer(i), _)) => Ok(Some(DVec3::splat(*i as f64))),
            Some((Value::Spectrum(sp), loc)) => {
                let (rgb, warning) = sp.to_rgb(role);
                if let Some(w) = warning {
                    self.warnings.push(format!("{loc}: {w}"));
                }
                // (the conversion stores what f32 cannot hold as ±f32::MAX, with a warning)
                if rgb.is_nan() || rgb.abs().max_element() >= f32::MAX as f64 {
                    return Err(Error::scene(
                        loc,
                        format!(
                            "the spectrum of '{name}' of {} is beyond the single-precision range (3.4e38) that penumbra renders in",
                            describe(self.obj)
                        ),
                    ));
                }
                Ok(Some(rgb))
            }
            Some((v, loc)) => Err(self.wrong_type(name, v, loc, "an rgb, float or spectrum")),
        }
    }

    pub(super) fn point(&mut self, name: &str, default: DVec3) -> Result<DVec3> {
        match self.take(name) {
            None => Ok(default),
            Some((Value::Point(p), _)) | Some((Value::Vector(p), _)) => Ok(*p),
            Some((v, loc)) => Err(self.wrong_type(name, v, loc, "a point")),
        }
    }

    pub(super) fn transform(&mut self, name: &str) -> Result<DMat4> {
        match self.take(name) {
            None => Ok(DMat4::IDENTITY),
            Some((Value::Transform(m), _)) => Ok(*m),
            Some((v, loc)) => Err(self.wrong_type(name, v, loc, "a transform")),
        }
    }

    /// Fails on the first property that was never read; else returns the warnings met while
    /// reading (see [`Ctx::finish`], which records them).
    pub(super) fn finish(self) -> Result<Vec<String>> {
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
        Ok(self.warnings)
    }
}

/// What every plugin reader needs besides its element: where relative file names are looked
/// up, and the warnings gathered on the way (Mitsuba logs them; penumbra prints them).
pub(super) struct Ctx<'a> {
    pub resolver: &'a FileResolver,
    pub warnings: RefCell<Vec<String>>,
    /// Shape groups met so far, keyed by the address of their (shared) XML object, so that
    /// every instance of one group refers to one description.
    pub groups: RefCell<Vec<(*const Object, ShapeGroupDesc)>>,
    /// Media met so far, keyed like `groups`.
    pub media: RefCell<Vec<(*const Object, MediumDesc)>>,
    /// See [`SceneDescription::spectral_only`].
    pub spectral_only: RefCell<Option<String>>,
}

impl Ctx<'_> {
    pub fn warn(&self, message: String) {
        self.warnings.borrow_mut().push(message);
    }

    /// [`Props::finish`], keeping the warnings.
    pub fn finish(&self, p: Props) -> Result<()> {
        let w = p.finish()?;
        self.warnings.borrow_mut().extend(w);
        Ok(())
    }
}

/// The required `filename` string parameter, looked up with Mitsuba's file resolver (the
/// `<path>`s, then the scene file's directory, then the working directory; see
/// [`FileResolver`]). A name that is found nowhere is placed in the scene's directory, and
/// the reader that opens it reports it missing there.
pub(super) fn file_parameter(cx: &Ctx, p: &mut Props, o: &Object) -> Result<PathBuf> {
    let (name, _) = p
        .string("filename")?
        .ok_or_else(|| Error::scene(&o.location, format!("{} needs a 'filename'", describe(o))))?;
    if name.is_empty() {
        return Err(Error::scene(
            &o.location,
            format!("empty 'filename' in {}", describe(o)),
        ));
    }
    Ok(cx.resolver.resolve_file(Path::new(name)))
}

pub(super) fn unsupported_plugin(o: &Object) -> Error {
    Error::scene(
        &o.location,
        format!(
            "unsupported plugin {}: penumbra does not implement it",
            describe(o)
        ),
    )
}

pub(super) fn unexpected_child(parent: &Object, child: &Object) -> Error {
    Error::scene(
        &child.location,
        format!(
            "{} cannot be nested in {}",
            describe(child),
            describe(parent)
        ),
    )
}

pub(super) fn positive(value: f64, what: &str, o: &Object) -> Result<f64> {
    if value > 0.0 && value.is_finite() {
        Ok(value)
    } else {
        Err(Error::scene(
            &o.location,
            format!("{what} of {} must be positive, got {value}", describe(o)),
        ))
    }
}

/// Converts a parsed scene file ([`super::xml::Document`]) into a typed description.
pub fn from_xml(doc: &Document) -> Result<SceneDescription> {
    let root = &doc.root;
    if root.tag != "scene" {
        return Err(Error::scene(
            &root.location,
            "the root element must be <scene>",
        ));
    }
    // The scene's own parameters in Mitsuba 3.9.1 steer its GPU and acceleration-structure
    // backends (thread reordering, compaction, Embree's robust mode, the kd-tree's build
    // costs): none changes an image. They are read and checked for their type.
    let mut p = Props::new(root);
    for name in [
        "allow_thread_reordering",
        "compact_acceleration_structures",
        "embree_use_robust_intersections",
        "kd_clip",
        "kd_retract_bad_splits",
    ] {
        p.boolean(name, false)?;
    }
    for name in [
        "kd_intersection_cost",
        "kd_traversal_cost",
        "kd_empty_space_bonus",
    ] {
        p.float(name, 0.0)?;
    }
    for name in [
        "kd_stop_prims",
        "kd_max_depth",
        "kd_min_max_bins",
        "kd_exact_primitive_threshold",
    ] {
        p.int(name, 0)?;
    }
    p.finish()?;
    let cx = Ctx {
        resolver: &doc.resolver,
        warnings: RefCell::new(doc.warnings.clone()),
        groups: RefCell::new(Vec::new()),
        media: RefCell::new(Vec::new()),
        spectral_only: RefCell::new(None),
    };
    let mut integrator = None;
    let mut sensors = Vec::new();
    let mut shapes = Vec::new();
    let mut emitters = Vec::new();
    let mut emitter_weights = Vec::new();
    let mut scene_area_emitters = Vec::new();
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
            // Several sensors are allowed, as in Mitsuba; the first is rendered unless another
            // is selected.
            "sensor" => sensors.push(sensor_desc(&cx, o)?),
            // A shape group is only seen through its instances (Mitsuba: "not visible on
            // its own"); check it now so that errors surface even when it is never used.
            "shape" if o.plugin == "shapegroup" => {
                shape_group(&cx, o)?;
            }
            "shape" => shapes.push(shape_desc(&cx, o)?),
            // An area emitter declared at the scene level (to be referenced by a shape, as in
            // Mitsuba's cbox-rgb.xml) emits only through the shapes that carry it.
            "emitter" if o.plugin == "area" => {
                area_emitter_desc(&cx, o)?;
                scene_area_emitters.push(Arc::clone(o));
            }
            "emitter" => {
                let (e, weight) = scene_emitter_desc(&cx, o)?;
                emitter_weights.push(weight);
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
                bsdf_desc(&cx, o)?;
            }
            // Declared for later <ref>s (shapes' interior/exterior, the sensor's medium),
            // checked now like BSDFs.
            "medium" => {
                medium_index(&cx, o)?;
            }
            // Declared for later <ref>s, checked now like BSDFs.
            "texture" => {
                texture::texture_desc(&cx, o, crate::spectrum::ColorRole::Reflectance)?;
            }
            _ => return Err(unexpected_child(root, o)),
        }
    }
    for e in &scene_area_emitters {
        let used = root.children.iter().any(|c| {
            c.object.tag == "shape" && c.object.children.iter().any(|s| Arc::ptr_eq(&s.object, e))
        });
        if !used {
            cx.warn(format!(
                "{}: {} is not attached to any shape and emits nothing",
                e.location,
                describe(e)
            ));
        }
    }
    let sensor = sensors.first().cloned().ok_or_else(|| {
        Error::scene(
            &root.location,
            "the scene has no <sensor>: there is nothing to render",
        )
    })?;
    // Mitsuba loads a scene without an integrator but `mi.render` then needs one passed in
    // (its test suite passes `path`); penumbra renders it with `path` and its defaults, and
    // the built scene says so (see [`NO_INTEGRATOR_WARNING`]).
    let integrator_missing = integrator.is_none();
    let (integrator, moment, timeout) = integrator.unwrap_or((
        IntegratorDesc::Path {
            max_depth: -1,
            rr_depth: 5,
            hide_emitters: false,
        },
        false,
        None,
    ));
    let shape_groups = cx.groups.into_inner().into_iter().map(|(_, g)| g).collect();
    let media = cx.media.into_inner().into_iter().map(|(_, m)| m).collect();
    Ok(SceneDescription {
        integrator,
        moment,
        timeout,
        integrator_missing,
        sensor,
        sensors,
        shapes,
        shape_groups,
        emitters,
        emitter_weights,
        media,
        warnings: cx.warnings.into_inner(),
        mode: crate::spectrum::Mode::Rgb,
        spectral_only: cx.spectral_only.into_inner(),
    })
}

pub(super) fn no_children(o: &Object) -> Result<()> {
    match o.children.first() {
        Some(c) => Err(unexpected_child(o, &c.object)),
        None => Ok(()),
    }
}
