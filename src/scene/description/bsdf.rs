//! BSDFs: the leaf plugins, each read through its parameter table (`crate::bsdf::plugin`:
//! `diffuse`, conductors, dielectrics, plastics, `phong`, `principled`, `principledthin`),
//! and Mitsuba's adapters (`twosided`, `mask`, `blendbsdf`, `normalmap`, `bumpmap`, `null`).
//! Parameters Mitsuba reads as textures are [`TextureDesc`]s.

use super::texture::{texture_desc, texture_or, texture_param, Children};
use super::*;
use crate::bsdf::{ParamKind, PluginInfo};
use crate::spectrum::{ColorRole, SpectrumValue};

#[derive(Clone, Debug, PartialEq)]
pub enum BsdfDesc {
    TwoSided {
        front: Box<BsdfDesc>,
        back: Box<BsdfDesc>,
    },
    /// A leaf BSDF, read through its plugin's parameter table (`crate::bsdf::TABLE_PLUGINS`):
    /// one texture per parameter, in table order (a plain number, flag, choice or IOR as a
    /// constant).
    Table {
        plugin: &'static str,
        params: Vec<TextureDesc>,
    },
    /// `mask`: `opacity` (one value) of the nested BSDF, the rest passes through.
    Mask {
        opacity: TextureDesc,
        nested: Box<BsdfDesc>,
    },
    /// `blendbsdf`: (1 − `weight`) · first + `weight` · second.
    Blend {
        weight: TextureDesc,
        nested: Box<[BsdfDesc; 2]>,
    },
    NormalMap {
        normalmap: TextureDesc,
        nested: Box<BsdfDesc>,
        flip_invalid_normals: bool,
        use_shadowing_function: bool,
    },
    BumpMap {
        height: TextureDesc,
        scale: f64,
        nested: Box<BsdfDesc>,
        flip_invalid_normals: bool,
        use_shadowing_function: bool,
    },
    /// `null`: no interaction, light passes straight through.
    Null,
}

impl BsdfDesc {
    /// The image files the BSDF's textures (and those of the BSDFs it nests) read.
    pub fn files<'a>(&'a self, out: &mut Vec<&'a Path>) {
        match self {
            BsdfDesc::Table { params, .. } => params.iter().for_each(|t| t.files(out)),
            BsdfDesc::Null => {}
            BsdfDesc::TwoSided { front, back } => {
                front.files(out);
                back.files(out);
            }
            BsdfDesc::Mask { opacity, nested } => {
                opacity.files(out);
                nested.files(out);
            }
            BsdfDesc::Blend { weight, nested } => {
                weight.files(out);
                nested[0].files(out);
                nested[1].files(out);
            }
            BsdfDesc::NormalMap {
                normalmap, nested, ..
            } => {
                normalmap.files(out);
                nested.files(out);
            }
            BsdfDesc::BumpMap { height, nested, .. } => {
                height.files(out);
                nested.files(out);
            }
        }
    }

    /// Mitsuba's default for a shape without a BSDF: diffuse with reflectance 0.5.
    pub fn default_diffuse() -> Self {
        Self::diffuse(TextureDesc::value(0.5))
    }

    /// `diffuse` with this reflectance.
    pub fn diffuse(reflectance: TextureDesc) -> Self {
        BsdfDesc::Table {
            plugin: "diffuse",
            params: vec![reflectance],
        }
    }

    /// The plugin's name in scene files, for a leaf BSDF.
    pub fn plugin(&self) -> Option<&'static str> {
        match self {
            BsdfDesc::Table { plugin, .. } => Some(plugin),
            _ => None,
        }
    }

    /// The parameter `name` of a leaf BSDF read through its table.
    pub fn param(&self, name: &str) -> Option<&TextureDesc> {
        let BsdfDesc::Table { plugin, params } = self else {
            return None;
        };
        let info = crate::bsdf::table_plugin(plugin)?;
        let i = info.params.iter().position(|s| s.name == name)?;
        params.get(i)
    }
}

/// The one nested `<bsdf>` of an adapter.
fn one_nested(cx: &Ctx, o: &Object, ch: &mut Children) -> Result<Box<BsdfDesc>> {
    let nested = ch.with_tag("bsdf");
    match nested.as_slice() {
        [b] => Ok(Box::new(bsdf_desc(cx, b)?)),
        [] => Err(Error::scene(
            &o.location,
            format!("{} needs a nested <bsdf>", describe(o)),
        )),
        [_, extra, ..] => Err(Error::scene(
            &extra.location,
            format!("{} takes a single nested <bsdf>", describe(o)),
        )),
    }
}

pub(super) fn bsdf_desc(cx: &Ctx, o: &Arc<Object>) -> Result<BsdfDesc> {
    let mut p = Props::new(o);
    let mut ch = Children::new(o);
    let refl = ColorRole::Reflectance;
    if let Some(info) = crate::bsdf::table_plugin(&o.plugin) {
        let desc = table_desc(cx, &mut p, &mut ch, o, info)?;
        cx.finish(p)?;
        ch.finish()?;
        return Ok(desc);
    }
    let desc = match o.plugin.as_str() {
        "twosided" => {
            if let Some((true, loc)) = p
                .take("allow_transmission")
                .map(|(v, l)| (*v == Value::Boolean(true), l))
            {
                return Err(Error::scene(
                    loc,
                    format!("{}: allow_transmission is not supported", describe(o)),
                ));
            }
            let nested = ch.with_tag("bsdf");
            if let Some(inner) = nested.iter().find(|c| c.plugin == "twosided") {
                return Err(Error::scene(
                    &inner.location,
                    "a twosided BSDF cannot nest another twosided",
                ));
            }
            let mut it = nested.into_iter();
            let front = it.next().ok_or_else(|| {
                Error::scene(
                    &o.location,
                    format!("{} needs a nested <bsdf>", describe(o)),
                )
            })?;
            let front = bsdf_desc(cx, front)?;
            let back = match it.next() {
                Some(b) => bsdf_desc(cx, b)?,
                None => front.clone(),
            };
            if let Some(extra) = it.next() {
                return Err(unexpected_child(o, extra));
            }
            BsdfDesc::TwoSided {
                front: Box::new(front),
                back: Box::new(back),
            }
        }
        "mask" => {
            let opacity = texture_or(
                cx,
                &mut p,
                &mut ch,
                "opacity",
                refl,
                TextureDesc::value(0.5),
            )?;
            BsdfDesc::Mask {
                opacity,
                nested: one_nested(cx, o, &mut ch)?,
            }
        }
        "blendbsdf" => {
            let weight = texture_param(cx, &mut p, &mut ch, "weight", refl)?.ok_or_else(|| {
                Error::scene(&o.location, format!("{} needs a 'weight'", describe(o)))
            })?;
            let nested = ch.with_tag("bsdf");
            let [a, b] = nested.as_slice() else {
                return Err(Error::scene(
                    &o.location,
                    format!(
                        "{} needs exactly two nested <bsdf>s, found {}",
                        describe(o),
                        nested.len()
                    ),
                ));
            };
            BsdfDesc::Blend {
                weight,
                nested: Box::new([bsdf_desc(cx, a)?, bsdf_desc(cx, b)?]),
            }
        }
        "normalmap" => {
            let normalmap = texture_param(cx, &mut p, &mut ch, "normalmap", ColorRole::Unbounded)?
                .ok_or_else(|| {
                    Error::scene(
                        &o.location,
                        format!("{} needs a 'normalmap' texture", describe(o)),
                    )
                })?;
            BsdfDesc::NormalMap {
                normalmap,
                nested: one_nested(cx, o, &mut ch)?,
                flip_invalid_normals: p.boolean("flip_invalid_normals", true)?,
                use_shadowing_function: p.boolean("use_shadowing_function", true)?,
            }
        }
        "bumpmap" => {
            let textures = ch.with_tag("texture");
            let height = match textures.as_slice() {
                [t] => texture_desc(cx, t, ColorRole::Unbounded)?,
                [] => {
                    return Err(Error::scene(
                        &o.location,
                        format!(
                            "{} needs a nested <texture> (the height field)",
                            describe(o)
                        ),
                    ))
                }
                [_, extra, ..] => {
                    return Err(Error::scene(
                        &extra.location,
                        format!("{} takes a single <texture>", describe(o)),
                    ))
                }
            };
            let scale = p.float("scale", 1.0)?;
            if !scale.is_finite() {
                return Err(Error::scene(
                    &o.location,
                    format!("scale of {} must be finite", describe(o)),
                ));
            }
            BsdfDesc::BumpMap {
                height,
                scale,
                nested: one_nested(cx, o, &mut ch)?,
                flip_invalid_normals: p.boolean("flip_invalid_normals", true)?,
                use_shadowing_function: p.boolean("use_shadowing_function", true)?,
            }
        }
        "null" => BsdfDesc::Null,
        _ => return Err(unsupported_plugin(o)),
    };
    cx.finish(p)?;
    ch.finish()?;
    Ok(desc)
}

/// A leaf BSDF read through its parameter table: each parameter from the scene or its
/// default, read as its kind says (`crate::bsdf::ParamKind`), a constant of a colour or
/// number checked against the parameter's range, then the plugin's check across parameters.
fn table_desc(
    cx: &Ctx,
    p: &mut Props,
    ch: &mut Children,
    o: &Object,
    info: &'static PluginInfo,
) -> Result<BsdfDesc> {
    let mut params = Vec::with_capacity(info.params.len());
    let mut constants = Vec::with_capacity(info.params.len());
    // The second of a pair read together (roughness v, conductor k), for the next entry.
    let mut second: Option<TextureDesc> = None;
    for (i, spec) in info.params.iter().enumerate() {
        let default = TextureDesc::value(spec.default);
        // The default of the entry a pair's first one reads with it.
        let next_default = info.params.get(i + 1).map_or(spec.default, |s| s.default);
        let t = match spec.kind {
            ParamKind::Color(role) => texture_or(cx, p, ch, spec.name, role, default)?,
            ParamKind::Number(role) => texture_or(cx, p, ch, spec.name, role, default)?,
            ParamKind::Exclusive(other) => {
                let has = |n: &str| o.properties.iter().any(|q| q.name == n);
                if has(spec.name) && has(other) {
                    return Err(Error::scene(
                        &o.location,
                        format!(
                            "{}: give either '{}' or '{other}', not both",
                            describe(o),
                            spec.name
                        ),
                    ));
                }
                TextureDesc::value(if has(spec.name) {
                    positive(p.float(spec.name, 0.0)?, spec.name, o)?
                } else {
                    0.0
                })
            }
            // Mitsuba's get_flag: given, and not a number equal to 0.
            ParamKind::Given(name) => TextureDesc::value(match p.peek(name) {
                Some(Value::Float(x)) => (*x != 0.0) as u8 as f64,
                Some(Value::Integer(i)) => (*i != 0) as u8 as f64,
                Some(_) => 1.0,
                None => ch.has(name) as u8 as f64,
            }),
            ParamKind::Float => TextureDesc::value(p.float(spec.name, spec.default)?),
            ParamKind::Bool => {
                let b = p.boolean(spec.name, spec.default != 0.0)?;
                TextureDesc::value(if b { 1.0 } else { 0.0 })
            }
            ParamKind::Choice(names) => {
                TextureDesc::value(choice(p, o, spec.name, names, spec.default)? as f64)
            }
            ParamKind::Ior(preset) => TextureDesc::value(ior(p, o, spec.name, preset)?),
            ParamKind::Roughness {
                anisotropic,
                texture,
            } => {
                let (u, v) = roughness(cx, p, ch, o, (anisotropic, texture), spec.default)?;
                if anisotropic {
                    second = Some(v);
                }
                u
            }
            ParamKind::ConductorEta => {
                let (eta, k) = conductor_ior(cx, p, ch, o, (spec.default, next_default))?;
                second = Some(k);
                eta
            }
            ParamKind::RoughnessV | ParamKind::ConductorK => second.take().ok_or_else(|| {
                Error::Invalid(format!(
                    "the parameter table of {} has {} without the entry it pairs with",
                    info.name, spec.name
                ))
            })?,
        };
        let constant = if spec.is_scalar() {
            t.constant_scalar().map(DVec3::splat)
        } else {
            t.constant_rgb()
        };
        let ranged = matches!(
            spec.kind,
            ParamKind::Color(_) | ParamKind::Number(_) | ParamKind::Float
        );
        if let (Some(c), true) = (constant, ranged) {
            let bad = if spec.is_scalar() {
                (!(spec.min..=spec.max).contains(&c.x)).then(|| format!("{}", c.x))
            } else {
                (!(0..3).all(|i| (spec.min..=spec.max).contains(&c[i]))).then(|| format!("{c:?}"))
            };
            if let Some(v) = bad {
                return Err(Error::scene(
                    &o.location,
                    format!(
                        "the {} of {} must be in [{}, {}], got {v}",
                        spec.name,
                        describe(o),
                        spec.min,
                        spec.max
                    ),
                ));
            }
        }
        constants.push(constant);
        params.push(t);
    }
    (info.check)(&constants)
        .map_err(|m| Error::scene(&o.location, format!("{}: {m}", describe(o))))?;
    Ok(BsdfDesc::Table {
        plugin: info.name,
        params,
    })
}

/// A string that must be one of `names` (default: the name at index `default`), as its
/// index.
fn choice(p: &mut Props, o: &Object, name: &str, names: &[&str], default: f64) -> Result<usize> {
    match p.string(name)? {
        None => Ok(default as usize),
        Some((s, loc)) => names.iter().position(|n| *n == s).ok_or_else(|| {
            let quoted: Vec<String> = names.iter().map(|n| format!("\"{n}\"")).collect();
            Error::scene(
                loc,
                format!(
                    "invalid {name} '{s}' of {}: must be {}",
                    describe(o),
                    quoted.join(" or ")
                ),
            )
        }),
    }
}

/// An index of refraction given as a number or as one of Mitsuba's named presets.
pub(super) fn ior(p: &mut Props, o: &Object, name: &str, default: &str) -> Result<f64> {
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

/// `eta` and `k` of a conductor: textures (numbers, colours, spectra), or a named `material`
/// (not both), as in Mitsuba; without either, `defaults` (the `none` material's η = 0,
/// k = 1: the ideal mirror).
fn conductor_ior(
    cx: &Ctx,
    p: &mut Props,
    ch: &mut Children,
    o: &Object,
    defaults: (f64, f64),
) -> Result<(TextureDesc, TextureDesc)> {
    let material = p.string("material")?;
    let eta = texture_param(cx, p, ch, "eta", ColorRole::Unbounded)?;
    let k = texture_param(cx, p, ch, "k", ColorRole::Unbounded)?;
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
            // RGB mode: Mitsuba's RGB of the measured spectra; spectral mode: the spectra.
            let ((ew, ev), (kw, kv)) =
                crate::bsdf::presets::conductor_spectra(name).ok_or_else(|| {
                    Error::scene(loc, format!("no spectra for conductor material '{name}'"))
                })?;
            let v = |a: [f32; 3], w: &[f64], x: &[f64]| -> Result<TextureDesc> {
                let spectrum = SpectrumValue::sampled(w.to_vec(), x.to_vec())
                    .map_err(|e| Error::scene(loc, format!("conductor material '{name}': {e}")))?;
                Ok(TextureDesc::color(ColorDesc {
                    rgb: DVec3::new(a[0] as f64, a[1] as f64, a[2] as f64),
                    spectral: SpectralDesc::Sampled(spectrum),
                }))
            };
            Ok((v(e, ew, ev)?, v(kk, kw, kv)?))
        }
        _ => {
            let eta = eta.unwrap_or(TextureDesc::value(defaults.0));
            let k = k.unwrap_or(TextureDesc::value(defaults.1));
            for t in [&eta, &k] {
                if let Some(c) = t.constant_rgb() {
                    if !(c.is_finite() && c.min_element() >= 0.0) {
                        return Err(Error::scene(
                            &o.location,
                            format!("eta and k of {} must be finite and >= 0", describe(o)),
                        ));
                    }
                }
            }
            Ok((eta, k))
        }
    }
}

/// Mitsuba's microfacet roughness: `alpha` (`default`, Mitsuba's 0.1) or, when `anisotropic` is allowed,
/// both `alpha_u` and `alpha_v` (numbers, or one-value textures where `texture` allows), as
/// (u, v). A numeric roughness must be finite and >= 0 (Mitsuba accepts negative values
/// without meaning; penumbra refuses them).
fn roughness(
    cx: &Ctx,
    p: &mut Props,
    ch: &mut Children,
    o: &Object,
    (anisotropic, texture): (bool, bool),
    default: f64,
) -> Result<(TextureDesc, TextureDesc)> {
    let unb = ColorRole::Unbounded;
    let alpha = texture_param(cx, p, ch, "alpha", unb)?;
    let u = texture_param(cx, p, ch, "alpha_u", unb)?;
    let v = texture_param(cx, p, ch, "alpha_v", unb)?;
    let (alpha_u, alpha_v) = match (alpha, u, v) {
        (a, None, None) => {
            let a = a.unwrap_or(TextureDesc::value(default));
            (a.clone(), a)
        }
        // Mitsuba's isotropic-only models (roughplastic) take alpha_u and alpha_v when they
        // are equal numbers: that is the isotropic alpha.
        (None, Some(u), Some(v))
            if !anisotropic
                && u.constant_scalar().is_some()
                && u.constant_scalar() == v.constant_scalar() =>
        {
            (u.clone(), u)
        }
        (_, Some(_), _) | (_, _, Some(_)) if !anisotropic => {
            return Err(Error::scene(
                &o.location,
                format!(
                    "{} does not support anisotropic roughness (alpha_u/alpha_v must be equal numbers, or use alpha)",
                    describe(o)
                ),
            ))
        }
        (Some(_), _, _) => {
            return Err(Error::scene(
                &o.location,
                format!(
                    "{}: give either alpha or both alpha_u and alpha_v",
                    describe(o)
                ),
            ))
        }
        (None, Some(u), Some(v)) => (u, v),
        (None, _, _) => {
            return Err(Error::scene(
                &o.location,
                format!(
                    "{}: both alpha_u and alpha_v must be specified",
                    describe(o)
                ),
            ))
        }
    };
    for (name, a) in [("alpha_u", &alpha_u), ("alpha_v", &alpha_v)] {
        if let Some(a) = a.constant_scalar() {
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
    }
    if !texture && alpha_u.constant_scalar().is_none() {
        return Err(Error::scene(
            &o.location,
            format!("the alpha of {} must be a number, not a texture (Mitsuba precomputes its tables from it)", describe(o)),
        ));
    }
    Ok((alpha_u, alpha_v))
}
