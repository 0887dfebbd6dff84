//! What a leaf BSDF plugin is: the model's interface ([`BsdfModel`]: eval, pdf, sample, and
//! the few properties the integrators ask about) and, for plugins described by a table,
//! their parameters ([`TablePlugin`]: each parameter's name, kind, default and range, at the
//! top of the plugin's own file, as Mitsuba's plugins document theirs).
//!
//! A plugin with a table needs nothing else: the scene description reads its parameters
//! from the table (defaults, range checks, textures where the kind allows them;
//! `scene::description::bsdf`), the scene builder turns constants and texture means into the
//! BSDF ([`TablePlugin::from_params`]) and binds the textured ones by their index in the
//! table ([`BsdfModel::set_param`]). Adding such a BSDF is its file plus one line in the
//! `bsdfs!` list of `bsdf/mod.rs`.
//!
//! The interface is written for one path at a time (`f32`, `Vec3`); the lane engine's
//! kernels (issue 42) take the same tables and implement the model per lane in the same
//! files.

use super::{BsdfSample, Spectrum};
use crate::spectrum::ColorRole;
use glam::{DVec3, Vec2, Vec3};

/// How a parameter is given in a scene file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamKind {
    /// A colour, texture allowed (Mitsuba's `get_texture`): an RGB triple at each point.
    Color(ColorRole),
    /// One value, texture allowed (Mitsuba's `get_texture` read with `eval_1`); a colour or
    /// spectrum given for it is read in this role.
    Number(ColorRole),
    /// A plain number (Mitsuba's `get<float>`): no texture.
    Float,
    /// `true` or `false` (value 1 or 0; the default likewise).
    Bool,
    /// One of these names (value: its index; the default is an index).
    Choice(&'static [&'static str]),
    /// An index of refraction: a positive number or one of Mitsuba's named presets
    /// (`bsdf::presets::IOR_PRESETS`); the default is the preset named here.
    Ior(&'static str),
    /// A microfacet roughness, Mitsuba's `alpha` for both axes or `alpha_u` and `alpha_v`
    /// (default 0.1, finite and ≥ 0). `anisotropic`: u and v may differ, and this entry is
    /// the u axis, the next entry of the table (kind [`ParamKind::RoughnessV`]) the v axis;
    /// otherwise this one entry is both. `texture`: whether they may be textures
    /// (roughplastic precomputes tables from a number).
    Roughness { anisotropic: bool, texture: bool },
    /// The v axis of the [`ParamKind::Roughness`] just before it in the table.
    RoughnessV,
    /// A conductor's η, a colour or texture, or from the named `material` preset
    /// (`bsdf::presets::CONDUCTOR_PRESETS`; not both); the default `none` is the ideal
    /// mirror η = 0, k = 1. The next entry of the table (kind [`ParamKind::ConductorK`]) is k.
    ConductorEta,
    /// The k that goes with the [`ParamKind::ConductorEta`] just before it.
    ConductorK,
    /// A positive number that may be absent (value 0), and is refused together with the
    /// parameter named here (principled's `eta`, which `specular` otherwise stands for).
    Exclusive(&'static str),
    /// Not a scene parameter: 1 when the scene gives the parameter named here as a texture
    /// or as a number other than 0, else 0 (Mitsuba's `get_flag`, principled's
    /// `spec_trans`).
    Given(&'static str),
}

impl ParamKind {
    /// Whether the parameter may be given as a texture.
    pub fn texture_allowed(self) -> bool {
        match self {
            ParamKind::Color(_) | ParamKind::Number(_) | ParamKind::ConductorEta => true,
            ParamKind::ConductorK | ParamKind::RoughnessV => true,
            ParamKind::Roughness { texture, .. } => texture,
            ParamKind::Float
            | ParamKind::Bool
            | ParamKind::Choice(_)
            | ParamKind::Ior(_)
            | ParamKind::Exclusive(_)
            | ParamKind::Given(_) => false,
        }
    }
}

/// One parameter of a plugin's table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamSpec {
    pub name: &'static str,
    pub kind: ParamKind,
    /// The value when the scene does not give the parameter (all three channels of a colour).
    pub default: f64,
    /// The values a constant may take (inclusive); a value outside is an error naming it.
    /// A texture's values are not checked.
    pub min: f64,
    pub max: f64,
    /// What the parameter does, for the documentation.
    pub doc: &'static str,
}

impl ParamSpec {
    /// A parameter with any value allowed (`min`, `max` infinite; see [`ParamSpec::range`]).
    pub const fn new(name: &'static str, kind: ParamKind, default: f64, doc: &'static str) -> Self {
        ParamSpec {
            name,
            kind,
            default,
            min: f64::NEG_INFINITY,
            max: f64::INFINITY,
            doc,
        }
    }

    /// The parameter with its constants limited to [min, max].
    pub const fn range(self, min: f64, max: f64) -> Self {
        ParamSpec { min, max, ..self }
    }

    /// Whether the parameter is one value (looked up with `eval_1`; a constant's scalar).
    pub fn is_scalar(&self) -> bool {
        !matches!(
            self.kind,
            ParamKind::Color(_) | ParamKind::ConductorEta | ParamKind::ConductorK
        )
    }
}

/// A leaf BSDF model: directions in the local shading frame, in Mitsuba's conventions (see
/// the module `bsdf`).
pub trait BsdfModel {
    /// The plugin's name in scene files (`type="..."`).
    const NAME: &'static str;
    /// f(wi, wo) |cos θo|.
    fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum;
    /// Solid-angle density with which `sample` produces `wo`.
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32;
    /// Samples an outgoing direction; `u1` picks a lobe, `u2` the direction.
    fn sample(&self, wi: Vec3, u1: f32, u2: Vec2) -> Option<BsdfSample>;
    /// Whether the BSDF has a non-delta lobe on the side `wi` lies on (emitter sampling
    /// makes sense only then). One-sided reflectors: the front side.
    fn has_smooth_lobe(&self, wi: Vec3) -> bool {
        wi.z > 0.0
    }
    /// Whether the BSDF can transmit light to the other side.
    fn is_transmissive(&self) -> bool {
        false
    }
    /// Sets parameter `index` of the plugin's table to a value looked up from a texture at
    /// the shading point.
    fn set_param(&mut self, index: usize, v: Spectrum) {
        let _ = (index, v);
    }
    /// Called once after the textured parameters of a shading point are set: a model whose
    /// derived quantities depend on its parameters (principled's lobe weights) makes them
    /// anew here.
    fn params_set(&mut self) {}
}

/// A BSDF plugin described by its parameter table.
pub trait TablePlugin: BsdfModel + Sized {
    /// The parameters, in the order [`TablePlugin::from_params`] receives their values.
    const PARAMS: &'static [ParamSpec];
    /// The BSDF from its parameters' values in table order (a number splatted to three
    /// channels; a plain number, choice, flag or IOR exactly as the scene gave it; a
    /// textured parameter at its texture's mean, as Mitsuba derives sampling weights from
    /// means). `cache` keeps what is costly to compute across the BSDFs of a scene.
    fn from_params(values: &[DVec3], cache: &mut PluginCache) -> Self;
    /// A check across parameters, on the scene's constant values in table order (`None` for
    /// a textured one; a number in all three channels): the reason a combination is refused.
    fn check(values: &[Option<DVec3>]) -> Result<(), String> {
        let _ = values;
        Ok(())
    }
}

/// What the scene description and builder need of a table plugin, without its type.
#[derive(Clone, Copy, Debug)]
pub struct PluginInfo {
    pub name: &'static str,
    pub params: &'static [ParamSpec],
    pub check: fn(&[Option<DVec3>]) -> Result<(), String>,
    pub build: fn(&[DVec3], &mut PluginCache) -> super::Bsdf,
}

/// What plugins keep while one scene's BSDFs are built (roughplastic's coating tables, by
/// distribution and η): one value of each type, made on first use.
#[derive(Default)]
pub struct PluginCache(Vec<Box<dyn std::any::Any>>);

impl PluginCache {
    /// The cache's `T`, made with `T::default()` on first use.
    pub fn get<T: Default + 'static>(&mut self) -> &mut T {
        let i = match self.0.iter().position(|b| b.is::<T>()) {
            Some(i) => i,
            None => {
                self.0.push(Box::new(T::default()));
                self.0.len() - 1
            }
        };
        self.0[i]
            .downcast_mut::<T>()
            .expect("the entry found for T holds a T")
    }
}

/// The table plugin named `name`.
pub fn table_plugin(name: &str) -> Option<&'static PluginInfo> {
    super::TABLE_PLUGINS.iter().find(|p| p.name == name)
}

/// How a parameter of this kind is written in a scene file, for the documentation.
fn kind_text(kind: ParamKind) -> String {
    match kind {
        ParamKind::Color(ColorRole::Reflectance) => "colour or texture".into(),
        ParamKind::Color(_) => "colour or texture (unbounded)".into(),
        ParamKind::Number(_) | ParamKind::RoughnessV => "number or texture".into(),
        ParamKind::Exclusive(other) => format!("number (not with `{other}`)"),
        ParamKind::Given(_) => "—".into(),
        ParamKind::Float => "number".into(),
        ParamKind::Bool => "boolean".into(),
        ParamKind::Choice(names) => names.join(" \\| "),
        ParamKind::Ior(_) => "number or IOR name".into(),
        ParamKind::Roughness { texture: true, .. } => "number or texture".into(),
        ParamKind::Roughness { texture: false, .. } => "number".into(),
        ParamKind::ConductorEta | ParamKind::ConductorK => "colour or texture (unbounded)".into(),
    }
}

/// The parameter's default as a scene file would give it.
fn default_text(spec: &ParamSpec) -> String {
    match spec.kind {
        ParamKind::Bool => (spec.default != 0.0).to_string(),
        ParamKind::Choice(names) => names
            .get(spec.default as usize)
            .copied()
            .unwrap_or("?")
            .to_string(),
        ParamKind::Ior(preset) => format!("{preset} ({})", spec.default),
        ParamKind::Exclusive(_) => "none".into(),
        _ => spec.default.to_string(),
    }
}

/// The values a constant may take.
fn range_text(spec: &ParamSpec) -> String {
    match (spec.kind, spec.min, spec.max) {
        (ParamKind::Ior(_), ..) => "> 0".into(),
        (ParamKind::Exclusive(_), ..) => "> 0".into(),
        (ParamKind::Bool | ParamKind::Choice(_), ..) => String::new(),
        (_, lo, hi) if lo == f64::NEG_INFINITY && hi == f64::INFINITY => String::new(),
        (_, lo, hi) if hi == f64::INFINITY => format!("≥ {lo}"),
        (_, lo, hi) => format!("[{lo}, {hi}]"),
    }
}

/// The parameter tables of the leaf BSDF plugins as Markdown, generated from their
/// [`TablePlugin::PARAMS`] (`penumbra plugins` prints it; docs/bsdfs.md is its output).
pub fn markdown() -> String {
    let mut s = String::from(
        "# BSDF plugins and their parameters\n\n\
         Generated from the plugins' parameter tables (`src/bsdf/`) by `penumbra plugins`;\n\
         `tests/plugin_docs.rs` checks that this file is its output. A parameter not given\n\
         takes its default; a constant outside its range is refused with one line naming it.\n\
         `alpha` sets both `alpha_u` and `alpha_v`; a conductor's `material` (a named metal,\n\
         default `none`) gives `eta` and `k` instead.\n",
    );
    for p in super::TABLE_PLUGINS {
        s.push_str(&format!(
            "\n## `{}`\n\n| parameter | kind | default | range | what it is |\n|---|---|---|---|---|\n",
            p.name
        ));
        for spec in p
            .params
            .iter()
            .filter(|s| !matches!(s.kind, ParamKind::Given(_)))
        {
            s.push_str(&format!(
                "| `{}` | {} | {} | {} | {} |\n",
                spec.name,
                kind_text(spec.kind),
                default_text(spec),
                range_text(spec),
                spec.doc
            ));
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every table is well formed: names unique within a plugin, each pair's second entry
    /// right after its first, the documented IOR defaults the presets' values.
    #[test]
    fn tables_are_well_formed() {
        let mut names: Vec<&str> = super::super::TABLE_PLUGINS.iter().map(|p| p.name).collect();
        names.sort();
        let n = names.len();
        names.dedup();
        assert_eq!(names.len(), n, "plugin names are unique");
        assert!(n >= 9, "{names:?}");
        for p in super::super::TABLE_PLUGINS {
            for (i, spec) in p.params.iter().enumerate() {
                assert!(
                    !p.params[..i].iter().any(|s| s.name == spec.name),
                    "{}: {} twice",
                    p.name,
                    spec.name
                );
                let before = i.checked_sub(1).map(|j| p.params[j].kind);
                match spec.kind {
                    ParamKind::RoughnessV => assert!(
                        matches!(
                            before,
                            Some(ParamKind::Roughness {
                                anisotropic: true,
                                ..
                            })
                        ),
                        "{}: {}",
                        p.name,
                        spec.name
                    ),
                    ParamKind::ConductorK => assert_eq!(
                        before,
                        Some(ParamKind::ConductorEta),
                        "{}: {}",
                        p.name,
                        spec.name
                    ),
                    ParamKind::Ior(preset) => assert_eq!(
                        crate::bsdf::presets::ior(preset),
                        Some(spec.default as f32),
                        "{}: {}",
                        p.name,
                        spec.name
                    ),
                    _ => {}
                }
                assert!(spec.min <= spec.max && !spec.doc.is_empty());
            }
        }
    }

    /// `set_param(i, x)` on a BSDF built with the defaults gives the BSDF built with x as
    /// parameter i (what the material layer relies on for textured parameters): a wrong
    /// index in a plugin's `set_param` fails here. Compared by eval over a few direction
    /// pairs, and by the sampled weights for BSDFs made of delta lobes (eval 0).
    #[test]
    fn set_param_matches_the_table() {
        use super::super::BsdfParam;
        let dirs = [
            (Vec3::new(0.3, 0.2, 0.93), Vec3::new(-0.4, 0.1, 0.91)),
            (Vec3::new(0.6, -0.3, 0.74), Vec3::new(-0.5, 0.4, 0.77)),
            (Vec3::new(0.1, 0.5, 0.86), Vec3::new(-0.2, -0.3, -0.93)),
        ];
        let mut checked = 0;
        for info in super::super::TABLE_PLUGINS {
            let defaults: Vec<DVec3> = info
                .params
                .iter()
                .map(|s| DVec3::splat(s.default))
                .collect();
            for (i, spec) in info.params.iter().enumerate() {
                if !spec.kind.texture_allowed() {
                    continue;
                }
                let x = if spec.is_scalar() {
                    DVec3::splat(0.35)
                } else {
                    DVec3::new(0.3, 0.6, 0.9) * 0.5
                };
                let mut values = defaults.clone();
                values[i] = x;
                let mut cache = PluginCache::default();
                let want = (info.build)(&values, &mut cache);
                let mut got = (info.build)(&defaults, &mut cache);
                let slot = if spec.is_scalar() {
                    BsdfParam::TableScalar(i as u8)
                } else {
                    BsdfParam::TableColor(i as u8)
                };
                got.set_param(slot, crate::spectrum::from_rgb_f64(x));
                got.params_set();
                let mut nonzero = false;
                for (a, b) in dirs {
                    let (wi, wo) = (a.normalize(), b.normalize());
                    let (e_want, e_got) = (want.eval(wi, wo), got.eval(wi, wo));
                    nonzero |= e_want != Spectrum::ZERO;
                    assert_eq!(e_want, e_got, "{} {}: eval", info.name, spec.name);
                }
                if !nonzero {
                    for (a, _) in dirs {
                        let wi = a.normalize();
                        for u1 in [0.1, 0.9] {
                            let s = |b: &super::super::Bsdf| {
                                b.sample(wi, u1, Vec2::new(0.3, 0.7)).map(|s| s.weight)
                            };
                            assert_eq!(s(&want), s(&got), "{} {}: sample", info.name, spec.name);
                        }
                    }
                }
                checked += 1;
            }
        }
        assert!(checked >= 44, "{checked} parameters checked");
    }
}
