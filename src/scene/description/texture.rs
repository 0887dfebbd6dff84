//! Textures (`bitmap`, `checkerboard`, `mesh_attribute`, `rawconstant`, `srgb`, `uniform`,
//! `volume`)
//! and texture-valued parameters: a parameter Mitsuba reads with `get_texture` can be a
//! colour, a float, a `<spectrum>`, or a nested or referenced `<texture>`.

use super::*;
use crate::spectrum::ColorRole;
use crate::texture::bitmap::{to_uv_from_4x4, Filter, Format, Wrap};
use glam::DMat3;

#[derive(Clone, Debug, PartialEq)]
pub enum TextureDesc {
    /// The same value everywhere: `rgb` for colour lookups, `scalar` for one-value lookups
    /// (a float's value, a colour's mean, as Mitsuba's `srgb` texture).
    Constant {
        rgb: DVec3,
        scalar: f64,
        /// What Mitsuba's spectral variants make of the same value.
        spectral: SpectralDesc,
    },
    /// Mitsuba's `rawconstant`: the value as given, not converted (normal maps).
    Raw(DVec3),
    Bitmap(BitmapDesc),
    Checkerboard {
        color0: Box<TextureDesc>,
        color1: Box<TextureDesc>,
        to_uv: DMat3,
    },
    MeshAttribute {
        name: String,
        scale: f64,
    },
    /// Mitsuba's `volume` texture: a volume looked up at the shading point.
    Volume(VolumeDesc),
}

/// Mitsuba's `bitmap` texture.
#[derive(Clone, Debug, PartialEq)]
pub struct BitmapDesc {
    pub filename: PathBuf,
    /// `raw`: keep 8/16-bit values as stored (no sRGB decoding).
    pub raw: bool,
    /// `filter_type`.
    pub filter: Filter,
    /// `wrap_mode`.
    pub wrap: Wrap,
    /// `format`: how the texels are stored (which decides where sRGB is decoded).
    pub format: Format,
    /// `to_uv` as a 2D affine map (Mitsuba takes the upper-left 2x2 block and the
    /// translation of the 4x4 transform).
    pub to_uv: DMat3,
    pub location: Location,
}

impl TextureDesc {
    /// A constant reflectance colour (its one-value lookup is the mean, as Mitsuba's `srgb`
    /// texture; a grey's is its value exactly, so that `rgb(splat(v)) == value(v)` in RGB).
    pub fn rgb(c: DVec3) -> Self {
        TextureDesc::color(ColorDesc {
            rgb: c,
            spectral: SpectralDesc::Srgb(c),
        })
    }

    /// A constant colour parameter, in both its forms.
    pub fn color(c: ColorDesc) -> Self {
        let scalar = if c.rgb.x == c.rgb.y && c.rgb.y == c.rgb.z {
            c.rgb.x
        } else {
            (c.rgb.x + c.rgb.y + c.rgb.z) / 3.0
        };
        TextureDesc::Constant {
            rgb: c.rgb,
            scalar,
            spectral: c.spectral,
        }
    }

    /// A constant value (grey colour, that value for one-value lookups; a flat spectrum).
    pub fn value(v: f64) -> Self {
        TextureDesc::number(v, ColorRole::Reflectance)
    }

    /// A number given for a parameter read in `role` (an emitter's is a D65 spectrum in
    /// spectral mode, see [`SpectralDesc::number`]).
    pub fn number(v: f64, role: ColorRole) -> Self {
        TextureDesc::Constant {
            rgb: DVec3::splat(v),
            scalar: v,
            spectral: SpectralDesc::number(v, role),
        }
    }

    /// The value of a parameter read in `role` that was not given and defaults to `d`.
    pub fn default_for(d: f64, role: ColorRole) -> Self {
        TextureDesc::Constant {
            rgb: DVec3::splat(d),
            scalar: d,
            spectral: SpectralDesc::default_for(d, role),
        }
    }

    /// The colour, if the texture is constant.
    pub fn constant_rgb(&self) -> Option<DVec3> {
        match self {
            TextureDesc::Constant { rgb, .. } => Some(*rgb),
            TextureDesc::Raw(v) => Some(*v),
            _ => None,
        }
    }

    /// The image files the texture reads.
    pub fn files<'a>(&'a self, out: &mut Vec<&'a Path>) {
        match self {
            TextureDesc::Bitmap(b) => out.push(&b.filename),
            TextureDesc::Checkerboard { color0, color1, .. } => {
                color0.files(out);
                color1.files(out);
            }
            TextureDesc::Volume(VolumeDesc::Grid { filename, .. }) => out.push(filename),
            _ => {}
        }
    }

    /// The one-value lookup, if the texture is constant.
    pub fn constant_scalar(&self) -> Option<f64> {
        match self {
            TextureDesc::Constant { scalar, .. } => Some(*scalar),
            TextureDesc::Raw(v) => Some(v.x),
            _ => None,
        }
    }
}

/// The children of an object (nested or referenced objects), consumed by name or by tag;
/// [`Children::finish`] reports the first one nobody asked for.
pub(super) struct Children<'a> {
    obj: &'a Object,
    used: Vec<bool>,
}

impl<'a> Children<'a> {
    pub fn new(obj: &'a Object) -> Self {
        Children {
            obj,
            used: vec![false; obj.children.len()],
        }
    }

    /// The child named `name` (`<texture name="..">` or `<ref name=".." id=".."/>`).
    pub fn named(&mut self, name: &str) -> Option<&'a Arc<Object>> {
        let i = self
            .obj
            .children
            .iter()
            .position(|c| c.name.as_deref() == Some(name))?;
        self.used[i] = true;
        Some(&self.obj.children[i].object)
    }

    /// Whether a child is named `name` (without taking it).
    pub fn has(&self, name: &str) -> bool {
        self.obj
            .children
            .iter()
            .any(|c| c.name.as_deref() == Some(name))
    }

    /// Every child with tag `tag` not yet taken, in document order.
    pub fn with_tag(&mut self, tag: &str) -> Vec<&'a Arc<Object>> {
        let mut v = Vec::new();
        for (i, c) in self.obj.children.iter().enumerate() {
            if !self.used[i] && c.object.tag == tag {
                self.used[i] = true;
                v.push(&c.object);
            }
        }
        v
    }

    /// Fails on the first child that was not taken.
    pub fn finish(self) -> Result<()> {
        for (c, used) in self.obj.children.iter().zip(&self.used) {
            if !used {
                return Err(unexpected_child(self.obj, &c.object));
            }
        }
        Ok(())
    }
}

/// A parameter Mitsuba reads as a texture: a child texture named `name`, else a colour,
/// float or spectrum property (converted for `role`); `None` if neither is given.
pub(super) fn texture_param(
    cx: &Ctx,
    p: &mut Props,
    ch: &mut Children,
    name: &str,
    role: ColorRole,
) -> Result<Option<TextureDesc>> {
    if let Some(t) = ch.named(name) {
        return texture_desc(cx, t, role).map(Some);
    }
    match p.take(name) {
        None => Ok(None),
        Some((Value::Float(x), _)) => Ok(Some(TextureDesc::number(*x, role))),
        Some((Value::Integer(i), _)) => Ok(Some(TextureDesc::number(*i as f64, role))),
        Some(_) => {
            // Put it back for `color`, which knows every colour form and its errors.
            p.untake(name);
            Ok(p.color(name, role)?.map(TextureDesc::color))
        }
    }
}

/// A parameter Mitsuba reads as a texture that penumbra keeps constant (the intensity of
/// point and spot lights, the radiance of the constant emitter, a directional's irradiance):
/// a colour, float or spectrum property, or a nested constant spectrum plugin (`<spectrum
/// type="blackbody">`, `uniform`, `srgb`); a spatially varying texture is refused.
pub(super) fn constant_color(
    cx: &Ctx,
    p: &mut Props,
    ch: &mut Children,
    name: &str,
    role: ColorRole,
) -> Result<Option<ColorDesc>> {
    if let Some(t) = ch.named(name) {
        return match texture_desc(cx, t, role)? {
            TextureDesc::Constant { rgb, spectral, .. } => Ok(Some(ColorDesc { rgb, spectral })),
            _ => Err(Error::scene(
                &t.location,
                format!(
                    "'{name}' must be a constant colour or spectrum here, not {}",
                    describe(t)
                ),
            )),
        };
    }
    p.color(name, role)
}

/// Like [`texture_param`] with a default, for parameters that always have a value.
pub(super) fn texture_or(
    cx: &Ctx,
    p: &mut Props,
    ch: &mut Children,
    name: &str,
    role: ColorRole,
    default: TextureDesc,
) -> Result<TextureDesc> {
    Ok(texture_param(cx, p, ch, name, role)?.unwrap_or(default))
}

/// Mitsuba's `to_uv`: the 4x4 transform's upper-left 2x2 block and translation as a 2D
/// affine map.
fn to_uv(p: &mut Props) -> Result<DMat3> {
    Ok(to_uv_from_4x4(&p.transform("to_uv")?))
}

/// A string option read with a plugin's own parser (`from_name`), its error located.
fn option<T: Default>(
    p: &mut Props,
    o: &Object,
    name: &str,
    parse: fn(&str) -> std::result::Result<T, String>,
) -> Result<T> {
    match p.string(name)? {
        None => Ok(T::default()),
        Some((s, loc)) => parse(s).map_err(|e| Error::scene(loc, format!("{e} ({})", describe(o)))),
    }
}

/// A `<texture>` object (nested, referenced, or declared at the scene level).
pub(super) fn texture_desc(cx: &Ctx, o: &Object, role: ColorRole) -> Result<TextureDesc> {
    // `<spectrum type="...">` is a spectrum plugin: Mitsuba 3 makes it a texture too.
    if o.tag != "texture" && o.tag != "spectrum" {
        return Err(Error::scene(
            &o.location,
            format!("{} is not a texture", describe(o)),
        ));
    }
    let mut p = Props::new(o);
    let mut ch = Children::new(o);
    let t = match o.plugin.as_str() {
        "bitmap" => {
            let filename = file_parameter(cx, &mut p, o)?;
            let raw = p.boolean("raw", false)?;
            let filter = option(&mut p, o, "filter_type", Filter::from_name)?;
            let wrap = option(&mut p, o, "wrap_mode", Wrap::from_name)?;
            let format = option(&mut p, o, "format", Format::from_name)?;
            // Mitsuba's GPU texture hardware switch: nothing to do on a CPU.
            let _ = p.boolean("accel", true)?;
            TextureDesc::Bitmap(BitmapDesc {
                filename,
                raw,
                filter,
                wrap,
                format,
                to_uv: to_uv(&mut p)?,
                location: o.location.clone(),
            })
        }
        "checkerboard" => {
            let color0 = texture_or(cx, &mut p, &mut ch, "color0", role, TextureDesc::value(0.4))?;
            let color1 = texture_or(cx, &mut p, &mut ch, "color1", role, TextureDesc::value(0.2))?;
            TextureDesc::Checkerboard {
                color0: Box::new(color0),
                color1: Box::new(color1),
                to_uv: to_uv(&mut p)?,
            }
        }
        "mesh_attribute" => {
            let (name, loc) = p.string("name")?.ok_or_else(|| {
                Error::scene(&o.location, format!("{} needs a 'name'", describe(o)))
            })?;
            if !(name.starts_with("vertex_") || name.starts_with("face_")) {
                return Err(Error::scene(
                    loc,
                    format!("invalid mesh attribute name \"{name}\": it must start with \"vertex_\" or \"face_\""),
                ));
            }
            let scale = p.float("scale", 1.0)?;
            TextureDesc::MeshAttribute {
                name: name.to_string(),
                scale,
            }
        }
        "rawconstant" => match p.take("value") {
            Some((Value::Float(x), _)) => TextureDesc::Raw(DVec3::splat(*x)),
            Some((Value::Integer(i), _)) => TextureDesc::Raw(DVec3::splat(*i as f64)),
            Some((Value::Vector(v) | Value::Point(v) | Value::Rgb(v), _)) => TextureDesc::Raw(*v),
            Some((v, loc)) => return Err(p.wrong_type("value", v, loc, "a float or a vector")),
            None => {
                return Err(Error::scene(
                    &o.location,
                    format!("{} needs a 'value'", describe(o)),
                ))
            }
        },
        "srgb" => {
            // `unbounded` lifts Mitsuba's [0, 1] check of an <rgb> reflectance.
            let unbounded = p.boolean("unbounded", false)?;
            let role = if unbounded && role == ColorRole::Reflectance {
                ColorRole::Unbounded
            } else {
                role
            };
            let c = p.color("color", role)?.ok_or_else(|| {
                Error::scene(&o.location, format!("{} needs a 'color'", describe(o)))
            })?;
            // An explicit `srgb` is upsampled as a reflectance in spectral mode even where an
            // emitter reads it (no D65), as Mitsuba's plugin is.
            let spectral = SpectralDesc::Srgb(c.rgb);
            TextureDesc::color(ColorDesc { spectral, ..c })
        }
        "uniform" => {
            // The wavelength range matters only to spectral variants (outside it the
            // spectrum is 0); in RGB the value is the value.
            let lo = p.float("wavelength_min", 360.0)?;
            let hi = p.float("wavelength_max", 830.0)?;
            if lo.partial_cmp(&hi).is_none_or(|o| o.is_ge()) {
                return Err(Error::scene(
                    &o.location,
                    format!(
                        "wavelength_min ({lo}) of {} must be below wavelength_max ({hi})",
                        describe(o)
                    ),
                ));
            }
            let value = p.float("value", 1.0)?;
            TextureDesc::Constant {
                rgb: DVec3::splat(value),
                scalar: value,
                spectral: SpectralDesc::Uniform { value, lo, hi },
            }
        }
        "blackbody" => {
            // Spectral variants only: Mitsuba's RGB variants refuse to evaluate it, and so
            // does penumbra's RGB mode (`SceneDescription::spectral_only`).
            let temperature = match p.take("temperature") {
                Some((Value::Float(t), _)) if t.is_finite() && *t > 0.0 => *t,
                Some((Value::Integer(t), _)) if *t > 0 => *t as f64,
                Some((v, loc)) => {
                    return Err(p.wrong_type("temperature", v, loc, "a temperature > 0 (kelvins)"))
                }
                None => {
                    return Err(Error::scene(
                        &o.location,
                        format!("{} needs a 'temperature' (kelvins)", describe(o)),
                    ))
                }
            };
            let lo = p.float("wavelength_min", 360.0)?;
            let hi = p.float("wavelength_max", 830.0)?;
            if lo.partial_cmp(&hi).is_none_or(|o| o.is_ge()) || lo <= 0.0 {
                return Err(Error::scene(
                    &o.location,
                    format!(
                        "wavelength_min ({lo}) of {} must be positive and below wavelength_max ({hi})",
                        describe(o)
                    ),
                ));
            }
            cx.spectral_only
                .borrow_mut()
                .get_or_insert_with(|| format!("the blackbody spectrum at {}", o.location));
            TextureDesc::Constant {
                rgb: DVec3::ZERO,
                scalar: 0.0,
                spectral: SpectralDesc::Blackbody {
                    temperature,
                    lo,
                    hi,
                },
            }
        }
        "volume" => {
            // Mitsuba reads `volume` as an object only (a <float> or <rgb> is refused there).
            if let Some((v, loc)) = p.take("volume") {
                return Err(p.wrong_type("volume", v, loc, "a <volume>"));
            }
            let v = ch.named("volume").ok_or_else(|| {
                Error::scene(
                    &o.location,
                    format!("{} needs a <volume name=\"volume\">", describe(o)),
                )
            })?;
            TextureDesc::Volume(volume_desc(cx, v)?)
        }
        _ => return Err(unsupported_plugin(o)),
    };
    cx.finish(p)?;
    ch.finish()?;
    Ok(t)
}
