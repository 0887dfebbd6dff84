//! Mitsuba 3 XML scene files, parsed into a generic object tree.
//!
//! This module reads a scene file as Mitsuba 3.9.1's parser (`src/core/parser.cpp`) does, and
//! accepts and refuses what it accepts and refuses, for everything that is independent of
//! specific plugins:
//!
//! - the XML syntax itself, with pugixml's leniencies ([`markup`]: comments containing `--`,
//!   a DOCTYPE, unknown entities, text anywhere, repeated attributes, ...); every node but
//!   elements is ignored, text included,
//! - `<path value="..."/>` and `<include filename="..." name="..."/>`, with Mitsuba's file
//!   resolver ([`FileResolver`]: the including file's directory first, then the `<path>`s,
//!   the scene's directory and the working directory); an included file needs its own
//!   `version`; a `<scene>` root contributes its objects (its properties and references are
//!   dropped, as in Mitsuba), another root that one object; at most [`MAX_INCLUDE_DEPTH`]
//!   files deep, include cycles rejected, at most [`MAX_INCLUDED_FILES`] included files
//!   and [`MAX_PARSED_BYTES`] bytes of XML parsed in all (a file counts each time it is
//!   included),
//! - `<default name="..." value="..."/>` and `$name` substitution in every attribute value
//!   (Mitsuba's: longest names first, anywhere in the value, `\$` for a literal `$`), with
//!   command-line overrides taking precedence over the file's defaults; an override the scene
//!   never uses is a warning (see below),
//! - `<ref id="..."/>`, resolved after the whole scene is parsed, as Mitsuba does: a
//!   reference may name an object declared later in the file or in a later include, and every
//!   reference to an id yields the very same [`Arc<Object>`]; reference cycles are rejected;
//!   `<alias id="..." as="..."/>` names an id already declared (in the same file or the files
//!   it included),
//! - `<transform>` blocks, composed exactly like Mitsuba does (each operation `M` is applied
//!   after the previous ones: `T = M * T`),
//! - typed properties (`integer`, `float`, `boolean`, `string`, `rgb`, `point`, `vector`,
//!   `spectrum`, `transform`), parsed into [`Value`]s with Mitsuba's number syntax ([`values`]),
//! - names: a property's name may be used once in an object; a nested object whose name is
//!   already used replaces that entry (Mitsuba's `Properties::set(.., false)`; penumbra warns),
//! - the in-memory upgrade of files older than version 2.0.0 ([`upgrade`]).
//!
//! It knows nothing about specific plugins: a later stage turns the [`Object`] tree into typed
//! scene objects and rejects unknown plugins and parameters.
//!
//! Deliberate differences from Mitsuba, all refusals of input no real scene contains:
//! non-finite numbers (`inf`, `nan`, `1e999`, or a transform that overflows) are refused,
//! since nothing downstream can use them; the main file's root must be `<scene>` (Mitsuba
//! would load a lone `<shape version="...">` as that object) and `<scene>` cannot be nested;
//! the `type` of a `<scene>` can only be `scene`; names and values must be UTF-8. And one
//! acceptance: an override (`-D`) that the scene never uses is a warning, where Mitsuba's
//! default `ParserConfig::unused_parameters` makes it an error; penumbra's own tools pass
//! `-D res=...`, `spp` and `integrator` to whole sets of scenes (the test suites, `study`),
//! not all of which use them.
//!
//! Every [`Object`] and [`Property`] carries the [`Location`] of its element, and every error
//! about an element names its tag, its `type` (if any) and its location. The parser is meant
//! to face hostile input: it never panics, bounds its recursion, the XML tree it builds and
//! the work and text that `$`-substitution may produce.

mod markup;
mod upgrade;
mod values;

use super::resolver::FileResolver;
use crate::error::{Error, Location, Result};
use glam::{DMat3, DMat4, DVec3};
use markup::{Element, Markup};
use std::borrow::Cow;
use std::cell::Cell;
use std::cmp::Reverse;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use values::{parse_float, parse_integer, parse_version, tokenize};

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

/// Maximum number of files in a chain of `<include>`s, the main file included: Mitsuba's
/// `ParserConfig::max_include_depth`.
const MAX_INCLUDE_DEPTH: usize = 15;

/// Included files parsed while loading one scene, counting a file each time it is included:
/// with [`MAX_INCLUDE_DEPTH`] alone, a chain of files that each include the next twice
/// would be parsed 2^14 times, and one whose files include the next eight times 8^14 times.
/// (Mitsuba has no such limit; no real scene includes files thousands of times.)
const MAX_INCLUDED_FILES: usize = 1 << 13;

/// Bytes of XML parsed while loading one scene, the main file's and every included file's
/// (each time it is included): 4 times the largest file read, [`MAX_SCENE_FILE_BYTES`].
///
/// [`MAX_SCENE_FILE_BYTES`]: crate::io::MAX_SCENE_FILE_BYTES
const MAX_PARSED_BYTES: u64 = 4 * crate::io::MAX_SCENE_FILE_BYTES;

/// Longest chain of objects reached through `<ref>`s while resolving one object (nested
/// objects count too): bounds the resolver's recursion on hostile input.
const MAX_REFERENCE_DEPTH: usize = 512;

/// Total number of bytes that `$name` substitution may produce while loading one scene; this
/// stops defaults that expand into each other from blowing up exponentially.
const SUBSTITUTION_BUDGET: usize = 64 << 20;

/// Total number of bytes that `$name` substitution may scan while loading one scene (Mitsuba
/// searches each attribute value once per parameter, so many defaults and long values would
/// otherwise take quadratic time).
const SUBSTITUTION_WORK: usize = 1 << 31;

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
/// over the file's `<default>`s; if a name is given twice, the last one wins. One that no
/// `$name` of the scene uses gets a warning.
///
/// Errors: [`Error::Io`] if the file cannot be read, [`Error::Xml`] if it is not well-formed
/// XML (as pugixml sees it), [`Error::Scene`] for everything the scene says that is not
/// accepted.
pub fn load_file(path: &Path, overrides: &[(String, String)]) -> Result<Document> {
    let bytes =
        crate::io::read_file_limited(path, crate::io::MAX_SCENE_FILE_BYTES).map_err(|cause| {
            Error::Io {
                path: path.to_path_buf(),
                cause,
            }
        })?;
    load_bytes(&bytes, path, overrides)
}

/// Parses the scene in `text` and returns its `<scene>` root.
///
/// `path` is the file the text came from: it is used for locations in errors and to resolve
/// relative `<include>`s (it need not exist if there are none). `overrides` are as in
/// [`load_file`].
pub fn load_str(text: &str, path: &Path, overrides: &[(String, String)]) -> Result<Document> {
    load_bytes(text.as_bytes(), path, overrides)
}

fn load_bytes(bytes: &[u8], path: &Path, overrides: &[(String, String)]) -> Result<Document> {
    let text = markup::to_utf8(bytes);
    let mut file = SourceFile::new(path, &text);
    let mut loader = Loader::new(overrides, FileResolver::for_scene(&file.dir));
    loader.parsed_bytes = bytes.len() as u64;
    let doc = parse_document(&file)?;
    loader.include_stack.push(IncludeFrame {
        key: include_key(path),
        shown: path.to_path_buf(),
    });
    let raw = loader.load_root(&mut file, doc.root())?;
    let root = loader.resolve_root(raw)?;
    loader.warn_unused_overrides();
    Ok(Document {
        root,
        resolver: loader.resolver,
        warnings: loader.warnings,
    })
}

/// A `$name` parameter: a command-line override or a `<default>`.
struct Parameter {
    /// The name, without the `$`.
    name: String,
    value: String,
    /// Whether it replaced something (only overrides are checked).
    used: bool,
    /// Whether it came from the command line.
    is_override: bool,
}

/// The `$name` parameters in Mitsuba's order: longest name first (so that `$ab` is not read
/// as `$a` followed by `b` when both exist), names of one length in the order they came.
#[derive(Default)]
struct Parameters {
    by_length: BTreeMap<Reverse<usize>, Vec<Parameter>>,
    names: HashSet<String>,
}

impl Parameters {
    fn contains(&self, name: &str) -> bool {
        self.names.contains(name)
    }

    /// Adds a parameter, or (for a name already there) replaces its value.
    fn set(&mut self, param: Parameter) {
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

/// The document-order state of a load: parameters, parsed objects, declared ids, the
/// include chain and the file resolver.
struct Loader {
    /// The `$name` parameters: overrides, then the `<default>`s (the first definition of a
    /// name wins).
    params: Parameters,
    /// Every object parsed so far (nested ones included), by index; references point here.
    arena: Vec<RawObject>,
    /// Every id declared so far, but those of included `<scene>` roots.
    ids: HashMap<String, IdDecl>,
    /// Ids declared so far (a counter: the order of declarations).
    id_count: usize,
    /// The files being parsed, outermost first, with the ids only they can see.
    scopes: Vec<FileScope>,
    /// The chain of files being included, outermost first.
    include_stack: Vec<IncludeFrame>,
    /// Included files parsed so far (see [`MAX_INCLUDED_FILES`]).
    included_files: usize,
    /// Bytes of XML parsed so far, the main file's included (see [`MAX_PARSED_BYTES`]).
    parsed_bytes: u64,
    /// Bytes that `$name` substitution may still produce.
    substitution_budget: usize,
    /// Bytes that `$name` substitution may still scan.
    substitution_work: usize,
    /// Where relative file names are looked up (changes with `<path>` and `<include>`).
    resolver: FileResolver,
    /// The nesting depth of the children of the current file's root element, where `<path>`
    /// may appear.
    file_root_depth: usize,
    /// Warnings met while parsing.
    warnings: Vec<String>,
}

/// What a file being parsed sees of the ids: in Mitsuba each included file is parsed into a
/// state of its own, merged into the including file's afterwards.
struct FileScope {
    /// The first id declaration of this file (`IdDecl::order`): an `<alias>` can only name
    /// ids declared from there on (in this file or the files it included).
    first_id: usize,
    /// The ids of an included `<scene>` root and its aliases: they exist while the file is
    /// parsed and are dropped with its root, as in Mitsuba.
    root_ids: HashMap<String, Location>,
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
#[derive(Clone, Copy)]
enum IdTarget {
    Object(usize),
    /// The main file's `<scene>` root (a reference to it is a cycle).
    Root,
}

struct IdDecl {
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
    /// The file's text (UTF-8 but for what the XML reader skips).
    text: &'t [u8],
    /// Whether the file declares a version before 2.0.0 and gets Mitsuba's in-memory upgrade.
    upgrade: bool,
    /// The last position mapped to a location, as `(byte offset, line, column)`: elements are
    /// visited in document order, so mapping continues from there in linear total time.
    cursor: Cell<(usize, u32, u32)>,
}

impl<'t> SourceFile<'t> {
    fn new(path: &Path, text: &'t [u8]) -> Self {
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
    fn location(&self, pos: usize) -> Location {
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
    fn node_location(&self, node: Element) -> Location {
        self.location(node.start())
    }
}

/// Parses `file`'s text as XML.
fn parse_document<'t>(file: &SourceFile<'t>) -> Result<Markup<'t>> {
    markup::parse(file.text).map_err(|e| {
        let location = file.location(e.offset);
        Error::Xml {
            path: file.path.clone(),
            message: format!("{} (at {}:{})", e.message, location.line, location.col),
        }
    })
}

/// The canonical form of a path for cycle detection (the path itself if it does not exist).
fn include_key(path: &Path) -> PathBuf {
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

/// An element with its attributes `$`-substituted.
struct Elem<'m, 't> {
    node: Element<'m, 't>,
    tag: String,
    /// The attributes in document order; a name may repeat (the first one counts).
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
        scene_error(&self.location, message)
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

    /// The `name` of a property, which must be present (it may be empty, as in Mitsuba).
    fn property_name(&self) -> Result<String> {
        Ok(self.require("name")?.to_string())
    }

    /// The `name` of a nested object, reference or include: an empty one is no name.
    fn child_name(&self) -> Option<String> {
        self.get("name")
            .filter(|name| !name.is_empty())
            .map(str::to_string)
    }

    /// Parses attribute `name` as a finite float.
    fn float_attr(&self, name: &str) -> Result<f64> {
        self.float(self.require(name)?)
    }

    /// Parses a finite float with Mitsuba's syntax.
    fn float(&self, text: &str) -> Result<f64> {
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
    fn xyz_attrs(&self) -> Result<[Option<String>; 3]> {
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
    fn xyz(&self, parts: &[Option<String>; 3], default: f64) -> Result<DVec3> {
        let mut v = [default; 3];
        for (slot, part) in v.iter_mut().zip(parts) {
            if let Some(text) = part {
                *slot = self.float(text)?;
            }
        }
        Ok(DVec3::from_array(v))
    }

    /// Parses a list of finite floats separated by spaces and/or commas.
    fn numbers(&self, text: &str) -> Result<Vec<f64>> {
        tokenize(text).map(|token| self.float(token)).collect()
    }

    /// Parses attribute text as exactly three numbers (for `<lookat>`).
    fn vec3(&self, name: &str, text: &str) -> Result<DVec3> {
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
fn shorten(text: &str) -> Cow<'_, str> {
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
fn scene_error(location: &Location, message: impl Into<String>) -> Error {
    let message = message.into();
    Error::scene(location, one_line(&message))
}

/// A path for a message, on one line.
fn shown(path: &Path) -> String {
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
fn describe_node(node: Element) -> String {
    let attrs: Vec<(&str, String)> = node
        .attributes()
        .map(|a| (a.name(), a.value().map(Cow::into_owned).unwrap_or_default()))
        .collect();
    describe(node.name(), attrs.iter().map(|(k, v)| (*k, v.as_str())))
}

/// An entry of an object: a property or a child, in document order (Mitsuba keeps both in
/// one `Properties` list, where a child may replace a property of the same name).
enum Entry {
    Property(Property),
    Child(RawChild),
}

impl Entry {
    fn name(&self) -> Option<&str> {
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
struct Body {
    entries: Vec<Entry>,
    /// The entry of each name used so far.
    names: HashMap<String, usize>,
}

impl Body {
    fn push(&mut self, entry: Entry) {
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
    fn add_object(&mut self, entry: Entry) -> bool {
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
    fn rename(&mut self, i: usize, new_name: String) {
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
    fn remove(&mut self, i: usize) {
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
    fn new(overrides: &[(String, String)], resolver: FileResolver) -> Self {
        let mut params = Parameters::default();
        for (name, value) in overrides {
            // The last override of a name wins.
            params.set(Parameter {
                name: name.clone(),
                value: value.clone(),
                used: false,
                is_override: true,
            });
        }
        Loader {
            params,
            arena: Vec::new(),
            ids: HashMap::new(),
            id_count: 0,
            scopes: vec![FileScope {
                first_id: 0,
                root_ids: HashMap::new(),
            }],
            include_stack: Vec::new(),
            included_files: 0,
            parsed_bytes: 0,
            substitution_budget: SUBSTITUTION_BUDGET,
            substitution_work: SUBSTITUTION_WORK,
            resolver,
            file_root_depth: 1,
            warnings: Vec::new(),
        }
    }

    /// Mitsuba's `substitute_parameters`: for each parameter, longest name first, every
    /// `$name` in the value that is not preceded by `\` is replaced (anywhere: `$ab` with only
    /// `a` defined is the value of `a` followed by `b`); text a replacement brings in is seen
    /// by the parameters after it. Then any `$` left that is not escaped is an undefined
    /// parameter, and `\$` becomes `$`. Only values that contain a `$` are touched.
    fn substitute<'v>(&mut self, value: &'v str) -> std::result::Result<Cow<'v, str>, String> {
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
    fn warn_unused_overrides(&mut self) {
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

    /// Reads an element: its tag and `$`-substituted attributes.
    fn element<'m, 't>(
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

    /// Reads a file root's `version` (required, not substituted) and notes whether the file
    /// gets the pre-2.0 upgrade.
    fn read_version(&self, file: &mut SourceFile, root: Element) -> Result<()> {
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

    /// Loads the `<scene>` root of the main file (references not yet resolved).
    fn load_root(&mut self, file: &mut SourceFile, root: Element) -> Result<RawObject> {
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
    fn parse_children(
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
    fn parse_child(
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
    fn add_object(&mut self, body: &mut Body, child: RawChild, elem: &Elem, parent_desc: &str) {
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
    fn parse_object(
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
    fn declare_id(&mut self, elem: &Elem, id: &str, target: IdTarget) -> Result<()> {
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
    fn resolve_root(&self, raw: RawObject) -> Result<Object> {
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
    fn parse_ref(&mut self, elem: &Elem) -> Result<RawChild> {
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
    fn parse_alias(&mut self, elem: &Elem) -> Result<()> {
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

    /// Parses `<spectrum name=".." value=".."/>` or `filename=".."` (exactly one of the two;
    /// the file is looked up with the resolver as it stands, as in Mitsuba).
    fn parse_spectrum(&self, elem: &Elem) -> Result<Value> {
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

    /// Parses `<path value=".."/>`, allowed only directly inside a file's root element: the
    /// folder (relative to this file's directory, else looked up with the resolver) is
    /// searched first from now on. Inside an included file it lasts until the end of that
    /// file, as in Mitsuba.
    fn parse_path(
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

    /// Parses `<default name=".." value=".."/>`: a new `$name` (any non-empty name), unless
    /// an override or an earlier default has that name.
    fn parse_default(&mut self, elem: &Elem) -> Result<()> {
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

    /// Parses `<include filename=".." name=".."/>`: a file whose root is `<scene>` (or an
    /// object without a `type`, which Mitsuba takes for a scene) contributes its nested
    /// objects to `body`; a file whose root is another object contributes that object, named
    /// `name`.
    fn parse_include(
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

    /// Parses `<transform name="..">` and its operations into a property. Other nodes inside
    /// it, and whatever is inside an operation, are ignored, as in Mitsuba.
    fn parse_transform(&mut self, file: &SourceFile, elem: &Elem) -> Result<Property> {
        elem.check_attrs(&["name"])?;
        let name = elem.property_name()?;
        let mut matrix = DMat4::IDENTITY;
        for child in elem.node.children() {
            let op = self.element(file, child)?;
            let m = transform_op(&op)?;
            if op.tag == "rotate" {
                let axis = op.xyz(&op.xyz_attrs()?, 0.0)?;
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
            if !matrix.is_finite()
                || matrix
                    .abs()
                    .to_cols_array()
                    .iter()
                    .any(|x| *x > f32::MAX as f64)
            {
                return Err(op.error(format!(
                    "{} makes the transform {} non-finite or beyond single precision (3.4e38)",
                    op.desc, elem.desc
                )));
            }
        }
        Ok(Property {
            name,
            value: Value::Transform(matrix),
            location: elem.location.clone(),
        })
    }
}

/// Whether an included file does not exist (Mitsuba checks before reading it).
fn filename_is_missing(path: &Path) -> bool {
    !path.exists()
}

/// A `<scene>`'s `type` may only be `scene` (Mitsuba takes any other as the plugin that
/// makes the scene, and has none).
fn check_scene_type(elem: &Elem) -> Result<()> {
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

/// Parses the value of a simple property element (everything but `<transform>` and
/// `<spectrum>`).
fn parse_value(elem: &Elem) -> Result<Value> {
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

/// The matrix of one operation inside a `<transform>`.
fn transform_op(op: &Elem) -> Result<DMat4> {
    let xyz_allowed = |extra: &[&'static str]| -> Vec<&'static str> {
        let mut allowed = vec!["x", "y", "z"];
        if op.get("value").is_some() {
            allowed.push("value");
        }
        allowed.extend_from_slice(extra);
        allowed
    };
    match op.tag.as_str() {
        "translate" => {
            let parts = op.xyz_attrs()?;
            op.check_attrs(&xyz_allowed(&[]))?;
            Ok(DMat4::from_translation(op.xyz(&parts, 0.0)?))
        }
        "scale" => {
            let parts = op.xyz_attrs()?;
            op.check_attrs(&xyz_allowed(&[]))?;
            Ok(DMat4::from_scale(op.xyz(&parts, 1.0)?))
        }
        "rotate" => {
            let parts = op.xyz_attrs()?;
            op.check_attrs(&xyz_allowed(&["angle"]))?;
            op.require("angle")?;
            let axis = op.xyz(&parts, 0.0)?;
            if axis == DVec3::ZERO {
                return Err(op.error(format!("{} has a zero rotation axis", op.desc)));
            }
            let angle = op.float_attr("angle")?;
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
            let origin = op.vec3("origin", op.require("origin")?)?;
            let target = op.vec3("target", op.require("target")?)?;
            // An absent or empty `up` is zero: Mitsuba then picks one.
            let up = match op.get("up").filter(|up| !up.is_empty()) {
                Some(up) => op.vec3("up", up)?,
                None => DVec3::ZERO,
            };
            look_at(origin, target, up).map_err(|m| op.error(format!("{m} in {}", op.desc)))
        }
        _ => Err(op.error(format!(
            "unexpected {} inside <transform>: only translate, rotate, scale, matrix and lookat are allowed",
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

/// Mitsuba's `dr::normalize`: `v · (1 / |v|)`, NaN for a zero vector (or one whose squared
/// length underflows).
fn mitsuba_normalize(v: DVec3) -> DVec3 {
    v * (1.0 / v.dot(v).sqrt())
}

/// Mitsuba's `look_at`: columns (left, new_up, dir, origin), with dir = normalize(target −
/// origin) and left = normalize(up × dir), computed as Mitsuba computes them; refused where
/// Mitsuba's result is NaN (target at origin, `up` parallel to the direction). An `up` of
/// exactly zero is replaced by Mitsuba's choice (`coordinate_system(dir)`).
fn look_at(origin: DVec3, target: DVec3, up: DVec3) -> std::result::Result<DMat4, String> {
    let dir = mitsuba_normalize(target - origin);
    if dir.is_nan() {
        return Err("target coincides with origin".to_string());
    }
    let up = if up == DVec3::ZERO {
        crate::geometry::coordinate_system(dir).0
    } else {
        up
    };
    let left = mitsuba_normalize(up.cross(dir));
    if left.is_nan() {
        return Err("up vector is parallel to the viewing direction".to_string());
    }
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

#[cfg(test)]
mod tests;
