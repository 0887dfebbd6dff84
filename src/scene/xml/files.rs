//! The files of a scene: a source file's text and the locations in it, the `version` of its
//! root, `<path>`, and `<include>`: the include chain, its limits and the roots of included
//! files.

use super::elem::{scene_error, shorten, shown, Elem};
use super::markup::{self, Element, Markup};
use super::objects::{check_scene_type, Body, Entry};
use super::resolve::{FileScope, RawChild};
use super::values::parse_version;
use super::{Loader, MAX_INCLUDED_FILES, MAX_INCLUDE_DEPTH, MAX_PARSED_BYTES, OBJECT_TAGS};
use crate::error::{Error, Location, Result};
use std::cell::Cell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// One file of the include chain.
pub(super) struct IncludeFrame {
    /// The canonical path when it exists, to recognise the same file under other names.
    pub(super) key: PathBuf,
    /// The path as written, for messages.
    pub(super) shown: PathBuf,
}

/// One XML file being parsed.
pub(super) struct SourceFile<'t> {
    /// The path as given, used in locations.
    path: PathBuf,
    /// The directory relative `<include>`s are resolved against.
    pub(super) dir: PathBuf,
    /// The file's text (UTF-8 but for what the XML reader skips).
    text: &'t [u8],
    /// Whether the file declares a version before 2.0.0 and gets Mitsuba's in-memory upgrade.
    pub(super) upgrade: bool,
    /// The last position mapped to a location, as `(byte offset, line, column)`: elements are
    /// visited in document order, so mapping continues from there in linear total time.
    cursor: Cell<(usize, u32, u32)>,
}

impl<'t> SourceFile<'t> {
    pub(super) fn new(path: &Path, text: &'t [u8]) -> Self {
        SourceFile {
            path: path.to_path_buf(),
            dir: path.parent().map(Path::to_path_buf).unwrap_or_default(),
            text,
            upgrade: false,
            cursor: Cell::new((0, 1, 1)),
        }
    }

    /// The location of byte offset `pos`: 1-based lines, and 1-based columns counted in
    /// characters.
    pub(super) fn location(&self, pos: usize) -> Location {
        let bytes = self.text;
        let pos = pos.min(bytes.len());
        let (cursor_pos, cursor_line, cursor_col) = self.cursor.get();
        let (start, mut line, mut col) = if pos >= cursor_pos {
            (cursor_pos, cursor_line, cursor_col)
        } else {
            (0, 1, 1)
        };
        for &b in bytes.get(start..pos).unwrap_or_default() {
            if b == b'\n' {
                line = line.saturating_add(1);
                col = 1;
            } else if b & 0xC0 != 0x80 {
                // Count characters, not UTF-8 continuation bytes.
                col = col.saturating_add(1);
            }
        }
        self.cursor.set((pos, line, col));
        Location {
            file: self.path.clone(),
            line,
            col,
        }
    }

    /// The location of an element's start.
    pub(super) fn node_location(&self, node: Element) -> Location {
        self.location(node.start())
    }
}

/// Parses `file`'s text as XML.
pub(super) fn parse_document<'t>(file: &SourceFile<'t>) -> Result<Markup<'t>> {
    markup::parse(file.text).map_err(|e| {
        let location = file.location(e.offset);
        Error::Xml {
            path: file.path.clone(),
            message: format!("{} (at {}:{})", e.message, location.line, location.col),
        }
    })
}

/// The canonical form of a path for cycle detection (the path itself if it does not exist).
pub(super) fn include_key(path: &Path) -> PathBuf {
    std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf())
}

/// The raw (not `$`-substituted) value of an element's first attribute `name`, as Mitsuba
/// reads the `version` of a file's root.
fn raw_attribute(file: &SourceFile, node: Element, name: &str) -> Result<Option<String>> {
    match node.attributes().find(|a| a.name() == name) {
        Some(attr) => attr.value().map(|v| Some(v.into_owned())).map_err(|e| {
            scene_error(
                &file.location(e.offset),
                format!("{} in <{}>", e.message, node.name()),
            )
        }),
        None => Ok(None),
    }
}

impl Loader {
    /// Reads a file root's `version` (required, not substituted) and notes whether the file
    /// gets the pre-2.0 upgrade.
    pub(super) fn read_version(&self, file: &mut SourceFile, root: Element) -> Result<()> {
        let location = file.node_location(root);
        let Some(version) = raw_attribute(file, root, "version")? else {
            return Err(scene_error(
                &location,
                format!(
                    "missing attribute \"version\" in root element <{}>",
                    root.name()
                ),
            ));
        };
        let parsed = parse_version(&version).ok_or_else(|| {
            scene_error(
                &location,
                format!(
                    "invalid version number \"{}\" in root element <{}> (expected major.minor.patch)",
                    shorten(&version),
                    root.name()
                ),
            )
        })?;
        file.upgrade = parsed < (2, 0, 0);
        Ok(())
    }

    /// Parses `<path value=".."/>`, allowed only directly inside a file's root element: the
    /// folder (relative to this file's directory, else looked up with the resolver) is
    /// searched first from now on. Inside an included file it lasts until the end of that
    /// file, as in Mitsuba.
    pub(super) fn parse_path(
        &mut self,
        file: &SourceFile,
        elem: &Elem,
        parent_desc: &str,
        depth: usize,
    ) -> Result<()> {
        elem.check_attrs(&["value"])?;
        let value = Path::new(elem.require("value")?);
        if depth != self.file_root_depth {
            return Err(elem.error(format!(
                "{} can only appear directly inside the root element (found in {parent_desc})",
                elem.desc
            )));
        }
        let mut dir = if value.is_absolute() {
            value.to_path_buf()
        } else {
            file.dir.join(value)
        };
        if !dir.exists() {
            let found = self.resolver.resolve(value);
            if found.exists() {
                dir = found;
            }
        }
        if !dir.exists() {
            return Err(elem.error(format!(
                "{}: folder \"{}\" not found",
                elem.desc,
                shown(&dir)
            )));
        }
        self.resolver.prepend(dir);
        Ok(())
    }

    /// Parses `<include filename=".." name=".."/>`: a file whose root is `<scene>` (or an
    /// object without a `type`, which Mitsuba takes for a scene) contributes its nested
    /// objects to `body`; a file whose root is another object contributes that object, named
    /// `name`.
    pub(super) fn parse_include(
        &mut self,
        file: &SourceFile,
        elem: &Elem,
        parent_desc: &str,
        body: &mut Body,
        depth: usize,
    ) -> Result<()> {
        elem.check_attrs(&["filename", "name"])?;
        let filename = elem.require("filename")?;
        // Mitsuba looks the file up with the resolver, this file's directory first; whatever
        // the included file adds to the resolver is dropped after it.
        let saved_resolver = self.resolver.clone();
        if !file.dir.as_os_str().is_empty() {
            self.resolver.prepend(file.dir.clone());
        }
        let path = self.resolver.resolve(Path::new(filename));
        let result = self.include_file(elem, parent_desc, body, depth, path);
        self.resolver = saved_resolver;
        result
    }

    /// Parses the included file at `path` (see [`Loader::parse_include`]).
    fn include_file(
        &mut self,
        elem: &Elem,
        parent_desc: &str,
        body: &mut Body,
        depth: usize,
        path: PathBuf,
    ) -> Result<()> {
        if filename_is_missing(&path) {
            return Err(elem.error(format!(
                "{}: included file \"{}\" not found",
                elem.desc,
                shown(&path)
            )));
        }
        if self.include_stack.len() >= MAX_INCLUDE_DEPTH {
            return Err(elem.error(format!(
                "{} exceeds the include depth limit of {MAX_INCLUDE_DEPTH} files (Mitsuba's)",
                elem.desc
            )));
        }
        let key = include_key(&path);
        if self.include_stack.iter().any(|frame| frame.key == key) {
            let chain: Vec<String> = self
                .include_stack
                .iter()
                .map(|frame| shown(&frame.shown))
                .chain(std::iter::once(shown(&path)))
                .collect();
            return Err(elem.error(format!("cyclic include: {}", chain.join(" -> "))));
        }
        if self.included_files >= MAX_INCLUDED_FILES {
            return Err(elem.error(format!(
                "{}: more than {MAX_INCLUDED_FILES} included files parsed for one scene (a \
                 file counts each time it is included)",
                elem.desc
            )));
        }
        self.included_files += 1;
        let bytes =
            crate::io::read_file_limited(&path, crate::io::MAX_SCENE_FILE_BYTES).map_err(|e| {
                elem.error(format!(
                    "cannot read included file \"{}\": {e}",
                    shown(&path)
                ))
            })?;
        self.parsed_bytes += bytes.len() as u64;
        if self.parsed_bytes > MAX_PARSED_BYTES {
            return Err(elem.error(format!(
                "{}: more than {MAX_PARSED_BYTES} bytes of XML parsed for one scene (the \
                 scene file and its included files, each time it is included)",
                elem.desc
            )));
        }
        let text = markup::to_utf8(&bytes);
        let mut included = SourceFile::new(&path, &text);
        let doc = parse_document(&included)?;
        self.include_stack.push(IncludeFrame { key, shown: path });
        self.scopes.push(FileScope {
            first_id: self.id_count,
            root_ids: HashMap::new(),
        });
        let result = self.parse_included(&mut included, doc.root(), elem, parent_desc, body, depth);
        self.scopes.pop();
        self.include_stack.pop();
        result
    }

    /// Adds the root of an included file to `body` (see [`Loader::parse_include`]).
    fn parse_included(
        &mut self,
        included: &mut SourceFile,
        root: Element,
        include: &Elem,
        parent_desc: &str,
        body: &mut Body,
        depth: usize,
    ) -> Result<()> {
        self.read_version(included, root)?;
        let root_elem = self.element(included, root)?;
        let tag = root_elem.tag.as_str();
        let is_object = OBJECT_TAGS.contains(&tag)
            || tag == "scene"
            || (tag == "spectrum" && root_elem.get("type").is_some());
        if !is_object {
            // Mitsuba reads such a root as usual: its `version` is an unexpected attribute.
            return self.parse_child(included, root, parent_desc, body, depth);
        }
        root_elem.check_attrs(&["version", "type", "id", "name"])?;
        if tag == "scene" {
            check_scene_type(&root_elem)?;
        }
        let saved_root_depth = self.file_root_depth;
        let result = if root_elem.get("type").is_none() {
            // A scene: its nested objects join `body`; its id lives while it is parsed.
            if let Some(id) = root_elem.get("id").filter(|id| !id.is_empty()) {
                if let Some(scope) = self.scopes.last_mut() {
                    scope
                        .root_ids
                        .insert(id.to_string(), root_elem.location.clone());
                }
            }
            self.file_root_depth = depth;
            self.splice_scene(included, &root_elem, body, depth)
        } else {
            self.file_root_depth = depth + 1;
            self.parse_object(included, &root_elem, include.child_name(), depth)
                .map(|child| self.add_object(body, child, include, parent_desc))
        };
        self.file_root_depth = saved_root_depth;
        result
    }

    /// Parses the children of an included `<scene>` root and adds its nested objects to
    /// `body`. Its properties and references are parsed (so their errors are reported) but
    /// dropped: Mitsuba 3.9.1 merges only the objects of an included scene into the
    /// including element.
    fn splice_scene(
        &mut self,
        included: &SourceFile,
        root: &Elem,
        body: &mut Body,
        depth: usize,
    ) -> Result<()> {
        let mut own = Body::default();
        self.parse_children(included, root.node, &root.desc, &mut own, depth)?;
        for entry in own.entries {
            match entry {
                Entry::Child(child @ RawChild::Object { .. }) => {
                    let name = match &child {
                        RawChild::Object { name, .. } | RawChild::Ref { name, .. } => name.clone(),
                    };
                    if body.add_object(Entry::Child(child)) {
                        self.warnings.push(format!(
                            "{}: an object of the included file replaces the earlier entry named \"{}\" (as in Mitsuba, the last object of a name wins)",
                            root.location,
                            name.unwrap_or_default()
                        ));
                    }
                }
                Entry::Child(RawChild::Ref { location, desc, .. }) => {
                    self.warnings.push(format!(
                        "{location}: {desc} directly inside an included <scene> is ignored, as Mitsuba ignores it"
                    ));
                }
                Entry::Property(p) => {
                    self.warnings.push(format!(
                        "{}: property \"{}\" directly inside an included <scene> is ignored, as Mitsuba ignores it",
                        p.location, p.name
                    ));
                }
            }
        }
        Ok(())
    }
}

/// Whether an included file does not exist (Mitsuba checks before reading it).
fn filename_is_missing(path: &Path) -> bool {
    !path.exists()
}
