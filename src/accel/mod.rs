//! One bounding volume hierarchy over every primitive of the scene (triangles, analytic
//! spheres and disks together), built with obvhs: PLOC (Meister and Bittner 2018) with
//! reinsertion and SAH-driven leaf collapse into a binary BVH. Primitive tests are our own: the
//! watertight triangle test and f64 analytic shapes (obvhs's triangle test is not watertight).
//!
//! The binary BVH is then collapsed into a 4-wide BVH ("QBVH", Dammertz, Hanika and Keller
//! 2008, "Shallow Bounding Volume Hierarchies for Fast SIMD Ray Tracing of Incoherent Rays";
//! Wald, Benthin and Boulos 2008): each node holds the boxes of up to four children in
//! structure-of-arrays form, tested against one ray in one SSE slab test, and each leaf holds up
//! to four triangles tested at once by [`intersect_triangle4`]. Traversal visits children
//! nearest first and, for closest hits, skips subtrees entered beyond the nearest hit so far.
//! The slab test's far distance is widened by 1 + 2γ(3) (pbrt-v4 §6.1.2) so rounding can
//! never cull a box the ray touches; primitive bounds carry a relative pad for the same reason.
//!
//! Instancing (Mitsuba's `shapegroup` + `instance`) makes it two-level: each shape group has
//! its own hierarchy over its shapes, built once, and an instance is one primitive of the
//! scene's hierarchy holding a transform; a ray reaching it is carried into the group's space
//! and traced through the group's hierarchy. Memory grows with the groups, not the instances.
//!
//! Why not obvhs's own 8-wide CWBVH: its traversal (obvhs 0.4.0, `cwbvh/node.rs`) clamps
//! every child's entry distance to an absolute `EPSILON = 1e-4`, so children whose exit
//! distance is below 1e-4 world units are never visited. Hits closer than that are lost: a
//! Cornell box scaled by 1e-4 rendered 18% too dark (shadow rays passed through the boxes).
//! The traversal here has no absolute constant.

use crate::geometry::{gamma, Ray};
use crate::shape::mesh::{intersect_triangle4, RayShear4, Tri4};
use crate::shape::{Shape, ShapeGeometry, SurfaceInteraction};
use crate::simd::lanes_of;
use glam::{DMat3, DMat4, DVec3, Vec3, Vec3A, Vec4};
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::{Boundable, BvhBuildParams};
use std::mem::MaybeUninit;
use std::time::Duration;

#[cfg(target_arch = "x86_64")]
mod wide8;

/// The node and leaf width of a hierarchy: 4 (SSE, any x86-64 processor) or 8 (AVX2,
/// detected at run time; see `wide8.rs`). Both find the same hits (t and barycentrics
/// bit-identical); they may keep different ones of two hits at exactly the same distance.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layout {
    Wide4,
    Wide8,
}

impl Layout {
    /// The widest layout this processor runs.
    pub fn best() -> Layout {
        #[cfg(target_arch = "x86_64")]
        if wide8::supported() {
            return Layout::Wide8;
        }
        Layout::Wide4
    }

    /// Primitives per leaf block: 4 or 8.
    fn block_width(self) -> u32 {
        match self {
            Layout::Wide4 => 4,
            Layout::Wide8 => 8,
        }
    }
}

/// A primitive as the BVH sees it: triangle `index` of mesh `shape`, an analytic shape
/// (sphere, disk, cylinder, SDF grid: one primitive each), or an instance of a shape group.
/// Triangle vertices are read from the mesh once, when the leaves are packed.
#[derive(Clone, Copy, Debug)]
pub enum Primitive {
    Triangle { shape: u32, index: u32 },
    Analytic { shape: u32 },
    Instance { instance: u32 },
}

/// A primitive's bounds, for the builder.
struct Bounded(Aabb);

impl Boundable for Bounded {
    fn aabb(&self) -> Aabb {
        self.0
    }
}

/// An instance of a shape group: the group's hierarchy (in [`Accel::groups`]) placed by a
/// transform.
#[derive(Clone, Debug)]
pub struct Instance {
    pub group: u32,
    pub to_world: DMat4,
    pub to_local: DMat4,
}

impl Instance {
    /// `None` when `to_world` cannot be inverted.
    pub fn new(group: u32, to_world: DMat4) -> Option<Self> {
        let to_local = to_world.inverse();
        (to_world.determinant() != 0.0 && to_local.is_finite()).then_some(Instance {
            group,
            to_world,
            to_local,
        })
    }

    /// The ray in the group's space: the same `t` parameterises both.
    #[inline]
    fn local_ray(&self, ray: &Ray) -> Ray {
        Ray::new(
            self.to_local.transform_point3(ray.o.as_dvec3()).as_vec3(),
            self.to_local.transform_vector3(ray.d.as_dvec3()).as_vec3(),
            ray.tmax,
        )
    }
}

/// A shape group's hierarchy over its shapes (which live in the scene's shape list, in the
/// group's own space).
pub struct Group {
    pub accel: Accel,
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

/// The vertices of triangle `index` of mesh `shape`.
fn triangle_vertices(shapes: &[Shape], shape: u32, index: u32) -> [Vec3; 3] {
    match &shapes[shape as usize].geometry {
        ShapeGeometry::Mesh(m) => m.vertices(index as usize),
        _ => unreachable!("triangle primitive of a non-mesh shape"),
    }
}

/// The padded bounds of one primitive.
fn primitive_bounds(
    prim: &Primitive,
    shapes: &[Shape],
    instances: &[Instance],
    groups: &[Group],
) -> Aabb {
    match *prim {
        Primitive::Triangle { shape, index } => padded(triangle_vertices(shapes, shape, index)),
        Primitive::Analytic { shape } => match shapes[shape as usize].geometry.bounds() {
            Some((lo, hi)) => padded([lo, hi]),
            None => Aabb::empty(),
        },
        Primitive::Instance { instance } => {
            let inst = &instances[instance as usize];
            let Some((lo, hi)) = groups[inst.group as usize].accel.bounds else {
                return Aabb::empty();
            };
            let corners = (0..8).map(|k| {
                let c = DVec3::new(
                    if k & 1 == 0 { lo.x } else { hi.x } as f64,
                    if k & 2 == 0 { lo.y } else { hi.y } as f64,
                    if k & 4 == 0 { lo.z } else { hi.z } as f64,
                );
                inst.to_world.transform_point3(c).as_vec3()
            });
            padded(corners)
        }
    }
}

/// A closest-hit record: which primitive, where along the ray, and its barycentrics. For a
/// hit inside an instance, `prim` is the primitive of the group's hierarchy.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub prim: u32,
    pub t: f32,
    pub b1: f32,
    pub b2: f32,
    /// The instance hit, or [`NO_INSTANCE`].
    pub instance: u32,
}

/// [`Hit::instance`] of a hit outside any instance.
pub const NO_INSTANCE: u32 = u32::MAX;

/// Child reference: an inner node index, [`LEAF`] | a leaf index, or [`EMPTY`].
const LEAF: u32 = 1 << 31;
const EMPTY: u32 = u32::MAX;

/// A 4-wide node: `bounds[0]` are the children's minima, `bounds[1]` their maxima, per axis
/// (lane = child); `valid` masks the lanes that hold a child.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
struct Node4 {
    bounds: [[Vec4; 3]; 2],
    child: [u32; 4],
    valid: u32,
}

impl Node4 {
    const EMPTY: Node4 = Node4 {
        bounds: [[Vec4::INFINITY; 3], [Vec4::NEG_INFINITY; 3]],
        child: [EMPTY; 4],
        valid: 0,
    };
}

/// Up to four primitives of one BVH leaf: triangles packed for the 4-wide test, spheres and
/// disks tested one by one. `slot[lane]` is the primitive's index in `Accel::prims`.
#[derive(Clone, Copy, Debug)]
struct Leaf4 {
    tri: Tri4,
    slot: [u32; 4],
    tri_mask: u32,
    analytic_mask: u32,
    /// The next leaf block belongs to the same BVH leaf.
    more: bool,
}

/// Per-ray constants of the slab test.
struct BoxRay {
    o: [Vec4; 3],
    inv: [Vec4; 3],
}

impl BoxRay {
    fn new(ray: &Ray) -> Self {
        // Direction components below 1e-30 are nudged to ±1e-30 (inverse ±1e30), so the
        // slab of an axis-parallel ray stays effectively infinite and 0 · ∞ never makes a NaN.
        let inv = |x: f32| {
            1.0 / if x.abs() < 1e-30 {
                1e-30f32.copysign(x)
            } else {
                x
            }
        };
        let inv = [inv(ray.d.x), inv(ray.d.y), inv(ray.d.z)];
        BoxRay {
            o: [0, 1, 2].map(|a| Vec4::splat(ray.o[a])),
            inv: inv.map(Vec4::splat),
        }
    }

    /// Entry distances of the four children and the mask of those the ray enters within
    /// (0, tmax).
    #[inline(always)]
    fn test(&self, node: &Node4, tmax: f32) -> (u32, Vec4) {
        let mut t_near = Vec4::ZERO;
        let mut t_far = Vec4::INFINITY;
        for a in 0..3 {
            let t0 = (node.bounds[0][a] - self.o[a]) * self.inv[a];
            let t1 = (node.bounds[1][a] - self.o[a]) * self.inv[a];
            t_near = t_near.max(t0.min(t1));
            t_far = t_far.min(t0.max(t1));
        }
        let t_far = (t_far * Vec4::splat(1.0 + 2.0 * gamma(3))).min(Vec4::splat(tmax));
        (t_near.cmple(t_far).bitmask() & node.valid, t_near)
    }
}

/// What a leaf test needs of the ray and the scene.
struct LeafContext<'a> {
    shear: RayShear4,
    ray: &'a Ray,
    shapes: &'a [Shape],
}

/// A hit on an analytic primitive or inside an instance: (t, barycentrics, instance, slot in
/// the hierarchy that was hit).
type InnerHit = Hit;

#[cfg(test)]
thread_local! {
    /// Inner nodes whose children's boxes traversals on this thread have tested. Unit tests
    /// only: the library outside `cfg(test)` has no counter, so its traversal is unchanged.
    static NODE_VISITS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

/// Counts one inner node's box test (unit tests only, see [`NODE_VISITS`]).
#[cfg(test)]
#[inline(always)]
fn count_node_visit() {
    NODE_VISITS.with(|c| c.set(c.get() + 1));
}

/// Traversal stack depth without heap allocation; deeper trees (degenerate input) fall back
/// to a heap-allocated stack.
const STACK: usize = 128;

pub struct Accel {
    nodes: Vec<Node4>,
    leaves: Vec<Leaf4>,
    /// Child reference of the root (`EMPTY` for an empty scene).
    root: u32,
    /// Stack entries one traversal can need: 3 per level plus one.
    stack_size: usize,
    /// Primitives in BVH slot order.
    prims: Vec<Primitive>,
    /// Bounds of every primitive (min, max); `None` without primitives.
    pub bounds: Option<(Vec3, Vec3)>,
    /// Instances (primitives of this hierarchy) and the shape groups they place.
    instances: Vec<Instance>,
    groups: Vec<Group>,
    /// The 8-wide hierarchy, which replaces `nodes` and `leaves` when the layout is
    /// [`Layout::Wide8`].
    #[cfg(target_arch = "x86_64")]
    wide8: Option<wide8::Wide8>,
}

/// The children a node of `width` takes from binary node `b`: its two children, then
/// repeatedly the two children of the inner one of largest surface area, until there are
/// `width` or only nodes that `is_leaf` says stay whole (become a leaf) are left.
fn open_children(
    nodes: &[obvhs::bvh2::node::Bvh2Node],
    b: usize,
    width: usize,
    is_leaf: impl Fn(usize) -> bool,
) -> Vec<usize> {
    let first = nodes[b].first_index as usize;
    let mut children = vec![first, first + 1];
    while children.len() < width {
        let widest = children
            .iter()
            .enumerate()
            .filter(|(_, &c)| !is_leaf(c))
            .max_by(|x, y| {
                let ax = nodes[*x.1].aabb.half_area();
                let ay = nodes[*y.1].aabb.half_area();
                ax.total_cmp(&ay)
            })
            .map(|(i, _)| i);
        let Some(i) = widest else { break };
        let c = children.swap_remove(i);
        let f = nodes[c].first_index as usize;
        children.extend([f, f + 1]);
    }
    children
}

/// Whether a hit at `t` on primitive `prim` (of instance `instance`, or [`NO_INSTANCE`])
/// comes before `best` in the canonical order of hits along a ray: by t, then instance, then
/// primitive (slot). The closest hit is the least hit in this order, so it is a function of
/// the ray alone, whatever order a traversal visits the nodes in (issue 42: a packet
/// traversal must find the hit the single-ray one finds, even between coplanar triangles
/// at exactly the same t). The tests only report hits below [`bound_after`] the best one's t,
/// so `t` is at most `best.t` here.
#[inline(always)]
fn precedes(t: f32, instance: u32, prim: u32, best: &Option<Hit>) -> bool {
    match best {
        None => true,
        Some(b) => t != b.t || (instance, prim) < (b.instance, b.prim),
    }
}

/// The bound the tests of a traversal use once `t` is the best hit: the next f32 above it,
/// so that a test keeping hits strictly below the bound also reports ties at exactly `t`,
/// for [`precedes`] to decide. (A hit's t is positive and finite: its successor is one more
/// in its bits.)
#[inline(always)]
fn bound_after(t: f32) -> f32 {
    f32::from_bits(t.to_bits() + 1)
}

/// Records the triangle hits of one leaf block (lanes `mask`, with distances `t` and
/// barycentrics `b1`, `b2`, primitives `slot`): the least in the order of [`precedes`] into
/// `best`, or with `any` the first one. Every reported hit lies below `tmax` (the ray's own
/// bound, or [`bound_after`] the best hit's t). Returns the new bound and whether an
/// occlusion query is answered.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn record_triangle_hits<const N: usize>(
    mut mask: u32,
    t: &[f32; N],
    b1: &[f32; N],
    b2: &[f32; N],
    slot: &[u32; N],
    mut tmax: f32,
    best: &mut Option<Hit>,
    any: bool,
) -> (f32, bool) {
    if any && mask != 0 {
        // Occlusion: any hit will do.
        let lane = mask.trailing_zeros() as usize;
        *best = Some(Hit {
            prim: slot[lane],
            t: t[lane],
            b1: b1[lane],
            b2: b2[lane],
            instance: NO_INSTANCE,
        });
        return (tmax, true);
    }
    while mask != 0 {
        let lane = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        if t[lane] < tmax && precedes(t[lane], NO_INSTANCE, slot[lane], best) {
            tmax = bound_after(t[lane]);
            *best = Some(Hit {
                prim: slot[lane],
                t: t[lane],
                b1: b1[lane],
                b2: b2[lane],
                instance: NO_INSTANCE,
            });
        }
    }
    (tmax, false)
}

/// Pushes the entered children of a node (lanes `mask`, at least two, with entry distances
/// `t_near`) onto the stack, far to near, all but the nearest, and returns that one to
/// descend into. At most `N` of them: insertion sort.
#[inline(always)]
fn push_entered<const N: usize>(
    mut mask: u32,
    t_near: &[f32; N],
    child: &[u32; N],
    stack: &mut [MaybeUninit<(u32, f32)>],
    sp: &mut usize,
) -> u32 {
    let mut order = [(0u32, 0.0f32); N];
    let mut count = 0;
    while mask != 0 {
        let lane = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        let entry = (child[lane], t_near[lane]);
        let mut j = count;
        while j > 0 && order[j - 1].1 < entry.1 {
            order[j] = order[j - 1];
            j -= 1;
        }
        order[j] = entry;
        count += 1;
    }
    for &entry in &order[..count - 1] {
        stack[*sp] = MaybeUninit::new(entry);
        *sp += 1;
    }
    order[count - 1].0
}

impl Accel {
    /// Collects every primitive of `shapes` and builds the hierarchy.
    /// Whether the scene instances shape groups (two-level hierarchy).
    pub fn has_instances(&self) -> bool {
        !self.instances.is_empty()
    }

    pub fn build(shapes: &[Shape]) -> Self {
        Self::build_with_instances(shapes, 0..shapes.len(), Vec::new(), Vec::new())
    }

    /// [`Accel::build`] in the given layout ([`Layout::Wide8`] only where
    /// [`Layout::best`] is, else `Wide4`).
    pub fn build_with_layout(shapes: &[Shape], layout: Layout) -> Self {
        let layout = if layout == Layout::Wide8 {
            Layout::best()
        } else {
            layout
        };
        Self::build_in_layout(
            shapes,
            0..shapes.len(),
            Vec::new(),
            Vec::new(),
            layout,
            layout.block_width(),
        )
    }

    /// The layout this hierarchy was built in.
    pub fn layout(&self) -> Layout {
        #[cfg(target_arch = "x86_64")]
        if self.wide8.is_some() {
            return Layout::Wide8;
        }
        Layout::Wide4
    }

    /// Stack entries one traversal of this hierarchy can need.
    #[inline]
    fn stack_entries(&self) -> usize {
        #[cfg(target_arch = "x86_64")]
        if let Some(w) = &self.wide8 {
            return w.stack_size;
        }
        self.stack_size
    }

    /// The hierarchy of the shapes `range` of `shapes` (indices stay global) and of
    /// `instances`, whose groups are `groups` (each built over its own shapes), in the
    /// widest layout this processor runs.
    pub fn build_with_instances(
        shapes: &[Shape],
        range: std::ops::Range<usize>,
        instances: Vec<Instance>,
        groups: Vec<Group>,
    ) -> Self {
        let layout = Layout::best();
        Self::build_in_layout(
            shapes,
            range,
            instances,
            groups,
            layout,
            layout.block_width(),
        )
    }

    /// The hierarchy in `layout`, whose binary BVH has leaves of at most
    /// `max_prims_per_leaf` primitives (the block width, so that a leaf is one block, except
    /// in the tests of leaves that span several blocks).
    fn build_in_layout(
        shapes: &[Shape],
        range: std::ops::Range<usize>,
        instances: Vec<Instance>,
        groups: Vec<Group>,
        layout: Layout,
        max_prims_per_leaf: u32,
    ) -> Self {
        let mut prims = Vec::new();
        for i in range {
            let shape_id = i as u32;
            match &shapes[i].geometry {
                ShapeGeometry::Mesh(m) => {
                    for t in 0..m.triangles.len() {
                        prims.push(Primitive::Triangle {
                            shape: shape_id,
                            index: t as u32,
                        });
                    }
                }
                _ => prims.push(Primitive::Analytic { shape: shape_id }),
            }
        }
        for i in 0..instances.len() {
            prims.push(Primitive::Instance { instance: i as u32 });
        }
        let mut accel = Accel {
            nodes: Vec::new(),
            leaves: Vec::new(),
            root: EMPTY,
            stack_size: 1,
            prims: Vec::new(),
            bounds: None,
            instances,
            groups,
            #[cfg(target_arch = "x86_64")]
            wide8: None,
        };
        if prims.is_empty() {
            return accel;
        }
        let bounded: Vec<Bounded> = prims
            .iter()
            .map(|prim| {
                Bounded(primitive_bounds(
                    prim,
                    shapes,
                    &accel.instances,
                    &accel.groups,
                ))
            })
            .collect();
        let mut all = Aabb::empty();
        for b in &bounded {
            if b.0.min.cmple(b.0.max).all() {
                all = all.union(&b.0);
            }
        }
        if all.min.cmple(all.max).all() {
            accel.bounds = Some((Vec3::from(all.min), Vec3::from(all.max)));
        }
        let bvh = obvhs::bvh2::builder::build_bvh2(
            &bounded,
            BvhBuildParams {
                // One leaf block's worth: its primitives are tested at once.
                max_prims_per_leaf,
                ..BvhBuildParams::medium_build()
            },
            &mut Duration::default(),
        );
        accel.prims = bvh
            .primitive_indices
            .iter()
            .map(|&i| prims[i as usize])
            .collect();
        drop(bounded);
        match layout {
            #[cfg(target_arch = "x86_64")]
            Layout::Wide8 => {
                accel.wide8 = Some(wide8::Wide8::collapse(&bvh, &accel.prims, shapes));
            }
            _ => accel.collapse(&bvh, shapes),
        }
        accel
    }

    /// Turns the binary BVH into 4-wide nodes: each node takes its two children and keeps
    /// opening the inner child of largest surface area until it has four.
    fn collapse(&mut self, bvh: &Bvh2, shapes: &[Shape]) {
        let nodes = &bvh.nodes;
        if nodes.is_empty() {
            return;
        }
        if nodes[0].prim_count > 0 {
            self.root = self.add_leaf(&nodes[0], shapes);
            return;
        }
        self.nodes.push(Node4::EMPTY);
        self.root = 0;
        let mut max_depth = 1;
        // (binary node, 4-wide node it becomes, depth)
        let mut work = vec![(0usize, 0usize, 1usize)];
        while let Some((b, n4, depth)) = work.pop() {
            max_depth = max_depth.max(depth);
            let children = open_children(nodes, b, 4, |c| nodes[c].prim_count > 0);
            let mut node = Node4::EMPTY;
            for (lane, &c) in children.iter().enumerate() {
                let aabb = nodes[c].aabb;
                for a in 0..3 {
                    node.bounds[0][a][lane] = aabb.min[a];
                    node.bounds[1][a][lane] = aabb.max[a];
                }
                node.valid |= 1 << lane;
                node.child[lane] = if nodes[c].prim_count > 0 {
                    self.add_leaf(&nodes[c], shapes)
                } else {
                    let idx = self.nodes.len();
                    self.nodes.push(Node4::EMPTY);
                    work.push((c, idx, depth + 1));
                    idx as u32
                };
            }
            self.nodes[n4] = node;
        }
        self.stack_size = 3 * max_depth + 1;
    }

    /// Packs the primitives of one binary leaf into leaf blocks of four; returns its child
    /// reference.
    fn add_leaf(&mut self, node: &obvhs::bvh2::node::Bvh2Node, shapes: &[Shape]) -> u32 {
        let first_block = self.leaves.len() as u32;
        let slots: Vec<u32> = (node.first_index..node.first_index + node.prim_count).collect();
        let chunks: Vec<&[u32]> = slots.chunks(4).collect();
        for (k, chunk) in chunks.iter().enumerate() {
            let mut block = Leaf4 {
                tri: Tri4::pack(&[]),
                slot: [0; 4],
                tri_mask: 0,
                analytic_mask: 0,
                more: k + 1 < chunks.len(),
            };
            let mut tris = [[Vec3::ZERO; 3]; 4];
            for (lane, &slot) in chunk.iter().enumerate() {
                block.slot[lane] = slot;
                match self.prims[slot as usize] {
                    Primitive::Triangle { shape, index } => {
                        tris[lane] = triangle_vertices(shapes, shape, index);
                        block.tri_mask |= 1 << lane;
                    }
                    _ => block.analytic_mask |= 1 << lane,
                }
            }
            block.tri = Tri4::pack(&tris);
            self.leaves.push(block);
        }
        LEAF | first_block
    }

    pub fn primitive_count(&self) -> usize {
        self.prims.len()
    }

    /// Test of the non-triangle primitive in `slot`: an analytic shape, or an instance (the
    /// ray carried into the group's space and traced through its hierarchy).
    #[inline(never)]
    fn test_analytic(
        &self,
        slot: u32,
        ray: &Ray,
        tmax: f32,
        shapes: &[Shape],
        any: bool,
    ) -> Option<InnerHit> {
        let ray = Ray { tmax, ..*ray };
        match self.prims[slot as usize] {
            Primitive::Analytic { shape } => {
                let t = shapes[shape as usize].geometry.intersect(&ray)?;
                Some(Hit {
                    prim: slot,
                    t,
                    b1: 0.0,
                    b2: 0.0,
                    instance: NO_INSTANCE,
                })
            }
            Primitive::Instance { instance } => {
                let inst = &self.instances[instance as usize];
                let local = inst.local_ray(&ray);
                let hit = self.groups[inst.group as usize]
                    .accel
                    .run(&local, shapes, any)?;
                Some(Hit { instance, ..hit })
            }
            Primitive::Triangle { .. } => None,
        }
    }

    /// Tests the analytic primitives and instances of one leaf block (lanes `mask` of
    /// `slot`), the least hit in the order of [`precedes`] into `best`. Returns the new bound
    /// and whether an occlusion query is answered.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn test_analytic_lanes(
        &self,
        mut mask: u32,
        slot: &[u32],
        ray: &Ray,
        shapes: &[Shape],
        mut tmax: f32,
        best: &mut Option<Hit>,
        any: bool,
    ) -> (f32, bool) {
        while mask != 0 {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            if let Some(hit) = self.test_analytic(slot[lane], ray, tmax, shapes, any) {
                if any {
                    *best = Some(hit);
                    return (tmax, true);
                }
                if precedes(hit.t, hit.instance, hit.prim, best) {
                    tmax = bound_after(hit.t);
                    *best = Some(hit);
                }
            }
        }
        (tmax, false)
    }

    /// Tests the leaf blocks starting at `first`; updates `best` and returns the new tmax.
    /// With `any`, returns at the first block with a hit (occlusion).
    #[inline(always)]
    fn test_leaf(
        &self,
        first: usize,
        ctx: &LeafContext,
        mut tmax: f32,
        best: &mut Option<Hit>,
        any: bool,
    ) -> f32 {
        let mut k = first;
        loop {
            let block = &self.leaves[k];
            if block.tri_mask != 0 {
                let (mask, t, b1, b2) =
                    intersect_triangle4(&ctx.shear, &block.tri, tmax, block.tri_mask);
                let (t, b1, b2) = (t.to_array(), b1.to_array(), b2.to_array());
                let done;
                (tmax, done) =
                    record_triangle_hits(mask, &t, &b1, &b2, &block.slot, tmax, best, any);
                if done {
                    return tmax;
                }
            }
            let done;
            (tmax, done) = self.test_analytic_lanes(
                block.analytic_mask,
                &block.slot,
                ctx.ray,
                ctx.shapes,
                tmax,
                best,
                any,
            );
            if done {
                return tmax;
            }
            if !block.more {
                return tmax;
            }
            k += 1;
        }
    }

    /// Walks the tree with the stack `stack` (entries: child reference, entry distance), of
    /// at least `self.stack_size` entries. Entries below the stack pointer are always written
    /// before they are read, so the stack needs no initialisation (zeroing 1 KiB per ray was
    /// 4% of all instructions).
    fn traverse(
        &self,
        ray: &Ray,
        shapes: &[Shape],
        any: bool,
        stack: &mut [MaybeUninit<(u32, f32)>],
    ) -> Option<Hit> {
        let ctx = LeafContext {
            shear: RayShear4::new(ray.o, ray.d),
            ray,
            shapes,
        };
        let boxes = BoxRay::new(ray);
        let mut tmax = ray.tmax;
        let mut best = None;
        let mut sp = 0;
        stack[0] = MaybeUninit::new((self.root, 0.0));
        sp += 1;
        while sp > 0 {
            sp -= 1;
            // SAFETY: entries 0..sp were written by the pushes below (or the root above).
            let (mut node, t_enter) = unsafe { stack[sp].assume_init() };
            if t_enter > tmax {
                continue;
            }
            // Descend through inner nodes, nearest child first.
            while node & LEAF == 0 {
                let n = &self.nodes[node as usize];
                #[cfg(test)]
                count_node_visit();
                let (mask, t_near) = boxes.test(n, tmax);
                if mask == 0 {
                    node = EMPTY;
                    break;
                }
                if mask & (mask - 1) == 0 {
                    // One child entered: descend without touching the stack.
                    node = n.child[mask.trailing_zeros() as usize];
                    continue;
                }
                node = push_entered(mask, &t_near.to_array(), &n.child, stack, &mut sp);
            }
            if node == EMPTY {
                continue;
            }
            tmax = self.test_leaf((node & !LEAF) as usize, &ctx, tmax, &mut best, any);
            if any && best.is_some() {
                return best;
            }
        }
        best
    }

    /// Traces `ray` with a stack of the size this hierarchy needs: on the thread's stack
    /// when it fits in [`STACK`] entries, else on the heap (degenerate trees).
    #[inline]
    fn run(&self, ray: &Ray, shapes: &[Shape], any: bool) -> Option<Hit> {
        let size = self.stack_entries();
        if size <= STACK {
            let mut stack = [MaybeUninit::uninit(); STACK];
            self.walk(ray, shapes, any, &mut stack)
        } else {
            let mut stack = vec![MaybeUninit::uninit(); size];
            self.walk(ray, shapes, any, &mut stack)
        }
    }

    /// The traversal of this hierarchy's layout.
    #[inline(always)]
    fn walk(
        &self,
        ray: &Ray,
        shapes: &[Shape],
        any: bool,
        stack: &mut [MaybeUninit<(u32, f32)>],
    ) -> Option<Hit> {
        #[cfg(target_arch = "x86_64")]
        if let Some(wide) = &self.wide8 {
            if wide.is_empty() {
                return None;
            }
            // SAFETY: a `Wide8` is only built where `wide8::supported()` found AVX2.
            return unsafe { self.traverse8(wide, ray, shapes, any, stack) };
        }
        if self.root == EMPTY {
            return None;
        }
        self.traverse(ray, shapes, any, stack)
    }

    /// The closest hits of the rays of the lanes `mask` (bit i: `rays[i]`), into `out[i]`
    /// (other entries untouched): [`Accel::intersect`] for each, with the layout chosen and
    /// the stack set up once for all of them (the lane engine's rays).
    pub fn intersect_lanes(
        &self,
        rays: &[Ray],
        mask: u32,
        shapes: &[Shape],
        out: &mut [Option<Hit>],
    ) {
        self.run_lanes(rays, mask, shapes, false, |i, hit| out[i] = hit);
    }

    /// The lanes of `mask` whose rays are occluded: [`Accel::occluded`] for each ray
    /// `rays[i]`, bit i, set up once for all of them.
    pub fn occluded_lanes(&self, rays: &[Ray], mask: u32, shapes: &[Shape]) -> u32 {
        let mut occluded = 0u32;
        self.run_lanes(rays, mask, shapes, true, |i, hit| {
            occluded |= (hit.is_some() as u32) << i
        });
        occluded
    }

    #[inline(always)]
    fn run_lanes(
        &self,
        rays: &[Ray],
        mask: u32,
        shapes: &[Shape],
        any: bool,
        mut out: impl FnMut(usize, Option<Hit>),
    ) {
        let size = self.stack_entries();
        let mut fixed = [MaybeUninit::uninit(); STACK];
        let mut heap = Vec::new();
        let stack: &mut [MaybeUninit<(u32, f32)>] = if size <= STACK {
            &mut fixed
        } else {
            heap.resize(size, MaybeUninit::uninit());
            &mut heap
        };
        #[cfg(target_arch = "x86_64")]
        if let Some(wide) = self.wide8.as_ref().filter(|w| !w.is_empty()) {
            // SAFETY: a `Wide8` is only built where `wide8::supported()` found AVX2.
            unsafe { self.traverse8_lanes(wide, rays, mask, shapes, any, stack, &mut out) };
            return;
        }
        for i in lanes_of(mask) {
            out(i, self.walk(&rays[i], shapes, any, stack));
        }
    }

    /// The closest hit with 0 < t < ray.tmax.
    pub fn intersect(&self, ray: &Ray, shapes: &[Shape]) -> Option<Hit> {
        self.run(ray, shapes, false)
    }

    /// True if anything lies on the ray with 0 < t < ray.tmax.
    pub fn occluded(&self, ray: &Ray, shapes: &[Shape]) -> bool {
        self.run(ray, shapes, true).is_some()
    }

    /// The mesh and triangle of a hit outside any instance (`None` for analytic shapes and
    /// instances): what the lane engine's mesh interaction kernel takes.
    #[inline]
    pub fn mesh_triangle(&self, hit: &Hit) -> Option<(u32, u32)> {
        if hit.instance != NO_INSTANCE {
            return None;
        }
        match self.prims[hit.prim as usize] {
            Primitive::Triangle { shape, index } => Some((shape, index)),
            _ => None,
        }
    }

    /// The surface interaction of a hit found by [`Accel::intersect`] on `ray`.
    pub fn interaction(&self, hit: &Hit, ray: &Ray, shapes: &[Shape]) -> SurfaceInteraction {
        if hit.instance != NO_INSTANCE {
            let inst = &self.instances[hit.instance as usize];
            let local_ray = inst.local_ray(ray);
            let local_hit = Hit {
                instance: NO_INSTANCE,
                ..*hit
            };
            let si = self.groups[inst.group as usize]
                .accel
                .interaction(&local_hit, &local_ray, shapes);
            return instance_to_world(&si, inst);
        }
        match self.prims[hit.prim as usize] {
            Primitive::Triangle { shape, index, .. } => match &shapes[shape as usize].geometry {
                ShapeGeometry::Mesh(m) => {
                    m.interaction(index as usize, hit.t, hit.b1, hit.b2, shape)
                }
                _ => unreachable!("triangle primitive of a non-mesh shape"),
            },
            Primitive::Analytic { shape } => shapes[shape as usize]
                .geometry
                .interaction(ray, hit.t, shape),
            Primitive::Instance { .. } => unreachable!("instance hits carry their instance"),
        }
    }
}

/// A surface interaction in an instance's group space carried to world space, as Mitsuba's
/// `instance` does: points and tangents by the transform, normals by its inverse transpose,
/// the shading frame rebuilt from the world normal and dp/du. The point's error bound is the
/// local bound through |M| plus the final rounding (the transform itself is applied in f64).
fn instance_to_world(si: &SurfaceInteraction, inst: &Instance) -> SurfaceInteraction {
    let m = inst.to_world;
    let lin = DMat3::from_mat4(m);
    let normal_m = DMat3::from_mat4(inst.to_local).transpose();
    let p = m.transform_point3(si.p.as_dvec3());
    let abs = DMat3::from_cols(lin.x_axis.abs(), lin.y_axis.abs(), lin.z_axis.abs());
    let p_error = abs * si.p_error.as_dvec3() + p.abs() * (2.0 * f32::EPSILON as f64);
    let n = |v: Vec3| (normal_m * v.as_dvec3()).normalize_or_zero().as_vec3();
    let ns = n(si.frame.n);
    let dp_du = (lin * si.dp_du.as_dvec3()).as_vec3();
    SurfaceInteraction {
        p: p.as_vec3(),
        p_error: p_error.as_vec3(),
        t: si.t,
        ng: n(si.ng),
        frame: crate::geometry::Frame::from_normal_tangent(ns, dp_du),
        uv: si.uv,
        dp_du,
        dp_dv: (lin * si.dp_dv.as_dvec3()).as_vec3(),
        shape: si.shape,
        prim: si.prim,
        bary: si.bary,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shape::mesh::{intersect_triangle, RayShear};
    use crate::shape::{Mesh, Sphere};
    use glam::DVec3;
    use rand::{RngExt, SeedableRng};

    /// The padding is relative: a box grows by 4 ε times its largest coordinate magnitude on
    /// every side (a few ulps), so it still holds its points after rounding but stays tight;
    /// an absolute or much larger pad would cost traversal time without changing any hit.
    #[test]
    fn padding_is_a_few_ulps_of_the_largest_coordinate() {
        let b = padded([Vec3::new(1.0, -2.0, 3.0), Vec3::new(-1.0, 0.5, 5.0)]);
        // max |coordinate| per axis: 1, 2, 5
        let pad = Vec3::new(1.0, 2.0, 5.0) * (4.0 * f32::EPSILON);
        assert_eq!(Vec3::from(b.min), Vec3::new(-1.0, -2.0, 3.0) - pad);
        assert_eq!(Vec3::from(b.max), Vec3::new(1.0, 0.5, 5.0) + pad);
        let far = padded([Vec3::splat(1000.0), Vec3::splat(1000.5)]);
        assert!(far.min.x < 1000.0 && far.min.x > 1000.0 - 1e-3);
        assert!(far.max.x > 1000.5 && far.max.x < 1000.5 + 1e-3);
    }

    /// Brute force over every primitive: the closest t and whether anything is hit.
    fn brute_force(shapes: &[Shape], ray: &Ray) -> Option<f32> {
        let shear = RayShear::new(ray.o, ray.d);
        let mut best: Option<f32> = None;
        for shape in shapes {
            let t = match &shape.geometry {
                ShapeGeometry::Mesh(m) => (0..m.triangles.len())
                    .filter_map(|i| intersect_triangle(&shear, &m.vertices(i), ray.tmax))
                    .map(|h| h.0)
                    .min_by(f32::total_cmp),
                g => g.intersect(ray),
            };
            if let Some(t) = t {
                best = Some(best.map_or(t, |b: f32| b.min(t)));
            }
        }
        best
    }

    /// Brute force in the canonical order: the least (t, slot) over every primitive slot of
    /// `accel` (triangles and analytic shapes).
    fn brute_force_canonical(accel: &Accel, shapes: &[Shape], ray: &Ray) -> Option<(f32, u32)> {
        let shear = RayShear::new(ray.o, ray.d);
        let mut best: Option<(f32, u32)> = None;
        for (slot, prim) in accel.prims.iter().enumerate() {
            let t = match *prim {
                Primitive::Triangle { shape, index } => match &shapes[shape as usize].geometry {
                    ShapeGeometry::Mesh(m) => {
                        intersect_triangle(&shear, &m.vertices(index as usize), ray.tmax)
                            .map(|h| h.0)
                    }
                    _ => None,
                },
                Primitive::Analytic { shape } => shapes[shape as usize].geometry.intersect(ray),
                Primitive::Instance { .. } => None,
            };
            if let Some(t) = t {
                let key = (t, slot as u32);
                if best.is_none_or(|b| key < b) {
                    best = Some(key);
                }
            }
        }
        best
    }

    /// Coplanar, overlapping triangles hit at exactly the same t: the closest hit is the
    /// least (t, primitive slot), whichever order the triangles were inserted in and
    /// whichever order the traversal visits their leaves. Scenes: two triangles of one plane,
    /// one a shifted copy of the other, inserted in both orders; 24 identical triangles
    /// (three 8-wide leaf blocks, equal boxes: the visit order is the traversal's alone); 24
    /// triangles of one plane at random offsets (ties where their t rounds alike), with a
    /// sphere touching the plane. Both layouts.
    #[test]
    fn ties_resolve_by_primitive_slot() {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(42);
        let tri = |c: Vec3| {
            [
                c + Vec3::new(-1.0, -1.0, 0.0),
                c + Vec3::new(1.5, -1.0, 0.0),
                c + Vec3::new(-1.0, 1.5, 0.0),
            ]
        };
        let mesh = |tris: Vec<[Vec3; 3]>| {
            let n = tris.len() as u32;
            shape(ShapeGeometry::Mesh(Mesh::new(
                tris.concat(),
                None,
                None,
                (0..n).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect(),
                false,
            )))
        };
        let (a, b) = (tri(Vec3::new(0.0, 0.0, 1.0)), tri(Vec3::new(0.3, 0.2, 1.0)));
        let scattered: Vec<[Vec3; 3]> = (0..24)
            .map(|_| {
                tri(Vec3::new(
                    rng.random_range(-0.5..0.5),
                    rng.random_range(-0.5..0.5),
                    1.0,
                ))
            })
            .collect();
        let scenes = [
            vec![mesh(vec![a, b])],
            vec![mesh(vec![b, a])],
            vec![mesh(vec![a]), mesh(vec![b])],
            vec![mesh(vec![b]), mesh(vec![a])],
            vec![mesh(vec![a; 24])],
            vec![
                mesh(scattered),
                shape(ShapeGeometry::Sphere(Sphere::new(
                    DVec3::new(0.0, 0.0, 1.5),
                    0.5,
                    false,
                ))),
            ],
        ];
        for layout in [Layout::Wide4, Layout::Wide8] {
            for (k, shapes) in scenes.iter().enumerate() {
                let accel = Accel::build_with_layout(shapes, layout);
                let mut ties = 0;
                for i in 0..4000 {
                    let o = Vec3::new(
                        rng.random_range(-3.0..3.0),
                        rng.random_range(-3.0..3.0),
                        rng.random_range(-3.0..0.0),
                    );
                    let target = Vec3::new(
                        rng.random_range(-0.6..0.6),
                        rng.random_range(-0.6..0.6),
                        1.0,
                    );
                    let ray = Ray::new(o, target - o, f32::INFINITY);
                    let want = brute_force_canonical(&accel, shapes, &ray);
                    let got = accel.intersect(&ray, shapes).map(|h| (h.t, h.prim));
                    assert_eq!(got, want, "{layout:?} scene {k} ray {i}");
                    // rays with a second primitive at exactly the closest t
                    let shear = RayShear::new(ray.o, ray.d);
                    let at_best = accel
                        .prims
                        .iter()
                        .filter(|p| match **p {
                            Primitive::Triangle { shape, index } => {
                                match &shapes[shape as usize].geometry {
                                    ShapeGeometry::Mesh(m) => intersect_triangle(
                                        &shear,
                                        &m.vertices(index as usize),
                                        ray.tmax,
                                    )
                                    .is_some_and(|h| Some(h.0) == want.map(|w| w.0)),
                                    _ => false,
                                }
                            }
                            _ => false,
                        })
                        .count();
                    ties += (at_best > 1) as u32;
                }
                assert!(
                    ties > 100,
                    "{layout:?} scene {k}: only {ties} rays with a tie"
                );
            }
        }
    }

    /// The lane engine's queries (`intersect_lanes`, `occluded_lanes`) answer every lane of
    /// their mask as `intersect` and `occluded` answer its ray alone, and leave the other
    /// lanes alone: 16 rays at a time with random masks (empty and full among them), rays of
    /// random length, on 60 random triangles and a sphere, and on an empty scene, in both
    /// layouts.
    #[test]
    fn lane_queries_answer_as_single_rays() {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(7);
        let v = |rng: &mut rand_pcg::Pcg32, r: f32| {
            Vec3::new(
                rng.random_range(-r..r),
                rng.random_range(-r..r),
                rng.random_range(-r..r),
            )
        };
        let tris: Vec<Vec3> = (0..60)
            .flat_map(|_| {
                let c = v(&mut rng, 1.0);
                [
                    c + 0.3 * v(&mut rng, 1.0),
                    c + 0.3 * v(&mut rng, 1.0),
                    c + 0.3 * v(&mut rng, 1.0),
                ]
            })
            .collect();
        let shapes = [
            shape(ShapeGeometry::Mesh(Mesh::new(
                tris,
                None,
                None,
                (0..60).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect(),
                false,
            ))),
            shape(ShapeGeometry::Sphere(Sphere::new(
                DVec3::new(0.2, -0.1, 0.3),
                0.4,
                false,
            ))),
        ];
        let key = |h: &Option<Hit>| h.map(|h| (h.prim, h.t, h.b1, h.b2, h.instance));
        let sentinel = Some(Hit {
            prim: 99_999,
            t: -1.0,
            b1: 0.0,
            b2: 0.0,
            instance: 0,
        });
        let (mut hits, mut occluded) = (0, 0);
        for layout in [Layout::Wide4, Layout::Wide8] {
            for scene in [&shapes[..], &[]] {
                let accel = Accel::build_with_layout(scene, layout);
                for batch in 0..200 {
                    let rays: Vec<Ray> = (0..16)
                        .map(|_| {
                            let o = v(&mut rng, 2.0);
                            let tmax = if rng.random::<f32>() < 0.5 {
                                f32::INFINITY
                            } else {
                                rng.random_range(0.1..3.0)
                            };
                            Ray::new(o, v(&mut rng, 0.8) - o, tmax)
                        })
                        .collect();
                    let mask = match batch {
                        0 => 0,
                        1 => 0xffff,
                        _ => rng.random::<u32>() & 0xffff,
                    };
                    let mut out = [sentinel; 16];
                    accel.intersect_lanes(&rays, mask, scene, &mut out);
                    let bits = accel.occluded_lanes(&rays, mask, scene);
                    for (i, ray) in rays.iter().enumerate() {
                        let on = mask >> i & 1 == 1;
                        let want = if on {
                            key(&accel.intersect(ray, scene))
                        } else {
                            key(&sentinel)
                        };
                        assert_eq!(key(&out[i]), want, "{layout:?} batch {batch} lane {i}");
                        let want = on && accel.occluded(ray, scene);
                        assert_eq!(
                            bits >> i & 1 == 1,
                            want,
                            "{layout:?} batch {batch} lane {i}"
                        );
                        hits += (on && out[i].is_some()) as u32;
                        occluded += want as u32;
                    }
                    assert_eq!(bits & !mask, 0);
                }
            }
        }
        // The rays do hit, and not all of them.
        assert!(
            hits > 1000 && occluded > 1000 && hits < 2 * 200 * 16,
            "{hits} {occluded}"
        );
    }

    fn shape(geometry: ShapeGeometry) -> Shape {
        Shape {
            geometry,
            material: 0,
            emitter: None,
            interior: None,
            exterior: None,
        }
    }

    /// Rotated instances of a unit cube: their world bounds come from all eight transformed
    /// corners of the group's box, so rays aimed at points all over the cubes' surfaces (the
    /// corners that end up outermost included) hit exactly where brute force in the group's
    /// space does, in both layouts.
    #[test]
    fn rotated_instance_bounds_hold_the_whole_group() {
        let corners: Vec<Vec3> = (0..8)
            .map(|k| Vec3::new((k & 1) as f32, ((k >> 1) & 1) as f32, ((k >> 2) & 1) as f32))
            .collect();
        // Two triangles per face (vertex k has coordinates from the bits of k).
        let faces = [
            [0, 1, 3, 2],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 3, 7, 6],
            [0, 2, 6, 4],
            [1, 3, 7, 5],
        ];
        let triangles = faces
            .iter()
            .flat_map(|f| [[f[0], f[1], f[2]], [f[0], f[2], f[3]]])
            .collect();
        let cube = Mesh::new(corners, None, None, triangles, false);
        let shapes = vec![shape(ShapeGeometry::Mesh(cube))];
        let mut rng = rand_pcg::Pcg32::seed_from_u64(5);
        // Rotations by random unit quaternions: each corner is outermost along some axis in
        // some of them.
        let rotations: Vec<DMat4> = (0..8)
            .map(|_| {
                let q = glam::DQuat::from_xyzw(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                DMat4::from_quat(q.normalize())
            })
            .collect();
        // Sixteen instances on a grid, so that the top-level tree has inner nodes whose
        // boxes are the instances' bounds.
        let placements: Vec<DMat4> = (0..16)
            .map(|i| {
                let offset = DVec3::new((i % 4) as f64 * 3.0, (i / 4) as f64 * 3.0, 0.0);
                DMat4::from_translation(offset) * rotations[i % 8]
            })
            .collect();
        let instances: Vec<Instance> = placements
            .iter()
            .map(|&m| Instance::new(0, m).expect("invertible"))
            .collect();
        for layout in [Layout::Wide4, Layout::Wide8] {
            let group = Group {
                accel: Accel::build_in_layout(
                    &shapes,
                    0..1,
                    vec![],
                    vec![],
                    layout,
                    layout.block_width(),
                ),
            };
            let accel = Accel::build_in_layout(
                &shapes,
                1..1,
                instances.clone(),
                vec![group],
                layout,
                layout.block_width(),
            );
            let mut hits = 0;
            for i in 0..20000 {
                // A point on a random face of a random instance, in world space.
                let to_world = placements[rng.random_range(0..16usize)];
                let (axis, side) = (rng.random_range(0..3usize), rng.random_range(0..2) as f64);
                let mut q = DVec3::new(rng.random(), rng.random(), rng.random());
                q[axis] = side;
                let target = to_world.transform_point3(q).as_vec3();
                let dir = Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                let ray = Ray::new(target + dir * 4.0, -dir, f32::INFINITY);
                let expected = instances
                    .iter()
                    .filter_map(|inst| brute_force(&shapes, &inst.local_ray(&ray)))
                    .min_by(f32::total_cmp);
                let got = accel.intersect(&ray, &shapes).map(|h| h.t);
                assert_eq!(expected, got, "{layout:?} ray {i}");
                hits += expected.is_some() as u32;
            }
            assert!(hits > 15000, "{layout:?}: {hits} hits");
        }
    }

    /// A point with coordinates uniform in [−s, s).
    fn v3(rng: &mut rand_pcg::Pcg32, s: f32) -> Vec3 {
        Vec3::new(
            rng.random_range(-s..s),
            rng.random_range(-s..s),
            rng.random_range(-s..s),
        )
    }

    /// Leaf blocks followed by another block of the same leaf, in either layout.
    fn chained_blocks(accel: &Accel) -> usize {
        #[cfg(target_arch = "x86_64")]
        if let Some(w) = &accel.wide8 {
            return w.chained_blocks();
        }
        accel.leaves.iter().filter(|b| b.more).count()
    }

    /// Leaf blocks, in either layout.
    fn leaf_blocks(accel: &Accel) -> usize {
        #[cfg(target_arch = "x86_64")]
        if let Some(w) = &accel.wide8 {
            return w.leaf_blocks();
        }
        accel.leaves.len()
    }

    /// Runs `body` on a thread of its own and fails if it has not returned within `secs`
    /// seconds (an endless loop in the traversal), or with the thread's own panic.
    fn within_seconds(secs: u64, body: impl FnOnce() + Send + 'static) {
        use std::sync::mpsc::{channel, RecvTimeoutError};
        let (tx, rx) = channel();
        let worker = std::thread::spawn(move || {
            body();
            let _ = tx.send(());
        });
        match rx.recv_timeout(Duration::from_secs(secs)) {
            Err(RecvTimeoutError::Timeout) => {
                panic!("the traversal did not return within {secs} s (an endless loop?)")
            }
            Ok(()) | Err(RecvTimeoutError::Disconnected) => {
                if let Err(e) = worker.join() {
                    std::panic::resume_unwind(e);
                }
            }
        }
    }

    /// Leaves of up to 32 primitives (the builder's limit raised above the block width, as
    /// obvhs's default of 8 would do for the 4-wide layout, or another obvhs release might):
    /// each such leaf spans several leaf blocks chained by `more`, and the traversal must
    /// test every block of the chain and stop after its last. Two stacks of 32 parallel
    /// triangles in shuffled order (each one leaf) and a soup of 600 triangles, against
    /// brute force, in both layouts.
    /// The work runs on a thread of its own and the test fails if it has not returned in 60 s
    /// (it takes well under one): a chain walked without advancing never ends.
    #[test]
    fn leaves_of_several_blocks_are_tested_block_by_block() {
        within_seconds(60, || {
            let mut rng = rand_pcg::Pcg32::seed_from_u64(44);
            // Two stacks of 32 (obvhs collapses nothing in a tree of at most 2 · 32 + 1
            // nodes), 5 apart, their layers 0.001 apart: splitting a stack shrinks no box
            // enough to pay for a node, so each becomes one leaf.
            let mut order: Vec<u32> = (0..64).collect();
            for i in (1..order.len()).rev() {
                order.swap(i, rng.random_range(0..=i));
            }
            let stack: Vec<Vec3> = order
                .iter()
                .flat_map(|&i| {
                    let (x, z) = (5.0 * (i / 32) as f32, 0.001 * (i % 32) as f32);
                    [
                        Vec3::new(x, 0.0, z),
                        Vec3::new(x + 1.0, 0.0, z),
                        Vec3::new(x, 1.0, z),
                    ]
                })
                .collect();
            let stack = Mesh::new(
                stack,
                None,
                None,
                (0..64u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect(),
                false,
            );
            let mut soup = Vec::new();
            for _ in 0..600 {
                let c = v3(&mut rng, 2.0);
                soup.extend([
                    c + v3(&mut rng, 0.3),
                    c + v3(&mut rng, 0.3),
                    c + v3(&mut rng, 0.3),
                ]);
            }
            let soup = Mesh::new(
                soup,
                None,
                None,
                (0..600u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect(),
                false,
            );
            let scenes = [
                vec![shape(ShapeGeometry::Mesh(stack))],
                vec![shape(ShapeGeometry::Mesh(soup))],
            ];
            for layout in [Layout::Wide4, Layout::Wide8] {
                let layout = if layout == Layout::Wide8 {
                    Layout::best()
                } else {
                    layout
                };
                // The default build makes leaves of one block each (the builder's limit is
                // the block width), filled more than half on average: the 64 triangles take
                // 17 blocks of 4 or 9 of 8 (2026-12-02).
                let width = match layout {
                    Layout::Wide4 => 4,
                    Layout::Wide8 => 8,
                };
                let accel = Accel::build_with_layout(&scenes[0], layout);
                let blocks = leaf_blocks(&accel);
                assert_eq!(
                    chained_blocks(&accel),
                    0,
                    "{layout:?}: a leaf of several blocks"
                );
                assert!(
                    blocks <= 2 * 64 / width,
                    "{layout:?}: {blocks} leaf blocks for 64 triangles"
                );
                for (k, shapes) in scenes.iter().enumerate() {
                    let range = 0..shapes.len();
                    let accel = Accel::build_in_layout(shapes, range, vec![], vec![], layout, 32);
                    if k == 0 {
                        assert!(
                            chained_blocks(&accel) == 2 * (32 / width - 1),
                            "{layout:?}: each stack of 32 must be one leaf of chained blocks"
                        );
                    }
                    let mut hits = 0;
                    for i in 0..5000 {
                        let target = if k == 0 {
                            // A point inside the stack's footprint, between its layers.
                            let a = rng.random_range(0.0..1.0);
                            let b = rng.random_range(0.0..1.0);
                            let (a, b): (f32, f32) = if a + b > 1.0 {
                                (1.0 - a, 1.0 - b)
                            } else {
                                (a, b)
                            };
                            let x = 5.0 * rng.random_range(0..2) as f32;
                            Vec3::new(x + a, b, rng.random_range(-0.005..0.036))
                        } else {
                            v3(&mut rng, 2.0)
                        };
                        let o = target + v3(&mut rng, 3.0);
                        let ray = Ray::new(o, target - o, f32::INFINITY);
                        let expected = brute_force(shapes, &ray);
                        let got = accel.intersect(&ray, shapes).map(|h| h.t);
                        assert_eq!(expected, got, "{layout:?} scene {k} ray {i}");
                        assert_eq!(expected.is_some(), accel.occluded(&ray, shapes));
                        hits += expected.is_some() as u32;
                    }
                    assert!(hits > 1000, "{layout:?} scene {k}: {hits} hits");
                }
            }
        });
    }

    /// Box culling, counted: rays that pass a mesh at a distance (their closest approach to
    /// the centre of its unit-cube bounds is at least 1, beyond the cube's half-diagonal
    /// 0.87) test the root's children and enter none: exactly one node visit per query, in
    /// both layouts. A slab test that stopped culling boxes the ray passes ahead of it (the
    /// far distance widened by 2/γ(3) instead of 2γ(3)) would keep every hit and image, and
    /// only this count sees it.
    #[test]
    fn rays_that_pass_a_mesh_visit_only_the_root() {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(45);
        let mut positions = Vec::new();
        for _ in 0..500 {
            let c = (v3(&mut rng, 0.5) + 0.5) * 0.9 + Vec3::splat(0.05);
            positions.extend([
                c + ((v3(&mut rng, 0.5) + 0.5) - 0.5) * 0.1,
                c + ((v3(&mut rng, 0.5) + 0.5) - 0.5) * 0.1,
                c + ((v3(&mut rng, 0.5) + 0.5) - 0.5) * 0.1,
            ]);
        }
        let mesh = Mesh::new(
            positions,
            None,
            None,
            (0..500u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect(),
            false,
        );
        let shapes = vec![shape(ShapeGeometry::Mesh(mesh))];
        let centre = Vec3::splat(0.5);
        for layout in [Layout::Wide4, Layout::Wide8] {
            let accel = Accel::build_with_layout(&shapes, layout);
            NODE_VISITS.with(|c| c.set(0));
            let rays = 2000;
            for i in 0..rays {
                let d = ((v3(&mut rng, 0.5) + 0.5) - 0.5).normalize();
                // An offset perpendicular to d, of length 1 to 2.
                let u = d.any_orthonormal_vector();
                let w = d.cross(u);
                let phi = rng.random_range(0.0..std::f32::consts::TAU);
                let off = (u * phi.cos() + w * phi.sin()) * rng.random_range(1.0..2.0);
                let o = centre + off - 4.0 * d;
                let ray = Ray::new(o, d, f32::INFINITY);
                assert!(
                    accel.intersect(&ray, &shapes).is_none(),
                    "{layout:?} ray {i}"
                );
                assert!(!accel.occluded(&ray, &shapes), "{layout:?} ray {i}");
            }
            let visits = NODE_VISITS.with(|c| c.get());
            assert_eq!(
                visits,
                2 * rays,
                "{layout:?}: {visits} node visits for {rays} rays, each traced twice"
            );
        }
    }

    /// Rays from far away (|o| ≈ 1e4) aimed at points on small flat triangles near the
    /// origin: the boxes are a few ulps thick, and the slab test's distances carry an error of
    /// about ε |o| / |d|, far above the boxes' padding; only the far distance's widening by
    /// 1 + 2γ(3) keeps the boxes the rays hit from being culled. Both layouts must find
    /// every hit brute force finds.
    #[test]
    fn far_rays_hit_thin_boxes() {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(3);
        let mut positions = Vec::new();
        // One triangle per cell of an 8 × 8 grid, so that none overlap: of two coplanar
        // triangles the BVH may keep either hit (their distances differ in the last ulp,
        // within the slab test's rounding of entry distances).
        for cell in 0..64 {
            let c = Vec3::new((cell % 8) as f32 - 3.5, (cell / 8) as f32 - 3.5, 0.0) * 0.25;
            let mut corner = || {
                c + Vec3::new(
                    rng.random_range(-0.1..0.1),
                    rng.random_range(-0.1..0.1),
                    0.0,
                )
            };
            positions.extend([corner(), corner(), corner()]);
        }
        let flat = Mesh::new(
            positions.clone(),
            None,
            None,
            (0..64u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect(),
            false,
        );
        let shapes = vec![shape(ShapeGeometry::Mesh(flat))];
        for layout in [Layout::Wide4, Layout::Wide8] {
            let accel = Accel::build_with_layout(&shapes, layout);
            assert!(accel.layout() == layout || Layout::best() == Layout::Wide4);
            let mut hits = 0;
            for i in 0..20000 {
                // A point inside a random triangle, seen from a random far origin.
                let k = rng.random_range(0..64usize);
                let (b1, b2): (f32, f32) = (rng.random_range(0.0..1.0), rng.random_range(0.0..1.0));
                let (b1, b2) = if b1 + b2 > 1.0 {
                    (1.0 - b1, 1.0 - b2)
                } else {
                    (b1, b2)
                };
                let p = positions[3 * k] * (1.0 - b1 - b2)
                    + positions[3 * k + 1] * b1
                    + positions[3 * k + 2] * b2;
                let o = Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(0.2..1.0),
                )
                .normalize()
                    * 1e4;
                let ray = Ray::new(o, p - o, f32::INFINITY);
                let expected = brute_force(&shapes, &ray);
                let got = accel.intersect(&ray, &shapes).map(|h| h.t);
                assert_eq!(expected, got, "{layout:?} ray {i}");
                assert_eq!(expected.is_some(), accel.occluded(&ray, &shapes));
                hits += expected.is_some() as u32;
            }
            assert!(hits > 15000, "{layout:?}: {hits} hits");
        }
    }

    /// Closest hits and occlusion from the 4-wide and the 8-wide BVH equal brute force
    /// exactly, on a soup of small and large (box-spanning) triangles with spheres, on a
    /// degenerate pile of identical triangles whose tree is deep enough for the
    /// heap-allocated stack, and on quads (two triangles with one box, merged into one leaf
    /// block); the two layouts' barycentrics agree bit for bit.
    #[test]
    fn wide_bvh_matches_brute_force() {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(8);
        let mut v3 = |s: f32| {
            Vec3::new(
                rng.random_range(-s..s),
                rng.random_range(-s..s),
                rng.random_range(-s..s),
            )
        };
        let mut positions = Vec::new();
        for i in 0..3000 {
            let c = v3(4.0);
            let size = if i % 50 == 0 { 4.0 } else { 0.3 };
            positions.extend([c + v3(size), c + v3(size), c + v3(size)]);
        }
        let triangles = (0..1000u32)
            .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
            .collect();
        let soup = Mesh::new(positions, None, None, triangles, false);
        let spheres: Vec<Shape> = (0..5)
            .map(|i| {
                shape(ShapeGeometry::Sphere(Sphere::new(
                    DVec3::new(i as f64 - 2.0, 0.5, -1.0),
                    0.4,
                    false,
                )))
            })
            .collect();
        let pile = Mesh::new(
            [
                Vec3::new(0.0, 0.0, 9.0),
                Vec3::new(1.0, 0.0, 9.0),
                Vec3::new(0.0, 1.0, 9.0),
            ]
            .repeat(4000),
            None,
            None,
            (0..4000u32)
                .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
                .collect(),
            false,
        );
        // Three stacked quads of two triangles each, axis-aligned as Mitsuba's rectangles
        // often are: obvhs leaves one triangle per leaf in so small a tree, and the 8-wide
        // layout merges each quad's two leaves (one box) into one leaf block.
        let mut quad_positions = Vec::new();
        for z in [-2.0, 0.0, 2.0] {
            let c = Vec3::new(0.5 * z, 0.0, z);
            let (u, v) = (Vec3::X * 4.0, Vec3::Y * 4.0);
            quad_positions.extend([c - u - v, c + u - v, c + u + v, c - u + v]);
        }
        let quads = Mesh::new(
            quad_positions,
            None,
            None,
            (0..3u32)
                .flat_map(|i| [[4 * i, 4 * i + 1, 4 * i + 2], [4 * i, 4 * i + 2, 4 * i + 3]])
                .collect(),
            false,
        );
        let mut scenes = vec![[vec![shape(ShapeGeometry::Mesh(soup))], spheres].concat()];
        scenes.push(vec![shape(ShapeGeometry::Mesh(pile))]);
        scenes.push(vec![shape(ShapeGeometry::Mesh(quads))]);
        for layout in [Layout::Wide4, Layout::Wide8] {
            for (k, shapes) in scenes.iter().enumerate() {
                let accel = Accel::build_with_layout(shapes, layout);
                assert!(accel.layout() == layout || Layout::best() == Layout::Wide4);
                let four = Accel::build_with_layout(shapes, Layout::Wide4);
                let mut hits = 0;
                for i in 0..20000 {
                    let o = v3(6.0);
                    let target = if k == 1 {
                        Vec3::new(0.3, 0.3, 9.0) + v3(0.5)
                    } else {
                        v3(4.0)
                    };
                    let tmax = if i % 4 == 0 { 3.0 } else { f32::INFINITY };
                    let ray = Ray::new(o, target - o, tmax);
                    let expected = brute_force(shapes, &ray);
                    let hit = accel.intersect(&ray, shapes);
                    assert_eq!(expected, hit.map(|h| h.t), "{layout:?} scene {k} ray {i}");
                    // The same barycentrics from both layouts, bit for bit.
                    let bary = |h: Option<Hit>| h.map(|h| (h.t, h.b1, h.b2));
                    assert_eq!(bary(four.intersect(&ray, shapes)), bary(hit));
                    assert_eq!(expected.is_some(), accel.occluded(&ray, shapes));
                    hits += expected.is_some() as u32;
                }
                assert!(hits > 2000, "{layout:?} scene {k}: {hits} hits");
                if k == 1 {
                    assert!(
                        accel.stack_entries() > STACK,
                        "the pile must need more than {STACK} stack entries, got {}",
                        accel.stack_entries()
                    );
                }
            }
        }
    }
}
