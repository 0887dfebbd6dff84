//! Fuzzes the texture image reader (PNG, JPEG, BMP, OpenEXR) and the `bitmap` texture built
//! from what it accepts: every filter and wrap mode, a few storage formats, lookups inside
//! and outside [0, 1] and at non-finite uvs. Images above 2^20 pixels are refused (the real
//! limit, 2^28, would let one input allocate more than libFuzzer's memory limit).
#![no_main]

use glam::{DMat3, DVec2, Vec2};
use libfuzzer_sys::fuzz_target;
use penumbra::io::image::decode_limited;
use penumbra::texture::bitmap::{BitmapTexture, Filter, Format, TexImage, Wrap};
use std::sync::Arc;

fuzz_target!(|data: &[u8]| {
    let image = match decode_limited(data, 1 << 20) {
        Ok(image) => image,
        Err(e) => {
            assert!(!e.contains('\n'));
            return;
        }
    };
    assert!(image.channels == 1 || image.channels == 3);
    assert!(image.width > 0 && image.height > 0);
    assert_eq!(
        image.samples.len(),
        image.width * image.height * image.channels
    );
    for (raw, format) in [
        (false, Format::Auto),
        (true, Format::UInt8),
        (false, Format::Float16),
    ] {
        let tex = Arc::new(TexImage::from_image(image.clone(), raw, format));
        let _ = tex.mean();
        for filter in [Filter::Bilinear, Filter::Nearest] {
            for wrap in [Wrap::Repeat, Wrap::Mirror, Wrap::Clamp] {
                let to_uv = DMat3::from_scale_angle_translation(
                    DVec2::new(3.0, -2.0),
                    0.3,
                    DVec2::new(0.1, 0.2),
                );
                let t = BitmapTexture::new(tex.clone(), filter, wrap, to_uv);
                for uv in [
                    Vec2::new(0.5, 0.5),
                    Vec2::new(-1.25, 7.5),
                    Vec2::new(1.0, 0.0),
                    Vec2::new(f32::NAN, f32::INFINITY),
                ] {
                    let _ = (t.eval(uv), t.eval_1(uv));
                }
            }
        }
    }
});
