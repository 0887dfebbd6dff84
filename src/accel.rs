//! One bounding volume hierarchy over every primitive of the scene (triangles, analytic
//! spheres and disks together), built with obvhs: PLOC (Meister and Bittner 2018) with
//! reinsertion and SAH-driven leaf collapse into a binary BVH. Primitive tests are our own: the
//! watertight triangle test and f64 analytic shapes (obvhs's triangle test is not watertight).
//!
//! Why not obvhs's faster 8-wide CWBVH: its traversal (obvhs 0.4.0, `cwbvh/node.rs`) clamps
//! every child's entry distance to an absolute `EPSILON = 1e-4`, so children whose exit
//! distance is below 1e-4 world units are never visited. Hits closer than that are lost: a
//! Cornell box scaled by 1e-4 rendered 18% too dark (shadow rays passed through the boxes).
//! The binary BVH's slab test has no such constant.

use crate::geometry::Ray;
use crate::shape::mesh::{intersect_triangle, RayShear};
use crate::shape::{Shape, ShapeGeometry, SurfaceInteraction};
use glam::{Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::ray::RayHit;
use obvhs::{Boundable, BvhBuildParams};
use std::time::Duration;

/// A primitive as the BVH sees it. Triangles carry their vertices so that the hot loop
/// reads one cache line per triangle.
#[derive(Clone, Copy, Debug)]
pub enum Primitive {
    Triangle {
        p: [Vec3; 3],
        shape: u32,
        index: u32,
    },
    Sphere {
        shape: u32,
    },
    Disk {
        shape: u32,
    },
}

struct Bounded<'a> {
    prim: &'a Primitive,
    shapes: &'a [Shape],
}

/// Bounds padded by a relative margin, so that rounding in the slab test cannot cull a
/// primitive the exact test would hit.
fn padded(points: impl IntoIterator<Item = Vec3>) -> Aabb {
    let mut aabb = Aabb::empty();
    for p in points {
        aabb.extend(Vec3A::from(p));
    }
    let pad = aabb.min.abs().max(aabb.max.abs()) * (4.0 * f32::EPSILON);
    Aabb::new(aabb.min - pad, aabb.max + pad)
}

impl Boundable for Bounded<'_> {
    fn aabb(&self) -> Aabb {
        match *self.prim {
            Primitive::Triangle { p, .. } => padded(p),
            Primitive::Sphere { shape } => match &self.shapes[shape as usize].geometry {
                ShapeGeometry::Sphere(s) => {
                    let r = glam::DVec3::splat(s.radius);
                    padded([(s.center - r).as_vec3(), (s.center + r).as_vec3()])
                }
                _ => Aabb::empty(),
            },
            Primitive::Disk { shape } => match &self.shapes[shape as usize].geometry {
                ShapeGeometry::Disk(d) => padded(d.corners()),
                _ => Aabb::empty(),
            },
        }
    }
}

/// A closest-hit record: which primitive, where along the ray, and its barycentrics.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub prim: u32,
    pub t: f32,
    pub b1: f32,
    pub b2: f32,
}

pub struct Accel {
    bvh: Option<Bvh2>,
    /// Primitives in BVH slot order.
    prims: Vec<Primitive>,
}

impl Accel {
    /// Collects every primitive of `shapes` and builds the hierarchy.
    pub fn build(shapes: &[Shape]) -> Self {
        let mut prims = Vec::new();
        for (i, shape) in shapes.iter().enumerate() {
            let shape_id = i as u32;
            match &shape.geometry {
                ShapeGeometry::Mesh(m) => {
                    for t in 0..m.triangles.len() {
                        prims.push(Primitive::Triangle {
                            p: m.vertices(t),
                            shape: shape_id,
                            index: t as u32,
                        });
                    }
                }
                ShapeGeometry::Sphere(_) => prims.push(Primitive::Sphere { shape: shape_id }),
                ShapeGeometry::Disk(_) => prims.push(Primitive::Disk { shape: shape_id }),
            }
        }
        if prims.is_empty() {
            return Accel { bvh: None, prims };
        }
        let bounded: Vec<Bounded> = prims.iter().map(|prim| Bounded { prim, shapes }).collect();
        let bvh = obvhs::bvh2::builder::build_bvh2(
            &bounded,
            BvhBuildParams {
                max_prims_per_leaf: 4,
                ..BvhBuildParams::medium_build()
            },
            &mut Duration::default(),
        );
        let ordered = bvh
            .primitive_indices
            .iter()
            .map(|&i| prims[i as usize])
            .collect();
        Accel {
            bvh: Some(bvh),
            prims: ordered,
        }
    }

    pub fn primitive_count(&self) -> usize {
        self.prims.len()
    }

    #[inline(always)]
    fn test(
        prim: &Primitive,
        shear: &RayShear,
        ray: &Ray,
        tmax: f32,
        shapes: &[Shape],
    ) -> Option<(f32, f32, f32)> {
        match *prim {
            Primitive::Triangle { ref p, .. } => intersect_triangle(shear, p, tmax),
            Primitive::Sphere { shape } => match &shapes[shape as usize].geometry {
                ShapeGeometry::Sphere(s) => {
                    s.intersect(&Ray { tmax, ..*ray }).map(|t| (t, 0.0, 0.0))
                }
                _ => None,
            },
            Primitive::Disk { shape } => match &shapes[shape as usize].geometry {
                ShapeGeometry::Disk(d) => d.intersect(&Ray { tmax, ..*ray }).map(|t| (t, 0.0, 0.0)),
                _ => None,
            },
        }
    }

    /// The closest hit with 0 < t < ray.tmax.
    pub fn intersect(&self, ray: &Ray, shapes: &[Shape]) -> Option<Hit> {
        let bvh = self.bvh.as_ref()?;
        let shear = RayShear::new(ray.o, ray.d);
        let mut best: Option<Hit> = None;
        let mut rh = RayHit::none();
        bvh.ray_traverse(ray.to_obvhs(), &mut rh, |r, slot| {
            match Self::test(&self.prims[slot], &shear, ray, r.tmax, shapes) {
                Some((t, b1, b2)) => {
                    best = Some(Hit {
                        prim: slot as u32,
                        t,
                        b1,
                        b2,
                    });
                    t
                }
                None => f32::INFINITY,
            }
        });
        best
    }

    /// True if anything lies on the ray with 0 < t < ray.tmax.
    pub fn occluded(&self, ray: &Ray, shapes: &[Shape]) -> bool {
        let Some(bvh) = self.bvh.as_ref() else {
            return false;
        };
        let shear = RayShear::new(ray.o, ray.d);
        !bvh.ray_traverse_miss(ray.to_obvhs(), |r, slot| {
            Self::test(&self.prims[slot], &shear, ray, r.tmax, shapes)
                .map_or(f32::INFINITY, |h| h.0)
        })
    }

    /// The surface interaction of a hit found by [`Accel::intersect`] on `ray`.
    pub fn interaction(&self, hit: &Hit, ray: &Ray, shapes: &[Shape]) -> SurfaceInteraction {
        match self.prims[hit.prim as usize] {
            Primitive::Triangle { shape, index, .. } => match &shapes[shape as usize].geometry {
                ShapeGeometry::Mesh(m) => {
                    m.interaction(index as usize, hit.t, hit.b1, hit.b2, shape)
                }
                _ => unreachable!("triangle primitive of a non-mesh shape"),
            },
            Primitive::Sphere { shape } => match &shapes[shape as usize].geometry {
                ShapeGeometry::Sphere(s) => s.interaction(ray, hit.t, shape),
                _ => unreachable!("sphere primitive of a non-sphere shape"),
            },
            Primitive::Disk { shape } => match &shapes[shape as usize].geometry {
                ShapeGeometry::Disk(d) => d.interaction(ray, hit.t, shape),
                _ => unreachable!("disk primitive of a non-disk shape"),
            },
        }
    }
}
