//! Tone-mapped previews: linear RGB clamped to [0, 1] and encoded with the sRGB transfer
//! function (IEC 61966-2-1), 8 bits per channel.

use crate::error::{Error, Result};
use std::path::Path;

/// The sRGB opto-electronic transfer function.
pub fn linear_to_srgb(x: f32) -> f32 {
    let x = if x.is_finite() {
        x.clamp(0.0, 1.0)
    } else {
        0.0
    };
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// Writes a preview PNG of a linear RGB image (`exposure` multiplies before clamping),
/// atomically.
pub fn write_preview(
    path: &Path,
    width: usize,
    height: usize,
    rgb: &[[f32; 3]],
    exposure: f32,
) -> Result<()> {
    let bytes: Vec<u8> = rgb
        .iter()
        .flat_map(|p| p.map(|c| (linear_to_srgb(c * exposure) * 255.0 + 0.5) as u8))
        .collect();
    let err = |message: String| Error::Output {
        path: path.to_path_buf(),
        message,
    };
    let img = image::RgbImage::from_raw(width as u32, height as u32, bytes)
        .ok_or_else(|| err("pixel count does not match the resolution".into()))?;
    // Atomically ([`crate::io::atomic`]), like the EXR it previews.
    crate::io::atomic::write_with(path, |file| {
        let mut w = std::io::BufWriter::new(file);
        img.write_to(&mut w, image::ImageFormat::Png)
            .map_err(|e| std::io::Error::other(e.to_string()))?;
        std::io::Write::flush(&mut w)
    })
    .map_err(|e| err(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_curve_endpoints_and_midpoint() {
        assert_eq!(linear_to_srgb(0.0), 0.0);
        assert!((linear_to_srgb(1.0) - 1.0).abs() < 1e-6);
        assert!((linear_to_srgb(0.214_041) - 0.5).abs() < 1e-4);
        assert_eq!(linear_to_srgb(f32::NAN), 0.0);
        assert_eq!(linear_to_srgb(5.0), linear_to_srgb(1.0));
    }
}
