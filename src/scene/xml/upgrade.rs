//! Mitsuba 3.9.1's in-memory upgrade of scene files older than version 2.0.0
//! (`transform_upgrade` and `upgrade_from_v1` in `src/core/parser.cpp`).
//!
//! The version is per file: every object is upgraded when the file its element is in
//! declares a version below 2.0.0, the scene root by the main file's version. The upgrade
//! works on the names of an object's entries (properties and named children, whatever file
//! the children came from), after the whole object is parsed:
//!
//! 1. every name becomes [`camel_to_underscore`] of itself, unless that name is already taken
//!    in the object (then the entry keeps its name);
//! 2. in an object whose plugin is `diffuse`, `diffuse_reflectance` becomes `reflectance`
//!    (unless taken);
//! 3. `uoffset`, `voffset`, `uscale` and `vscale` (numbers) are removed and replaced by a
//!    `to_uv` transform, scale(uscale, vscale, 1) · translate(uoffset, voffset, 0); an object
//!    that already has `to_uv` is an error.
//!
//! Ids, tags (`<lookAt>` stays unknown) and `<default>` names are left alone.

use super::objects::{Body, Entry};
use super::{Property, Value};
use crate::error::{Error, Location, Result};
use glam::{DMat4, DVec3};

/// Mitsuba's `camel_to_underscore_case`: a capital letter that follows a lowercase letter
/// becomes `_` and its lowercase, and so do the capitals right after it (`fooBAR` →
/// `foo_bar`, `aBCdEf` → `a_bcd_ef`); other characters are kept (`x2Y`, `ABc` and `a_B` do not
/// change: a digit, a capital or `_` before the capital).
pub(super) fn camel_to_underscore(name: &str) -> String {
    let bytes = name.as_bytes();
    let mut out = Vec::with_capacity(bytes.len() + 4);
    let mut i = 0;
    while let Some(&c) = bytes.get(i) {
        let after_lower = i > 0 && bytes.get(i - 1).is_some_and(u8::is_ascii_lowercase);
        if after_lower && c.is_ascii_uppercase() {
            out.push(b'_');
            out.push(c.to_ascii_lowercase());
            while let Some(&next) = bytes.get(i + 1) {
                if !next.is_ascii_uppercase() {
                    break;
                }
                out.push(next.to_ascii_lowercase());
                i += 1;
            }
        } else {
            out.push(c);
        }
        i += 1;
    }
    // Only ASCII bytes were added or changed, so this is still UTF-8.
    String::from_utf8(out).unwrap_or_else(|_| name.to_string())
}

/// The `uoffset`/`voffset`/`uscale`/`vscale` properties, in the order Mitsuba reads them.
const UV_NAMES: [&str; 4] = ["uoffset", "voffset", "uscale", "vscale"];

impl Body {
    /// Applies the upgrade to the entries of an object whose plugin is `plugin`, located at
    /// `location`.
    pub(super) fn upgrade_from_v1(&mut self, plugin: &str, location: &Location) -> Result<()> {
        for i in 0..self.entries.len() {
            let Some(name) = self.entries.get(i).and_then(Entry::name) else {
                continue;
            };
            let new_name = camel_to_underscore(name);
            if new_name != name {
                self.rename(i, new_name);
            }
        }
        if plugin == "diffuse" {
            if let Some(&i) = self.names.get("diffuse_reflectance") {
                self.rename(i, "reflectance".to_string());
            }
        }
        let mut uv = [0.0, 0.0, 1.0, 1.0];
        let mut found = None;
        for (slot, key) in uv.iter_mut().zip(UV_NAMES) {
            let Some(&i) = self.names.get(key) else {
                continue;
            };
            let entry = self.entries.get(i);
            let (value, at) = match entry {
                Some(Entry::Property(Property {
                    value: Value::Float(v),
                    location,
                    ..
                })) => (*v, location.clone()),
                Some(Entry::Property(Property {
                    value: Value::Integer(v),
                    location,
                    ..
                })) => (*v as f64, location.clone()),
                other => {
                    let (got, at) = match other {
                        Some(Entry::Property(p)) => (p.value.type_name(), &p.location),
                        _ => ("object", location),
                    };
                    return Err(Error::scene(
                        at,
                        format!(
                            "the property \"{key}\" has the wrong type (expected float, got {got}) for the upgrade of a file older than version 2.0.0 to \"to_uv\""
                        ),
                    ));
                }
            };
            *slot = value;
            found.get_or_insert(at);
            self.remove(i);
        }
        if let Some(at) = found {
            if self.names.contains_key("to_uv") {
                return Err(Error::scene(
                    &at,
                    "property \"to_uv\" was specified multiple times (the upgrade of a file older than version 2.0.0 turns uoffset/voffset/uscale/vscale into \"to_uv\")",
                ));
            }
            let [uoffset, voffset, uscale, vscale] = uv;
            let to_uv = DMat4::from_scale(DVec3::new(uscale, vscale, 1.0))
                * DMat4::from_translation(DVec3::new(uoffset, voffset, 0.0));
            self.push(Entry::Property(Property {
                name: "to_uv".to_string(),
                value: Value::Transform(to_uv),
                location: at,
            }));
        }
        Ok(())
    }
}
