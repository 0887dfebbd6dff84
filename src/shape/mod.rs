//! Shapes: triangle meshes (rectangle, cube and OBJ files become meshes), analytic spheres
//! and analytic disks, all in world space. Each shape samples points uniformly by area (for
//! area lights) and turns a ray hit into a [`SurfaceInteraction`].

pub mod disk;
pub mod mesh;
pub mod sdfgrid;
pub mod sphere;

pub use disk::Disk;
pub use mesh::Mesh;
pub use sphere::Sphere;

use crate::geometry::Frame;
use glam::{Vec2, Vec3};

/// A local geometry record at a ray hit (pbrt's `SurfaceInteraction`, Mitsuba's
/// `SurfaceInteraction3f`).
#[derive(Clone, Copy, Debug)]
pub struct SurfaceInteraction {
    /// Hit point.
    pub p: Vec3,
    /// Conservative absolute error bound of each coordinate of `p`.
    pub p_error: Vec3,
    /// Distance along the ray (in units of the ray direction's length).
    pub t: f32,
    /// Geometric normal (unit). Decides the side a spawned ray starts on.
    pub ng: Vec3,
    /// Shading frame: `frame.n` is the shading normal. BSDFs and one-sided emitters work in
    /// this frame, as in Mitsuba.
    pub frame: Frame,
    pub uv: Vec2,
    /// Index of the shape hit, in `Scene::shapes`.
    pub shape: u32,
}

/// A point sampled on a shape's surface.
#[derive(Clone, Copy, Debug)]
pub struct PositionSample {
    pub p: Vec3,
    pub p_error: Vec3,
    /// Unit normal at `p` (shading normal where the shape has one).
    pub n: Vec3,
    /// Density w.r.t. surface area.
    pub pdf: f32,
}

/// The geometry of one shape.
#[derive(Clone, Debug)]
pub enum ShapeGeometry {
    Mesh(Mesh),
    Sphere(Sphere),
    Disk(Disk),
}

impl ShapeGeometry {
    /// Total surface area, in world units squared.
    pub fn area(&self) -> f64 {
        match self {
            ShapeGeometry::Mesh(m) => m.area(),
            ShapeGeometry::Sphere(s) => s.area(),
            ShapeGeometry::Disk(d) => d.area(),
        }
    }

    /// Samples a point uniformly by area.
    pub fn sample_position(&self, u: Vec2) -> Option<PositionSample> {
        match self {
            ShapeGeometry::Mesh(m) => m.sample_position(u),
            ShapeGeometry::Sphere(s) => Some(s.sample_position(u)),
            ShapeGeometry::Disk(d) => Some(d.sample_position(u)),
        }
    }
}

/// A shape with its material and, if it emits, its area emitter.
#[derive(Clone, Debug)]
pub struct Shape {
    pub geometry: ShapeGeometry,
    /// Index into `Scene::bsdfs`.
    pub bsdf: u32,
    /// Index into `Scene::emitters`, for shapes carrying an area emitter.
    pub emitter: Option<u32>,
}
