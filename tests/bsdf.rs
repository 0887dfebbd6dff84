//! Statistical and numerical tests of every BSDF, the methods of Mitsuba's and pbrt's own test
//! suites:
//!
//! - chi-square goodness of fit of the sampled directions against the integrated pdf on a
//!   (cos θ, φ) grid (1e6 samples per test, expected counts < 5 pooled), at several incident
//!   directions down to near-grazing and parameters from α = 0.001 to 1, anisotropic, IOR
//!   near 1 and large; α = 0.01 with the Šidák correction over every chi-square test here.
//!   Narrow lobes (α < 0.25) are tested through a stereographic magnification centred on the
//!   lobe (a bijection of the sphere with an analytic Jacobian), so that the grid resolves
//!   them; transmissive BSDFs are then tested one hemisphere at a time.
//! - energy: the directional albedo E[weight] (transmission counted in importance form,
//!   weight · η², undoing the radiance scaling) never exceeds 1 beyond noise; white furnace
//!   for the ideal conductor (exactly 1) and for smooth dielectrics (reflection + transmission
//!   = 1 for every sample, and the reflection frequency equals the Fresnel reflectance).
//! - reciprocity of eval for the non-transmissive BSDFs; no NaN or Inf from eval, sample or
//!   pdf at any direction, including cos θ down to 1e-7.
//!
//! - `principled` and `principledthin`, built from plain parameters: the same chi-square
//!   tests (with their own Šidák correction), and no NaN or Inf at the edge directions.
//!   (Their albedo may exceed 1: the Disney model does not conserve energy.) Cheaper, for the
//!   mutation tier: their mean sample weight equals a uniform-sphere estimate of ∫ eval dω
//!   (a z-test), which a lobe chosen with the wrong probability breaks.
//!
//! Every test is deterministic (fixed seeds).

mod common;
use common::*;
use glam::{Vec2, Vec3};
use penumbra::bsdf::Bsdf;
use penumbra::geometry::Frame;
use penumbra::material::ShadingBsdf;
use penumbra::sampler::SampleStream;
use penumbra::spectrum::Spectrum;
use penumbra::study::chi2::{chi2_test_adaptive, Chi2Config, Chi2Result};
use penumbra::study::stats::{normal_critical_z, sidak};
use rayon::prelude::*;

/// A BSDF configuration under test.
struct Case {
    name: &'static str,
    xml: String,
    /// The smallest roughness (for the magnification of narrow lobes); ∞ for smooth lobes.
    alpha: f32,
}

fn case(name: &'static str, xml: &str, alpha: f32) -> Case {
    Case {
        name,
        xml: xml.to_string(),
        alpha,
    }
}

fn rough(plugin: &str, dist: &str, alpha: f32, extra: &str) -> String {
    format!(
        r#"<bsdf type="{plugin}"><string name="distribution" value="{dist}"/><float name="alpha" value="{alpha}"/>{extra}</bsdf>"#
    )
}

fn aniso(plugin: &str, dist: &str, au: f32, av: f32, extra: &str) -> String {
    format!(
        r#"<bsdf type="{plugin}"><string name="distribution" value="{dist}"/><float name="alpha_u" value="{au}"/><float name="alpha_v" value="{av}"/>{extra}</bsdf>"#
    )
}

const NOVIS: &str = r#"<boolean name="sample_visible" value="false"/>"#;

/// The BSDFs with a non-delta lobe, for the chi-square tests.
fn smooth_cases() -> Vec<Case> {
    let mut v = vec![case(
        "diffuse",
        r#"<bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.5, 0.8"/></bsdf>"#,
        f32::INFINITY,
    )];
    for dist in ["beckmann", "ggx"] {
        for a in [0.001f32, 0.05, 0.3, 1.0] {
            v.push(Case {
                name: "roughconductor",
                xml: rough("roughconductor", dist, a, ""),
                alpha: a,
            });
        }
        v.push(Case {
            name: "roughconductor aniso",
            xml: aniso("roughconductor", dist, 0.05, 0.4, ""),
            alpha: 0.05,
        });
        v.push(Case {
            name: "roughconductor no-visible",
            xml: rough("roughconductor", dist, 0.3, NOVIS),
            alpha: 0.3,
        });
        for a in [0.001f32, 0.05, 0.3, 1.0] {
            v.push(Case {
                name: "roughdielectric",
                xml: rough("roughdielectric", dist, a, ""),
                alpha: a,
            });
        }
        for ior in [1.01f32, 2.42] {
            v.push(Case {
                name: "roughdielectric ior",
                xml: rough(
                    "roughdielectric",
                    dist,
                    0.3,
                    &format!(r#"<float name="int_ior" value="{ior}"/>"#),
                ),
                alpha: 0.3,
            });
        }
        v.push(Case {
            name: "roughdielectric aniso",
            xml: aniso("roughdielectric", dist, 0.4, 0.05, ""),
            alpha: 0.05,
        });
        v.push(Case {
            name: "roughdielectric no-visible",
            xml: rough("roughdielectric", dist, 0.3, NOVIS),
            alpha: 0.3,
        });
        for a in [0.01f32, 0.3, 1.0] {
            v.push(Case {
                name: "roughplastic",
                xml: rough("roughplastic", dist, a, ""),
                alpha: a,
            });
        }
        v.push(Case {
            name: "roughplastic nonlinear ior 2.5",
            xml: rough(
                "roughplastic",
                dist,
                0.2,
                r#"<boolean name="nonlinear" value="true"/><float name="int_ior" value="2.5"/><rgb name="diffuse_reflectance" value="0.9, 0.2, 0.1"/>"#,
            ),
            alpha: 0.2,
        });
        v.push(Case {
            name: "roughplastic no-visible",
            xml: rough("roughplastic", dist, 0.3, NOVIS),
            alpha: 0.3,
        });
    }
    v.push(case("plastic", r#"<bsdf type="plastic"/>"#, f32::INFINITY));
    v.push(case(
        "plastic ior 1.9 nonlinear",
        r#"<bsdf type="plastic"><float name="int_ior" value="1.9"/><boolean name="nonlinear" value="true"/></bsdf>"#,
        f32::INFINITY,
    ));
    v.push(case(
        "twosided roughconductor",
        r#"<bsdf type="twosided"><bsdf type="roughconductor"><string name="distribution" value="ggx"/><float name="alpha" value="0.2"/></bsdf></bsdf>"#,
        0.2,
    ));
    // phong (Mitsuba 0.6's modified Phong): "alpha" is the Beckmann roughness of equal
    // lobe width, √(2 / (n + 2)).
    v.extend([
        case("phong", r#"<bsdf type="phong"/>"#, 0.25),
        case(
            "phong n=1 coloured",
            r#"<bsdf type="phong"><float name="exponent" value="1"/><rgb name="diffuse_reflectance" value="0.1, 0.4, 0.7"/><rgb name="specular_reflectance" value="0.8, 0.5, 0.2"/></bsdf>"#,
            1.0,
        ),
        case(
            "phong n=1000 specular only",
            r#"<bsdf type="phong"><float name="exponent" value="1000"/><rgb name="diffuse_reflectance" value="0"/><rgb name="specular_reflectance" value="1"/></bsdf>"#,
            0.045,
        ),
        case(
            "phong n=0",
            r#"<bsdf type="phong"><float name="exponent" value="0"/><rgb name="diffuse_reflectance" value="0.3"/><rgb name="specular_reflectance" value="0.7"/></bsdf>"#,
            f32::INFINITY,
        ),
    ]);
    v
}

/// Every BSDF, including the purely specular ones and extra parameters that change weights
/// but not sampling.
fn all_cases() -> Vec<Case> {
    let mut v = smooth_cases();
    for dist in ["beckmann", "ggx"] {
        v.push(Case {
            name: "roughconductor large k",
            xml: rough(
                "roughconductor",
                dist,
                0.2,
                r#"<rgb name="eta" value="0.2, 1.2, 3.0"/><rgb name="k" value="20, 3, 0"/>"#,
            ),
            alpha: 0.2,
        });
        v.push(Case {
            name: "roughdielectric tinted",
            xml: rough(
                "roughdielectric",
                dist,
                0.1,
                r#"<rgb name="specular_reflectance" value="0.5, 1, 1"/><rgb name="specular_transmittance" value="1, 0.3, 1"/>"#,
            ),
            alpha: 0.1,
        });
    }
    v.extend([
        case("conductor", r#"<bsdf type="conductor"/>"#, 0.0),
        case(
            "conductor Au",
            r#"<bsdf type="conductor"><string name="material" value="Au"/></bsdf>"#,
            0.0,
        ),
        case(
            "conductor large k",
            r#"<bsdf type="conductor"><rgb name="eta" value="0.2, 1.2, 3.0"/><rgb name="k" value="20, 3, 0"/></bsdf>"#,
            0.0,
        ),
        case("dielectric", r#"<bsdf type="dielectric"/>"#, 0.0),
        case(
            "dielectric ior 1.01",
            r#"<bsdf type="dielectric"><float name="int_ior" value="1.01"/></bsdf>"#,
            0.0,
        ),
        case(
            "dielectric diamond",
            r#"<bsdf type="dielectric"><string name="int_ior" value="diamond"/></bsdf>"#,
            0.0,
        ),
        case("thindielectric", r#"<bsdf type="thindielectric"/>"#, 0.0),
        case(
            "twosided conductor",
            r#"<bsdf type="twosided"><bsdf type="conductor"/></bsdf>"#,
            0.0,
        ),
        case(
            "twosided plastic",
            r#"<bsdf type="twosided"><bsdf type="plastic"/></bsdf>"#,
            f32::INFINITY,
        ),
    ]);
    v
}

fn dir(theta_deg: f32, phi_deg: f32) -> Vec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

/// Incident directions: near-normal (0.5°, so that φ is defined), 60° and the near-grazing
/// 89.5°; for BSDFs that see both sides also from below: 160° (transmits into the outer
/// medium), 115° (beyond the critical angle for η = 1.5: total internal reflection).
fn incident_directions(b: &ShadingBsdf) -> Vec<Vec3> {
    let mut v = vec![dir(0.5, 10.0), dir(60.0, 200.0), dir(89.5, 77.0)];
    if b.is_transmissive() {
        v.extend([dir(160.0, 250.0), dir(115.0, 15.0)]);
    } else if b.as_leaf().is_none() || matches!(b.as_leaf(), Some(Bsdf::PrincipledThin(_))) {
        v.push(dir(130.0, 250.0));
    }
    v
}

/// A stereographic magnification of the sphere about `center` by `s`: directions at angle θ
/// from the centre go to 2 atan(s tan(θ/2)). Bijective, with the solid-angle Jacobian
/// dω/dω' = (1 + r'²)² / (s² (1 + r²)²), r = tan(θ/2), r' = s r.
struct Magnify {
    frame: glam::DMat3,
    s: f64,
}

impl Magnify {
    fn new(center: glam::DVec3, s: f64) -> Self {
        let f = Frame::from_normal(center.as_vec3().normalize());
        // re-orthonormalise in f64 around the exact centre
        let n = center.normalize();
        let t = (f.s.as_dvec3() - n * n.dot(f.s.as_dvec3())).normalize();
        let b = n.cross(t);
        Magnify {
            frame: glam::DMat3::from_cols(t, b, n),
            s,
        }
    }

    fn polar(&self, d: glam::DVec3) -> (f64, f64) {
        let l = self.frame.transpose() * d;
        ((l.x * l.x + l.y * l.y).sqrt().atan2(l.z), l.y.atan2(l.x))
    }

    fn direction_at(&self, theta: f64, phi: f64) -> glam::DVec3 {
        self.frame
            * glam::DVec3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            )
    }

    fn forward(&self, d: glam::DVec3) -> glam::DVec3 {
        let (theta, phi) = self.polar(d);
        self.direction_at(2.0 * (self.s * (0.5 * theta).tan()).atan(), phi)
    }

    /// The pre-image of a direction and dω/dω' there.
    fn inverse(&self, d2: glam::DVec3) -> (glam::DVec3, f64) {
        let (t2, phi) = self.polar(d2);
        let r2 = (0.5 * t2).tan();
        let r = r2 / self.s;
        let jac = (1.0 + r2 * r2).powi(2) / (self.s * self.s * (1.0 + r * r).powi(2));
        (self.direction_at(2.0 * r.atan(), phi), jac)
    }
}

/// The transform of a one-sided test (the hemisphere `h` points to): a magnification of
/// narrow lobes; the cut-off at the horizon is left to the adaptive quadrature.
struct Transform {
    h: f64,
    magnify: Option<Magnify>,
}

impl Transform {
    fn forward(&self, wo: Vec3) -> Vec3 {
        let u = wo.as_dvec3().normalize();
        match &self.magnify {
            Some(m) => m.forward(u),
            None => u,
        }
        .as_vec3()
    }

    /// The direction whose image is `d` and dω/dω' there.
    fn inverse(&self, d: Vec3) -> (Vec3, f64) {
        let d = d.as_dvec3().normalize();
        let (u, jac) = match &self.magnify {
            Some(m) => m.inverse(d),
            None => (d, 1.0),
        };
        (u.as_vec3(), jac)
    }
}

/// One chi-square test: a BSDF and an incident direction, on the whole sphere or, for
/// narrow lobes, one hemisphere at a time (+1: the side of wi, −1: the other) through a
/// [`Transform`].
struct Chi2Job<'a> {
    case: &'a Case,
    bsdf: ShadingBsdf,
    wi: Vec3,
    side: Option<f32>,
    transform: Option<Transform>,
    seed: u64,
}

const CHI2_SAMPLES: usize = 1_000_000;

fn run_chi2(job: &Chi2Job) -> Chi2Result {
    let cfg = Chi2Config::default();
    let b = &job.bsdf;
    let wi = job.wi;
    let keep = |wo: Vec3| match job.side {
        None => true,
        Some(s) => wo.z * wi.z * s > 0.0,
    };
    let mut rng = SampleStream::new(0xc412, job.seed, 0);
    let sample = |_: usize| {
        let u1 = rng.next_1d();
        let u2 = rng.next_2d();
        let bs = b.sample(wi, u1, u2)?;
        if bs.delta || !keep(bs.wo) {
            return None;
        }
        Some(match &job.transform {
            Some(t) => t.forward(bs.wo),
            None => bs.wo,
        })
    };
    let pdf = |d: Vec3| -> f64 {
        let (wo, jac) = match &job.transform {
            Some(t) => t.inverse(d),
            None => (d, 1.0),
        };
        if !keep(wo) {
            return 0.0;
        }
        b.pdf(wi, wo) as f64 * jac
    };
    // Expected counts to ~0.02 samples per cell: far below the counts' noise.
    chi2_test_adaptive(CHI2_SAMPLES, sample, pdf, &cfg, 0.02 / CHI2_SAMPLES as f64)
}

/// The magnification that spreads a lobe over a useful part of the grid: the angle from the
/// lobe's image `center` within which a quarter of a few pilot samples fall goes to 20°
/// (a lower quantile than the median, so that the narrow lobe of a mixture such as rough
/// plastic's is resolved; what the magnification compresses, the adaptive quadrature
/// resolves).
fn pilot_scale(b: &ShadingBsdf, wi: Vec3, t: &Transform, center: glam::DVec3, seed: u64) -> f64 {
    let h = t.h;
    let mut rng = SampleStream::new(0x9e7, seed, 0);
    let mut angles = Vec::new();
    for _ in 0..200_000 {
        if angles.len() == 2000 {
            break;
        }
        if let Some(bs) = b.sample(wi, rng.next_1d(), rng.next_2d()) {
            if !bs.delta && bs.wo.z * h as f32 > 0.0 {
                let u = t.forward(bs.wo).as_dvec3();
                angles.push(u.cross(center).length().atan2(u.dot(center)));
            }
        }
    }
    if angles.len() < 100 {
        return 1.0;
    }
    angles.sort_by(f64::total_cmp);
    let q = angles[angles.len() / 4];
    ((10f64).to_radians().tan() / (0.5 * q).tan()).clamp(1.0, 1e4)
}

/// The centre of the specular lobe on the given side (mirror or refracted direction through
/// the macro-normal), if there is one.
fn lobe_center(b: &ShadingBsdf, wi: Vec3, side: f32) -> Option<Vec3> {
    if side > 0.0 {
        return Some(Vec3::new(-wi.x, -wi.y, wi.z));
    }
    let eta = match b.as_leaf() {
        Some(Bsdf::RoughDielectric(d)) => d.eta,
        Some(Bsdf::Principled(d)) => {
            // its rough transmission goes on beyond the macro-normal's critical angle
            let fr = penumbra::bsdf::fresnel::fresnel_dielectric(wi.z, d.eta);
            if fr.f == 1.0 {
                return Some(-wi);
            }
            d.eta
        }
        // the thin sheet transmits straight through
        Some(Bsdf::PrincipledThin(_)) => return Some(-wi),
        _ => return None,
    };
    let fr = penumbra::bsdf::fresnel::fresnel_dielectric(wi.z, eta);
    (fr.f < 1.0).then(|| {
        penumbra::bsdf::fresnel::refract(wi, Vec3::Z, fr.cos_theta_t, fr.eta_ti).normalize()
    })
}

fn chi2_jobs(cases: &[Case]) -> Vec<Chi2Job<'_>> {
    let built: Vec<_> = cases.iter().map(|c| (c, bsdf_from_xml(&c.xml))).collect();
    chi2_jobs_for(&built)
}

fn chi2_jobs_for<'a>(cases: &[(&'a Case, ShadingBsdf)]) -> Vec<Chi2Job<'a>> {
    let mut jobs = Vec::new();
    for &(c, ref b) in cases {
        let b = b.clone();
        for wi in incident_directions(&b) {
            // One hemisphere at a time, narrow lobes magnified about their centre.
            let sides: &[f32] = if b.is_transmissive() {
                &[1.0, -1.0]
            } else {
                &[1.0]
            };
            for &side in sides {
                let Some(center) = lobe_center(&b, wi, side) else {
                    continue; // total internal reflection: nothing is transmitted
                };
                let mut t = Transform {
                    h: (wi.z.signum() * side) as f64,
                    magnify: None,
                };
                let c_img = t.forward(center).as_dvec3();
                let s = pilot_scale(&b, wi, &t, c_img, jobs.len() as u64);
                t.magnify = (s > 1.5).then(|| Magnify::new(c_img, s));
                jobs.push(Chi2Job {
                    case: c,
                    bsdf: b.clone(),
                    wi,
                    side: Some(side),
                    transform: Some(t),
                    seed: jobs.len() as u64,
                });
            }
        }
    }
    jobs
}

/// The fast tier (`cargo test --release`): one chi-square test per BSDF configuration, at an
/// incident direction that rotates from one configuration to the next.
#[test]
fn chi2_sampling_matches_pdf() {
    let cases = smooth_cases();
    check_chi2(chi2_jobs(&cases), Tier::Fast);
}

/// The full tier (`cargo test --release -- --ignored`): every other incident direction and
/// hemisphere of every configuration. With the fast tier's tests, the battery above.
#[test]
#[ignore = "full tier: cargo test --release -- --ignored"]
fn chi2_sampling_matches_pdf_full() {
    let cases = smooth_cases();
    check_chi2(chi2_jobs(&cases), Tier::Full);
}

/// Mitsuba's adapters around smooth BSDFs, with constant and bitmap parameters looked up at
/// uv = (0.5, 0.5): the mask's pass-through events are delta samples (left out: the pdf must
/// integrate to the fraction that is not), blends of reflective and transmissive BSDFs,
/// twosided with a different BSDF on each side, normal maps tilting the frame, a bump map.
fn adapter_cases() -> Vec<Case> {
    let rc = |dist: &str, a: f32| rough("roughconductor", dist, a, "");
    vec![
        case(
            "mask",
            &format!(
                r#"<bsdf type="mask"><float name="opacity" value="0.4"/>{}</bsdf>"#,
                rc("ggx", 0.2)
            ),
            0.2,
        ),
        case(
            "blendbsdf",
            &format!(
                r#"<bsdf type="blendbsdf"><float name="weight" value="0.3"/><bsdf type="diffuse"/>{}</bsdf>"#,
                rc("beckmann", 0.1)
            ),
            0.1,
        ),
        case(
            "blendbsdf textured, transmissive",
            r#"<bsdf type="blendbsdf"><texture type="bitmap" name="weight"><string name="filename" value="data/textures/grey8.png"/></texture><bsdf type="roughplastic"/><bsdf type="roughdielectric"><string name="distribution" value="ggx"/><float name="alpha" value="0.3"/></bsdf></bsdf>"#,
            0.1,
        ),
        case(
            "twosided front/back",
            &format!(
                r#"<bsdf type="twosided"><bsdf type="diffuse"/>{}</bsdf>"#,
                rc("ggx", 0.3)
            ),
            0.3,
        ),
        case(
            "normalmap roughconductor",
            &format!(
                r#"<bsdf type="normalmap"><texture type="rawconstant" name="normalmap"><vector name="value" x="0.7" y="0.4" z="0.9"/></texture>{}</bsdf>"#,
                rc("ggx", 0.3)
            ),
            0.3,
        ),
        case(
            "normalmap diffuse",
            r#"<bsdf type="normalmap"><texture type="rawconstant" name="normalmap"><vector name="value" x="0.3" y="0.6" z="0.8"/></texture><bsdf type="diffuse"/></bsdf>"#,
            f32::INFINITY,
        ),
        case(
            "bumpmap",
            &format!(
                r#"<bsdf type="bumpmap"><texture type="bitmap"><string name="filename" value="data/textures/grey8.png"/><boolean name="raw" value="true"/></texture><float name="scale" value="0.05"/>{}</bsdf>"#,
                rc("beckmann", 0.2)
            ),
            0.2,
        ),
    ]
}

#[test]
fn chi2_adapters_match_pdf() {
    let cases = adapter_cases();
    check_chi2(chi2_jobs(&cases), Tier::Fast);
}

#[test]
#[ignore = "full tier: cargo test --release -- --ignored"]
fn chi2_adapters_match_pdf_full() {
    let cases = adapter_cases();
    check_chi2(chi2_jobs(&cases), Tier::Full);
}

/// A `null` BSDF and a fully transparent mask let light through unchanged: eval and pdf are
/// 0, every sample is the delta pass-through wo = −wi with weight 1.
#[test]
fn null_and_transparent_mask_pass_light_through() {
    for xml in [
        r#"<bsdf type="null"/>"#,
        r#"<bsdf type="mask"><float name="opacity" value="0"/><bsdf type="diffuse"/></bsdf>"#,
    ] {
        let b = bsdf_from_xml(xml);
        let mut rng = SampleStream::new(8, 0, 0);
        for _ in 0..100 {
            let wi = penumbra::sampling::square_to_uniform_sphere(rng.next_2d());
            let wo = penumbra::sampling::square_to_uniform_sphere(rng.next_2d());
            assert_eq!(
                (b.eval(wi, wo), b.pdf(wi, wo)),
                (Spectrum::ZERO, 0.0),
                "{xml}"
            );
            let bs = b.sample(wi, rng.next_1d(), rng.next_2d()).expect(xml);
            assert!(
                bs.delta && bs.wo == -wi && bs.weight == Spectrum::ONE,
                "{xml}: {bs:?}"
            );
            assert!(!b.has_smooth_lobe(wi), "{xml}");
        }
    }
}

/// Which part of a battery of tests a test function runs: the fast tier (`cargo test
/// --release`) one per BSDF configuration, the full tier (`-- --ignored`) the rest. Both
/// correct for the whole battery, so the two together are exactly the battery's test.
#[derive(Clone, Copy, PartialEq)]
enum Tier {
    Fast,
    Full,
}

/// Whether each job is in the fast tier: of the consecutive jobs of one configuration, the
/// (k mod their number)-th for the k-th configuration, so that every configuration is tested
/// once and the incident direction rotates across configurations. Jobs whose quadrature
/// alone takes minutes (a lobe magnified more than 100 times at a near-grazing incidence,
/// where the horizon cuts through the magnified image) are skipped in that rotation: they
/// stay in the full tier.
fn fast_tier(jobs: &[Chi2Job]) -> Vec<bool> {
    let slow = |j: &Chi2Job| {
        let s = j
            .transform
            .as_ref()
            .and_then(|t| t.magnify.as_ref())
            .map_or(1.0, |m| m.s);
        j.wi.z.abs() < 0.01 && s > 100.0
    };
    let mut fast = vec![false; jobs.len()];
    let (mut start, mut k) = (0, 0);
    while start < jobs.len() {
        let n = jobs[start..]
            .iter()
            .take_while(|j| std::ptr::eq(j.case, jobs[start].case))
            .count();
        let pick = (0..n)
            .map(|i| start + (k + i) % n)
            .find(|&i| !slow(&jobs[i]))
            .unwrap_or(start + k % n);
        fast[pick] = true;
        start += n;
        k += 1;
    }
    fast
}

/// Runs the chi-square jobs of `tier` (those CHI2_FILTER selects) and fails on any p-value
/// below the Šidák-corrected α = 0.01 over all the jobs of both tiers, or a pdf that does not
/// integrate to the fraction of samples that landed.
fn check_chi2(jobs: Vec<Chi2Job>, tier: Tier) {
    let n_tests = jobs.len();
    let fast = fast_tier(&jobs);
    let mut jobs: Vec<Chi2Job> = jobs
        .into_iter()
        .zip(fast)
        .filter(|(_, f)| *f == (tier == Tier::Fast))
        .map(|(j, _)| j)
        .collect();
    // CHI2_FILTER=text runs only the tests whose BSDF XML or name contains it (for
    // development; the Šidák correction still counts every test). A filtered run reports
    // its results and then fails, so that it can never pass for a full one.
    let filter = std::env::var("CHI2_FILTER").ok();
    if let Some(f) = &filter {
        jobs.retain(|j| j.case.xml.contains(f.as_str()) || j.case.name.contains(f.as_str()));
    }
    let results: Vec<(Chi2Result, f64)> = jobs
        .par_iter()
        .map(|j| {
            let t = std::time::Instant::now();
            (run_chi2(j), t.elapsed().as_secs_f64())
        })
        .collect();
    let alpha = sidak(0.01, n_tests);
    let mut failures = Vec::new();
    let mut lines = Vec::new();
    for (j, (r, secs)) in jobs.iter().zip(&results) {
        let theta = j.wi.z.clamp(-1.0, 1.0).acos().to_degrees();
        let line = format!(
            "{:30} {:62} θi {:5.1}° {:>5} ×{:<7.1} p = {:.3e} (χ² {:.1}, dof {}, landed {:.4}, ∫pdf {:.4}) {secs:.1} s",
            j.case.name,
            j.case
                .xml
                .replace("<bsdf type=", "")
                .replace("<string name=\"distribution\" value=", "")
                .replace("<float name=", "")
                .chars()
                .take(62)
                .collect::<String>(),
            theta,
            match j.side {
                None => "both".into(),
                Some(s) => format!("{s:+}"),
            },
            j.transform
                .as_ref()
                .and_then(|t| t.magnify.as_ref())
                .map_or(1.0, |m| m.s),
            r.p_value,
            r.statistic,
            r.dof,
            r.landed as f64 / r.samples as f64,
            r.pdf_integral,
        );
        // The pdf must also integrate to the fraction of samples that landed.
        let frac = r.landed as f64 / r.samples as f64;
        let se = (frac * (1.0 - frac) / r.samples as f64).sqrt().max(1e-6);
        if r.p_value < alpha || (r.pdf_integral - frac).abs() > 5.0 * se + 2e-3 {
            failures.push(line.clone());
        }
        lines.push(line);
    }
    eprintln!(
        "{} of {n_tests} chi-square tests, Šidák-corrected α = {alpha:.3e}:\n{}",
        lines.len(),
        lines.join("\n")
    );
    assert!(failures.is_empty(), "failed:\n{}", failures.join("\n"));
    if let Some(f) = filter {
        panic!(
            "CHI2_FILTER={f:?} ran {} of {n_tests} chi-square tests (all passed); unset it \
             for a full run",
            jobs.len()
        );
    }
}

/// E[weight] per channel with transmission in importance form, and its standard error.
fn albedo(b: &ShadingBsdf, wi: Vec3, n: usize, seed: u64) -> (Vec3, Vec3) {
    let mut rng = SampleStream::new(0xa1be, seed, 0);
    let (mut s, mut s2) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
    for _ in 0..n {
        let u1 = rng.next_1d();
        let u2 = rng.next_2d();
        if let Some(bs) = b.sample(wi, u1, u2) {
            let w = penumbra::spectrum::to_rgb(bs.weight * bs.eta * bs.eta).as_dvec3();
            s += w;
            s2 += w * w;
        }
    }
    let mean = s / n as f64;
    let var = (s2 / n as f64 - mean * mean).max(glam::DVec3::ZERO);
    (mean.as_vec3(), (var / n as f64).map(f64::sqrt).as_vec3())
}

#[test]
fn albedo_never_exceeds_one() {
    // White versions: reflectances 1.
    let cases = all_cases();
    let mut jobs = Vec::new();
    for c in &cases {
        let b = bsdf_from_xml(&c.xml);
        for wi in incident_directions(&b) {
            jobs.push((c, b.clone(), wi));
        }
    }
    let n_tests = jobs.len() * 3;
    let z = normal_critical_z(2.0 * sidak(0.01, n_tests)); // one-sided
    let results: Vec<_> = jobs
        .par_iter()
        .enumerate()
        .map(|(i, (_, b, wi))| albedo(b, *wi, 200_000, i as u64))
        .collect();
    let mut failures = Vec::new();
    for ((c, _, wi), (mean, se)) in jobs.iter().zip(&results) {
        for k in 0..3 {
            if mean[k] as f64 - 1.0 > z * se[k] as f64 + 1e-5 {
                failures.push(format!(
                    "{} {}: wi {wi} albedo {mean} ± {se}",
                    c.name, c.xml
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn white_furnace_ideal_conductor_and_smooth_dielectric() {
    let mirror = bsdf_from_xml(r#"<bsdf type="conductor"/>"#);
    for wi in [dir(0.0, 0.0), dir(45.0, 20.0), dir(89.99, 0.0)] {
        let bs = mirror.sample(wi, 0.3, Vec2::splat(0.5)).unwrap();
        assert_eq!(bs.weight, Spectrum::ONE);
        assert!(bs.delta);
        assert!((bs.wo - Vec3::new(-wi.x, -wi.y, wi.z)).length() < 1e-6);
    }
    // (BSDF, relative IOR from Mitsuba's table: bk7 1.5046, diamond 2.419, air 1.000277, thin)
    let air = 1.000277;
    for (xml, eta, thin) in [
        (r#"<bsdf type="dielectric"/>"#, 1.5046 / air, false),
        (
            r#"<bsdf type="dielectric"><float name="int_ior" value="1.01"/></bsdf>"#,
            1.01 / air,
            false,
        ),
        (
            r#"<bsdf type="dielectric"><string name="int_ior" value="diamond"/></bsdf>"#,
            2.419 / air,
            false,
        ),
        (r#"<bsdf type="thindielectric"/>"#, 1.5046 / air, true),
    ] {
        let b = bsdf_from_xml(xml);
        for (i, wi) in [
            dir(0.0, 0.0),
            dir(50.0, 20.0),
            dir(88.0, 0.0),
            dir(140.0, 10.0),
        ]
        .into_iter()
        .enumerate()
        {
            let n = 100_000;
            let mut rng = SampleStream::new(0xf00, i as u64, 0);
            let mut reflected = 0usize;
            for _ in 0..n {
                let bs = b.sample(wi, rng.next_1d(), rng.next_2d()).unwrap();
                assert!(bs.delta);
                // every sample carries exactly the energy it takes: R + T = 1
                let e = bs.weight * bs.eta * bs.eta;
                assert!((e - Spectrum::ONE).abs().max_element() < 1e-5, "{xml}: {e}");
                if bs.wo.z * wi.z > 0.0 {
                    reflected += 1;
                    assert!((bs.wo - Vec3::new(-wi.x, -wi.y, wi.z)).length() < 1e-6);
                }
            }
            // The reflection frequency is the Fresnel reflectance (binomial z-test), from
            // Fresnel's equations written in the test; a thin sheet reflects the sum over its
            // inner bounces, R + (1 − R)² R / (1 − R²) (Mitsuba's `thindielectric`).
            let cos = wi.z as f64;
            let r = if thin {
                let r = fresnel_reflectance(cos.abs(), 1.0, eta);
                if r < 1.0 {
                    r + (1.0 - r).powi(2) * r / (1.0 - r * r)
                } else {
                    1.0
                }
            } else {
                fresnel_of_side(cos, eta)
            };
            let freq = reflected as f64 / n as f64;
            let se = (r * (1.0 - r) / n as f64).sqrt();
            assert!(
                (freq - r).abs() <= 4.5 * se + 1e-9,
                "{xml} wi {wi}: reflected {freq} vs F {r}"
            );
        }
    }
}

/// Directions for the robustness tests: random ones, axis-aligned ones, and ones with cos θ
/// of ±1e-7, ±1e-5, 0.
fn edge_directions() -> Vec<Vec3> {
    let mut v = Vec::new();
    for z in [1e-7f32, 1e-5, 0.0, -1e-7, -1e-5, 1.0, -1.0, 0.999_999_9] {
        for phi in [0.0f32, 1.0, 2.5, 4.0] {
            let s = (1.0 - z * z).max(0.0).sqrt();
            v.push(Vec3::new(s * phi.cos(), s * phi.sin(), z));
        }
    }
    let mut rng = SampleStream::new(7, 7, 7);
    for _ in 0..64 {
        let u = rng.next_2d();
        let z = 1.0 - 2.0 * u.y;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = 2.0 * std::f32::consts::PI * u.x;
        v.push(Vec3::new(r * phi.cos(), r * phi.sin(), z));
    }
    v
}

#[test]
fn no_nan_or_inf_anywhere() {
    let dirs = edge_directions();
    let mut rng = SampleStream::new(11, 0, 0);
    for c in all_cases() {
        let b = bsdf_from_xml(&c.xml);
        for &wi in &dirs {
            for &wo in &dirs {
                let f = b.eval(wi, wo);
                let p = b.pdf(wi, wo);
                assert!(
                    f.is_finite() && f.min_element() >= 0.0 && p.is_finite() && p >= 0.0,
                    "{} {}: eval {f} pdf {p} at wi {wi:?} wo {wo:?}",
                    c.name,
                    c.xml
                );
            }
            for _ in 0..64 {
                let (u1, u2) = (rng.next_1d(), rng.next_2d());
                if let Some(bs) = b.sample(wi, u1, u2) {
                    assert!(
                        bs.weight.is_finite()
                            && bs.weight.min_element() >= 0.0
                            && bs.pdf.is_finite()
                            && bs.pdf > 0.0
                            && bs.eta.is_finite()
                            && bs.eta > 0.0
                            && (bs.wo.length() - 1.0).abs() < 1e-4,
                        "{} {}: {bs:?} at wi {wi:?}",
                        c.name,
                        c.xml
                    );
                }
            }
            // extreme random numbers
            for (u1, u2) in [
                (0.0, Vec2::ZERO),
                (0.999_999_9, Vec2::splat(0.999_999_9)),
                (0.5, Vec2::new(0.0, 0.999_999_9)),
            ] {
                if let Some(bs) = b.sample(wi, u1, u2) {
                    assert!(
                        bs.weight.is_finite() && bs.pdf.is_finite(),
                        "{}: {bs:?}",
                        c.xml
                    );
                }
            }
        }
    }
}

#[test]
fn eval_is_reciprocal_for_reflective_bsdfs() {
    let dirs = edge_directions();
    for c in all_cases() {
        let b = bsdf_from_xml(&c.xml);
        if b.is_transmissive() {
            continue;
        }
        for &wi in &dirs {
            for &wo in &dirs {
                if wi.z.abs() < 1e-3 || wo.z.abs() < 1e-3 {
                    continue; // f = eval / |cos θo| is ill-conditioned there
                }
                let a = b.eval(wi, wo) / wo.z.abs();
                let r = b.eval(wo, wi) / wi.z.abs();
                let scale = a.max_element().max(r.max_element());
                assert!(
                    (a - r).abs().max_element() <= 1e-4 * scale + 1e-12,
                    "{} {}: f(wi, wo) = {a} but f(wo, wi) = {r} at {wi:?} {wo:?}",
                    c.name,
                    c.xml
                );
            }
        }
    }
}

#[test]
fn has_smooth_lobe_matches_sampling() {
    // NEE happens only where a BSDF has a non-delta lobe; a BSDF without one never samples
    // a non-delta direction, and one with only smooth lobes never samples a delta.
    for c in all_cases() {
        let b = bsdf_from_xml(&c.xml);
        for wi in incident_directions(&b) {
            let mut rng = SampleStream::new(3, 1, 4);
            let (mut smooth, mut delta) = (0, 0);
            for _ in 0..2000 {
                if let Some(bs) = b.sample(wi, rng.next_1d(), rng.next_2d()) {
                    if bs.delta {
                        delta += 1
                    } else {
                        smooth += 1
                    }
                }
            }
            if !b.has_smooth_lobe(wi) {
                assert_eq!(smooth, 0, "{}: smooth samples without a smooth lobe", c.xml);
            }
            if smooth > 0 {
                assert!(b.has_smooth_lobe(wi), "{}", c.xml);
            }
            if c.alpha.is_finite() && c.alpha > 0.0 {
                assert_eq!(delta, 0, "{}: rough BSDFs have no delta lobe", c.xml);
            }
        }
    }
}

/// `principled` and `principledthin`, built directly from their parameters (the XML is
/// Mitsuba's equivalent element, for the record): each lobe mixture Mitsuba samples, narrow
/// and anisotropic lobes, transmission from both sides, η < 1, non-default sampling rates.
fn principled_cases() -> Vec<(Case, ShadingBsdf)> {
    use penumbra::bsdf::{Principled, PrincipledParams, PrincipledThin, PrincipledThinParams};
    let p = PrincipledParams::default;
    let t = PrincipledThinParams::default;
    let principled = |name, xml, alpha, params| {
        (
            case(name, xml, alpha),
            ShadingBsdf::leaf(Bsdf::Principled(Principled::new(params))),
        )
    };
    let thin = |name, xml, alpha, params| {
        (
            case(name, xml, alpha),
            ShadingBsdf::leaf(Bsdf::PrincipledThin(PrincipledThin::new(params))),
        )
    };
    vec![
        principled("principled", r#"<bsdf type="principled"/>"#, 0.25, p()),
        principled(
            "principled all lobes",
            r#"<bsdf type="principled"><rgb name="base_color" value="0.9, 0.3, 0.1"/><float name="roughness" value="0.35"/><float name="anisotropic" value="0.6"/><float name="metallic" value="0.3"/><float name="spec_trans" value="0.4"/><float name="specular" value="0.6"/><float name="spec_tint" value="0.4"/><float name="sheen" value="0.3"/><float name="sheen_tint" value="0.2"/><float name="flatness" value="0.3"/><float name="clearcoat" value="0.6"/><float name="clearcoat_gloss" value="0.3"/></bsdf>"#,
            0.07,
            PrincipledParams {
                base_color: penumbra::spectrum::rgb(0.9, 0.3, 0.1),
                roughness: 0.35,
                anisotropic: 0.6,
                metallic: 0.3,
                spec_trans: 0.4,
                has_spec_trans: true,
                specular: 0.6,
                spec_tint: 0.4,
                sheen: 0.3,
                sheen_tint: 0.2,
                flatness: 0.3,
                clearcoat: 0.6,
                clearcoat_gloss: 0.3,
                ..p()
            },
        ),
        principled(
            "principled metallic aniso",
            r#"<bsdf type="principled"><float name="metallic" value="1"/><float name="roughness" value="0.3"/><float name="anisotropic" value="0.9"/></bsdf>"#,
            0.03,
            PrincipledParams {
                metallic: 1.0,
                roughness: 0.3,
                anisotropic: 0.9,
                ..p()
            },
        ),
        principled(
            "principled smooth metal",
            r#"<bsdf type="principled"><float name="metallic" value="1"/><float name="roughness" value="0"/></bsdf>"#,
            0.001,
            PrincipledParams {
                metallic: 1.0,
                roughness: 0.0,
                ..p()
            },
        ),
        principled(
            "principled clearcoat",
            r#"<bsdf type="principled"><float name="clearcoat" value="1"/><float name="clearcoat_gloss" value="0.8"/><float name="roughness" value="0.8"/></bsdf>"#,
            0.02,
            PrincipledParams {
                clearcoat: 1.0,
                clearcoat_gloss: 0.8,
                roughness: 0.8,
                ..p()
            },
        ),
        principled(
            "principled glass",
            r#"<bsdf type="principled"><float name="spec_trans" value="1"/><float name="eta" value="1.33"/><float name="roughness" value="0.3"/></bsdf>"#,
            0.09,
            PrincipledParams {
                spec_trans: 1.0,
                has_spec_trans: true,
                eta: Some(1.33),
                roughness: 0.3,
                ..p()
            },
        ),
        principled(
            "principled transmission eta 0.8",
            r#"<bsdf type="principled"><float name="spec_trans" value="0.6"/><float name="eta" value="0.8"/><float name="roughness" value="0.5"/><float name="clearcoat" value="0.5"/></bsdf>"#,
            0.25,
            PrincipledParams {
                spec_trans: 0.6,
                has_spec_trans: true,
                eta: Some(0.8),
                roughness: 0.5,
                clearcoat: 0.5,
                ..p()
            },
        ),
        principled(
            "principled sampling rates",
            r#"<bsdf type="principled"><float name="clearcoat" value="0.7"/><float name="spec_trans" value="0.3"/><float name="diffuse_reflectance_sampling_rate" value="0.3"/><float name="main_specular_sampling_rate" value="2"/><float name="clearcoat_sampling_rate" value="0.5"/></bsdf>"#,
            0.1,
            PrincipledParams {
                clearcoat: 0.7,
                spec_trans: 0.3,
                has_spec_trans: true,
                diffuse_reflectance_sampling_rate: 0.3,
                main_specular_sampling_rate: 2.0,
                clearcoat_sampling_rate: 0.5,
                ..p()
            },
        ),
        thin(
            "principledthin",
            r#"<bsdf type="principledthin"/>"#,
            0.25,
            t(),
        ),
        thin(
            "principledthin docs",
            r#"<bsdf type="principledthin"><rgb name="base_color" value="0.7, 0.1, 0.1"/><float name="roughness" value="0.15"/><float name="spec_tint" value="0.1"/><float name="anisotropic" value="0.5"/><float name="spec_trans" value="0.8"/><float name="diff_trans" value="0.3"/><float name="eta" value="1.33"/></bsdf>"#,
            0.01,
            PrincipledThinParams {
                base_color: penumbra::spectrum::rgb(0.7, 0.1, 0.1),
                roughness: 0.15,
                spec_tint: 0.1,
                anisotropic: 0.5,
                spec_trans: 0.8,
                diff_trans: 0.3,
                eta: 1.33,
                ..t()
            },
        ),
        thin(
            "principledthin diffuse transmission",
            r#"<bsdf type="principledthin"><float name="diff_trans" value="1.2"/><float name="sheen" value="1"/><float name="spec_trans" value="0.3"/><float name="roughness" value="0.6"/></bsdf>"#,
            0.2,
            PrincipledThinParams {
                diff_trans: 1.2,
                sheen: 1.0,
                spec_trans: 0.3,
                roughness: 0.6,
                ..t()
            },
        ),
        thin(
            "principledthin rates",
            r#"<bsdf type="principledthin"><float name="spec_trans" value="0.5"/><float name="diff_trans" value="0.8"/><float name="roughness" value="0.3"/><float name="eta" value="2"/><float name="specular_reflectance_sampling_rate" value="0.5"/><float name="specular_transmittance_sampling_rate" value="2"/><float name="diffuse_reflectance_sampling_rate" value="0.7"/><float name="diffuse_transmittance_sampling_rate" value="1.5"/></bsdf>"#,
            0.09,
            PrincipledThinParams {
                spec_trans: 0.5,
                diff_trans: 0.8,
                roughness: 0.3,
                eta: 2.0,
                specular_reflectance_sampling_rate: 0.5,
                specular_transmittance_sampling_rate: 2.0,
                diffuse_reflectance_sampling_rate: 0.7,
                diffuse_transmittance_sampling_rate: 1.5,
                ..t()
            },
        ),
    ]
}

/// Chi-square of the principled samplers against their pdfs (the pdfs themselves are
/// checked against Mitsuba's in tests/bsdf_mitsuba.rs: together, penumbra samples Mitsuba's
/// directions with Mitsuba's density, so its estimates have Mitsuba's variance).
#[test]
fn chi2_principled_sampling_matches_pdf() {
    let cases = principled_cases();
    let refs: Vec<(&Case, ShadingBsdf)> = cases.iter().map(|(c, b)| (c, b.clone())).collect();
    check_chi2(chi2_jobs_for(&refs), Tier::Fast);
}

#[test]
#[ignore = "full tier: cargo test --release -- --ignored"]
fn chi2_principled_sampling_matches_pdf_full() {
    let cases = principled_cases();
    let refs: Vec<(&Case, ShadingBsdf)> = cases.iter().map(|(c, b)| (c, b.clone())).collect();
    check_chi2(chi2_jobs_for(&refs), Tier::Full);
}

/// The choice among the Disney lobes in `sample()`: the mean sample weight (over the
/// non-delta samples) and a uniform-sphere estimate of ∫ eval dω (eval carries |cos θo|) both
/// estimate the directional albedo, independently of each other; if `sample()` picked its
/// lobes with other probabilities than `pdf()` assumes, the first one is biased. Moderately
/// rough lobes only (α ≥ 0.1, clearcoat gloss 0: α_cc = 0.1), so that the uniform estimate
/// has a light tail. Two-sided z-test on the difference, α = 0.01 with the Šidák correction
/// over every (case, direction, channel). The chi-square tests check the same more finely,
/// but are too slow for the mutation tier.
#[test]
fn principled_lobe_choice_is_unbiased() {
    use penumbra::bsdf::{Principled, PrincipledParams, PrincipledThin, PrincipledThinParams};
    use penumbra::sampling::square_to_uniform_sphere;
    let p = PrincipledParams::default;
    let all = PrincipledParams {
        base_color: penumbra::spectrum::rgb(0.8, 0.5, 0.3),
        roughness: 0.6,
        metallic: 0.2,
        spec_trans: 0.3,
        has_spec_trans: true,
        sheen: 0.4,
        clearcoat: 1.0,
        clearcoat_gloss: 0.0,
        ..p()
    };
    let rates = PrincipledParams {
        diffuse_reflectance_sampling_rate: 0.3,
        main_specular_sampling_rate: 2.0,
        clearcoat_sampling_rate: 0.5,
        ..all
    };
    let glass = PrincipledParams {
        spec_trans: 0.8,
        eta: Some(1.5),
        clearcoat: 0.5,
        ..all
    };
    let thin = PrincipledThinParams {
        roughness: 0.6,
        spec_trans: 0.4,
        diff_trans: 0.3,
        sheen: 0.4,
        ..PrincipledThinParams::default()
    };
    let cases = [
        (
            "all lobes",
            ShadingBsdf::leaf(Bsdf::Principled(Principled::new(all))),
        ),
        (
            "sampling rates",
            ShadingBsdf::leaf(Bsdf::Principled(Principled::new(rates))),
        ),
        (
            "glass",
            ShadingBsdf::leaf(Bsdf::Principled(Principled::new(glass))),
        ),
        (
            "thin",
            ShadingBsdf::leaf(Bsdf::PrincipledThin(PrincipledThin::new(thin))),
        ),
    ];
    let dirs = [dir(10.0, 10.0), dir(60.0, 200.0), dir(150.0, 40.0)];
    let jobs: Vec<_> = cases
        .iter()
        .flat_map(|c| dirs.iter().map(move |&wi| (c, wi)))
        .collect();
    let z = normal_critical_z(sidak(0.01, jobs.len() * 3));
    const N: usize = 400_000;
    let failures: Vec<String> = jobs
        .par_iter()
        .enumerate()
        .filter_map(|(i, ((name, b), wi))| {
            let mut rng = SampleStream::new(0x10be, i as u64, 0);
            let (mut s1, mut q1, mut s2, mut q2) = (
                glam::DVec3::ZERO,
                glam::DVec3::ZERO,
                glam::DVec3::ZERO,
                glam::DVec3::ZERO,
            );
            for _ in 0..N {
                if let Some(bs) = b.sample(*wi, rng.next_1d(), rng.next_2d()) {
                    if !bs.delta {
                        let w = penumbra::spectrum::to_rgb(bs.weight).as_dvec3();
                        s1 += w;
                        q1 += w * w;
                    }
                }
                let wo = square_to_uniform_sphere(rng.next_2d());
                let f = penumbra::spectrum::to_rgb(b.eval(*wi, wo)).as_dvec3()
                    * (4.0 * std::f64::consts::PI);
                s2 += f;
                q2 += f * f;
            }
            let n = N as f64;
            let (m1, m2) = (s1 / n, s2 / n);
            let var = (q1 / n - m1 * m1) / n + (q2 / n - m2 * m2) / n;
            let bad = (0..3).any(|k| (m1[k] - m2[k]).abs() > z * var[k].sqrt());
            bad.then(|| {
                format!(
                    "{name}: wi {wi}: E[weight] {m1} vs ∫ eval {m2} (σ {})",
                    var.map(f64::sqrt)
                )
            })
        })
        .collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn principled_no_nan_or_inf_and_lobes_match_sampling() {
    let dirs = edge_directions();
    let mut rng = SampleStream::new(12, 0, 0);
    for (c, b) in principled_cases() {
        for &wi in &dirs {
            for &wo in &dirs {
                let (f, p) = (b.eval(wi, wo), b.pdf(wi, wo));
                assert!(
                    f.is_finite() && f.min_element() >= 0.0 && p.is_finite() && p >= 0.0,
                    "{}: eval {f} pdf {p} at wi {wi:?} wo {wo:?}",
                    c.name
                );
            }
            let mut smooth = 0;
            for k in 0..256 {
                let (u1, u2) = match k {
                    0 => (0.0, Vec2::ZERO),
                    1 => (0.999_999_9, Vec2::splat(0.999_999_9)),
                    _ => (rng.next_1d(), rng.next_2d()),
                };
                if let Some(bs) = b.sample(wi, u1, u2) {
                    assert!(
                        !bs.delta
                            && bs.weight.is_finite()
                            && bs.weight.min_element() >= 0.0
                            && bs.pdf.is_finite()
                            && bs.pdf > 0.0
                            && bs.eta.is_finite()
                            && bs.eta > 0.0
                            && (bs.wo.length() - 1.0).abs() < 1e-4,
                        "{}: {bs:?} at wi {wi:?}",
                        c.name
                    );
                    smooth += 1;
                }
            }
            if smooth > 0 {
                assert!(b.has_smooth_lobe(wi), "{} at {wi}", c.name);
            }
            if wi.z.abs() > 0.1 && b.has_smooth_lobe(wi) {
                assert!(smooth > 0, "{}: nothing sampled at {wi}", c.name);
            }
        }
    }
}

/// The scene parser reads each principled case's Mitsuba XML into the BSDF its parameters
/// make: every eval and pdf agrees exactly (catches a parameter read under the wrong name, a
/// lost default, `specular` / `eta` / `has_spec_trans` mishandled, or sampling rates
/// swapped).
#[test]
fn principled_xml_reads_the_parameters() {
    let mut rng = SampleStream::new(5, 0, 0);
    for (c, b) in principled_cases() {
        let from_xml = bsdf_from_xml(&c.xml);
        for _ in 0..64 {
            let wi = penumbra::sampling::square_to_uniform_sphere(rng.next_2d());
            let wo = penumbra::sampling::square_to_uniform_sphere(rng.next_2d());
            assert_eq!(b.eval(wi, wo), from_xml.eval(wi, wo), "{}", c.name);
            assert_eq!(b.pdf(wi, wo), from_xml.pdf(wi, wo), "{}", c.name);
            let (u1, u2) = (rng.next_1d(), rng.next_2d());
            let (s1, s2) = (b.sample(wi, u1, u2), from_xml.sample(wi, u1, u2));
            assert_eq!(s1.map(|s| s.wo), s2.map(|s| s.wo), "{}", c.name);
        }
    }
}

/// Every case of this file: the plain BSDFs, Mitsuba's adapters, principled.
fn every_case() -> Vec<(Case, ShadingBsdf)> {
    let mut v: Vec<(Case, ShadingBsdf)> = all_cases()
        .into_iter()
        .chain(adapter_cases())
        .map(|c| {
            let b = bsdf_from_xml(&c.xml);
            (c, b)
        })
        .collect();
    v.extend(principled_cases());
    v
}

/// The integrator continues a path with `sample().weight` and weighs it against light
/// sampling with `sample().pdf`, while next-event estimation uses `eval()` and `pdf()`: for a
/// non-delta sample they must be the same function. For every BSDF (plain, adapted,
/// principled) at the chi-square directions, the edge directions and random ones, 2000
/// samples each: `pdf == pdf(wi, wo)` and `weight · pdf == eval(wi, wo)` within 2e-3
/// relative (f32 round-off through the half-vector and back; a 1% weight or pdf error is 5x
/// that).
#[test]
fn sample_weight_and_pdf_match_eval_and_pdf() {
    const TOL: f32 = 2e-3;
    let cases = every_case();
    let edge = edge_directions();
    let failures: Vec<String> = cases
        .par_iter()
        .enumerate()
        .flat_map_iter(|(i, (c, b))| {
            let mut dirs = incident_directions(b);
            dirs.extend(edge.iter().copied().filter(|d| d.z.abs() > 1e-3));
            let mut rng = SampleStream::new(0x5eed, i as u64, 0);
            let mut out = Vec::new();
            let mut checked = 0usize;
            let smooth = dirs.iter().any(|&wi| b.has_smooth_lobe(wi));
            for wi in dirs {
                for _ in 0..2000 {
                    let Some(bs) = b.sample(wi, rng.next_1d(), rng.next_2d()) else {
                        continue;
                    };
                    if bs.delta {
                        continue;
                    }
                    // The half vector rebuilt from (wi, wo) carries an angular error of
                    // ~ε / cos θ, magnified by 1/α in the microfacet density: skip the
                    // samples where that alone exceeds 2.5e-4 (a few times that in D).
                    let cos = wi.z.abs().min(bs.wo.z.abs());
                    if f32::EPSILON / (c.alpha * cos) > 2.5e-4 {
                        continue;
                    }
                    checked += 1;
                    let p = b.pdf(wi, bs.wo);
                    let f = b.eval(wi, bs.wo);
                    let fs = bs.weight * bs.pdf;
                    let scale = f.max_element().max(fs.max_element());
                    if (bs.pdf - p).abs() > TOL * bs.pdf.max(p)
                        || (fs - f).abs().max_element() > TOL * scale
                    {
                        out.push(format!(
                            "{} {}: wi {wi} wo {}: sample pdf {} vs pdf() {p}, weight·pdf {fs} vs eval {f}",
                            c.name, c.xml, bs.wo, bs.pdf
                        ));
                    }
                }
            }
            if smooth && checked < 1000 {
                out.push(format!("{}: only {checked} non-delta samples", c.name));
            }
            out.truncate(3);
            out
        })
        .collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Light tracing uses BSDFs in importance mode (`ShadingBsdf::importance`): continuing
/// a light path with its sample weight and connecting to the camera with its eval.
/// - For every non-delta sample of every BSDF here, importance `weight · pdf == eval`
///   within 2e-3 relative (as the radiance-mode test above).
/// - Independent truth for the η² factor: the physical BSDF is reciprocal (Veach 1997,
///   §6.2), so on refraction importance eval(wi, wo) |cos θi| equals radiance eval(wo, wi)
///   |cos θo| for the refracting BSDFs (rough dielectric, principled with spec_trans);
///   without the factor it is off by η² = 2.25 (or 1.69 for η = 1.3).
/// - The smooth dielectric (no eval): at normal incidence from outside (η = 1.5) the
///   refracted importance weight is exactly the transmittance 1, radiance's 1/η².
#[test]
fn importance_mode_weight_matches_eval_and_reciprocity() {
    const TOL: f32 = 2e-3;
    let cases = every_case();
    let mut refracting = 0usize;
    let failures: Vec<String> = cases
        .par_iter()
        .enumerate()
        .flat_map_iter(|(i, (c, b))| {
            let imp = b.clone().importance();
            let dirs = incident_directions(b);
            let mut rng = SampleStream::new(0xad10, i as u64, 0);
            let mut out = Vec::new();
            let reciprocal = c.xml.contains("roughdielectric")
                || (c.xml.contains("\"principled\"") && c.xml.contains("spec_trans"));
            for wi in dirs {
                for _ in 0..500 {
                    let (u1, u2) = (rng.next_1d(), rng.next_2d());
                    let Some(bs) = imp.sample(wi, u1, u2) else {
                        continue;
                    };
                    if bs.delta || bs.null {
                        continue;
                    }
                    let cos = wi.z.abs().min(bs.wo.z.abs());
                    if f32::EPSILON / (c.alpha * cos) > 2.5e-4 {
                        continue;
                    }
                    let f = imp.eval(wi, bs.wo);
                    let fs = bs.weight * bs.pdf;
                    let scale = f.max_element().max(fs.max_element());
                    if (fs - f).abs().max_element() > TOL * scale {
                        out.push(format!(
                            "{} {}: wi {wi} wo {}: importance weight·pdf {fs} vs eval {f}",
                            c.name, c.xml, bs.wo
                        ));
                    }
                    if reciprocal && wi.z * bs.wo.z < 0.0 && cos > 0.05 {
                        let lhs = f * wi.z.abs();
                        let rhs = b.eval(bs.wo, wi) * bs.wo.z.abs();
                        let scale = lhs.max_element().max(rhs.max_element());
                        if scale > 1e-6 && (lhs - rhs).abs().max_element() > 1e-2 * scale {
                            out.push(format!(
                                "{}: wi {wi} wo {}: importance f|cos i| {lhs} vs radiance swapped {rhs}",
                                c.name, bs.wo
                            ));
                        }
                        out.push(String::from("#refracting"));
                    }
                }
            }
            out
        })
        .collect();
    refracting += failures.iter().filter(|f| *f == "#refracting").count();
    let failures: Vec<&String> = failures
        .iter()
        .filter(|f| *f != "#refracting")
        .take(6)
        .collect();
    assert!(
        refracting > 1000,
        "only {refracting} refracted samples checked"
    );
    assert!(failures.is_empty(), "{failures:#?}");

    let glass = bsdf_from_xml(
        r#"<bsdf type="dielectric"><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf>"#,
    );
    let wi = Vec3::Z;
    // u1 = 0.99 > F = 0.04: the refracted lobe.
    let imp = glass
        .clone()
        .importance()
        .sample(wi, 0.99, Vec2::splat(0.5))
        .unwrap();
    let rad = glass.sample(wi, 0.99, Vec2::splat(0.5)).unwrap();
    assert!(imp.wo.z < 0.0 && rad.wo.z < 0.0);
    assert!(
        (imp.weight - Spectrum::ONE).abs().max_element() < 1e-6,
        "{}",
        imp.weight
    );
    assert!(
        (rad.weight - Spectrum::splat(1.0 / 2.25))
            .abs()
            .max_element()
            < 1e-6,
        "{}",
        rad.weight
    );
    // From inside: importance 1, radiance η².
    let imp = glass
        .clone()
        .importance()
        .sample(-wi, 0.99, Vec2::splat(0.5))
        .unwrap();
    let rad = glass.sample(-wi, 0.99, Vec2::splat(0.5)).unwrap();
    assert!(
        (imp.weight - Spectrum::ONE).abs().max_element() < 1e-6,
        "{}",
        imp.weight
    );
    assert!(
        (rad.weight - Spectrum::splat(2.25)).abs().max_element() < 1e-5,
        "{}",
        rad.weight
    );
}

/// Importance mode (light paths: `ptracer`, SPPM's photons) scales refraction by η² or 1/η².
/// At an extreme relative IOR that factor overflows f32 (η = 1e20: η² = ∞; η = 1e-20: 1/η² =
/// ∞), and ∞ times a zero transmission is NaN. Every value must stay finite and ≥ 0, as in
/// radiance mode (`no_nan_or_inf_anywhere`): for the refracting BSDFs, and for a principled
/// BSDF without transmission (spec_trans 0), whose scale must not enter at all.
#[test]
fn importance_mode_is_finite_at_extreme_iors() {
    let dirs = edge_directions();
    let mut rng = SampleStream::new(0x10e20, 0, 0);
    let mut checked = 0usize;
    for ior in ["1e20", "1e-20"] {
        let cases = [
            format!(r#"<bsdf type="dielectric"><float name="int_ior" value="{ior}"/></bsdf>"#),
            format!(
                r#"<bsdf type="roughdielectric"><float name="int_ior" value="{ior}"/><float name="alpha" value="0.3"/></bsdf>"#
            ),
            format!(
                r#"<bsdf type="principled"><float name="spec_trans" value="0.5"/><float name="eta" value="{ior}"/></bsdf>"#
            ),
            format!(
                r#"<bsdf type="principled"><float name="spec_trans" value="0"/><float name="eta" value="{ior}"/></bsdf>"#
            ),
        ];
        for xml in &cases {
            let b = bsdf_from_xml(xml).importance();
            for &wi in &dirs {
                for &wo in &dirs {
                    let f = b.eval(wi, wo);
                    assert!(
                        f.is_finite() && f.min_element() >= 0.0,
                        "{xml}: importance eval {f} at wi {wi:?} wo {wo:?}"
                    );
                    checked += 1;
                }
                for _ in 0..16 {
                    let (u1, u2) = (rng.next_1d(), rng.next_2d());
                    if let Some(bs) = b.sample(wi, u1, u2) {
                        assert!(
                            bs.weight.is_finite() && bs.weight.min_element() >= 0.0,
                            "{xml}: importance sample {bs:?} at wi {wi:?}"
                        );
                    }
                }
            }
        }
    }
    assert_eq!(checked, 8 * dirs.len() * dirs.len());
}

/// Float parameters of `principled` are not clamped (Mitsuba takes them as given), so a
/// weight can leave [0, 1]: with metallic 1.5 the dielectric lobes' weight 1 − metallic is
/// negative and each of them is switched off, the sheen included, so that the BSDF stays
/// non-negative. A sheen of 1 then changes nothing, and a negative sheen (−0.5) with a
/// dielectric base adds nothing either.
#[test]
fn principled_sheen_is_off_where_its_weight_is_not_positive() {
    let with = |metallic: f32, sheen: f32| {
        bsdf_from_xml(&format!(
            r#"<bsdf type="principled"><float name="metallic" value="{metallic}"/>
                <float name="sheen" value="{sheen}"/><float name="roughness" value="0.4"/></bsdf>"#
        ))
    };
    for (metallic, sheen) in [(1.5, 1.0), (0.0, -0.5)] {
        let (a, b) = (with(metallic, sheen), with(metallic, 0.0));
        let mut lit = 0;
        for ti in [5.0, 30.0, 60.0, 85.0] {
            for to in [5.0, 30.0, 60.0, 85.0] {
                for po in [0.0, 90.0, 180.0] {
                    let (wi, wo) = (dir(ti, 20.0), dir(to, po));
                    let (fa, fb) = (a.eval(wi, wo), b.eval(wi, wo));
                    assert_eq!(fa, fb, "metallic {metallic}, sheen {sheen}, {wi} -> {wo}");
                    assert!(fa.min_element() >= 0.0, "{fa}");
                    lit += usize::from(fb.max_element() > 0.0);
                }
            }
        }
        // The comparison is between lit values, not zeros (metal or diffuse lobe).
        assert!(lit > 40, "metallic {metallic}: {lit} of 48 pairs lit");
    }
}

/// Every colour parameter a BSDF reads from a texture reaches the BSDF. The material layer
/// builds a BSDF with its constant parameters and patches the textured ones at each shading
/// point (`Bsdf::set_param`, one match arm per BSDF and parameter): a parameter given by a
/// uniform checkerboard must give the BSDF that the same value given as a constant gives
/// (eval, pdf and samples bit for bit), and one that differs from the BSDF without the
/// parameter (Mitsuba's default), so that the value is seen to matter.
#[test]
fn textured_bsdf_parameters_reach_the_bsdf() {
    // (BSDF, parameter, other parameters of all three variants: a conductor's eta and k
    // count only together, as its default is a perfect mirror).
    let cases = [
        ("diffuse", "reflectance", ""),
        ("conductor", "eta", r#"<rgb name="k" value="3"/>"#),
        ("conductor", "k", r#"<rgb name="eta" value="1.5"/>"#),
        ("conductor", "specular_reflectance", ""),
        ("roughconductor", "eta", r#"<rgb name="k" value="3"/>"#),
        ("roughconductor", "k", r#"<rgb name="eta" value="1.5"/>"#),
        ("roughconductor", "specular_reflectance", ""),
        ("dielectric", "specular_reflectance", ""),
        ("dielectric", "specular_transmittance", ""),
        ("thindielectric", "specular_reflectance", ""),
        ("thindielectric", "specular_transmittance", ""),
        ("roughdielectric", "specular_reflectance", ""),
        ("roughdielectric", "specular_transmittance", ""),
        ("plastic", "diffuse_reflectance", ""),
        ("plastic", "specular_reflectance", ""),
        ("roughplastic", "diffuse_reflectance", ""),
        ("roughplastic", "specular_reflectance", ""),
        ("phong", "diffuse_reflectance", ""),
        ("phong", "specular_reflectance", ""),
    ];
    let value = "0.2, 0.3, 0.4";
    // eval and pdf towards a few directions on both sides, and samples of every lobe.
    let probe = |b: &penumbra::material::ShadingBsdf| {
        let wi = Vec3::new(0.3, -0.2, 0.9).normalize();
        let mut out = Vec::new();
        for k in 0..6 {
            let a = k as f32 / 6.0;
            let side = if k % 2 == 0 { 1.0 } else { -1.0 };
            let wo = Vec3::new(a - 0.4, 0.2 - a * 0.5, 0.7 * side).normalize();
            out.extend(b.eval(wi, wo).to_array());
            out.push(b.pdf(wi, wo));
        }
        for u1 in [0.02, 0.3, 0.6, 0.98] {
            match b.sample(wi, u1, Vec2::new(0.3, 0.7)) {
                Some(s) => {
                    out.extend(s.wo.to_array());
                    out.extend(s.weight.to_array());
                    out.push(s.pdf);
                }
                None => out.push(-1.0),
            }
        }
        out
    };
    for (bsdf, param, other) in cases {
        let textured = bsdf_from_xml(&format!(
            r#"<bsdf type="{bsdf}">{other}<texture type="checkerboard" name="{param}">
                <rgb name="color0" value="{value}"/><rgb name="color1" value="{value}"/>
            </texture></bsdf>"#
        ));
        let constant = bsdf_from_xml(&format!(
            r#"<bsdf type="{bsdf}">{other}<rgb name="{param}" value="{value}"/></bsdf>"#
        ));
        let default = bsdf_from_xml(&format!(r#"<bsdf type="{bsdf}">{other}</bsdf>"#));
        let p = probe(&textured);
        assert_eq!(p, probe(&constant), "{bsdf} {param}: textured vs constant");
        assert_ne!(p, probe(&default), "{bsdf} {param}: the value must matter");
    }
}

/// `phong`'s eval against Mitsuba 0.6's modified Phong (`src/bsdfs/phong.cpp`: f times
/// cos θo, as every BSDF here returns it), written in f64 from vectors: f = kd/π + ks (n + 2)
/// / (2π) max(0, cos α)ⁿ with cos α = wo · R, R = 2 (wi · z) z − wi the mirror direction of
/// wi, and 0 when either direction is below the surface. At pairs with different azimuths
/// (the mirror's φ + 180° matters), on and near the mirror direction, at α of 60° and just
/// beyond 90° (diffuse only), at grazing angles and below the horizon; coloured kd and ks, a
/// non-integer exponent. The normalisation tests beside the code look at normal incidence
/// only, where a mirror with the wrong azimuth or a lobe about the normal passes.
#[test]
fn phong_eval_is_mitsuba_06_modified_phong() {
    let (n, kd, ks) = (12.5f64, [0.3f64, 0.2, 0.1], [0.4f64, 0.5, 0.6]);
    let b = bsdf_from_xml(
        r#"<bsdf type="phong"><float name="exponent" value="12.5"/>
            <rgb name="diffuse_reflectance" value="0.3, 0.2, 0.1"/>
            <rgb name="specular_reflectance" value="0.4, 0.5, 0.6"/></bsdf>"#,
    );
    // (θi, φi, θo, φo) in degrees
    let pairs = [
        (30.0, 0.0, 30.0, 180.0),  // the mirror direction: cos α = 1
        (30.0, 40.0, 34.0, 215.0), // near it
        (50.0, 10.0, 20.0, 250.0),
        (60.0, 120.0, 60.0, 120.0), // back towards wi: cos α = cos 120° < 0, diffuse only
        (20.0, 0.0, 70.0, 180.0),   // α = 50° in the plane of incidence
        (45.0, 0.0, 45.0, 90.0),    // α = 60°, out of the plane
        (10.0, 0.0, 85.0, 5.0),     // α just beyond 90°: diffuse only
        (89.0, 200.0, 88.0, 20.5),  // grazing, near the mirror
        (0.0, 0.0, 40.0, 300.0),    // normal incidence
        (30.0, 0.0, 100.0, 180.0),  // wo below the surface
        (120.0, 0.0, 30.0, 180.0),  // wi below the surface
    ];
    let unit = |theta: f64, phi: f64| {
        let (t, p) = (theta.to_radians(), phi.to_radians());
        Vec3::new(
            (t.sin() * p.cos()) as f32,
            (t.sin() * p.sin()) as f32,
            t.cos() as f32,
        )
    };
    let mut lobes = 0;
    for (ti, pi, to, po) in pairs {
        let (wi, wo) = (unit(ti, pi), unit(to, po));
        let got = b.eval(wi, wo);
        // The expected value from the f32 directions penumbra sees, in f64.
        let (wi64, wo64) = (wi.as_dvec3().normalize(), wo.as_dvec3().normalize());
        let z = glam::DVec3::Z;
        let want = if wi64.z <= 0.0 || wo64.z <= 0.0 {
            [0.0; 3]
        } else {
            let mirror = 2.0 * wi64.dot(z) * z - wi64;
            let cos_alpha = wo64.dot(mirror);
            let lobe = if cos_alpha > 0.0 {
                lobes += 1;
                (n + 2.0) / (2.0 * std::f64::consts::PI) * cos_alpha.powf(n)
            } else {
                0.0
            };
            [0, 1, 2].map(|c| (kd[c] / std::f64::consts::PI + ks[c] * lobe) * wo64.z)
        };
        for c in 0..3 {
            let (g, w) = (got[c] as f64, want[c]);
            assert!(
                (g - w).abs() <= 2e-5 * w + 1e-7,
                "wi ({ti}, {pi}) wo ({to}, {po}) channel {c}: {g} vs {w}"
            );
        }
    }
    assert!(lobes >= 6, "{lobes} pairs inside the specular lobe");
}
