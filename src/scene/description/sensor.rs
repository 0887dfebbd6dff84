//! Sensors (`perspective`, `thinlens`, `orthographic`), films (`hdrfilm`), reconstruction
//! filters and samplers.

use super::*;
use crate::camera::FovAxis;
use crate::sampler::SamplerKind;
use glam::DVec2;

#[derive(Clone, Debug, PartialEq)]
pub struct SensorDesc {
    /// Index into [`SceneDescription::media`] of the medium the sensor sits in.
    pub medium: Option<usize>,
    /// Field of view in degrees along `fov_axis` (perspective and thin lens; unused by the
    /// orthographic sensor). Without `fov`, Mitsuba's default `focal_length` of 50 mm on a
    /// 36 × 24 mm film gives the diagonal field of view.
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
    /// The perspective sensor's `principal_point_offset_x`/`_y`: the principal point's shift
    /// from the film's centre, in fractions of the film's width and height.
    pub principal_point: DVec2,
    /// Mitsuba's `orthographic` sensor: parallel rays along local +z from the local
    /// [-1, 1]² square (scaled by `to_world`).
    pub orthographic: bool,
}

#[derive(Clone, Debug, PartialEq)]
pub struct FilmDesc {
    /// The whole film's size (`width`, `height`).
    pub width: u32,
    pub height: u32,
    /// The crop window that is rendered and written (`crop_offset_x`/`_y`,
    /// `crop_width`/`_height`; by default the whole film), in pixels of the film.
    pub crop_offset: (u32, u32),
    pub crop_size: (u32, u32),
    pub rfilter: FilterDesc,
    /// `component_format`: the EXR's colour channels as float16 (`true`) or float32. Unlike
    /// Mitsuba (float16 by default), penumbra writes float32 unless the file asks for float16:
    /// its images are references and inputs to statistical comparisons.
    pub half: bool,
    /// `sample_border`: also sample the pixels within the filter's reach outside the crop
    /// window, so that the edge pixels receive samples from all around (Mitsuba's "high
    /// quality edges"; default false).
    pub sample_border: bool,
}

impl FilmDesc {
    /// Mitsuba's film when a sensor has none: hdrfilm, 768 × 576, gaussian filter.
    pub fn default_film() -> Self {
        FilmDesc {
            width: 768,
            height: 576,
            crop_offset: (0, 0),
            crop_size: (768, 576),
            rfilter: FilterDesc::Gaussian { stddev: 0.5 },
            half: false,
            sample_border: false,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FilterDesc {
    Box,
    Tent { radius: f64 },
    Gaussian { stddev: f64 },
}

#[derive(Clone, Debug, PartialEq)]
pub struct SamplerDesc {
    /// The plugin and its parameters.
    pub kind: SamplerKind,
    /// `sample_count` as written (the sampler rounds it when the scene is built).
    pub sample_count: u32,
    pub seed: u64,
}

/// Mitsuba's `focal_length` (a string "<x>mm", or a number of millimetres) as the diagonal
/// field of view of a 36 × 24 mm film, in degrees.
fn focal_length_fov(p: &mut Props, o: &Object) -> Result<f64> {
    let text = match p.take("focal_length") {
        None => "50mm".to_string(),
        Some((Value::String(s), _)) => s.clone(),
        Some((Value::Float(x), _)) => x.to_string(),
        Some((Value::Integer(i), _)) => i.to_string(),
        Some((v, loc)) => return Err(p.wrong_type("focal_length", v, loc, "a string")),
    };
    let number = text.strip_suffix("mm").unwrap_or(&text).trim();
    match number.parse::<f64>() {
        Ok(f) if f > 0.0 && f.is_finite() => {
            Ok(2.0 * ((36.0f64 * 36.0 + 24.0 * 24.0).sqrt() / (2.0 * f)).atan().to_degrees())
        }
        _ => Err(Error::scene(
            &o.location,
            format!(
                "could not parse the focal length '{text}' of {} (must be of the form <x>mm with x > 0)",
                describe(o)
            ),
        )),
    }
}

/// Mitsuba's field of view of a projective sensor (and of the projector emitter): `fov`
/// along `fov_axis` (x, y, diagonal, smaller, larger; default x), or a `focal_length`
/// (default 50mm, as a diagonal field of view), not both. Degrees.
pub(super) fn fov_desc(p: &mut Props, o: &Object) -> Result<(f64, FovAxis)> {
    let has = |n: &str| o.properties.iter().any(|q| q.name == n);
    if has("fov") {
        if has("focal_length") {
            return Err(Error::scene(
                &o.location,
                format!(
                    "{}: give either a focal length ('focal_length') or a field of view ('fov')",
                    describe(o)
                ),
            ));
        }
        let fov = p.float("fov", f64::NAN)?;
        let fov_axis = match p.string("fov_axis")? {
            None => FovAxis::X,
            // Mitsuba lower-cases the axis name.
            Some((s, loc)) => match s.to_ascii_lowercase().as_str() {
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
        Ok((fov, fov_axis))
    } else {
        // Mitsuba ignores fov_axis with a focal length; accept it likewise.
        let _ = p.string("fov_axis")?;
        Ok((focal_length_fov(p, o)?, FovAxis::Diagonal))
    }
}

pub(super) fn sensor_desc(cx: &Ctx, o: &Arc<Object>) -> Result<SensorDesc> {
    if !matches!(
        o.plugin.as_str(),
        "perspective" | "thinlens" | "orthographic"
    ) {
        return Err(unsupported_plugin(o));
    }
    let orthographic = o.plugin == "orthographic";
    let mut p = Props::new(o);
    let aperture_radius = if o.plugin == "thinlens" {
        Some(p.float("aperture_radius", f64::NAN)?)
    } else {
        None
    };
    let (fov, fov_axis) = if orthographic {
        (90.0, FovAxis::X)
    } else {
        fov_desc(&mut p, o)?
    };
    let near_clip = p.float("near_clip", 0.01)?;
    let far_clip = p.float("far_clip", 1e4)?;
    // Mitsuba's projective cameras accept focus_distance (default: far_clip); a pinhole or
    // an orthographic camera has no use for it.
    let focus_distance = p.float("focus_distance", far_clip)?;
    let to_world = p.transform("to_world")?;
    let principal_point = if o.plugin == "perspective" {
        DVec2::new(
            p.float("principal_point_offset_x", 0.0)?,
            p.float("principal_point_offset_y", 0.0)?,
        )
    } else {
        DVec2::ZERO
    };
    // Mitsuba's sensors open and close a shutter for motion blur; nothing in a penumbra scene
    // moves, so the times only have to be in order, as Mitsuba requires.
    let shutter_open = p.float("shutter_open", 0.0)?;
    let shutter_close = p.float("shutter_close", 0.0)?;
    if shutter_close
        .partial_cmp(&shutter_open)
        .is_none_or(|o| o.is_lt())
    {
        return Err(Error::scene(
            &o.location,
            format!("shutter_open ({shutter_open}) must not be later than shutter_close ({shutter_close})"),
        ));
    }
    if let Some((_, loc)) = p.take("srf") {
        return Err(Error::scene(
            loc,
            format!("'srf' of {} (a spectral response function) needs spectral rendering, which penumbra does not do; Mitsuba refuses it in RGB variants too", describe(o)),
        ));
    }
    p.finish()?;
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
    let mut medium = None;
    for Child { object: c, .. } in &o.children {
        match c.tag.as_str() {
            "film" if film.is_none() => film = Some(film_desc(cx, c)?),
            "sampler" if sampler.is_none() => sampler = Some(sampler_desc(c)?),
            "medium" if medium.is_none() => medium = Some(medium_index(cx, c)?),
            _ => return Err(unexpected_child(o, c)),
        }
    }
    Ok(SensorDesc {
        medium,
        fov,
        fov_axis,
        near_clip,
        far_clip,
        to_world,
        film: film.unwrap_or_else(FilmDesc::default_film),
        sampler: sampler.unwrap_or(SamplerDesc {
            kind: SamplerKind::Independent,
            sample_count: 4,
            seed: 0,
        }),
        location: o.location.clone(),
        thin_lens,
        principal_point,
        orthographic,
    })
}

pub(super) fn film_desc(cx: &Ctx, o: &Object) -> Result<FilmDesc> {
    if o.plugin != "hdrfilm" {
        return Err(unsupported_plugin(o));
    }
    let mut p = Props::new(o);
    let width = p.int("width", 768)?;
    let height = p.int("height", 576)?;
    let crop_width = p.int("crop_width", width)?;
    let crop_height = p.int("crop_height", height)?;
    let crop_x = p.int("crop_offset_x", 0)?;
    let crop_y = p.int("crop_offset_y", 0)?;
    let sample_border = p.boolean("sample_border", false)?;
    // Mitsuba lower-cases the three format names.
    let lower = |v: Option<(&str, &Location)>| v.map(|(s, l)| (s.to_ascii_lowercase(), l.clone()));
    let file_format = lower(p.string("file_format")?);
    let pixel_format = lower(p.string("pixel_format")?);
    let component_format = lower(p.string("component_format")?);
    // Mitsuba 3 has no banner ("no banner in Mitsuba 3") and ignores it, as penumbra does.
    let _ = p.take("banner");
    if p.take("compensate").is_some() {
        cx.warn(format!(
            "{}: {}'s 'compensate' is ignored (Mitsuba 3 removed it; penumbra's sums are exact anyway)",
            o.location,
            describe(o)
        ));
    }
    p.finish()?;
    if let Some((f, loc)) = &file_format {
        match f.as_str() {
            "openexr" | "exr" => {}
            "rgbe" | "pfm" => cx.warn(format!(
                "{loc}: file_format '{f}' is not written by penumbra: the image is written as OpenEXR (the output's name is -o's)"
            )),
            _ => {
                return Err(Error::scene(
                    loc,
                    format!("file_format must be openexr, pfm or rgbe, not '{f}' (as in Mitsuba)"),
                ))
            }
        }
    }
    if let Some((f, loc)) = &pixel_format {
        match f.as_str() {
            "rgb" => {}
            "rgba" | "luminance" | "luminance_alpha" | "xyz" | "xyza" => cx.warn(format!(
                "{loc}: pixel_format '{f}' is written as rgb: penumbra writes R, G, B channels only"
            )),
            _ => {
                return Err(Error::scene(
                    loc,
                    format!(
                        "pixel_format must be luminance, luminance_alpha, rgb, rgba, xyz or xyza, not '{f}' (as in Mitsuba)"
                    ),
                ))
            }
        }
    }
    let half = match &component_format {
        None => false,
        Some((f, loc)) => match f.as_str() {
            "float16" => true,
            "float32" => false,
            "uint32" => {
                cx.warn(format!(
                    "{loc}: component_format 'uint32' is written as float32 (penumbra writes float16 or float32)"
                ));
                false
            }
            _ => {
                return Err(Error::scene(
                    loc,
                    format!("component_format must be float16, float32 or uint32, not '{f}' (as in Mitsuba)"),
                ))
            }
        },
    };
    for (name, v) in [("width", width), ("height", height)] {
        if v <= 0 || v > MAX_RESOLUTION as i64 {
            return Err(Error::scene(
                &o.location,
                format!("film {name} must be between 1 and {MAX_RESOLUTION}, got {v}"),
            ));
        }
    }
    // Mitsuba reads the crop parameters as unsigned integers and refuses a window that
    // leaves the film; an empty window renders nothing, and penumbra refuses it.
    let inside = crop_x >= 0
        && crop_y >= 0
        && crop_width > 0
        && crop_height > 0
        && crop_x + crop_width <= width
        && crop_y + crop_height <= height;
    if !inside {
        return Err(Error::scene(
            &o.location,
            format!(
                "invalid crop window: crop_offset ({crop_x}, {crop_y}) + crop size ({crop_width}, {crop_height}) must lie within the film's {width}x{height} pixels, and the crop must not be empty"
            ),
        ));
    }
    // What is rendered and held in memory is the crop window.
    let limits = crate::limits::current()?;
    if crop_width as u64 * crop_height as u64 > limits.render_pixels {
        return Err(Error::scene(
            &o.location,
            format!(
                "film of {crop_width}x{crop_height} pixels exceeds {}",
                limits.exceeded(crate::limits::Limit::RenderPixels)
            ),
        ));
    }
    let mut rfilter = None;
    for Child { object: c, .. } in &o.children {
        match c.tag.as_str() {
            "rfilter" if rfilter.is_none() => rfilter = Some(rfilter_desc(c)?),
            "rfilter" => {
                return Err(Error::scene(
                    &c.location,
                    "a film can only have one reconstruction filter (as in Mitsuba)",
                ))
            }
            _ => return Err(unexpected_child(o, c)),
        }
    }
    // Mitsuba's default reconstruction filter.
    let rfilter = rfilter.unwrap_or(FilterDesc::Gaussian { stddev: 0.5 });
    Ok(FilmDesc {
        width: width as u32,
        height: height as u32,
        crop_offset: (crop_x as u32, crop_y as u32),
        crop_size: (crop_width as u32, crop_height as u32),
        rfilter,
        half,
        sample_border,
    })
}

pub(super) fn rfilter_desc(c: &Object) -> Result<FilterDesc> {
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

pub(super) fn sampler_desc(o: &Object) -> Result<SamplerDesc> {
    let Some(mut kind) = SamplerKind::from_name(&o.plugin) else {
        return Err(unsupported_plugin(o));
    };
    no_children(o)?;
    let mut p = Props::new(o);
    let sample_count = p.int("sample_count", 4)?;
    let seed = p.int("seed", 0)?;
    match &mut kind {
        SamplerKind::Stratified { jitter } | SamplerKind::Multijitter { jitter } => {
            *jitter = p.boolean("jitter", true)?;
        }
        SamplerKind::Orthogonal { strength, jitter } => {
            *jitter = p.boolean("jitter", true)?;
            let s = p.int("strength", 2)?;
            // r^strength rows must fit the 32-bit sample index for r up to 2^16 / strength
            if !(2..=8).contains(&s) {
                return Err(Error::scene(
                    &o.location,
                    format!("strength must be between 2 and 8, got {s}"),
                ));
            }
            *strength = s as u32;
        }
        _ => {}
    }
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
        kind,
        sample_count: sample_count as u32,
        seed: seed as u64,
    })
}
