//! penumbra: a physically based CPU path tracer that renders Mitsuba 3 scene files.
//!
//! Data flows one way: Mitsuba XML → [`scene::xml`] → [`scene::description`] →
//! [`scene::build`] (a [`scene::Scene`]) → [`render`] (an [`integrator`] driving the
//! [`camera`] and [`sampler`]) → [`film`] (f64 accumulation) → [`io::exr`].
pub mod accel;
pub mod bsdf;
pub mod camera;
pub mod chi2;
pub mod compare;
pub mod convergence;
pub mod emitter;
pub mod error;
pub mod experiment;
pub mod film;
pub mod geometry;
pub mod integrator;
pub mod io;
pub mod metrics;
pub mod plot;
pub mod progressive;
pub mod render;
pub mod sampler;
pub mod sampling;
pub mod scene;
pub mod shape;
pub mod spectrum;
pub mod stats;
pub mod validation;

pub use error::{Error, Result};

/// penumbra's version, as written into output headers.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
