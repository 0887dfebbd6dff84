//! Mitsuba's `diffuse`: the Lambertian reflector f = R / π, one-sided (front side of the
//! shading frame only; wrap it in `twosided` for both sides), sampled with a cosine-weighted
//! hemisphere (Malley's method).

use super::plugin::{ParamKind, ParamSpec, PluginCache, TablePlugin};
use super::{BsdfSample, Spectrum};
use crate::sampling::{square_to_cosine_hemisphere_lanes, square_to_cosine_hemisphere_pdf_lanes};
use crate::simd::{LaneF32, Lanes, Scalar, V3, V4};
use crate::spectrum::ColorRole;
use glam::DVec3;
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// `diffuse`'s parameters (Mitsuba 3.9.1's names and defaults).
const PARAMS: &[ParamSpec] = &[ParamSpec::new(
    "reflectance",
    ParamKind::Color(ColorRole::Reflectance),
    0.5,
    "R, the albedo",
)];

#[derive(Clone, Debug)]
pub struct Diffuse {
    pub reflectance: Spectrum,
}

impl Diffuse {
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        eval_lanes(Scalar, self.reflectance.into(), wi.z, wo.z).lane(0)
    }

    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        pdf_lanes(Scalar, wi.z, wo.z)
    }

    pub fn sample(&self, wi: Vec3, u: Vec2) -> Option<BsdfSample> {
        let (ok, wo, pdf) = sample_lanes(Scalar, wi.z, (u.x, u.y));
        ok.then(|| BsdfSample {
            wo: wo.lane(0),
            pdf,
            weight: self.reflectance,
            eta: 1.0,
            delta: false,
            null: false,
        })
    }
}

/// The lanes whose BSDF is a `diffuse`, alone or under a `twosided` (whose rule is
/// `crate::material::twosided`'s: where wi lies below the surface, both directions are
/// mirrored through the tangent plane and the back BSDF answers), for the lane engine.
#[derive(Clone, Copy, Debug)]
pub struct DiffuseLanes<L: Lanes> {
    /// The lanes with a diffuse BSDF.
    pub m: L::M,
    /// Those under a `twosided`.
    pub two_sided: L::M,
    pub front: V4<L::F>,
    pub back: V4<L::F>,
}

impl<L: Lanes> DiffuseLanes<L> {
    /// No lane.
    #[inline(always)]
    pub fn none(l: L) -> Self {
        let zero = V4::splat(l.splat(0.0));
        DiffuseLanes {
            m: l.mask(0),
            two_sided: l.mask(0),
            front: zero,
            back: zero,
        }
    }

    /// Lanes flipped to the back (two-sided, wi below the surface), wi's z mirrored where
    /// flipped, and the reflectances that answer.
    #[inline(always)]
    fn side(&self, l: L, wi_z: L::F) -> (L::M, L::F, V4<L::F>) {
        let flip = self.two_sided & wi_z.cmp_lt(l.splat(0.0));
        (
            flip,
            L::F::select(flip, -wi_z, wi_z),
            V4::select(flip, self.back, self.front),
        )
    }

    /// f(wi, wo) |cos θo| (the directions' z in the shading frame).
    #[inline(always)]
    pub fn eval(&self, l: L, wi_z: L::F, wo_z: L::F) -> V4<L::F> {
        let (flip, wi_z, r) = self.side(l, wi_z);
        eval_lanes(l, r, wi_z, L::F::select(flip, -wo_z, wo_z))
    }

    /// The density of [`DiffuseLanes::sample`] (solid angle).
    #[inline(always)]
    pub fn pdf(&self, l: L, wi_z: L::F, wo_z: L::F) -> L::F {
        let (flip, wi_z, _) = self.side(l, wi_z);
        pdf_lanes(l, wi_z, L::F::select(flip, -wo_z, wo_z))
    }

    /// Cosine-weighted sampling from `u`, in the lanes of `self.m` whose wi lies on a side
    /// with the BSDF.
    #[inline(always)]
    pub fn sample(&self, l: L, wi_z: L::F, u: (L::F, L::F)) -> DiffuseSampleLanes<L> {
        let (flip, wi_z, r) = self.side(l, wi_z);
        let (ok, mut wo, pdf) = sample_lanes(l, wi_z, u);
        wo.z = L::F::select(flip, -wo.z, wo.z);
        DiffuseSampleLanes {
            ok: ok & self.m,
            wo,
            pdf,
            weight: r,
        }
    }
}

/// What [`DiffuseLanes::sample`] gives.
#[derive(Clone, Copy, Debug)]
pub struct DiffuseSampleLanes<L: Lanes> {
    /// The lanes with a direction.
    pub ok: L::M,
    pub wo: V3<L::F>,
    /// Solid-angle density.
    pub pdf: L::F,
    /// f |cos θo| / pdf: the reflectance.
    pub weight: V4<L::F>,
}

/// f(wi, wo) |cos θo| in lanes, of reflectances `r` and the directions' z in the shading
/// frame: R/π · cos θo where both directions lie above the surface, else 0. The lane engine
/// runs it for every lane whose BSDF is a `diffuse` ([`Diffuse::eval`] is its width-1
/// instance).
#[inline(always)]
pub fn eval_lanes<L: Lanes>(l: L, r: V4<L::F>, wi_z: L::F, wo_z: L::F) -> V4<L::F> {
    let zero = l.splat(0.0);
    let above = !(wi_z.cmp_le(zero) | wo_z.cmp_le(zero));
    V4::select(above, r * (l.splat(FRAC_1_PI) * wo_z), V4::splat(zero))
}

/// The density of [`sample_lanes`] in lanes (solid angle), of the directions' z.
#[inline(always)]
pub fn pdf_lanes<L: Lanes>(l: L, wi_z: L::F, wo_z: L::F) -> L::F {
    let zero = l.splat(0.0);
    let p = square_to_cosine_hemisphere_pdf_lanes(l, wo_z);
    L::F::select(wi_z.cmp_le(zero), zero, p)
}

/// Cosine-weighted sampling in lanes, from `u` (the BSDF's 2D sample): the lanes with a
/// direction (wi above the surface, density above 0), the directions and their densities.
/// The weight f |cos θo| / pdf is the reflectance.
#[inline(always)]
pub fn sample_lanes<L: Lanes>(l: L, wi_z: L::F, u: (L::F, L::F)) -> (L::M, V3<L::F>, L::F) {
    let zero = l.splat(0.0);
    let wo = square_to_cosine_hemisphere_lanes(l, u);
    let pdf = square_to_cosine_hemisphere_pdf_lanes(l, wo.z);
    (!wi_z.cmp_le(zero) & pdf.cmp_gt(zero), wo, pdf)
}

impl TablePlugin for Diffuse {
    const PARAMS: &'static [ParamSpec] = PARAMS;

    fn from_params(v: &[DVec3], _: &mut PluginCache) -> Self {
        Diffuse {
            reflectance: crate::spectrum::from_rgb_f64(v[0]),
        }
    }
}

impl super::BsdfModel for Diffuse {
    const NAME: &'static str = "diffuse";

    fn set_param(&mut self, index: usize, v: Spectrum) {
        if index == 0 {
            self.reflectance = v;
        }
    }

    #[inline]
    fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        Diffuse::eval(self, wi, wo)
    }

    #[inline]
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        Diffuse::pdf(self, wi, wo)
    }

    #[inline]
    fn sample(&self, wi: Vec3, _u1: f32, u2: Vec2) -> Option<BsdfSample> {
        Diffuse::sample(self, wi, u2)
    }

    #[inline]
    fn has_smooth_lobe(&self, _wi: Vec3) -> bool {
        true
    }
}
