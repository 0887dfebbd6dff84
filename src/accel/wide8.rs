//! The 8-wide layout of [`Accel`], used on processors with AVX2 (detected at run time; the
//! 4-wide SSE layout is the fallback everywhere else). Each node holds the boxes of up to
//! eight children, tested against one ray in one 256-bit slab test, and each leaf block holds
//! up to eight triangles, tested at once by [`intersect_triangle8`] (the wider nodes of
//! Wald, Benthin and Boulos 2008 and Ernst and Greiner 2008, "Multi Bounding Volume
//! Hierarchies", at AVX width, as in Embree's BVH8). Halving the tree's depth and the number
//! of leaf blocks a ray tests is what pays: the traversal is throughput-bound (≈3.8
//! instructions per cycle), so every vector instruction that does eight lanes instead of
//! four is work saved.
//!
//! Every lane of [`intersect_triangle8`] performs the operations of the scalar watertight
//! test ([`crate::shape::mesh::intersect_triangle`]) in the same order, with no fused
//! multiply-add, so t and the barycentrics are bit-identical to the scalar and the 4-wide
//! tests; lanes where an edge function is exactly zero take the scalar test with its f64
//! fallback. The slab test widens far distances by 1 + 2γ(3), as the 4-wide one does. The
//! layouts differ only in the order in which they visit children, which decides which of two
//! hits at exactly the same distance is kept.

use super::{push_entered, record_triangle_hits, Accel, Hit, Primitive, EMPTY, LEAF};
use crate::geometry::{gamma, Ray};
use crate::shape::mesh::{intersect_triangle, RayShear};
use crate::shape::Shape;
use glam::Vec3;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::bvh2::Bvh2;
use std::arch::x86_64::*;
use std::mem::MaybeUninit;

/// Whether this processor runs the 8-wide layout.
pub fn supported() -> bool {
    is_x86_feature_detected!("avx2")
}

/// Eight f32 lanes in an AVX register. Its methods compile only into functions with AVX2
/// enabled (the traversal below), where each is one instruction.
#[derive(Clone, Copy)]
struct F8(__m256);

impl F8 {
    #[inline]
    #[target_feature(enable = "avx2")]
    fn splat(x: f32) -> F8 {
        F8(_mm256_set1_ps(x))
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    fn zero() -> F8 {
        F8(_mm256_setzero_ps())
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    fn load(a: &[f32; 8]) -> F8 {
        // SAFETY: `a` is eight readable f32s; the load needs no alignment.
        F8(unsafe { _mm256_loadu_ps(a.as_ptr()) })
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    fn to_array(self) -> [f32; 8] {
        let mut out = [0.0f32; 8];
        // SAFETY: `out` is eight writable f32s; the store needs no alignment.
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), self.0) };
        out
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    fn add(self, o: F8) -> F8 {
        F8(_mm256_add_ps(self.0, o.0))
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    fn sub(self, o: F8) -> F8 {
        F8(_mm256_sub_ps(self.0, o.0))
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    fn mul(self, o: F8) -> F8 {
        F8(_mm256_mul_ps(self.0, o.0))
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    fn div(self, o: F8) -> F8 {
        F8(_mm256_div_ps(self.0, o.0))
    }
    /// Lane-wise `if self < o { self } else { o }` (x86 `minps`, as glam's SSE `min`).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn min(self, o: F8) -> F8 {
        F8(_mm256_min_ps(self.0, o.0))
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    fn max(self, o: F8) -> F8 {
        F8(_mm256_max_ps(self.0, o.0))
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    fn abs(self) -> F8 {
        F8(_mm256_and_ps(
            self.0,
            _mm256_castsi256_ps(_mm256_set1_epi32(0x7fff_ffff)),
        ))
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    fn eq(self, o: F8) -> u32 {
        movemask(_mm256_cmp_ps::<_CMP_EQ_OQ>(self.0, o.0))
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    fn lt(self, o: F8) -> u32 {
        movemask(_mm256_cmp_ps::<_CMP_LT_OQ>(self.0, o.0))
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    fn le(self, o: F8) -> u32 {
        movemask(_mm256_cmp_ps::<_CMP_LE_OQ>(self.0, o.0))
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    fn gt(self, o: F8) -> u32 {
        movemask(_mm256_cmp_ps::<_CMP_GT_OQ>(self.0, o.0))
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    fn ge(self, o: F8) -> u32 {
        movemask(_mm256_cmp_ps::<_CMP_GE_OQ>(self.0, o.0))
    }
    /// Lanes that are neither infinite nor NaN.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn finite(self) -> u32 {
        self.abs().lt(F8::splat(f32::INFINITY))
    }
}

#[inline]
#[target_feature(enable = "avx2")]
fn movemask(m: __m256) -> u32 {
    _mm256_movemask_ps(m) as u32
}

/// An 8-wide node: per axis, the children's minima and maxima (lane = child); `valid` masks
/// the lanes that hold a child (empty lanes have an empty box as well).
#[derive(Clone, Copy)]
#[repr(C, align(32))]
struct Node8 {
    lo: [[f32; 8]; 3],
    hi: [[f32; 8]; 3],
    child: [u32; 8],
    valid: u32,
}

impl Node8 {
    const EMPTY: Node8 = Node8 {
        lo: [[f32::INFINITY; 8]; 3],
        hi: [[f32::NEG_INFINITY; 8]; 3],
        child: [EMPTY; 8],
        valid: 0,
    };
}

/// Up to eight primitives of one BVH leaf: triangles in structure-of-arrays form
/// (`v[k][axis][lane]`: coordinate `axis` of vertex `k`), spheres, disks and instances
/// tested one by one. `slot[lane]` is the primitive's index in `Accel::prims`.
#[derive(Clone, Copy)]
#[repr(C, align(32))]
struct Leaf8 {
    v: [[[f32; 8]; 3]; 3],
    slot: [u32; 8],
    tri_mask: u32,
    analytic_mask: u32,
    /// The next leaf block belongs to the same BVH leaf.
    more: bool,
}

impl Leaf8 {
    /// The triangle in `lane`.
    fn lane(&self, lane: usize) -> [Vec3; 3] {
        self.v
            .map(|vk| Vec3::new(vk[0][lane], vk[1][lane], vk[2][lane]))
    }
}

/// The 8-wide hierarchy: nodes, leaf blocks, the root's child reference and the stack depth
/// one traversal can need (7 entries per level plus one).
pub(super) struct Wide8 {
    nodes: Vec<Node8>,
    leaves: Vec<Leaf8>,
    root: u32,
    pub(super) stack_size: usize,
}

impl Wide8 {
    /// Collapses obvhs's binary BVH into 8-wide nodes: each node takes its two children and
    /// keeps opening the inner child of largest surface area until it has eight.
    pub(super) fn collapse(bvh: &Bvh2, prims: &[Primitive], shapes: &[Shape]) -> Wide8 {
        let mut wide = Wide8 {
            nodes: Vec::new(),
            leaves: Vec::new(),
            root: EMPTY,
            stack_size: 1,
        };
        let nodes = &bvh.nodes;
        if nodes.is_empty() {
            return wide;
        }
        // A subtree of at most eight primitives becomes one leaf block: testing its
        // triangles at once costs about as much as one node test, less than the nodes and
        // partly filled blocks it would otherwise become (obvhs's SAH prices each primitive
        // test separately and often leaves one triangle per leaf).
        let merge = merged_subtrees(nodes);
        let is_leaf = |c: usize| merge[c];
        if is_leaf(0) {
            wide.root = wide.add_leaf(&leaf_slots(nodes, 0), prims, shapes);
            return wide;
        }
        wide.nodes.push(Node8::EMPTY);
        wide.root = 0;
        let mut max_depth = 1;
        // (binary node, 8-wide node it becomes, depth)
        let mut work = vec![(0usize, 0usize, 1usize)];
        while let Some((b, n8, depth)) = work.pop() {
            max_depth = max_depth.max(depth);
            let mut node = Node8::EMPTY;
            for (lane, c) in super::open_children(nodes, b, 8, is_leaf)
                .into_iter()
                .enumerate()
            {
                let aabb = nodes[c].aabb;
                for a in 0..3 {
                    node.lo[a][lane] = aabb.min[a];
                    node.hi[a][lane] = aabb.max[a];
                }
                node.valid |= 1 << lane;
                node.child[lane] = if is_leaf(c) {
                    wide.add_leaf(&leaf_slots(nodes, c), prims, shapes)
                } else {
                    let idx = wide.nodes.len();
                    wide.nodes.push(Node8::EMPTY);
                    work.push((c, idx, depth + 1));
                    idx as u32
                };
            }
            wide.nodes[n8] = node;
        }
        wide.stack_size = 7 * max_depth + 1;
        wide
    }

    /// Packs the primitives `slots` of one leaf into leaf blocks of eight; returns its
    /// child reference.
    fn add_leaf(&mut self, slots: &[u32], prims: &[Primitive], shapes: &[Shape]) -> u32 {
        let first_block = self.leaves.len() as u32;
        let chunks: Vec<&[u32]> = slots.chunks(8).collect();
        for (k, chunk) in chunks.iter().enumerate() {
            let mut block = Leaf8 {
                v: [[[0.0; 8]; 3]; 3],
                slot: [0; 8],
                tri_mask: 0,
                analytic_mask: 0,
                more: k + 1 < chunks.len(),
            };
            for (lane, &slot) in chunk.iter().enumerate() {
                block.slot[lane] = slot;
                match prims[slot as usize] {
                    Primitive::Triangle { shape, index } => {
                        let tri = super::triangle_vertices(shapes, shape, index);
                        for (k, p) in tri.iter().enumerate() {
                            for axis in 0..3 {
                                block.v[k][axis][lane] = p[axis];
                            }
                        }
                        block.tri_mask |= 1 << lane;
                    }
                    _ => block.analytic_mask |= 1 << lane,
                }
            }
            self.leaves.push(block);
        }
        LEAF | first_block
    }

    pub(super) fn is_empty(&self) -> bool {
        self.root == EMPTY
    }

    /// Leaf blocks followed by another block of the same leaf (unit tests: whether a tree
    /// has leaves of more than eight primitives).
    #[cfg(test)]
    pub(super) fn chained_blocks(&self) -> usize {
        self.leaves.iter().filter(|b| b.more).count()
    }

    /// Leaf blocks (unit tests).
    #[cfg(test)]
    pub(super) fn leaf_blocks(&self) -> usize {
        self.leaves.len()
    }
}

/// Which nodes of a binary BVH become one leaf block: its leaves, and every inner node of at
/// most eight primitives whose children both do and whose box is no larger than the larger
/// child's (the two triangles of a quad, say): splitting such a node culls nothing, and
/// testing its triangles at once costs one block test instead of two. Merging more (every
/// subtree of up to eight primitives, or by a surface-area cost) made the Cornell box slower:
/// larger leaves are entered by more rays. Children before parents, without recursion
/// (degenerate input makes deep trees).
fn merged_subtrees(nodes: &[Bvh2Node]) -> Vec<bool> {
    let mut count = vec![0u32; nodes.len()];
    let mut merge = vec![false; nodes.len()];
    let mut order = Vec::with_capacity(nodes.len());
    let mut stack = vec![0usize];
    while let Some(n) = stack.pop() {
        order.push(n);
        if nodes[n].prim_count == 0 {
            let f = nodes[n].first_index as usize;
            stack.extend([f, f + 1]);
        }
    }
    for &n in order.iter().rev() {
        if nodes[n].prim_count > 0 {
            count[n] = nodes[n].prim_count;
            merge[n] = true;
        } else {
            let f = nodes[n].first_index as usize;
            count[n] = count[f].saturating_add(count[f + 1]);
            let larger = nodes[f].aabb.half_area().max(nodes[f + 1].aabb.half_area());
            merge[n] = count[n] <= 8
                && merge[f]
                && merge[f + 1]
                && nodes[n].aabb.half_area() <= larger * (1.0 + 1e-4);
        }
    }
    merge
}

/// The primitive slots of every leaf under binary node `n`.
fn leaf_slots(nodes: &[Bvh2Node], n: usize) -> Vec<u32> {
    let mut slots = Vec::new();
    let mut stack = vec![n];
    while let Some(n) = stack.pop() {
        let node = &nodes[n];
        if node.prim_count > 0 {
            slots.extend(node.first_index..node.first_index + node.prim_count);
        } else {
            let f = node.first_index as usize;
            stack.extend([f, f + 1]);
        }
    }
    slots
}

/// [`RayShear`] with its permuted origin and shear splatted over eight lanes.
struct RayShear8 {
    scalar: RayShear,
    /// World axes that become x, y and z after the permutation.
    axes: [usize; 3],
    o: [F8; 3],
    sx: F8,
    sy: F8,
    sz: F8,
}

impl RayShear8 {
    #[inline]
    #[target_feature(enable = "avx2")]
    fn new(o: Vec3, d: Vec3) -> Self {
        let scalar = RayShear::new(o, d);
        let kz = scalar.kz();
        let axes = [(kz + 1) % 3, (kz + 2) % 3, kz];
        let (sx, sy, sz) = scalar.shear();
        RayShear8 {
            scalar,
            axes,
            o: [
                F8::splat(o[axes[0]]),
                F8::splat(o[axes[1]]),
                F8::splat(o[axes[2]]),
            ],
            sx: F8::splat(sx),
            sy: F8::splat(sy),
            sz: F8::splat(sz),
        }
    }
}

/// The watertight test on the triangles of `leaf` in `lanes` at once, lane by lane the scalar
/// test's operations (see the module's doc). Returns the mask of lanes hit with
/// 0 < t < tmax, and t, b1, b2 per lane.
#[inline]
#[target_feature(enable = "avx2")]
fn intersect_triangle8(
    r: &RayShear8,
    leaf: &Leaf8,
    tmax: f32,
    lanes: u32,
) -> (u32, [f32; 8], [f32; 8], [f32; 8]) {
    let [kx, ky, kz] = r.axes;
    let rel = |k: usize| {
        (
            F8::load(&leaf.v[k][kx]).sub(r.o[0]),
            F8::load(&leaf.v[k][ky]).sub(r.o[1]),
            F8::load(&leaf.v[k][kz]).sub(r.o[2]),
        )
    };
    let (a_x, a_y, a_z) = rel(0);
    let (b_x, b_y, b_z) = rel(1);
    let (c_x, c_y, c_z) = rel(2);
    let shear = |x: F8, y: F8, z: F8| (x.sub(r.sx.mul(z)), y.sub(r.sy.mul(z)));
    let (ax, ay) = shear(a_x, a_y, a_z);
    let (bx, by) = shear(b_x, b_y, b_z);
    let (cx, cy) = shear(c_x, c_y, c_z);
    let e0 = cx.mul(by).sub(cy.mul(bx));
    let e1 = ax.mul(cy).sub(ay.mul(cx));
    let e2 = bx.mul(ay).sub(by.mul(ax));
    let zero = F8::zero();
    let on_edge = (e0.eq(zero) | e1.eq(zero) | e2.eq(zero)) & lanes;
    let neg = e0.lt(zero) | e1.lt(zero) | e2.lt(zero);
    let pos = e0.gt(zero) | e1.gt(zero) | e2.gt(zero);
    let inside = lanes & !on_edge & !(neg & pos);
    let none = [0.0f32; 8];
    if inside == 0 && on_edge == 0 {
        // The ray passes outside every triangle: skip distances and error bounds.
        return (0, none, none, none);
    }
    let det = e0.add(e1).add(e2);
    let az = r.sz.mul(a_z);
    let bz = r.sz.mul(b_z);
    let cz = r.sz.mul(c_z);
    let t_scaled = e0.mul(az).add(e1.mul(bz)).add(e2.mul(cz));
    let tmax8 = F8::splat(tmax);
    let t_det = tmax8.mul(det);
    let det_neg = det.lt(zero);
    let det_pos = det.gt(zero);
    let reject_neg = det_neg & (t_scaled.ge(zero) | t_scaled.lt(t_det));
    let reject_pos = det_pos & (t_scaled.le(zero) | t_scaled.gt(t_det));
    let reject = det.eq(zero) | !det.finite() | reject_neg | reject_pos;
    let mut hit = inside & !reject;
    let inv_det = F8::splat(1.0).div(det);
    let t8 = t_scaled.mul(inv_det);
    if hit != 0 {
        let max3 = |x: F8, y: F8, z: F8| x.abs().max(y.abs()).max(z.abs());
        let max_zt = max3(az, bz, cz);
        let delta_z = F8::splat(gamma(3)).mul(max_zt);
        let max_xt = max3(ax, bx, cx);
        let max_yt = max3(ay, by, cy);
        let max_kz = max3(a_z, b_z, c_z);
        let g5 = F8::splat(gamma(5));
        let two = F8::splat(2.0);
        let delta_x = g5.mul(max_xt.add(two.mul(r.sx.abs()).mul(max_kz)));
        let delta_y = g5.mul(max_yt.add(two.mul(r.sy.abs()).mul(max_kz)));
        let delta_e = two.mul(
            F8::splat(gamma(2))
                .mul(max_xt)
                .mul(max_yt)
                .add(delta_y.mul(max_xt))
                .add(delta_x.mul(max_yt)),
        );
        let max_e = max3(e0, e1, e2);
        let delta_t = F8::splat(3.0)
            .mul(
                F8::splat(gamma(3))
                    .mul(max_e)
                    .mul(max_zt)
                    .add(delta_e.mul(max_zt))
                    .add(delta_z.mul(max_e)),
            )
            .mul(inv_det.abs());
        hit &= !(t8.le(delta_t) | t8.ge(tmax8));
    }
    let mut t = t8.to_array();
    let mut b1 = e1.mul(inv_det).to_array();
    let mut b2 = e2.mul(inv_det).to_array();
    // Lanes on an edge: the scalar test with its f64 fallback (rare).
    let mut rest = on_edge;
    while rest != 0 {
        let lane = rest.trailing_zeros() as usize;
        rest &= rest - 1;
        if let Some((tl, b1l, b2l)) = intersect_triangle(&r.scalar, &leaf.lane(lane), tmax) {
            hit |= 1 << lane;
            t[lane] = tl;
            b1[lane] = b1l;
            b2[lane] = b2l;
        }
    }
    (hit, t, b1, b2)
}

/// What a leaf test needs of the ray and the scene.
struct LeafContext8<'a> {
    shear: RayShear8,
    ray: &'a Ray,
    shapes: &'a [Shape],
}

/// Per-ray constants of the slab test.
struct BoxRay8 {
    o: [F8; 3],
    inv: [F8; 3],
}

impl BoxRay8 {
    #[inline]
    #[target_feature(enable = "avx2")]
    fn new(ray: &Ray) -> Self {
        // As the 4-wide test: components below 1e-30 become ±1e-30 (inverse ±1e30), so an
        // axis-parallel ray's slab stays effectively infinite and 0 · ∞ never makes a NaN.
        let inv = |x: f32| {
            F8::splat(
                1.0 / if x.abs() < 1e-30 {
                    1e-30f32.copysign(x)
                } else {
                    x
                },
            )
        };
        BoxRay8 {
            o: [F8::splat(ray.o.x), F8::splat(ray.o.y), F8::splat(ray.o.z)],
            inv: [inv(ray.d.x), inv(ray.d.y), inv(ray.d.z)],
        }
    }

    /// Entry distances of the eight children and the mask of those the ray enters within
    /// (0, tmax).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn test(&self, node: &Node8, tmax: f32) -> (u32, [f32; 8]) {
        let mut t_near = F8::zero();
        let mut t_far = F8::splat(f32::INFINITY);
        for a in 0..3 {
            let t0 = F8::load(&node.lo[a]).sub(self.o[a]).mul(self.inv[a]);
            let t1 = F8::load(&node.hi[a]).sub(self.o[a]).mul(self.inv[a]);
            t_near = t_near.max(t0.min(t1));
            t_far = t_far.min(t0.max(t1));
        }
        let t_far = t_far
            .mul(F8::splat(1.0 + 2.0 * gamma(3)))
            .min(F8::splat(tmax));
        (t_near.le(t_far) & node.valid, t_near.to_array())
    }
}

impl Accel {
    /// Tests the 8-wide leaf blocks starting at `first`; updates `best` and returns the new
    /// tmax. With `any`, returns at the first block with a hit (occlusion).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn test_leaf8(
        &self,
        wide: &Wide8,
        first: usize,
        ctx: &LeafContext8,
        mut tmax: f32,
        best: &mut Option<Hit>,
        any: bool,
    ) -> f32 {
        let mut k = first;
        loop {
            let block = &wide.leaves[k];
            if block.tri_mask != 0 {
                let (mask, t, b1, b2) =
                    intersect_triangle8(&ctx.shear, block, tmax, block.tri_mask);
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

    /// [`Accel::traverse8`] for each ray `rays[i]` of the lanes `mask`, its hit handed to
    /// `out(i, hit)`: one call into the AVX2 code for all of them.
    #[target_feature(enable = "avx2")]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn traverse8_lanes(
        &self,
        wide: &Wide8,
        rays: &[Ray],
        mask: u32,
        shapes: &[Shape],
        any: bool,
        stack: &mut [MaybeUninit<(u32, f32)>],
        out: &mut impl FnMut(usize, Option<Hit>),
    ) {
        for i in crate::simd::lanes_of(mask) {
            out(i, self.traverse8(wide, &rays[i], shapes, any, stack));
        }
    }

    /// Walks the 8-wide tree with `stack` (entries: child reference, entry distance), of at
    /// least `wide.stack_size` entries, nearest child first; entries below the stack pointer
    /// are always written before they are read, so the stack needs no initialisation.
    #[target_feature(enable = "avx2")]
    pub(super) fn traverse8(
        &self,
        wide: &Wide8,
        ray: &Ray,
        shapes: &[Shape],
        any: bool,
        stack: &mut [MaybeUninit<(u32, f32)>],
    ) -> Option<Hit> {
        let ctx = LeafContext8 {
            shear: RayShear8::new(ray.o, ray.d),
            ray,
            shapes,
        };
        let boxes = BoxRay8::new(ray);
        let mut tmax = ray.tmax;
        let mut best = None;
        let mut sp = 0;
        stack[0] = MaybeUninit::new((wide.root, 0.0));
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
                let n = &wide.nodes[node as usize];
                #[cfg(test)]
                super::count_node_visit();
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
                node = push_entered(mask, &t_near, &n.child, stack, &mut sp);
            }
            if node == EMPTY {
                continue;
            }
            tmax = self.test_leaf8(wide, (node & !LEAF) as usize, &ctx, tmax, &mut best, any);
            if any && best.is_some() {
                return best;
            }
        }
        best
    }
}
