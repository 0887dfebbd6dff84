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
use penumbra::shape::mesh::MeshAttribute;
use penumbra::shape::Mesh;
use penumbra::spectral::{srgb_model_eval, srgb_model_fetch};
use penumbra::texture::bitmap::{BitmapTexture, Filter, Format, TexImage, Wrap};
use penumbra::texture::{MeshAttributeTexture, TextureContext};
use penumbra::volume::GridVolume;
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
        let ours = penumbra::spectral::scaled_coefficients(*rgb);
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

/// `grid FILTER WRAP x y z l0..l3 s0..s3` lines: (trilinear, wrap, point, wavelengths, value).
fn grid_lookups() -> Vec<(bool, Wrap, Vec3, Vec4, Vec4)> {
    lines()
        .iter()
        .filter(|f| f[0] == "grid")
        .map(|f| {
            let v = nums(&f[3..]);
            (
                f[1] == "trilinear",
                Wrap::from_name(&f[2]).unwrap(),
                Vec3::new(v[0], v[1], v[2]),
                Vec4::from_slice(&v[3..7]),
                Vec4::from_slice(&v[7..11]),
            )
        })
        .collect()
}

fn grid(trilinear: bool, wrap: Wrap) -> GridVolume {
    let vol = penumbra::io::vol::read_vol(&data("grid_rgb.vol")).unwrap();
    GridVolume::new(vol, glam::Mat4::IDENTITY, false, trilinear, wrap).unwrap()
}

/// A three-channel `gridvolume` in spectral mode with Mitsuba's coefficients: every lookup
/// (trilinear and nearest, the three wrap modes, points inside and outside the unit cube) is
/// Mitsuba's to 2e-6 relative to the value plus 1e-6 relative to the grid's largest scale
/// (f32 rounding: the spectra and scales are interpolated in another order), and the cells'
/// scales s = 2 max(rgb) and the majorant (the largest s) are Mitsuba's exactly.
#[test]
fn gridvolume_structure_matches_mitsuba() {
    let cells = coefficients("grid");
    assert_eq!(cells.len(), 12);
    let lookups = grid_lookups();
    assert!(lookups.len() >= 500, "{}", lookups.len());
    let peak = cells.iter().map(|(_, c)| c[3]).fold(0.0, f32::max);
    let mut worst = 0.0f32;
    for (trilinear, wrap, p, wl, want) in lookups {
        let mut g = grid(trilinear, wrap);
        let mut next = cells.iter();
        g.to_spectral_with(|rgb| {
            let (stored, c) = next.next().unwrap();
            let s = c[3].max(1e-8);
            assert_eq!(rgb, stored.map(|x| x / s), "cells in Mitsuba's order");
            [c[0], c[1], c[2]]
        });
        assert_eq!(g.max, peak);
        let got = g.eval_spectral(p, wl);
        let tol = 2e-6 * want.abs().max_element() + 1e-6 * peak;
        let d = (got - want).abs().max_element();
        worst = worst.max(d / tol);
        assert!(d <= tol, "{p} {wl}: {got} vs Mitsuba {want}");
    }
    eprintln!("gridvolume structure: worst difference {worst} of the tolerance");
}

/// The grid converted with penumbra's own upsampling: the scales are Mitsuba's exactly, the
/// coefficients those of penumbra's table for rgb / s (the tables' difference is reported).
#[test]
fn gridvolume_cells_match_mitsuba() {
    let cells = coefficients("grid");
    let mut g = grid(true, Wrap::Clamp);
    let mut seen = Vec::new();
    g.to_spectral_with(|rgb| {
        seen.push(rgb);
        srgb_model_fetch(rgb)
    });
    assert_eq!(g.max, cells.iter().map(|(_, c)| c[3]).fold(0.0, f32::max));
    let mut table_difference = 0.0f32;
    for ((stored, c), rgb) in cells.iter().zip(&seen) {
        let s = c[3].max(1e-8);
        assert_eq!(*rgb, stored.map(|x| x / s), "{stored:?}");
        let wl = Vec4::new(412.5, 487.25, 601.0, 700.75);
        let a = srgb_model_eval(srgb_model_fetch(*rgb), wl);
        let b = srgb_model_eval([c[0], c[1], c[2]], wl);
        table_difference = table_difference.max((a - b).abs().max_element());
    }
    eprintln!("gridvolume cells: upsampling tables differ by up to {table_difference:e}");
}

/// `attr` / `attr_stored` lines: the attribute as given and as Mitsuba stores it.
fn mesh_attributes() -> Vec<(String, Vec<f32>, Vec<f32>)> {
    let l = lines();
    l.iter()
        .filter(|f| f[0] == "attr")
        .map(|f| {
            let stored = l
                .iter()
                .find(|g| g[0] == "attr_stored" && g[1] == f[1])
                .unwrap();
            (f[1].clone(), nums(&f[2..]), nums(&stored[2..]))
        })
        .collect()
}

/// Mitsuba's two-triangle mesh of the script, with the attributes `values` picks.
fn test_mesh(values: impl Fn(&(String, Vec<f32>, Vec<f32>)) -> Vec<f32>) -> Mesh {
    let p = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)].map(|(x, y)| Vec3::new(x, y, 0.0));
    let mut mesh = Mesh::new(p.to_vec(), None, None, vec![[0, 1, 2], [1, 3, 2]], false);
    mesh.attributes = mesh_attributes()
        .iter()
        .map(|a| MeshAttribute {
            name: a.0.clone(),
            channels: 3,
            per_face: a.0.starts_with("face_"),
            values: values(a),
        })
        .collect();
    mesh
}

/// Spectral mode's mesh attributes against Mitsuba's `eval_attribute`: the mesh built with
/// the values Mitsuba stores (its coefficients of the colours) gives Mitsuba's lookups to f32
/// rounding: the three vertices' spectra interpolated, a face's own spectrum, and a
/// three-channel attribute not named *color* taken as coefficients as it is, as Mitsuba does.
/// Tolerance 1e-6 plus the rounding of the polynomial x = (c₀λ + c₁)λ + c₂, which Mitsuba
/// evaluates with fused multiply-adds and `spectral::srgb_model_eval` without: two roundings
/// of up to half an ulp of terms as large as T = |c₀|λ² + |c₁|λ + |c₂| each, so |Δx| ≤ 2⁻²³ T,
/// and the sigmoid's slope is at most ½ (T = 430 for the (0.96, 0.03, 0.52) face, where the
/// difference is 1.9e-6).
#[test]
fn mesh_attributes_match_mitsuba() {
    let mesh = test_mesh(|a| a.2.clone());
    let terms = |name: &str, wl: Vec4| {
        let a = mesh.attribute(name).unwrap();
        let l = wl.max_element();
        a.values
            .chunks(3)
            .map(|c| c[0].abs() * l * l + c[1].abs() * l + c[2].abs())
            .fold(0.0f32, f32::max)
    };
    let mut checked = 0;
    for f in lines().iter().filter(|f| f[0] == "mesh_eval") {
        let v = nums(&f[2..]);
        let tex = MeshAttributeTexture {
            name: f[1].clone(),
            scale: 1.0,
            spectral: true,
        };
        let ctx = TextureContext {
            prim: v[0] as u32,
            bary: Vec2::new(v[1], v[2]),
            mesh: Some(&mesh),
            wavelengths: Vec4::from_slice(&v[3..7]),
            ..TextureContext::at_uv(Vec2::ZERO)
        };
        let (got, want) = (tex.eval_spectrum(&ctx), Vec4::from_slice(&v[7..11]));
        let tol = 1e-6 + 0.5 * terms(&f[1], ctx.wavelengths) / (1u32 << 23) as f32;
        assert!(
            (got - want).abs().max_element() <= tol,
            "{} prim {} bary {}: {got} vs Mitsuba {want}",
            f[1],
            v[0],
            ctx.bary
        );
        checked += 1;
    }
    assert_eq!(checked, 144);
}

/// Building the mesh in spectral mode converts exactly the three-channel attributes whose
/// name contains `color` (Mitsuba's add_attribute): into penumbra's coefficients of the
/// colours; `vertex_foo` stays as given, which is what Mitsuba stores.
#[test]
fn mesh_color_attributes_become_coefficients() {
    let mut mesh = test_mesh(|a| a.1.clone());
    mesh.upsample_color_attributes();
    for (name, given, stored) in mesh_attributes() {
        let got = &mesh.attribute(&name).unwrap().values;
        if name.contains("color") {
            let want: Vec<f32> = given
                .chunks(3)
                .flat_map(|c| srgb_model_fetch([c[0], c[1], c[2]]))
                .collect();
            assert_eq!(got, &want, "{name}");
        } else {
            assert_eq!(got, &stored, "{name}");
        }
    }
}

/// A scene in spectral mode: `body` inside a scene with a sensor, built as `render --mode
/// spectral` builds it; the error message if it is refused.
fn build_spectral(body: &str) -> Result<(), String> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let xml = format!(
        r#"<scene version="3.0.0"><integrator type="path"/><sensor type="perspective"><film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/></film></sensor>{body}</scene>"#
    );
    let mut desc = penumbra::scene::Scene::description_from_xml_str(&xml, &dir.join("t.xml"), &[])
        .map_err(|e| e.to_string())?;
    desc.mode = penumbra::spectrum::Mode::Spectral;
    penumbra::render::Job::build(&desc)
        .map(|_| ())
        .map_err(|e| e.to_string())
}

/// What Mitsuba's spectral variants refuse (at their first lookup) is refused with one line
/// when the scene is built; what they render builds. Each refused case was seen building
/// before the checks existed (the refusal is not a side effect of something else).
#[test]
fn spectral_refusals_are_mitsubas() {
    let rgb = "textures/rgb8.png";
    let grey = "textures/grey8.png";
    let bitmap = |name: &str, file: &str, extra: &str| {
        format!(
            r#"<texture type="bitmap" name="{name}"><string name="filename" value="{file}"/>{extra}</texture>"#
        )
    };
    let sphere = |bsdf: String| format!(r#"<shape type="sphere">{bsdf}</shape>"#);
    let volume_texture = |name: &str, extra: &str| {
        format!(
            r#"<texture type="volume" name="{name}"><volume type="gridvolume" name="volume"><string name="filename" value="spectral/grid_rgb.vol"/>{extra}</volume></texture>"#
        )
    };
    let ok = [
        sphere(format!(r#"<bsdf type="diffuse">{}</bsdf>"#, bitmap("reflectance", rgb, ""))),
        sphere(format!(
            r#"<bsdf type="roughconductor">{}</bsdf>"#,
            bitmap("alpha", grey, "")
        )),
        sphere(format!(
            r#"<bsdf type="roughconductor">{}</bsdf>"#,
            bitmap("alpha", rgb, r#"<boolean name="raw" value="true"/>"#)
        )),
        r#"<emitter type="envmap"><string name="filename" value="spectral/env_rgb.exr"/></emitter>"#.into(),
        // A volume texture: a three-channel grid as a colour; raw three channels as one value.
        sphere(format!(
            r#"<bsdf type="diffuse">{}</bsdf>"#,
            volume_texture("reflectance", "")
        )),
        sphere(format!(
            r#"<bsdf type="roughconductor">{}</bsdf>"#,
            volume_texture("alpha", r#"<boolean name="raw" value="true"/>"#)
        )),
        // Media: a three-channel grid becomes spectra.
        format!(
            r#"<medium type="heterogeneous" id="m">{}</medium>{}"#,
            r#"<volume type="gridvolume" name="albedo"><string name="filename" value="spectral/grid_rgb.vol"/></volume>"#,
            sphere(r#"<bsdf type="null"/><ref name="interior" id="m"/>"#.into())
        ),
        format!(
            r#"<medium type="homogeneous" id="m"><rgb name="sigma_t" value="0.5, 0.4, 0.3"/></medium>{}"#,
            sphere(r#"<bsdf type="null"/><ref name="interior" id="m"/>"#.into())
        ),
    ];
    for body in &ok {
        build_spectral(body).unwrap_or_else(|e| panic!("{body}: {e}"));
    }
    let refused = [
        (
            sphere(format!(
                r#"<bsdf type="diffuse">{}</bsdf>"#,
                bitmap("reflectance", rgb, r#"<boolean name="raw" value="true"/>"#)
            )),
            "raw=\"true\" and three channels",
        ),
        (
            sphere(format!(
                r#"<bsdf type="roughconductor">{}</bsdf>"#,
                bitmap("alpha", rgb, "")
            )),
            "looked up as one value",
        ),
        (
            sphere(format!(
                r#"<bsdf type="normalmap">{}<bsdf type="diffuse"/></bsdf>"#,
                bitmap("normalmap", rgb, "")
            )),
            "looked up as raw RGB",
        ),
        (
            sphere(format!(
                r#"<bsdf type="diffuse">{}</bsdf>"#,
                bitmap(
                    "reflectance",
                    rgb,
                    r#"<string name="format" value="uint8"/>"#
                )
            )),
            "format=\"uint8\" is not supported in spectral mode",
        ),
        (
            sphere(format!(
                r#"<bsdf type="roughconductor">{}</bsdf>"#,
                volume_texture("alpha", "")
            )),
            "converts a three-channel gridvolume into spectra",
        ),
        (
            sphere(format!(
                r#"<bsdf type="diffuse">{}</bsdf>"#,
                volume_texture("reflectance", r#"<boolean name="raw" value="true"/>"#)
            )),
            "volume texture's gridvolume has raw=\"true\"",
        ),
        (
            format!(
                r#"<medium type="heterogeneous" id="m">{}</medium>{}"#,
                r#"<volume type="gridvolume" name="sigma_t"><string name="filename" value="spectral/grid_rgb.vol"/><boolean name="raw" value="true"/></volume>"#,
                sphere(r#"<bsdf type="null"/><ref name="interior" id="m"/>"#.into())
            ),
            "raw=\"true\" cannot be looked up as a spectrum",
        ),
    ];
    let wrong: Vec<String> = refused
        .iter()
        .filter_map(|(body, why)| match build_spectral(body) {
            Err(e) if e.contains(why) && !e.contains('\n') => None,
            other => Some(format!("{body}: {other:?}, expected an error with {why:?}")),
        })
        .collect();
    assert!(wrong.is_empty(), "{wrong:#?}");
}
