//! Participating media (Mitsuba's `medium` plugins): what happens to light between surfaces
//! inside smoke, fog, skin or milk. One file per plugin; this module holds the interface the
//! volumetric integrators use, after Mitsuba 3's `Medium` (`src/render/medium.cpp`):
//!
//! - [`Medium::sample_interaction`] draws a tentative collision distance along a ray with
//!   density m_c · exp(−m_c t), m the *majorant* (combined extinction) and c one RGB channel
//!   chosen per path in RGB mode, the path's first wavelength in spectral mode (Mitsuba's
//!   `*_spectral` variants: the other three are weighed by their transmittance over its
//!   free-flight density); at the collision it reports σs, σt and the null (fictitious)
//!   extinction σn = m − σt, per [`Spectrum`] lane;
//! - [`Medium::transmittance_eval_pdf`] gives the majorant transmittance over the sampled
//!   segment and its free-flight density, from which the integrator weighs the sample.
//!
//! A collision is real with probability mean(σt / m) over the mode's channels ([`mean`]: R, G,
//! B in RGB mode, the four wavelengths in spectral mode; the integrators' choice) and null
//! otherwise: delta tracking (Woodcock et al. 1965) for paths, ratio tracking (Novák et al.
//! 2014, "Residual ratio tracking for estimating attenuation in participating media") for
//! shadow rays. Homogeneous media use σt itself as the majorant, so every collision is real.
//!
//! | plugin | file | parameters (Mitsuba's defaults) |
//! |---|---|---|
//! | `homogeneous` | [`homogeneous`] | `sigma_t` (1), `albedo` (0.75), `scale` (1), `sample_emitters` (true), a `<phase>` (isotropic) |
//! | `heterogeneous` | [`heterogeneous`] | the same, `sigma_t` and `albedo` volumes ([`crate::volume`]) |
//!
//! Media sit on shapes as `interior` / `exterior` (a ray leaving a surface along its normal
//! enters the exterior medium, against it the interior one, as Mitsuba's
//! `SurfaceInteraction::target_medium`) and on the sensor.

pub mod heterogeneous;
pub mod homogeneous;

pub use heterogeneous::Heterogeneous;
pub use homogeneous::Homogeneous;

use crate::geometry::Ray;
use crate::phase::PhaseFunction;
use crate::spectrum::{Mode, Spectrum};
use glam::{Vec3, Vec4};

#[derive(Clone, Debug)]
pub enum MediumKind {
    Homogeneous(Homogeneous),
    Heterogeneous(Heterogeneous),
}

/// A medium of the scene: its density model, phase function, and whether next-event
/// estimation is done at its scattering events.
#[derive(Clone, Debug)]
pub struct Medium {
    pub kind: MediumKind,
    pub phase: PhaseFunction,
    /// Mitsuba's `sample_emitters` (default true).
    pub sample_emitters: bool,
}

/// A tentative collision sampled in a medium (Mitsuba's `MediumInteraction`).
#[derive(Clone, Copy, Debug)]
pub struct MediumInteraction {
    /// Distance along the ray; infinite when no collision was sampled before `ray.tmax`.
    pub t: f32,
    pub p: Vec3,
    /// Direction back along the ray (−ray.d).
    pub wi: Vec3,
    /// Where the sampled segment starts (the medium's box entry, or 0).
    pub mint: f32,
    /// Where it ends: the box exit clipped to the ray's tmax (∞ in a homogeneous medium; 0
    /// when the ray misses the box). The majorant acts only on [mint, maxt].
    pub maxt: f32,
    pub sigma_s: Spectrum,
    pub sigma_n: Spectrum,
    pub sigma_t: Spectrum,
    /// The majorant m used to sample `t`.
    pub combined_extinction: Spectrum,
}

impl MediumInteraction {
    #[inline]
    pub fn is_valid(&self) -> bool {
        self.t < f32::INFINITY
    }

    /// Length of the sampled segment inside the medium's box, up to the collision or `end`
    /// (whichever comes first), never negative.
    #[inline]
    pub fn segment(&self, end: f32) -> f32 {
        (self.t.min(end).min(self.maxt) - self.mint).max(0.0)
    }
}

impl Medium {
    #[inline]
    pub fn is_homogeneous(&self) -> bool {
        matches!(self.kind, MediumKind::Homogeneous(_))
    }

    /// The ray's parameter interval where the medium can interact: (hit, t_min, t_max) with
    /// t_min possibly negative (Mitsuba's `intersect_aabb`).
    #[inline]
    fn intersect_aabb(&self, ray: &Ray) -> (bool, f32, f32) {
        match &self.kind {
            MediumKind::Homogeneous(_) => (true, 0.0, f32::INFINITY),
            MediumKind::Heterogeneous(h) => h.intersect_aabb(ray),
        }
    }

    /// Samples a tentative collision along `ray` (unit direction, up to `ray.tmax`) with the
    /// majorant of `channel` (a [`Spectrum`] lane), using the uniform number `u`, with the
    /// coefficients at the path's `wavelengths` (Mitsuba's `Medium::sample_interaction`).
    pub fn sample_interaction(
        &self,
        ray: &Ray,
        u: f32,
        channel: usize,
        wavelengths: Vec4,
    ) -> MediumInteraction {
        let (hit, mint, maxt) = self.intersect_aabb(ray);
        let active = hit && (mint.is_finite() || maxt.is_finite());
        let (mint, maxt) = if active {
            (mint.max(0.0), ray.tmax.min(maxt))
        } else {
            (0.0, f32::INFINITY)
        };
        let combined_extinction = match &self.kind {
            MediumKind::Homogeneous(h) if active => h.sigma_t(ray.o, wavelengths),
            MediumKind::Homogeneous(_) => Spectrum::ZERO,
            MediumKind::Heterogeneous(h) => Spectrum::splat(h.majorant),
        };
        let m = combined_extinction[channel];
        let sampled_t = mint + (-crate::math::lnf(1.0 - u) / m);
        let valid = active && sampled_t <= maxt;
        let maxt = if active { maxt } else { 0.0 };
        let p = ray.at(sampled_t);
        let (sigma_s, sigma_n, sigma_t) = if valid {
            match &self.kind {
                MediumKind::Homogeneous(h) => h.coefficients(p, wavelengths),
                MediumKind::Heterogeneous(h) => h.coefficients(p, wavelengths),
            }
        } else {
            (Spectrum::ZERO, Spectrum::ZERO, Spectrum::ZERO)
        };
        MediumInteraction {
            t: if valid { sampled_t } else { f32::INFINITY },
            p,
            wi: -ray.d,
            mint,
            maxt,
            sigma_s,
            sigma_n,
            sigma_t,
            combined_extinction,
        }
    }

    /// The majorant transmittance from `mi.mint` to the collision (or to the surface at
    /// distance `si_t` when that comes first) and the density of having sampled that
    /// (free-flight pdf: tr · m at a collision, tr when the surface came first), per channel
    /// (Mitsuba's `transmittance_eval_pdf`). The segment stops at the medium's box
    /// (`mi.maxt`), beyond which no distance is sampled: the same ratio tr/pdf as measuring
    /// to the surface, but exp(−m t) does not underflow to 0/0 along a long ray past a
    /// small, dense grid (docs/media.md).
    #[inline]
    pub fn transmittance_eval_pdf(mi: &MediumInteraction, si_t: f32) -> (Spectrum, Spectrum) {
        let t = mi.segment(si_t);
        let tr = transmittance(t, mi.combined_extinction);
        let pdf = if si_t < mi.t {
            tr
        } else {
            tr * mi.combined_extinction
        };
        (tr, pdf)
    }
}

/// The transmittance exp(−t σ) of a segment of length `t` per channel of extinction `sigma`,
/// with a zero extinction transmitting everything even over an infinite segment (where
/// t · σ is ∞ · 0 = NaN). Any other NaN (a NaN extinction or length) stays NaN, so the
/// sample is dropped and counted as non-finite, never turned into a transmittance.
#[inline]
pub fn transmittance(t: f32, sigma: Spectrum) -> Spectrum {
    let e = |s: f32| {
        if s == 0.0 {
            1.0
        } else {
            crate::math::expf(-t * s)
        }
    };
    Spectrum::new(e(sigma.x), e(sigma.y), e(sigma.z), e(sigma.w))
}

/// The mean over the channels of `mode`: R, G and B in RGB mode (lane 3, green's copy, left
/// out), the four wavelengths in spectral mode (Mitsuba's `dr::mean` over its `Spectrum`).
#[inline]
pub fn mean(v: Spectrum, mode: Mode) -> f32 {
    match mode {
        Mode::Rgb => (v.x + v.y + v.z) / 3.0,
        Mode::Spectral => (v.x + v.y + v.z + v.w) / 4.0,
    }
}

/// Component-wise a / b with 0 where b is 0 (σn / m for a zero majorant).
#[inline]
pub fn safe_div(a: Spectrum, b: Spectrum) -> Spectrum {
    let d = |a: f32, b: f32| if b != 0.0 { a / b } else { 0.0 };
    Spectrum::new(d(a.x, b.x), d(a.y, b.y), d(a.z, b.z), d(a.w, b.w))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// exp(−t σ) per channel; a zero extinction transmits everything, even over an infinite
    /// segment; a NaN extinction or length is NaN (dropped as a non-finite sample), never a
    /// transmittance of 1.
    #[test]
    fn transmittance_never_turns_nan_into_one() {
        let tr = transmittance(2.0, Vec4::new(0.5, 0.0, 1e30, 0.25));
        assert_eq!(tr, Vec4::new((-1.0f32).exp(), 1.0, 0.0, (-0.5f32).exp()));
        assert_eq!(transmittance(f32::INFINITY, Vec4::ZERO), Vec4::ONE);
        let nan = transmittance(1.0, Vec4::new(f32::NAN, 1.0, f32::NAN, 0.0));
        assert!(nan.x.is_nan() && nan.z.is_nan() && nan.y == (-1.0f32).exp() && nan.w == 1.0);
        assert!(transmittance(f32::NAN, Vec4::ONE).is_nan());
    }

    /// RGB mode averages R, G, B (never lane 3, green's copy); spectral mode all four.
    #[test]
    fn the_mean_runs_over_the_modes_channels() {
        let v = Vec4::new(1.0, 2.0, 6.0, 7.0);
        assert_eq!(mean(v, Mode::Rgb), 3.0);
        assert_eq!(mean(v, Mode::Spectral), 4.0);
        assert_eq!(
            safe_div(v, Vec4::new(2.0, 0.0, 3.0, 7.0)),
            Vec4::new(0.5, 0.0, 2.0, 1.0)
        );
    }
}
