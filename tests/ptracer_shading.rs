//! The light tracers' adjoint shading-normal correction (Veach 1997, §5.3 and p. 155; issue
//! 47) on a surface whose interpolated vertex normals differ strongly from its geometric
//! normal (tests/data/ptracer-shading/: a flat grid whose vertex normals lean 10° to 50°
//! away from it). Where the two normals agree the correction is exactly 1, which is why
//! every other light-tracing scene passes without it. Here the particle tracer (`ptracer`)
//! and the photon pass of `sppm` must render the image penumbra's own path tracer renders
//! of the same scene: the path tracer uses the shading normal as it is, and Veach's
//! correction is what makes light tracing estimate the same image with it.
//!
//! - direct.xml (max_depth 2): light → grid → camera. The light tracer's image rests on the
//!   correction at the connection of the grid vertex to the camera.
//! - bounce.xml (max_depth 3): light → grid → panel → camera, the grid out of the camera's
//!   view and the panel flat: the image rests on the correction of the throughput after
//!   sampling the grid's BSDF (ptracer), or of the photon's weight (sppm).
//! - normalmap.xml and bumpmap.xml: direct.xml with a normal or a bump map over the bent
//!   normals. Mitsuba's `normalmap` and `bumpmap` have no adjoint of their own (the nested
//!   BSDF is evaluated in the perturbed frame in either transport mode; the correction sees
//!   the unperturbed shading frame only), so in Mitsuba 3.9.1 a light tracer and a path
//!   tracer render different images of them: these are compared with Mitsuba's ptracer
//!   (validation/references/ptracer-shading-*.exr, rendered by
//!   validation/mitsuba/render_reference.py), as is direct.xml.
//!
//! The formula itself is unit-tested in src/integrator/ptracer.rs.
//!
//! Statistics: two independent images (fixed seeds) are compared pixel by pixel, z =
//! (a − b) / √(σ²_a + σ²_b) with each image's per-pixel variance of the mean, Šidák α =
//! 0.01 over all pixel-channels; and by their image means, α = 0.01 Šidák-corrected over
//! the three channels. SPPM images carry no per-pixel variance, so the sppm test uses the
//! spread of the image mean over independent renders (a t-test, as tests/sppm.rs does).

mod common;
use common::*;
use glam::{Vec2, Vec3};
use penumbra::integrator::Integrator;
use penumbra::math::simpson;
use penumbra::render::Job;
use penumbra::render::RenderOutput;
use penumbra::study::stats::{normal_critical_z, sidak};
use penumbra::study::validation::Reference;

const SEED_PATH: u64 = 0x5ad1;
const SEED_LIGHT: u64 = 0x5ad2;
/// The light tracer's renders compared with Mitsuba (one seed per scene, independent of the
/// renders compared with the path tracer).
const SEED_MITSUBA: u64 = 0x5ad3;

/// One of the scenes of tests/data/ptracer-shading/ with `integrator` at `res` x `res`.
fn scene(file: &str, integrator: &str, res: usize) -> Job {
    let s = load(
        &format!("tests/data/ptracer-shading/{file}"),
        &[("integrator", integrator), ("res", &res.to_string())],
    );
    assert!(
        s.scene.warnings.is_empty(),
        "{file}: {:?}",
        s.scene.warnings
    );
    s
}

/// Per pixel-channel: the pixel's value and the variance of that value.
fn pixels(out: &RenderOutput) -> Pixels {
    let spp = out.film.spp();
    (0..out.film.sum.len())
        .map(|i| {
            let v = out.film.sample_variance_f64(i, spp);
            (out.film.mean_f64(i), v.map(|v| v / spp))
        })
        .collect()
}

/// The image mean per channel and its standard error (pixels independent: box filter).
fn mean_and_se(px: &[([f64; 3], [f64; 3])]) -> ([f64; 3], [f64; 3]) {
    let n = px.len() as f64;
    let mean = std::array::from_fn(|c| px.iter().map(|p| p.0[c]).sum::<f64>() / n);
    let se = std::array::from_fn(|c| (px.iter().map(|p| p.1[c]).sum::<f64>()).sqrt() / n);
    (mean, se)
}

/// Per pixel-channel value and variance of the value.
type Pixels = Vec<([f64; 3], [f64; 3])>;

/// A Mitsuba 3.9.1 reference of validation/references/ (its variance channels are
/// spp × the variance of the pixel value, as penumbra's).
fn reference(name: &str) -> Pixels {
    let r = Reference::read(&repo_path(&format!("validation/references/{name}")))
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    let var = r.image.variance.as_ref().expect("variance channels");
    let spp = r.spp as f64;
    r.image
        .rgb
        .iter()
        .zip(var)
        .map(|(m, v)| (m.map(f64::from), v.map(|v| v as f64 / spp)))
        .collect()
}

/// Compares the light tracer's image `a` with `b` (`who_b`: what rendered it) of the same
/// scene: every pixel-channel (Šidák α = 0.01) and the image means (Šidák α = 0.01 over
/// the channels). Also checks that the comparison can see what it is for: the standard
/// error of the difference of the means is small enough to resolve a `resolve` relative
/// difference at the test's limit, and the images have no black pixel (the scene fills the
/// view) and no pixel of too few splats for its variance estimate to hold (each pixel's
/// relative standard error below 10%).
fn assert_same_image(what: &str, a: &Pixels, b: &Pixels, who_b: &str, resolve: f64) {
    assert_eq!(a.len(), b.len());
    let z_pixel = normal_critical_z(sidak(0.01, a.len() * 3));
    let (mut fails, mut worst, mut worst_at) = (0, 0.0f64, (0, 0));
    for (i, (pa, pb)) in a.iter().zip(b).enumerate() {
        for c in 0..3 {
            for (p, who) in [(pa, "light"), (pb, who_b)] {
                assert!(
                    p.0[c] > 0.0 && p.1[c].sqrt() < 0.1 * p.0[c],
                    "{what}: {who} pixel {i} channel {c}: {} ± {}",
                    p.0[c],
                    p.1[c].sqrt()
                );
            }
            let z = (pa.0[c] - pb.0[c]) / (pa.1[c] + pb.1[c]).sqrt();
            if z.abs() > worst.abs() {
                (worst, worst_at) = (z, (i, c));
            }
            fails += usize::from(z.abs() > z_pixel);
        }
    }
    let ((ma, sa), (mb, sb)) = (mean_and_se(a), mean_and_se(b));
    let z_mean = normal_critical_z(sidak(0.01, 3));
    let (mut problems, mut weak) = (Vec::new(), Vec::new());
    for c in 0..3 {
        let se = (sa[c] * sa[c] + sb[c] * sb[c]).sqrt();
        let z = (ma[c] - mb[c]) / se;
        let line = format!(
            "channel {c}: image mean {:.5} ± {:.5} (light) vs {:.5} ± {:.5} ({who_b}), ratio \
             {:.4}, z = {z:.2} (limit {z_mean:.2})",
            ma[c],
            sa[c],
            mb[c],
            sb[c],
            ma[c] / mb[c]
        );
        eprintln!("{what} {line}");
        if z.abs() >= z_mean {
            problems.push(line);
        }
        if se * z_mean >= resolve * mb[c] {
            weak.push(format!(
                "channel {c}: se {se:.3e} cannot resolve {resolve} of {:.5}",
                mb[c]
            ));
        }
    }
    let (i, c) = worst_at;
    let line = format!(
        "{fails} of {} pixel-channels differ (limit |z| {z_pixel:.2}); worst z = {worst:.2} at \
         pixel {i} channel {c}: {:.5} (light) vs {:.5} ({who_b})",
        a.len() * 3,
        a[i].0[c],
        b[i].0[c]
    );
    eprintln!("{what}: {line}");
    if fails > 0 {
        problems.push(line);
    }
    problems.extend(weak);
    assert!(problems.is_empty(), "{what}: {}", problems.join("; "));
}

/// The scenes are built to need the correction: at every pixel centre of direct.xml the grid
/// seen has a shading normal 11° to 49° away from its geometric one, and Veach's factor for
/// light from the centre of the area light to the camera,
/// |ω_l · n_s| |ω_c · n_g| / (|ω_l · n_g| |ω_c · n_s|), lies between 1.3 and 2.8 (mean
/// 1.9): without it a light tracer's image would be far too dark, everywhere.
#[test]
fn the_scene_needs_the_correction() {
    let s = scene("direct.xml", "ptracer", 16);
    assert!(matches!(s.integrator, Integrator::ParticleTracer(_)));
    // Camera-relative coordinates: the camera at (0, 0, 3) is the origin.
    let light = Vec3::new(2.0, 0.0, 1.5) - Vec3::new(0.0, 0.0, 3.0);
    let (mut lo, mut hi, mut sum) = (f32::INFINITY, 0.0f32, 0.0f32);
    let (mut angle_lo, mut angle_hi) = (f32::INFINITY, 0.0f32);
    for i in 0..16 * 16 {
        let film = Vec2::new((i % 16) as f32 + 0.5, (i / 16) as f32 + 0.5) / 16.0;
        let ray = s.scene.camera.generate_ray(film);
        let si = s
            .scene
            .intersect(&ray)
            .expect("every pixel centre sees the grid");
        let (ng, ns) = (si.ng, si.frame.n);
        let angle = ng.dot(ns).clamp(-1.0, 1.0).acos().to_degrees();
        (angle_lo, angle_hi) = (angle_lo.min(angle), angle_hi.max(angle));
        let wc = -ray.d.normalize();
        let wl = (light - si.p).normalize();
        let f = (wl.dot(ns) * wc.dot(ng) / (wl.dot(ng) * wc.dot(ns))).abs();
        (lo, hi, sum) = (lo.min(f), hi.max(f), sum + f);
    }
    let mean = sum / 256.0;
    eprintln!("angle {angle_lo:.1}..{angle_hi:.1} deg, factor {lo:.3}..{hi:.3}, mean {mean:.3}");
    assert!(angle_lo > 11.0 && angle_hi < 49.0, "{angle_lo}..{angle_hi}");
    assert!(
        lo > 1.3 && hi < 2.8 && mean > 1.8,
        "{lo}..{hi}, mean {mean}"
    );
}

/// direct.xml: the particle tracer and the path tracer render the same image. Without the
/// correction at the camera connection the light tracer's image is ~40% too dark.
#[test]
fn ptracer_matches_path_with_shading_normals_direct() {
    let (res, spp) = (16, 4096);
    let light = render_scene(&scene("direct.xml", "ptracer", res), spp, SEED_LIGHT, None);
    let path = render_scene(&scene("direct.xml", "path", res), spp, SEED_PATH, None);
    assert_eq!(light.stats.nonfinite + path.stats.nonfinite, 0);
    assert_same_image("direct.xml", &pixels(&light), &pixels(&path), "path", 0.02);
}

/// bounce.xml: the same after one bounce off the bent normals, which the camera does not
/// see: the correction of the throughput after BSDF sampling at the grid.
#[test]
fn ptracer_matches_path_with_shading_normals_after_a_bounce() {
    // ~1 particle in 60 reaches the panel in view: 32768 spp land ~500 splats per pixel.
    let res = 8;
    let light = render_scene(
        &scene("bounce.xml", "ptracer", res),
        32768,
        SEED_LIGHT,
        None,
    );
    let path = render_scene(&scene("bounce.xml", "path", res), 16384, SEED_PATH, None);
    assert_eq!(light.stats.nonfinite + path.stats.nonfinite, 0);
    assert_same_image("bounce.xml", &pixels(&light), &pixels(&path), "path", 0.02);
}

/// penumbra's particle tracer against Mitsuba 3.9.1's (`ptracer`, which applies the same
/// correction) on `name`.xml: the reference validation/references/ptracer-shading-`name`.exr
/// (262144 spp in 1024 passes of 256, its variance from the spread of the passes: 1023
/// degrees of freedom per pixel, and 1/64 of the variance of penumbra's 4096 spp, so the
/// normal quantiles hold), per pixel and by the image mean.
fn assert_matches_mitsuba(name: &str, seed: u64) {
    let out = render_scene(
        &scene(&format!("{name}.xml"), "ptracer", 16),
        4096,
        seed,
        None,
    );
    assert_eq!(out.stats.nonfinite, 0);
    let r = reference(&format!("ptracer-shading-{name}.exr"));
    assert_same_image(&format!("{name}.xml"), &pixels(&out), &r, "Mitsuba", 0.02);
}

/// direct.xml against Mitsuba's ptracer (whose image mean, 0.14759, is its path tracer's
/// too).
#[test]
fn ptracer_matches_mitsuba_with_shading_normals() {
    assert_matches_mitsuba("direct", SEED_MITSUBA);
}

/// normalmap.xml: a normal map over the bent vertex normals, against Mitsuba's ptracer (a
/// path tracer renders another image here: see the scene file).
#[test]
fn ptracer_matches_mitsuba_with_a_normal_map_on_shading_normals() {
    assert_matches_mitsuba("normalmap", SEED_MITSUBA + 1);
}

/// bumpmap.xml: a bump map over the bent vertex normals, against Mitsuba's ptracer.
#[test]
fn ptracer_matches_mitsuba_with_a_bump_map_on_shading_normals() {
    assert_matches_mitsuba("bumpmap", SEED_MITSUBA + 2);
}

/// Two-sided Student t quantile for `dof` degrees of freedom at `alpha`, by bisection on
/// the distribution's tail (its density integrated numerically), as tests/sppm.rs does.
fn t_quantile(dof: f64, alpha: f64) -> f64 {
    let dens = |t: f64| (1.0 + t * t / dof).powf(-(dof + 1.0) / 2.0);
    let integral = |a: f64, b: f64| simpson(dens, a, b, 20_000);
    let total = 2.0 * integral(0.0, 200.0);
    let (mut lo, mut hi) = (0.0f64, 100.0f64);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if 1.0 - 2.0 * integral(0.0, mid) / total > alpha {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// bounce.xml with sppm: the panel's light is all photons (its visible points see no
/// emitter: the camera pass adds nothing), deposited at their second hit after the
/// photon's weight was corrected at the grid. The image mean over 16 independent renders
/// against the path tracer's: a t-test with 15 degrees of freedom (the path tracer's
/// standard error, from 1M samples, only raises the Welch–Satterthwaite degrees of freedom,
/// so 15 is conservative), Šidák α = 0.01 over the channels. The gather radius starts at a
/// pixel footprint (0.05 here) and shrinks; the panel extends beyond the view by more than
/// that, so no gather disk reaches off the panel (with the panel's edge 0.02 from the view's,
/// the image mean came out 1.1% low, 2.5 standard errors over 32 renders).
#[test]
fn sppm_photons_match_path_with_shading_normals() {
    let res = 16;
    let mut s = scene("bounce.xml", "sppm", res);
    let Integrator::Sppm(sppm) = &mut s.integrator else {
        panic!("not sppm")
    };
    sppm.photon_count = 20_000;
    let k = 16u64;
    let means: Vec<[f64; 3]> = (0..k)
        .map(|i| {
            let out = render_scene(&s, 16, 0x5f0 + i, None);
            assert_eq!(out.stats.nonfinite, 0);
            let img = out.film.image();
            let n = img.len() as f64;
            std::array::from_fn(|c| img.iter().map(|p| p[c] as f64).sum::<f64>() / n)
        })
        .collect();
    let kf = k as f64;
    let path = render_scene(&scene("bounce.xml", "path", res), 4096, SEED_PATH, None);
    let (mp, sp) = mean_and_se(&pixels(&path));
    let t_crit = t_quantile(kf - 1.0, sidak(0.01, 3));
    for c in 0..3 {
        let m = means.iter().map(|x| x[c]).sum::<f64>() / kf;
        let var = means.iter().map(|x| (x[c] - m).powi(2)).sum::<f64>() / (kf - 1.0);
        let se_sppm = (var / kf).sqrt();
        let se = (se_sppm * se_sppm + sp[c] * sp[c]).sqrt();
        let t = (m - mp[c]) / se;
        eprintln!(
            "sppm channel {c}: {m:.5} ± {se_sppm:.5} vs path {:.5} ± {:.5}, ratio {:.4}, t {t:.2} \
             (limit {t_crit:.2})",
            mp[c],
            sp[c],
            m / mp[c]
        );
        assert!(
            t.abs() < t_crit,
            "channel {c}: sppm image mean {m} ± {se_sppm} vs path {} ± {}, ratio {:.4}, t = \
             {t:.2} (limit {t_crit:.2})",
            mp[c],
            sp[c],
            m / mp[c]
        );
        // Resolves a 3% error at the test's limit.
        assert!(se * t_crit < 0.03 * mp[c], "se {se} of {}", mp[c]);
    }
}
