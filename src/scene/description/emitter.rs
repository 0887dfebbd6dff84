//! Emitters: `area` (on shapes) and the scene-level ones.

use super::sensor::fov_desc;
use super::texture::{constant_color, texture_or, texture_param, Children};
use super::*;
use crate::camera::FovAxis;
use crate::spectrum::ColorRole;

#[derive(Clone, Debug, PartialEq)]
pub enum EmitterDesc {
    /// `radiance` may be a texture (looked up at the shape's uv).
    Area {
        radiance: TextureDesc,
    },
    Point {
        position: DVec3,
        intensity: ColorDesc,
    },
    Spot {
        to_world: DMat4,
        intensity: ColorDesc,
        /// Degrees.
        cutoff_angle: f64,
        beam_width: f64,
        /// `texture`: a spatially varying texture over the cone, uv from the direction.
        texture: Option<TextureDesc>,
    },
    /// Mitsuba's `projector`: a pinhole projecting the `irradiance` texture (the image
    /// irradiance on a plane at distance 1) along local +z.
    Projector {
        to_world: DMat4,
        irradiance: TextureDesc,
        scale: f64,
        /// Degrees along `fov_axis` of the irradiance texture's aspect ratio.
        fov: f64,
        fov_axis: FovAxis,
    },
    Directional {
        /// Unit direction in which the light travels (world).
        direction: DVec3,
        irradiance: ColorDesc,
    },
    Constant {
        radiance: ColorDesc,
    },
    EnvMap {
        filename: PathBuf,
        scale: f64,
        to_world: DMat4,
        location: Location,
    },
}

impl EmitterDesc {
    /// The image files the emitter reads.
    pub fn files<'a>(&'a self, out: &mut Vec<&'a Path>) {
        match self {
            EmitterDesc::EnvMap { filename, .. } => out.push(filename),
            EmitterDesc::Area { radiance } => radiance.files(out),
            EmitterDesc::Spot {
                texture: Some(t), ..
            } => t.files(out),
            EmitterDesc::Projector { irradiance, .. } => irradiance.files(out),
            _ => {}
        }
    }
}

/// An `area` emitter and its sampling weight.
pub(super) fn area_emitter_desc(cx: &Ctx, o: &Object) -> Result<(EmitterDesc, f64)> {
    if o.plugin != "area" {
        return Err(unsupported_plugin(o));
    }
    let mut p = Props::new(o);
    let mut ch = Children::new(o);
    let radiance = texture_param(cx, &mut p, &mut ch, "radiance", ColorRole::Emission)?;
    let weight = common_emitter_params(cx, o, &mut p, &mut ch)?;
    cx.finish(p)?;
    ch.finish()?;
    let radiance = radiance
        .ok_or_else(|| Error::scene(&o.location, format!("{} needs a 'radiance'", describe(o))))?;
    if let Some(c) = radiance.constant_rgb() {
        if c.min_element() < 0.0 {
            return Err(Error::scene(&o.location, "radiance must not be negative"));
        }
    }
    Ok((EmitterDesc::Area { radiance }, weight))
}

/// What every Mitsuba emitter reads (its `Emitter` and `Endpoint` base classes): the
/// `sampling_weight` (relative probability of choosing the emitter for emitter sampling,
/// default 1), and a nested `<medium>` the emitter sits in, which penumbra's integrators do
/// not use (as Mitsuba's path tracers, which connect from the shading point; penumbra's
/// light tracers render no media) but checks.
fn common_emitter_params(cx: &Ctx, o: &Object, p: &mut Props, ch: &mut Children) -> Result<f64> {
    let weight = p.float("sampling_weight", 1.0)?;
    if !(weight >= 0.0 && weight.is_finite()) {
        return Err(Error::scene(
            &o.location,
            format!(
                "sampling_weight of {} must be finite and >= 0, got {weight}",
                describe(o)
            ),
        ));
    }
    for m in ch.with_tag("medium") {
        medium_index(cx, m)?;
    }
    Ok(weight)
}

/// A scene-level emitter and its sampling weight.
pub(super) fn scene_emitter_desc(cx: &Ctx, o: &Object) -> Result<(EmitterDesc, f64)> {
    let mut p = Props::new(o);
    let mut ch = Children::new(o);
    let non_negative = |c: ColorDesc, what: &str| -> Result<ColorDesc> {
        if c.rgb.min_element() < 0.0 || !c.rgb.is_finite() {
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
            let intensity = constant_color(cx, &mut p, &mut ch, "intensity", ColorRole::Emission)?
                .unwrap_or_else(|| ColorDesc::default_for(1.0, ColorRole::Emission));
            EmitterDesc::Point {
                position,
                intensity: non_negative(intensity, "intensity")?,
            }
        }
        "spot" => {
            let to_world = p.transform("to_world")?;
            let intensity = constant_color(cx, &mut p, &mut ch, "intensity", ColorRole::Emission)?
                .unwrap_or_else(|| ColorDesc::default_for(1.0, ColorRole::Emission));
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
            // Mitsuba: `texture` must vary over the cone (a constant belongs in `intensity`).
            let texture = texture_param(cx, &mut p, &mut ch, "texture", ColorRole::Reflectance)?;
            if texture.as_ref().is_some_and(|t| t.constant_rgb().is_some()) {
                return Err(Error::scene(
                    &o.location,
                    format!(
                        "the 'texture' of {} must be spatially varying (e.g. a bitmap)",
                        describe(o)
                    ),
                ));
            }
            EmitterDesc::Spot {
                to_world,
                intensity: non_negative(intensity, "intensity")?,
                cutoff_angle,
                beam_width,
                texture,
            }
        }
        "projector" => {
            let to_world = p.transform("to_world")?;
            let irradiance = texture_or(
                cx,
                &mut p,
                &mut ch,
                "irradiance",
                ColorRole::Emission,
                TextureDesc::default_for(1.0, ColorRole::Emission),
            )?;
            if let Some(c) = irradiance.constant_rgb() {
                if c.min_element() < 0.0 || !c.is_finite() {
                    return Err(Error::scene(
                        &o.location,
                        format!(
                            "irradiance of {} must be finite and not negative",
                            describe(o)
                        ),
                    ));
                }
            }
            let scale = p.float("scale", 1.0)?;
            if !(scale >= 0.0 && scale.is_finite()) {
                return Err(Error::scene(
                    &o.location,
                    format!(
                        "scale of {} must be finite and >= 0, got {scale}",
                        describe(o)
                    ),
                ));
            }
            let (fov, fov_axis) = fov_desc(&mut p, o)?;
            if !(fov > 0.0 && fov < 180.0) {
                return Err(Error::scene(
                    &o.location,
                    format!(
                        "the field of view of {} must lie in (0, 180) degrees, got {fov}",
                        describe(o)
                    ),
                ));
            }
            EmitterDesc::Projector {
                to_world,
                irradiance,
                scale,
                fov,
                fov_axis,
            }
        }
        "directional" => {
            let to_world = p.transform("to_world")?;
            let direction = p.point("direction", to_world.transform_vector3(DVec3::Z))?;
            let irradiance =
                constant_color(cx, &mut p, &mut ch, "irradiance", ColorRole::Emission)?
                    .unwrap_or_else(|| ColorDesc::default_for(1.0, ColorRole::Emission));
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
            // Read by Mitsuba's Endpoint base class; a uniform background has no use for it.
            p.transform("to_world")?;
            let radiance = constant_color(cx, &mut p, &mut ch, "radiance", ColorRole::Emission)?
                .unwrap_or_else(|| ColorDesc::default_for(1.0, ColorRole::Emission));
            EmitterDesc::Constant {
                radiance: non_negative(radiance, "radiance")?,
            }
        }
        "envmap" => {
            let filename = file_parameter(cx, &mut p, o)?;
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
            // Mitsuba's `mis_compensation` samples the map in proportion to its texels minus
            // their mean (Karlík et al. 2019), which changes the variance, not the image.
            // penumbra samples in proportion to the texels and says so.
            if p.boolean("mis_compensation", false)? {
                cx.warn(format!(
                    "{}: mis_compensation of {} is not implemented: the map is sampled in proportion to its texels (the same image, another variance)",
                    o.location,
                    describe(o)
                ));
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
    let weight = common_emitter_params(cx, o, &mut p, &mut ch)?;
    cx.finish(p)?;
    ch.finish()?;
    Ok((e, weight))
}
