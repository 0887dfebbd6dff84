//! Textures through the scene: a bitmap used by several textures, BSDFs and emitters is read
//! and stored once; texture lookups at a shading point see the surface's uv.

mod common;
use common::*;
use penumbra::material::Material;
use penumbra::texture::Texture;
use std::sync::Arc;

fn bitmap(name: &str, extra: &str) -> String {
    format!(
        r#"<texture type="bitmap" name="{name}"><string name="filename" value="{}"/>{extra}</texture>"#,
        repo_path("validation/mitsuba-suite/common/textures/carrot.png").display()
    )
}

/// Every bitmap texture of the scene's materials.
fn bitmaps(materials: &[Material]) -> Vec<&Texture> {
    materials
        .iter()
        .flat_map(|m| match m {
            Material::Leaf { textures, .. } => textures.iter().map(|(_, t)| t).collect(),
            Material::Mask { opacity, .. } => vec![opacity],
            _ => vec![],
        })
        .filter(|t| matches!(t, Texture::Bitmap(_)))
        .collect()
}

#[test]
fn a_bitmap_shared_by_several_textures_is_loaded_once() {
    let xml = format!(
        r#"<scene version="3.0.0">
    <sensor type="perspective"><film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/></film></sensor>
    <shape type="sphere"><bsdf type="diffuse">{}</bsdf></shape>
    <shape type="sphere"><point name="center" x="3" y="0" z="0"/><bsdf type="roughplastic">{}</bsdf></shape>
    <shape type="sphere"><point name="center" x="6" y="0" z="0"/><bsdf type="mask">{}<bsdf type="diffuse"/></bsdf></shape>
    <shape type="sphere"><point name="center" x="9" y="0" z="0"/><bsdf type="diffuse">{}</bsdf></shape>
</scene>"#,
        bitmap("reflectance", ""),
        bitmap(
            "diffuse_reflectance",
            r#"<transform name="to_uv"><scale value="2"/></transform>"#
        ),
        bitmap("opacity", r#"<string name="filter_type" value="nearest"/>"#),
        // raw: a different decoding of the same file, so a second image.
        bitmap("reflectance", r#"<boolean name="raw" value="true"/>"#),
    );
    let scene = scene_from_str(&xml);
    let images: Vec<_> = bitmaps(&scene.scene.materials)
        .into_iter()
        .map(|t| match t {
            Texture::Bitmap(b) => b.image().clone(),
            _ => unreachable!(),
        })
        .collect();
    assert_eq!(images.len(), 4);
    assert!(Arc::ptr_eq(&images[0], &images[1]) && Arc::ptr_eq(&images[0], &images[2]));
    assert!(
        !Arc::ptr_eq(&images[0], &images[3]),
        "raw decodes differently"
    );
}

/// `Scene::bsdf_at` hands out a prebuilt BSDF only where the material does not vary: on the
/// textures scene (bitmap, checkerboard, mask, blend, bump map and plain materials) the BSDF
/// it returns at each camera hit evaluates, samples and weighs exactly as the one built at
/// that hit (`Scene::shading_bsdf`), and both kinds of material are hit.
#[test]
fn prebuilt_bsdfs_equal_the_ones_built_at_each_hit() {
    use glam::{Vec2, Vec3};
    let scene = load("scenes/textures.xml", &[]);
    let mut buf = penumbra::material::ShadingBsdf::new();
    let (mut prebuilt, mut built) = (0, 0);
    let n = 64;
    for y in 0..n {
        for x in 0..n {
            let s = Vec2::new((x as f32 + 0.5) / n as f32, (y as f32 + 0.5) / n as f32);
            let ray = scene.scene.camera.generate_ray(s);
            let Some(si) = scene.scene.intersect(&ray) else {
                continue;
            };
            let reference = scene
                .scene
                .shading_bsdf(&si, penumbra::spectrum::NO_WAVELENGTHS);
            let buf_at: *const penumbra::material::ShadingBsdf = &buf;
            let bsdf = scene
                .scene
                .bsdf_at(&si, penumbra::spectrum::NO_WAVELENGTHS, &mut buf);
            if std::ptr::eq(bsdf, buf_at) {
                built += 1;
            } else {
                prebuilt += 1;
            }
            let wi = si.frame.to_local(-ray.d.normalize());
            for k in 0..8 {
                let a = (k as f32 + 0.5) / 8.0;
                let wo = Vec3::new(a - 0.5, 0.3 - a, 0.6).normalize();
                assert_eq!(
                    bsdf.eval(wi, wo),
                    reference.eval(wi, wo),
                    "pixel ({x}, {y})"
                );
                assert_eq!(bsdf.pdf(wi, wo), reference.pdf(wi, wo), "pixel ({x}, {y})");
                let (u1, u2) = (a, Vec2::new(1.0 - a, a * a));
                let (s1, s2) = (bsdf.sample(wi, u1, u2), reference.sample(wi, u1, u2));
                assert_eq!(
                    s1.map(|s| (s.wo, s.weight, s.pdf)),
                    s2.map(|s| (s.wo, s.weight, s.pdf))
                );
            }
        }
    }
    assert!(
        prebuilt > 100 && built > 100,
        "prebuilt {prebuilt}, built {built}"
    );
}
