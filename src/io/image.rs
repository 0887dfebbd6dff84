//! Image input for textures, as Mitsuba 3.9.1's `Bitmap` reads them (src/core/bitmap.cpp),
//! reduced to what the `bitmap` texture keeps: one channel (grey) or three (RGB).
//!
//! | Format | Mitsuba's reader | penumbra |
//! | --- | --- | --- |
//! | PNG | libpng: grey, grey+alpha, RGB, RGBA at 8 or 16 bits; palettes and 1/2/4-bit grey expanded to 8 bits, a `tRNS` chunk to an alpha channel; gAMA/iCCP/sRGB chunks ignored | the `image` crate (`png`), same expansions |
//! | JPEG | libjpeg: 1 component (grey) or 3 (RGB); CMYK refused | the `image` crate (`jpeg`, zune-jpeg); CMYK and other component counts refused; a file without an end-of-image marker refused as truncated (libjpeg would fill the missing rows with grey and warn) |
//! | BMP | its own reader: 40-byte BITMAPINFOHEADER, uncompressed only; 8 bpp read as grey **ignoring the palette**, 16 bpp as grey + alpha, 24 and 32 bpp as BGR[A]; negative height = top-down rows | its own reader of exactly that subset (the `image` crate's BMP decoder applies palettes and reads RGB555, so it would disagree with Mitsuba) |
//! | OpenEXR | OpenEXR: the first part, channels Y, YA, RGB, RGBA, XYZ, XYZA (exact names), half, float or uint | the `exr` crate: same channel sets, half or float (uint and chroma-subsampled channels refused) |
//! | RGBE (`.hdr`) | its own reader: `FORMAT=32-bit_rle_rgbe` (or `_xyze`), `-Y h +X w`, flat or run-length scanlines, value = byte · 2^(e − 136) | the `image` crate (`hdr`): the same header, orientation and decoding, float RGB; XYZE refused |
//! | PFM, PPM, TGA | read | refused with a message naming the format |
//!
//! The format is detected from the first bytes, as Mitsuba does (not from the extension).
//!
//! Channel rules (Mitsuba's `BitmapTexture::target_pixel_format` and `Bitmap::convert`):
//! Y and YA become one channel, RGB, RGBA, XYZ and XYZA three. Alpha is dropped, not
//! multiplied in (checked: an RGBA PNG texel (255, 0, 0, 128) evaluates to (1, 0, 0)). XYZ is
//! converted to linear sRGB with Mitsuba's matrix.
//!
//! Samples keep their stored type ([`Samples`]): 8- and 16-bit integers are sRGB-encoded
//! unless the texture says `raw`; half and float samples are linear. The texture decides
//! what to do with them (src/texture/bitmap.rs).
//!
//! Hostile input: nothing here panics on any byte string (and a panic inside a decoder crate
//! is caught and reported as an error); the header's dimensions are
//! checked before any pixel buffer is allocated (the `image_pixels` limit of
//! [`crate::limits`], and a compression-ratio
//! bound: no supported codec expands a file more than [`MAX_EXPANSION`] times); every error
//! is one line.

use half::f16;
use std::io::Cursor;
use std::path::Path;

// The largest image accepted (pixels) and image file read (bytes) are the `image_pixels`
// and `image_bytes` limits of `crate::limits` (default 2^28 pixels and 4 GiB).
/// Upper bound on decoded bytes per file byte. Deflate (PNG, EXR ZIP) expands at most 1032
/// times; baseline and progressive Huffman JPEG need at least one bit per 8x8 block and
/// component (≤ 1365 times with 4:1:0 chroma subsampling); EXR RLE ≤ 64, PIZ ≤ ~400,
/// PXR24 ≤ ~1400 times. A header claiming more is lying about its size.
pub const MAX_EXPANSION: u64 = 2048;
/// Decoded bytes always allowed whatever the file size (small files, small images).
const EXPANSION_SLACK: u64 = 16 << 20;

/// The file formats read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileFormat {
    Png,
    Jpeg,
    Bmp,
    Exr,
    /// Radiance RGBE (`.hdr`).
    Rgbe,
}

/// The channel layout stored in the file, before alpha is dropped and XYZ converted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layout {
    Y,
    YA,
    Rgb,
    Rgba,
    Xyz,
    Xyza,
}

impl Layout {
    /// Channels in the file.
    pub fn file_channels(self) -> usize {
        match self {
            Layout::Y => 1,
            Layout::YA => 2,
            Layout::Rgb | Layout::Xyz => 3,
            Layout::Rgba | Layout::Xyza => 4,
        }
    }
    /// Channels kept: 1 for grey, 3 for colour.
    pub fn channels(self) -> usize {
        match self {
            Layout::Y | Layout::YA => 1,
            _ => 3,
        }
    }
}

/// Samples in their stored type, row-major from the top row, channels interleaved.
#[derive(Clone, Debug, PartialEq)]
pub enum Samples {
    /// 8-bit integers (PNG, JPEG, BMP): sRGB-encoded unless the texture is `raw`.
    U8(Vec<u8>),
    /// 16-bit integers (PNG): sRGB-encoded unless the texture is `raw`.
    U16(Vec<u16>),
    /// Half floats (EXR): linear.
    F16(Vec<f16>),
    /// Floats (EXR): linear.
    F32(Vec<f32>),
}

impl Samples {
    pub fn len(&self) -> usize {
        match self {
            Samples::U8(v) => v.len(),
            Samples::U16(v) => v.len(),
            Samples::F16(v) => v.len(),
            Samples::F32(v) => v.len(),
        }
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Integer samples, which Mitsuba takes as sRGB-encoded (unless `raw`).
    pub fn is_integer(&self) -> bool {
        matches!(self, Samples::U8(_) | Samples::U16(_))
    }
    /// Sample `i` as stored, integers normalised to [0, 1] (v / 255, v / 65535), not decoded.
    pub fn value(&self, i: usize) -> f32 {
        match self {
            Samples::U8(v) => v[i] as f32 / 255.0,
            Samples::U16(v) => v[i] as f32 / 65535.0,
            Samples::F16(v) => v[i].to_f32(),
            Samples::F32(v) => v[i],
        }
    }
}

/// A decoded image: 1 or 3 channels.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    /// 1 (grey) or 3 (RGB).
    pub channels: usize,
    /// `width * height * channels` samples.
    pub samples: Samples,
    pub format: FileFormat,
    /// What the file stored (e.g. `Rgba` for an RGBA PNG, of which `samples` keeps RGB).
    pub layout: Layout,
}

/// Reads an image file (format detected from its first bytes) of at most the `image_bytes`
/// limit and `image_pixels` pixels ([`crate::limits::current`]).
pub fn read(path: &Path) -> Result<Image, String> {
    let limits = crate::limits::current().map_err(|e| e.to_string())?;
    let bytes = crate::io::read_file_limited(path, limits.file(crate::limits::Limit::ImageBytes))
        .map_err(|e| format!("{}: {e}", path.display()))?;
    decode_limited(&bytes, limits.image_pixels).map_err(|e| format!("{}: {e}", path.display()))
}

/// Decodes an image held in memory, at most the `image_pixels` limit's pixels
/// ([`crate::limits::current`]).
pub fn decode(bytes: &[u8]) -> Result<Image, String> {
    let limits = crate::limits::current().map_err(|e| e.to_string())?;
    decode_limited(bytes, limits.image_pixels)
}

/// Decodes an image held in memory, refusing more than `max_pixels` pixels before
/// allocating (the fuzz target uses a small limit).
pub fn decode_limited(bytes: &[u8], max_pixels: u64) -> Result<Image, String> {
    let format = detect(bytes)?;
    // Last line of defence: a panic inside a decoder crate on a malformed file becomes an
    // error. (Each decoder runs on this thread for that: exr without its thread pool.)
    let decoded = std::panic::catch_unwind(|| match format {
        FileFormat::Png => decode_png(bytes, max_pixels),
        FileFormat::Jpeg => decode_jpeg(bytes, max_pixels),
        FileFormat::Bmp => decode_bmp(bytes, max_pixels),
        FileFormat::Exr => decode_exr(bytes, max_pixels),
        FileFormat::Rgbe => decode_rgbe(bytes, max_pixels),
    })
    .unwrap_or_else(|_| {
        Err(format!(
            "the {format:?} decoder failed on this file (corrupt?)"
        ))
    });
    // the decoders' messages may span lines (zune-jpeg's do)
    let image = decoded.map_err(|e| e.split_whitespace().collect::<Vec<_>>().join(" "))?;
    debug_assert_eq!(
        image.samples.len(),
        image.width * image.height * image.channels
    );
    Ok(image)
}

/// The format from the magic bytes, in Mitsuba's order (`Bitmap::detect_file_format`).
pub fn detect(bytes: &[u8]) -> Result<FileFormat, String> {
    let start = |magic: &[u8]| bytes.starts_with(magic);
    if start(b"BM") {
        Ok(FileFormat::Bmp)
    } else if start(b"#?") {
        Ok(FileFormat::Rgbe)
    } else if start(b"PF") || start(b"Pf") {
        Err("PFM images are not supported".into())
    } else if start(b"P6") {
        Err("PPM images are not supported".into())
    } else if start(&[0xFF, 0xD8]) {
        Ok(FileFormat::Jpeg)
    } else if start(b"\x89PNG\r\n\x1a\n") {
        Ok(FileFormat::Png)
    } else if start(&[0x76, 0x2f, 0x31, 0x01]) {
        Ok(FileFormat::Exr)
    } else if bytes.len() >= 18 && bytes.ends_with(b"TRUEVISION-XFILE.\0") {
        Err("TGA images are not supported".into())
    } else if bytes.is_empty() {
        Err("empty file".into())
    } else {
        Err("unknown image format (not PNG, JPEG, BMP, OpenEXR or RGBE)".into())
    }
}

/// Refuses zero-sized images and headers claiming more pixels than allowed or than the
/// file can hold: `bits_per_pixel` as stored in the file before compression (0: skip the
/// file-size check).
pub(crate) fn check_size(
    width: u64,
    height: u64,
    bits_per_pixel: u64,
    file_len: usize,
    max_pixels: u64,
) -> Result<(), String> {
    if width == 0 || height == 0 {
        return Err(format!("zero-sized image ({width} x {height})"));
    }
    let pixels = width.saturating_mul(height);
    if pixels > max_pixels {
        return Err(format!(
            "image of {width} x {height} pixels exceeds {}",
            crate::limits::Limit::ImagePixels.exceeded(max_pixels)
        ));
    }
    let decoded = pixels.saturating_mul(bits_per_pixel).div_ceil(8);
    let bound = (file_len as u64)
        .saturating_mul(MAX_EXPANSION)
        .saturating_add(EXPANSION_SLACK);
    if decoded > bound {
        return Err(format!(
            "header claims {width} x {height} pixels, more than a {file_len}-byte file can hold"
        ));
    }
    Ok(())
}

fn image_limits(width: u32, height: u32, bytes_per_pixel: u64) -> image::Limits {
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(width);
    limits.max_image_height = Some(height);
    // the output buffer plus the decoder's own (a few rows, Huffman tables, the input copy)
    let out = width as u64 * height as u64 * bytes_per_pixel;
    limits.max_alloc = Some(out.saturating_mul(2).saturating_add(64 << 20));
    limits
}

/// Keeps the first `keep` of every `stride` samples (drops alpha).
fn strip<T: Copy>(data: Vec<T>, stride: usize, keep: usize) -> Vec<T> {
    if stride == keep {
        return data;
    }
    data.chunks_exact(stride)
        .flat_map(|p| p[..keep].iter().copied())
        .collect()
}

fn layout_of(color: image::ColorType) -> Option<(Layout, bool)> {
    use image::ColorType as C;
    Some(match color {
        C::L8 => (Layout::Y, false),
        C::La8 => (Layout::YA, false),
        C::Rgb8 => (Layout::Rgb, false),
        C::Rgba8 => (Layout::Rgba, false),
        C::L16 => (Layout::Y, true),
        C::La16 => (Layout::YA, true),
        C::Rgb16 => (Layout::Rgb, true),
        C::Rgba16 => (Layout::Rgba, true),
        _ => return None,
    })
}

/// Runs an `image` decoder whose header is already read: checks, decodes, drops alpha.
fn finish_image_decoder(
    mut decoder: impl image::ImageDecoder,
    file_len: usize,
    max_pixels: u64,
    format: FileFormat,
    what: &str,
) -> Result<Image, String> {
    let (w, h) = decoder.dimensions();
    let color = decoder.color_type();
    let (layout, sixteen) =
        layout_of(color).ok_or_else(|| format!("unsupported {what} channel layout {color:?}"))?;
    let bpp = color.bytes_per_pixel() as u64;
    // (the caller checked the size against the file's length)
    check_size(w as u64, h as u64, 0, file_len, max_pixels)?;
    decoder
        .set_limits(image_limits(w, h, bpp))
        .map_err(|e| format!("{what}: {e}"))?;
    let total = usize::try_from(decoder.total_bytes()).map_err(|_| "image too large")?;
    let mut buf = vec![0u8; total];
    decoder
        .read_image(&mut buf)
        .map_err(|e| format!("cannot decode {what} (truncated or corrupt): {e}"))?;
    let (fc, c) = (layout.file_channels(), layout.channels());
    let samples = if sixteen {
        let v: Vec<u16> = buf
            .chunks_exact(2)
            .map(|b| u16::from_ne_bytes([b[0], b[1]]))
            .collect();
        Samples::U16(strip(v, fc, c))
    } else {
        Samples::U8(strip(buf, fc, c))
    };
    Ok(Image {
        width: w as usize,
        height: h as usize,
        channels: c,
        samples,
        format,
        layout,
    })
}

fn decode_png(bytes: &[u8], max_pixels: u64) -> Result<Image, String> {
    // IHDR is the first chunk: width, height, bit depth, colour type
    let ihdr = bytes
        .get(12..29)
        .filter(|b| &b[..4] == b"IHDR")
        .ok_or("truncated or corrupt PNG header")?;
    let be = |o: usize| u32::from_be_bytes([ihdr[o], ihdr[o + 1], ihdr[o + 2], ihdr[o + 3]]);
    let samples = match ihdr[13] {
        0 | 3 => 1,
        4 => 2,
        2 => 3,
        6 => 4,
        t => return Err(format!("corrupt PNG: colour type {t}")),
    };
    let bits = samples * ihdr[12] as u64;
    check_size(be(4) as u64, be(8) as u64, bits, bytes.len(), max_pixels)?;
    // Header first, with limits that allow nothing yet: `with_limits` reads only IHDR and
    // the chunks before the image data.
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(64 << 20);
    let decoder = image::codecs::png::PngDecoder::with_limits(Cursor::new(bytes), limits)
        .map_err(|e| format!("cannot read PNG header (truncated or corrupt): {e}"))?;
    finish_image_decoder(decoder, bytes.len(), max_pixels, FileFormat::Png, "PNG")
}

/// The frame header of a JPEG: (width, height, components), and whether an end-of-image
/// marker follows the first scan. Walks the marker segments; never reads out of bounds.
fn jpeg_frame(bytes: &[u8]) -> Result<(u64, u64, u8, bool), String> {
    let truncated = || "truncated JPEG header".to_string();
    let mut i = 2; // after SOI
    let mut frame = None;
    loop {
        // skip fill bytes before a marker
        while bytes.get(i) == Some(&0xFF) && bytes.get(i + 1) == Some(&0xFF) {
            i += 1;
        }
        let (&ff, &marker) = bytes.get(i).zip(bytes.get(i + 1)).ok_or_else(truncated)?;
        if ff != 0xFF {
            return Err("corrupt JPEG: marker expected".into());
        }
        i += 2;
        if marker == 0xD8 || marker == 0x01 || (0xD0..=0xD7).contains(&marker) {
            continue; // no length
        }
        if marker == 0xD9 {
            return Err("corrupt JPEG: end of image before any scan".into());
        }
        let len = bytes
            .get(i..i + 2)
            .map(|b| u16::from_be_bytes([b[0], b[1]]) as usize)
            .ok_or_else(truncated)?;
        if len < 2 || i + len > bytes.len() {
            return Err(truncated());
        }
        let seg = &bytes[i + 2..i + len];
        // SOF0..SOF15 except DHT (C4), JPG (C8), DAC (CC)
        if (0xC0..=0xCF).contains(&marker) && ![0xC4, 0xC8, 0xCC].contains(&marker) {
            if seg.len() < 6 {
                return Err("corrupt JPEG frame header".into());
            }
            let h = u16::from_be_bytes([seg[1], seg[2]]) as u64;
            let w = u16::from_be_bytes([seg[3], seg[4]]) as u64;
            frame = Some((w, h, seg[5]));
        }
        i += len;
        if marker == 0xDA {
            // Start of scan: the entropy-coded data follows. Inside it 0xFF is stuffed as
            // FF 00 and restart markers are FF D0..D7, so FF D9 can only be the end of image.
            let (w, h, c) = frame.ok_or("corrupt JPEG: scan before the frame header")?;
            let eoi = bytes[i..].windows(2).any(|p| p == [0xFF, 0xD9]);
            return Ok((w, h, c, eoi));
        }
    }
}

fn decode_jpeg(bytes: &[u8], max_pixels: u64) -> Result<Image, String> {
    let (w, h, components, eoi) = jpeg_frame(bytes)?;
    if components != 1 && components != 3 {
        return Err(format!(
            "unsupported JPEG with {components} components (Mitsuba reads grey or RGB)"
        ));
    }
    check_size(w, h, 8 * components as u64, bytes.len(), max_pixels)?;
    if !eoi {
        return Err("truncated JPEG (no end-of-image marker)".into());
    }
    let decoder = image::codecs::jpeg::JpegDecoder::new(Cursor::new(bytes))
        .map_err(|e| format!("cannot read JPEG header (truncated or corrupt): {e}"))?;
    let image = finish_image_decoder(decoder, bytes.len(), max_pixels, FileFormat::Jpeg, "JPEG")?;
    if image.channels != components as usize
        || (image.width, image.height) != (w as usize, h as usize)
    {
        return Err("corrupt JPEG: the decoder disagrees with the frame header".into());
    }
    Ok(image)
}

/// Mitsuba's BMP subset (`Bitmap::read_bmp`).
fn decode_bmp(bytes: &[u8], max_pixels: u64) -> Result<Image, String> {
    let u16_at = |o: usize| {
        bytes
            .get(o..o + 2)
            .map(|b| u16::from_le_bytes([b[0], b[1]]))
    };
    let u32_at = |o: usize| {
        bytes
            .get(o..o + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let truncated = || "truncated BMP header".to_string();
    let offset = u32_at(10).ok_or_else(truncated)? as usize;
    let header_size = u32_at(14).ok_or_else(truncated)?;
    let width = u32_at(18).ok_or_else(truncated)? as i32;
    let height = u32_at(22).ok_or_else(truncated)? as i32;
    let planes = u16_at(26).ok_or_else(truncated)?;
    let bpp = u16_at(28).ok_or_else(truncated)?;
    let compression = u32_at(30).ok_or_else(truncated)?;
    if header_size != 40 || planes != 1 || width < 0 {
        return Err(format!(
            "unsupported BMP (header of {header_size} bytes, {planes} planes, width {width}): \
             Mitsuba reads the 40-byte BITMAPINFOHEADER only"
        ));
    }
    if compression != 0 {
        return Err("compressed BMP files are not supported (as in Mitsuba)".into());
    }
    let (layout, fc) = match bpp {
        8 => (Layout::Y, 1),
        16 => (Layout::YA, 2),
        24 => (Layout::Rgb, 3),
        32 => (Layout::Rgba, 4),
        _ => return Err(format!("unsupported BMP bit depth {bpp}")),
    };
    let (w, h) = (width as u64, height.unsigned_abs() as u64);
    check_size(w, h, 8 * fc as u64, bytes.len(), max_pixels)?;
    let (w, h) = (w as usize, h as usize);
    let row = w * fc;
    let stride = row.div_ceil(4) * 4;
    // the last row needs no padding in the file
    let needed = offset
        .checked_add(stride * (h - 1) + row)
        .ok_or("corrupt BMP")?;
    if offset < 34 || needed > bytes.len() {
        return Err("truncated BMP (pixel data ends early)".into());
    }
    let c = layout.channels();
    let mut out = Vec::with_capacity(w * h * c);
    for y in 0..h {
        let file_row = if height > 0 { h - 1 - y } else { y };
        let src = &bytes[offset + file_row * stride..][..row];
        for p in src.chunks_exact(fc) {
            match fc {
                1 | 2 => out.push(p[0]),
                _ => out.extend_from_slice(&[p[2], p[1], p[0]]),
            }
        }
    }
    Ok(Image {
        width: w,
        height: h,
        channels: c,
        samples: Samples::U8(out),
        format: FileFormat::Bmp,
        layout,
    })
}

/// Mitsuba's XYZ → linear sRGB matrix (`Bitmap::convert`).
const XYZ_TO_RGB: [[f32; 3]; 3] = [
    [3.240479, -1.53715, -0.498535],
    [-0.969256, 1.875991, 0.041556],
    [0.055648, -0.204043, 1.057311],
];

/// Radiance RGBE through the `image` crate: float RGB, linear (as Mitsuba's `read_rgbe`).
fn decode_rgbe(bytes: &[u8], max_pixels: u64) -> Result<Image, String> {
    use image::ImageDecoder;
    // Mitsuba takes any first line starting with "#?" (its own writer's is "#?RGBE"); the
    // crate wants Radiance's "#?RADIANCE": give it that line.
    let line_end = bytes
        .iter()
        .position(|&b| b == b'\n')
        .unwrap_or(bytes.len());
    let patched;
    let bytes = if &bytes[..line_end] == b"#?RADIANCE" {
        bytes
    } else {
        patched = [b"#?RADIANCE".as_slice(), &bytes[line_end..]].concat();
        patched.as_slice()
    };
    let decoder = image::codecs::hdr::HdrDecoder::new(Cursor::new(bytes))
        .map_err(|e| format!("cannot read RGBE header (truncated or corrupt): {e}"))?;
    let (w, h) = decoder.dimensions();
    // 32 bits a pixel before run-length coding, which expands at most 64 times.
    check_size(w as u64, h as u64, 32, bytes.len(), max_pixels)?;
    let total = usize::try_from(decoder.total_bytes()).map_err(|_| "image too large")?;
    if total != w as usize * h as usize * 12 {
        return Err(format!("unexpected RGBE layout {:?}", decoder.color_type()));
    }
    let mut buf = vec![0u8; total];
    decoder
        .read_image(&mut buf)
        .map_err(|e| format!("cannot decode RGBE (truncated or corrupt): {e}"))?;
    let v: Vec<f32> = buf
        .chunks_exact(4)
        .map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    Ok(Image {
        width: w as usize,
        height: h as usize,
        channels: 3,
        samples: Samples::F32(v),
        format: FileFormat::Rgbe,
        layout: Layout::Rgb,
    })
}

fn decode_exr(bytes: &[u8], max_pixels: u64) -> Result<Image, String> {
    use ::exr::prelude::*;
    let meta = ::exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false)
        .map_err(|e| format!("cannot read OpenEXR header: {e}"))?;
    let header = meta.headers.first().ok_or("OpenEXR file without parts")?;
    if header.deep {
        return Err("deep OpenEXR images are not supported".into());
    }
    let list = &header.channels.list;
    let names: Vec<String> = list.iter().map(|c| c.name.to_string()).collect();
    let layout = match names
        .iter()
        .map(|s| s.as_str())
        .collect::<Vec<_>>()
        .as_slice()
    {
        // the exr crate keeps channels sorted by name, as the format requires
        ["B", "G", "R"] => Layout::Rgb,
        ["A", "B", "G", "R"] => Layout::Rgba,
        ["X", "Y", "Z"] => Layout::Xyz,
        ["A", "X", "Y", "Z"] => Layout::Xyza,
        ["Y"] => Layout::Y,
        ["A", "Y"] => Layout::YA,
        _ => {
            return Err(format!(
                "unsupported OpenEXR channels [{}]: a texture needs Y, YA, RGB, RGBA, XYZ or XYZA",
                names.join(", ")
            ))
        }
    };
    if list.iter().any(|c| c.sampling != Vec2(1, 1)) {
        return Err("sub-sampled OpenEXR channels are not supported".into());
    }
    // Mitsuba stores all channels in the type of the first one (in name order).
    let half = match list[0].sample_type {
        SampleType::F16 => true,
        SampleType::F32 => false,
        SampleType::U32 => return Err("OpenEXR images with uint channels are not supported".into()),
    };
    let bits_per_pixel: u64 = list
        .iter()
        .map(|c| 8 * c.sample_type.bytes_per_sample() as u64)
        .sum();
    let size = header.layer_size;
    check_size(
        size.0 as u64,
        size.1 as u64,
        bits_per_pixel,
        bytes.len(),
        max_pixels,
    )?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_buffered(Cursor::new(bytes))
        .map_err(|e| format!("cannot decode OpenEXR (truncated or corrupt): {e}"))?;
    let layer = image.layer_data;
    let (w, h) = (layer.size.0, layer.size.1);
    if (w, h) != (size.0, size.1) || layer.channel_data.list.len() != list.len() {
        return Err("corrupt OpenEXR: layer differs from its header".into());
    }
    let channel = |name: &str| -> std::result::Result<Vec<f32>, String> {
        let c = layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.to_string() == name)
            .ok_or("corrupt OpenEXR: channel missing")?;
        let v: Vec<f32> = c.sample_data.values_as_f32().collect();
        if v.len() != w * h {
            return Err("corrupt OpenEXR: channel size".into());
        }
        Ok(v)
    };
    let n = w * h;
    let data: Vec<f32> = match layout {
        Layout::Y | Layout::YA => channel("Y")?,
        Layout::Rgb | Layout::Rgba => {
            let (r, g, b) = (channel("R")?, channel("G")?, channel("B")?);
            (0..n).flat_map(|i| [r[i], g[i], b[i]]).collect()
        }
        Layout::Xyz | Layout::Xyza => {
            let (x, y, z) = (channel("X")?, channel("Y")?, channel("Z")?);
            (0..n)
                .flat_map(|i| XYZ_TO_RGB.map(|m| m[0] * x[i] + m[1] * y[i] + m[2] * z[i]))
                .collect()
        }
    };
    let samples = if half {
        Samples::F16(data.into_iter().map(f16::from_f32).collect())
    } else {
        Samples::F32(data)
    };
    // (`Image` is the exr crate's inside this function)
    Ok(self::Image {
        width: w,
        height: h,
        channels: layout.channels(),
        samples,
        format: FileFormat::Exr,
        layout,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn repo(rel: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
    }

    fn file(name: &str) -> Vec<u8> {
        std::fs::read(repo(&format!("tests/data/textures/{name}"))).unwrap()
    }

    fn chunk(kind: &[u8], data: &[u8]) -> Vec<u8> {
        let mut c = (data.len() as u32).to_be_bytes().to_vec();
        c.extend_from_slice(kind);
        c.extend_from_slice(data);
        let crc = crc32(&c[4..]);
        c.extend_from_slice(&crc.to_be_bytes());
        c
    }

    fn crc32(bytes: &[u8]) -> u32 {
        let mut crc = !0u32;
        for &b in bytes {
            crc ^= b as u32;
            for _ in 0..8 {
                crc = if crc & 1 != 0 {
                    (crc >> 1) ^ 0xEDB8_8320
                } else {
                    crc >> 1
                };
            }
        }
        !crc
    }

    /// A PNG signature and IHDR claiming `w` x `h` RGB8, then `rest`.
    fn png_header(w: u32, h: u32, rest: &[u8]) -> Vec<u8> {
        let mut ihdr = w.to_be_bytes().to_vec();
        ihdr.extend_from_slice(&h.to_be_bytes());
        ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
        let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
        out.extend(chunk(b"IHDR", &ihdr));
        out.extend_from_slice(rest);
        out
    }

    /// A BMP header (40-byte info header) for `w` x `h` at `bpp`, followed by `pixels`.
    fn bmp(w: i32, h: i32, bpp: u16, compression: u32, pixels: &[u8]) -> Vec<u8> {
        let mut b = b"BM".to_vec();
        b.extend_from_slice(&(54 + pixels.len() as u32).to_le_bytes());
        b.extend_from_slice(&[0; 4]);
        b.extend_from_slice(&54u32.to_le_bytes());
        b.extend_from_slice(&40u32.to_le_bytes());
        b.extend_from_slice(&w.to_le_bytes());
        b.extend_from_slice(&h.to_le_bytes());
        b.extend_from_slice(&1u16.to_le_bytes());
        b.extend_from_slice(&bpp.to_le_bytes());
        b.extend_from_slice(&compression.to_le_bytes());
        b.extend_from_slice(&[0; 20]);
        b.extend_from_slice(pixels);
        b
    }

    /// An EXR of `w` x `h` with the given float channels (all zero), in memory.
    fn exr(w: usize, h: usize, names: &[&str]) -> Vec<u8> {
        use ::exr::prelude::*;
        let channels: Vec<AnyChannel<FlatSamples>> = names
            .iter()
            .map(|n| AnyChannel::new(*n, FlatSamples::F32(vec![0.25; w * h])))
            .collect();
        let layer = Layer::new(
            (w, h),
            LayerAttributes::default(),
            Encoding::FAST_LOSSLESS,
            AnyChannels::sort(SmallVec::from_vec(channels)),
        );
        let mut out = Cursor::new(Vec::new());
        Image::from_layer(layer)
            .write()
            .to_buffered(&mut out)
            .unwrap();
        out.into_inner()
    }

    fn err(bytes: &[u8]) -> String {
        let e = decode(bytes).expect_err("must be refused");
        assert!(!e.contains('\n'), "one line: {e}");
        e
    }

    #[test]
    fn reads_each_layout_and_sample_type() {
        use FileFormat::*;
        // (file, format, layout, width, height, kind)
        let expected = [
            ("grey8.png", Png, Layout::Y, 4, 3, "u8"),
            ("ya8.png", Png, Layout::YA, 4, 3, "u8"),
            ("rgb8.png", Png, Layout::Rgb, 4, 3, "u8"),
            ("rgba8.png", Png, Layout::Rgba, 4, 3, "u8"),
            ("grey16.png", Png, Layout::Y, 4, 3, "u16"),
            ("rgb16.png", Png, Layout::Rgb, 4, 3, "u16"),
            ("rgba16.png", Png, Layout::Rgba, 4, 3, "u16"),
            ("palette4.png", Png, Layout::Rgba, 4, 3, "u8"), // tRNS adds alpha
            ("grey2.png", Png, Layout::YA, 4, 3, "u8"),      // tRNS adds alpha
            ("one_pixel.png", Png, Layout::Rgb, 1, 1, "u8"),
            ("rgb.jpg", Jpeg, Layout::Rgb, 16, 12, "u8"),
            ("grey.jpg", Jpeg, Layout::Y, 16, 12, "u8"),
            ("pal8.bmp", Bmp, Layout::Y, 5, 3, "u8"),
            ("ya16.bmp", Bmp, Layout::YA, 5, 3, "u8"),
            ("bgr24.bmp", Bmp, Layout::Rgb, 5, 3, "u8"),
            ("bgra32_topdown.bmp", Bmp, Layout::Rgba, 5, 3, "u8"),
            ("rgb_f32.exr", Exr, Layout::Rgb, 4, 3, "f32"),
            ("rgba_f16.exr", Exr, Layout::Rgba, 4, 3, "f16"),
            ("y_f32.exr", Exr, Layout::Y, 4, 3, "f32"),
            ("ya_f16.exr", Exr, Layout::YA, 4, 3, "f16"),
            ("xyz_f32.exr", Exr, Layout::Xyz, 4, 3, "f32"),
        ];
        for (name, format, layout, w, h, kind) in expected {
            let img = read(&repo(&format!("tests/data/textures/{name}"))).unwrap();
            assert_eq!(
                (img.format, img.layout, img.width, img.height),
                (format, layout, w, h),
                "{name}"
            );
            assert_eq!(img.channels, layout.channels(), "{name}");
            assert_eq!(img.samples.len(), w * h * img.channels, "{name}");
            let k = match img.samples {
                Samples::U8(_) => "u8",
                Samples::U16(_) => "u16",
                Samples::F16(_) => "f16",
                Samples::F32(_) => "f32",
            };
            assert_eq!(k, kind, "{name}");
        }
    }

    #[test]
    fn bmp_rows_and_channel_order() {
        // 2 x 2, 24 bpp, bottom-up: the file's first row is the picture's bottom row;
        // pixels are B, G, R; rows padded to 4 bytes (6 -> 8)
        let px = [
            1, 2, 3, 4, 5, 6, 0, 0, // bottom row
            7, 8, 9, 10, 11, 12, 0, 0, // top row
        ];
        let img = decode(&bmp(2, 2, 24, 0, &px)).unwrap();
        assert_eq!(
            img.samples,
            Samples::U8(vec![9, 8, 7, 12, 11, 10, 3, 2, 1, 6, 5, 4])
        );
        // negative height: top-down
        let img = decode(&bmp(2, -2, 24, 0, &px)).unwrap();
        assert_eq!(
            img.samples,
            Samples::U8(vec![3, 2, 1, 6, 5, 4, 9, 8, 7, 12, 11, 10])
        );
        // 8 bpp: the index is the grey value (Mitsuba ignores the palette)
        let img = decode(&bmp(3, 1, 8, 0, &[10, 20, 30, 0])).unwrap();
        assert_eq!(img.samples, Samples::U8(vec![10, 20, 30]));
        // the last row needs no padding
        assert!(decode(&bmp(3, 1, 8, 0, &[10, 20, 30])).is_ok());
        assert!(err(&bmp(3, 1, 8, 0, &[10, 20])).contains("truncated"));
        assert!(err(&bmp(2, 2, 24, 1, &px)).contains("compressed"));
        assert!(err(&bmp(2, 2, 4, 0, &px)).contains("bit depth"));
    }

    #[test]
    fn exr_channel_sets() {
        for (names, layout) in [
            (&["R", "G", "B"][..], Layout::Rgb),
            (&["R", "G", "B", "A"][..], Layout::Rgba),
            (&["Y"][..], Layout::Y),
            (&["Y", "A"][..], Layout::YA),
            (&["X", "Y", "Z"][..], Layout::Xyz),
        ] {
            let img = decode(&exr(3, 2, names)).unwrap();
            assert_eq!(img.layout, layout);
            assert_eq!(img.samples.len(), 6 * layout.channels());
        }
        // Mitsuba's texture refuses anything else (MultiChannel): so does penumbra
        for names in [
            &["R", "G"][..],
            &["r", "g", "b"][..],
            &["diffuse.R", "diffuse.G", "diffuse.B"][..],
            &["R", "G", "B", "Z"][..],
            &["Y", "Z"][..],
            &["A"][..],
        ] {
            let e = err(&exr(3, 2, names));
            assert!(e.contains("unsupported OpenEXR channels"), "{e}");
        }
    }

    #[test]
    fn xyz_converts_to_rgb() {
        // X = Y = Z = 0.25 through Mitsuba's matrix (Bitmap::convert), by hand
        let one = decode(&exr(1, 1, &["X", "Y", "Z"])).unwrap();
        assert_eq!((one.layout, one.channels), (Layout::Xyz, 3));
        let Samples::F32(v) = one.samples else {
            panic!()
        };
        let rgb = [0.25 * 1.204794, 0.25 * 0.948291, 0.25 * 0.908916];
        for k in 0..3 {
            assert!((v[k] - rgb[k]).abs() < 1e-6, "{v:?}");
        }
    }

    #[test]
    fn malformed_input_is_refused_without_panicking() {
        // missing file, empty file, a directory
        let e = read(&repo("tests/data/textures/no-such-file.png")).unwrap_err();
        assert!(e.contains("no-such-file.png") && !e.contains('\n'), "{e}");
        assert!(read(&repo("tests/data/textures")).is_err());
        assert!(err(b"").contains("empty"));
        // random bytes (and random bytes after each magic number)
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state as u8
        };
        let magics: [&[u8]; 5] = [
            b"",
            b"\x89PNG\r\n\x1a\n",
            &[0xFF, 0xD8],
            b"BM",
            &[0x76, 0x2f, 0x31, 0x01],
        ];
        for magic in magics {
            for len in [0, 1, 7, 30, 100, 1000] {
                let mut b = magic.to_vec();
                b.extend((0..len).map(|_| next()));
                let _ = err(&b);
            }
        }
        // formats Mitsuba reads and penumbra does not
        assert!(err(b"#?RADIANCE\n").contains("RGBE"));
        assert!(err(b"PF\n1 1\n-1\n").contains("PFM"));
        let mut tga = vec![0u8; 40];
        tga.extend_from_slice(b"TRUEVISION-XFILE.\0");
        assert!(err(&tga).contains("TGA"));
    }

    #[test]
    fn truncated_files_are_refused() {
        // every prefix of each test file that cuts into the pixel data
        for name in [
            "rgb8.png",
            "rgb16.png",
            "palette4.png",
            "rgb.jpg",
            "grey.jpg",
        ] {
            let bytes = file(name);
            // a PNG may end after its image data (IEND, 12 bytes, is not needed)
            let end = if name.ends_with(".png") {
                bytes.len() - 12
            } else {
                bytes.len() - 1
            };
            for n in 0..end {
                let _ = err(&bytes[..n]);
            }
            assert!(decode(&bytes).is_ok());
        }
        let e = err(&file("rgb.jpg")[..400]);
        assert!(e.contains("truncated JPEG"), "{e}");
        let png = file("rgb8.png");
        let e = err(&png[..png.len() - 30]);
        assert!(e.contains("truncated or corrupt"), "{e}");
        for name in ["bgr24.bmp", "rgb_f32.exr", "rgba_f16.exr"] {
            let bytes = file(name);
            for n in 0..bytes.len() - 1 {
                // an EXR's last bytes may be padding
                let _ = decode(&bytes[..n]);
            }
            assert!(decode(&bytes[..bytes.len() / 2]).is_err(), "{name}");
        }
    }

    /// Found by the fuzz target: a B44 block whose decode under- and overflows u32. exr
    /// computes in wrapping arithmetic, as OpenEXR does, and the file decodes; with overflow
    /// checks (debug builds) exr panicked, in its thread pool, which aborted the process.
    /// Cargo.toml turns exr's overflow checks off in debug builds, and decode_limited
    /// catches decoder panics (then this would be an error, not an abort).
    #[test]
    fn b44_wrapping_arithmetic_does_not_panic() {
        let img = decode(&file("fuzz_b44_overflow.exr")).unwrap();
        assert_eq!((img.width, img.height), (4, 3));
    }

    /// Found by the fuzz target: zune-jpeg's message for this file spans several lines.
    #[test]
    fn decoder_messages_become_one_line() {
        let e = err(&file("fuzz_jpeg_multiline_error.jpg"));
        assert!(e.contains("JPEG"), "{e}");
    }

    #[test]
    fn zero_sized_images_are_refused() {
        assert!(err(&png_header(0, 5, &[])).contains("zero-sized"));
        assert!(err(&bmp(0, 3, 24, 0, &[])).contains("zero-sized"));
        assert!(err(&bmp(3, 0, 24, 0, &[])).contains("zero-sized"));
        // a JPEG frame header with height 0 (SOI, SOF0, SOS, EOI)
        let jpeg = [
            0xFF, 0xD8, 0xFF, 0xC0, 0, 11, 8, 0, 0, 0, 4, 1, 1, 0x11, 0, 0xFF, 0xDA, 0, 2, 0xFF,
            0xD9,
        ];
        assert!(err(&jpeg).contains("zero-sized"));
    }

    #[test]
    fn absurd_dimensions_are_refused_before_allocating() {
        const ABOVE: &str = "exceeds the image_pixels limit of 268435456 pixels (raise it with \
                             PENUMBRA_LIMITS=image_pixels=...)";
        let big = 1u32 << 20;
        let e = err(&png_header(big, big, &[]));
        assert!(e.contains(ABOVE), "{e}");
        let e = err(&bmp(big as i32, big as i32, 24, 0, &[]));
        assert!(e.contains(ABOVE), "{e}");
        let jpeg = [
            0xFF, 0xD8, 0xFF, 0xC0, 0, 11, 8, 0xFF, 0xFF, 0xFF, 0xFF, 1, 1, 0x11, 0, 0xFF, 0xDA, 0,
            2, 0xFF, 0xD9,
        ];
        let e = err(&jpeg);
        assert!(e.contains(ABOVE), "{e}");
        // allowed pixel count, but far more than the file can hold
        let e = err(&png_header(8192, 8192, &[]));
        assert!(e.contains("more than a"), "{e}");
        let e = err(&bmp(4096, 4096, 24, 0, &[]));
        assert!(e.contains("more than a"), "{e}");
        // an EXR whose header claims 2^20 x 2^20: change the data window's max corner
        let mut e = exr(4, 4, &["Y"]);
        let key = b"dataWindow\0box2i\0";
        let at = e.windows(key.len()).position(|w| w == key).unwrap() + key.len() + 4;
        e[at + 8..at + 16].copy_from_slice(&[0xFF, 0xFF, 0x0F, 0, 0xFF, 0xFF, 0x0F, 0]);
        let msg = err(&e);
        assert!(msg.contains(ABOVE), "{msg}");
        // a smaller limit, as the fuzz target uses
        assert!(decode_limited(&file("rgb.jpg"), 100).is_err());
        assert!(decode_limited(&file("rgb.jpg"), 192).is_ok());
    }

    #[test]
    fn unsupported_layouts_are_refused() {
        // a 4-component (CMYK) JPEG frame
        let jpeg = [
            0xFF, 0xD8, 0xFF, 0xC0, 0, 20, 8, 0, 8, 0, 8, 4, 1, 0x11, 0, 2, 0x11, 0, 3, 0x11, 0, 4,
            0x11, 0, 0xFF, 0xDA, 0, 2, 0xFF, 0xD9,
        ];
        assert!(err(&jpeg).contains("4 components"));
        assert!(err(&exr(2, 2, &["U", "V"])).contains("unsupported OpenEXR channels"));
    }

    /// scenes/volume-texture/sky.hdr was written by Mitsuba 3.9.1 from sky-64x32.exr
    /// (make_assets.py): its texels are the EXR's to RGBE's precision (8-bit mantissas sharing
    /// the largest channel's exponent), with Mitsuba's "#?RGBE" first line or Radiance's.
    #[test]
    fn rgbe_written_by_mitsuba_matches_its_source() {
        let hdr = std::fs::read(repo("scenes/volume-texture/sky.hdr")).unwrap();
        let exr = std::fs::read(repo("scenes/textures/sky-64x32.exr")).unwrap();
        assert!(hdr.starts_with(b"#?RGBE\n"));
        let (a, b) = (decode(&hdr).unwrap(), decode(&exr).unwrap());
        assert_eq!(
            (a.format, a.layout, a.channels),
            (FileFormat::Rgbe, Layout::Rgb, 3)
        );
        assert_eq!((a.width, a.height), (b.width, b.height));
        for p in 0..a.width * a.height {
            let m = (0..3)
                .map(|c| b.samples.value(3 * p + c))
                .fold(0.0f32, f32::max);
            for c in 0..3 {
                let (x, y) = (a.samples.value(3 * p + c), b.samples.value(3 * p + c));
                // RGBE truncates each channel to a step of 2^(e-8) with 2^e > max channel
                assert!(
                    y - x >= 0.0 && y - x <= m / 128.0,
                    "texel {p} channel {c}: {x} vs {y}"
                );
            }
        }
        let radiance = [b"#?RADIANCE".as_slice(), &hdr[6..]].concat();
        assert_eq!(decode(&radiance).unwrap(), a);
        // a truncated file is an error, not a panic
        assert!(err(&hdr[..hdr.len() / 2]).contains("RGBE"));
    }
}
