//! BSDFs: `diffuse`, `twosided`, conductors, dielectrics and plastics.

use super::*;
use crate::spectrum::ColorRole;

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

pub(super) fn bsdf_desc(cx: &Ctx, o: &Arc<Object>) -> Result<BsdfDesc> {
    match o.plugin.as_str() {
        "diffuse" => {
            no_children(o)?;
            let mut p = Props::new(o);
            let reflectance = p
                .color("reflectance", ColorRole::Reflectance)?
                .unwrap_or(DVec3::splat(0.5));
            cx.finish(p)?;
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
                nested.push(bsdf_desc(cx, c)?);
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
            let specular_reflectance = p
                .color("specular_reflectance", ColorRole::Reflectance)?
                .unwrap_or(DVec3::ONE);
            cx.finish(p)?;
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
            let specular_reflectance = p
                .color("specular_reflectance", ColorRole::Reflectance)?
                .unwrap_or(DVec3::ONE);
            let specular_transmittance = p
                .color("specular_transmittance", ColorRole::Reflectance)?
                .unwrap_or(DVec3::ONE);
            cx.finish(p)?;
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
            let diffuse_reflectance = p
                .color("diffuse_reflectance", ColorRole::Reflectance)?
                .unwrap_or(DVec3::splat(0.5));
            let specular_reflectance = p
                .color("specular_reflectance", ColorRole::Reflectance)?
                .unwrap_or(DVec3::ONE);
            let nonlinear = p.boolean("nonlinear", false)?;
            cx.finish(p)?;
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

/// `eta` and `k` of a conductor: numbers/colours, or a named `material` (not both), as in
/// Mitsuba; the default `none` is the ideal mirror η = 0, k = 1.
pub(super) fn conductor_ior(p: &mut Props, o: &Object) -> Result<(DVec3, DVec3)> {
    let material = p.string("material")?;
    let eta = p.color("eta", ColorRole::Unbounded)?;
    let k = p.color("k", ColorRole::Unbounded)?;
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
pub(super) fn microfacet_desc(
    p: &mut Props,
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
