//! Mitsuba 3 XML scene files, parsed into a generic object tree.
//!
//! This module reads the XML syntax of a Mitsuba 3 scene and resolves everything that is
//! independent of the plugins themselves:
//!
//! - `<path value="..."/>` and `<include filename="..."/>`, with Mitsuba's file resolver
//!   ([`FileResolver`]: the including file's directory first, then the `<path>`s, the scene's
//!   directory and the working directory; include cycles rejected),
//! - `<default name="..." value="..."/>` and `$name` substitution in every attribute value,
//!   with command-line overrides taking precedence over the file's defaults,
//! - `<ref id="..."/>` (and `<alias id="..." as="..."/>`), resolved after the whole scene is
//!   parsed, as Mitsuba does: a reference may name an object declared later in the file or in
//!   a later include, and every reference to an id yields the very same [`Arc<Object>`];
//!   reference cycles are rejected,
//! - `<transform>` blocks, composed exactly like Mitsuba does (each operation `M` is applied
//!   after the previous ones: `T = M * T`),
//! - typed properties (`integer`, `float`, `boolean`, `string`, `rgb`, `point`, `vector`,
//!   `transform`), parsed into [`Value`]s.
//!
//! It knows nothing about specific plugins: a later stage turns the [`Object`] tree into typed
//! scene objects and rejects unknown plugins and parameters.
//!
//! Every [`Object`] and [`Property`] carries the [`Location`] of its element, and every error
//! about an element names its tag, its `type` (if any) and its location. The parser is meant
//! to face hostile input: it never panics, bounds its recursion, and rejects deeply nested
//! documents before building them.

use super::resolver::FileResolver;
use crate::error::{Error, Location, Result};
use glam::{DMat3, DMat4, DVec3};
use roxmltree::{Node, NodeType};
use std::borrow::Cow;
use std::cell::Cell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Tags that declare a plugin object (`<shape type="...">` and so on).
/// (`<spectrum>` is a property, or an object when it has a `type`.)
const OBJECT_TAGS: &[&str] = &[
    "integrator",
    "sensor",
    "film",
    "rfilter",
    "sampler",
    "bsdf",
    "shape",
    "emitter",
    "texture",
    "medium",
    "phase",
    "volume",
];

/// Tags that may only appear inside a `<transform>`.
const TRANSFORM_OPS: &[&str] = &["translate", "rotate", "scale", "matrix", "lookat"];

/// Maximum nesting depth of elements below `<scene>`, counted across included files.
const MAX_NESTING_DEPTH: usize = 64;

/// Maximum length of a chain of `<include>`s.
const MAX_INCLUDE_DEPTH: usize = 32;

/// Maximum XML element depth of one file, checked by a cheap scan before the document is
/// built, so that absurdly deep input is rejected without building it.
const MAX_XML_DEPTH: usize = 128;

/// Maximum number of attributes of one element, checked by the same scan (the XML parser's
/// duplicate-attribute check is quadratic in it).
const MAX_XML_ATTRIBUTES: usize = 256;

/// Longest chain of objects reached through `<ref>`s while resolving one object (nested
/// objects count too): bounds the resolver's recursion on hostile input.
const MAX_REFERENCE_DEPTH: usize = 512;

/// Total number of bytes that `$name` substitution may produce while loading one scene; this
/// stops defaults that expand into each other from blowing up exponentially.
const SUBSTITUTION_BUDGET: usize = 64 << 20;

/// The value of a property.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// `<integer name=".." value="3"/>`
    Integer(i64),
    /// `<float name=".." value="0.5"/>` (always finite)
    Float(f64),
    /// `<boolean name=".." value="true"/>`
    Boolean(bool),
    /// `<string name=".." value=".."/>`
    String(String),
    /// `<rgb name=".." value="r g b"/>` (or a single value for grey)
    Rgb(DVec3),
    /// `<point name=".." x=".." y=".." z=".."/>` or `value="x y z"`
    Point(DVec3),
    /// `<vector name=".." x=".." y=".." z=".."/>` or `value="x y z"`
    Vector(DVec3),
    /// `<transform name="..">` with its operations composed into one matrix.
    Transform(DMat4),
    /// `<spectrum name=".." value=".."/>` (one number, or wavelength:value pairs) or
    /// `filename=".."` (a `.spd` file, read when the scene is parsed); turned into RGB by the
    /// plugin that reads it ([`crate::spectrum::SpectrumValue::to_rgb`]).
    Spectrum(crate::spectrum::SpectrumValue),
}

impl Value {
    /// The XML tag of this kind of value: `"integer"`, `"float"`, `"boolean"`, `"string"`,
    /// `"rgb"`, `"point"`, `"vector"`, `"transform"` or `"spectrum"`.
    pub fn type_name(&self) -> &'static str {
        match self {
            Value::Integer(_) => "integer",
            Value::Float(_) => "float",
            Value::Boolean(_) => "boolean",
            Value::String(_) => "string",
            Value::Rgb(_) => "rgb",
            Value::Point(_) => "point",
            Value::Vector(_) => "vector",
            Value::Transform(_) => "transform",
            Value::Spectrum(_) => "spectrum",
        }
    }
}

/// A named property of an object, such as `<float name="radius" value="2"/>`.
#[derive(Debug, Clone, PartialEq)]
pub struct Property {
    /// The `name` attribute.
    pub name: String,
    /// The parsed value.
    pub value: Value,
    /// Where the property's element starts.
    pub location: Location,
}

/// A nested object or a `<ref>` inside an object.
#[derive(Debug, Clone, PartialEq)]
pub struct Child {
    /// The `name` attribute at the use site (of the nested object or of the `<ref>`), if any.
    pub name: Option<String>,
    /// The object. A `<ref>` yields the same `Arc` as the object it refers to.
    pub object: Arc<Object>,
}

/// An object of the scene: a plugin instance such as `<shape type="sphere">`, or the `<scene>`
/// root itself.
#[derive(Debug, Clone, PartialEq)]
pub struct Object {
    /// The element's tag: `"shape"`, `"bsdf"`, ..., or `"scene"` for the root.
    pub tag: String,
    /// The `type` attribute (the plugin name); empty for the scene root.
    pub plugin: String,
    /// The `id` attribute, if any (unique across the scene and its included files).
    pub id: Option<String>,
    /// The properties, in document order.
    pub properties: Vec<Property>,
    /// Nested objects and references, in document order.
    pub children: Vec<Child>,
    /// Where the object's element starts.
    pub location: Location,
}

/// A parsed scene file: its `<scene>` root, and the file resolver its plugins look their
/// files up with (see [`FileResolver`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Document {
    pub root: Object,
    pub resolver: FileResolver,
    /// What the user should know that is not an error (non-unit rotation axes).
    pub warnings: Vec<String>,
}

/// Loads the scene file at `path` and returns its `<scene>` root.
///
/// `overrides` are `(name, value)` pairs (the CLI's `-D name=value`) that take precedence
/// over the file's `<default>`s; if a name is given twice, the last one wins.
///
/// Errors: [`Error::Io`] if the file cannot be read, [`Error::Xml`] if it is not UTF-8 or not
/// well-formed XML, [`Error::Scene`] for everything the scene says that is not accepted.
pub fn load_file(path: &Path, overrides: &[(String, String)]) -> Result<Document> {
    let text =
        crate::io::read_file_limited(path, crate::io::MAX_SCENE_FILE_BYTES).map_err(|cause| {
            Error::Io {
                path: path.to_path_buf(),
                cause,
            }
        })?;
    let text = decode_utf8(path, text)?;
    load_str(&text, path, overrides)
}

/// Parses the scene in `text` and returns its `<scene>` root.
///
/// `path` is the file the text came from: it is used for locations in errors and to resolve
/// relative `<include>`s (it need not exist if there are none). `overrides` are as in
/// [`load_file`].
pub fn load_str(text: &str, path: &Path, overrides: &[(String, String)]) -> Result<Document> {
    let mut file = SourceFile::new(path, text);
    let mut loader = Loader::new(overrides, FileResolver::for_scene(&file.dir));
    let doc = parse_document(&file)?;
    loader.include_stack.push(IncludeFrame {
        key: include_key(path),
        shown: path.to_path_buf(),
    });
    let raw = loader.load_root(&mut file, doc.root_element())?;
    let root = loader.resolve_root(raw)?;
    Ok(Document {
        root,
        resolver: loader.resolver,
        warnings: loader.warnings,
    })
}

/// The document-order state of a load: parameters, parsed objects, declared ids, the
/// include chain and the file resolver.
struct Loader {
    /// `$name` values: overrides first, then `<default>`s (the first definition wins).
    params: HashMap<String, String>,
    /// Every object parsed so far (nested ones included), by index; references point here.
    arena: Vec<RawObject>,
    /// Every id declared so far: an object of `arena`, or an alias of another id.
    ids: HashMap<String, IdDecl>,
    /// The chain of files being included, outermost first.
    include_stack: Vec<IncludeFrame>,
    /// Bytes that `$name` substitution may still produce.
    substitution_budget: usize,
    /// Where relative file names are looked up (changes with `<path>` and `<include>`).
    resolver: FileResolver,
    /// The nesting depth of the children of the current file's `<scene>` root, where
    /// `<path>` may appear.
    file_root_depth: usize,
    /// Warnings met while parsing.
    warnings: Vec<String>,
}

/// An object as parsed, before its references are resolved.
struct RawObject {
    tag: String,
    plugin: String,
    id: Option<String>,
    properties: Vec<Property>,
    children: Vec<RawChild>,
    location: Location,
    /// `<tag type=".." id="..">`, for messages.
    desc: String,
}

/// A child as parsed: a nested object (an index into the loader's arena) or a reference.
enum RawChild {
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
enum IdTarget {
    Object(usize),
    /// `<alias id="of" as="...">`: resolved after parsing, like references.
    Alias {
        of: String,
        desc: String,
    },
}

struct IdDecl {
    target: IdTarget,
    location: Location,
}

/// How far the resolution of an arena object has got.
#[derive(Clone, Copy, PartialEq, Eq)]
enum ResolveState {
    Todo,
    /// Being resolved: reaching it again means a reference cycle.
    InProgress,
}

/// One file of the include chain.
struct IncludeFrame {
    /// The canonical path when it exists, to recognise the same file under other names.
    key: PathBuf,
    /// The path as written, for messages.
    shown: PathBuf,
}

/// One XML file being parsed.
struct SourceFile<'t> {
    /// The path as given, used in locations.
    path: PathBuf,
    /// The directory relative `<include>`s are resolved against.
    dir: PathBuf,
    /// The file's text.
    text: &'t str,
    /// Whether the file declares a version before 2.0.0 and gets Mitsuba's in-memory upgrade.
    upgrade: bool,
    /// The last position mapped to a location, as `(byte offset, line, column)`: elements are
    /// visited in document order, so mapping continues from there in linear total time.
    cursor: Cell<(usize, u32, u32)>,
}

impl<'t> SourceFile<'t> {
    fn new(path: &Path, text: &'t str) -> Self {
        SourceFile {
            path: path.to_path_buf(),
            dir: path.parent().map(Path::to_path_buf).unwrap_or_default(),
            text,
            upgrade: false,
            cursor: Cell::new((0, 1, 1)),
        }
    }

    /// The location of byte offset `pos`, with roxmltree's conventions: 1-based lines, and
    /// 1-based columns counted in characters.
    fn location(&self, pos: usize) -> Location {
        let bytes = self.text.as_bytes();
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

    /// The location of a node's start.
    fn node_location(&self, node: Node) -> Location {
        self.location(node.range().start)
    }
}

/// Turns the bytes of a file into text, or explains where it is not UTF-8.
fn decode_utf8(path: &Path, bytes: Vec<u8>) -> Result<String> {
    String::from_utf8(bytes).map_err(|e| {
        let offset = e.utf8_error().valid_up_to();
        let valid = e.as_bytes().get(..offset).unwrap_or_default();
        let line = 1 + valid.iter().filter(|&&b| b == b'\n').count();
        Error::Xml {
            path: path.to_path_buf(),
            message: format!(
                "the file is not valid UTF-8 (invalid byte at line {line}, byte offset {offset})"
            ),
        }
    })
}

/// Parses `file`'s text as XML, after rejecting absurd nesting or attribute counts.
fn parse_document<'t>(file: &SourceFile<'t>) -> Result<roxmltree::Document<'t>> {
    if let Some((pos, problem)) = precheck(file.text) {
        let location = file.location(pos);
        return Err(Error::Xml {
            path: file.path.clone(),
            message: format!("{problem} (at {}:{})", location.line, location.col),
        });
    }
    roxmltree::Document::parse(file.text).map_err(|e| Error::Xml {
        path: file.path.clone(),
        message: e.to_string(),
    })
}

/// Scans XML text for an element opened more than [`MAX_XML_DEPTH`] levels deep or with more
/// than [`MAX_XML_ATTRIBUTES`] attributes, and returns its byte offset and the problem.
///
/// This is a cheap pre-check (it follows comments, CDATA, processing instructions and quoted
/// attribute values, which is exact for well-formed documents); on malformed input it may
/// give up and return `None`, leaving the diagnosis to the XML parser.
fn precheck(text: &str) -> Option<(usize, String)> {
    let mut i = 0usize;
    let mut depth = 0usize;
    loop {
        i += text.get(i..)?.find('<')?;
        let rest = text.get(i..)?;
        let skip = if rest.starts_with("<!--") {
            rest.find("-->")? + 3
        } else if rest.starts_with("<![CDATA[") {
            rest.find("]]>")? + 3
        } else if rest.starts_with("<?") {
            rest.find("?>")? + 2
        } else if rest.starts_with("<!") {
            rest.find('>')? + 1
        } else if rest.starts_with("</") {
            depth = depth.saturating_sub(1);
            rest.find('>')? + 1
        } else {
            let (end, attributes) = start_tag_end(rest)?;
            if attributes > MAX_XML_ATTRIBUTES {
                let problem = format!("an element has more than {MAX_XML_ATTRIBUTES} attributes");
                return Some((i, problem));
            }
            if end == 0 || rest.as_bytes().get(end - 1) != Some(&b'/') {
                depth += 1;
                if depth > MAX_XML_DEPTH {
                    let problem =
                        format!("elements are nested more than {MAX_XML_DEPTH} levels deep");
                    return Some((i, problem));
                }
            }
            end + 1
        };
        i += skip;
    }
}

/// The offset of the `>` that closes the start tag at the beginning of `tag`, skipping quoted
/// attribute values, and the number of attributes (`=` signs outside quotes) before it.
fn start_tag_end(tag: &str) -> Option<(usize, usize)> {
    let mut quote = None;
    let mut attributes = 0;
    for (i, b) in tag.bytes().enumerate() {
        match (quote, b) {
            (None, b'"' | b'\'') => quote = Some(b),
            (None, b'=') => attributes += 1,
            (None, b'>') => return Some((i, attributes)),
            (Some(q), _) if q == b => quote = None,
            _ => {}
        }
    }
    None
}

/// The canonical form of a path for cycle detection (the path itself if it does not exist).
fn include_key(path: &Path) -> PathBuf {
    std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf())
}

/// An element with its attributes upgraded (for old files) and `$`-substituted.
struct Elem<'a, 'input> {
    node: Node<'a, 'input>,
    tag: String,
    attrs: Vec<(String, String)>,
    location: Location,
    /// `<tag type=".." id=".." name="..">`, for messages.
    desc: String,
}

impl Elem<'_, '_> {
    /// The value of attribute `name`, if present.
    fn get(&self, name: &str) -> Option<&str> {
        self.attrs
            .iter()
            .find(|(key, _)| key == name)
            .map(|(_, value)| value.as_str())
    }

    /// An error located at this element.
    fn error(&self, message: impl Into<String>) -> Error {
        Error::scene(&self.location, message)
    }

    /// Rejects attributes other than `allowed`.
    fn check_attrs(&self, allowed: &[&str]) -> Result<()> {
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
    fn require(&self, name: &str) -> Result<&str> {
        self.get(name)
            .ok_or_else(|| self.error(format!("missing attribute \"{name}\" in {}", self.desc)))
    }

    /// The `name` attribute of a property, which must be present and valid.
    fn property_name(&self) -> Result<String> {
        let name = self.require("name")?;
        self.check_name(name)?;
        Ok(name.to_string())
    }

    /// Checks a parameter name (`name` attribute), as Mitsuba does.
    fn check_name(&self, name: &str) -> Result<()> {
        self.check_identifier("name", name)
    }

    /// Checks an identifier (`id` attribute), as Mitsuba does.
    fn check_id(&self, id: &str) -> Result<()> {
        self.check_identifier("id", id)
    }

    /// A `name` or `id` must be non-empty and must not start with '_' (Mitsuba reserves it).
    fn check_identifier(&self, what: &str, value: &str) -> Result<()> {
        if value.is_empty() {
            Err(self.error(format!("empty {what} in {}", self.desc)))
        } else if value.starts_with('_') {
            Err(self.error(format!(
                "invalid {what} \"{value}\" in {}: leading underscores are reserved",
                self.desc
            )))
        } else {
            Ok(())
        }
    }

    /// Parses attribute `name` as a finite float.
    fn float_attr(&self, name: &str) -> Result<f64> {
        let text = self.require(name)?;
        parse_f64(text).map_err(|m| self.error(format!("{m} in {}", self.desc)))
    }

    /// Parses a 3-vector given either as `value="a"` / `value="x y z"` or as `x`, `y`, `z`
    /// attributes, each defaulting to `default` (Mitsuba also treats an empty one as absent).
    fn xyz(&self, default: f64) -> Result<DVec3> {
        if let Some(value) = self.get("value") {
            if ["x", "y", "z"].iter().any(|k| self.get(k).is_some()) {
                return Err(self.error(format!(
                    "the \"value\" attribute cannot be mixed with \"x\"/\"y\"/\"z\" in {}",
                    self.desc
                )));
            }
            let numbers = self.numbers(value)?;
            return match numbers.as_slice() {
                [v] => Ok(DVec3::splat(*v)),
                [x, y, z] => Ok(DVec3::new(*x, *y, *z)),
                _ => Err(self.error(format!(
                    "\"value\" must have 1 or 3 components, found {} in {}",
                    numbers.len(),
                    self.desc
                ))),
            };
        }
        let mut v = [default; 3];
        for (slot, key) in v.iter_mut().zip(["x", "y", "z"]) {
            match self.get(key) {
                Some(text) if !text.is_empty() => {
                    *slot =
                        parse_f64(text).map_err(|m| self.error(format!("{m} in {}", self.desc)))?;
                }
                _ => {}
            }
        }
        Ok(DVec3::from_array(v))
    }

    /// Parses a list of finite floats separated by whitespace and/or commas.
    fn numbers(&self, text: &str) -> Result<Vec<f64>> {
        tokenize(text)
            .map(|token| parse_f64(token).map_err(|m| self.error(format!("{m} in {}", self.desc))))
            .collect()
    }

    /// Parses attribute `name` as exactly three numbers (for `<lookat>`).
    fn vec3_attr(&self, name: &str) -> Result<DVec3> {
        let numbers = self.numbers(self.require(name)?)?;
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

/// Splits a list of numbers at whitespace and commas.
fn tokenize(text: &str) -> impl Iterator<Item = &str> {
    text.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|token| !token.is_empty())
}

/// Parses a finite `f64` (surrounding whitespace allowed).
fn parse_f64(text: &str) -> std::result::Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(format!(
            "non-finite floating point value \"{}\"",
            shorten(text)
        )),
        Err(_) => Err(format!(
            "could not parse floating point value \"{}\"",
            shorten(text)
        )),
    }
}

/// Parses an `i64` (surrounding whitespace allowed).
fn parse_i64(text: &str) -> std::result::Result<i64, String> {
    text.trim()
        .parse::<i64>()
        .map_err(|_| format!("could not parse integer value \"{}\"", shorten(text)))
}

/// Cuts long attribute values down for messages.
fn shorten(text: &str) -> Cow<'_, str> {
    const MAX: usize = 60;
    match text.char_indices().nth(MAX) {
        Some((cut, _)) => Cow::Owned(format!("{}...", text.get(..cut).unwrap_or_default())),
        None => Cow::Borrowed(text),
    }
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

/// Mitsuba's upgrade of pre-2.0 parameter names: `camelCase` becomes `camel_case`, with the
/// same quirks as Mitsuba's loop (a run of capitals after a lowercase letter is lowered).
fn camel_to_snake(name: &str) -> String {
    let mut bytes = name.as_bytes().to_vec();
    let mut i = 0;
    while i + 1 < bytes.len() {
        let lower = bytes.get(i).is_some_and(u8::is_ascii_lowercase);
        let upper_next = bytes.get(i + 1).is_some_and(u8::is_ascii_uppercase);
        if lower && upper_next {
            bytes.insert(i + 1, b'_');
            i += 2;
            while let Some(b) = bytes.get_mut(i) {
                if !b.is_ascii_uppercase() {
                    break;
                }
                b.make_ascii_lowercase();
                i += 1;
            }
        }
        i += 1;
    }
    // Only ASCII bytes were inserted or changed, so this is still UTF-8.
    String::from_utf8(bytes).unwrap_or_else(|_| name.to_string())
}

/// Parses a version `"major.minor.patch"` as Mitsuba does.
fn parse_version(text: &str) -> Option<(u32, u32, u32)> {
    let mut parts = text
        .split(['.', ' '])
        .filter(|p| !p.is_empty())
        .map(|p| p.parse::<u32>().ok());
    let version = (parts.next()??, parts.next()??, parts.next()??);
    match parts.next() {
        None => Some(version),
        Some(_) => None,
    }
}

/// The properties and children of an object under construction.
#[derive(Default)]
struct Body {
    properties: Vec<Property>,
    children: Vec<RawChild>,
    /// Names used so far by properties and named children, with where.
    names: HashMap<String, Location>,
}

impl Body {
    /// Records that `name` is used at `elem`; each name may be used once per object.
    fn claim(&mut self, name: &str, elem: &Elem, parent_desc: &str) -> Result<()> {
        if let Some(previous) = self.names.get(name) {
            return Err(elem.error(format!(
                "duplicate name \"{name}\" in {parent_desc}: {} repeats the name used at {previous}",
                elem.desc
            )));
        }
        self.names.insert(name.to_string(), elem.location.clone());
        Ok(())
    }

    fn add_property(&mut self, property: Property, elem: &Elem, parent_desc: &str) -> Result<()> {
        self.claim(&property.name, elem, parent_desc)?;
        self.properties.push(property);
        Ok(())
    }

    fn add_child(&mut self, child: RawChild, elem: &Elem, parent_desc: &str) -> Result<()> {
        let name = match &child {
            RawChild::Object { name, .. } | RawChild::Ref { name, .. } => name,
        };
        if let Some(name) = name {
            self.claim(name, elem, parent_desc)?;
        }
        self.children.push(child);
        Ok(())
    }
}

impl Loader {
    fn new(overrides: &[(String, String)], resolver: FileResolver) -> Self {
        Loader {
            params: overrides.iter().cloned().collect(),
            arena: Vec::new(),
            ids: HashMap::new(),
            include_stack: Vec::new(),
            substitution_budget: SUBSTITUTION_BUDGET,
            resolver,
            file_root_depth: 1,
            warnings: Vec::new(),
        }
    }

    /// Replaces every `$name` in `value` (the longest run of `[A-Za-z0-9_]` after the `$`).
    fn substitute<'v>(&mut self, value: &'v str) -> std::result::Result<Cow<'v, str>, String> {
        if !value.contains('$') {
            return Ok(Cow::Borrowed(value));
        }
        let mut out = String::with_capacity(value.len());
        let mut rest = value;
        while let Some((before, after)) = rest.split_once('$') {
            out.push_str(before);
            let len = after
                .bytes()
                .take_while(|b| b.is_ascii_alphanumeric() || *b == b'_')
                .count();
            // The name is ASCII, so `len` is a character boundary.
            let (name, tail) = after.split_at_checked(len).unwrap_or((after, ""));
            if name.is_empty() {
                return Err(format!(
                    "\"$\" not followed by a parameter name in \"{}\"",
                    shorten(value)
                ));
            }
            let Some(replacement) = self.params.get(name) else {
                return Err(format!("undefined parameter \"${name}\""));
            };
            out.push_str(replacement);
            if out.len() > self.substitution_budget {
                return Err(format!(
                    "$-substitution produces more than {} MiB of text",
                    SUBSTITUTION_BUDGET >> 20
                ));
            }
            rest = tail;
        }
        out.push_str(rest);
        self.substitution_budget = self.substitution_budget.saturating_sub(out.len());
        Ok(Cow::Owned(out))
    }

    /// Reads an element: its tag and attributes, upgraded for old files and substituted.
    fn element<'a, 'input>(
        &mut self,
        file: &SourceFile,
        node: Node<'a, 'input>,
    ) -> Result<Elem<'a, 'input>> {
        let location = file.node_location(node);
        let raw_tag = node.tag_name().name();
        let raw_desc = || describe(raw_tag, node.attributes().map(|a| (a.name(), a.value())));
        if node.tag_name().namespace().is_some() {
            return Err(Error::scene(
                &location,
                format!("namespaced element {} is not supported", raw_desc()),
            ));
        }
        let tag = if file.upgrade && raw_tag == "lookAt" {
            "lookat".to_string()
        } else {
            raw_tag.to_string()
        };
        let mut attrs = Vec::new();
        for attr in node.attributes() {
            if attr.namespace().is_some() {
                return Err(Error::scene(
                    &location,
                    format!(
                        "unexpected namespaced attribute \"{}\" in {}",
                        attr.name(),
                        raw_desc()
                    ),
                ));
            }
            let name = attr.name();
            let raw = if file.upgrade {
                upgrade_attribute(node, &tag, name, attr.value())
            } else {
                Cow::Borrowed(attr.value())
            };
            let value = self.substitute(&raw).map_err(|message| {
                Error::scene(
                    &location,
                    format!("{message} in attribute \"{name}\" of {}", raw_desc()),
                )
            })?;
            attrs.push((name.to_string(), value.into_owned()));
        }
        let desc = describe(&tag, attrs.iter().map(|(k, v)| (k.as_str(), v.as_str())));
        Ok(Elem {
            node,
            tag,
            attrs,
            location,
            desc,
        })
    }

    /// Loads the `<scene>` root of the main file (references not yet resolved).
    fn load_root(&mut self, file: &mut SourceFile, root: Node) -> Result<RawObject> {
        let elem = self.element(file, root)?;
        if elem.tag != "scene" {
            return Err(elem.error(format!(
                "the root element must be <scene>, found {}",
                elem.desc
            )));
        }
        elem.check_attrs(&["version"])?;
        let version = elem
            .get("version")
            .ok_or_else(|| elem.error("missing attribute \"version\" in root element <scene>"))?;
        file.upgrade = self.check_version(&elem, version)?;
        let mut body = Body::default();
        self.parse_children(file, root, "<scene>", &mut body, 1)?;
        Ok(RawObject {
            tag: "scene".to_string(),
            plugin: String::new(),
            id: None,
            properties: body.properties,
            children: body.children,
            location: elem.location,
            desc: "<scene>".to_string(),
        })
    }

    /// Parses a scene version; returns whether the file needs the pre-2.0 upgrade.
    fn check_version(&self, elem: &Elem, version: &str) -> Result<bool> {
        let parsed = parse_version(version).ok_or_else(|| {
            elem.error(format!(
                "could not parse version number \"{}\" in {} (expected major.minor.patch)",
                shorten(version),
                elem.desc
            ))
        })?;
        Ok(parsed < (2, 0, 0))
    }

    /// Parses the child nodes of `parent` into `body`. `depth` is the nesting depth of the
    /// children.
    fn parse_children(
        &mut self,
        file: &SourceFile,
        parent: Node,
        parent_desc: &str,
        body: &mut Body,
        depth: usize,
    ) -> Result<()> {
        for child in parent.children() {
            match child.node_type() {
                NodeType::Element => self.parse_child(file, child, parent_desc, body, depth)?,
                NodeType::Text => check_text(file, child, parent_desc)?,
                NodeType::Root | NodeType::Comment | NodeType::PI => {}
            }
        }
        Ok(())
    }

    /// Parses one element inside an object (or inside `<scene>`) into `body`.
    fn parse_child(
        &mut self,
        file: &SourceFile,
        node: Node,
        parent_desc: &str,
        body: &mut Body,
        depth: usize,
    ) -> Result<()> {
        if depth > MAX_NESTING_DEPTH {
            return Err(Error::scene(
                &file.node_location(node),
                format!("elements are nested more than {MAX_NESTING_DEPTH} levels deep"),
            ));
        }
        let elem = self.element(file, node)?;
        let tag = elem.tag.as_str();
        if OBJECT_TAGS.contains(&tag) {
            let child = self.parse_object(file, &elem, depth)?;
            return body.add_child(child, &elem, parent_desc);
        }
        match tag {
            "ref" => {
                let child = self.parse_ref(file, &elem)?;
                body.add_child(child, &elem, parent_desc)
            }
            "alias" => self.parse_alias(file, &elem),
            "default" => self.parse_default(file, &elem),
            "include" => self.parse_include(file, &elem, parent_desc, body, depth),
            "path" => self.parse_path(file, &elem, parent_desc, depth),
            // `<spectrum type="...">` is a spectrum plugin (an object), as in Mitsuba.
            "spectrum" if elem.get("type").is_some() => {
                let child = self.parse_object(file, &elem, depth)?;
                body.add_child(child, &elem, parent_desc)
            }
            "spectrum" => {
                ensure_leaf(file, &elem)?;
                let property = Property {
                    name: elem.property_name()?,
                    value: self.parse_spectrum(&elem)?,
                    location: elem.location.clone(),
                };
                body.add_property(property, &elem, parent_desc)
            }
            "integer" | "float" | "boolean" | "string" | "rgb" | "point" | "vector" => {
                ensure_leaf(file, &elem)?;
                let property = Property {
                    name: elem.property_name()?,
                    value: parse_value(&elem)?,
                    location: elem.location.clone(),
                };
                body.add_property(property, &elem, parent_desc)
            }
            "transform" => {
                let property = self.parse_transform(file, &elem)?;
                body.add_property(property, &elem, parent_desc)
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

    /// Parses `<shape type=".." id=".." name="..">...</shape>` and friends into the arena.
    fn parse_object(&mut self, file: &SourceFile, elem: &Elem, depth: usize) -> Result<RawChild> {
        elem.check_attrs(&["type", "id", "name"])?;
        let plugin = elem.require("type")?;
        if plugin.is_empty() {
            return Err(elem.error(format!("empty \"type\" attribute in {}", elem.desc)));
        }
        let name = match elem.get("name") {
            Some(name) => {
                elem.check_name(name)?;
                Some(name.to_string())
            }
            None => None,
        };
        // The slot is reserved first, so that the id names it while the children are parsed.
        let index = self.arena.len();
        let id = match elem.get("id") {
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
        self.arena[index] = RawObject {
            tag: elem.tag.clone(),
            plugin: plugin.to_string(),
            id,
            properties: body.properties,
            children: body.children,
            location: elem.location.clone(),
            desc: elem.desc.clone(),
        };
        Ok(RawChild::Object { name, index })
    }

    /// Declares a new id at `elem`.
    fn declare_id(&mut self, elem: &Elem, id: &str, target: IdTarget) -> Result<()> {
        elem.check_id(id)?;
        if let Some(previous) = self.ids.get(id) {
            return Err(elem.error(format!(
                "{} has duplicate id \"{id}\" (first declared at {})",
                elem.desc, previous.location
            )));
        }
        self.ids.insert(
            id.to_string(),
            IdDecl {
                target,
                location: elem.location.clone(),
            },
        );
        Ok(())
    }

    /// The arena index of the object named `id` (following aliases), for a reference
    /// described by `desc` at `location`.
    fn lookup(&self, id: &str, location: &Location, desc: &str) -> Result<usize> {
        let mut id = id;
        let mut desc = desc;
        let mut location = location;
        // Each alias hop names a different id, so a chain longer than the id count cycles.
        for _ in 0..=self.ids.len() {
            match self.ids.get(id) {
                Some(IdDecl {
                    target: IdTarget::Object(index),
                    ..
                }) => return Ok(*index),
                Some(IdDecl {
                    target: IdTarget::Alias { of, desc: d },
                    location: l,
                }) => {
                    id = of;
                    desc = d;
                    location = l;
                }
                None => {
                    return Err(Error::scene(
                        location,
                        format!("{desc} refers to unknown id \"{id}\""),
                    ))
                }
            }
        }
        Err(Error::scene(
            location,
            format!("{desc} is part of a cycle of aliases"),
        ))
    }

    /// Resolves every reference below the scene root, once the whole scene is parsed.
    fn resolve_root(&self, raw: RawObject) -> Result<Object> {
        // Every alias must name an object, referenced or not (checked in document order).
        let mut aliases: Vec<(&Location, &String)> = self
            .ids
            .iter()
            .filter(|(_, d)| matches!(d.target, IdTarget::Alias { .. }))
            .map(|(id, d)| (&d.location, id))
            .collect();
        aliases.sort_by(|a, b| (&a.0.file, a.0.line, a.0.col).cmp(&(&b.0.file, b.0.line, b.0.col)));
        for (location, id) in aliases {
            self.lookup(id, location, "<alias>")?;
        }
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
                    return Err(Error::scene(
                        location,
                        format!(
                            "{desc} refers to {} at {}, which contains it: cyclic reference",
                            self.arena[index].desc, self.arena[index].location
                        ),
                    ));
                }
                if depth > MAX_REFERENCE_DEPTH {
                    return Err(Error::scene(
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

    /// Parses `<ref id=".." name=".."/>` (resolved after parsing).
    fn parse_ref(&mut self, file: &SourceFile, elem: &Elem) -> Result<RawChild> {
        ensure_leaf(file, elem)?;
        elem.check_attrs(&["id", "name"])?;
        let id = elem.require("id")?;
        let name = match elem.get("name") {
            Some(name) => {
                elem.check_name(name)?;
                Some(name.to_string())
            }
            None => None,
        };
        Ok(RawChild::Ref {
            name,
            id: id.to_string(),
            location: elem.location.clone(),
            desc: elem.desc.clone(),
        })
    }

    /// Parses `<alias id="existing" as="new"/>`: `new` becomes another id of the same object
    /// (checked after parsing, so `existing` may be declared later).
    fn parse_alias(&mut self, file: &SourceFile, elem: &Elem) -> Result<()> {
        ensure_leaf(file, elem)?;
        elem.check_attrs(&["id", "as"])?;
        let of = elem.require("id")?.to_string();
        let new_id = elem.require("as")?;
        let target = IdTarget::Alias {
            of,
            desc: elem.desc.clone(),
        };
        self.declare_id(elem, new_id, target)
    }

    /// Parses `<spectrum name=".." value=".."/>` or `filename=".."` (exactly one of the two;
    /// the file is looked up with the resolver as it stands, as in Mitsuba).
    fn parse_spectrum(&self, elem: &Elem) -> Result<Value> {
        use crate::spectrum::SpectrumValue;
        elem.check_attrs(&["name", "value", "filename"])?;
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
                            path.display()
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

    /// Parses `<path value=".."/>`, allowed only directly in a file's `<scene>`: the folder
    /// (relative to this file's directory, else looked up with the resolver) is searched first
    /// from now on. Inside an included file it lasts until the end of that file, as in Mitsuba.
    fn parse_path(
        &mut self,
        file: &SourceFile,
        elem: &Elem,
        parent_desc: &str,
        depth: usize,
    ) -> Result<()> {
        ensure_leaf(file, elem)?;
        elem.check_attrs(&["value"])?;
        if depth != self.file_root_depth {
            return Err(elem.error(format!(
                "{} can only appear directly inside <scene> (found in {parent_desc})",
                elem.desc
            )));
        }
        let value = Path::new(elem.require("value")?);
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
        if !dir.is_dir() {
            return Err(elem.error(format!(
                "{}: folder \"{}\" not found",
                elem.desc,
                dir.display()
            )));
        }
        self.resolver.prepend(dir);
        Ok(())
    }

    /// Parses `<default name=".." value=".."/>`; the first definition of a name wins, and
    /// overrides always win.
    fn parse_default(&mut self, file: &SourceFile, elem: &Elem) -> Result<()> {
        ensure_leaf(file, elem)?;
        elem.check_attrs(&["name", "value"])?;
        let name = elem.require("name")?;
        let value = elem.require("value")?;
        if name.is_empty() || !name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_') {
            return Err(elem.error(format!(
                "invalid parameter name \"{}\" in {}: use letters, digits and '_'",
                shorten(name),
                elem.desc
            )));
        }
        self.params
            .entry(name.to_string())
            .or_insert_with(|| value.to_string());
        Ok(())
    }

    /// Parses `<include filename=".."/>`: the file's `<scene>` children are spliced into
    /// `body` (a file whose root is not `<scene>` contributes that one element, as in
    /// Mitsuba).
    fn parse_include(
        &mut self,
        file: &SourceFile,
        elem: &Elem,
        parent_desc: &str,
        body: &mut Body,
        depth: usize,
    ) -> Result<()> {
        ensure_leaf(file, elem)?;
        elem.check_attrs(&["filename"])?;
        let filename = elem.require("filename")?;
        if filename.is_empty() {
            return Err(elem.error(format!("empty \"filename\" in {}", elem.desc)));
        }
        // Mitsuba looks the file up with the resolver, this file's directory first; whatever
        // the included file adds to the resolver is dropped after it.
        let saved_resolver = self.resolver.clone();
        self.resolver.prepend(file.dir.clone());
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
        if self.include_stack.len() > MAX_INCLUDE_DEPTH {
            return Err(elem.error(format!(
                "{} exceeds the include depth limit of {MAX_INCLUDE_DEPTH}",
                elem.desc
            )));
        }
        let key = include_key(&path);
        if self.include_stack.iter().any(|frame| frame.key == key) {
            let chain: Vec<String> = self
                .include_stack
                .iter()
                .map(|frame| frame.shown.display().to_string())
                .chain(std::iter::once(path.display().to_string()))
                .collect();
            return Err(elem.error(format!("cyclic include: {}", chain.join(" -> "))));
        }
        let bytes =
            crate::io::read_file_limited(&path, crate::io::MAX_SCENE_FILE_BYTES).map_err(|e| {
                elem.error(format!(
                    "cannot read included file \"{}\": {e}",
                    path.display()
                ))
            })?;
        let text = decode_utf8(&path, bytes)?;
        let mut included = SourceFile::new(&path, &text);
        let doc = parse_document(&included)?;
        let root = doc.root_element();
        self.include_stack.push(IncludeFrame { key, shown: path });
        let result = self.parse_included(&mut included, root, parent_desc, body, depth + 1);
        self.include_stack.pop();
        result
    }

    /// Splices the root of an included file into `body`.
    fn parse_included(
        &mut self,
        included: &mut SourceFile,
        root: Node,
        parent_desc: &str,
        body: &mut Body,
        depth: usize,
    ) -> Result<()> {
        if root.tag_name().name() != "scene" || root.tag_name().namespace().is_some() {
            return self.parse_child(included, root, parent_desc, body, depth);
        }
        let root_elem = self.element(included, root)?;
        root_elem.check_attrs(&["version"])?;
        if let Some(version) = root_elem.get("version") {
            included.upgrade = self.check_version(&root_elem, version)?;
        }
        let saved_root_depth = std::mem::replace(&mut self.file_root_depth, depth);
        let result = self.parse_children(included, root, parent_desc, body, depth);
        self.file_root_depth = saved_root_depth;
        result
    }

    /// Parses `<transform name="..">` and its operations into a property.
    fn parse_transform(&mut self, file: &SourceFile, elem: &Elem) -> Result<Property> {
        elem.check_attrs(&["name"])?;
        let name = elem.property_name()?;
        let mut matrix = DMat4::IDENTITY;
        for child in elem.node.children() {
            match child.node_type() {
                NodeType::Element => {
                    let op = self.element(file, child)?;
                    ensure_leaf(file, &op)?;
                    let m = transform_op(&op, &elem.desc)?;
                    if op.tag == "rotate" {
                        let axis = op.xyz(0.0)?;
                        if (axis.length_squared() - 1.0).abs() > 1e-6 {
                            self.warnings.push(format!(
                                "{}: {} has an axis of length {:.6}: Mitsuba does not normalise rotation axes, so this also scales and shears (penumbra does as Mitsuba)",
                                op.location,
                                op.desc,
                                axis.length()
                            ));
                        }
                    }
                    // Each operation applies after the previous ones, as in Mitsuba.
                    matrix = m * matrix;
                    if !matrix.is_finite() {
                        return Err(op.error(format!(
                            "{} makes the transform {} non-finite",
                            op.desc, elem.desc
                        )));
                    }
                }
                NodeType::Text => check_text(file, child, &elem.desc)?,
                NodeType::Root | NodeType::Comment | NodeType::PI => {}
            }
        }
        Ok(Property {
            name,
            value: Value::Transform(matrix),
            location: elem.location.clone(),
        })
    }
}

/// Mitsuba's in-memory upgrade of one attribute of a pre-2.0 file.
fn upgrade_attribute<'v>(node: Node, tag: &str, name: &str, value: &'v str) -> Cow<'v, str> {
    match name {
        "name" if tag != "default" => {
            let upgraded = camel_to_snake(value);
            let parent_is_diffuse = node.parent_element().is_some_and(|p| {
                p.tag_name().name() == "bsdf" && p.attribute("type") == Some("diffuse")
            });
            if parent_is_diffuse && upgraded == "diffuse_reflectance" {
                Cow::Borrowed("reflectance")
            } else if upgraded == value {
                Cow::Borrowed(value)
            } else {
                Cow::Owned(upgraded)
            }
        }
        "id" if value.starts_with('_') => Cow::Owned(format!("ID{value}__UPGR")),
        _ => Cow::Borrowed(value),
    }
}

/// Rejects child elements and text inside an element that takes none.
fn ensure_leaf(file: &SourceFile, elem: &Elem) -> Result<()> {
    for child in elem.node.children() {
        match child.node_type() {
            NodeType::Element => {
                let tag = child.tag_name().name();
                let desc = describe(tag, child.attributes().map(|a| (a.name(), a.value())));
                return Err(Error::scene(
                    &file.node_location(child),
                    format!("{desc} cannot appear inside {}", elem.desc),
                ));
            }
            NodeType::Text => check_text(file, child, &elem.desc)?,
            NodeType::Root | NodeType::Comment | NodeType::PI => {}
        }
    }
    Ok(())
}

/// Rejects a text node that is not whitespace only.
fn check_text(file: &SourceFile, node: Node, parent_desc: &str) -> Result<()> {
    let text = node.text().unwrap_or_default();
    let trimmed = text.trim();
    if trimmed.is_empty() {
        return Ok(());
    }
    // Point at the first non-blank character of the source text, when it can be found.
    let range = node.range();
    let start = file
        .text
        .get(range.clone())
        .and_then(|source| source.find(|c: char| !c.is_whitespace()))
        .map_or(range.start, |offset| range.start + offset);
    Err(Error::scene(
        &file.location(start),
        format!("unexpected text \"{}\" in {parent_desc}", shorten(trimmed)),
    ))
}

/// Parses the value of a simple property element (everything but `<transform>`).
fn parse_value(elem: &Elem) -> Result<Value> {
    let located = |m: String| elem.error(format!("{m} in {}", elem.desc));
    match elem.tag.as_str() {
        "point" | "vector" => {
            elem.check_attrs(&["name", "value", "x", "y", "z"])?;
            let v = elem.xyz(0.0)?;
            Ok(if elem.tag == "point" {
                Value::Point(v)
            } else {
                Value::Vector(v)
            })
        }
        tag => {
            elem.check_attrs(&["name", "value"])?;
            let text = elem.require("value")?;
            match tag {
                "integer" => Ok(Value::Integer(parse_i64(text).map_err(located)?)),
                "float" => Ok(Value::Float(parse_f64(text).map_err(located)?)),
                "boolean" => match text.to_ascii_lowercase().as_str() {
                    "true" => Ok(Value::Boolean(true)),
                    "false" => Ok(Value::Boolean(false)),
                    _ => Err(elem.error(format!(
                        "could not parse boolean value \"{}\" in {}: must be \"true\" or \"false\"",
                        shorten(text),
                        elem.desc
                    ))),
                },
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

/// The matrix of one operation inside a `<transform>`.
fn transform_op(op: &Elem, transform_desc: &str) -> Result<DMat4> {
    match op.tag.as_str() {
        "translate" => {
            op.check_attrs(&["x", "y", "z", "value"])?;
            Ok(DMat4::from_translation(op.xyz(0.0)?))
        }
        "scale" => {
            op.check_attrs(&["x", "y", "z", "value"])?;
            Ok(DMat4::from_scale(op.xyz(1.0)?))
        }
        "rotate" => {
            op.check_attrs(&["x", "y", "z", "value", "angle"])?;
            let axis = op.xyz(0.0)?;
            let angle = op.float_attr("angle")?;
            if axis == DVec3::ZERO {
                return Err(op.error(format!("{} has a zero rotation axis", op.desc)));
            }
            Ok(mitsuba_rotate(axis, angle))
        }
        "matrix" => {
            op.check_attrs(&["value"])?;
            let numbers = op.numbers(op.require("value")?)?;
            if let Ok(rows) = <[f64; 16]>::try_from(numbers.as_slice()) {
                Ok(DMat4::from_cols_array(&rows).transpose())
            } else if let Ok(rows) = <[f64; 9]>::try_from(numbers.as_slice()) {
                Ok(DMat4::from_mat3(DMat3::from_cols_array(&rows).transpose()))
            } else {
                Err(op.error(format!(
                    "<matrix> requires 16 (or 9) values, found {} in {}",
                    numbers.len(),
                    op.desc
                )))
            }
        }
        "lookat" => {
            op.check_attrs(&["origin", "target", "up"])?;
            let origin = op.vec3_attr("origin")?;
            let target = op.vec3_attr("target")?;
            let up = match op.get("up") {
                Some(_) => op.vec3_attr("up")?,
                None => DVec3::ZERO,
            };
            look_at(origin, target, up).map_err(|m| op.error(format!("{m} in {}", op.desc)))
        }
        _ => Err(op.error(format!(
            "unexpected {} inside {transform_desc}: only translate, rotate, scale, matrix and lookat are allowed",
            op.desc
        ))),
    }
}

/// Mitsuba's `rotate`: cos θ · I + (1 − cos θ) · a aᵀ + sin θ · [a]×, with the axis `a` as
/// written, NOT normalised (Mitsuba 3.9.1's `Transform::rotate` does not normalise it). For a
/// unit axis this is the rotation by `angle` degrees about `a`; for another axis it also
/// scales and shears, and Mitsuba's own hello.xml (axis 0, 1, 1) relies on it. The parser
/// warns about such axes.
fn mitsuba_rotate(a: DVec3, angle: f64) -> DMat4 {
    let (s, c) = angle.to_radians().sin_cos();
    let outer = DMat3::from_cols(a * a.x, a * a.y, a * a.z);
    let cross = DMat3::from_cols(
        DVec3::new(0.0, a.z, -a.y),
        DVec3::new(-a.z, 0.0, a.x),
        DVec3::new(a.y, -a.x, 0.0),
    );
    DMat4::from_mat3(DMat3::IDENTITY * c + outer * (1.0 - c) + cross * s)
}

/// Mitsuba's `look_at`: columns (left, new_up, dir, origin). A zero `up` picks one, as
/// Mitsuba does.
fn look_at(origin: DVec3, target: DVec3, up: DVec3) -> std::result::Result<DMat4, String> {
    let dir = safe_normalize(target - origin)
        .ok_or_else(|| "target coincides with origin".to_string())?;
    let up = match safe_normalize(up) {
        Some(up) => up,
        None => crate::geometry::coordinate_system(dir).0,
    };
    let left = up.cross(dir);
    // A relative test: a unit `up` (nearly) parallel to the unit `dir` leaves no frame.
    if !left.is_finite() || left.length() <= 1e-10 {
        return Err("up vector is parallel to the viewing direction".to_string());
    }
    let left = left.normalize();
    let new_up = dir.cross(left);
    let m = DMat4::from_cols(
        left.extend(0.0),
        new_up.extend(0.0),
        dir.extend(0.0),
        origin.extend(1.0),
    );
    if m.is_finite() {
        Ok(m)
    } else {
        Err("non-finite look-at transform".to_string())
    }
}

/// `v / |v|`, or `None` if `v` is zero or not finite.
fn safe_normalize(v: DVec3) -> Option<DVec3> {
    let largest = v.abs().max_element();
    if !largest.is_finite() || largest <= 0.0 {
        return None;
    }
    let v = (v / largest).normalize();
    v.is_finite().then_some(v)
}

#[cfg(test)]
mod tests;
