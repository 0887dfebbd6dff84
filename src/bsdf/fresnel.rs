//! Fresnel equations, reflection and refraction, once for every BSDF.
//!
//! - Dielectric interfaces: the unpolarised Fresnel reflectance of a real relative index of
//!   refraction (Born and Wolf, "Principles of Optics", §1.5.2), with total internal
//!   reflection, in Mitsuba's sign conventions (`cos_theta_i` < 0 means the incident
//!   direction lies inside, the transmitted cosine has the opposite sign of the incident one).
//! - Conductors: the exact unpolarised reflectance of a complex index of refraction η + ik,
//!   evaluated with complex arithmetic in f64 (Born and Wolf §14.2).
//! - The hemispherical average of the dielectric reflectance (cosine weighted, "Fdr"), by
//!   numerical quadrature, for the internal-scattering terms of the plastic models.

use crate::spectrum::Spectrum;
use glam::Vec3;

/// Reflectance of a dielectric interface and the refraction geometry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DielectricFresnel {
    /// Unpolarised reflectance F ∈ [0, 1].
    pub f: f32,
    /// Cosine of the refracted direction, with the sign opposite to `cos_theta_i` (0 under
    /// total internal reflection).
    pub cos_theta_t: f32,
    /// Relative IOR η_t / η_i seen from the incident side.
    pub eta_it: f32,
    /// Its inverse η_i / η_t.
    pub eta_ti: f32,
}

/// Fresnel reflectance for a dielectric with relative IOR `eta` = η_inside / η_outside;
/// `cos_theta_i` is the signed cosine of the incident direction to the normal (negative:
/// incident from inside).
pub fn fresnel_dielectric(cos_theta_i: f32, eta: f32) -> DielectricFresnel {
    let outside = cos_theta_i >= 0.0;
    let (eta_it, eta_ti) = if outside {
        (eta, 1.0 / eta)
    } else {
        (1.0 / eta, eta)
    };
    let ci = cos_theta_i.abs().min(1.0) as f64;
    let eti = eta_ti as f64;
    // Snell: sin²θt = (η_i/η_t)² sin²θi.
    let cos_t_sqr = 1.0 - eti * eti * (1.0 - ci * ci);
    if cos_t_sqr <= 0.0 {
        return DielectricFresnel {
            f: 1.0,
            cos_theta_t: 0.0,
            eta_it,
            eta_ti,
        };
    }
    let ct = cos_t_sqr.sqrt();
    if eta == 1.0 {
        return DielectricFresnel {
            f: 0.0,
            cos_theta_t: -cos_theta_i,
            eta_it,
            eta_ti,
        };
    }
    let eit = eta_it as f64;
    // Amplitudes for s and p polarisation, written with the relative index.
    let rs = (ci - eit * ct) / (ci + eit * ct);
    let rp = (eit * ci - ct) / (eit * ci + ct);
    let f = 0.5 * (rs * rs + rp * rp);
    DielectricFresnel {
        f: f.clamp(0.0, 1.0) as f32,
        cos_theta_t: if outside { -ct as f32 } else { ct as f32 },
        eta_it,
        eta_ti,
    }
}

#[derive(Clone, Copy, Debug)]
struct Complex {
    re: f64,
    im: f64,
}

impl Complex {
    fn new(re: f64, im: f64) -> Self {
        Complex { re, im }
    }
    fn add(self, o: Complex) -> Complex {
        Complex::new(self.re + o.re, self.im + o.im)
    }
    fn sub(self, o: Complex) -> Complex {
        Complex::new(self.re - o.re, self.im - o.im)
    }
    fn mul(self, o: Complex) -> Complex {
        Complex::new(
            self.re * o.re - self.im * o.im,
            self.re * o.im + self.im * o.re,
        )
    }
    fn norm_sqr(self) -> f64 {
        self.re * self.re + self.im * self.im
    }
    /// The principal square root (non-negative real part).
    fn sqrt(self) -> Complex {
        let r = self.norm_sqr().sqrt();
        let re = (0.5 * (r + self.re)).max(0.0).sqrt();
        let im = (0.5 * (r - self.re)).max(0.0).sqrt();
        Complex::new(re, if self.im < 0.0 { -im } else { im })
    }
    /// |a / b|² without forming the quotient.
    fn ratio_norm_sqr(a: Complex, b: Complex) -> f64 {
        let d = b.norm_sqr();
        if d > 0.0 {
            a.norm_sqr() / d
        } else {
            1.0
        }
    }
}

/// Unpolarised reflectance of a conductor with complex relative IOR `eta + i k`, for the
/// cosine `cos_theta_i` ∈ [0, 1]. `eta = 0, k = 1` is a perfect mirror (F = 1 everywhere).
fn fresnel_conductor_1(cos_theta_i: f64, eta: f64, k: f64) -> f64 {
    let c = cos_theta_i.clamp(0.0, 1.0);
    let n = Complex::new(eta, k);
    let n2 = n.mul(n);
    let sin2 = 1.0 - c * c;
    // n cos θt = sqrt(n² − sin²θi)
    let n_cos_t = n2.sub(Complex::new(sin2, 0.0)).sqrt();
    let ci = Complex::new(c, 0.0);
    // r_s = (cos θi − n cos θt) / (cos θi + n cos θt)
    let rs = Complex::ratio_norm_sqr(ci.sub(n_cos_t), ci.add(n_cos_t));
    // r_p = (n² cos θi − n cos θt) / (n² cos θi + n cos θt)
    let n2c = n2.mul(ci);
    let rp = Complex::ratio_norm_sqr(n2c.sub(n_cos_t), n2c.add(n_cos_t));
    (0.5 * (rs + rp)).clamp(0.0, 1.0)
}

/// Per-lane conductor reflectance for a complex IOR given per lane.
pub fn fresnel_conductor(cos_theta_i: f32, eta: Spectrum, k: Spectrum) -> Spectrum {
    let c = cos_theta_i as f64;
    let (eta, k) = (eta.to_array(), k.to_array());
    Spectrum::from_array(std::array::from_fn(|i| {
        fresnel_conductor_1(c, eta[i] as f64, k[i] as f64) as f32
    }))
}

/// Mirror reflection of `wi` about the normal `m`.
#[inline]
pub fn reflect(wi: Vec3, m: Vec3) -> Vec3 {
    2.0 * wi.dot(m) * m - wi
}

/// Refraction of `wi` through the microsurface normal `m`, given the transmitted cosine and
/// η_i / η_t from [`fresnel_dielectric`] evaluated at `wi · m`.
#[inline]
pub fn refract(wi: Vec3, m: Vec3, cos_theta_t: f32, eta_ti: f32) -> Vec3 {
    m * (wi.dot(m) * eta_ti + cos_theta_t) - wi * eta_ti
}

/// Cosine-weighted hemispherical average of the dielectric Fresnel reflectance,
/// Fdr(η) = 2 ∫₀¹ F(μ, η) μ dμ, for light arriving from the side where the relative IOR is
/// `eta` (η < 1: from inside a denser medium). Composite Simpson rule on 4096 intervals in
/// μ², which is smooth except at the critical angle; accurate to ~1e-6.
pub fn diffuse_fresnel_reflectance(eta: f64) -> f64 {
    // With s = μ², 2 μ dμ = ds.
    let f = |s: f64| fresnel_dielectric(s.sqrt() as f32, eta as f32).f as f64;
    crate::math::simpson(f, 0.0, 1.0, 4096)
}

/// Fdr(η) by the published fits Mitsuba's `plastic` uses (its `fresnel_diffuse_reflectance`):
/// Egan and Hilgeman 1973 for η < 1, d'Eon and Irving 2011 (a quintic in 1/η) for η ≥ 1.
/// Within 0.1% of [`diffuse_fresnel_reflectance`] for 1 ≤ η ≤ 2 and 0.6% for 1/2 ≤ η < 1
/// (the papers' bounds): penumbra uses them where Mitsuba does, so that both render the same.
pub fn diffuse_fresnel_reflectance_fit(eta: f64) -> f64 {
    if eta < 1.0 {
        -1.4399 * eta * eta + 0.7099 * eta + 0.6681 + 0.0636 / eta
    } else {
        let x = 1.0 / eta;
        0.919317 + x * (-3.4793 + x * (6.75335 + x * (-7.80989 + x * (4.98554 - 1.36881 * x))))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diffuse_fresnel_fits_are_within_their_published_accuracy() {
        // Relative error where Fdr is not near 0 (η = 1), absolute 3e-4 everywhere.
        for i in 0..=40 {
            let eta = 1.0 + i as f64 / 40.0;
            let (fit, exact) = (
                diffuse_fresnel_reflectance_fit(eta),
                diffuse_fresnel_reflectance(eta),
            );
            assert!(
                (fit - exact).abs() <= (1e-3 * exact).max(3e-4),
                "η {eta}: {fit} vs {exact}"
            );
            let eta = 1.0 / eta;
            let (fit, exact) = (
                diffuse_fresnel_reflectance_fit(eta),
                diffuse_fresnel_reflectance(eta),
            );
            assert!(
                (fit - exact).abs() <= (6e-3 * exact).max(3e-4),
                "η {eta}: {fit} vs {exact}"
            );
        }
    }

    #[test]
    fn dielectric_known_values() {
        // Normal incidence: ((η − 1)/(η + 1))².
        let r = fresnel_dielectric(1.0, 1.5);
        assert!((r.f - 0.04).abs() < 1e-6);
        assert_eq!(r.cos_theta_t, -1.0);
        // From inside beyond the critical angle (sin θc = 1/1.5): total internal reflection.
        let tir = fresnel_dielectric(-0.5, 1.5);
        assert_eq!((tir.f, tir.cos_theta_t), (1.0, 0.0));
        // Reciprocity of F across the interface: F(θi, η) = F(θt, 1/η).
        let a = fresnel_dielectric(0.7, 1.33);
        let b = fresnel_dielectric(a.cos_theta_t, 1.33);
        assert!((a.f - b.f).abs() < 1e-6);
        assert!((b.cos_theta_t - 0.7).abs() < 1e-6);
        // η = 1: no interface.
        assert_eq!(fresnel_dielectric(0.3, 1.0).f, 0.0);
        // Grazing: F → 1.
        assert!(fresnel_dielectric(1e-7, 1.5).f > 0.9999);
    }

    #[test]
    fn conductor_known_values() {
        // Ideal mirror.
        for c in [0.0, 1e-7, 0.3, 1.0] {
            assert!(
                (fresnel_conductor(c, Spectrum::ZERO, Spectrum::ONE) - Spectrum::ONE).length()
                    < 1e-6
            );
        }
        // Normal incidence: ((η−1)² + k²) / ((η+1)² + k²).
        let (e, k) = (0.2f32, 3.9f32);
        let want = ((e - 1.0).powi(2) + k * k) / ((e + 1.0).powi(2) + k * k);
        assert!(
            (fresnel_conductor(1.0, Spectrum::splat(e), Spectrum::splat(k)).x - want).abs() < 1e-6
        );
        // k = 0 reduces to the dielectric formula.
        for c in [0.1f32, 0.5, 0.9] {
            let d = fresnel_dielectric(c, 1.7).f;
            let m = fresnel_conductor(c, Spectrum::splat(1.7), Spectrum::ZERO).x;
            assert!((d - m).abs() < 1e-6, "{c}: {d} vs {m}");
        }
    }

    #[test]
    fn conductor_reflectance_is_even_in_k() {
        // The sign of the extinction coefficient is a convention (e^{iωt} or e^{−iωt}): n + ik
        // and n − ik are complex conjugates, every amplitude conjugates with them, and the
        // reflectance |r|² is the same. With k < 0, n² − sin²θ has a negative imaginary part,
        // which is where the principal square root's sign matters (shard 6's mutant returned
        // the conjugate root there).
        for (e, k) in [(0.2, 3.9), (1.5, 0.7), (0.05, 0.3), (2.5, 4.0)] {
            for c in [0.0, 0.2, 0.5, 0.8, 1.0] {
                let pos = fresnel_conductor_1(c, e, k);
                let neg = fresnel_conductor_1(c, e, -k);
                assert!(
                    (pos - neg).abs() < 1e-12,
                    "η {e}, k {k}, cos {c}: {pos} vs {neg}"
                );
            }
            let want = ((e - 1.0).powi(2) + k * k) / ((e + 1.0).powi(2) + k * k);
            let got = fresnel_conductor_1(1.0, e, -k);
            assert!((got - want).abs() < 1e-12, "η {e}, k −{k}: {got} vs {want}");
        }
    }

    #[test]
    fn diffuse_fresnel_reflectance_relation() {
        // Energy balance across a smooth interface: η² (1 − Fdr(1/η)) = 1 − Fdr(η).
        let eta = 1.49;
        let ext = diffuse_fresnel_reflectance(eta);
        let int = diffuse_fresnel_reflectance(1.0 / eta);
        assert!(
            (eta * eta * (1.0 - int) - (1.0 - ext)).abs() < 1e-4,
            "{ext} {int}"
        );
    }
}
