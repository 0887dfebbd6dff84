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
    /// One value, texture allowed (Mitsuba's `get_texture` read with `eval_1`).
    Number,
    /// A plain number (Mitsuba's `get<float>`): no texture.
    Float,
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
    /// Whether the parameter is one value (looked up with `eval_1`; a constant's scalar).
    pub fn is_scalar(&self) -> bool {
        !matches!(self.kind, ParamKind::Color(_))
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
    /// the shading point (plugins without a table have no such parameters).
    fn set_param(&mut self, index: usize, v: Spectrum) {
        let _ = (index, v);
    }
}

/// A BSDF plugin described by its parameter table.
pub trait TablePlugin: BsdfModel + Sized {
    /// The parameters, in the order [`TablePlugin::from_params`] receives their values.
    const PARAMS: &'static [ParamSpec];
    /// The BSDF from its parameters' values in table order (a number splatted to three
    /// channels; a textured parameter at its texture's mean, as Mitsuba derives sampling
    /// weights from means).
    fn from_params(values: &[Spectrum]) -> Self;
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
    pub build: fn(&[Spectrum]) -> super::Bsdf,
}

/// The table plugin named `name`.
pub fn table_plugin(name: &str) -> Option<&'static PluginInfo> {
    super::TABLE_PLUGINS.iter().find(|p| p.name == name)
}
