//! The limits on input that a real scene could exceed, and the environment variable that
//! raises (or lowers) them: `PENUMBRA_LIMITS`.
//!
//! Every read is bounded before it allocates. Most bounds guard against hostile files and
//! are fixed (a scene file's size, the XML parsed in all, included files and their depth,
//! a film's side, decompression ratios): no real scene comes near them. The ones here bound
//! what a large but honest scene holds — a 16K × 8K panorama's film, a 32K HDRI, a scanned
//! mesh of billions of triangles, a large `.vol` grid, a fine radiosity solution — so a run
//! may set them, e.g.
//!
//! ```text
//! PENUMBRA_LIMITS="render_pixels=2^28,mesh_bytes=32G" penumbra render scene.xml
//! ```
//!
//! The variable is read once per process ([`current`]), by the loaders themselves, so the
//! CLI, the Python module and Slurm jobs (whose scripts export the environment) all obey it.
//! A limit that refuses an input names itself and the variable in its one-line message.
//!
//! Syntax: comma-separated `name=value` entries (spaces around them allowed, empty entries
//! ignored, each name at most once). A value is a positive integer, optionally with a
//! binary suffix `K`, `M`, `G` or `T` (× 2^10, 2^20, 2^30, 2^40; either case), or `2^N`
//! (N ≤ 63). 0 is refused, as are unknown names, other forms and values above 2^64 − 1.

use crate::{Error, Result};
use std::sync::OnceLock;

/// The environment variable read by [`current`].
pub const VAR: &str = "PENUMBRA_LIMITS";

/// One limit that [`VAR`] sets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Limit {
    /// Pixels of the film rendered (its crop window), and of a checkpoint or part file.
    RenderPixels,
    /// Pixels of an input image: a texture, an environment map, a compared EXR.
    ImagePixels,
    /// Bytes of an input image file.
    ImageBytes,
    /// Bytes of a mesh file (OBJ, PLY, `.serialized`).
    MeshBytes,
    /// Decompressed bytes of one shape of a `.serialized` file.
    ShapeBytes,
    /// Bytes of a `.vol` grid file.
    VolBytes,
    /// Form-factor rays of a radiosity solution (2 sides × patches × `rays_per_patch`).
    RadiosityRays,
}

/// What a limit counts, for its messages.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Unit {
    Pixels,
    Bytes,
    Rays,
}

impl Limit {
    /// Every limit, in the order messages and the documentation list them.
    pub const ALL: [Limit; 7] = [
        Limit::RenderPixels,
        Limit::ImagePixels,
        Limit::ImageBytes,
        Limit::MeshBytes,
        Limit::ShapeBytes,
        Limit::VolBytes,
        Limit::RadiosityRays,
    ];

    /// Its name in [`VAR`].
    pub fn name(self) -> &'static str {
        match self {
            Limit::RenderPixels => "render_pixels",
            Limit::ImagePixels => "image_pixels",
            Limit::ImageBytes => "image_bytes",
            Limit::MeshBytes => "mesh_bytes",
            Limit::ShapeBytes => "shape_bytes",
            Limit::VolBytes => "vol_bytes",
            Limit::RadiosityRays => "radiosity_rays",
        }
    }

    fn unit(self) -> Unit {
        match self {
            Limit::RenderPixels | Limit::ImagePixels => Unit::Pixels,
            Limit::RadiosityRays => Unit::Rays,
            _ => Unit::Bytes,
        }
    }

    /// `the mesh_bytes limit of 8 GiB`: the limit at `value`, for a message.
    pub fn of(self, value: u64) -> String {
        format!("the {} limit of {}", self.name(), show(value, self.unit()))
    }

    /// `PENUMBRA_LIMITS=mesh_bytes=...`: how to raise it, for a message.
    pub fn setting(self) -> String {
        format!("{VAR}={}=...", self.name())
    }

    /// `the mesh_bytes limit of 8 GiB (raise it with PENUMBRA_LIMITS=mesh_bytes=...)`: what
    /// a message says of the limit an input exceeds.
    pub fn exceeded(self, value: u64) -> String {
        format!("{} (raise it with {})", self.of(value), self.setting())
    }
}

/// `value` in its unit: bytes in the largest binary unit that divides them (`8 GiB`,
/// `1500 bytes`), counts as integers (`67108864 pixels`).
fn show(value: u64, unit: Unit) -> String {
    match unit {
        Unit::Pixels => format!("{value} pixels"),
        Unit::Rays => format!("{value} rays"),
        Unit::Bytes => {
            for (shift, suffix) in [(40, "TiB"), (30, "GiB"), (20, "MiB"), (10, "KiB")] {
                if value >= 1 << shift && value.is_multiple_of(1 << shift) {
                    return format!("{} {suffix}", value >> shift);
                }
            }
            if value == 1 {
                "1 byte".into()
            } else {
                format!("{value} bytes")
            }
        }
    }
}

/// The limits in effect: [`Limits::DEFAULT`] with what [`VAR`] sets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Pixels of the film rendered, its crop window (default 2^26 = 8192²: its f64 film
    /// takes 3.8 GB). A film's side is also at most 2^16 (fixed).
    pub render_pixels: u64,
    /// Pixels of an input image (default 2^28 = 16384²; NASA's 21600 × 10800 Blue Marble
    /// stays below; at 3 half-float channels 1.5 GiB).
    pub image_pixels: u64,
    /// Bytes of an input image file (default 4 GiB: a 16384² RGB float EXR, uncompressed,
    /// is 3 GiB).
    pub image_bytes: u64,
    /// Bytes of a mesh file (default 8 GiB).
    pub mesh_bytes: u64,
    /// Decompressed bytes of one `.serialized` shape (default 8 GiB, as a mesh file).
    pub shape_bytes: u64,
    /// Bytes of a `.vol` grid file (default 8 GiB).
    pub vol_bytes: u64,
    /// Form-factor rays of a radiosity solution (default 2^28, about a minute of ray casting
    /// on 2 cores; the ladder's finest study casts 2^25).
    pub radiosity_rays: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Limits::DEFAULT
    }
}

impl Limits {
    /// The limits when [`VAR`] is unset.
    pub const DEFAULT: Limits = Limits {
        render_pixels: 1 << 26,
        image_pixels: 1 << 28,
        image_bytes: 1 << 32,
        mesh_bytes: 1 << 33,
        shape_bytes: 1 << 33,
        vol_bytes: 1 << 33,
        radiosity_rays: 1 << 28,
    };

    /// One limit's value.
    pub fn get(&self, limit: Limit) -> u64 {
        match limit {
            Limit::RenderPixels => self.render_pixels,
            Limit::ImagePixels => self.image_pixels,
            Limit::ImageBytes => self.image_bytes,
            Limit::MeshBytes => self.mesh_bytes,
            Limit::ShapeBytes => self.shape_bytes,
            Limit::VolBytes => self.vol_bytes,
            Limit::RadiosityRays => self.radiosity_rays,
        }
    }

    fn get_mut(&mut self, limit: Limit) -> &mut u64 {
        match limit {
            Limit::RenderPixels => &mut self.render_pixels,
            Limit::ImagePixels => &mut self.image_pixels,
            Limit::ImageBytes => &mut self.image_bytes,
            Limit::MeshBytes => &mut self.mesh_bytes,
            Limit::ShapeBytes => &mut self.shape_bytes,
            Limit::VolBytes => &mut self.vol_bytes,
            Limit::RadiosityRays => &mut self.radiosity_rays,
        }
    }

    /// [`Limit::exceeded`] at this limit's value.
    pub fn exceeded(&self, limit: Limit) -> String {
        limit.exceeded(self.get(limit))
    }

    /// The size limit of a file that `limit` bounds, for [`crate::io::open_regular`].
    pub fn file(&self, limit: Limit) -> crate::io::FileLimit {
        crate::io::FileLimit {
            bytes: self.get(limit),
            limit: Some(limit),
        }
    }

    /// The largest file any loader reads under these limits: the largest of the (fixed)
    /// scene file limit and the image, mesh and `.vol` file limits. The scene's identity
    /// hash (`progressive::scene_hash`) reads at most this much of a file.
    pub fn input_file_bytes(&self) -> u64 {
        [
            crate::io::MAX_SCENE_FILE_BYTES,
            self.image_bytes,
            self.mesh_bytes,
            self.vol_bytes,
        ]
        .into_iter()
        .max()
        .unwrap_or(u64::MAX)
    }

    /// [`Limits::DEFAULT`] with the entries of `spec`, a value of [`VAR`] (see the module's
    /// documentation for the syntax). An empty `spec` gives the defaults.
    pub fn parse(spec: &str) -> Result<Limits> {
        let mut limits = Limits::DEFAULT;
        let mut given: Vec<Limit> = Vec::new();
        for entry in spec.split(',').map(str::trim).filter(|e| !e.is_empty()) {
            let refuse =
                |problem: String| Error::Limits(format!("{problem} in \"{entry}\"; {HELP}"));
            let Some((name, value)) = entry.split_once('=') else {
                return Err(refuse("no '=' (entries are name=value)".into()));
            };
            let name = name.trim();
            let Some(limit) = Limit::ALL.into_iter().find(|l| l.name() == name) else {
                return Err(refuse(format!("unknown limit \"{name}\"")));
            };
            if given.contains(&limit) {
                return Err(refuse(format!("{name} given twice")));
            }
            given.push(limit);
            *limits.get_mut(limit) =
                parse_value(value.trim()).map_err(|problem| refuse(problem.into()))?;
        }
        Ok(limits)
    }

    /// The limits from the environment: [`Limits::parse`] of [`VAR`], the defaults when it
    /// is unset. Read every time; [`current`] reads it once.
    pub fn from_env() -> Result<Limits> {
        match std::env::var(VAR) {
            Ok(spec) => Limits::parse(&spec),
            Err(std::env::VarError::NotPresent) => Ok(Limits::DEFAULT),
            Err(std::env::VarError::NotUnicode(_)) => {
                Err(Error::Limits(format!("not valid UTF-8; {HELP}")))
            }
        }
    }
}

/// What every message about the variable's syntax ends with.
const HELP: &str = "the limits are render_pixels, image_pixels, image_bytes, mesh_bytes, \
                    shape_bytes, vol_bytes and radiosity_rays, set as name=value[,name=value...] \
                    with a value of at least 1: an integer, optionally with a binary suffix \
                    K, M, G or T, or 2^N";

/// A limit's value: `1024`, `8K`, `32G`, `2^28` (see the module's documentation).
fn parse_value(text: &str) -> Result<u64, &'static str> {
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    let too_large = "value above 2^64 - 1";
    let value = if let Some(exponent) = text.strip_prefix("2^") {
        if !digits(exponent) {
            return Err("bad value (2^N needs a whole N)");
        }
        match exponent.parse::<u32>() {
            Ok(n) if n < 64 => 1u64 << n,
            _ => return Err(too_large),
        }
    } else {
        let (number, shift) = match text.as_bytes().last().map(u8::to_ascii_uppercase) {
            Some(b'K') => (&text[..text.len() - 1], 10),
            Some(b'M') => (&text[..text.len() - 1], 20),
            Some(b'G') => (&text[..text.len() - 1], 30),
            Some(b'T') => (&text[..text.len() - 1], 40),
            _ => (text, 0),
        };
        if !digits(number) {
            return Err("bad value");
        }
        let n = number.parse::<u64>().map_err(|_| too_large)?;
        n.checked_mul(1u64 << shift).ok_or(too_large)?
    };
    if value == 0 {
        return Err("a limit of 0 allows nothing");
    }
    Ok(value)
}

/// The limits of this process: [`Limits::from_env`] read once, at the first call (the CLI
/// makes it before loading anything), and the same value or error ever after.
pub fn current() -> Result<Limits> {
    static CURRENT: OnceLock<std::result::Result<Limits, String>> = OnceLock::new();
    let read = CURRENT.get_or_init(|| {
        Limits::from_env().map_err(|e| match e {
            Error::Limits(message) => message,
            other => other.to_string(),
        })
    });
    read.clone().map_err(Error::Limits)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(spec: &str) -> Limits {
        Limits::parse(spec).unwrap_or_else(|e| panic!("{spec:?}: {e}"))
    }

    fn refused(spec: &str) -> String {
        match Limits::parse(spec) {
            Ok(l) => panic!("{spec:?} accepted: {l:?}"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn defaults_are_the_documented_values() {
        let d = Limits::DEFAULT;
        assert_eq!(d.render_pixels, 67_108_864);
        assert_eq!(d.image_pixels, 268_435_456);
        assert_eq!(d.image_bytes, 4_294_967_296);
        assert_eq!(d.mesh_bytes, 8_589_934_592);
        assert_eq!(d.shape_bytes, 8_589_934_592);
        assert_eq!(d.vol_bytes, 8_589_934_592);
        assert_eq!(d.radiosity_rays, 268_435_456);
        assert_eq!(Limits::default(), d);
        // the scene hash reads as much as the largest file limit (mesh and vol: 8 GiB)
        assert_eq!(d.input_file_bytes(), 1 << 33);
    }

    #[test]
    fn empty_specs_give_the_defaults() {
        for spec in ["", " ", ",", " , ,"] {
            assert_eq!(parse(spec), Limits::DEFAULT, "{spec:?}");
        }
    }

    #[test]
    fn accepted_forms_have_exact_values() {
        let cases: [(&str, u64); 16] = [
            ("1", 1),
            ("1024", 1024),
            ("18446744073709551615", u64::MAX),
            ("1K", 1 << 10),
            ("1k", 1 << 10),
            ("3K", 3 << 10),
            ("5M", 5 << 20),
            ("5m", 5 << 20),
            ("32G", 32 << 30),
            ("2T", 2 << 40),
            ("16777215T", 16_777_215 << 40),
            ("2^0", 1),
            ("2^10", 1024),
            ("2^28", 1 << 28),
            ("2^63", 1 << 63),
            ("007", 7),
        ];
        for (value, expected) in cases {
            let l = parse(&format!("mesh_bytes={value}"));
            assert_eq!(l.mesh_bytes, expected, "{value}");
            assert_eq!(
                Limits {
                    mesh_bytes: Limits::DEFAULT.mesh_bytes,
                    ..l
                },
                Limits::DEFAULT,
                "{value}: only mesh_bytes set"
            );
        }
    }

    #[test]
    fn every_limit_is_set_by_its_name() {
        let l = parse(
            " render_pixels = 2^28 , image_pixels=1G,image_bytes=64G, mesh_bytes=32G,\
             shape_bytes=3,vol_bytes=1T,radiosity_rays=2^30,",
        );
        assert_eq!(
            l,
            Limits {
                render_pixels: 1 << 28,
                image_pixels: 1 << 30,
                image_bytes: 64 << 30,
                mesh_bytes: 32 << 30,
                shape_bytes: 3,
                vol_bytes: 1 << 40,
                radiosity_rays: 1 << 30,
            }
        );
        for limit in Limit::ALL {
            let l = parse(&format!("{}=7", limit.name()));
            assert_eq!(l.get(limit), 7, "{limit:?}");
            let mut d = Limits::DEFAULT;
            *d.get_mut(limit) = 9;
            assert_eq!((d.get(limit), d.exceeded(limit)), (9, limit.exceeded(9)));
        }
        // the hash's bound follows the largest file limit, up or down to the scene file's
        assert_eq!(l.input_file_bytes(), 1 << 40);
        let small = parse("image_bytes=1K,mesh_bytes=1K,vol_bytes=1K");
        assert_eq!(small.input_file_bytes(), crate::io::MAX_SCENE_FILE_BYTES);
    }

    #[test]
    fn refused_forms_name_the_variable_the_entry_and_the_limits() {
        let cases = [
            (
                "mesh_byte=1K",
                "unknown limit \"mesh_byte\" in \"mesh_byte=1K\"",
            ),
            (
                "MESH_BYTES=1K",
                "unknown limit \"MESH_BYTES\" in \"MESH_BYTES=1K\"",
            ),
            ("=5", "unknown limit \"\" in \"=5\""),
            (
                "mesh_bytes",
                "no '=' (entries are name=value) in \"mesh_bytes\"",
            ),
            ("mesh_bytes=", "bad value in \"mesh_bytes=\""),
            (
                "mesh_bytes=0",
                "a limit of 0 allows nothing in \"mesh_bytes=0\"",
            ),
            (
                "mesh_bytes=0K",
                "a limit of 0 allows nothing in \"mesh_bytes=0K\"",
            ),
            ("mesh_bytes=-1", "bad value in \"mesh_bytes=-1\""),
            ("mesh_bytes=+1", "bad value in \"mesh_bytes=+1\""),
            ("mesh_bytes=1.5G", "bad value in \"mesh_bytes=1.5G\""),
            ("mesh_bytes=1 K", "bad value in \"mesh_bytes=1 K\""),
            ("mesh_bytes=1KB", "bad value in \"mesh_bytes=1KB\""),
            ("mesh_bytes=1KiB", "bad value in \"mesh_bytes=1KiB\""),
            ("mesh_bytes=K", "bad value in \"mesh_bytes=K\""),
            ("mesh_bytes=1P", "bad value in \"mesh_bytes=1P\""),
            ("mesh_bytes=1e9", "bad value in \"mesh_bytes=1e9\""),
            ("mesh_bytes=0x10", "bad value in \"mesh_bytes=0x10\""),
            ("mesh_bytes=1_000", "bad value in \"mesh_bytes=1_000\""),
            (
                "mesh_bytes=2^",
                "bad value (2^N needs a whole N) in \"mesh_bytes=2^\"",
            ),
            (
                "mesh_bytes=2^-1",
                "bad value (2^N needs a whole N) in \"mesh_bytes=2^-1\"",
            ),
            (
                "mesh_bytes=2^1.5",
                "bad value (2^N needs a whole N) in \"mesh_bytes=2^1.5\"",
            ),
            ("mesh_bytes=3^4", "bad value in \"mesh_bytes=3^4\""),
            (
                "mesh_bytes=2^64",
                "value above 2^64 - 1 in \"mesh_bytes=2^64\"",
            ),
            (
                "mesh_bytes=2^99999999999",
                "value above 2^64 - 1 in \"mesh_bytes=2^99999999999\"",
            ),
            (
                "mesh_bytes=18446744073709551616",
                "value above 2^64 - 1 in \"mesh_bytes=18446744073709551616\"",
            ),
            (
                "mesh_bytes=16777216T",
                "value above 2^64 - 1 in \"mesh_bytes=16777216T\"",
            ),
            ("mesh_bytes=1=2", "bad value in \"mesh_bytes=1=2\""),
            (
                "mesh_bytes=1K,mesh_bytes=2K",
                "mesh_bytes given twice in \"mesh_bytes=2K\"",
            ),
            (
                "render_pixels=2^28;mesh_bytes=1K",
                "bad value (2^N needs a whole N) in \"render_pixels=2^28;mesh_bytes=1K\"",
            ),
            (
                "mesh_bytes=1K,oops",
                "no '=' (entries are name=value) in \"oops\"",
            ),
        ];
        for (spec, expected) in cases {
            let e = refused(spec);
            assert_eq!(
                e,
                format!("PENUMBRA_LIMITS: {expected}; {HELP}"),
                "{spec:?}"
            );
            assert!(!e.contains('\n'), "{e}");
            for limit in Limit::ALL {
                assert!(e.contains(limit.name()), "{e}");
            }
        }
    }

    #[test]
    fn messages_name_the_limit_and_how_to_raise_it() {
        assert_eq!(
            Limit::MeshBytes.exceeded(1 << 33),
            "the mesh_bytes limit of 8 GiB (raise it with PENUMBRA_LIMITS=mesh_bytes=...)"
        );
        assert_eq!(
            Limits::DEFAULT.exceeded(Limit::RenderPixels),
            "the render_pixels limit of 67108864 pixels (raise it with \
             PENUMBRA_LIMITS=render_pixels=...)"
        );
        assert_eq!(
            Limit::RadiosityRays.of(1 << 28),
            "the radiosity_rays limit of 268435456 rays"
        );
        let shown = [
            (1, "1 byte"),
            (1000, "1000 bytes"),
            (1024, "1 KiB"),
            (1536, "1536 bytes"),
            (3 << 20, "3 MiB"),
            ((1 << 30) + 1, "1073741825 bytes"),
            (3 << 40, "3 TiB"),
            (u64::MAX, "18446744073709551615 bytes"),
        ];
        for (value, expected) in shown {
            assert_eq!(show(value, Unit::Bytes), expected, "{value}");
        }
    }
}
