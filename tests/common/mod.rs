//! Helpers shared by the scene-level tests.
#![allow(dead_code)]

use penumbra::render::{Job, RenderOutput, RenderSettings};
use std::path::{Path, PathBuf};

pub fn repo_path(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

pub fn scene_from_str(xml: &str) -> Job {
    Job::from_xml_str(xml, &repo_path("tests/inline.xml"), &[]).expect("scene builds")
}

/// The scene at `rel` rendered with integrator `kind` instead of its own (`--integrator`).
pub fn load_with_integrator(rel: &str, defines: &[(&str, &str)], kind: &str) -> Job {
    let defines: Vec<(String, String)> = defines
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    let mut desc =
        penumbra::scene::Scene::load_description(&repo_path(rel), &defines).expect("scene loads");
    desc.use_integrator(kind).expect("integrator switches");
    Job::build(&desc).expect("scene builds")
}

pub fn load(rel: &str, defines: &[(&str, &str)]) -> Job {
    let defines: Vec<(String, String)> = defines
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    Job::load(&repo_path(rel), &defines).expect("scene loads")
}

pub fn render_scene(job: &Job, spp: u32, seed: u64, threads: Option<usize>) -> RenderOutput {
    job.render(
        &RenderSettings {
            spp,
            seed,
            threads,
            sampler: None,
            first_sample: 0,
        },
        &|_, _| {},
    )
    .expect("render")
}

/// Per-channel mean over all pixels of the image and the standard error of that mean,
/// estimated from the per-pixel sample variances (pixels are independent).
pub fn image_mean_and_se(out: &RenderOutput, spp: u32) -> ([f64; 3], [f64; 3]) {
    let img = out.film.image();
    let var = out.film.sample_variance();
    let n = img.len() as f64;
    let mut mean = [0.0; 3];
    let mut se = [0.0; 3];
    for c in 0..3 {
        mean[c] = img.iter().map(|p| p[c] as f64).sum::<f64>() / n;
        let v: f64 = var.iter().map(|p| p[c] as f64 / spp as f64).sum::<f64>() / (n * n);
        se[c] = v.sqrt();
    }
    (mean, se)
}

/// Builds the BSDF of a `<bsdf>` element through the scene parser (as a rectangle's BSDF),
/// as it is at the rectangle's centre (uv = (0.5, 0.5), shading frame = the local frame).
pub fn bsdf_from_xml(bsdf: &str) -> penumbra::material::ShadingBsdf {
    let xml = format!(
        r#"<scene version="3.0.0">
            <sensor type="perspective"><float name="fov" value="45"/>
                <film type="hdrfilm"><integer name="width" value="4"/>
                    <integer name="height" value="4"/><rfilter type="box"/></film></sensor>
            <shape type="rectangle">{bsdf}</shape></scene>"#
    );
    let scene = scene_from_str(&xml).scene;
    let ctx = penumbra::material::ShadingContext {
        tex: penumbra::texture::TextureContext::at_uv(glam::Vec2::splat(0.5)),
        frame: penumbra::geometry::Frame::from_normal(glam::Vec3::Z),
        dp_du: glam::Vec3::X,
        dp_dv: glam::Vec3::Y,
        ng: glam::Vec3::Z,
    };
    penumbra::material::Material::shading_bsdf(&scene.materials, scene.shapes[0].material, &ctx)
}

/// What [`compare_instanced_hits`] checks beyond hit or miss, t, p and the geometric normal.
pub struct HitChecks {
    /// Largest |ng_direct − ng_instanced|.
    pub ng_tolerance: f32,
    /// Also compare uv, the shading tangent, and the two points against their error bounds.
    pub surface_details: bool,
}

/// Traces each of `rays` in a scene with a shape placed directly and in one with the shape
/// instanced by the same transform: both must hit or both miss, at the same t and p (1e-5
/// relative) with the same geometric normal, and with `surface_details` the same uv and
/// shading tangent (1e-4) and points within each other's error bounds. Returns the number of
/// hits; `what` names the case in messages.
pub fn compare_instanced_hits(
    direct: &penumbra::scene::Scene,
    instanced: &penumbra::scene::Scene,
    rays: impl IntoIterator<Item = penumbra::geometry::Ray>,
    checks: &HitChecks,
    what: &str,
) -> usize {
    let mut hits = 0;
    for (i, r) in rays.into_iter().enumerate() {
        let (a, b) = (direct.intersect(&r), instanced.intersect(&r));
        assert_eq!(a.is_some(), b.is_some(), "{what}: ray {i}");
        let (Some(a), Some(b)) = (a, b) else {
            continue;
        };
        hits += 1;
        assert!(
            (a.t - b.t).abs() <= 1e-5 * a.t,
            "{what} ray {i}: {} vs {}",
            a.t,
            b.t
        );
        assert!(
            (a.ng - b.ng).length() < checks.ng_tolerance,
            "{what} ray {i}: {} vs {}",
            a.ng,
            b.ng
        );
        assert!(
            (a.p - b.p).length() <= 1e-5 * a.p.length(),
            "{what} ray {i}"
        );
        if checks.surface_details {
            assert!((a.uv - b.uv).length() < 1e-4, "{what} ray {i}");
            assert!((a.frame.s - b.frame.s).length() < 1e-4, "{what} ray {i}");
            // The error bound covers the difference between the two computations.
            let d = (a.p - b.p).abs();
            assert!(
                d.cmple(a.p_error + b.p_error).all(),
                "{what} ray {i}: {d} vs {} + {}",
                a.p_error,
                b.p_error
            );
        }
    }
    hits
}

/// The unpolarised reflectance of a smooth interface from a medium of index `n_i` into one of
/// index `n_t`, at incidence cosine `cos_i` ∈ [0, 1], in f64: Fresnel's equations in their
/// angle form (Born and Wolf, "Principles of Optics", §1.5.2), R_s = sin²(θi − θt) /
/// sin²(θi + θt) and R_p = tan²(θi − θt) / tan²(θi + θt), with θt from Snell's law
/// n_i sin θi = n_t sin θt, and R = (R_s + R_p)/2; 1 beyond the critical angle, and
/// ((n_i − n_t)/(n_i + n_t))² at normal incidence (the limit of both). Written from the
/// physics, independently of penumbra's `fresnel_dielectric` (the amplitude form in
/// cosines), so that tests of glass do not check penumbra against itself.
pub fn fresnel_reflectance(cos_i: f64, n_i: f64, n_t: f64) -> f64 {
    let theta_i = cos_i.clamp(0.0, 1.0).acos();
    let sin_t = n_i / n_t * theta_i.sin();
    if sin_t >= 1.0 {
        return 1.0;
    }
    if theta_i == 0.0 {
        return ((n_i - n_t) / (n_i + n_t)).powi(2);
    }
    let theta_t = sin_t.asin();
    let (minus, plus) = (theta_i - theta_t, theta_i + theta_t);
    let rs = (minus.sin() / plus.sin()).powi(2);
    let rp = (minus.tan() / plus.tan()).powi(2);
    0.5 * (rs + rp)
}

/// [`fresnel_reflectance`] in Mitsuba's convention for a dielectric of relative index `eta`
/// (inside over outside): `cos_theta` > 0 on the outside, < 0 on the inside.
pub fn fresnel_of_side(cos_theta: f64, eta: f64) -> f64 {
    if cos_theta >= 0.0 {
        fresnel_reflectance(cos_theta, 1.0, eta)
    } else {
        fresnel_reflectance(-cos_theta, eta, 1.0)
    }
}
