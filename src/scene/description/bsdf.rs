//! BSDFs: `diffuse`, conductors, dielectrics, plastics, `principled`, `principledthin`, and
//! Mitsuba's adapters (`twosided`, `mask`, `blendbsdf`, `normalmap`, `bumpmap`, `null`).
//! Parameters Mitsuba reads as textures are [`TextureDesc`]s.

use super::texture::{texture_desc, texture_or, texture_param, Children};
use super::*;
use crate::bsdf::{BsdfParam, ParamKind, PluginInfo};
use crate::spectrum::ColorRole;

#[derive(Clone, Debug, PartialEq)]
pub enum BsdfDesc {
    Diffuse {
        reflectance: TextureDesc,
    },
    TwoSided {
        front: Box<BsdfDesc>,
        back: Box<BsdfDesc>,
    },
    /// `conductor`: complex IOR (from `eta`/`k` or a named `material`).
    Conductor {
        eta: TextureDesc,
        k: TextureDesc,
        specular_reflectance: TextureDesc,
    },
    RoughConductor {
        distribution: MicrofacetDesc,
        eta: TextureDesc,
        k: TextureDesc,
        specular_reflectance: TextureDesc,
    },
    /// `dielectric`; IORs resolved to numbers (presets looked up).
    Dielectric {
        int_ior: f64,
        ext_ior: f64,
        specular_reflectance: TextureDesc,
        specular_transmittance: TextureDesc,
    },
    ThinDielectric {
        int_ior: f64,
        ext_ior: f64,
        specular_reflectance: TextureDesc,
        specular_transmittance: TextureDesc,
    },
    RoughDielectric {
        distribution: MicrofacetDesc,
        int_ior: f64,
        ext_ior: f64,
        specular_reflectance: TextureDesc,
        specular_transmittance: TextureDesc,
    },
    Plastic {
        int_ior: f64,
        ext_ior: f64,
        diffuse_reflectance: TextureDesc,
        specular_reflectance: TextureDesc,
        nonlinear: bool,
    },
    /// `roughplastic`; its roughness is a number (Mitsuba precomputes tables for it).
    RoughPlastic {
        distribution: MicrofacetDesc,
        int_ior: f64,
        ext_ior: f64,
        diffuse_reflectance: TextureDesc,
        specular_reflectance: TextureDesc,
        nonlinear: bool,
    },
    /// A plugin read through its parameter table (`crate::bsdf::TABLE_PLUGINS`): one
    /// texture (a plain number as a constant) per parameter, in table order.
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
    /// `principled` or `principledthin`.
    Principled(Box<PrincipledDesc>),
}

/// Mitsuba's `principled` (Disney) BSDF and its thin-sheet variant.
#[derive(Clone, Debug, PartialEq)]
pub struct PrincipledDesc {
    /// `principledthin`.
    pub thin: bool,
    /// The texture parameters the scene gives (the others keep Mitsuba's defaults).
    pub params: Vec<(BsdfParam, TextureDesc)>,
    /// `principled`: `eta` if given, else the one `specular` stands for (not both).
    pub eta: Option<f64>,
    pub specular: f64,
    /// `spec_trans` given as a texture or a float other than 0 (Mitsuba's `get_flag`).
    pub has_spec_trans: bool,
    /// Sampling rates: `principled`'s diffuse_reflectance, main_specular and clearcoat;
    /// `principledthin`'s specular_reflectance, specular_transmittance, diffuse_reflectance
    /// and diffuse_transmittance.
    pub sampling_rates: Vec<f64>,
}

/// Microfacet distribution parameters shared by the rough BSDFs (Mitsuba's `distribution`,
/// `alpha` or `alpha_u`/`alpha_v` as one-value textures, `sample_visible`).
#[derive(Clone, Debug, PartialEq)]
pub struct MicrofacetDesc {
    pub kind: MicrofacetKind,
    pub alpha_u: TextureDesc,
    pub alpha_v: TextureDesc,
    pub sample_visible: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MicrofacetKind {
    Beckmann,
    Ggx,
}

impl BsdfDesc {
    /// The image files the BSDF's textures (and those of the BSDFs it nests) read.
    pub fn files<'a>(&'a self, out: &mut Vec<&'a Path>) {
        let mut tex = |t: &'a TextureDesc| t.files(out);
        match self {
            BsdfDesc::Diffuse { reflectance } => tex(reflectance),
            BsdfDesc::Conductor {
                eta,
                k,
                specular_reflectance,
            } => {
                tex(eta);
                tex(k);
                tex(specular_reflectance);
            }
            BsdfDesc::RoughConductor {
                distribution,
                eta,
                k,
                specular_reflectance,
            } => {
                tex(&distribution.alpha_u);
                tex(&distribution.alpha_v);
                tex(eta);
                tex(k);
                tex(specular_reflectance);
            }
            BsdfDesc::Dielectric {
                specular_reflectance,
                specular_transmittance,
                ..
            }
            | BsdfDesc::ThinDielectric {
                specular_reflectance,
                specular_transmittance,
                ..
            } => {
                tex(specular_reflectance);
                tex(specular_transmittance);
            }
            BsdfDesc::RoughDielectric {
                distribution,
                specular_reflectance,
                specular_transmittance,
                ..
            } => {
                tex(&distribution.alpha_u);
                tex(&distribution.alpha_v);
                tex(specular_reflectance);
                tex(specular_transmittance);
            }
            BsdfDesc::Plastic {
                diffuse_reflectance,
                specular_reflectance,
                ..
            }
            | BsdfDesc::RoughPlastic {
                diffuse_reflectance,
                specular_reflectance,
                ..
            } => {
                tex(diffuse_reflectance);
                tex(specular_reflectance);
            }
            BsdfDesc::Principled(p) => p.params.iter().for_each(|(_, t)| tex(t)),
            BsdfDesc::Table { params, .. } => params.iter().for_each(tex),
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
        BsdfDesc::Diffuse {
            reflectance: TextureDesc::value(0.5),
        }
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
        "diffuse" => BsdfDesc::Diffuse {
            reflectance: texture_or(
                cx,
                &mut p,
                &mut ch,
                "reflectance",
                refl,
                TextureDesc::value(0.5),
            )?,
        },
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
        "conductor" | "roughconductor" => {
            let distribution = if o.plugin == "roughconductor" {
                Some(microfacet_desc(cx, &mut p, &mut ch, o, true)?)
            } else {
                None
            };
            let (eta, k) = conductor_ior(cx, &mut p, &mut ch, o)?;
            let specular_reflectance = texture_or(
                cx,
                &mut p,
                &mut ch,
                "specular_reflectance",
                refl,
                TextureDesc::value(1.0),
            )?;
            match distribution {
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
            }
        }
        "dielectric" | "thindielectric" | "roughdielectric" => {
            let distribution = if o.plugin == "roughdielectric" {
                Some(microfacet_desc(cx, &mut p, &mut ch, o, true)?)
            } else {
                None
            };
            let int_ior = ior(&mut p, o, "int_ior", "bk7")?;
            let ext_ior = ior(&mut p, o, "ext_ior", "air")?;
            let specular_reflectance = texture_or(
                cx,
                &mut p,
                &mut ch,
                "specular_reflectance",
                refl,
                TextureDesc::value(1.0),
            )?;
            let specular_transmittance = texture_or(
                cx,
                &mut p,
                &mut ch,
                "specular_transmittance",
                refl,
                TextureDesc::value(1.0),
            )?;
            match (o.plugin.as_str(), distribution) {
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
            }
        }
        "plastic" | "roughplastic" => {
            let distribution = if o.plugin == "roughplastic" {
                // Mitsuba's roughplastic is isotropic, with a numeric roughness.
                let d = microfacet_desc(cx, &mut p, &mut ch, o, false)?;
                if d.alpha_u.constant_scalar().is_none() {
                    return Err(Error::scene(
                        &o.location,
                        format!("the alpha of {} must be a number, not a texture (Mitsuba precomputes its tables from it)", describe(o)),
                    ));
                }
                Some(d)
            } else {
                None
            };
            let int_ior = ior(&mut p, o, "int_ior", "polypropylene")?;
            let ext_ior = ior(&mut p, o, "ext_ior", "air")?;
            let diffuse_reflectance = texture_or(
                cx,
                &mut p,
                &mut ch,
                "diffuse_reflectance",
                refl,
                TextureDesc::value(0.5),
            )?;
            let specular_reflectance = texture_or(
                cx,
                &mut p,
                &mut ch,
                "specular_reflectance",
                refl,
                TextureDesc::value(1.0),
            )?;
            let nonlinear = p.boolean("nonlinear", false)?;
            match distribution {
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
        "principled" | "principledthin" => principled_desc(cx, &mut p, &mut ch, o)?,
        _ => return Err(unsupported_plugin(o)),
    };
    cx.finish(p)?;
    ch.finish()?;
    Ok(desc)
}

/// A plugin with a parameter table: each parameter from the scene or its default, a constant
/// checked against the parameter's range, then the plugin's check across parameters.
fn table_desc(
    cx: &Ctx,
    p: &mut Props,
    ch: &mut Children,
    o: &Object,
    info: &'static PluginInfo,
) -> Result<BsdfDesc> {
    let mut params = Vec::with_capacity(info.params.len());
    let mut constants = Vec::with_capacity(info.params.len());
    for spec in info.params {
        let default = TextureDesc::value(spec.default);
        let t = match spec.kind {
            ParamKind::Color(role) => texture_or(cx, p, ch, spec.name, role, default)?,
            ParamKind::Number => texture_or(cx, p, ch, spec.name, ColorRole::Unbounded, default)?,
            ParamKind::Float => TextureDesc::value(p.float(spec.name, spec.default)?),
        };
        let constant = if spec.is_scalar() {
            t.constant_scalar().map(DVec3::splat)
        } else {
            t.constant_rgb()
        };
        if let Some(c) = constant {
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

/// `principled` and `principledthin` (Mitsuba 3.9.1: every parameter but `eta`/`specular`
/// and the sampling rates is a texture; `eta` is one for `principledthin`).
fn principled_desc(cx: &Ctx, p: &mut Props, ch: &mut Children, o: &Object) -> Result<BsdfDesc> {
    use BsdfParam as P;
    let thin = o.plugin == "principledthin";
    let refl = ColorRole::Reflectance;
    let mut names: Vec<(&str, BsdfParam, ColorRole)> = vec![
        ("base_color", P::BaseColor, refl),
        ("roughness", P::Roughness, refl),
        ("anisotropic", P::Anisotropic, refl),
        ("spec_trans", P::SpecTrans, refl),
        ("sheen", P::Sheen, refl),
        ("sheen_tint", P::SheenTint, refl),
        ("flatness", P::Flatness, refl),
        ("spec_tint", P::SpecTint, refl),
    ];
    if thin {
        names.extend([
            ("eta", P::SheetEta, ColorRole::Unbounded),
            ("diff_trans", P::DiffTrans, refl),
        ]);
    } else {
        names.extend([
            ("metallic", P::Metallic, refl),
            ("clearcoat", P::Clearcoat, refl),
            ("clearcoat_gloss", P::ClearcoatGloss, refl),
        ]);
    }
    // Mitsuba's get_flag: given, and not a float equal to 0.
    let has_spec_trans = match p.peek("spec_trans") {
        Some(Value::Float(x)) => *x != 0.0,
        Some(Value::Integer(i)) => *i != 0,
        Some(_) => true,
        None => ch.has("spec_trans"),
    };
    let mut params = Vec::new();
    for (name, param, role) in names {
        if let Some(t) = texture_param(cx, p, ch, name, role)? {
            if let Some(v) = t.constant_rgb() {
                if !v.is_finite() {
                    return Err(Error::scene(
                        &o.location,
                        format!("{name} of {} must be finite", describe(o)),
                    ));
                }
            }
            params.push((param, t));
        }
    }
    let (eta, specular) = if thin {
        (None, 0.5)
    } else {
        let has = |n: &str| o.properties.iter().any(|q| q.name == n);
        if has("eta") && has("specular") {
            return Err(Error::scene(
                &o.location,
                format!("{}: give either 'eta' or 'specular', not both", describe(o)),
            ));
        }
        let eta = if has("eta") {
            Some(positive(p.float("eta", 1.5)?, "eta", o)?)
        } else {
            None
        };
        let specular = p.float("specular", 0.5)?;
        if !(0.0..=1.0).contains(&specular) {
            return Err(Error::scene(
                &o.location,
                format!(
                    "specular of {} must lie in [0, 1], got {specular}",
                    describe(o)
                ),
            ));
        }
        (eta, specular)
    };
    let rate_names: &[&str] = if thin {
        &[
            "specular_reflectance_sampling_rate",
            "specular_transmittance_sampling_rate",
            "diffuse_reflectance_sampling_rate",
            "diffuse_transmittance_sampling_rate",
        ]
    } else {
        &[
            "diffuse_reflectance_sampling_rate",
            "main_specular_sampling_rate",
            "clearcoat_sampling_rate",
        ]
    };
    let mut sampling_rates = Vec::new();
    for name in rate_names {
        let r = p.float(name, 1.0)?;
        if !(r >= 0.0 && r.is_finite()) {
            return Err(Error::scene(
                &o.location,
                format!("{name} of {} must be finite and >= 0, got {r}", describe(o)),
            ));
        }
        sampling_rates.push(r);
    }
    Ok(BsdfDesc::Principled(Box::new(PrincipledDesc {
        thin,
        params,
        eta,
        specular,
        has_spec_trans,
        sampling_rates,
    })))
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
/// (not both), as in Mitsuba; the default `none` is the ideal mirror η = 0, k = 1.
pub(super) fn conductor_ior(
    cx: &Ctx,
    p: &mut Props,
    ch: &mut Children,
    o: &Object,
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
            let v =
                |a: [f32; 3]| TextureDesc::rgb(DVec3::new(a[0] as f64, a[1] as f64, a[2] as f64));
            Ok((v(e), v(kk)))
        }
        _ => {
            let eta = eta.unwrap_or(TextureDesc::value(0.0));
            let k = k.unwrap_or(TextureDesc::value(1.0));
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

/// Mitsuba's microfacet parameters: `distribution` (beckmann | ggx, default beckmann),
/// `alpha` (default 0.1) or, when `anisotropic` is allowed, both `alpha_u` and `alpha_v`
/// (numbers or one-value textures); `sample_visible` (default true). A numeric roughness must
/// be finite and >= 0 (Mitsuba accepts negative values without meaning; penumbra refuses
/// them).
pub(super) fn microfacet_desc(
    cx: &Ctx,
    p: &mut Props,
    ch: &mut Children,
    o: &Object,
    anisotropic: bool,
) -> Result<MicrofacetDesc> {
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
    let unb = ColorRole::Unbounded;
    let alpha = texture_param(cx, p, ch, "alpha", unb)?;
    let u = texture_param(cx, p, ch, "alpha_u", unb)?;
    let v = texture_param(cx, p, ch, "alpha_v", unb)?;
    let (alpha_u, alpha_v) = match (alpha, u, v) {
        (a, None, None) => {
            let a = a.unwrap_or(TextureDesc::value(0.1));
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
    let sample_visible = p.boolean("sample_visible", true)?;
    Ok(MicrofacetDesc {
        kind,
        alpha_u,
        alpha_v,
        sample_visible,
    })
}
