//! Elements and messages: an element with its attributes `$`-substituted ([`Elem`]) and
//! the typed reading of its attributes, and the helpers that keep error messages short, on
//! one line and naming the element.

use super::files::SourceFile;
use super::markup::Element;
use super::values::{parse_float, tokenize};
use super::Loader;
use crate::error::{Error, Location, Result};
use glam::DVec3;
use std::borrow::Cow;
use std::path::Path;

/// An element with its attributes `$`-substituted.
pub(super) struct Elem<'m, 't> {
    pub(super) node: Element<'m, 't>,
    pub(super) tag: String,
    /// The attributes in document order; a name may repeat (the first one counts).
    attrs: Vec<(String, String)>,
    pub(super) location: Location,
    /// `<tag type=".." id=".." name="..">`, for messages.
    pub(super) desc: String,
}

impl Elem<'_, '_> {
    /// The value of attribute `name`, if present.
    pub(super) fn get(&self, name: &str) -> Option<&str> {
        self.attrs
            .iter()
            .find(|(key, _)| key == name)
            .map(|(_, value)| value.as_str())
    }

    /// An error located at this element.
    pub(super) fn error(&self, message: impl Into<String>) -> Error {
        scene_error(&self.location, message)
    }

    /// Rejects attributes other than `allowed`.
    pub(super) fn check_attrs(&self, allowed: &[&str]) -> Result<()> {
        match self
            .attrs
            .iter()
            .find(|(key, _)| !allowed.contains(&key.as_str()))
        {
            Some((key, _)) => Err(self.error(format!(
                "unexpected attribute \"{key}\" in {} (allowed: {})",
                self.desc,
                allowed.join(", ")
            ))),
            None => Ok(()),
        }
    }

    /// The value of attribute `name`, which must be present.
    pub(super) fn require(&self, name: &str) -> Result<&str> {
        self.get(name)
            .ok_or_else(|| self.error(format!("missing attribute \"{name}\" in {}", self.desc)))
    }

    /// The `name` of a property, which must be present (it may be empty, as in Mitsuba).
    pub(super) fn property_name(&self) -> Result<String> {
        Ok(self.require("name")?.to_string())
    }

    /// The `name` of a nested object, reference or include: an empty one is no name.
    pub(super) fn child_name(&self) -> Option<String> {
        self.get("name")
            .filter(|name| !name.is_empty())
            .map(str::to_string)
    }

    /// Parses attribute `name` as a finite float.
    pub(super) fn float_attr(&self, name: &str) -> Result<f64> {
        self.float(self.require(name)?)
    }

    /// Parses a finite float with Mitsuba's syntax.
    pub(super) fn float(&self, text: &str) -> Result<f64> {
        match parse_float(text) {
            // penumbra renders in f32: a value beyond its range would become infinite there.
            Some(v) if v.is_finite() && v.abs() <= f32::MAX as f64 => Ok(v),
            Some(v) if v.is_finite() => Err(self.error(format!(
                "floating point value \"{}\" in {} exceeds the single-precision range (3.4e38) that penumbra renders in",
                shorten(text),
                self.desc
            ))),
            Some(_) => Err(self.error(format!(
                "non-finite floating point value \"{}\" in {} (penumbra refuses infinities and NaNs)",
                shorten(text),
                self.desc
            ))),
            None => Err(self.error(format!(
                "could not parse floating point value \"{}\" in {}",
                shorten(text),
                self.desc
            ))),
        }
    }

    /// Mitsuba's `expand_value_to_xyz`: a `value` of one or three numbers stands for `x`,
    /// `y` and `z`; returns the three components as written (`None` where absent).
    pub(super) fn xyz_attrs(&self) -> Result<[Option<String>; 3]> {
        if let Some(value) = self.get("value") {
            if ["x", "y", "z"].iter().any(|k| self.get(k).is_some()) {
                return Err(self.error(format!(
                    "cannot mix \"value\" and \"x\"/\"y\"/\"z\" attributes in {}",
                    self.desc
                )));
            }
            let tokens: Vec<&str> = tokenize(value).collect();
            return match tokens.as_slice() {
                [v] => Ok([
                    Some(v.to_string()),
                    Some(v.to_string()),
                    Some(v.to_string()),
                ]),
                [x, y, z] => Ok([
                    Some(x.to_string()),
                    Some(y.to_string()),
                    Some(z.to_string()),
                ]),
                _ => Err(self.error(format!(
                    "the \"value\" attribute must have exactly 1 or 3 elements, found {} in {}",
                    tokens.len(),
                    self.desc
                ))),
            };
        }
        Ok(["x", "y", "z"].map(|k| self.get(k).map(str::to_string)))
    }

    /// Parses the components of [`Elem::xyz_attrs`], each defaulting to `default` when absent
    /// (a present but empty one is 0, as Mitsuba reads it).
    pub(super) fn xyz(&self, parts: &[Option<String>; 3], default: f64) -> Result<DVec3> {
        let mut v = [default; 3];
        for (slot, part) in v.iter_mut().zip(parts) {
            if let Some(text) = part {
                *slot = self.float(text)?;
            }
        }
        Ok(DVec3::from_array(v))
    }

    /// Parses a list of finite floats separated by spaces and/or commas.
    pub(super) fn numbers(&self, text: &str) -> Result<Vec<f64>> {
        tokenize(text).map(|token| self.float(token)).collect()
    }

    /// Parses attribute text as exactly three numbers (for `<lookat>`).
    pub(super) fn vec3(&self, name: &str, text: &str) -> Result<DVec3> {
        let numbers = self.numbers(text)?;
        match numbers.as_slice() {
            [x, y, z] => Ok(DVec3::new(*x, *y, *z)),
            _ => Err(self.error(format!(
                "attribute \"{name}\" must have exactly 3 components, found {} in {}",
                numbers.len(),
                self.desc
            ))),
        }
    }
}

/// Cuts long attribute values down for messages, with [`one_line`].
pub(super) fn shorten(text: &str) -> Cow<'_, str> {
    const MAX: usize = 60;
    match text.char_indices().nth(MAX) {
        Some((cut, _)) => Cow::Owned(format!(
            "{}...",
            one_line(text.get(..cut).unwrap_or_default())
        )),
        None => one_line(text),
    }
}

/// Escapes control characters (a value may hold a line break written `&#10;`), so that a
/// message stays one line.
fn one_line(text: &str) -> Cow<'_, str> {
    if !text.chars().any(char::is_control) {
        return Cow::Borrowed(text);
    }
    Cow::Owned(
        text.chars()
            .map(|c| {
                if c.is_control() {
                    c.escape_default().to_string()
                } else {
                    c.to_string()
                }
            })
            .collect(),
    )
}

/// [`Error::scene`] with the message on one line (it may quote values or other modules'
/// messages).
pub(super) fn scene_error(location: &Location, message: impl Into<String>) -> Error {
    let message = message.into();
    Error::scene(location, one_line(&message))
}

/// A path for a message, on one line.
pub(super) fn shown(path: &Path) -> String {
    one_line(&path.display().to_string()).into_owned()
}

/// `<tag type=".." id=".." name=".." filename="..">`: the element as messages name it.
fn describe<'s>(tag: &str, attrs: impl Iterator<Item = (&'s str, &'s str)> + Clone) -> String {
    let mut desc = format!("<{tag}");
    for key in ["type", "id", "name", "filename"] {
        if let Some((_, value)) = attrs.clone().find(|(k, _)| *k == key) {
            desc.push_str(&format!(" {key}=\"{}\"", shorten(value)));
        }
    }
    desc.push('>');
    desc
}

/// [`describe`] of an element as written (values not substituted).
pub(super) fn describe_node(node: Element) -> String {
    let attrs: Vec<(&str, String)> = node
        .attributes()
        .map(|a| (a.name(), a.value().map(Cow::into_owned).unwrap_or_default()))
        .collect();
    describe(node.name(), attrs.iter().map(|(k, v)| (*k, v.as_str())))
}

impl Loader {
    /// Reads an element: its tag and `$`-substituted attributes.
    pub(super) fn element<'m, 't>(
        &mut self,
        file: &SourceFile,
        node: Element<'m, 't>,
    ) -> Result<Elem<'m, 't>> {
        let location = file.node_location(node);
        let tag = node.name();
        let mut attrs = Vec::new();
        for attr in node.attributes() {
            let name = attr.name();
            let raw = attr.value().map_err(|e| {
                let at = file.location(e.offset);
                scene_error(
                    &at,
                    format!(
                        "{} (attribute \"{name}\" of <{tag}>, at line {}, column {})",
                        e.message, at.line, at.col
                    ),
                )
            })?;
            let value = self.substitute(&raw).map_err(|message| {
                let raw_desc = describe_node(node);
                scene_error(
                    &location,
                    format!("{message} in attribute \"{name}\" of {raw_desc}"),
                )
            })?;
            attrs.push((name.to_string(), value.into_owned()));
        }
        let desc = describe(tag, attrs.iter().map(|(k, v)| (k.as_str(), v.as_str())));
        Ok(Elem {
            node,
            tag: tag.to_string(),
            attrs,
            location,
            desc,
        })
    }
}
