//! Mitsuba 3's own render regression suite, judged by Mitsuba's own rule.
//!
//! The suite (`validation/mitsuba-suite/`, a copy of the test scenes of Mitsuba's data
//! repository with their RGB references) holds scenes `tests/scenes/<group>/<name>_<integrator>.xml`
//! and references `tests/scenes/<group>/refs/<name>_ref_rgb.exr` with their per-sample variance
//! `<name>_ref_rgb_var.exr`. Mitsuba's `test_renders.py` renders each scene with
//! spp = 2,000,000 / pixels, seed 0 and the integrator named by the file name's last word, and
//! accepts it when at least 99.75% of the pixel-channels pass a z-test against the reference:
//!
//! 1. render, reference and reference variance are converted from linear sRGB to CIE XYZ (the
//!    variance through the same matrix, as Mitsuba does);
//! 2. the reference variance is clamped below at 1e-4;
//! 3. per pixel and channel z = |render − ref| · √(spp / var_ref) and p = 2 (1 − Φ(z));
//! 4. a pixel-channel passes when p > α, with α Šidák-corrected from 0.01 over the pixel count.
//!
//! Only the reference's variance enters the test (the render is assumed as noisy as Mitsuba's),
//! so a correct renderer with more variance than Mitsuba on a scene can fail it: the mean
//! difference per channel is reported beside it.
//!
//! In spectral mode ([`discover`] with [`Mode::Spectral`]) each scene renders with
//! `--mode spectral` against Mitsuba's spectral references `<name>_ref_spectral.exr` and
//! `_ref_spectral_var.exr` (RGB images of `scalar_spectral` renders), by the same rule.

use crate::error::Error;
use crate::io::exr;
use crate::render::{render, Job, RenderSettings};
use crate::spectrum::Mode;
use crate::study::stats::{normal_critical_z, normal_two_sided_p, sidak};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Mitsuba's sample budget per scene.
pub const SAMPLE_BUDGET: usize = 2_000_000;
/// Mitsuba's significance level before the Šidák correction.
pub const SIGNIFICANCE: f64 = 0.01;
/// Mitsuba's share of pixel-channels that must pass.
pub const PASS_FRACTION: f64 = 0.9975;
/// Mitsuba's lower clamp of the reference variance.
pub const VARIANCE_FLOOR: f64 = 1e-4;

/// One scene of the suite.
#[derive(Clone, Debug)]
pub struct SuiteScene {
    /// `<group>/<file stem>`, e.g. `bsdf_spheres/test_roughdielectric_path`.
    pub name: String,
    pub path: PathBuf,
    /// The file name's last word: `path`, `direct`, `volpath`, ...
    pub integrator: String,
    pub reference: PathBuf,
    pub variance: PathBuf,
    /// RGB or spectral: the mode it renders in, and which references judge it.
    pub mode: Mode,
}

/// Every scene of the suite under `root`, sorted by name, to be rendered in `mode` and judged
/// against that mode's references.
pub fn discover(root: &Path, mode: Mode) -> std::io::Result<Vec<SuiteScene>> {
    let kind = match mode {
        Mode::Rgb => "rgb",
        Mode::Spectral => "spectral",
    };
    let mut scenes = Vec::new();
    let scenes_dir = root.join("tests/scenes");
    let mut groups: Vec<PathBuf> = std::fs::read_dir(&scenes_dir)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_dir())
        .collect();
    groups.sort();
    for group in groups {
        let group_name = group
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let mut files: Vec<PathBuf> = std::fs::read_dir(&group)?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "xml"))
            .collect();
        files.sort();
        for path in files {
            let stem = path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            let Some((base, integrator)) = stem.rsplit_once('_') else {
                continue;
            };
            let refs = group.join("refs");
            scenes.push(SuiteScene {
                name: format!("{group_name}/{stem}"),
                integrator: integrator.to_string(),
                reference: refs.join(format!("{base}_ref_{kind}.exr")),
                variance: refs.join(format!("{base}_ref_{kind}_var.exr")),
                path,
                mode,
            });
        }
    }
    Ok(scenes)
}

/// What Mitsuba's rule says of one render.
#[derive(Clone, Debug)]
pub struct Judgement {
    pub spp: u32,
    pub pixels: usize,
    /// Share of pixel-channels whose p-value exceeds the corrected α.
    pub pass_fraction: f64,
    pub passed: bool,
    /// Per channel (R, G, B): (mean of the render − mean of the reference) / mean of the
    /// reference.
    pub mean_rel_diff: [f64; 3],
    /// Per channel: the standard error of the render's image mean, √(Σ σ²_p / spp) / pixels,
    /// with σ²_p the larger of the reference's and the render's own per-sample variance
    /// summed over the pixels (the reference's noise is neglected, as Mitsuba's rule does).
    pub mean_se: [f64; 3],
    /// Per channel: (mean of the render − mean of the reference) / [`Judgement::mean_se`].
    pub mean_z: [f64; 3],
    /// The mean of the reference, per channel.
    pub reference_mean: [f64; 3],
    /// Wall time of the render (scene loading excluded), seconds.
    pub seconds: f64,
}

/// The outcome of one scene: it could not be loaded or rendered (the one-line error, which
/// names the first construct penumbra does not support), or it was judged.
#[derive(Clone, Debug)]
pub enum Outcome {
    Unsupported(String),
    Judged(Judgement),
}

impl Judgement {
    /// The image-mean test's negative control for channel `c`: where the test at level
    /// `alpha` has at least 95% power to see the render's mean scaled by `k`
    /// (|k − 1| · mean / se ≥ z_α + 1.645), the z of the render × `k` against the reference;
    /// `None` where it has not.
    pub fn scaled_mean_z(&self, c: usize, k: f64, alpha: f64) -> Option<f64> {
        let shift = (k - 1.0) * self.reference_mean[c].abs() / self.mean_se[c];
        (shift.abs() >= normal_critical_z(alpha) + 1.645).then(|| {
            self.mean_z[c]
                + (k - 1.0) * self.reference_mean[c] * (1.0 + self.mean_rel_diff[c])
                    / self.mean_se[c]
        })
    }

    /// `pass` or `FAIL`, the share of passing pixel-channels and the mean differences, for
    /// tables and logs.
    pub fn summary(&self) -> String {
        format!(
            "{} {:.2}% | {:+.2}% / {:+.2}% / {:+.2}%",
            if self.passed { "pass" } else { "FAIL" },
            100.0 * self.pass_fraction,
            100.0 * self.mean_rel_diff[0],
            100.0 * self.mean_rel_diff[1],
            100.0 * self.mean_rel_diff[2],
        )
    }
}

/// Mitsuba's `srgb_to_xyz` (single-precision coefficients, as in its source).
fn srgb_to_xyz(c: [f32; 3]) -> [f64; 3] {
    const M: [[f32; 3]; 3] = [
        [0.412453, 0.357580, 0.180423],
        [0.212671, 0.715160, 0.072169],
        [0.019334, 0.119193, 0.950227],
    ];
    M.map(|row| (0..3).map(|k| row[k] as f64 * c[k] as f64).sum())
}

/// Mitsuba's acceptance rule for a render at `spp` against a reference and its per-sample
/// variance (all linear sRGB, same size): (share of pixel-channels passing, accepted).
pub fn z_test(
    render: &[[f32; 3]],
    reference: &[[f32; 3]],
    variance: &[[f32; 3]],
    spp: u32,
) -> (f64, bool) {
    let pixels = reference.len();
    let alpha = sidak(SIGNIFICANCE, pixels);
    let mut passing = 0usize;
    for i in 0..pixels {
        let (a, r, v) = (
            srgb_to_xyz(render[i]),
            srgb_to_xyz(reference[i]),
            srgb_to_xyz(variance[i]),
        );
        for c in 0..3 {
            let var = v[c].max(VARIANCE_FLOOR);
            let z = (a[c] - r[c]).abs() * (spp as f64 / var).sqrt();
            // A NaN render value fails (p is NaN, not > α).
            if normal_two_sided_p(z) > alpha {
                passing += 1;
            }
        }
    }
    let fraction = passing as f64 / (3 * pixels).max(1) as f64;
    (
        fraction,
        passing as f64 / 3.0 >= PASS_FRACTION * pixels as f64,
    )
}

/// Renders one scene as Mitsuba's test does and judges it; `threads` as in
/// [`RenderSettings::threads`].
pub fn run(scene: &SuiteScene, threads: Option<usize>) -> Outcome {
    run_with(scene, threads, &mut |_| true)
        .unwrap_or_else(|| Outcome::Unsupported(format!("{}: not run", scene.name)))
}

/// [`run`] with the loaded scene changed by `adjust` before the render (a negative control:
/// one bounce short, say); `None` where `adjust` declines the scene (returns false).
pub fn run_with(
    scene: &SuiteScene,
    threads: Option<usize>,
    adjust: &mut dyn FnMut(&mut Job) -> bool,
) -> Option<Outcome> {
    match try_run(scene, threads, adjust) {
        Ok(Some(j)) => Some(Outcome::Judged(j)),
        Ok(None) => None,
        Err(e) => Some(Outcome::Unsupported(e.to_string())),
    }
}

fn try_run(
    scene: &SuiteScene,
    threads: Option<usize>,
    adjust: &mut dyn FnMut(&mut Job) -> bool,
) -> Result<Option<Judgement>, Error> {
    let reference = exr::read(&scene.reference)?;
    let variance = exr::read(&scene.variance)?;
    let pixels = reference.width * reference.height;
    if pixels == 0 || variance.width != reference.width || variance.height != reference.height {
        return Err(Error::Invalid(format!(
            "{}: reference and variance sizes differ or are empty",
            scene.name
        )));
    }
    let spp = (SAMPLE_BUDGET / pixels).max(1) as u32;
    let defines = vec![
        ("spp".to_string(), spp.to_string()),
        ("integrator".to_string(), scene.integrator.clone()),
    ];
    let mut job = Job::load_in(&scene.path, &defines, scene.mode)?;
    if !adjust(&mut job) {
        return Ok(None);
    }
    let loaded = &job.scene;
    if loaded.width != reference.width || loaded.height != reference.height {
        return Err(Error::Invalid(format!(
            "{}: the scene renders {}x{}, its reference is {}x{}",
            scene.name, loaded.width, loaded.height, reference.width, reference.height
        )));
    }
    let start = Instant::now();
    let out = render(
        loaded,
        &job.integrator,
        &RenderSettings {
            spp,
            first_sample: 0,
            seed: 0,
            threads,
            sampler: None,
        },
        &|_, _| {},
    )?;
    let seconds = start.elapsed().as_secs_f64();
    let image = out.film.image();
    let (pass_fraction, passed) = z_test(&image, &reference.rgb, &variance.rgb, spp);
    let mean = |img: &[[f32; 3]], c: usize| {
        img.iter().map(|p| p[c] as f64).sum::<f64>() / img.len() as f64
    };
    let mean_rel_diff = [0, 1, 2].map(|c| {
        let r = mean(&reference.rgb, c);
        (mean(&image, c) - r) / r.abs().max(1e-12)
    });
    let own = out.film.sample_variance();
    let sum = |img: &[[f32; 3]], c: usize| img.iter().map(|p| p[c] as f64).sum::<f64>();
    let mean_se = [0, 1, 2].map(|c| {
        let var = sum(&variance.rgb, c).max(sum(&own, c));
        (var / spp as f64).sqrt() / pixels as f64
    });
    let reference_mean = [0, 1, 2].map(|c| mean(&reference.rgb, c));
    let mean_z = [0, 1, 2]
        .map(|c| (mean(&image, c) - reference_mean[c]) / mean_se[c].max(f64::MIN_POSITIVE));
    Ok(Some(Judgement {
        spp,
        pixels,
        pass_fraction,
        passed,
        mean_rel_diff,
        mean_se,
        mean_z,
        reference_mean,
        seconds,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rule on synthetic images: a render within noise of the reference passes, one 2%
    /// too bright with tiny variance fails, and the 99.75% threshold counts pixel-channels.
    #[test]
    fn z_test_follows_mitsubas_rule() {
        let n = 400;
        let reference = vec![[0.5f32; 3]; n];
        let variance = vec![[0.01f32; 3]; n];
        // z = 0.001 · √(1000 / 0.01·k): far below the critical value.
        let close = vec![[0.501f32; 3]; n];
        assert!(z_test(&close, &reference, &variance, 1000).1);
        let bright = vec![[0.51f32; 3]; n];
        let (fraction, passed) = z_test(&bright, &reference, &variance, 100_000);
        assert!(!passed && fraction < 0.01, "{fraction}");
        // One bad pixel in 400 (0.25%) is still accepted; two are not.
        let mut one_bad = close.clone();
        one_bad[7] = [5.0; 3];
        assert!(z_test(&one_bad, &reference, &variance, 1000).1);
        let mut two_bad = one_bad.clone();
        two_bad[8] = [5.0; 3];
        assert!(!z_test(&two_bad, &reference, &variance, 1000).1);
        // NaN fails its pixel.
        let mut nan = close.clone();
        nan[0] = [f32::NAN; 3];
        nan[1] = [f32::NAN; 3];
        assert!(!z_test(&nan, &reference, &variance, 1000).1);
    }
}
