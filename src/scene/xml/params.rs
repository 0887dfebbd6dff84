//! `$name` parameters: the command-line overrides and the `<default>`s, and their
//! substitution into attribute values (Mitsuba's `substitute_parameters`).

use super::elem::{shorten, Elem};
use super::{Loader, SUBSTITUTION_BUDGET};
use crate::error::Result;
use std::borrow::Cow;
use std::cmp::Reverse;
use std::collections::{BTreeMap, HashSet};

/// A `$name` parameter: a command-line override or a `<default>`.
pub(super) struct Parameter {
    /// The name, without the `$`.
    pub(super) name: String,
    pub(super) value: String,
    /// Whether it replaced something (only overrides are checked).
    pub(super) used: bool,
    /// Whether it came from the command line.
    pub(super) is_override: bool,
}

/// The `$name` parameters in Mitsuba's order: longest name first (so that `$ab` is not read
/// as `$a` followed by `b` when both exist), names of one length in the order they came.
#[derive(Default)]
pub(super) struct Parameters {
    by_length: BTreeMap<Reverse<usize>, Vec<Parameter>>,
    names: HashSet<String>,
}

impl Parameters {
    fn contains(&self, name: &str) -> bool {
        self.names.contains(name)
    }

    /// Adds a parameter, or (for a name already there) replaces its value.
    pub(super) fn set(&mut self, param: Parameter) {
        let bucket = self.by_length.entry(Reverse(param.name.len())).or_default();
        if !self.names.insert(param.name.clone()) {
            if let Some(p) = bucket.iter_mut().find(|p| p.name == param.name) {
                p.value = param.value;
            }
            return;
        }
        bucket.push(param);
    }

    fn iter(&self) -> impl Iterator<Item = &Parameter> {
        self.by_length.values().flatten()
    }

    fn iter_mut(&mut self) -> impl Iterator<Item = &mut Parameter> {
        self.by_length.values_mut().flatten()
    }
}

impl Loader {
    /// Mitsuba's `substitute_parameters`: for each parameter, longest name first, every
    /// `$name` in the value that is not preceded by `\` is replaced (anywhere: `$ab` with only
    /// `a` defined is the value of `a` followed by `b`); text a replacement brings in is seen
    /// by the parameters after it. Then any `$` left that is not escaped is an undefined
    /// parameter, and `\$` becomes `$`. Only values that contain a `$` are touched.
    pub(super) fn substitute<'v>(
        &mut self,
        value: &'v str,
    ) -> std::result::Result<Cow<'v, str>, String> {
        if !value.contains('$') {
            return Ok(Cow::Borrowed(value));
        }
        let mut text = value.to_string();
        for param in self.params.iter_mut() {
            let key = format!("${}", param.name);
            let mut pos = 0;
            loop {
                let found = text.get(pos..).and_then(|rest| rest.find(&key));
                // The bytes this search looked at.
                let scanned = found.map_or(text.len().saturating_sub(pos), |f| f + key.len());
                self.substitution_work =
                    self.substitution_work.checked_sub(scanned).ok_or_else(|| {
                        "$-substitution scans too much text (too many parameters and long values)"
                            .to_string()
                    })?;
                let Some(found) = found else {
                    break;
                };
                let at = pos + found;
                if at > 0 && text.as_bytes().get(at - 1) == Some(&b'\\') {
                    pos = at + key.len();
                    continue;
                }
                text.replace_range(at..at + key.len(), &param.value);
                param.used = true;
                pos = at + param.value.len();
                if text.len() > self.substitution_budget {
                    return Err(format!(
                        "$-substitution produces more than {} MiB of text",
                        SUBSTITUTION_BUDGET >> 20
                    ));
                }
            }
        }
        let bytes = text.as_bytes();
        for (i, &b) in bytes.iter().enumerate() {
            if b == b'$' && !(i > 0 && bytes.get(i - 1) == Some(&b'\\')) {
                let rest = text.get(i + 1..).unwrap_or_default();
                let len = rest
                    .bytes()
                    .take_while(|b| b.is_ascii_alphanumeric() || *b == b'_')
                    .count();
                let name = rest.get(..len).unwrap_or_default();
                return Err(format!("undefined parameter \"${name}\""));
            }
        }
        let text = text.replace("\\$", "$");
        self.substitution_budget = self.substitution_budget.saturating_sub(text.len());
        Ok(Cow::Owned(text))
    }

    /// Warns about parameters given on the command line that the scene never uses (Mitsuba
    /// refuses them by default; see the module documentation).
    pub(super) fn warn_unused_overrides(&mut self) {
        let unused: Vec<String> = self
            .params
            .iter()
            .filter(|p| p.is_override && !p.used)
            .map(|p| format!("${}={}", p.name, shorten(&p.value)))
            .collect();
        if !unused.is_empty() {
            self.warnings.push(format!(
                "unused parameters (no $name in the scene uses them; Mitsuba would refuse them): {}",
                unused.join(", ")
            ));
        }
    }

    /// Parses `<default name=".." value=".."/>`: a new `$name` (any non-empty name), unless
    /// an override or an earlier default has that name.
    pub(super) fn parse_default(&mut self, elem: &Elem) -> Result<()> {
        elem.check_attrs(&["name", "value"])?;
        let name = elem.require("name")?;
        let value = elem.require("value")?;
        if name.is_empty() {
            return Err(elem.error(format!("{}: the name must be non-empty", elem.desc)));
        }
        if self.params.contains(name) {
            return Ok(());
        }
        // After the names at least as long, as Mitsuba inserts it.
        self.params.set(Parameter {
            name: name.to_string(),
            value: value.to_string(),
            used: false,
            is_override: false,
        });
        Ok(())
    }
}
