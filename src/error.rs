//! The library's error type. Every failure on user input ends here: the CLI prints its
//! `Display` form as one line and exits non-zero.

use std::path::PathBuf;

/// A location in a scene file, printed as `file:line:column`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Location {
    pub file: PathBuf,
    pub line: u32,
    pub col: u32,
}

impl std::fmt::Display for Location {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}:{}", self.file.display(), self.line, self.col)
    }
}

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written. (The cause is part of the message, not a
    /// `source`, so that `{:#}` printing does not repeat it.)
    #[error("{}: {cause}", path.display())]
    Io {
        path: PathBuf,
        cause: std::io::Error,
    },
    /// The scene file is not well-formed XML.
    #[error("{}: malformed XML: {message}", path.display())]
    Xml { path: PathBuf, message: String },
    /// The scene is well-formed but says something penumbra refuses: an unknown plugin or
    /// parameter, a bad number, a missing reference, a cyclic include, ...
    #[error("{location}: {message}")]
    Scene { location: Location, message: String },
    /// A problem with the scene as a whole, not tied to one element (no sensor, ...).
    #[error("{0}")]
    Invalid(String),
    /// A mesh file could not be loaded.
    #[error("{}: cannot load mesh: {message}", path.display())]
    Mesh { path: PathBuf, message: String },
    /// An input image (reference, environment map) could not be read.
    #[error("{}: cannot read image: {message}", path.display())]
    Image { path: PathBuf, message: String },
    /// `PENUMBRA_LIMITS` (see [`crate::limits`]) is malformed.
    #[error("PENUMBRA_LIMITS: {0}")]
    Limits(String),
    /// Writing an output image failed.
    #[error("{}: cannot write image: {message}", path.display())]
    Output { path: PathBuf, message: String },
}

impl Error {
    pub fn scene(location: &Location, message: impl Into<String>) -> Self {
        Error::Scene {
            location: location.clone(),
            message: message.into(),
        }
    }

    /// `e` placed at `location`, unless it already names a place in the scene (the more
    /// precise one, e.g. the `<texture>` inside a `<shape>`) or a file.
    pub fn within(location: &Location, e: Error) -> Self {
        match e {
            Error::Invalid(message) => Error::scene(location, message),
            other => other,
        }
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;
