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
    let images: Vec<_> = bitmaps(&scene.materials)
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
