//! Triangle meshes and the watertight ray/triangle test of Woop, Benthin and Wald 2013,
//! "Watertight Ray/Triangle Intersection" (JCGT 2(1)), with the conservative `t > 0` bound
//! of pbrt-v4 §6.8.4 so that a ray leaving a triangle never re-hits it.

use super::{PositionSample, PositionSamples, SurfaceInteraction, SurfaceInteractions};
use crate::geometry::{gamma, Frames};
use crate::sampling::{square_to_uniform_triangle_lanes, Distribution1D};
use crate::simd::{
    for_each_lane, gather_u32x3, gather_vec3, LaneF32, LaneMask, LaneU32, Lanes, Scalar, V3,
};
use glam::{DVec3, Vec2, Vec3, Vec4};

/// A world-space triangle mesh.
#[derive(Clone, Debug)]
pub struct Mesh {
    pub positions: Vec<Vec3>,
    /// Per-vertex shading normals (unit), if the mesh has them.
    pub normals: Option<Vec<Vec3>>,
    pub uvs: Option<Vec<Vec2>>,
    pub triangles: Vec<[u32; 3]>,
    pub flip_normals: bool,
    /// Triangles by area, for uniform area sampling; `None` if the mesh has no area.
    area_distribution: Option<Distribution1D>,
    /// Unit geometric normal per triangle (flipped if `flip_normals`), computed once.
    face_normals: Vec<Vec3>,
    /// Per-vertex and per-face attributes (PLY colours, ...), for `mesh_attribute` textures.
    pub attributes: Vec<MeshAttribute>,
}

/// A named attribute of a mesh: one or three values per vertex (`vertex_*`) or per face
/// (`face_*`, one row per entry of `Mesh::triangles`).
#[derive(Clone, Debug)]
pub struct MeshAttribute {
    pub name: String,
    pub channels: usize,
    pub per_face: bool,
    pub values: Vec<f32>,
}

impl MeshAttribute {
    /// Row `i` (a vertex or a face) as three values (a single channel in `x`; 0 past the
    /// end).
    pub fn row(&self, i: usize) -> Vec3 {
        let c = self.channels;
        let v = self.values.get(i * c..i * c + c).unwrap_or(&[]);
        Vec3::new(
            v.first().copied().unwrap_or(0.0),
            v.get(1).copied().unwrap_or(0.0),
            v.get(2).copied().unwrap_or(0.0),
        )
    }
}

impl Mesh {
    /// Builds a mesh. Indices must be in range (the caller validates input meshes).
    pub fn new(
        positions: Vec<Vec3>,
        normals: Option<Vec<Vec3>>,
        uvs: Option<Vec<Vec2>>,
        triangles: Vec<[u32; 3]>,
        flip_normals: bool,
    ) -> Self {
        let mut mesh = Mesh {
            positions,
            normals,
            uvs,
            triangles,
            flip_normals,
            area_distribution: None,
            face_normals: Vec::new(),
            attributes: Vec::new(),
        };
        mesh.face_normals = (0..mesh.triangles.len())
            .map(|t| mesh.compute_face_normal(t))
            .collect();
        mesh.area_distribution =
            Distribution1D::new((0..mesh.triangles.len()).map(|i| mesh.triangle_area(i)));
        mesh
    }

    /// The attribute `name` at barycentrics `bary` = (b1, b2) of triangle `tri`, with its
    /// channel count (1 or 3; a single channel is in `x`). `None` if the mesh has no such
    /// attribute.
    pub fn eval_attribute(&self, name: &str, tri: usize, bary: Vec2) -> Option<(Vec3, usize)> {
        let a = self.attribute(name)?;
        let value = if a.per_face {
            a.row(tri)
        } else {
            let [i0, i1, i2] = *self.triangles.get(tri)?;
            a.row(i0 as usize) * (1.0 - bary.x - bary.y)
                + a.row(i1 as usize) * bary.x
                + a.row(i2 as usize) * bary.y
        };
        Some((value, a.channels))
    }

    /// The attribute called `name`, if the mesh has it.
    pub fn attribute(&self, name: &str) -> Option<&MeshAttribute> {
        self.attributes.iter().find(|a| a.name == name)
    }

    /// Spectral mode: every three-channel attribute whose name contains `color` becomes
    /// the sigmoid-polynomial coefficients of its colours, row by row, as Mitsuba's spectral
    /// variants convert such attributes when a mesh is loaded (`Mesh::add_attribute`).
    pub fn upsample_color_attributes(&mut self) {
        for a in &mut self.attributes {
            if a.channels == 3 && a.name.contains("color") {
                for row in a.values.chunks_exact_mut(3) {
                    let c = crate::spectral::srgb_model_fetch([row[0], row[1], row[2]]);
                    row.copy_from_slice(&c);
                }
            }
        }
    }

    pub fn vertices(&self, tri: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[tri];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Area of one triangle, computed in f64.
    pub fn triangle_area(&self, tri: usize) -> f64 {
        let [a, b, c] = self.vertices(tri).map(|p| p.as_dvec3());
        0.5 * (b - a).cross(c - a).length()
    }

    pub fn area(&self) -> f64 {
        self.area_distribution
            .as_ref()
            .map_or(0.0, Distribution1D::total)
    }

    /// Geometric normal of a triangle: normalize((p1 − p0) × (p2 − p0)), Mitsuba's winding,
    /// computed in f64 (tiny triangles would underflow in f32).
    fn compute_face_normal(&self, tri: usize) -> Vec3 {
        let [a, b, c] = self.vertices(tri).map(|p| p.as_dvec3());
        let n = (b - a).cross(c - a).normalize_or_zero().as_vec3();
        if self.flip_normals {
            -n
        } else {
            n
        }
    }

    /// The shading normal lane by lane, at barycentrics `b` = (b0, b1, b2) of the triangles
    /// with vertices `v`: Σ bᵢ nᵢ normalised (glam's `normalize_or_zero`), flipped with
    /// `flip_normals`; the geometric normal `ng` where the mesh has no normals or the sum
    /// is zero.
    #[inline(always)]
    pub fn shading_normal_lanes<L: Lanes>(
        &self,
        l: L,
        m: L::M,
        v: [L::U32; 3],
        b: [L::F; 3],
        ng: V3<L::F>,
    ) -> V3<L::F> {
        let Some(normals) = &self.normals else {
            return ng;
        };
        let [n0, n1, n2] = v.map(|i| gather_vec3(l, normals, i, m));
        let n = n0 * b[0] + n1 * b[1] + n2 * b[2];
        let n = n.normalize_or_zero(l.splat(1.0), l.splat(0.0));
        let n = if self.flip_normals { -n } else { n };
        V3::select(n.cmp_eq(V3::splat(l.splat(0.0))), ng, n)
    }

    /// The surface interaction at barycentrics (b1, b2) of triangle `tri`. The width-1
    /// instance of [`triangle_interactions`].
    pub fn interaction(
        &self,
        tri: usize,
        t: f32,
        b1: f32,
        b2: f32,
        shape: u32,
    ) -> SurfaceInteraction {
        let mut tl = TriangleLanes::zero(Scalar);
        self.load_triangle(&mut tl, 0, tri as u32, shape);
        triangle_interactions(Scalar, &tl, t, b1, b2).into()
    }

    /// Loads triangle `tri` of this mesh (shape `shape`) into lane `i` of `tl`: its
    /// vertices, vertex normals and texture coordinates where the mesh has them, its face
    /// normal, and whether the mesh flips its normals.
    #[inline(always)]
    pub fn load_triangle<L: Lanes>(
        &self,
        tl: &mut TriangleLanes<L>,
        i: usize,
        tri: u32,
        shape: u32,
    ) {
        let v = self.triangles[tri as usize];
        for (p, &k) in tl.p.iter_mut().zip(&v) {
            p.set_lane(i, self.positions[k as usize]);
        }
        tl.ng.set_lane(i, self.face_normals[tri as usize]);
        if let Some(normals) = &self.normals {
            for (n, &k) in tl.n.iter_mut().zip(&v) {
                n.set_lane(i, normals[k as usize]);
            }
            tl.normals |= 1 << i;
        }
        if let Some(uvs) = &self.uvs {
            for (uv, &k) in tl.uv.iter_mut().zip(&v) {
                let t = uvs[k as usize];
                uv[0].set_lane(i, t.x);
                uv[1].set_lane(i, t.y);
            }
            tl.uvs |= 1 << i;
        }
        if self.flip_normals {
            tl.flip |= 1 << i;
        }
        tl.tri.set_lane(i, tri);
        tl.shape.set_lane(i, shape);
    }

    /// Picks a triangle ∝ area, then a uniform point on it. The width-1 instance of
    /// [`Mesh::sample_position_lanes`].
    pub fn sample_position(&self, u: Vec2) -> Option<PositionSample> {
        let (ok, ps) = self.sample_position_lanes(Scalar, true, u.x, u.y);
        ok.then(|| ps.into())
    }

    /// [`Mesh::sample_position`] lane by lane where `m` is set: the triangle picked ∝ area
    /// by `ux` (a search of the f64 CDF, lane by lane), `ux` rescaled and `uy` mapped to
    /// uniform barycentrics, the point and its error bound from the gathered vertices, the
    /// shading normal there, and the density 1 / area. The mask of the lanes that got a
    /// point (none when the mesh has no area).
    #[inline(always)]
    pub fn sample_position_lanes<L: Lanes>(
        &self,
        l: L,
        m: L::M,
        ux: L::F,
        uy: L::F,
    ) -> (L::M, PositionSamples<L>) {
        let Some(dist) = self.area_distribution.as_ref() else {
            return (l.mask(0), PositionSamples::zero(l));
        };
        let mut tri = l.splat_u32(0);
        let mut ux2 = l.splat(0.0);
        for_each_lane(
            L::WIDTH,
            m,
            #[inline(always)]
            |i| {
                let (t, r) = dist.sample_reuse(ux.lane(i));
                tri.set_lane(i, t as u32);
                ux2.set_lane(i, r);
            },
        );
        let (b1, b2) = square_to_uniform_triangle_lanes(l, ux2, uy);
        let b = [l.splat(1.0) - b1 - b2, b1, b2];
        let v = gather_u32x3(l, &self.triangles, tri, m);
        let p = v.map(|i| gather_vec3(l, &self.positions, i, m));
        let (p, p_error) = barycentric_point_lanes(l, p, b, 6);
        let ng = gather_vec3(l, &self.face_normals, tri, m);
        let n = self.shading_normal_lanes(l, m, v, b, ng);
        let pdf = l.splat((1.0 / dist.total()) as f32);
        (m, PositionSamples { p, p_error, n, pdf })
    }
}

/// Where each texture coordinate lies on a mesh (Mitsuba's `eval_parameterization` for
/// meshes, which traces a ray in uv space): a uniform grid over the uvs' bounding box, each
/// cell listing the triangles whose uv triangle overlaps it. Built for meshes whose emitted
/// radiance is textured.
#[derive(Clone, Debug)]
pub struct UvGrid {
    lo: Vec2,
    /// Cells per unit of uv.
    scale: Vec2,
    n: usize,
    /// Cell c's triangles are `tris[start[c]..start[c + 1]]`.
    start: Vec<u32>,
    tris: Vec<u32>,
}

impl UvGrid {
    /// `None` if the mesh has no texture coordinates.
    pub fn new(mesh: &Mesh) -> Option<Self> {
        let uvs = mesh.uvs.as_ref()?;
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        for uv in uvs.iter().filter(|uv| uv.is_finite()) {
            lo = lo.min(*uv);
            hi = hi.max(*uv);
        }
        if !(lo.is_finite() && hi.is_finite()) {
            return None;
        }
        let n = ((mesh.triangles.len() as f64).sqrt().ceil() as usize).clamp(1, 1024);
        let extent = (hi - lo).max(Vec2::splat(1e-12));
        let scale = Vec2::splat(n as f32) / extent;
        let cell_range = |tri: &[u32; 3]| {
            let t = tri.map(|i| uvs[i as usize]);
            let (a, b) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
            let c0 = ((a - lo) * scale).floor();
            let c1 = ((b - lo) * scale).floor();
            let clamp = |x: f32| (x.max(0.0) as usize).min(n - 1);
            (clamp(c0.x), clamp(c1.x), clamp(c0.y), clamp(c1.y))
        };
        let mut count = vec![0u32; n * n + 1];
        for tri in &mesh.triangles {
            let (x0, x1, y0, y1) = cell_range(tri);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    count[y * n + x + 1] += 1;
                }
            }
        }
        for c in 1..count.len() {
            count[c] += count[c - 1];
        }
        let mut fill = count.clone();
        let mut tris = vec![0u32; *count.last().unwrap_or(&0) as usize];
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let (x0, x1, y0, y1) = cell_range(tri);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let c = y * n + x;
                    tris[fill[c] as usize] = t as u32;
                    fill[c] += 1;
                }
            }
        }
        Some(UvGrid {
            lo,
            scale,
            n,
            start: count,
            tris,
        })
    }

    /// The triangle whose uv triangle contains `uv`, and the barycentrics (b1, b2) of `uv`
    /// in it; `None` where no triangle maps (or when `mesh` has no uvs).
    pub fn locate(&self, mesh: &Mesh, uv: Vec2) -> Option<(usize, Vec2)> {
        let uvs = mesh.uvs.as_ref()?;
        let c = ((uv - self.lo) * self.scale).floor();
        if !(c.x >= 0.0 && c.y >= 0.0 && (c.x as usize) < self.n && (c.y as usize) < self.n) {
            return None;
        }
        let cell = c.y as usize * self.n + c.x as usize;
        let range = self.start[cell] as usize..self.start[cell + 1] as usize;
        for &t in &self.tris[range] {
            let [a, b, c] = mesh.triangles[t as usize].map(|i| uvs[i as usize].as_dvec2());
            let (e1, e2, q) = (b - a, c - a, uv.as_dvec2() - a);
            let det = e1.x * e2.y - e1.y * e2.x;
            if det == 0.0 || !det.is_finite() {
                continue;
            }
            let b1 = (q.x * e2.y - q.y * e2.x) / det;
            let b2 = (e1.x * q.y - e1.y * q.x) / det;
            const EPS: f64 = 1e-9;
            if b1 >= -EPS && b2 >= -EPS && b1 + b2 <= 1.0 + EPS {
                return Some((t as usize, Vec2::new(b1 as f32, b2 as f32)));
            }
        }
        None
    }
}

/// The point Σ bᵢ pᵢ and its conservative error bound γ(n) Σ |bᵢ pᵢ| (pbrt-v4 §6.8.2), lane
/// by lane: ((b₀p₀ + b₁p₁) + b₂p₂, γ(n) ((|b₀p₀| + |b₁p₁|) + |b₂p₂|)).
#[inline(always)]
pub fn barycentric_point_lanes<L: Lanes>(
    l: L,
    p: [V3<L::F>; 3],
    b: [L::F; 3],
    n: i32,
) -> (V3<L::F>, V3<L::F>) {
    let q = [p[0] * b[0], p[1] * b[1], p[2] * b[2]];
    let point = q[0] + q[1] + q[2];
    let abs_sum = q[0].abs() + q[1].abs() + q[2].abs();
    (point, abs_sum * l.splat(gamma(n)))
}

/// Triangles hit, in lanes, each lane's from its own mesh ([`Mesh::load_triangle`]): what
/// [`triangle_interactions`] computes the surface interactions from. The lane engine loads
/// every lane that hit a mesh (outside instances), whatever the mesh, and runs the kernel
/// once for all of them.
#[derive(Clone, Copy, Debug)]
pub struct TriangleLanes<L: Lanes> {
    /// The vertices.
    pub p: [V3<L::F>; 3],
    /// The vertex normals (lanes of `normals`).
    pub n: [V3<L::F>; 3],
    /// The vertices' (u, v) (lanes of `uvs`).
    pub uv: [[L::F; 2]; 3],
    /// The face normal.
    pub ng: V3<L::F>,
    pub tri: L::U32,
    pub shape: L::U32,
    /// The lanes (bits) whose mesh has vertex normals, texture coordinates, flip_normals.
    pub normals: u32,
    pub uvs: u32,
    pub flip: u32,
}

impl<L: Lanes> TriangleLanes<L> {
    #[inline(always)]
    pub fn zero(l: L) -> Self {
        let z = l.splat(0.0);
        let v = V3::splat(z);
        TriangleLanes {
            p: [v; 3],
            n: [v; 3],
            uv: [[z; 2]; 3],
            ng: v,
            tri: l.splat_u32(0),
            shape: l.splat_u32(0),
            normals: 0,
            uvs: 0,
            flip: 0,
        }
    }
}

/// [`Mesh::interaction`] lane by lane, at distances `t` and barycentrics (b1, b2) of the
/// triangles `tl`: the point and its error bound, the face normal, the shading normal
/// (Σ bᵢ nᵢ normalised, flipped with flip_normals; the face normal where the mesh has no
/// normals or the sum is zero), and Mitsuba's parameterisation (barycentric without texture
/// coordinates, dp/du = p1 − p0; else the texture coordinates, with an arbitrary basis
/// around the unflipped face normal where the triangle's uv map is degenerate), the shading
/// frame following dp/du. Lanes not loaded give values to be ignored.
#[inline(always)]
pub fn triangle_interactions<L: Lanes>(
    l: L,
    tl: &TriangleLanes<L>,
    t: L::F,
    b1: L::F,
    b2: L::F,
) -> SurfaceInteractions<L> {
    let zero = l.splat(0.0);
    let b0 = l.splat(1.0) - b1 - b2;
    let [p0, p1, p2] = tl.p;
    let (p, p_error) = barycentric_point_lanes(l, tl.p, [b0, b1, b2], 7);
    let ng = tl.ng;
    let flip = l.mask(tl.flip);
    let ns = if tl.normals != 0 {
        let [n0, n1, n2] = tl.n;
        let n = n0 * b0 + n1 * b1 + n2 * b2;
        let n = n.normalize_or_zero(l.splat(1.0), zero);
        let n = V3::select(flip, -n, n);
        let n = V3::select(n.cmp_eq(V3::splat(zero)), ng, n);
        V3::select(l.mask(tl.normals), n, ng)
    } else {
        ng
    };
    let (dp0, dp1) = (p1 - p0, p2 - p0);
    let (uv, dp_du, dp_dv) = if tl.uvs != 0 {
        let has = l.mask(tl.uvs);
        let [t0, t1, t2] = tl.uv;
        let uv = [
            t0[0] * b0 + t1[0] * b1 + t2[0] * b2,
            t0[1] * b0 + t1[1] * b1 + t2[1] * b2,
        ];
        let duv0 = [t1[0] - t0[0], t1[1] - t0[1]];
        let duv1 = [t2[0] - t0[0], t2[1] - t0[1]];
        let det = duv0[0] * duv1[1] - duv0[1] * duv1[0];
        let inv = l.splat(1.0) / det;
        let mut dp_du = (dp0 * duv1[1] - dp1 * duv0[1]) * inv;
        let mut dp_dv = (dp1 * duv0[0] - dp0 * duv1[0]) * inv;
        let degenerate = has & !(det.cmp_ne(zero) & det.is_finite());
        if degenerate.any() {
            // Around the normal before flip_normals, as Mitsuba flips last.
            let f = Frames::from_normal(l, V3::select(flip, -ng, ng));
            dp_du = V3::select(degenerate, f.s, dp_du);
            dp_dv = V3::select(degenerate, f.t, dp_dv);
        }
        (
            [L::F::select(has, uv[0], b1), L::F::select(has, uv[1], b2)],
            V3::select(has, dp_du, dp0),
            V3::select(has, dp_dv, dp1),
        )
    } else {
        ([b1, b2], dp0, dp1)
    };
    SurfaceInteractions {
        p,
        p_error,
        t,
        ng,
        frame: Frames::from_normal_tangent(l, ns, dp_du),
        uv,
        dp_du,
        dp_dv,
        shape: tl.shape,
        prim: tl.tri,
        bary: [b1, b2],
    }
}

/// Per-ray constants of the watertight test: the dominant axis `kz` of the direction, the
/// origin and direction cyclically permuted so that `kz` becomes z, and the shear that maps the
/// direction onto +z. (The paper also swaps x and y when d_kz < 0 to keep the winding; both
/// windings are accepted here, so the cyclic permutation alone suffices.)
#[derive(Clone, Copy, Debug)]
pub struct RayShear {
    o: Vec3,
    kz: usize,
    sx: f32,
    sy: f32,
    sz: f32,
}

/// Cyclic permutation taking axis `KZ` to z.
#[inline(always)]
fn permute<const KZ: usize>(v: Vec3) -> Vec3 {
    match KZ {
        0 => Vec3::new(v.y, v.z, v.x),
        1 => Vec3::new(v.z, v.x, v.y),
        _ => v,
    }
}

impl RayShear {
    /// The world axis that the permutation takes to z (the direction's largest component).
    pub fn kz(&self) -> usize {
        self.kz
    }

    /// The shear (s_x, s_y, s_z) of the permuted space.
    pub fn shear(&self) -> (f32, f32, f32) {
        (self.sx, self.sy, self.sz)
    }

    pub fn new(o: Vec3, d: Vec3) -> Self {
        let a = d.abs();
        let kz = if a.x > a.y && a.x > a.z {
            0
        } else if a.y > a.z {
            1
        } else {
            2
        };
        let dp = match kz {
            0 => permute::<0>(d),
            1 => permute::<1>(d),
            _ => d,
        };
        RayShear {
            o,
            kz,
            sx: dp.x / dp.z,
            sy: dp.y / dp.z,
            sz: 1.0 / dp.z,
        }
    }
}

/// Watertight ray/triangle intersection. Returns (t, b1, b2) for a hit with
/// 0 < t < tmax, where t is conservatively positive.
#[inline(always)]
pub fn intersect_triangle(r: &RayShear, p: &[Vec3; 3], tmax: f32) -> Option<(f32, f32, f32)> {
    match r.kz {
        0 => intersect_permuted::<0>(r, p, tmax),
        1 => intersect_permuted::<1>(r, p, tmax),
        _ => intersect_permuted::<2>(r, p, tmax),
    }
}

#[inline(always)]
fn intersect_permuted<const KZ: usize>(
    r: &RayShear,
    p: &[Vec3; 3],
    tmax: f32,
) -> Option<(f32, f32, f32)> {
    let a = permute::<KZ>(p[0] - r.o);
    let b = permute::<KZ>(p[1] - r.o);
    let c = permute::<KZ>(p[2] - r.o);
    let (ax, ay) = (a.x - r.sx * a.z, a.y - r.sy * a.z);
    let (bx, by) = (b.x - r.sx * b.z, b.y - r.sy * b.z);
    let (cx, cy) = (c.x - r.sx * c.z, c.y - r.sy * c.z);
    let mut e0 = cx * by - cy * bx;
    let mut e1 = ax * cy - ay * cx;
    let mut e2 = bx * ay - by * ax;
    if e0 == 0.0 || e1 == 0.0 || e2 == 0.0 {
        // Fall back to double precision on edges, as the paper prescribes.
        let f = |x: f32, y: f32, z: f32, w: f32| (x as f64 * y as f64 - z as f64 * w as f64) as f32;
        e0 = f(cx, by, cy, bx);
        e1 = f(ax, cy, ay, cx);
        e2 = f(bx, ay, by, ax);
    }
    if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
        return None;
    }
    let det = e0 + e1 + e2;
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let az = r.sz * a.z;
    let bz = r.sz * b.z;
    let cz = r.sz * c.z;
    let t_scaled = e0 * az + e1 * bz + e2 * cz;
    if det < 0.0 && (t_scaled >= 0.0 || t_scaled < tmax * det) {
        return None;
    }
    if det > 0.0 && (t_scaled <= 0.0 || t_scaled > tmax * det) {
        return None;
    }
    let inv_det = 1.0 / det;
    let t = t_scaled * inv_det;
    // Conservative bound on the error of t (after pbrt-v4 §6.8.4): accept only t > δt.
    let max_zt = az.abs().max(bz.abs()).max(cz.abs());
    let delta_z = gamma(3) * max_zt;
    let max_xt = ax.abs().max(bx.abs()).max(cx.abs());
    let max_yt = ay.abs().max(by.abs()).max(cy.abs());
    // pbrt bounds the sheared x, y errors by γ(5)(max|x'| + max|z'|); the shear term is
    // really |s_x| max|A_kz|, which is far smaller for grazing rays at a distance, where
    // pbrt's looser bound would reject genuine hits.
    let max_kz = a.z.abs().max(b.z.abs()).max(c.z.abs());
    let delta_x = gamma(5) * (max_xt + 2.0 * r.sx.abs() * max_kz);
    let delta_y = gamma(5) * (max_yt + 2.0 * r.sy.abs() * max_kz);
    let delta_e = 2.0 * (gamma(2) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = e0.abs().max(e1.abs()).max(e2.abs());
    let delta_t =
        3.0 * (gamma(3) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * inv_det.abs();
    if t <= delta_t || t >= tmax {
        return None;
    }
    Some((t, e1 * inv_det, e2 * inv_det))
}

/// Four triangles in structure-of-arrays form for [`intersect_triangle4`]: `v[k][axis]`
/// holds coordinate `axis` of vertex `k` of each lane's triangle.
#[derive(Clone, Copy, Debug)]
pub struct Tri4 {
    pub v: [[Vec4; 3]; 3],
}

impl Tri4 {
    /// Packs up to four triangles; missing lanes are zero (degenerate, and masked off by the
    /// caller's lane mask anyway).
    pub fn pack(tris: &[[Vec3; 3]]) -> Self {
        let mut v = [[[0.0f32; 4]; 3]; 3];
        for (lane, t) in tris.iter().take(4).enumerate() {
            for (k, p) in t.iter().enumerate() {
                for axis in 0..3 {
                    v[k][axis][lane] = p[axis];
                }
            }
        }
        Tri4 {
            v: v.map(|vk| vk.map(Vec4::from_array)),
        }
    }

    /// The triangle in `lane`.
    pub fn lane(&self, lane: usize) -> [Vec3; 3] {
        self.v
            .map(|vk| Vec3::new(vk[0][lane], vk[1][lane], vk[2][lane]))
    }
}

/// [`RayShear`] with its permuted origin and shear splatted over four lanes.
#[derive(Clone, Copy, Debug)]
pub struct RayShear4 {
    pub scalar: RayShear,
    /// World axes that become x, y and z after the permutation.
    axes: [usize; 3],
    o: [Vec4; 3],
    sx: Vec4,
    sy: Vec4,
    sz: Vec4,
}

impl RayShear4 {
    pub fn new(o: Vec3, d: Vec3) -> Self {
        let scalar = RayShear::new(o, d);
        let kz = scalar.kz;
        let axes = [(kz + 1) % 3, (kz + 2) % 3, kz];
        RayShear4 {
            scalar,
            axes,
            o: axes.map(|a| Vec4::splat(o[a])),
            sx: Vec4::splat(scalar.sx),
            sy: Vec4::splat(scalar.sy),
            sz: Vec4::splat(scalar.sz),
        }
    }
}

/// [`intersect_triangle`] on four triangles at once (SSE lanes through glam's `Vec4`). Every
/// lane performs the scalar test's operations in the same order, so results are bit-identical
/// to it; lanes where an edge function is exactly zero take the scalar test's f64 fallback.
/// Returns the mask of lanes (within `lanes`) hit with 0 < t < tmax, and t, b1, b2 per lane.
#[inline(always)]
pub fn intersect_triangle4(
    r: &RayShear4,
    tri: &Tri4,
    tmax: f32,
    lanes: u32,
) -> (u32, Vec4, Vec4, Vec4) {
    let [kx, ky, kz] = r.axes;
    let rel = |k: usize| {
        (
            tri.v[k][kx] - r.o[0],
            tri.v[k][ky] - r.o[1],
            tri.v[k][kz] - r.o[2],
        )
    };
    let (a_x, a_y, a_z) = rel(0);
    let (b_x, b_y, b_z) = rel(1);
    let (c_x, c_y, c_z) = rel(2);
    let (ax, ay) = (a_x - r.sx * a_z, a_y - r.sy * a_z);
    let (bx, by) = (b_x - r.sx * b_z, b_y - r.sy * b_z);
    let (cx, cy) = (c_x - r.sx * c_z, c_y - r.sy * c_z);
    let e0 = cx * by - cy * bx;
    let e1 = ax * cy - ay * cx;
    let e2 = bx * ay - by * ax;
    let zero = Vec4::ZERO;
    let on_edge = (e0.cmpeq(zero) | e1.cmpeq(zero) | e2.cmpeq(zero)).bitmask() & lanes;
    let neg = e0.cmplt(zero) | e1.cmplt(zero) | e2.cmplt(zero);
    let pos = e0.cmpgt(zero) | e1.cmpgt(zero) | e2.cmpgt(zero);
    let inside = lanes & !on_edge & !(neg & pos).bitmask();
    if inside == 0 && on_edge == 0 {
        // The ray passes outside all four triangles: skip distances and error bounds.
        return (0, zero, zero, zero);
    }
    let det = e0 + e1 + e2;
    let az = r.sz * a_z;
    let bz = r.sz * b_z;
    let cz = r.sz * c_z;
    let t_scaled = e0 * az + e1 * bz + e2 * cz;
    let tmax4 = Vec4::splat(tmax);
    let t_det = tmax4 * det;
    let det_neg = det.cmplt(zero);
    let det_pos = det.cmpgt(zero);
    let reject_neg = det_neg & (t_scaled.cmpge(zero) | t_scaled.cmplt(t_det));
    let reject_pos = det_pos & (t_scaled.cmple(zero) | t_scaled.cmpgt(t_det));
    let reject = det.cmpeq(zero) | !det.is_finite_mask() | reject_neg | reject_pos;
    let mut hit = inside & !reject.bitmask();
    let inv_det = Vec4::ONE / det;
    let mut t = t_scaled * inv_det;
    let mut b1 = e1 * inv_det;
    let mut b2 = e2 * inv_det;
    if hit != 0 {
        let max_zt = az.abs().max(bz.abs()).max(cz.abs());
        let delta_z = Vec4::splat(gamma(3)) * max_zt;
        let max_xt = ax.abs().max(bx.abs()).max(cx.abs());
        let max_yt = ay.abs().max(by.abs()).max(cy.abs());
        let max_kz = a_z.abs().max(b_z.abs()).max(c_z.abs());
        let g5 = Vec4::splat(gamma(5));
        let two = Vec4::splat(2.0);
        let delta_x = g5 * (max_xt + two * r.sx.abs() * max_kz);
        let delta_y = g5 * (max_yt + two * r.sy.abs() * max_kz);
        let delta_e =
            two * (Vec4::splat(gamma(2)) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
        let max_e = e0.abs().max(e1.abs()).max(e2.abs());
        let delta_t = Vec4::splat(3.0)
            * (Vec4::splat(gamma(3)) * max_e * max_zt + delta_e * max_zt + delta_z * max_e)
            * inv_det.abs();
        hit &= !(t.cmple(delta_t) | t.cmpge(tmax4)).bitmask();
    }
    // Lanes on an edge: the scalar test with its f64 fallback (rare).
    let mut rest = on_edge;
    while rest != 0 {
        let lane = rest.trailing_zeros() as usize;
        rest &= rest - 1;
        if let Some((tl, b1l, b2l)) = intersect_triangle(&r.scalar, &tri.lane(lane), tmax) {
            hit |= 1 << lane;
            t[lane] = tl;
            b1[lane] = b1l;
            b2[lane] = b2l;
        }
    }
    (hit, t, b1, b2)
}

/// Angle-weighted vertex normals (Thürmer and Wüthrich 1998,
/// "Computing Vertex Normals from Polygonal Facets"), what Mitsuba computes for meshes
/// without normals. Degenerate faces contribute nothing.
pub fn angle_weighted_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    let mut acc = vec![DVec3::ZERO; positions.len()];
    for tri in triangles {
        let p = tri.map(|i| positions[i as usize].as_dvec3());
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        let Some(n) = n.try_normalize() else { continue };
        for k in 0..3 {
            let e1 = p[(k + 1) % 3] - p[k];
            let e2 = p[(k + 2) % 3] - p[k];
            let (Some(e1), Some(e2)) = (e1.try_normalize(), e2.try_normalize()) else {
                continue;
            };
            let angle = e1.dot(e2).clamp(-1.0, 1.0).acos();
            acc[tri[k] as usize] += n * angle;
        }
    }
    acc.into_iter()
        .map(|n| n.normalize_or_zero().as_vec3())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> [Vec3; 3] {
        [
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ]
    }

    fn hit(o: Vec3, d: Vec3, p: &[Vec3; 3]) -> Option<(f32, f32, f32)> {
        intersect_triangle(&RayShear::new(o, d), p, f32::INFINITY)
    }

    #[test]
    fn hits_from_both_sides_and_reports_barycentrics() {
        let p = tri();
        let (t, b1, b2) = hit(Vec3::new(0.0, 0.0, 2.0), -Vec3::Z, &p).unwrap();
        assert!((t - 2.0).abs() < 1e-6);
        let q = p[0] * (1.0 - b1 - b2) + p[1] * b1 + p[2] * b2;
        assert!(q.length() < 1e-6, "{q}");
        let (t, _, _) = hit(Vec3::new(0.0, 0.0, -3.0), Vec3::Z, &p).unwrap();
        assert!((t - 3.0).abs() < 1e-6);
    }

    #[test]
    fn misses_outside_behind_and_parallel() {
        let p = tri();
        assert!(hit(Vec3::new(2.0, 0.0, 2.0), -Vec3::Z, &p).is_none());
        assert!(hit(Vec3::new(0.0, 0.0, 2.0), Vec3::Z, &p).is_none());
        assert!(hit(Vec3::new(0.0, 0.0, 0.0), Vec3::X, &p).is_none());
        assert!(hit(Vec3::new(-5.0, 0.0, 1e-3), Vec3::X, &p).is_none());
        // tmax bounds the hit
        let r = RayShear::new(Vec3::new(0.0, 0.0, 2.0), -Vec3::Z);
        assert!(intersect_triangle(&r, &p, 1.5).is_none());
    }

    #[test]
    fn grazing_ray_hits() {
        let p = tri();
        let d = Vec3::new(1.0, 0.0, -1e-4).normalize();
        let o = Vec3::new(-1e4 * d.x, 0.0, 1.0);
        let (t, _, _) = hit(o, d, &p).expect("grazing hit");
        assert!(o.z + t * d.z < 1e-2);
    }

    #[test]
    fn shared_edge_and_vertex_are_watertight() {
        // A quad split along its diagonal: rays through points on the diagonal and through
        // the shared vertices must hit exactly one or both triangles, never neither.
        let q = [
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ];
        let t0 = [q[0], q[1], q[2]];
        let t1 = [q[2], q[3], q[0]];
        for i in 1..1000 {
            let s = -1.0 + 2.0 * i as f32 / 1000.0;
            let o = Vec3::new(s, s, 1.0) + Vec3::new(0.3, -0.2, 0.0);
            let d = Vec3::new(-0.3, 0.2, -1.0);
            assert!(
                hit(o, d, &t0).is_some() || hit(o, d, &t1).is_some(),
                "ray through diagonal point {s} slipped through"
            );
        }
        // A fan of four triangles around the interior vertex c: rays aimed exactly at c.
        let c = Vec3::new(0.25, -0.5, 0.125);
        let fan = [
            [q[0], q[1], c],
            [q[1], q[2], c],
            [q[2], q[3], c],
            [q[3], q[0], c],
        ];
        for k in 0..200 {
            let a = k as f32 * 0.1;
            let d = Vec3::new(a.cos(), a.sin(), -(1.0 + k as f32 * 0.05));
            let o = c - d * 3.0;
            assert!(
                fan.iter().any(|t| hit(o, d, t).is_some()),
                "ray {k} through the shared vertex slipped through"
            );
        }
    }

    /// The 4-wide test must agree bit for bit with the scalar one, on random rays and
    /// triangles including shared edges, vertices and degenerate lanes.
    #[test]
    fn four_wide_test_matches_scalar_bit_for_bit() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg32::seed_from_u64(4);
        let mut v3 = |s: f32| {
            Vec3::new(
                rng.random_range(-s..s),
                rng.random_range(-s..s),
                rng.random_range(-s..s),
            )
        };
        let mut hits = 0;
        for case in 0..20000 {
            let base = v3(1.0);
            let mut tris: Vec<[Vec3; 3]> = (0..4)
                .map(|_| [base + v3(1.0), base + v3(1.0), base + v3(1.0)])
                .collect();
            if case % 5 == 0 {
                tris[1] = [tris[0][1], tris[0][0], tris[1][2]]; // shared edge
                tris[3] = [tris[2][0]; 3]; // degenerate
            }
            let o = v3(3.0);
            // Aim at a vertex or edge midpoint of lane 0 or 1 every other case.
            let target = match case % 4 {
                0 => tris[0][0],
                1 => (tris[0][0] + tris[0][1]) * 0.5,
                _ => base + v3(0.5),
            };
            let d = target - o;
            let tmax = if case % 3 == 0 { 2.5 } else { f32::INFINITY };
            let packed = Tri4::pack(&tris);
            let r4 = RayShear4::new(o, d);
            let lanes = if case % 7 == 0 { 0b0111 } else { 0b1111 };
            let (mask, t, b1, b2) = intersect_triangle4(&r4, &packed, tmax, lanes);
            for (lane, tri) in tris.iter().enumerate() {
                let scalar = if lanes & (1 << lane) != 0 {
                    intersect_triangle(&RayShear::new(o, d), tri, tmax)
                } else {
                    None
                };
                let vector = (mask & (1 << lane) != 0).then(|| (t[lane], b1[lane], b2[lane]));
                let bits =
                    |h: Option<(f32, f32, f32)>| h.map(|(a, b, c)| [a, b, c].map(f32::to_bits));
                assert_eq!(bits(scalar), bits(vector), "case {case} lane {lane}");
                hits += scalar.is_some() as u32;
            }
        }
        assert!(hits > 5000, "the cases must exercise hits, got {hits}");
    }

    #[test]
    fn degenerate_triangles_are_never_hit() {
        let collinear = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
        let point = [Vec3::ONE; 3];
        for d in [Vec3::Z, -Vec3::Z, Vec3::new(0.3, 0.3, -1.0)] {
            assert!(hit(Vec3::new(0.5, 0.0, 1.0), d, &collinear).is_none());
            assert!(hit(Vec3::new(1.0, 1.0, 2.0), d, &point).is_none());
        }
    }

    #[test]
    fn mesh_sampling_is_uniform_by_area_and_interaction_has_normals() {
        let p = vec![
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        ];
        let m = Mesh::new(p, None, None, vec![[0, 1, 2], [0, 3, 1]], false);
        assert!((m.area() - 3.0).abs() < 1e-9);
        let mut in_first = 0;
        let n = 10000;
        for i in 0..n {
            let u = Vec2::new((i as f32 + 0.5) / n as f32, 0.37);
            let s = m.sample_position(u).unwrap();
            assert!((s.pdf - 1.0 / 3.0).abs() < 1e-6);
            if s.p.z.abs() < 1e-7 {
                in_first += 1;
                assert!((s.n - Vec3::Z).length() < 1e-6);
            }
        }
        assert!((in_first as f64 / n as f64 - 2.0 / 3.0).abs() < 1e-3);
        let si = m.interaction(1, 1.0, 0.25, 0.25, 0);
        assert!(
            (si.ng - Vec3::Y).length() < 1e-6,
            "(p1 - p0) x (p2 - p0) winding"
        );
    }

    #[test]
    fn angle_weighted_normals_of_a_tetra_corner() {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let n = angle_weighted_normals(&p, &[[0, 2, 1], [0, 1, 3], [0, 3, 2]]);
        let expected = -Vec3::ONE.normalize();
        assert!((n[0] - expected).length() < 1e-6, "{}", n[0]);
    }

    /// `Mesh::sample_position` as it was before the lane kernel (issue 42, step 3a): the
    /// oracle of [`Mesh::sample_position_lanes`].
    fn sample_position_reference(m: &Mesh, u: Vec2) -> Option<PositionSample> {
        let dist = m.area_distribution.as_ref()?;
        let (tri, ux) = dist.sample_reuse(u.x);
        let t = (1.0 - ux).sqrt();
        let b = Vec2::new(1.0 - t, u.y * t);
        let bary = [1.0 - b.x - b.y, b.x, b.y];
        let p = m.vertices(tri);
        let q = [p[0] * bary[0], p[1] * bary[1], p[2] * bary[2]];
        let point = q[0] + q[1] + q[2];
        let p_error = (q[0].abs() + q[1].abs() + q[2].abs()) * gamma(6);
        let ng = m.face_normals[tri];
        let n = match &m.normals {
            None => ng,
            Some(normals) => {
                let [i0, i1, i2] = m.triangles[tri];
                let n = normals[i0 as usize] * bary[0]
                    + normals[i1 as usize] * bary[1]
                    + normals[i2 as usize] * bary[2];
                let n = n.normalize_or_zero();
                if n == Vec3::ZERO {
                    ng
                } else if m.flip_normals {
                    -n
                } else {
                    n
                }
            }
        };
        Some(PositionSample {
            p: point,
            p_error,
            n,
            pdf: (1.0 / dist.total()) as f32,
        })
    }

    struct SamplePositions<'a> {
        mesh: &'a Mesh,
        u: &'a [Vec2],
        active: &'a [bool],
    }

    impl crate::simd::LaneProgram for SamplePositions<'_> {
        type Output = Vec<Option<PositionSample>>;
        #[inline(always)]
        fn run<L: Lanes>(self, l: L) -> Self::Output {
            let mut out = Vec::with_capacity(self.u.len());
            for (chunk, act) in self.u.chunks(L::WIDTH).zip(self.active.chunks(L::WIDTH)) {
                let (mut ux, mut uy) = (l.splat(0.0), l.splat(0.0));
                let mut bits = 0u32;
                for (i, (u, &a)) in chunk.iter().zip(act).enumerate() {
                    ux.set_lane(i, u.x);
                    uy.set_lane(i, u.y);
                    bits |= (a as u32) << i;
                }
                let (ok, ps) = self.mesh.sample_position_lanes(l, l.mask(bits), ux, uy);
                let ok = crate::simd::LaneMask::bits(ok);
                out.extend((0..chunk.len()).map(|i| {
                    (ok >> i & 1 != 0).then(|| PositionSample {
                        p: ps.p.lane(i),
                        p_error: ps.p_error.lane(i),
                        n: ps.n.lane(i),
                        pdf: ps.pdf.lane(i),
                    })
                }));
            }
            out
        }
    }

    /// Random meshes: uneven and zero-area triangles, with and without vertex normals (some
    /// summing to zero), either orientation.
    fn random_mesh(rng: &mut rand_pcg::Pcg32, normals: bool, flip: bool) -> Mesh {
        use rand::RngExt;
        let nv = 40;
        let mut v3 = |s: f32| {
            Vec3::new(
                rng.random_range(-s..s),
                rng.random_range(-s..s),
                rng.random_range(-s..s),
            )
        };
        let mut positions: Vec<Vec3> = (0..nv).map(|_| v3(3.0)).collect();
        positions[7] = positions[3]; // a repeated vertex: zero-area triangles through it
        positions[8] = positions[3] * 1e-30; // tiny coordinates
        let normals = normals.then(|| {
            let mut n: Vec<Vec3> = (0..nv).map(|_| v3(1.0).normalize_or_zero()).collect();
            // zero normals: their triangle's normals sum to zero (the geometric normal then)
            n[9] = Vec3::ZERO;
            n[10] = Vec3::ZERO;
            n[11] = Vec3::ZERO;
            n
        });
        let tris: Vec<[u32; 3]> = (0..60u32)
            .map(|k| match k % 10 {
                0 => [3, 7, (k % nv as u32)],
                1 => [9, 10, 11],
                _ => [
                    k % nv as u32,
                    (k * 7 + 1) % nv as u32,
                    (k * 13 + 2) % nv as u32,
                ],
            })
            .collect();
        Mesh::new(positions, normals, None, tris, flip)
    }

    /// The lane kernel against the scalar code of before, lane by lane, on every backend
    /// this processor runs, with inactive lanes mixed in.
    #[test]
    fn sample_position_in_lanes_matches_the_scalar_code_bit_for_bit() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg32::seed_from_u64(0x5a3b1e);
        let edges = [0.0, 1.0 - f32::EPSILON / 2.0, 0.5, 1e-30, 0.1];
        let u: Vec<Vec2> = (0..16 * 512)
            .map(|k| match k % 5 {
                0 => Vec2::new(edges[k / 5 % 5], edges[k / 25 % 5]),
                _ => Vec2::new(rng.random::<f32>(), rng.random::<f32>()),
            })
            .collect();
        let active: Vec<bool> = (0..u.len()).map(|_| rng.random_range(0..5) != 0).collect();
        let mut checked = 0;
        for (normals, flip) in [(false, false), (true, false), (true, true), (false, true)] {
            let mesh = random_mesh(&mut rng, normals, flip);
            let want: Vec<Option<PositionSample>> = u
                .iter()
                .map(|&u| sample_position_reference(&mesh, u))
                .collect();
            for b in crate::simd::Backend::all_supported() {
                let got = crate::simd::dispatch(
                    b,
                    SamplePositions {
                        mesh: &mesh,
                        u: &u,
                        active: &active,
                    },
                )
                .expect("supported");
                for k in 0..u.len() {
                    let want = want[k].filter(|_| active[k]);
                    let bits = |p: &Option<PositionSample>| {
                        p.map(|p| {
                            [p.p, p.p_error, p.n]
                                .map(|v| v.to_array().map(f32::to_bits))
                                .concat()
                                .into_iter()
                                .chain([p.pdf.to_bits()])
                                .collect::<Vec<u32>>()
                        })
                    };
                    assert_eq!(
                        bits(&got[k]),
                        bits(&want),
                        "{b}, normals {normals}, flip {flip}: u {:?}",
                        u[k]
                    );
                    checked += want.is_some() as usize;
                }
            }
            // the public scalar function is the width-1 instance
            for (k, &uk) in u.iter().enumerate() {
                let g = mesh
                    .sample_position(uk)
                    .map(|p| (p.p, p.p_error, p.n, p.pdf));
                let w = want[k].map(|p| (p.p, p.p_error, p.n, p.pdf));
                assert_eq!(format!("{g:?}"), format!("{w:?}"));
            }
        }
        assert!(checked > 10000, "{checked}");
    }

    /// `Mesh::interaction` as it was before the lane kernel (issue 42, step 3b): the oracle
    /// of [`triangle_interactions`]. (Its shading frame is `Frame::from_normal_tangent`,
    /// which `geometry`'s tests hold to the scalar code of before.)
    fn interaction_reference(
        m: &Mesh,
        tri: usize,
        t: f32,
        b1: f32,
        b2: f32,
        shape: u32,
    ) -> SurfaceInteraction {
        use crate::geometry::Frame;
        let b0 = 1.0 - b1 - b2;
        let [p0, p1, p2] = m.vertices(tri);
        let q = [p0 * b0, p1 * b1, p2 * b2];
        let p = q[0] + q[1] + q[2];
        let p_error = (q[0].abs() + q[1].abs() + q[2].abs()) * gamma(7);
        let ng = m.face_normals[tri];
        let ns = match &m.normals {
            None => ng,
            Some(normals) => {
                let [i0, i1, i2] = m.triangles[tri];
                let n = normals[i0 as usize] * b0
                    + normals[i1 as usize] * b1
                    + normals[i2 as usize] * b2;
                let n = n.normalize_or_zero();
                if n == Vec3::ZERO {
                    ng
                } else if m.flip_normals {
                    -n
                } else {
                    n
                }
            }
        };
        let (dp0, dp1) = (p1 - p0, p2 - p0);
        let (uv, dp_du, dp_dv) = match &m.uvs {
            Some(uvs) => {
                let [i0, i1, i2] = m.triangles[tri].map(|i| uvs[i as usize]);
                let uv = i0 * b0 + i1 * b1 + i2 * b2;
                let (duv0, duv1) = (i1 - i0, i2 - i0);
                let det = duv0.x * duv1.y - duv0.y * duv1.x;
                if det != 0.0 && det.is_finite() {
                    let inv = 1.0 / det;
                    (
                        uv,
                        (dp0 * duv1.y - dp1 * duv0.y) * inv,
                        (dp1 * duv0.x - dp0 * duv1.x) * inv,
                    )
                } else {
                    let f = Frame::from_normal(if m.flip_normals { -ng } else { ng });
                    (uv, f.s, f.t)
                }
            }
            None => (Vec2::new(b1, b2), dp0, dp1),
        };
        SurfaceInteraction {
            p,
            p_error,
            t,
            ng,
            frame: Frame::from_normal_tangent(ns, dp_du),
            uv,
            dp_du,
            dp_dv,
            shape,
            prim: tri as u32,
            bary: Vec2::new(b1, b2),
        }
    }

    /// Every field's bits (NaN as one value: a computed NaN's payload is not specified).
    fn interaction_bits(si: &SurfaceInteraction) -> Vec<u32> {
        let f = [si.p, si.p_error, si.ng, si.frame.s, si.frame.t, si.frame.n]
            .into_iter()
            .chain([si.dp_du, si.dp_dv])
            .flat_map(|v| v.to_array())
            .chain([si.t, si.uv.x, si.uv.y, si.bary.x, si.bary.y])
            .map(|x| if x.is_nan() { u32::MAX } else { x.to_bits() });
        f.chain([si.shape, si.prim]).collect()
    }

    /// A hit: mesh, triangle, t, b1, b2, and whether its lane is active.
    type HitCase = (usize, u32, f32, f32, f32, bool);

    struct Interactions<'a> {
        meshes: &'a [Mesh],
        hits: &'a [HitCase],
    }

    impl crate::simd::LaneProgram for Interactions<'_> {
        type Output = Vec<Option<SurfaceInteraction>>;
        #[inline(always)]
        fn run<L: Lanes>(self, l: L) -> Self::Output {
            let mut out = Vec::with_capacity(self.hits.len());
            for chunk in self.hits.chunks(L::WIDTH) {
                // as the lane engine: each active lane's triangle from its own mesh
                let mut tl = TriangleLanes::zero(l);
                let (mut t, mut b1, mut b2) = (l.splat(0.0), l.splat(0.0), l.splat(0.0));
                for (i, &(mi, k, tk, u, v, a)) in chunk.iter().enumerate() {
                    if a {
                        self.meshes[mi].load_triangle(&mut tl, i, k, mi as u32);
                        t.set_lane(i, tk);
                        b1.set_lane(i, u);
                        b2.set_lane(i, v);
                    }
                }
                let r = triangle_interactions(l, &tl, t, b1, b2);
                out.extend(
                    chunk
                        .iter()
                        .enumerate()
                        .map(|(i, h)| h.5.then(|| r.lane(i))),
                );
            }
            out
        }
    }

    /// The mesh interaction in lanes against the scalar code of before, lane by lane, on
    /// every backend this processor runs, the lanes of a packet hitting different meshes:
    /// with and without vertex normals and texture coordinates, either orientation,
    /// zero-area triangles, vertex normals summing to zero, degenerate uv maps (repeated,
    /// collinear and infinite texture coordinates), edge barycentrics, inactive lanes.
    #[test]
    fn interaction_in_lanes_matches_the_scalar_code_bit_for_bit() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg32::seed_from_u64(0x3b1a7e);
        let edges = [0.0, 1.0, 1e-30, 0.5, 1.0 - f32::EPSILON / 2.0];
        let mut meshes = Vec::new();
        for (normals, flip, uvs) in [
            (false, false, false),
            (true, false, false),
            (true, true, false),
            (false, true, false),
            (false, false, true),
            (true, false, true),
            (true, true, true),
            (false, true, true),
        ] {
            let base = random_mesh(&mut rng, normals, flip);
            let nv = base.positions.len();
            let uvs = uvs.then(|| {
                let mut uv: Vec<Vec2> = (0..nv)
                    .map(|_| Vec2::new(rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0)))
                    .collect();
                uv[13] = uv[12]; // repeated: det = 0
                uv[14] = uv[12] * 2.0 - uv[15]; // 12 halfway between 14 and 15: collinear
                uv[16] = Vec2::new(f32::INFINITY, 0.5); // det not finite
                uv
            });
            let mut tris = base.triangles.clone();
            tris.extend([[12, 13, 20], [12, 14, 15], [16, 21, 22], [23, 24, 25]]);
            meshes.push(Mesh::new(base.positions, base.normals, uvs, tris, flip));
        }
        let hits: Vec<HitCase> = (0..16 * 2048)
            .map(|k| {
                // runs of lanes on one mesh, and packets mixing them
                let mi = if k % 64 < 32 {
                    k / 64 % meshes.len()
                } else {
                    rng.random_range(0..meshes.len())
                };
                let nt = meshes[mi].triangles.len() as u32;
                // the uv edge triangles often
                let tri = match rng.random_range(0..4) {
                    0 => nt - 1 - rng.random_range(0..4),
                    _ => rng.random_range(0..nt),
                };
                let (b1, b2) = match k % 4 {
                    0 => (
                        edges[k / 4 % 5],
                        edges[k / 20 % 5] * (1.0 - edges[k / 4 % 5]),
                    ),
                    _ => {
                        let (u, v) = (rng.random::<f32>(), rng.random::<f32>());
                        if u + v > 1.0 {
                            (1.0 - u, 1.0 - v)
                        } else {
                            (u, v)
                        }
                    }
                };
                let active = rng.random_range(0..5) != 0;
                (mi, tri, rng.random_range(0.0..100.0), b1, b2, active)
            })
            .collect();
        let want: Vec<Option<SurfaceInteraction>> = hits
            .iter()
            .map(|&(mi, tri, t, b1, b2, a)| {
                a.then(|| interaction_reference(&meshes[mi], tri as usize, t, b1, b2, mi as u32))
            })
            .collect();
        for b in crate::simd::Backend::all_supported() {
            let got = crate::simd::dispatch(
                b,
                Interactions {
                    meshes: &meshes,
                    hits: &hits,
                },
            )
            .expect("supported");
            for (k, (g, w)) in got.iter().zip(&want).enumerate() {
                let m = &meshes[hits[k].0];
                assert_eq!(
                    g.as_ref().map(interaction_bits),
                    w.as_ref().map(interaction_bits),
                    "{b}, normals {}, flip {}, uvs {}: hit {:?}",
                    m.normals.is_some(),
                    m.flip_normals,
                    m.uvs.is_some(),
                    hits[k]
                );
            }
        }
        // the public scalar function is the width-1 instance; the cases reach the
        // degenerate uv maps
        let mut checked = [0usize; 2];
        for (&(mi, tri, t, b1, b2, _), w) in hits.iter().zip(&want) {
            let Some(w) = w else { continue };
            let m = &meshes[mi];
            let g = m.interaction(tri as usize, t, b1, b2, mi as u32);
            assert_eq!(interaction_bits(&g), interaction_bits(w));
            let degenerate = m.uvs.as_ref().is_some_and(|u| {
                let uv = m.triangles[tri as usize].map(|i| u[i as usize]);
                let (d0, d1) = (uv[1] - uv[0], uv[2] - uv[0]);
                let det = d0.x * d1.y - d0.y * d1.x;
                !(det != 0.0 && det.is_finite())
            });
            checked[degenerate as usize] += 1;
        }
        assert!(checked[0] > 10000 && checked[1] > 500, "{checked:?}");
    }
}
