//! penumbra: a physically based CPU path tracer that renders Mitsuba 3 scene files.
//!
//! Two halves. The renderer: data flows one way, Mitsuba XML → [`scene::xml`] →
//! [`scene::description`] → [`scene::build`] (a [`scene::Scene`]) → [`render`] (an
//! [`integrator`] driving the [`camera`] and [`sampler`]) → [`film`] (f64 accumulation) →
//! [`io::exr`]. The study ([`study`]): comparing images, convergence ladders and experiments,
//! the validation against Mitsuba, metrics, statistics and plots.

// The renderer.
pub mod accel;
pub mod bsdf;
pub mod camera;
pub mod display;
pub mod emitter;
pub mod error;
pub mod film;
pub mod geometry;
pub mod integrator;
pub mod io;
pub mod limits;
pub mod material;
pub mod math;
pub mod medium;
pub mod phase;
pub mod progressive;
pub mod render;
pub mod sampler;
pub mod sampling;
pub mod scene;
pub mod shape;
pub mod simd;
pub mod spectral;
pub mod spectrum;
pub mod texture;
pub mod volume;

// The measurement side.
pub mod study;

pub use error::{Error, Result};

/// penumbra's version, as written into output headers.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
