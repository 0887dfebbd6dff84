//! OpenEXR output (32-bit float, linear RGB, one part) with render metadata in the header,
//! and input of the same (and of Mitsuba's references). An optional per-sample variance is
//! stored as the channels `variance.R`, `variance.G`, `variance.B` of the same part.

use crate::error::{Error, Result};
use ::exr::prelude::*;
use std::collections::BTreeMap;
use std::path::Path;

/// An RGB image with an optional per-pixel variance, in row-major order from the top row.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbImage {
    pub width: usize,
    pub height: usize,
    pub rgb: Vec<[f32; 3]>,
    pub variance: Option<Vec<[f32; 3]>>,
    /// Header attributes other than the required ones, as text.
    pub attributes: BTreeMap<String, String>,
}

impl RgbImage {
    /// The samples per pixel recorded in the header attribute `spp` (penumbra and
    /// validation/mitsuba/render_reference.py write it), if present and a positive number.
    pub fn spp(&self) -> Option<f64> {
        self.attributes
            .get("spp")
            .and_then(|s| s.trim().parse::<f64>().ok())
            .filter(|v| v.is_finite() && *v > 0.0)
    }
}

/// A header attribute value to write.
#[derive(Clone, Debug)]
pub enum Attribute {
    Int(i32),
    Float(f64),
    Text(String),
}

fn channel(name: &str, data: &[[f32; 3]], c: usize) -> AnyChannel<FlatSamples> {
    AnyChannel::new(name, FlatSamples::F32(data.iter().map(|p| p[c]).collect()))
}

/// Writes `image` to `path` atomically ([`crate::io::atomic`]): into a temporary file of a
/// unique name next to it, synced, then renamed over it.
pub fn write(path: &Path, image: &RgbImage, attributes: &[(&str, Attribute)]) -> Result<()> {
    let n = image.width * image.height;
    if image.rgb.len() != n || image.variance.as_ref().is_some_and(|v| v.len() != n) {
        return Err(Error::Output {
            path: path.to_path_buf(),
            message: "pixel count does not match the resolution".into(),
        });
    }
    let mut channels = vec![
        channel("R", &image.rgb, 0),
        channel("G", &image.rgb, 1),
        channel("B", &image.rgb, 2),
    ];
    if let Some(var) = &image.variance {
        channels.push(channel("variance.R", var, 0));
        channels.push(channel("variance.G", var, 1));
        channels.push(channel("variance.B", var, 2));
    }
    write_any(path, (image.width, image.height), channels, attributes)
}

/// Writes named float channels (e.g. the `aov` integrator's `dd.T`, `nn.X`, ...) of a
/// `width` × `height` image, each row-major from the top row, atomically.
pub fn write_channels(
    path: &Path,
    (width, height): (usize, usize),
    channels: &[(String, Vec<f32>)],
    attributes: &[(&str, Attribute)],
) -> Result<()> {
    if channels.iter().any(|(_, v)| v.len() != width * height) {
        return Err(Error::Output {
            path: path.to_path_buf(),
            message: "pixel count does not match the resolution".into(),
        });
    }
    let channels = channels
        .iter()
        .map(|(name, v)| AnyChannel::new(name.as_str(), FlatSamples::F32(v.clone())))
        .collect();
    write_any(path, (width, height), channels, attributes)
}

fn write_any(
    path: &Path,
    size: (usize, usize),
    channels: Vec<AnyChannel<FlatSamples>>,
    attributes: &[(&str, Attribute)],
) -> Result<()> {
    let out_err = |message: String| Error::Output {
        path: path.to_path_buf(),
        message,
    };
    let mut la = LayerAttributes::default();
    for (name, value) in attributes {
        let v = match value {
            Attribute::Int(i) => AttributeValue::I32(*i),
            Attribute::Float(f) => AttributeValue::F64(*f),
            Attribute::Text(t) => {
                AttributeValue::Text(Text::new_or_none(t.as_str()).unwrap_or_default())
            }
        };
        la.other.insert(Text::from(*name), v);
    }
    let layer = Layer::new(
        size,
        la,
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(channels)),
    );
    let image = Image::from_layer(layer);
    crate::io::atomic::write_with(path, |file| {
        image
            .write()
            .to_buffered(file)
            .map_err(|e| std::io::Error::other(e.to_string()))
    })
    .map_err(|e| out_err(e.to_string()))
}

fn attribute_text(v: &AttributeValue) -> Option<String> {
    match v {
        AttributeValue::Text(t) => Some(t.to_string()),
        AttributeValue::I32(i) => Some(i.to_string()),
        AttributeValue::F32(f) => Some(f.to_string()),
        AttributeValue::F64(f) => Some(f.to_string()),
        _ => None,
    }
}

/// Reads the first part of an EXR file: channels R, G, B and, if present, the variance
/// channels (`variance.R` ... as penumbra writes them).
pub fn read(path: &Path) -> Result<RgbImage> {
    let in_err = |message: String| Error::Image {
        path: path.to_path_buf(),
        message,
    };
    let image = read_flat(path)?;
    let layer = &image.layer_data;
    let (width, height) = (layer.size.width(), layer.size.height());
    let get = |name: &str| -> Option<Vec<f32>> {
        layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.to_string() == name)
            .map(|c| c.sample_data.values_as_f32().collect())
    };
    let triple = |names: [&str; 3]| -> Result<Option<Vec<[f32; 3]>>> {
        let [r, g, b] = names.map(get);
        let (Some(r), Some(g), Some(b)) = (r, g, b) else {
            return Ok(None);
        };
        if [&r, &g, &b].iter().any(|c| c.len() != width * height) {
            return Err(in_err(
                "corrupt OpenEXR: a channel's size differs from the image's".into(),
            ));
        }
        Ok(Some(
            (0..width * height).map(|i| [r[i], g[i], b[i]]).collect(),
        ))
    };
    let rgb =
        triple(["R", "G", "B"])?.ok_or_else(|| in_err("EXR has no R, G, B channels".into()))?;
    let variance = triple(["variance.R", "variance.G", "variance.B"])?;
    let mut attributes = BTreeMap::new();
    for (k, v) in layer
        .attributes
        .other
        .iter()
        .chain(image.attributes.other.iter())
    {
        if let Some(t) = attribute_text(v) {
            attributes.insert(k.to_string(), t);
        }
    }
    Ok(RgbImage {
        width,
        height,
        rgb,
        variance,
        attributes,
    })
}

/// The checks made on the header before any pixel is allocated: a flat (not deep) first part
/// of at most `max_pixels` pixels (the `image_pixels` limit), whose decoded samples a
/// file of `file_len` bytes can hold (at most
/// [`MAX_EXPANSION`](crate::io::image::MAX_EXPANSION) decoded bytes per file byte), and no
/// sub-sampled channel (their sample counts differ from the pixel count). The size checks
/// are the texture images' ([`crate::io::image::check_size`]).
fn check_header(
    header: &::exr::meta::header::Header,
    file_len: u64,
    max_pixels: u64,
) -> Result<(), String> {
    if header.deep {
        return Err("deep OpenEXR images are not supported".into());
    }
    if header
        .channels
        .list
        .iter()
        .any(|c| c.sampling != Vec2(1, 1))
    {
        return Err("sub-sampled OpenEXR channels are not supported".into());
    }
    let (w, h) = (header.layer_size.0 as u64, header.layer_size.1 as u64);
    let bits_per_pixel: u64 = header
        .channels
        .list
        .iter()
        .map(|c| 8 * c.sample_type.bytes_per_sample() as u64)
        .sum();
    crate::io::image::check_size(
        w,
        h,
        bits_per_pixel,
        usize::try_from(file_len).unwrap_or(usize::MAX),
        max_pixels,
    )
}

/// The first part of an EXR file as flat samples. The file is opened as every input is
/// ([`crate::io::open_regular`]: a regular file of at most the `image_bytes` limit of
/// [`crate::limits`]), its header checked
/// ([`check_header`]) before any pixel is allocated, and a panic inside the decoder on a
/// malformed file becomes an error.
fn read_flat(path: &Path) -> Result<Image<Layer<AnyChannels<FlatSamples>>>> {
    use std::io::Seek;
    let in_err = |message: String| Error::Image {
        path: path.to_path_buf(),
        message,
    };
    let limits = crate::limits::current()?;
    let (file, file_len) =
        crate::io::open_regular(path, limits.file(crate::limits::Limit::ImageBytes)).map_err(
            |cause| Error::Io {
                path: path.to_path_buf(),
                cause,
            },
        )?;
    let mut reader = std::io::BufReader::new(file);
    let meta = ::exr::meta::MetaData::read_from_buffered(&mut reader, false)
        .map_err(|e| in_err(format!("cannot read OpenEXR header: {e}")))?;
    let header = meta
        .headers
        .first()
        .ok_or_else(|| in_err("EXR has no layer".into()))?;
    check_header(header, file_len, limits.image_pixels).map_err(in_err)?;
    let size = header.layer_size;
    reader.rewind().map_err(|cause| Error::Io {
        path: path.to_path_buf(),
        cause,
    })?;
    // The decoder runs on this thread (non_parallel), so that a panic can be caught here.
    let decoded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        ::exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .first_valid_layer()
            .all_attributes()
            .non_parallel()
            .from_buffered(reader)
    }))
    .map_err(|_| in_err("the OpenEXR decoder failed on this file (corrupt?)".into()))?;
    let image = decoded.map_err(|e| in_err(e.to_string()))?;
    if image.layer_data.size != size {
        return Err(in_err(
            "corrupt OpenEXR: layer differs from its header".into(),
        ));
    }
    Ok(image)
}

/// Named channels of an image, each row-major from the top row.
pub type NamedChannels = Vec<(String, Vec<f32>)>;

/// Every channel of the first part of an EXR file, by name (as `write_channels` writes them),
/// with the image's size.
pub fn read_channels(path: &Path) -> Result<((usize, usize), NamedChannels)> {
    let image = read_flat(path)?;
    let layer = &image.layer_data;
    let channels = layer
        .channel_data
        .list
        .iter()
        .map(|c| (c.name.to_string(), c.sample_data.values_as_f32().collect()))
        .collect();
    Ok(((layer.size.width(), layer.size.height()), channels))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_with_variance_and_attributes() {
        let dir = std::env::temp_dir().join(format!("penumbra-exr-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("rt.exr");
        let img = RgbImage {
            width: 3,
            height: 2,
            rgb: (0..6)
                .map(|i| [i as f32, 0.5, -1.0 / (i as f32 + 1.0)])
                .collect(),
            variance: Some((0..6).map(|i| [0.1 * i as f32; 3]).collect()),
            attributes: BTreeMap::new(),
        };
        write(
            &path,
            &img,
            &[
                ("spp", Attribute::Int(64)),
                ("penumbra_version", Attribute::Text("x".into())),
            ],
        )
        .unwrap();
        let back = read(&path).unwrap();
        assert_eq!(back.rgb, img.rgb);
        assert_eq!(back.variance, img.variance);
        assert_eq!(back.attributes.get("spp").map(String::as_str), Some("64"));
        let names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["rt.exr"], "no temporary file is left");
        std::fs::remove_dir_all(&dir).ok();
    }
}
