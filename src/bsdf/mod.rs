//! BSDFs in Mitsuba 3's conventions: directions in the local shading frame (z = normal),
//! `wi` points to where the light goes (towards the camera along the path), `wo` to where it
//! comes from; `eval` includes the cosine foreshortening |cos θo|, and `sample` returns the
//! weight eval / pdf. Closed set of models, dispatched by `match`.

pub mod conductor;
pub mod dielectric;
pub mod diffuse;
pub mod fresnel;
pub mod microfacet;
pub mod phong;
pub mod plastic;
pub mod plugin;
pub mod presets;
pub mod principled;
pub mod principledthin;
pub mod roughconductor;
pub mod roughdielectric;
pub mod roughplastic;
pub mod thindielectric;

pub use conductor::Conductor;
pub use dielectric::Dielectric;
pub use diffuse::Diffuse;
pub use microfacet::{Microfacet, MicrofacetType};
pub use phong::Phong;
pub use plastic::Plastic;
pub use plugin::{
    table_plugin, BsdfModel, ParamKind, ParamSpec, PluginCache, PluginInfo, TablePlugin,
};
pub use principled::{Principled, PrincipledParams};
pub use principledthin::{PrincipledThin, PrincipledThinParams};
pub use roughconductor::RoughConductor;
pub use roughdielectric::RoughDielectric;
pub use roughplastic::RoughPlastic;
pub use thindielectric::ThinDielectric;

use arrayvec::ArrayVec;
use glam::{Vec2, Vec3};

pub use crate::spectrum::Spectrum;

/// A direction sampled from a BSDF.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    /// Sampled direction (local frame).
    pub wo: Vec3,
    /// Solid-angle density of `wo` (meaningless for delta lobes).
    pub pdf: f32,
    /// eval(wi, wo) / pdf.
    pub weight: Spectrum,
    /// Relative index of refraction along the sampled direction (1 for reflection).
    pub eta: f32,
    /// The sampled lobe is a Dirac delta.
    pub delta: bool,
    /// The sampled lobe is Mitsuba's `Null` one: light passes straight through (`wo = −wi`),
    /// as through a `null` BSDF, a mask's holes or a thin dielectric's transmission. Volumetric
    /// path tracers do not count it as a scattering event.
    pub null: bool,
}

impl BsdfSample {
    /// A sample of a non-delta lobe: direction `wo` drawn with solid-angle density `pdf`, where
    /// the BSDF is `f`. `None` unless the density is positive and finite and the weight
    /// f / pdf is finite.
    #[inline]
    pub fn smooth(wo: Vec3, pdf: f32, f: impl FnOnce() -> Spectrum, eta: f32) -> Option<Self> {
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        let weight = f() / pdf;
        weight.is_finite().then_some(BsdfSample {
            wo,
            pdf,
            weight,
            eta,
            delta: false,
            null: false,
        })
    }
}

/// Declares the leaf BSDFs: the [`Bsdf`] enum, its dispatch to each model's [`BsdfModel`]
/// methods, and [`TABLE_PLUGINS`], the plugins the scene reads through their parameter table.
macro_rules! bsdfs {
    (
        table: [$($t:ident($tt:ty)),* $(,)?] $(,)?
    ) => {
        /// Variants are stored inline, the largest (roughplastic with its 64-entry albedo
        /// table) included: a BSDF is copied into the shading point's tree, which must not
        /// allocate.
        #[allow(clippy::large_enum_variant)]
        #[derive(Clone, Debug)]
        pub enum Bsdf {
            $($t($tt),)*
        }

        /// The leaf BSDF plugins described by their parameter table.
        pub static TABLE_PLUGINS: &[PluginInfo] = &[$(PluginInfo {
            name: <$tt as BsdfModel>::NAME,
            params: <$tt as TablePlugin>::PARAMS,
            check: <$tt as TablePlugin>::check,
            build: |v, cache| Bsdf::$t(<$tt as TablePlugin>::from_params(v, cache)),
        }),*];

        impl Bsdf {
            /// f(wi, wo) |cos θo|.
            pub fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
                match self {
                    $(Bsdf::$t(b) => BsdfModel::eval(b, wi, wo),)*
                }
            }

            /// Solid-angle density with which `sample` produces `wo`.
            pub fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
                match self {
                    $(Bsdf::$t(b) => BsdfModel::pdf(b, wi, wo),)*
                }
            }

            /// Samples an outgoing direction; `u1` picks a lobe, `u2` the direction.
            pub fn sample(&self, wi: Vec3, u1: f32, u2: Vec2) -> Option<BsdfSample> {
                match self {
                    $(Bsdf::$t(b) => BsdfModel::sample(b, wi, u1, u2),)*
                }
            }

            /// Whether the BSDF has a non-delta lobe on the side `wi` lies on: only then does
            /// emitter sampling (NEE) make sense. (A one-sided BSDF seen from behind has
            /// nothing.)
            pub fn has_smooth_lobe(&self, wi: Vec3) -> bool {
                match self {
                    $(Bsdf::$t(b) => BsdfModel::has_smooth_lobe(b, wi),)*
                }
            }

            /// Whether the BSDF can transmit light to the other side (then reciprocity of
            /// `eval` does not hold in radiance mode, and albedos count transmission too).
            pub fn is_transmissive(&self) -> bool {
                match self {
                    $(Bsdf::$t(b) => BsdfModel::is_transmissive(b),)*
                }
            }

            /// The plugin's name in scene files.
            pub fn plugin_name(&self) -> &'static str {
                match self {
                    $(Bsdf::$t(_) => <$tt as BsdfModel>::NAME,)*
                }
            }

            /// Sets parameter `index` of a table plugin's table.
            #[inline]
            fn set_table_param(&mut self, index: usize, v: Spectrum) {
                match self {
                    $(Bsdf::$t(b) => BsdfModel::set_param(b, index, v),)*
                }
            }

            /// Called once after the textured parameters of a shading point are set (see
            /// [`BsdfModel::params_set`]).
            #[inline]
            pub fn params_set(&mut self) {
                match self {
                    $(Bsdf::$t(b) => BsdfModel::params_set(b),)*
                }
            }
        }
    };
}

// The leaf BSDFs. A new one is its file (a `TablePlugin`) and one line here.
bsdfs! {
    table: [
        Diffuse(Diffuse),
        Conductor(Conductor),
        RoughConductor(RoughConductor),
        Dielectric(Dielectric),
        ThinDielectric(ThinDielectric),
        RoughDielectric(RoughDielectric),
        Plastic(Plastic),
        RoughPlastic(RoughPlastic),
        Phong(Phong),
        Principled(Principled),
        PrincipledThin(PrincipledThin),
    ],
}

impl Bsdf {
    /// The factor that turns this BSDF's radiance-mode value for (wi, wo) into its
    /// importance-mode one: η_it² where light refracts through an interface of relative IOR
    /// η (η_it = η seen from the outside, 1/η from the inside), since radiance-mode
    /// refraction carries the 1/η_it² of radiance's solid-angle compression (Veach 1997,
    /// §5.2) and importance does not; 1 for reflection and for BSDFs that do not refract.
    /// Capped at `f32::MAX`: at an extreme IOR (η = 1e20, or 1e-20) η² or 1/η² overflows, and
    /// ∞ times a zero transmission would be NaN.
    pub fn importance_scale(&self, wi: Vec3, wo: Vec3) -> f32 {
        let eta = match self {
            Bsdf::Dielectric(b) => b.eta,
            Bsdf::RoughDielectric(b) => b.eta,
            Bsdf::Principled(b) if b.bsdf > 0.0 => b.eta,
            _ => return 1.0,
        };
        if wi.z * wo.z >= 0.0 {
            1.0
        } else if wi.z > 0.0 {
            (eta * eta).min(f32::MAX)
        } else {
            (1.0 / (eta * eta)).min(f32::MAX)
        }
    }

    /// Every outcome of `sample` with its probability as `pdf`, for the BSDFs made of two
    /// Dirac-delta lobes picked at random (`dielectric`, `thindielectric`); `None` for the
    /// others. Radiance mode.
    pub fn delta_branches(&self, wi: Vec3) -> Option<ArrayVec<BsdfSample, 2>> {
        match self {
            Bsdf::Dielectric(b) => Some(b.branches(wi)),
            Bsdf::ThinDielectric(b) => Some(b.branches(wi)),
            _ => None,
        }
    }

    /// The fraction of light that passes straight through the surface from `wi` (Mitsuba's
    /// `eval_null_transmission`): what a shadow ray of a volumetric path tracer carries
    /// across it. Only the thin dielectric's transmission is such a `Null` lobe here.
    #[inline]
    pub fn null_transmission(&self, wi: Vec3) -> Spectrum {
        match self {
            Bsdf::ThinDielectric(b) => b.null_transmission(wi),
            _ => Spectrum::ZERO,
        }
    }

    /// Sets one parameter to a value looked up from a texture at the shading point (the
    /// material layer builds a BSDF once with its constant parameters and patches the
    /// textured ones per shading point). A parameter the BSDF does not have is ignored (the
    /// scene builder only pairs parameters with the BSDFs that take them).
    #[inline]
    pub fn set_param(&mut self, param: BsdfParam, v: Spectrum) {
        let (BsdfParam::TableColor(i) | BsdfParam::TableScalar(i)) = param;
        self.set_table_param(i as usize, v);
    }
}

/// A BSDF parameter that a texture can drive (Mitsuba's `get_texture` parameters). Scalar
/// parameters (roughness) take the texture's `eval_1`, colours its `eval`; see
/// [`BsdfParam::is_scalar`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BsdfParam {
    /// Colour parameter `i` of a table plugin's table ([`TABLE_PLUGINS`]).
    TableColor(u8),
    /// One-value parameter `i` of a table plugin's table.
    TableScalar(u8),
}

impl BsdfParam {
    /// Whether the parameter is one value (looked up with `eval_1`).
    pub fn is_scalar(self) -> bool {
        matches!(self, BsdfParam::TableScalar(_))
    }
}
