//! Ids and references: the objects as parsed (before their references are resolved), the
//! ids declared and those each file being parsed sees, `<ref>` and `<alias>`, and, once the
//! whole scene is parsed, the resolution of every reference into the [`Arc<Object>`] of the
//! object it names.

use super::elem::{scene_error, Elem};
use super::{Child, Loader, Object, Property, MAX_REFERENCE_DEPTH};
use crate::error::{Location, Result};
use std::collections::HashMap;
use std::sync::Arc;

/// What a file being parsed sees of the ids: in Mitsuba each included file is parsed into a
/// state of its own, merged into the including file's afterwards.
pub(super) struct FileScope {
    /// The first id declaration of this file (`IdDecl::order`): an `<alias>` can only name
    /// ids declared from there on (in this file or the files it included).
    pub(super) first_id: usize,
    /// The ids of an included `<scene>` root and its aliases: they exist while the file is
    /// parsed and are dropped with its root, as in Mitsuba.
    pub(super) root_ids: HashMap<String, Location>,
}

/// An object as parsed, before its references are resolved.
pub(super) struct RawObject {
    pub(super) tag: String,
    pub(super) plugin: String,
    pub(super) id: Option<String>,
    pub(super) properties: Vec<Property>,
    pub(super) children: Vec<RawChild>,
    pub(super) location: Location,
    /// `<tag type=".." id="..">`, for messages.
    pub(super) desc: String,
}

/// A child as parsed: a nested object (an index into the loader's arena) or a reference.
pub(super) enum RawChild {
    Object {
        name: Option<String>,
        index: usize,
    },
    Ref {
        name: Option<String>,
        id: String,
        location: Location,
        desc: String,
    },
}

/// What a declared id names.
#[derive(Clone, Copy)]
pub(super) enum IdTarget {
    Object(usize),
    /// The main file's `<scene>` root (a reference to it is a cycle).
    Root,
}

pub(super) struct IdDecl {
    target: IdTarget,
    location: Location,
    /// The order of declaration (see [`FileScope::first_id`]).
    order: usize,
}

/// How far the resolution of an arena object has got.
#[derive(Clone, Copy, PartialEq, Eq)]
enum ResolveState {
    Todo,
    /// Being resolved: reaching it again means a reference cycle.
    InProgress,
}

impl Loader {
    /// Whether `id` is taken: declared anywhere, or the root id of a file being parsed.
    fn id_taken(&self, id: &str) -> Option<Location> {
        if let Some(decl) = self.ids.get(id) {
            return Some(decl.location.clone());
        }
        self.scopes
            .iter()
            .find_map(|scope| scope.root_ids.get(id).cloned())
    }

    /// Declares a new id at `elem`.
    pub(super) fn declare_id(&mut self, elem: &Elem, id: &str, target: IdTarget) -> Result<()> {
        if let Some(previous) = self.id_taken(id) {
            return Err(elem.error(format!(
                "{} has duplicate id \"{id}\" (first declared at {previous})",
                elem.desc
            )));
        }
        self.ids.insert(
            id.to_string(),
            IdDecl {
                target,
                location: elem.location.clone(),
                order: self.id_count,
            },
        );
        self.id_count += 1;
        Ok(())
    }

    /// The arena index of the object named `id`, for a reference described by `desc` at
    /// `location`.
    fn lookup(&self, id: &str, location: &Location, desc: &str) -> Result<usize> {
        match self.ids.get(id) {
            Some(IdDecl {
                target: IdTarget::Object(index),
                ..
            }) => Ok(*index),
            Some(IdDecl {
                target: IdTarget::Root,
                ..
            }) => Err(scene_error(
                location,
                format!("{desc} refers to the scene root, which contains it: cyclic reference"),
            )),
            None => Err(scene_error(
                location,
                format!("{desc} refers to unknown id \"{id}\""),
            )),
        }
    }

    /// Resolves every reference below the scene root, once the whole scene is parsed.
    pub(super) fn resolve_root(&self, raw: RawObject) -> Result<Object> {
        let mut done: Vec<Option<Arc<Object>>> = vec![None; self.arena.len()];
        let mut state = vec![ResolveState::Todo; self.arena.len()];
        let children = raw
            .children
            .iter()
            .map(|c| self.resolve_child(c, &mut done, &mut state, 1))
            .collect::<Result<Vec<_>>>()?;
        Ok(Object {
            tag: raw.tag,
            plugin: raw.plugin,
            id: raw.id,
            properties: raw.properties,
            children,
            location: raw.location,
        })
    }

    fn resolve_child(
        &self,
        child: &RawChild,
        done: &mut Vec<Option<Arc<Object>>>,
        state: &mut Vec<ResolveState>,
        depth: usize,
    ) -> Result<Child> {
        let (name, index) = match child {
            RawChild::Object { name, index } => (name, *index),
            RawChild::Ref {
                name,
                id,
                location,
                desc,
            } => {
                let index = self.lookup(id, location, desc)?;
                if state[index] == ResolveState::InProgress {
                    return Err(scene_error(
                        location,
                        format!(
                            "{desc} refers to {} at {}, which contains it: cyclic reference",
                            self.arena[index].desc, self.arena[index].location
                        ),
                    ));
                }
                if depth > MAX_REFERENCE_DEPTH {
                    return Err(scene_error(
                        location,
                        format!(
                            "{desc}: references and nested objects chain more than {MAX_REFERENCE_DEPTH} levels deep"
                        ),
                    ));
                }
                (name, index)
            }
        };
        let object = self.resolve_object(index, done, state, depth)?;
        Ok(Child {
            name: name.clone(),
            object,
        })
    }

    fn resolve_object(
        &self,
        index: usize,
        done: &mut Vec<Option<Arc<Object>>>,
        state: &mut Vec<ResolveState>,
        depth: usize,
    ) -> Result<Arc<Object>> {
        if let Some(object) = &done[index] {
            return Ok(Arc::clone(object));
        }
        state[index] = ResolveState::InProgress;
        let raw = &self.arena[index];
        let children = raw
            .children
            .iter()
            .map(|c| self.resolve_child(c, done, state, depth + 1))
            .collect::<Result<Vec<_>>>()?;
        let object = Arc::new(Object {
            tag: raw.tag.clone(),
            plugin: raw.plugin.clone(),
            id: raw.id.clone(),
            properties: raw.properties.clone(),
            children,
            location: raw.location.clone(),
        });
        state[index] = ResolveState::Todo;
        done[index] = Some(Arc::clone(&object));
        Ok(object)
    }

    /// Parses `<ref id=".." name=".."/>` (resolved after parsing; attributes checked).
    pub(super) fn parse_ref(&mut self, elem: &Elem) -> Result<RawChild> {
        let id = elem.require("id")?;
        Ok(RawChild::Ref {
            name: elem.child_name(),
            id: id.to_string(),
            location: elem.location.clone(),
            desc: elem.desc.clone(),
        })
    }

    /// Parses `<alias id="existing" as="new"/>`: `new` becomes another id of the object
    /// `existing` names, which must be declared already, in this file or in a file it
    /// included (Mitsuba parses each included file on its own); `new` must be free.
    pub(super) fn parse_alias(&mut self, elem: &Elem) -> Result<()> {
        elem.check_attrs(&["id", "as"])?;
        let source = elem.require("id")?;
        let new_id = elem.require("as")?;
        if let Some(previous) = self.id_taken(new_id) {
            return Err(elem.error(format!(
                "{}: alias destination id \"{new_id}\" already exists (declared at {previous})",
                elem.desc
            )));
        }
        let Some(scope) = self.scopes.last_mut() else {
            return Ok(());
        };
        if scope.root_ids.contains_key(source) {
            // An alias of an included <scene> root is dropped with it.
            scope
                .root_ids
                .insert(new_id.to_string(), elem.location.clone());
            return Ok(());
        }
        let first_id = scope.first_id;
        match self.ids.get(source) {
            Some(decl) if decl.order >= first_id => {
                let target = decl.target;
                self.declare_id(elem, new_id, target)
            }
            _ => Err(elem.error(format!(
                "{}: alias source id \"{source}\" not found (an alias can only name an id declared before it, in the same file or a file it included)",
                elem.desc
            ))),
        }
    }
}
