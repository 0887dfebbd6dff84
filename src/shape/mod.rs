//! Shapes: triangle meshes (rectangle, cube, OBJ, PLY and serialized files become meshes),
//! analytic spheres, disks and cylinders, Mitsuba's SDF grids, all in world space (or a shape group's space). Each
//! shape samples points uniformly by area (for area lights) and turns a ray hit into a
//! [`SurfaceInteraction`] with Mitsuba's (u, v) parameterisation and dp/du.

pub mod cylinder;
pub mod disk;
pub mod mesh;
pub mod sdfgrid;
pub mod sphere;

pub use cylinder::Cylinder;
pub use disk::Disk;
pub use mesh::{triangle_interactions, Mesh, TriangleLanes, UvGrid};
pub use sdfgrid::SdfGrid;
pub use sphere::Sphere;

use crate::geometry::{Frame, Frames, Ray};
use crate::simd::{LaneF32, LaneU32, Lanes, Scalar, V3};
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
    /// Shading frame: `frame.n` is the shading normal and `frame.s` follows `dp_du`
    /// ([`Frame::from_normal_tangent`]). BSDFs and one-sided emitters work in this frame, as
    /// in Mitsuba.
    pub frame: Frame,
    /// Surface coordinates, parameterised per shape as in Mitsuba.
    pub uv: Vec2,
    /// Position partials with respect to `uv` (world space), as Mitsuba defines them per
    /// shape; `dp_du` orients the shading frame's tangent.
    pub dp_du: Vec3,
    pub dp_dv: Vec3,
    /// Index of the shape hit, in `Scene::shapes`.
    pub shape: u32,
    /// Triangle index within the mesh hit (0 for analytic shapes), for mesh attributes.
    pub prim: u32,
    /// Barycentrics (b1, b2) of the hit in that triangle (zero for analytic shapes).
    pub bary: Vec2,
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

/// Points sampled on a shape's surface, one per lane ([`PositionSample`] in lanes).
#[derive(Clone, Copy, Debug)]
pub struct PositionSamples<L: Lanes> {
    pub p: V3<L::F>,
    pub p_error: V3<L::F>,
    pub n: V3<L::F>,
    pub pdf: L::F,
}

impl<L: Lanes> PositionSamples<L> {
    #[inline(always)]
    pub fn zero(l: L) -> Self {
        let v = V3::splat(l.splat(0.0));
        PositionSamples {
            p: v,
            p_error: v,
            n: v,
            pdf: l.splat(0.0),
        }
    }

    #[inline(always)]
    pub fn set_lane(&mut self, i: usize, ps: &PositionSample) {
        self.p.set_lane(i, ps.p);
        self.p_error.set_lane(i, ps.p_error);
        self.n.set_lane(i, ps.n);
        self.pdf.set_lane(i, ps.pdf);
    }
}

impl From<PositionSamples<Scalar>> for PositionSample {
    #[inline(always)]
    fn from(ps: PositionSamples<Scalar>) -> Self {
        PositionSample {
            p: ps.p.into(),
            p_error: ps.p_error.into(),
            n: ps.n.into(),
            pdf: ps.pdf,
        }
    }
}

/// Surface interactions in lanes ([`SurfaceInteraction`] per lane).
#[derive(Clone, Copy, Debug)]
pub struct SurfaceInteractions<L: Lanes> {
    pub p: V3<L::F>,
    pub p_error: V3<L::F>,
    pub t: L::F,
    pub ng: V3<L::F>,
    pub frame: Frames<L>,
    /// (u, v).
    pub uv: [L::F; 2],
    pub dp_du: V3<L::F>,
    pub dp_dv: V3<L::F>,
    pub shape: L::U32,
    pub prim: L::U32,
    /// (b1, b2).
    pub bary: [L::F; 2],
}

impl<L: Lanes> SurfaceInteractions<L> {
    #[inline(always)]
    pub fn zero(l: L) -> Self {
        let z = l.splat(0.0);
        let v = V3::splat(z);
        SurfaceInteractions {
            p: v,
            p_error: v,
            t: z,
            ng: v,
            frame: Frames { s: v, t: v, n: v },
            uv: [z; 2],
            dp_du: v,
            dp_dv: v,
            shape: l.splat_u32(0),
            prim: l.splat_u32(0),
            bary: [z; 2],
        }
    }

    /// Lane `i`'s interaction.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> SurfaceInteraction {
        SurfaceInteraction {
            p: self.p.lane(i),
            p_error: self.p_error.lane(i),
            t: self.t.lane(i),
            ng: self.ng.lane(i),
            frame: self.frame.lane(i),
            uv: Vec2::new(self.uv[0].lane(i), self.uv[1].lane(i)),
            dp_du: self.dp_du.lane(i),
            dp_dv: self.dp_dv.lane(i),
            shape: self.shape.lane(i),
            prim: self.prim.lane(i),
            bary: Vec2::new(self.bary[0].lane(i), self.bary[1].lane(i)),
        }
    }

    #[inline(always)]
    pub fn set_lane(&mut self, i: usize, si: &SurfaceInteraction) {
        self.p.set_lane(i, si.p);
        self.p_error.set_lane(i, si.p_error);
        self.t.set_lane(i, si.t);
        self.ng.set_lane(i, si.ng);
        self.frame.set_lane(i, &si.frame);
        self.uv[0].set_lane(i, si.uv.x);
        self.uv[1].set_lane(i, si.uv.y);
        self.dp_du.set_lane(i, si.dp_du);
        self.dp_dv.set_lane(i, si.dp_dv);
        self.shape.set_lane(i, si.shape);
        self.prim.set_lane(i, si.prim);
        self.bary[0].set_lane(i, si.bary.x);
        self.bary[1].set_lane(i, si.bary.y);
    }

    /// `if m { a } else { b }` lane by lane.
    #[inline(always)]
    pub fn select(m: L::M, a: &Self, b: &Self) -> Self {
        let f = |x: L::F, y: L::F| L::F::select(m, x, y);
        let v = |x: V3<L::F>, y: V3<L::F>| V3::select(m, x, y);
        SurfaceInteractions {
            p: v(a.p, b.p),
            p_error: v(a.p_error, b.p_error),
            t: f(a.t, b.t),
            ng: v(a.ng, b.ng),
            frame: Frames::select(m, &a.frame, &b.frame),
            uv: [f(a.uv[0], b.uv[0]), f(a.uv[1], b.uv[1])],
            dp_du: v(a.dp_du, b.dp_du),
            dp_dv: v(a.dp_dv, b.dp_dv),
            shape: L::U32::select(m, a.shape, b.shape),
            prim: L::U32::select(m, a.prim, b.prim),
            bary: [f(a.bary[0], b.bary[0]), f(a.bary[1], b.bary[1])],
        }
    }
}

impl From<&SurfaceInteraction> for SurfaceInteractions<Scalar> {
    #[inline(always)]
    fn from(si: &SurfaceInteraction) -> Self {
        SurfaceInteractions {
            p: si.p.into(),
            p_error: si.p_error.into(),
            t: si.t,
            ng: si.ng.into(),
            frame: si.frame.into(),
            uv: [si.uv.x, si.uv.y],
            dp_du: si.dp_du.into(),
            dp_dv: si.dp_dv.into(),
            shape: si.shape,
            prim: si.prim,
            bary: [si.bary.x, si.bary.y],
        }
    }
}

impl From<SurfaceInteractions<Scalar>> for SurfaceInteraction {
    #[inline(always)]
    fn from(si: SurfaceInteractions<Scalar>) -> Self {
        si.lane(0)
    }
}

/// The geometry of one shape.
#[derive(Clone, Debug)]
pub enum ShapeGeometry {
    Mesh(Mesh),
    Sphere(Sphere),
    Disk(Disk),
    Cylinder(Cylinder),
    SdfGrid(Box<SdfGrid>),
}

impl ShapeGeometry {
    /// The plugin's name in scene files; `mesh` for the triangle meshes (`obj`, `ply`,
    /// `serialized`, `rectangle`, `cube` all become one).
    pub fn plugin_name(&self) -> &'static str {
        match self {
            ShapeGeometry::Mesh(_) => "mesh",
            ShapeGeometry::Sphere(_) => "sphere",
            ShapeGeometry::Disk(_) => "disk",
            ShapeGeometry::Cylinder(_) => "cylinder",
            ShapeGeometry::SdfGrid(_) => "sdfgrid",
        }
    }

    /// Total surface area, in world units squared.
    pub fn area(&self) -> f64 {
        match self {
            ShapeGeometry::Mesh(m) => m.area(),
            ShapeGeometry::Sphere(s) => s.area(),
            ShapeGeometry::Disk(d) => d.area(),
            ShapeGeometry::Cylinder(c) => c.area(),
            // Mitsuba gives the SDF grid no area (it cannot be sampled as an emitter).
            ShapeGeometry::SdfGrid(_) => 0.0,
        }
    }

    /// Samples a point uniformly by area.
    pub fn sample_position(&self, u: Vec2) -> Option<PositionSample> {
        match self {
            ShapeGeometry::Mesh(m) => m.sample_position(u),
            ShapeGeometry::Sphere(s) => Some(s.sample_position(u)),
            ShapeGeometry::Disk(d) => Some(d.sample_position(u)),
            ShapeGeometry::Cylinder(c) => Some(c.sample_position(u)),
            ShapeGeometry::SdfGrid(_) => None,
        }
    }

    /// The point with surface coordinates `uv` (Mitsuba's `eval_parameterization`), for
    /// textured emitters: analytic shapes invert their parameterisation, meshes look `uv` up
    /// in `grid` (built for this mesh). `None` where no point has these coordinates, and for
    /// SDF grids.
    pub fn at_uv(&self, uv: Vec2, grid: Option<&UvGrid>, shape: u32) -> Option<SurfaceInteraction> {
        if !uv.is_finite() {
            return None;
        }
        Some(match self {
            ShapeGeometry::Mesh(m) => {
                let (tri, b) = grid?.locate(m, uv)?;
                m.interaction(tri, 0.0, b.x, b.y, shape)
            }
            ShapeGeometry::Sphere(s) => s.at_uv(uv, shape),
            ShapeGeometry::Disk(d) => d.at_uv(uv, shape),
            ShapeGeometry::Cylinder(c) => c.at_uv(uv, shape),
            ShapeGeometry::SdfGrid(_) => return None,
        })
    }

    /// World-space bounds (min, max) of an analytic shape (`None` for meshes, whose
    /// triangles are bounded one by one).
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        match self {
            ShapeGeometry::Mesh(_) => None,
            ShapeGeometry::Sphere(s) => {
                let r = glam::DVec3::splat(s.radius);
                Some(((s.center - r).as_vec3(), (s.center + r).as_vec3()))
            }
            ShapeGeometry::Disk(d) => {
                let c = d.corners();
                let lo = c.iter().fold(Vec3::INFINITY, |a, &p| a.min(p));
                let hi = c.iter().fold(Vec3::NEG_INFINITY, |a, &p| a.max(p));
                Some((lo, hi))
            }
            ShapeGeometry::Cylinder(c) => {
                let [lo, hi] = c.bounds();
                Some((lo, hi))
            }
            ShapeGeometry::SdfGrid(g) => {
                let [lo, hi] = g.bounds();
                Some((lo, hi))
            }
        }
    }

    /// The closest hit of an analytic shape with 0 < t < ray.tmax (`None` for meshes).
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<f32> {
        match self {
            ShapeGeometry::Mesh(_) => None,
            ShapeGeometry::Sphere(s) => s.intersect(ray),
            ShapeGeometry::Disk(d) => d.intersect(ray),
            ShapeGeometry::Cylinder(c) => c.intersect(ray),
            ShapeGeometry::SdfGrid(g) => g.intersect(ray),
        }
    }

    /// The surface interaction at a hit of an analytic shape found by
    /// [`ShapeGeometry::intersect`].
    pub fn interaction(&self, ray: &Ray, t: f32, shape: u32) -> SurfaceInteraction {
        match self {
            ShapeGeometry::Mesh(_) => unreachable!("mesh hits are triangle hits"),
            ShapeGeometry::Sphere(s) => s.interaction(ray, t, shape),
            ShapeGeometry::Disk(d) => d.interaction(ray, t, shape),
            ShapeGeometry::Cylinder(c) => c.interaction(ray, t, shape),
            ShapeGeometry::SdfGrid(g) => g.interaction(ray, t, shape),
        }
    }
}

/// A shape with its material and, if it emits, its area emitter.
#[derive(Clone, Debug)]
pub struct Shape {
    pub geometry: ShapeGeometry,
    /// Index of its BSDF in `Scene::materials`.
    pub material: u32,
    /// Index into `Scene::emitters`, for shapes carrying an area emitter.
    pub emitter: Option<u32>,
    /// Indices into `Scene::media` of the media inside and outside the shape (Mitsuba's
    /// `interior` and `exterior`).
    pub interior: Option<u32>,
    pub exterior: Option<u32>,
}
