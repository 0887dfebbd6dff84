//! Typed property elements: `<integer>`, `<float>`, `<boolean>`, `<string>`, `<rgb>`,
//! `<point>` and `<vector>` ([`parse_value`]), and `<spectrum>` (a value or a `.spd` file).

use super::elem::{shorten, shown, Elem};
use super::values::parse_integer;
use super::{Loader, Value};
use crate::error::Result;
use glam::DVec3;
use std::path::Path;

impl Loader {
    /// Parses `<spectrum name=".." value=".."/>` or `filename=".."` (exactly one of the two;
    /// the file is looked up with the resolver as it stands, as in Mitsuba).
    pub(super) fn parse_spectrum(&self, elem: &Elem) -> Result<Value> {
        use crate::spectrum::SpectrumValue;
        let value = elem.get("value").filter(|v| !v.is_empty());
        let filename = elem.get("filename").filter(|v| !v.is_empty());
        let spectrum = match (value, filename) {
            (Some(v), None) => SpectrumValue::parse(v),
            (None, Some(f)) => {
                let path = self.resolver.resolve(Path::new(f));
                let bytes = crate::io::read_file_limited(&path, crate::io::MAX_SCENE_FILE_BYTES)
                    .map_err(|e| {
                        elem.error(format!(
                            "cannot read spectrum file \"{}\": {e}",
                            shown(&path)
                        ))
                    })?;
                SpectrumValue::from_spd(&bytes)
            }
            _ => {
                return Err(elem.error(format!(
                    "{} needs either a \"value\" or a \"filename\" attribute (but not both)",
                    elem.desc
                )))
            }
        };
        spectrum
            .map(Value::Spectrum)
            .map_err(|m| elem.error(format!("{m} in {}", elem.desc)))
    }
}

/// Parses the value of a simple property element (everything but `<transform>` and
/// `<spectrum>`).
pub(super) fn parse_value(elem: &Elem) -> Result<Value> {
    match elem.tag.as_str() {
        "point" | "vector" => {
            let parts = elem.xyz_attrs()?;
            let mut allowed = vec!["name", "x", "y", "z"];
            if elem.get("value").is_some() {
                allowed.push("value");
            }
            elem.check_attrs(&allowed)?;
            elem.require("name")?;
            // After `value` is expanded, Mitsuba requires all three components.
            for (part, key) in parts.iter().zip(["x", "y", "z"]) {
                if part.is_none() {
                    return Err(elem.error(format!("missing attribute \"{key}\" in {}", elem.desc)));
                }
            }
            let v = elem.xyz(&parts, 0.0)?;
            Ok(if elem.tag == "point" {
                Value::Point(v)
            } else {
                Value::Vector(v)
            })
        }
        tag => {
            elem.check_attrs(&["name", "value"])?;
            elem.require("name")?;
            let text = elem.require("value")?;
            match tag {
                "integer" => parse_integer(text).map(Value::Integer).ok_or_else(|| {
                    elem.error(format!(
                        "could not parse integer value \"{}\" in {}",
                        shorten(text),
                        elem.desc
                    ))
                }),
                "float" => Ok(Value::Float(elem.float(text)?)),
                "boolean" => {
                    if text.eq_ignore_ascii_case("true") {
                        Ok(Value::Boolean(true))
                    } else if text.eq_ignore_ascii_case("false") {
                        Ok(Value::Boolean(false))
                    } else {
                        Err(elem.error(format!(
                            "could not parse boolean value \"{}\" in {}: must be \"true\" or \"false\"",
                            shorten(text),
                            elem.desc
                        )))
                    }
                }
                "rgb" => {
                    let numbers = elem.numbers(text)?;
                    match numbers.as_slice() {
                        [v] => Ok(Value::Rgb(DVec3::splat(*v))),
                        [r, g, b] => Ok(Value::Rgb(DVec3::new(*r, *g, *b))),
                        _ => Err(elem.error(format!(
                            "<rgb> requires one or three values, found {} in {}",
                            numbers.len(),
                            elem.desc
                        ))),
                    }
                }
                _ => Ok(Value::String(text.to_string())),
            }
        }
    }
}
