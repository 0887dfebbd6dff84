//! Objects in document order: the `<scene>` root of the main file, each element inside an
//! object (dispatched by its tag), the entries of an object under construction (properties
//! and children, with Mitsuba's rules for names), and nested objects parsed into the
//! loader's arena.

use super::elem::{describe_node, scene_error, shorten, Elem};
use super::files::SourceFile;
use super::markup::Element;
use super::property::parse_value;
use super::resolve::{IdTarget, RawChild, RawObject};
use super::{Loader, Property, MAX_NESTING_DEPTH, OBJECT_TAGS, TRANSFORM_OPS};
use crate::error::Result;
use std::collections::HashMap;

/// An entry of an object: a property or a child, in document order (Mitsuba keeps both in
/// one `Properties` list, where a child may replace a property of the same name).
pub(super) enum Entry {
    Property(Property),
    Child(RawChild),
}

impl Entry {
    pub(super) fn name(&self) -> Option<&str> {
        match self {
            Entry::Property(p) => Some(&p.name),
            Entry::Child(RawChild::Object { name, .. } | RawChild::Ref { name, .. }) => {
                name.as_deref()
            }
        }
    }

    fn set_name(&mut self, new_name: String) {
        match self {
            Entry::Property(p) => p.name = new_name,
            Entry::Child(RawChild::Object { name, .. } | RawChild::Ref { name, .. }) => {
                *name = Some(new_name)
            }
        }
    }
}

/// The properties and children of an object under construction.
#[derive(Default)]
pub(super) struct Body {
    pub(super) entries: Vec<Entry>,
    /// The entry of each name used so far.
    pub(super) names: HashMap<String, usize>,
}

impl Body {
    pub(super) fn push(&mut self, entry: Entry) {
        if let Some(name) = entry.name() {
            self.names.insert(name.to_string(), self.entries.len());
        }
        self.entries.push(entry);
    }

    /// Adds a property or a named reference: its name must be new, as Mitsuba's
    /// `Properties::set` requires.
    fn add_unique(&mut self, entry: Entry, elem: &Elem, parent_desc: &str) -> Result<()> {
        if let Some(name) = entry.name() {
            if let Some(&i) = self.names.get(name) {
                let previous = match self.entries.get(i) {
                    Some(Entry::Property(p)) => p.location.to_string(),
                    _ => "an earlier element".to_string(),
                };
                return Err(elem.error(format!(
                    "duplicate name \"{name}\" in {parent_desc}: {} repeats the name used at {previous}",
                    elem.desc
                )));
            }
        }
        self.push(entry);
        Ok(())
    }

    /// Adds a nested object: one whose name is already used replaces that entry, where it is
    /// (Mitsuba's `Properties::set(name, .., false)`); returns whether it replaced one.
    pub(super) fn add_object(&mut self, entry: Entry) -> bool {
        if let Some(&i) = entry.name().and_then(|name| self.names.get(name)) {
            if let Some(slot) = self.entries.get_mut(i) {
                *slot = entry;
                return true;
            }
        }
        self.push(entry);
        false
    }

    /// Renames entry `i`, unless the new name is taken (then nothing changes).
    pub(super) fn rename(&mut self, i: usize, new_name: String) {
        if self.names.contains_key(&new_name) {
            return;
        }
        let Some(entry) = self.entries.get_mut(i) else {
            return;
        };
        if let Some(old) = entry.name() {
            self.names.remove(old);
        }
        self.names.insert(new_name.clone(), i);
        entry.set_name(new_name);
    }

    /// Removes entry `i`.
    pub(super) fn remove(&mut self, i: usize) {
        if i < self.entries.len() {
            self.entries.remove(i);
            self.names = self
                .entries
                .iter()
                .enumerate()
                .filter_map(|(j, e)| e.name().map(|n| (n.to_string(), j)))
                .collect();
        }
    }

    /// The properties and the children, each in document order.
    fn split(self) -> (Vec<Property>, Vec<RawChild>) {
        let mut properties = Vec::new();
        let mut children = Vec::new();
        for entry in self.entries {
            match entry {
                Entry::Property(p) => properties.push(p),
                Entry::Child(c) => children.push(c),
            }
        }
        (properties, children)
    }
}

impl Loader {
    /// Loads the `<scene>` root of the main file (references not yet resolved).
    pub(super) fn load_root(&mut self, file: &mut SourceFile, root: Element) -> Result<RawObject> {
        self.read_version(file, root)?;
        let elem = self.element(file, root)?;
        if elem.tag != "scene" {
            return Err(elem.error(format!(
                "the root element must be <scene>, found {}",
                elem.desc
            )));
        }
        elem.check_attrs(&["version", "type", "id", "name"])?;
        check_scene_type(&elem)?;
        if let Some(id) = elem.get("id").filter(|id| !id.is_empty()) {
            self.declare_id(&elem, id, IdTarget::Root)?;
        }
        let mut body = Body::default();
        self.parse_children(file, root, "<scene>", &mut body, 1)?;
        if file.upgrade {
            body.upgrade_from_v1("scene", &elem.location)?;
        }
        let (properties, children) = body.split();
        Ok(RawObject {
            tag: "scene".to_string(),
            plugin: String::new(),
            id: None,
            properties,
            children,
            location: elem.location,
            desc: "<scene>".to_string(),
        })
    }

    /// Parses the child elements of `parent` into `body` (text and every other node is
    /// ignored, as in Mitsuba). `depth` is the nesting depth of the children.
    pub(super) fn parse_children(
        &mut self,
        file: &SourceFile,
        parent: Element,
        parent_desc: &str,
        body: &mut Body,
        depth: usize,
    ) -> Result<()> {
        for child in parent.children() {
            self.parse_child(file, child, parent_desc, body, depth)?;
        }
        Ok(())
    }

    /// Parses one element inside an object (or inside `<scene>`) into `body`.
    pub(super) fn parse_child(
        &mut self,
        file: &SourceFile,
        node: Element,
        parent_desc: &str,
        body: &mut Body,
        depth: usize,
    ) -> Result<()> {
        if depth > MAX_NESTING_DEPTH {
            return Err(scene_error(
                &file.node_location(node),
                format!("elements are nested more than {MAX_NESTING_DEPTH} levels deep"),
            ));
        }
        let elem = self.element(file, node)?;
        let tag = elem.tag.as_str();
        if OBJECT_TAGS.contains(&tag) || (tag == "spectrum" && elem.get("type").is_some()) {
            // `<spectrum type="...">` is a spectrum plugin (an object), as in Mitsuba.
            elem.check_attrs(&["type", "id", "name"])?;
            let child = self.parse_object(file, &elem, elem.child_name(), depth)?;
            self.add_object(body, child, &elem, parent_desc);
            return Ok(());
        }
        match tag {
            "ref" => {
                elem.check_attrs(&["id", "name"])?;
                let child = self.parse_ref(&elem)?;
                ensure_leaf(file, &elem)?;
                body.add_unique(Entry::Child(child), &elem, parent_desc)
            }
            "alias" => {
                self.parse_alias(&elem)?;
                ensure_leaf(file, &elem)
            }
            "default" => {
                self.parse_default(&elem)?;
                ensure_leaf(file, &elem)
            }
            "include" => {
                self.parse_include(file, &elem, parent_desc, body, depth)?;
                ensure_leaf(file, &elem)
            }
            "path" => {
                self.parse_path(file, &elem, parent_desc, depth)?;
                ensure_leaf(file, &elem)
            }
            "spectrum" => {
                elem.check_attrs(&["name", "value", "filename"])?;
                let property = Property {
                    name: elem.property_name()?,
                    value: self.parse_spectrum(&elem)?,
                    location: elem.location.clone(),
                };
                body.add_unique(Entry::Property(property), &elem, parent_desc)?;
                ensure_leaf(file, &elem)
            }
            "integer" | "float" | "boolean" | "string" | "rgb" | "point" | "vector" => {
                let property = Property {
                    value: parse_value(&elem)?,
                    name: elem.property_name()?,
                    location: elem.location.clone(),
                };
                body.add_unique(Entry::Property(property), &elem, parent_desc)?;
                ensure_leaf(file, &elem)
            }
            "transform" => {
                let property = self.parse_transform(file, &elem)?;
                body.add_unique(Entry::Property(property), &elem, parent_desc)
            }
            "scene" => Err(elem.error(format!(
                "{} can only be the root element (found in {parent_desc})",
                elem.desc
            ))),
            _ if TRANSFORM_OPS.contains(&tag) => Err(elem.error(format!(
                "transform operation {} outside of a <transform> (in {parent_desc})",
                elem.desc
            ))),
            _ => {
                let kind = if elem.get("type").is_some() {
                    "object "
                } else if elem.get("name").is_some() {
                    "property "
                } else {
                    ""
                };
                Err(elem.error(format!("unknown {kind}tag {} in {parent_desc}", elem.desc)))
            }
        }
    }

    /// Adds a nested object to `body`, warning when it replaces an entry of the same name.
    pub(super) fn add_object(
        &mut self,
        body: &mut Body,
        child: RawChild,
        elem: &Elem,
        parent_desc: &str,
    ) {
        let name = match &child {
            RawChild::Object { name, .. } | RawChild::Ref { name, .. } => name.clone(),
        };
        if body.add_object(Entry::Child(child)) {
            self.warnings.push(format!(
                "{}: {} replaces the earlier entry named \"{}\" in {parent_desc} (as in Mitsuba, the last object of a name wins)",
                elem.location,
                elem.desc,
                name.unwrap_or_default()
            ));
        }
    }

    /// Parses `<shape type=".." id=".." name="..">...</shape>` and friends into the arena
    /// (attributes already checked). `name` is the name it gets in its parent.
    pub(super) fn parse_object(
        &mut self,
        file: &SourceFile,
        elem: &Elem,
        name: Option<String>,
        depth: usize,
    ) -> Result<RawChild> {
        let plugin = elem.require("type")?;
        if plugin.is_empty() {
            return Err(elem.error(format!("empty \"type\" attribute in {}", elem.desc)));
        }
        // The slot is reserved first, so that the id names it while the children are parsed.
        let index = self.arena.len();
        let id = match elem.get("id").filter(|id| !id.is_empty()) {
            Some(id) => {
                self.declare_id(elem, id, IdTarget::Object(index))?;
                Some(id.to_string())
            }
            None => None,
        };
        self.arena.push(RawObject {
            tag: String::new(),
            plugin: String::new(),
            id: None,
            properties: Vec::new(),
            children: Vec::new(),
            location: elem.location.clone(),
            desc: String::new(),
        });
        let mut body = Body::default();
        self.parse_children(file, elem.node, &elem.desc, &mut body, depth + 1)?;
        if file.upgrade {
            body.upgrade_from_v1(plugin, &elem.location)?;
        }
        let (properties, children) = body.split();
        self.arena[index] = RawObject {
            tag: elem.tag.clone(),
            plugin: plugin.to_string(),
            id,
            properties,
            children,
            location: elem.location.clone(),
            desc: elem.desc.clone(),
        };
        Ok(RawChild::Object { name, index })
    }
}

/// A `<scene>`'s `type` may only be `scene` (Mitsuba takes any other as the plugin that
/// makes the scene, and has none).
pub(super) fn check_scene_type(elem: &Elem) -> Result<()> {
    match elem.get("type") {
        None | Some("scene") => Ok(()),
        Some(other) => Err(elem.error(format!(
            "{}: unknown scene plugin \"{}\" (only \"scene\" is known)",
            elem.desc,
            shorten(other)
        ))),
    }
}

/// Rejects child elements inside an element that takes none (other nodes are ignored).
fn ensure_leaf(file: &SourceFile, elem: &Elem) -> Result<()> {
    match elem.node.children().next() {
        Some(child) => {
            let desc = describe_node(child);
            Err(scene_error(
                &file.node_location(child),
                format!("{desc} cannot appear inside {}", elem.desc),
            ))
        }
        None => Ok(()),
    }
}
