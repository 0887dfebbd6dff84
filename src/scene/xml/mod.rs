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
//!
//! The submodules, one concern each:
//!
//! - [`markup`]: the XML reader, with pugixml's syntax and leniencies,
//! - [`files`]: source files and locations in them, `version`, `<path>` and `<include>`,
//! - [`params`]: the `$name` parameters (overrides and `<default>`s) and their substitution,
//! - [`elem`]: an element with its attributes substituted, and the helpers of error messages,
//! - [`objects`]: the elements of an object in document order, and nested objects,
//! - [`resolve`]: ids, `<alias>`, `<ref>`, and the resolution of references after parsing,
//! - [`property`]: typed properties and `<spectrum>`,
//! - [`transform`]: `<transform>` and its operations,
//! - [`values`]: Mitsuba's syntax for numbers and versions,
//! - [`upgrade`]: the upgrade of files older than version 2.0.0.
//!
//! This module holds the parsed tree ([`Value`], [`Property`], [`Child`], [`Object`],
//! [`Document`]), the entry points ([`load_file`], [`load_str`]), the limits of one load and
//! its state ([`Loader`]).

mod elem;
mod files;
mod markup;
mod objects;
mod params;
mod property;
mod resolve;
mod transform;
mod upgrade;
mod values;

use super::resolver::FileResolver;
use crate::error::{Error, Location, Result};
use files::{include_key, parse_document, IncludeFrame, SourceFile};
use glam::{DMat4, DVec3};
use params::{Parameter, Parameters};
use resolve::{FileScope, IdDecl, RawObject};
use std::collections::HashMap;
use std::path::Path;
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
}

// What tests.rs (`use super::*`) reached here before the split.
#[cfg(test)]
use {std::path::PathBuf, transform::mitsuba_rotate};

#[cfg(test)]
mod tests;
