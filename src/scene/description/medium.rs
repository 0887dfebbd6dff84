//! Media: `homogeneous` and `heterogeneous`, their `phase` functions (`isotropic`, `hg`) and
//! volumes (`constvolume`, `gridvolume`). A medium is parsed once however many shapes or
//! sensors refer to it, and referred to by index into [`SceneDescription::media`].

use super::*;

/// A `volume` parameter of a medium, or a plain value (Mitsuba's `get_volume` wraps one in a
/// `constvolume` with the identity transform).
#[derive(Clone, Debug, PartialEq)]
pub enum VolumeDesc {
    Constant {
        value: ColorDesc,
        to_world: DMat4,
    },
    Grid {
        filename: PathBuf,
        to_world: DMat4,
        use_grid_bbox: bool,
        /// `filter_type` trilinear (else nearest).
        trilinear: bool,
        /// `wrap_mode`: "clamp", "repeat" or "mirror".
        wrap: String,
        /// `max_value`: replaces the grid's largest value where the largest is used (the
        /// majorant of a heterogeneous medium), as in Mitsuba; a value below the grid's
        /// largest biases the medium, in Mitsuba too.
        max_value: Option<f64>,
        /// `raw`: three channels kept as numbers in spectral mode (which then refuses to
        /// look them up as spectra, as Mitsuba does).
        raw: bool,
    },
}

#[derive(Clone, Debug, PartialEq)]
pub enum PhaseDesc {
    Isotropic,
    HenyeyGreenstein { g: f64 },
}

#[derive(Clone, Debug, PartialEq)]
pub struct MediumDesc {
    /// `homogeneous` (else `heterogeneous`).
    pub homogeneous: bool,
    pub sigma_t: VolumeDesc,
    pub albedo: VolumeDesc,
    pub scale: f64,
    pub sample_emitters: bool,
    pub phase: PhaseDesc,
    pub location: Location,
}

/// The index of the medium declared by `o` in `cx.media`, parsing it on first use.
pub(super) fn medium_index(cx: &Ctx, o: &Arc<Object>) -> Result<usize> {
    if o.tag != "medium" {
        return Err(Error::scene(
            &o.location,
            format!("{} is not a <medium>", describe(o)),
        ));
    }
    let key = Arc::as_ptr(o);
    if let Some(i) = cx.media.borrow().iter().position(|(k, _)| *k == key) {
        return Ok(i);
    }
    let m = medium_desc(cx, o)?;
    let mut media = cx.media.borrow_mut();
    media.push((key, m));
    Ok(media.len() - 1)
}

fn medium_desc(cx: &Ctx, o: &Object) -> Result<MediumDesc> {
    let homogeneous = match o.plugin.as_str() {
        "homogeneous" => true,
        "heterogeneous" => false,
        _ => return Err(unsupported_plugin(o)),
    };
    let mut p = Props::new(o);
    let scale = p.float("scale", 1.0)?;
    if !(scale >= 0.0 && scale.is_finite()) {
        return Err(Error::scene(
            &o.location,
            format!("scale of {} must be >= 0, got {scale}", describe(o)),
        ));
    }
    let sample_emitters = p.boolean("sample_emitters", true)?;
    // Accepted: penumbra always takes the spectral code path, which serves both settings.
    p.boolean("has_spectral_extinction", true)?;
    let mut sigma_t = None;
    let mut albedo = None;
    let mut phase = None;
    // Mitsuba reads a plain `<rgb>` of a medium as a reflectance: components outside [0, 1]
    // are refused (use `scale` for a larger extinction).
    for name in ["sigma_t", "albedo"] {
        if let Some(c) = p.color(name, ColorRole::Reflectance)? {
            let v = VolumeDesc::Constant {
                value: c,
                to_world: DMat4::IDENTITY,
            };
            if name == "sigma_t" {
                sigma_t = Some(v)
            } else {
                albedo = Some(v)
            }
        }
    }
    cx.finish(p)?;
    for Child { name, object: c } in &o.children {
        match (c.tag.as_str(), name.as_deref()) {
            ("phase", _) if phase.is_none() => phase = Some(phase_desc(c)?),
            ("volume", Some("sigma_t")) if sigma_t.is_none() => sigma_t = Some(volume_desc(cx, c)?),
            ("volume", Some("albedo")) if albedo.is_none() => albedo = Some(volume_desc(cx, c)?),
            ("volume", Some(n @ ("sigma_t" | "albedo"))) => {
                return Err(Error::scene(
                    &c.location,
                    format!("'{n}' of {} is given twice", describe(o)),
                ))
            }
            ("phase", _) => {
                return Err(Error::scene(
                    &c.location,
                    "only a single phase function can be specified per medium",
                ))
            }
            _ => return Err(unexpected_child(o, c)),
        }
    }
    let constant = |v: f64| VolumeDesc::Constant {
        value: ColorDesc::default_for(v, ColorRole::Reflectance),
        to_world: DMat4::IDENTITY,
    };
    Ok(MediumDesc {
        homogeneous,
        sigma_t: sigma_t.unwrap_or_else(|| constant(1.0)),
        albedo: albedo.unwrap_or_else(|| constant(0.75)),
        scale,
        sample_emitters,
        phase: phase.unwrap_or(PhaseDesc::Isotropic),
        location: o.location.clone(),
    })
}

fn phase_desc(o: &Object) -> Result<PhaseDesc> {
    no_children(o)?;
    let mut p = Props::new(o);
    let d = match o.plugin.as_str() {
        "isotropic" => PhaseDesc::Isotropic,
        "hg" => {
            let g = p.float("g", 0.8)?;
            if !(g > -1.0 && g < 1.0) {
                return Err(Error::scene(
                    &o.location,
                    format!(
                        "g of {} must lie in the interval (-1, 1), got {g}",
                        describe(o)
                    ),
                ));
            }
            PhaseDesc::HenyeyGreenstein { g }
        }
        _ => return Err(unsupported_plugin(o)),
    };
    p.finish()?;
    Ok(d)
}

pub(super) fn volume_desc(cx: &Ctx, o: &Object) -> Result<VolumeDesc> {
    no_children(o)?;
    let mut p = Props::new(o);
    let to_world = p.transform("to_world")?;
    if !to_world.is_finite() || to_world.determinant() == 0.0 {
        return Err(Error::scene(
            &o.location,
            format!("to_world of {} is not invertible", describe(o)),
        ));
    }
    let d = match o.plugin.as_str() {
        "constvolume" => VolumeDesc::Constant {
            value: p
                .color("value", ColorRole::Unbounded)?
                .unwrap_or_else(|| ColorDesc::default_for(1.0, ColorRole::Unbounded)),
            to_world,
        },
        "gridvolume" => {
            let filename = file_parameter(cx, &mut p, o)?;
            let use_grid_bbox = p.boolean("use_grid_bbox", false)?;
            let trilinear = match p.string("filter_type")? {
                None | Some(("trilinear", _)) => true,
                Some(("nearest", _)) => false,
                Some((s, loc)) => {
                    return Err(Error::scene(
                        loc,
                        format!(
                            "invalid filter_type '{s}' of {}: must be \"nearest\" or \"trilinear\"",
                            describe(o)
                        ),
                    ))
                }
            };
            let wrap = match p.string("wrap_mode")? {
                None => "clamp".to_string(),
                Some((s @ ("clamp" | "repeat" | "mirror"), _)) => s.to_string(),
                Some((s, loc)) => {
                    return Err(Error::scene(
                        loc,
                        format!(
                            "invalid wrap_mode '{s}' of {}: must be \"repeat\", \"mirror\" or \"clamp\"",
                            describe(o)
                        ),
                    ))
                }
            };
            // RGB rendering never converts grid values; `accel` changes nothing.
            let raw = p.boolean("raw", false)?;
            p.boolean("accel", true)?;
            let max_value = match p.take("max_value") {
                None => None,
                Some((Value::Float(x), _))
                    if x.is_finite() && *x >= 0.0 && *x <= f32::MAX as f64 =>
                {
                    Some(*x)
                }
                Some((Value::Integer(i), _)) if *i >= 0 => Some(*i as f64),
                Some((v, loc)) => {
                    return Err(Error::scene(
                        loc,
                        format!(
                            "max_value of {} must be a finite number >= 0, not {v:?}",
                            describe(o)
                        ),
                    ))
                }
            };
            VolumeDesc::Grid {
                filename,
                to_world,
                use_grid_bbox,
                trilinear,
                wrap,
                max_value,
                raw,
            }
        }
        _ => return Err(unsupported_plugin(o)),
    };
    cx.finish(p)?;
    Ok(d)
}
