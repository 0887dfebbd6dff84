//! Mitsuba `<spectrum>` values turned into the linear sRGB triple that Mitsuba 3.9.1's RGB
//! variants (`scalar_rgb`, `llvm_ad_rgb`) store.
//!
//! A scene gives a spectrum as one number (`value="0.789"`, a *uniform* spectrum), as
//! wavelength:value pairs (`value="400:0.343, 404:0.445, ..."`, nm), or as a `.spd` file
//! (`filename="foo.spd"`, see [`SpectrumValue::from_spd`]). What RGB value Mitsuba makes of it
//! depends on how the plugin reads the parameter ([`ColorRole`]):
//!
//! | spectrum | [`Reflectance`](ColorRole::Reflectance) | [`Unbounded`](ColorRole::Unbounded) | [`Emission`](ColorRole::Emission) |
//! |---|---|---|---|
//! | uniform `v` | `(v, v, v)` | `(v, v, v)` | `v · xyz_to_srgb(1, 1, 1)` ≈ `v · (1.205, 0.948, 0.909)` |
//! | pairs | D65-weighted, clamped to [0, 1] | D65-weighted, negatives clamped to 0 | not D65-weighted, negatives clamped to 0 |
//!
//! Uniform values are never clamped or checked (a uniform reflectance of 1.5 or -0.25 is taken
//! as is, like Mitsuba's `uniform` texture), and a uniform emitter spectrum is deliberately not
//! grey: Mitsuba's RGB variants imitate its spectral variants, where a flat spectrum is not white
//! under sRGB's D65 white point.
//!
//! Pairs are integrated as Mitsuba's `spectrum_list_to_srgb` does: 1000 wavelengths evenly
//! spaced over [360, 830] nm (both ends included), the list interpolated linearly and
//! contributing nothing outside its first and last wavelength (it is not extended), each sample
//! weighted by the CIE 1931 2° colour matching functions (linearly interpolated from their 5 nm
//! table) and, unless the role is emission, by the CIE D65 illuminant normalised to luminance
//! 1; the sum is scaled by `470 / 1000 / 106.75...` (so that a unit spectrum has luminance 1)
//! and converted with [`xyz_to_srgb`]. Mitsuba computes all of this in double precision (its
//! `Properties` hold doubles; only the tables and matrix coefficients are single-precision
//! literals) and rounds the result to `f32` when the texture stores it; this module does the
//! same operations in the same order, so its results agree with Mitsuba's stored values to the
//! last bit in every case of `tests/data/mitsuba_spectrum_values.txt`.
//!
//! Where penumbra departs from Mitsuba on purpose: numbers that are not finite (`nan`, `inf`,
//! `1e400`) are parse errors here (Mitsuba accepts them and renders NaNs), and a result that does
//! not fit in `f32` is replaced by a finite one with a warning (see [`SpectrumValue::to_rgb`]).
//! One more: a number made only of tabs (possible only through `&#9;` in the XML, since XML
//! turns literal tabs in attributes into spaces, which separate entries) is an error here; a
//! quirk of Mitsuba's `string::stof` reads it as 0.

use glam::DVec3;

/// An RGB triple of linear sRGB-primaries values: what penumbra renders (RGB mode).
pub type Spectrum = glam::Vec3;

/// Mitsuba's luminance of a linear sRGB colour (its `luminance()` weights): the one
/// luminance of penumbra (Russian roulette, texture means, error estimates).
#[inline]
pub fn luminance(c: glam::Vec3) -> f32 {
    0.212671 * c.x + 0.715160 * c.y + 0.072169 * c.z
}

/// The exact sRGB decode (IEC 61966-2-1) of one channel in [0, 1].
pub fn srgb_to_linear(x: f64) -> f64 {
    if x <= 0.04045 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

/// How a plugin reads a colour parameter, which decides how a spectrum becomes RGB
/// (Mitsuba's `Properties::get_texture`, `get_unbounded_texture`, `get_emissive_texture`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ColorRole {
    /// A reflectance or transmittance in [0, 1] (`get_texture`: diffuse `reflectance`,
    /// `specular_reflectance`, ...): D65-weighted, clamped to [0, 1].
    Reflectance,
    /// An unbounded non-emissive quantity (`get_unbounded_texture`: conductor `eta` and `k`,
    /// roughness `alpha`): D65-weighted, negative components clamped to 0.
    Unbounded,
    /// Emitted radiance, intensity or irradiance (`get_emissive_texture`: area and constant
    /// emitter `radiance`, ...): not D65-weighted, negative components clamped to 0.
    Emission,
}

/// A parsed `<spectrum>` value.
#[derive(Clone, Debug, PartialEq)]
pub enum SpectrumValue {
    /// A single number: the same value at every wavelength.
    Uniform(f64),
    /// Wavelength (nm) / value pairs. [`SpectrumValue::parse`], [`SpectrumValue::from_spd`] and
    /// [`SpectrumValue::sampled`] guarantee at least two entries, equal lengths, finite numbers
    /// and strictly increasing wavelengths; [`SpectrumValue::to_rgb`] re-checks a value built
    /// directly and refuses one that breaks these rules.
    Sampled {
        /// Wavelengths in nanometres, strictly increasing.
        wavelengths: Vec<f64>,
        /// The spectrum's value at each wavelength.
        values: Vec<f64>,
    },
}

/// Shortest wavelength of the CIE tables and of the integration (nm), Mitsuba's `MI_CIE_MIN`.
pub const CIE_MIN: f64 = 360.0;
/// Longest wavelength of the CIE tables and of the integration (nm), Mitsuba's `MI_CIE_MAX`.
pub const CIE_MAX: f64 = 830.0;
/// Number of entries of the CIE tables (5 nm apart), Mitsuba's `MI_CIE_SAMPLES`.
pub const CIE_SAMPLES: usize = 95;
/// Scale of the CIE curves that gives a unit spectrum luminance 1, Mitsuba's
/// `MI_CIE_Y_NORMALIZATION` (the integral of ȳ over the table, as a double).
// Written out in full: 106.7502593994140625 is exact in f32 and f64, as in Mitsuba's source.
#[allow(clippy::excessive_precision)]
pub const CIE_Y_NORMALIZATION: f64 = 1.0 / 106.750_259_399_414_062_5;
/// Scale of the D65 table that gives it luminance 1, Mitsuba's `MI_CIE_D65_NORMALIZATION`.
pub(crate) const D65_NORMALIZATION: f64 = 1.0 / 98.997_417_518_762_55;
/// Number of wavelengths at which `spectrum_list_to_srgb` samples a list.
const STEPS: usize = 1000;

// CIE 1931 2° colour matching functions x̄, ȳ, z̄, 360-830 nm in 5 nm steps (CIE 015:2004 /
// CVRL table, the values Mitsuba uses). Mitsuba stores them as `f32` (written as double literals
// cast to float), so they are rounded through `f32` when read, see `table`.
#[rustfmt::skip]
pub(crate) const CIE_X: [f64; CIE_SAMPLES] = [
    0.0001299, 0.0002321, 0.0004149, 0.0007416, 0.001368, 0.002236, 0.004243, 0.00765, 0.01431,
    0.02319, 0.04351, 0.07763, 0.13438, 0.21477, 0.2839, 0.3285, 0.34828, 0.34806, 0.3362, 0.3187,
    0.2908, 0.2511, 0.19536, 0.1421, 0.09564, 0.05795001, 0.03201, 0.0147, 0.0049, 0.0024, 0.0093,
    0.0291, 0.06327, 0.1096, 0.1655, 0.2257499, 0.2904, 0.3597, 0.4334499, 0.5120501, 0.5945,
    0.6784, 0.7621, 0.8425, 0.9163, 0.9786, 1.0263, 1.0567, 1.0622, 1.0456, 1.0026, 0.9384,
    0.8544499, 0.7514, 0.6424, 0.5419, 0.4479, 0.3608, 0.2835, 0.2187, 0.1649, 0.1212, 0.0874,
    0.0636, 0.04677, 0.0329, 0.0227, 0.01584, 0.01135916, 0.008110916, 0.005790346, 0.004109457,
    0.002899327, 0.00204919, 0.001439971, 0.0009999493, 0.0006900786, 0.0004760213, 0.0003323011,
    0.0002348261, 0.0001661505, 0.000117413, 0.00008307527, 0.00005870652, 0.00004150994,
    0.00002935326, 0.00002067383, 0.00001455977, 0.00001025398, 0.000007221456, 0.000005085868,
    0.000003581652, 0.000002522525, 0.000001776509, 0.000001251141,
];
#[rustfmt::skip]
pub(crate) const CIE_Y: [f64; CIE_SAMPLES] = [
    0.000003917, 0.000006965, 0.00001239, 0.00002202, 0.000039, 0.000064, 0.00012, 0.000217,
    0.000396, 0.00064, 0.00121, 0.00218, 0.004, 0.0073, 0.0116, 0.01684, 0.023, 0.0298, 0.038,
    0.048, 0.06, 0.0739, 0.09098, 0.1126, 0.13902, 0.1693, 0.20802, 0.2586, 0.323, 0.4073, 0.503,
    0.6082, 0.71, 0.7932, 0.862, 0.9148501, 0.954, 0.9803, 0.9949501, 1.0, 0.995, 0.9786, 0.952,
    0.9154, 0.87, 0.8163, 0.757, 0.6949, 0.631, 0.5668, 0.503, 0.4412, 0.381, 0.321, 0.265, 0.217,
    0.175, 0.1382, 0.107, 0.0816, 0.061, 0.04458, 0.032, 0.0232, 0.017, 0.01192, 0.00821, 0.005723,
    0.004102, 0.002929, 0.002091, 0.001484, 0.001047, 0.00074, 0.00052, 0.0003611, 0.0002492,
    0.0001719, 0.00012, 0.0000848, 0.00006, 0.0000424, 0.00003, 0.0000212, 0.00001499, 0.0000106,
    0.0000074657, 0.0000052578, 0.0000037029, 0.0000026078, 0.0000018366, 0.0000012934,
    0.00000091093, 0.00000064153, 0.00000045181,
];
#[rustfmt::skip]
pub(crate) const CIE_Z: [f64; CIE_SAMPLES] = [
    0.0006061, 0.001086, 0.001946, 0.003486, 0.006450001, 0.01054999, 0.02005001, 0.03621,
    0.06785001, 0.1102, 0.2074, 0.3713, 0.6456, 1.0390501, 1.3856, 1.62296, 1.74706, 1.7826,
    1.77211, 1.7441, 1.6692, 1.5281, 1.28764, 1.0419, 0.8129501, 0.6162, 0.46518, 0.3533, 0.272,
    0.2123, 0.1582, 0.1117, 0.07824999, 0.05725001, 0.04216, 0.02984, 0.0203, 0.0134, 0.008749999,
    0.005749999, 0.0039, 0.002749999, 0.0021, 0.0018, 0.001650001, 0.0014, 0.0011, 0.001, 0.0008,
    0.0006, 0.00034, 0.00024, 0.00019, 0.0001, 0.00004999999, 0.00003, 0.00002, 0.00001, 0.0, 0.0,
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
    0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
];
#[rustfmt::skip]
pub(crate) const D65: [f32; CIE_SAMPLES] = [
    46.6383, 49.3637, 52.0891, 51.0323, 49.9755, 52.3118, 54.6482, 68.7015, 82.7549, 87.1204,
    91.486, 92.4589, 93.4318, 90.057, 86.6823, 95.7736, 104.865, 110.936, 117.008, 117.41, 117.812,
    116.336, 114.861, 115.392, 115.923, 112.367, 108.811, 109.082, 109.354, 108.578, 107.802,
    106.296, 104.79, 106.239, 107.689, 106.047, 104.405, 104.225, 104.046, 102.023, 100.0, 98.1671,
    96.3342, 96.0611, 95.788, 92.2368, 88.6856, 89.3459, 90.0062, 89.8026, 89.5991, 88.6489,
    87.6987, 85.4936, 83.2886, 83.4939, 83.6992, 81.863, 80.0268, 80.1207, 80.2146, 81.2462,
    82.2778, 80.281, 78.2842, 74.0027, 69.7213, 70.6652, 71.6091, 72.979, 74.349, 67.9765, 61.604,
    65.7448, 69.8856, 72.4863, 75.087, 69.3398, 63.5927, 55.0054, 46.4182, 56.6118, 66.8054,
    65.0941, 63.3828, 63.8434, 64.304, 61.8779, 59.4519, 55.7054, 51.959, 54.6998, 57.4406,
    58.8765, 60.3125,
];

/// Entry `i` of a double-literal table as Mitsuba holds it: rounded to `f32`.
fn table(t: &[f64; CIE_SAMPLES], i: usize) -> f64 {
    t[i] as f32 as f64
}

/// Table position of wavelength `w`: the index of the entry at or below it and the weights
/// of that entry and the next, as Mitsuba's table lookups compute them. `None` outside
/// [`CIE_MIN`, `CIE_MAX`].
fn table_position(w: f64) -> Option<(usize, f64, f64)> {
    if !(CIE_MIN..=CIE_MAX).contains(&w) {
        return None;
    }
    let t = (w - CIE_MIN) * ((CIE_SAMPLES - 1) as f64 / (CIE_MAX - CIE_MIN));
    let i0 = (t as usize).min(CIE_SAMPLES - 2);
    let w1 = t - i0 as f64;
    Some((i0, 1.0 - w1, w1))
}

/// The CIE 1931 2° colour matching functions (x̄, ȳ, z̄) at wavelength `w` (nm), linearly
/// interpolated from the 5 nm table; zero outside [`CIE_MIN`, `CIE_MAX`]. Mitsuba's
/// `cie1931_xyz`, unnormalised (ȳ peaks at 1 at 555 nm).
pub fn cie1931_xyz(w: f64) -> DVec3 {
    match table_position(w) {
        None => DVec3::ZERO,
        Some((i, w0, w1)) => {
            let lerp = |t: &[f64; CIE_SAMPLES]| w0 * table(t, i) + w1 * table(t, i + 1);
            DVec3::new(lerp(&CIE_X), lerp(&CIE_Y), lerp(&CIE_Z))
        }
    }
}

/// The CIE D65 illuminant at wavelength `w` (nm), linearly interpolated from the 5 nm table and
/// normalised to luminance 1 (about 0.01 at 560 nm); zero outside [`CIE_MIN`, `CIE_MAX`].
/// Mitsuba's `cie_d65`.
pub fn cie_d65(w: f64) -> f64 {
    match table_position(w) {
        None => 0.0,
        Some((i, w0, w1)) => (w0 * D65[i] as f64 + w1 * D65[i + 1] as f64) * D65_NORMALIZATION,
    }
}

/// CIE 1931 XYZ to linear sRGB (ITU-R BT.709 primaries, D65 white), as Mitsuba's
/// `xyz_to_srgb`: its single-precision matrix coefficients, applied in double precision.
pub fn xyz_to_srgb(xyz: DVec3) -> DVec3 {
    const M: [[f32; 3]; 3] = [
        [3.240479, -1.53715, -0.498535],
        [-0.969256, 1.875991, 0.041556],
        [0.055648, -0.204043, 1.057311],
    ];
    let row = |r: [f32; 3]| r[0] as f64 * xyz.x + r[1] as f64 * xyz.y + r[2] as f64 * xyz.z;
    DVec3::new(row(M[0]), row(M[1]), row(M[2]))
}

impl SpectrumValue {
    /// Parses a `<spectrum value="...">` attribute as Mitsuba does: one number is a uniform
    /// spectrum ("0.5"); otherwise entries separated by commas and/or spaces, each
    /// `wavelength:value` ("400:0.1, 500:0.2"). Numbers may have blanks or tabs around them and
    /// a leading `+`; empty entries and repeated `:` are ignored, like Mitsuba's tokenizer does.
    /// A list needs at least two entries with strictly increasing wavelengths, and every number
    /// must be finite. Errors are one-line messages without the file location (the caller adds
    /// it); offending text is quoted, shortened if long.
    pub fn parse(text: &str) -> Result<Self, String> {
        let mut tokens = text.split([',', ' ']).filter(|t| !t.is_empty()).peekable();
        let first = tokens.peek().copied();
        if let Some(first) = first {
            let single = tokens.clone().nth(1).is_none();
            if single && !first.contains(':') {
                let value = parse_whole_number(first).ok_or_else(|| {
                    format!(
                        "could not parse uniform spectrum value \"{}\"",
                        shorten(first)
                    )
                })?;
                if !value.is_finite() {
                    return Err(format!(
                        "uniform spectrum value \"{}\" is not a finite number",
                        shorten(first)
                    ));
                }
                return Ok(SpectrumValue::Uniform(value));
            }
        }
        let mut wavelengths = Vec::new();
        let mut values = Vec::new();
        for token in tokens {
            let mut parts = token.split(':').filter(|p| !p.is_empty());
            let (Some(wl), Some(value), None) = (parts.next(), parts.next(), parts.next()) else {
                return Err(format!(
                    "invalid spectrum entry \"{}\" (expected wavelength:value pairs)",
                    shorten(token)
                ));
            };
            let (Some(wl), Some(value)) = (parse_whole_number(wl), parse_whole_number(value))
            else {
                return Err(format!(
                    "could not parse wavelength:value pair \"{}\"",
                    shorten(token)
                ));
            };
            if !wl.is_finite() || !value.is_finite() {
                return Err(format!(
                    "wavelength:value pair \"{}\" holds a number that is not finite",
                    shorten(token)
                ));
            }
            wavelengths.push(wl);
            values.push(value);
        }
        Self::sampled(wavelengths, values)
    }

    /// Reads the contents of a `.spd` spectrum file as Mitsuba's XML loader does
    /// (`Properties::Spectrum` from a path): one `wavelength value` pair per line, separated by
    /// blanks or tabs, anything after the second number ignored (a third column, a trailing
    /// comment); a line that starts with `#`, or is empty (`\n`, `\r\n`), is skipped; any other
    /// line must start with the two numbers (blanks and tabs before them are fine, but a blank
    /// line made of spaces or an indented `#` is an error, as in Mitsuba). Lines end at `\n`
    /// only. Like Mitsuba's `fgets` with a 1024-byte buffer, a line longer than 1023 bytes is
    /// read as several lines, and a NUL byte ends a line's content. Bytes, not text: comments
    /// need not be UTF-8. Then the rules of [`SpectrumValue::sampled`] apply.
    pub fn from_spd(bytes: &[u8]) -> Result<Self, String> {
        let mut wavelengths = Vec::new();
        let mut values = Vec::new();
        for (index, chunk) in fgets_lines(bytes).enumerate() {
            let line_number = index + 1;
            let line = match chunk.iter().position(|&b| b == 0) {
                Some(nul) => &chunk[..nul],
                None => chunk,
            };
            if matches!(line.first(), Some(b'#' | b'\n' | b'\r')) {
                continue;
            }
            let Some((wl, rest)) = scan_number(line) else {
                return Err(format!(
                    "could not read a wavelength in line {line_number} of the spectrum file \
                     (each line holds a wavelength in nm and a value)"
                ));
            };
            let Some((value, _)) = scan_number(rest) else {
                return Err(format!(
                    "could not read a value after the wavelength in line {line_number} of the \
                     spectrum file (each line holds a wavelength in nm and a value)"
                ));
            };
            if !wl.is_finite() || !value.is_finite() {
                return Err(format!(
                    "line {line_number} of the spectrum file holds a number that is not finite"
                ));
            }
            wavelengths.push(wl);
            values.push(value);
        }
        Self::sampled(wavelengths, values)
    }

    /// A list spectrum from wavelengths (nm) and values, checked as Mitsuba checks them: equal
    /// lengths, at least two entries, strictly increasing wavelengths (and, penumbra's own rule,
    /// finite numbers).
    pub fn sampled(wavelengths: Vec<f64>, values: Vec<f64>) -> Result<Self, String> {
        check_list(&wavelengths, &values)?;
        Ok(SpectrumValue::Sampled {
            wavelengths,
            values,
        })
    }

    /// The linear sRGB triple Mitsuba's RGB variants store for this spectrum when a plugin reads
    /// it in `role`, and a warning when Mitsuba would clamp it (an out-of-gamut list, the same
    /// condition on which Mitsuba logs "Spectrum: clamping out-of-gamut color"). Each component
    /// is exactly an `f32` value, as Mitsuba's `Color3f`.
    ///
    /// Never panics. A `Sampled` value that breaks the rules of [`SpectrumValue::sampled`]
    /// (built directly, bypassing the checks) gives black and the error as the warning. A result
    /// too large for `f32` (only from numbers beyond about 1e37, where Mitsuba would store inf or
    /// NaN) is replaced by a finite one (±`f32::MAX`, NaN by 0) with a warning.
    pub fn to_rgb(&self, role: ColorRole) -> (DVec3, Option<String>) {
        let (rgb, warning) = match self {
            SpectrumValue::Uniform(v) => match role {
                ColorRole::Emission => (*v * xyz_to_srgb(DVec3::ONE), None),
                ColorRole::Reflectance | ColorRole::Unbounded => (DVec3::splat(*v), None),
            },
            SpectrumValue::Sampled {
                wavelengths,
                values,
            } => {
                if let Err(error) = check_list(wavelengths, values) {
                    return (
                        DVec3::ZERO,
                        Some(format!("invalid spectrum, using black: {error}")),
                    );
                }
                let bounded = role == ColorRole::Reflectance;
                let d65 = role != ColorRole::Emission;
                list_to_srgb(wavelengths, values, bounded, d65)
            }
        };
        store_as_f32(rgb, warning)
    }
}

/// Mitsuba's checks of a wavelength list, and finiteness.
fn check_list(wavelengths: &[f64], values: &[f64]) -> Result<(), String> {
    if wavelengths.len() != values.len() {
        return Err(format!(
            "spectrum has {} wavelengths but {} values",
            wavelengths.len(),
            values.len()
        ));
    }
    if wavelengths.len() < 2 {
        return Err(format!(
            "spectrum must have at least two wavelength:value entries (found {})",
            wavelengths.len()
        ));
    }
    if let Some(i) =
        (0..wavelengths.len()).find(|&i| !wavelengths[i].is_finite() || !values[i].is_finite())
    {
        return Err(format!(
            "spectrum entry {} ({}:{}) is not finite",
            i + 1,
            wavelengths[i],
            values[i]
        ));
    }
    if let Some(i) = (1..wavelengths.len()).find(|&i| wavelengths[i] <= wavelengths[i - 1]) {
        return Err(format!(
            "spectrum wavelengths must be strictly increasing, but entry {} ({} nm) follows {} nm",
            i + 1,
            wavelengths[i],
            wavelengths[i - 1]
        ));
    }
    Ok(())
}

/// Mitsuba's `spectrum_list_to_srgb` for a checked list, in double precision, before the
/// final rounding to `f32`.
fn list_to_srgb(
    wavelengths: &[f64],
    values: &[f64],
    bounded: bool,
    d65: bool,
) -> (DVec3, Option<String>) {
    let n = wavelengths.len();
    let (first, last) = (wavelengths[0], wavelengths[n - 1]);
    let mut xyz = DVec3::ZERO;
    for i in 0..STEPS {
        let w = CIE_MIN + (i as f64 / (STEPS - 1) as f64) * (CIE_MAX - CIE_MIN);
        if w < first || w > last {
            continue;
        }
        // The entry at or below `w` among the first n - 1 (so that entry + 1 exists).
        let index = wavelengths[1..n - 1].partition_point(|&x| x <= w);
        let (w0, w1) = (wavelengths[index], wavelengths[index + 1]);
        let (v0, v1) = (values[index], values[index + 1]);
        let v = ((w - w1) * v0 + (w0 - w) * v1) / (w0 - w1);
        let weight = if d65 { cie_d65(w) } else { 1.0 };
        xyz += cie1931_xyz(w) * v * weight;
    }
    xyz *= (CIE_MAX - CIE_MIN) * CIE_Y_NORMALIZATION / STEPS as f64;
    let rgb = xyz_to_srgb(xyz);

    let out_of_range = |c: f64| c < 0.0 || (bounded && c > 1.0);
    if !rgb.to_array().into_iter().any(out_of_range) {
        return (rgb, None);
    }
    let clamped = if bounded {
        rgb.clamp(DVec3::ZERO, DVec3::ONE)
    } else {
        rgb.max(DVec3::ZERO)
    };
    let range = if bounded { "[0, 1]" } else { "0 and above" };
    let warning = format!(
        "clamping out-of-gamut spectrum: RGB ({}, {}, {}) clamped to {range}",
        rgb.x as f32, rgb.y as f32, rgb.z as f32
    );
    (clamped, Some(warning))
}

/// Rounds to `f32` as Mitsuba's `Color3f` storage does; replaces what `f32` cannot hold.
fn store_as_f32(rgb: DVec3, warning: Option<String>) -> (DVec3, Option<String>) {
    let stored = rgb.to_array().map(|c| c as f32);
    if stored.iter().all(|c| c.is_finite()) {
        return (DVec3::from_array(stored.map(f64::from)), warning);
    }
    let finite = stored.map(|c| match c {
        c if c.is_nan() => 0.0,
        c if c.is_infinite() => f32::MAX.copysign(c) as f64,
        c => c as f64,
    });
    let note = format!(
        "spectrum RGB ({}, {}, {}) does not fit in single precision (Mitsuba would store \
         inf/NaN); using ({}, {}, {})",
        rgb.x, rgb.y, rgb.z, finite[0], finite[1], finite[2]
    );
    let warning = Some(match warning {
        Some(w) => format!("{w}; {note}"),
        None => note,
    });
    (DVec3::from_array(finite), warning)
}

/// Lines as C's `fgets` with a 1024-byte buffer returns them: up to and including `\n`, at most
/// 1023 bytes each.
fn fgets_lines(bytes: &[u8]) -> impl Iterator<Item = &[u8]> {
    const MAX: usize = 1023;
    let mut rest = bytes;
    std::iter::from_fn(move || {
        if rest.is_empty() {
            return None;
        }
        let window = &rest[..rest.len().min(MAX)];
        let len = match window.iter().position(|&b| b == b'\n') {
            Some(newline) => newline + 1,
            None => window.len(),
        };
        let (line, tail) = rest.split_at(len);
        rest = tail;
        Some(line)
    })
}

/// Reads a number at the start of `s` as Mitsuba's `string::parse_float` does: blanks and tabs
/// skipped, one optional `+`, then the longest prefix that is a number in `fast_float`'s syntax
/// (`-`, digits with an optional `.`, an optional exponent that is only taken when digits follow
/// it; or `nan`, `inf`, `infinity` in any case). Returns the number (rounded to nearest, ±inf on
/// overflow) and the rest of `s`, or `None` if no number starts there.
fn scan_number(s: &[u8]) -> Option<(f64, &[u8])> {
    let mut start = 0;
    while matches!(s.get(start), Some(b' ' | b'\t')) {
        start += 1;
    }
    if s.get(start) == Some(&b'+') {
        start += 1;
    }
    let body = &s[start..];
    let mut i = usize::from(body.first() == Some(&b'-'));
    let sign = if i == 1 { -1.0 } else { 1.0 };

    let word = |w: &[u8]| body.len() >= i + w.len() && body[i..i + w.len()].eq_ignore_ascii_case(w);
    if word(b"infinity") {
        return Some((sign * f64::INFINITY, &body[i + 8..]));
    }
    if word(b"inf") {
        return Some((sign * f64::INFINITY, &body[i + 3..]));
    }
    if word(b"nan") {
        return Some((f64::NAN, &body[i + 3..]));
    }

    let digits = |mut j: usize| {
        while body.get(j).is_some_and(u8::is_ascii_digit) {
            j += 1;
        }
        j
    };
    let int_end = digits(i);
    let mut end = int_end;
    let mut digit_count = int_end - i;
    if body.get(end) == Some(&b'.') {
        let frac_end = digits(end + 1);
        digit_count += frac_end - (end + 1);
        end = frac_end;
    }
    if digit_count == 0 {
        return None;
    }
    if matches!(body.get(end), Some(b'e' | b'E')) {
        let mut j = end + 1;
        if matches!(body.get(j), Some(b'+' | b'-')) {
            j += 1;
        }
        let exp_end = digits(j);
        if exp_end > j {
            end = exp_end;
        }
    }
    i = end;
    // The prefix is ASCII in a syntax Rust's parser accepts too; it rounds correctly, as
    // fast_float does.
    let text = std::str::from_utf8(&body[..i]).ok()?;
    let value = text.parse::<f64>().ok()?;
    Some((value, &body[i..]))
}

/// A whole token as a number, as Mitsuba's `string::stof`: [`scan_number`], then only blanks
/// and tabs may follow.
fn parse_whole_number(token: &str) -> Option<f64> {
    let (value, rest) = scan_number(token.as_bytes())?;
    rest.iter()
        .all(|&b| b == b' ' || b == b'\t')
        .then_some(value)
}

/// Text for an error message: at most 40 characters, `…` marking a cut.
fn shorten(text: &str) -> String {
    const MAX: usize = 40;
    match text.char_indices().nth(MAX) {
        Some((cut, _)) => format!("{}…", &text[..cut]),
        None => text.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn repo_path(rel: &str) -> std::path::PathBuf {
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
    }

    fn role_named(name: &str) -> ColorRole {
        match name {
            "reflectance" => ColorRole::Reflectance,
            "unbounded" => ColorRole::Unbounded,
            "emission" => ColorRole::Emission,
            other => panic!("unknown role {other:?} in the Mitsuba data file"),
        }
    }

    /// Every entry of tests/data/mitsuba_spectrum_values.txt (written by
    /// validation/mitsuba/spectrum_values.py from Mitsuba 3.9.1's stored values).
    ///
    /// Tolerance: one `f32` ulp. Mitsuba computes in double precision and rounds once to `f32`;
    /// this module does the same double operations in the same order, so the only possible
    /// difference is an `f32` rounding flipped by a last-bit double difference (a fused
    /// multiply-add where Mitsuba's build has one). In practice every entry matches exactly.
    #[test]
    fn matches_mitsuba_stored_values() {
        let data = std::fs::read_to_string(repo_path("tests/data/mitsuba_spectrum_values.txt"))
            .expect("tests/data/mitsuba_spectrum_values.txt");
        let mut spectrum: Option<(String, SpectrumValue)> = None;
        let mut names = Vec::new();
        let (mut checked, mut exact) = (0, 0);
        let mut failures = Vec::new();
        for line in data.lines() {
            if line.starts_with('#') || line.trim().is_empty() {
                continue;
            }
            let mut words = line.splitn(4, ' ');
            let head = words.next().unwrap();
            if head == "spectrum" {
                let name = words.next().unwrap().to_string();
                let kind = words.next().unwrap();
                let text = words.next().unwrap();
                let value = match kind {
                    "value" => SpectrumValue::parse(text),
                    "file" => SpectrumValue::from_spd(&std::fs::read(repo_path(text)).unwrap()),
                    other => panic!("unknown spectrum kind {other:?}"),
                }
                .unwrap_or_else(|e| panic!("{name}: {e}"));
                names.push(name.clone());
                spectrum = Some((name, value));
                continue;
            }
            let (name, value) = spectrum.as_ref().expect("role line before any spectrum");
            let role = role_named(head);
            let fields: Vec<&str> = line.split(' ').skip(1).collect();
            assert_eq!(fields.len(), 4, "{line}");
            let expected: Vec<f32> = fields[..3].iter().map(|f| f.parse().unwrap()).collect();
            let warned = fields[3] == "1";
            let (rgb, warning) = value.to_rgb(role);
            for (c, (&got, &want)) in rgb.to_array().iter().zip(&expected).enumerate() {
                let got32 = got as f32;
                assert_eq!(got32 as f64, got, "{name} {head}: not an f32 value");
                if got32 == want {
                    exact += 1;
                } else if (got32 - want).abs() > f32::EPSILON * want.abs() {
                    failures.push(format!(
                        "{name} {head} channel {c}: {got32} vs Mitsuba {want}"
                    ));
                }
            }
            if warning.is_some() != warned {
                failures.push(format!(
                    "{name} {head}: warning {warning:?}, Mitsuba warned: {warned}"
                ));
            }
            checked += 1;
        }
        assert!(
            failures.is_empty(),
            "{} mismatches:\n{}",
            failures.len(),
            failures.join("\n")
        );
        for required in [
            "cbox-white",
            "cbox-red",
            "cbox-green",
            "cbox-light-reflectance",
            "cbox-light-radiance",
            "uniform-0.5",
            "out-of-gamut-tilt",
            "narrow-blue",
            "spd-file",
        ] {
            assert!(
                names.iter().any(|n| n == required),
                "data file lacks {required}"
            );
        }
        assert_eq!(
            checked,
            names.len() * 3,
            "every spectrum in all three roles"
        );
        assert!(checked >= 60, "only {checked} entries in the data file");
        assert_eq!(
            exact,
            checked * 3,
            "all channels bit-identical to Mitsuba's"
        );
    }

    #[test]
    fn uniform_spectrum_per_role() {
        let s = SpectrumValue::parse("0.789").unwrap();
        assert_eq!(s, SpectrumValue::Uniform(0.789));
        let v = 0.789f32 as f64;
        assert_eq!(s.to_rgb(ColorRole::Reflectance), (DVec3::splat(v), None));
        assert_eq!(s.to_rgb(ColorRole::Unbounded), (DVec3::splat(v), None));
        // Emission: purple-ish, value times xyz_to_srgb(1, 1, 1) = (1.204794, 0.948291, 0.908916).
        let (e, w) = s.to_rgb(ColorRole::Emission);
        assert!(w.is_none());
        let white = DVec3::new(1.204794, 0.948291, 0.908916) * 0.789;
        assert!((e - white).abs().max_element() < 1e-6, "{e}");
        // Uniform values are not clamped in any role, as Mitsuba's `uniform` texture.
        let s = SpectrumValue::parse("-0.25").unwrap();
        assert_eq!(
            s.to_rgb(ColorRole::Reflectance),
            (DVec3::splat(-0.25), None)
        );
    }

    #[test]
    fn xyz_to_srgb_maps_d65_white_to_grey() {
        // D65's chromaticity (0.3127, 0.3290) at Y = 1 is sRGB's white.
        let xyz = DVec3::new(0.3127 / 0.3290, 1.0, (1.0 - 0.3127 - 0.3290) / 0.3290);
        let rgb = xyz_to_srgb(xyz);
        assert!((rgb - DVec3::ONE).abs().max_element() < 2e-3, "{rgb}");
    }

    #[test]
    fn d65_weighting_makes_a_flat_reflectance_white_and_a_flat_emitter_not() {
        let flat = SpectrumValue::parse("360:1, 830:1").unwrap();
        let (r, _) = flat.to_rgb(ColorRole::Reflectance);
        assert!((r - DVec3::ONE).abs().max_element() < 5e-3, "{r}");
        let (e, _) = flat.to_rgb(ColorRole::Emission);
        assert!(e.x > 1.1 && e.z < 0.95, "{e}");
    }

    #[test]
    fn clamping_depends_on_the_role() {
        let s = SpectrumValue::parse("400:5, 700:-3").unwrap();
        let (r, w) = s.to_rgb(ColorRole::Reflectance);
        assert_eq!(r, DVec3::new(0.0, 1.0, 1.0));
        assert!(w.unwrap().contains("[0, 1]"));
        let (u, w) = s.to_rgb(ColorRole::Unbounded);
        assert_eq!(u.x, 0.0);
        assert!(u.y > 1.1 && u.z > 3.8, "{u}");
        assert!(w.is_some());
        // In gamut: no warning.
        let (_, w) = SpectrumValue::parse("400:0.5, 700:0.5")
            .unwrap()
            .to_rgb(ColorRole::Reflectance);
        assert!(w.is_none());
    }

    #[test]
    fn parses_value_attributes_like_mitsuba() {
        let pairs = |s: &str| match SpectrumValue::parse(s).unwrap() {
            SpectrumValue::Sampled {
                wavelengths,
                values,
            } => wavelengths.into_iter().zip(values).collect::<Vec<_>>(),
            u => panic!("{s:?} parsed as {u:?}"),
        };
        let expected = vec![(400.0, 0.5), (500.0, 0.6)];
        assert_eq!(pairs("400:0.5, 500:0.6"), expected);
        assert_eq!(pairs("400:0.5 500:0.6"), expected);
        assert_eq!(pairs(" 400:0.5,,500:0.6, "), expected);
        assert_eq!(pairs("400::0.5, :500:0.6:"), expected);
        assert_eq!(pairs("+400:+.5, 5e2:0.6"), expected);
        assert_eq!(pairs("400:\t0.5\t, 500:0.6"), expected);
        assert_eq!(
            pairs("400:+-0.5, 500:6E-1"),
            vec![(400.0, -0.5), (500.0, 0.6)]
        );
        assert_eq!(
            SpectrumValue::parse(" 0.5 ").unwrap(),
            SpectrumValue::Uniform(0.5)
        );
        assert_eq!(
            SpectrumValue::parse("0.5,").unwrap(),
            SpectrumValue::Uniform(0.5)
        );
        assert_eq!(
            SpectrumValue::parse("5.").unwrap(),
            SpectrumValue::Uniform(5.0)
        );
        assert_eq!(
            SpectrumValue::parse("1e-400").unwrap(),
            SpectrumValue::Uniform(0.0)
        );
    }

    /// Each malformed value gets its own message (first words checked), never a panic.
    #[test]
    fn value_attribute_errors() {
        let cases = [
            ("", "spectrum must have at least two"),
            (" , ", "spectrum must have at least two"),
            ("400:0.5", "spectrum must have at least two"),
            (
                "500:0.5, 400:0.6",
                "spectrum wavelengths must be strictly increasing",
            ),
            (
                "400:0.5, 400:0.6",
                "spectrum wavelengths must be strictly increasing",
            ),
            ("abc", "could not parse uniform spectrum value \"abc\""),
            ("++5", "could not parse uniform spectrum value"),
            ("1e", "could not parse uniform spectrum value"),
            ("0x10", "could not parse uniform spectrum value"),
            // Mitsuba's stof reads a tab-only token as 0; penumbra refuses it (see module docs).
            ("\t", "could not parse uniform spectrum value"),
            (
                "nan",
                "uniform spectrum value \"nan\" is not a finite number",
            ),
            (
                "-inf",
                "uniform spectrum value \"-inf\" is not a finite number",
            ),
            (
                "1e400",
                "uniform spectrum value \"1e400\" is not a finite number",
            ),
            ("0.5 0.6", "invalid spectrum entry \"0.5\""),
            ("400 : 0.5, 500:0.6", "invalid spectrum entry \"400\""),
            ("400:0.5:7, 500:1", "invalid spectrum entry \"400:0.5:7\""),
            (
                "400:x, 500:1",
                "could not parse wavelength:value pair \"400:x\"",
            ),
            (
                "400:0.5, 500:1;",
                "could not parse wavelength:value pair \"500:1;\"",
            ),
            (
                "400:nan, 500:1",
                "wavelength:value pair \"400:nan\" holds a number that is not finite",
            ),
            (
                "inf:1, 500:1",
                "wavelength:value pair \"inf:1\" holds a number that is not finite",
            ),
            (
                "400:1e309, 500:1",
                "wavelength:value pair \"400:1e309\" holds",
            ),
        ];
        for (text, message) in cases {
            match SpectrumValue::parse(text) {
                Err(e) => assert!(
                    e.starts_with(message),
                    "{text:?}: {e:?}, expected {message:?}"
                ),
                Ok(v) => panic!("{text:?} parsed as {v:?}"),
            }
        }
        // A hostile token is quoted shortened, not whole.
        let long = format!("400:{}, 500:1", "9".repeat(100_000) + "x");
        let e = SpectrumValue::parse(&long).unwrap_err();
        assert!(e.len() < 120 && e.contains('…'), "{e}");
    }

    #[test]
    fn reads_spd_files_like_mitsuba() {
        let expected = SpectrumValue::sampled(vec![400.0, 500.0], vec![0.5, 0.6]).unwrap();
        let ok = [
            "400 0.5\n500 0.6\n",
            "400 0.5\n500 0.6",
            "# header\n\n400 0.5\r\n\r\n#x\n500 0.6\r\n",
            "  400\t0.5\n\t500  0.6\n",
            "400 0.5 9\n500 0.6 # trailing comment\n",
            "+400 +0.5\n500 0.6#c\n",
            "400 0.5\0 junk\n500 0.6\n",
        ];
        for text in ok {
            assert_eq!(
                SpectrumValue::from_spd(text.as_bytes()),
                Ok(expected.clone()),
                "{text:?}"
            );
        }
        // Comments need not be UTF-8 (Latin-1 "°").
        let latin1 = b"# 20 \xb0C\n400 0.5\n500 0.6\n";
        assert_eq!(SpectrumValue::from_spd(latin1), Ok(expected.clone()));
        // A line is cut after 1023 bytes, as fgets does: the rest is read as a new line. A
        // 1024-byte line leaves just "\n" (skipped), one byte more leaves " \n" (an error).
        let long = format!("400 0.5{}\n500 0.6\n", " ".repeat(1016));
        assert_eq!(
            SpectrumValue::from_spd(long.as_bytes()),
            Ok(expected.clone())
        );
        let longer = format!("400 0.5{}\n500 0.6\n", " ".repeat(1017));
        let e = SpectrumValue::from_spd(longer.as_bytes()).unwrap_err();
        assert!(
            e.starts_with("could not read a wavelength in line 2"),
            "{e}"
        );
        let split = format!("400 0.5{}7 8\n500 0.6\n", " ".repeat(1016));
        let e = SpectrumValue::from_spd(split.as_bytes()).unwrap_err();
        assert!(e.contains("strictly increasing"), "{e}");
    }

    /// A spectrum file that is not one (a `filename` naming any file the user can read) is
    /// refused without any of its contents in the message, which may be shown or logged.
    #[test]
    fn spd_errors_never_quote_the_file() {
        for bytes in [
            b"root:secret-hash:19000:0:99999:7:::\n".as_slice(),
            b"400 secret\n500 0.6\n",
            b"400 0.5\n500 nan-secret\n",
            b"400 inf\nsecret\n",
        ] {
            let e = SpectrumValue::from_spd(bytes).unwrap_err();
            assert!(!e.contains("secret") && !e.contains("root"), "{e}");
        }
    }

    #[test]
    fn spd_errors() {
        let cases: [(&[u8], &str); 10] = [
            (b"", "spectrum must have at least two"),
            (b"# only a comment\n", "spectrum must have at least two"),
            (b"400 0.5\n", "spectrum must have at least two"),
            (
                b"400 0.5\n  # indented\n500 0.6\n",
                "could not read a wavelength in line 2",
            ),
            (
                b"400 0.5\n   \n500 0.6\n",
                "could not read a wavelength in line 2",
            ),
            (
                b"400,0.5\n500,0.6\n",
                "could not read a value after the wavelength in line 1",
            ),
            (
                b"400\n500 0.6\n",
                "could not read a value after the wavelength in line 1",
            ),
            (
                b"400 0.5\n500 nan\n",
                "line 2 of the spectrum file holds a number that is not",
            ),
            (
                b"500 0.5\n400 0.6\n",
                "spectrum wavelengths must be strictly increasing",
            ),
            (b"400 0.5\r500 0.6\r", "spectrum must have at least two"),
        ];
        for (bytes, message) in cases {
            match SpectrumValue::from_spd(bytes) {
                Err(e) => assert!(e.starts_with(message), "{bytes:?}: {e:?}"),
                Ok(v) => panic!("{bytes:?} read as {v:?}"),
            }
        }
    }

    #[test]
    fn invalid_lists_built_directly_give_black_and_a_message() {
        let cases = [
            (
                vec![400.0, 500.0],
                vec![1.0],
                "spectrum has 2 wavelengths but 1 values",
            ),
            (vec![], vec![], "spectrum must have at least two"),
            (
                vec![500.0, 400.0],
                vec![1.0, 1.0],
                "spectrum wavelengths must be strictly",
            ),
            (
                vec![400.0, f64::NAN],
                vec![1.0, 1.0],
                "spectrum entry 2 (NaN:1) is not finite",
            ),
        ];
        for (wavelengths, values, message) in cases {
            assert!(SpectrumValue::sampled(wavelengths.clone(), values.clone())
                .unwrap_err()
                .starts_with(message));
            let s = SpectrumValue::Sampled {
                wavelengths,
                values,
            };
            for role in [
                ColorRole::Reflectance,
                ColorRole::Unbounded,
                ColorRole::Emission,
            ] {
                let (rgb, warning) = s.to_rgb(role);
                assert_eq!(rgb, DVec3::ZERO);
                assert!(warning.unwrap().contains(message));
            }
        }
    }

    #[test]
    fn hostile_values_stay_finite_and_fast() {
        let roles = [
            ColorRole::Reflectance,
            ColorRole::Unbounded,
            ColorRole::Emission,
        ];
        for text in [
            "1e308",
            "-1e308",
            "400:1e308, 500:-1e308",
            "-1e308:1e308, 1e308:1e308",
            "400:1e38, 700:1e38",
            "400:1e-308, 401:5e-324",
            "829.9999999999999:1, 830:1",
        ] {
            let s = SpectrumValue::parse(text).unwrap();
            for role in roles {
                let (rgb, _) = s.to_rgb(role);
                assert!(rgb.is_finite(), "{text} {role:?}: {rgb}");
            }
        }
        let (rgb, w) = SpectrumValue::parse("1e308")
            .unwrap()
            .to_rgb(ColorRole::Emission);
        assert_eq!(rgb, DVec3::splat(f32::MAX as f64));
        assert!(w.unwrap().contains("does not fit in single precision"));
        let (_, w) = SpectrumValue::Uniform(f64::NAN).to_rgb(ColorRole::Reflectance);
        assert!(w.is_some());

        // 200 000 entries: parsed and converted without trouble.
        let big: String = (0..200_000)
            .map(|i| format!("{}:{}", 300.0 + i as f64 * 0.003, (i % 7) as f64 / 7.0))
            .collect::<Vec<_>>()
            .join(",");
        let s = SpectrumValue::parse(&big).unwrap();
        let (rgb, _) = s.to_rgb(ColorRole::Reflectance);
        assert!(rgb.is_finite());
        let spd = big.replace(',', "\n").replace(':', " ");
        assert_eq!(SpectrumValue::from_spd(spd.as_bytes()).unwrap(), s);
    }

    #[test]
    fn scan_number_follows_fast_float_prefix_rules() {
        let scan = |s: &str| scan_number(s.as_bytes()).map(|(v, rest)| (v, rest.len()));
        assert_eq!(scan(" \t+1.5e3xyz"), Some((1500.0, 3)));
        assert_eq!(scan("1e+"), Some((1.0, 2)));
        assert_eq!(scan("-.25"), Some((-0.25, 0)));
        assert_eq!(scan("."), None);
        assert_eq!(scan("-"), None);
        assert_eq!(scan("+-2"), Some((-2.0, 0)));
        assert_eq!(scan("++2"), None);
        assert_eq!(scan("\n1"), None);
        assert_eq!(scan("INFINITY"), Some((f64::INFINITY, 0)));
        assert!(scan("nan").unwrap().0.is_nan());
    }
}
