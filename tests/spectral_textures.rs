//! Spectral mode's bitmap texture and envmap emitter against Mitsuba 3.9.1's own lookups in
//! its scalar_spectral variant (validation/mitsuba/spectral_textures.py →
//! tests/data/spectral/mitsuba_spectral_textures.txt).
//!
//! Two kinds of check each:
//! - **structure**, exact: penumbra's texture or envmap built from Mitsuba's own coefficients
//!   (its `srgb_model_fetch`) must give Mitsuba's values to f32 rounding: which texels, the
//!   spectra interpolated (not the coefficients), the weights, the envmap's s and D65;
//! - **loading**: the image loaded as spectral mode loads it is exactly the texture of
//!   penumbra's own upsampling of its texels; that upsampling (its fitted table) differs
//!   from Mitsuba's by amounts `fit`'s tests measure, and which these tests report.

use glam::{DMat3, Mat3, Vec2, Vec3, Vec4};
use penumbra::emitter::EnvMapEmitter;
use penumbra::spectral::{srgb_model_eval, srgb_model_fetch};
use penumbra::texture::bitmap::{BitmapTexture, Filter, Format, TexImage, Wrap};
use std::path::{Path, PathBuf};
use std::sync::Arc;

fn data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/spectral")
        .join(rel)
}

fn lines() -> Vec<Vec<String>> {
    std::fs::read_to_string(data("mitsuba_spectral_textures.txt"))
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| l.split_whitespace().map(String::from).collect())
        .collect()
}

fn nums(f: &[String]) -> Vec<f32> {
    f.iter().map(|s| s.parse().unwrap()).collect()
}

/// `coeff NAME i r g b c0 c1 c2 [s]` lines of one image: (rgb, coefficients (and s)).
fn coefficients(name: &str) -> Vec<([f32; 3], Vec<f32>)> {
    lines()
        .iter()
        .filter(|f| f[0] == "coeff" && f[1] == name)
        .map(|f| {
            let v = nums(&f[3..]);
            ([v[0], v[1], v[2]], v[3..].to_vec())
        })
        .collect()
}

/// `bitmap FILTER WRAP u v l0..l3 s0..s3` lines: (filter, wrap, uv, wavelengths, value).
fn bitmap_lookups() -> Vec<(Filter, Wrap, Vec2, Vec4, Vec4)> {
    lines()
        .iter()
        .filter(|f| f[0] == "bitmap")
        .map(|f| {
            let v = nums(&f[3..]);
            (
                Filter::from_name(&f[1]).unwrap(),
                Wrap::from_name(&f[2]).unwrap(),
                Vec2::new(v[0], v[1]),
                Vec4::from_slice(&v[2..6]),
                Vec4::from_slice(&v[6..10]),
            )
        })
        .collect()
}

const TEX_SIZE: (usize, usize) = (3, 2);

/// Every lookup of the 3x2 test bitmap, with Mitsuba's coefficients: f32 rounding only
/// (1e-6 on spectra in [0, 1]; both sides evaluate the same sigmoid and the same fused
/// multiply-adds). Also Mitsuba's mean (the mean of srgb_model_mean over the texels).
#[test]
fn bitmap_structure_matches_mitsuba() {
    let coeffs: Vec<f32> = coefficients("tex")
        .iter()
        .flat_map(|(_, c)| c.clone())
        .collect();
    let img = Arc::new(TexImage::from_coefficients(TEX_SIZE.0, TEX_SIZE.1, coeffs).unwrap());
    let lookups = bitmap_lookups();
    assert!(lookups.len() >= 900, "{}", lookups.len());
    let mut worst = 0.0f32;
    for (filter, wrap, uv, wl, want) in &lookups {
        let tex = BitmapTexture::new(img.clone(), *filter, *wrap, DMat3::IDENTITY);
        let got = tex.eval_spectrum(*uv, *wl);
        let d = (got - *want).abs().max_element();
        worst = worst.max(d);
        assert!(
            d <= 1e-6,
            "{filter:?} {wrap:?} uv {uv} at {wl}: {got} vs Mitsuba {want}"
        );
    }
    for f in lines().iter().filter(|f| f[0] == "bitmap_mean") {
        let m: f32 = f[3].parse().unwrap();
        assert!((img.mean() - m).abs() <= 1e-6, "mean {} vs {m}", img.mean());
    }
    eprintln!("bitmap structure: worst difference {worst:e}");
}

/// The image itself, loaded as spectral mode loads it (EXR data linear, f32 storage, one
/// texel above 1): every lookup equals, bit for bit, the lookup of the texture made of
/// penumbra's upsampling (`srgb_model_fetch`, which clamps to [0, 1] as Mitsuba's does) of
/// the texels Mitsuba read. Together with the structure test above this is Mitsuba's texture
/// up to the two upsampling tables' difference, which `fit`'s tests measure; here it is
/// reported (largest difference of the texels' spectra at the lookups' wavelengths).
#[test]
fn bitmap_loaded_is_the_upsampled_image() {
    let texels = coefficients("tex");
    let img = Arc::new(TexImage::load_spectral(&data("tex_rgb.exr"), false, Format::Auto).unwrap());
    assert!(img.holds_coefficients());
    let ours: Vec<f32> = texels
        .iter()
        .flat_map(|(rgb, _)| srgb_model_fetch(*rgb))
        .collect();
    let expected = Arc::new(TexImage::from_coefficients(TEX_SIZE.0, TEX_SIZE.1, ours).unwrap());
    assert_eq!(img.mean(), expected.mean());
    let mut table_difference = 0.0f32;
    for (filter, wrap, uv, wl, _) in bitmap_lookups() {
        let tex = BitmapTexture::new(img.clone(), filter, wrap, DMat3::IDENTITY);
        let want = BitmapTexture::new(expected.clone(), filter, wrap, DMat3::IDENTITY);
        assert_eq!(
            tex.eval_spectrum(uv, wl),
            want.eval_spectrum(uv, wl),
            "{uv} {wl}"
        );
        for (rgb, c) in &texels {
            let a = srgb_model_eval(srgb_model_fetch(*rgb), wl);
            let b = srgb_model_eval([c[0], c[1], c[2]], wl);
            table_difference = table_difference.max((a - b).abs().max_element());
        }
    }
    eprintln!("bitmap texels: upsampling tables differ by up to {table_difference:e}");
}

/// `envmap SCALE dx dy dz l0..l3 s0..s3` lines: (scale, d, wavelengths, value).
fn envmap_lookups() -> Vec<(f32, Vec3, Vec4, Vec4)> {
    lines()
        .iter()
        .filter(|f| f[0] == "envmap")
        .map(|f| {
            let v = nums(&f[1..]);
            (
                v[0],
                Vec3::new(v[1], v[2], v[3]),
                Vec4::from_slice(&v[4..8]),
                Vec4::from_slice(&v[8..12]),
            )
        })
        .collect()
}

const ENV_SIZE: (usize, usize) = (4, 3);

/// The envmap's radiance with Mitsuba's coefficients and s, in every direction but the two
/// poles. Tolerance 2e-6 relative to the
/// value plus 1e-6 relative to the largest radiance of the map: penumbra maps a direction
/// to (u, v) with atan2 alone where Mitsuba uses acos(y), which differ by an f32 rounding
/// of the angle; the bilinear weights move by W/2π (resp. (H − 1)/π) times that.
#[test]
fn envmap_structure_matches_mitsuba() {
    let texels: Vec<[f32; 4]> = coefficients("env")
        .iter()
        .map(|(_, c)| [c[0], c[1], c[2], c[3]])
        .collect();
    let lookups = envmap_lookups();
    assert!(lookups.len() >= 300, "{}", lookups.len());
    let peak = lookups
        .iter()
        .map(|l| l.3.max_element())
        .fold(0.0f32, f32::max);
    let (mut worst, mut poles) = (0.0f32, 0);
    for (scale, d, wl, want) in &lookups {
        let env = EnvMapEmitter::from_spectral_texels(
            ENV_SIZE.0,
            ENV_SIZE.1,
            texels.clone(),
            *scale,
            Mat3::IDENTITY,
        )
        .unwrap();
        let got = env.eval(*d, *wl);
        let diff = (got - *want).abs().max_element();
        let tol = 2e-6 * want.abs().max_element() + 1e-6 * peak;
        if d.y.abs() == 1.0 {
            // straight up or down u is undefined (atan2(0, ±0)): each picks its own column
            poles += 1;
            continue;
        }
        worst = worst.max(diff / tol);
        assert!(
            diff <= tol,
            "scale {scale} d {d} at {wl}: {got} vs Mitsuba {want}"
        );
    }
    assert_eq!(poles, 12);
    eprintln!("envmap structure: worst difference {worst} of the tolerance");
}

/// Texels as the envmap stores them: s = 2 max(rgb) exactly as Mitsuba's, and the
/// coefficients of rgb / s from penumbra's upsampling (the two tables' difference is
/// reported, as for the bitmap).
#[test]
fn envmap_texels_match_mitsuba() {
    let texels = coefficients("env");
    assert_eq!(texels.len(), ENV_SIZE.0 * ENV_SIZE.1);
    let mut table_difference = 0.0f32;
    for (rgb, c) in &texels {
        let ours = EnvMapEmitter::spectral_texel(*rgb);
        assert_eq!(ours[3], c[3], "s of {rgb:?}");
        let d = c[3].max(1e-8);
        let fetched = srgb_model_fetch([rgb[0] / d, rgb[1] / d, rgb[2] / d]);
        assert_eq!(&ours[..3], &fetched[..], "{rgb:?}");
        for wl in [
            Vec4::new(360.0, 450.0, 550.0, 830.0),
            Vec4::new(412.5, 487.25, 601.0, 700.75),
        ] {
            let a = srgb_model_eval(fetched, wl);
            let b = srgb_model_eval([c[0], c[1], c[2]], wl);
            table_difference = table_difference.max((a - b).abs().max_element());
        }
    }
    eprintln!("envmap texels: upsampling tables differ by up to {table_difference:e}");
}
