//! The BSDF at a shading point: a small tree of plain BSDFs and Mitsuba's adapters
//! (`twosided`, `mask`, `blendbsdf`, `normalmap`, `bumpmap`, `null`) with every texture
//! already looked up, stored inline (at most [`MAX_NODES`] nodes, no allocation). Node 0 is the
//! root. Each adapter's rules live in its own file; this one dispatches.
//!
//! Conventions are those of [`crate::bsdf`]: local shading frame, `eval` includes |cos θo|,
//! `sample` returns eval / pdf. A `null` event (light passing through a mask or a `null`
//! BSDF) is sampled as a delta transmission `wo = −wi` with weight 1, as in Mitsuba, and counts
//! as a bounce.

use super::{blendbsdf, mask, normalmap, twosided};
use crate::bsdf::{Bsdf, BsdfSample, Spectrum};
use arrayvec::ArrayVec;
use glam::{Vec2, Vec3};

/// The most nodes a material becomes (leaves and adapters together); deeper materials are
/// refused when the scene is built.
pub const MAX_NODES: usize = 8;

/// One node of a [`ShadingBsdf`]; children by index. Leaves are inline (no allocation at a
/// shading point), hence the size difference between variants.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum Node {
    Leaf(Bsdf),
    TwoSided {
        front: u8,
        back: u8,
    },
    Mask {
        opacity: f32,
        nested: u8,
    },
    Blend {
        weight: f32,
        nested: [u8; 2],
    },
    /// A normal- or bump-mapped frame: see [`normalmap::Perturbation`].
    Perturb {
        perturbation: normalmap::Perturbation,
        nested: u8,
    },
    Null,
}

/// The BSDF at one shading point.
#[derive(Clone, Debug)]
pub struct ShadingBsdf {
    nodes: ArrayVec<Node, MAX_NODES>,
    /// Importance transport ([`ShadingBsdf::importance`]); radiance when false.
    importance: bool,
}

impl Default for ShadingBsdf {
    fn default() -> Self {
        Self::new()
    }
}

impl ShadingBsdf {
    pub fn new() -> Self {
        ShadingBsdf {
            nodes: ArrayVec::new(),
            importance: false,
        }
    }

    /// Empties the BSDF for reuse (radiance transport), keeping its storage in place: a
    /// `ShadingBsdf` holds its nodes inline (about 2.5 KB), so filling one per hit in place
    /// ([`crate::scene::Scene::shading_bsdf_into`]) saves copying it out of a function.
    pub fn clear(&mut self) {
        self.nodes.clear();
        self.importance = false;
    }

    /// A shading BSDF of one plain BSDF.
    pub fn leaf(b: Bsdf) -> Self {
        let mut s = Self::new();
        s.push(Node::Leaf(b));
        s
    }

    /// Appends a node and returns its index. Past [`MAX_NODES`] nodes the node is dropped
    /// and the returned index points at a null node (the scene builder prevents that).
    pub fn push(&mut self, node: Node) -> u8 {
        let i = self.nodes.len();
        if self.nodes.try_push(node).is_err() {
            return 0;
        }
        i as u8
    }

    pub fn set(&mut self, i: u8, node: Node) {
        if let Some(slot) = self.nodes.get_mut(i as usize) {
            *slot = node;
        }
    }

    /// The root's plain BSDF, when the whole tree is one leaf.
    pub fn as_leaf(&self) -> Option<&Bsdf> {
        match self.nodes.first() {
            Some(Node::Leaf(b)) if self.nodes.len() == 1 => Some(b),
            _ => None,
        }
    }

    /// The reflectances of a BSDF that is one `diffuse` in radiance mode, (front, back), the
    /// back `None` where it is one-sided: the root a `diffuse`, or a `twosided` of two (or
    /// one) `diffuse`. What the lane engine evaluates and samples in lanes
    /// ([`crate::bsdf::diffuse::DiffuseLanes`]).
    #[inline(always)]
    pub fn as_diffuse(&self) -> Option<(Spectrum, Option<Spectrum>)> {
        if self.importance {
            return None;
        }
        let leaf = |i: u8| match self.node(i) {
            Node::Leaf(Bsdf::Diffuse(d)) => Some(d.reflectance),
            _ => None,
        };
        match self.nodes.first()? {
            Node::Leaf(Bsdf::Diffuse(d)) if self.nodes.len() == 1 => Some((d.reflectance, None)),
            Node::TwoSided { front, back } => Some((leaf(*front)?, Some(leaf(*back)?))),
            _ => None,
        }
    }

    #[inline]
    pub(crate) fn node(&self, i: u8) -> &Node {
        self.nodes.get(i as usize).unwrap_or(&Node::Null)
    }

    /// f(wi, wo) |cos θo| (non-delta lobes only).
    #[inline]
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Spectrum {
        self.eval_node(0, wi, wo)
    }

    /// Solid-angle density with which [`ShadingBsdf::sample`] produces `wo` (non-delta).
    #[inline]
    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        self.pdf_node(0, wi, wo)
    }

    /// Samples an outgoing direction; `u1` picks lobes (and nested BSDFs), `u2` the
    /// direction.
    #[inline]
    pub fn sample(&self, wi: Vec3, u1: f32, u2: Vec2) -> Option<BsdfSample> {
        self.sample_node(0, wi, u1, u2)
    }

    /// The same BSDF in importance transport mode (Mitsuba's `TransportMode::Importance`,
    /// pbrt's `TransportMode::Importance`), for light tracing: `wi` then points to where the
    /// light came from and `wo` onwards, and refraction does not scale the transported
    /// quantity by 1/η² as it scales radiance (Veach 1997, §5.2): eval and sample weights of
    /// refracting lobes are those of radiance mode times η_it², η_it the relative IOR seen
    /// from `wi`'s side ([`Bsdf::importance_scale`]). Directions and densities are unchanged.
    pub fn importance(mut self) -> Self {
        self.importance = true;
        self
    }

    /// [`ShadingBsdf::importance`] in place.
    pub fn set_importance(&mut self) {
        self.importance = true;
    }

    /// Whether the BSDF has a non-delta lobe for `wi` (emitter sampling is useful).
    pub fn has_smooth_lobe(&self, wi: Vec3) -> bool {
        self.smooth_node(0, wi)
    }

    /// Every outcome of [`ShadingBsdf::sample`] with its probability as `pdf`, where the
    /// BSDF is one plain `dielectric` or `thindielectric` in radiance mode
    /// ([`Bsdf::delta_branches`]); `None` otherwise.
    pub fn delta_branches(&self, wi: Vec3) -> Option<ArrayVec<BsdfSample, 2>> {
        if self.importance {
            return None;
        }
        self.as_leaf()?.delta_branches(wi)
    }

    /// Whether the BSDF can send light to the other side of the surface.
    pub fn is_transmissive(&self) -> bool {
        self.nodes.iter().any(|n| match n {
            Node::Leaf(b) => b.is_transmissive(),
            Node::Mask { .. } | Node::Null => true,
            _ => false,
        })
    }

    /// The fraction of light passing straight through the surface from `wi` (Mitsuba's
    /// `eval_null_transmission`): 1 for `null`, the holes of a mask, the thin dielectric's
    /// transmission, blended and two-sided as those adapters blend and flip.
    pub fn null_transmission(&self, wi: Vec3) -> Spectrum {
        self.null_node(0, wi)
    }

    fn null_node(&self, i: u8, wi: Vec3) -> Spectrum {
        match self.node(i) {
            Node::Leaf(b) => b.null_transmission(wi),
            Node::TwoSided { front, back } => {
                if front == back {
                    self.null_node(*front, Vec3::new(wi.x, wi.y, wi.z.abs()))
                } else if wi.z > 0.0 {
                    self.null_node(*front, wi)
                } else if wi.z < 0.0 {
                    self.null_node(*back, twosided::flip(wi))
                } else {
                    Spectrum::ZERO
                }
            }
            Node::Mask { opacity, nested } => {
                Spectrum::ONE - (Spectrum::ONE - self.null_node(*nested, wi)) * *opacity
            }
            Node::Blend { weight, nested } => {
                self.null_node(nested[0], wi) * (1.0 - weight)
                    + self.null_node(nested[1], wi) * *weight
            }
            // Mitsuba's normal and bump maps do not pass null transmission on (BSDF default: 0).
            Node::Perturb { .. } => Spectrum::ZERO,
            Node::Null => Spectrum::ONE,
        }
    }

    pub(crate) fn eval_node(&self, i: u8, wi: Vec3, wo: Vec3) -> Spectrum {
        match self.node(i) {
            Node::Leaf(b) if self.importance => b.eval(wi, wo) * b.importance_scale(wi, wo),
            Node::Leaf(b) => b.eval(wi, wo),
            Node::TwoSided { front, back } => twosided::eval(self, *front, *back, wi, wo),
            Node::Mask { opacity, nested } => mask::eval(self, *opacity, *nested, wi, wo),
            Node::Blend { weight, nested } => blendbsdf::eval(self, *weight, *nested, wi, wo),
            Node::Perturb {
                perturbation,
                nested,
            } => perturbation.eval(self, *nested, wi, wo),
            Node::Null => Spectrum::ZERO,
        }
    }

    pub(crate) fn pdf_node(&self, i: u8, wi: Vec3, wo: Vec3) -> f32 {
        match self.node(i) {
            Node::Leaf(b) => b.pdf(wi, wo),
            Node::TwoSided { front, back } => twosided::pdf(self, *front, *back, wi, wo),
            Node::Mask { opacity, nested } => mask::pdf(self, *opacity, *nested, wi, wo),
            Node::Blend { weight, nested } => blendbsdf::pdf(self, *weight, *nested, wi, wo),
            Node::Perturb {
                perturbation,
                nested,
            } => perturbation.pdf(self, *nested, wi, wo),
            Node::Null => 0.0,
        }
    }

    pub(crate) fn sample_node(&self, i: u8, wi: Vec3, u1: f32, u2: Vec2) -> Option<BsdfSample> {
        match self.node(i) {
            Node::Leaf(b) if self.importance => {
                let mut bs = b.sample(wi, u1, u2)?;
                bs.weight *= b.importance_scale(wi, bs.wo);
                Some(bs)
            }
            Node::Leaf(b) => b.sample(wi, u1, u2),
            Node::TwoSided { front, back } => twosided::sample(self, *front, *back, wi, u1, u2),
            Node::Mask { opacity, nested } => mask::sample(self, *opacity, *nested, wi, u1, u2),
            Node::Blend { weight, nested } => blendbsdf::sample(self, *weight, *nested, wi, u1, u2),
            Node::Perturb {
                perturbation,
                nested,
            } => perturbation.sample(self, *nested, wi, u1, u2),
            Node::Null => Some(null_sample(wi, 1.0)),
        }
    }

    pub(crate) fn smooth_node(&self, i: u8, wi: Vec3) -> bool {
        match self.node(i) {
            Node::Leaf(b) => b.has_smooth_lobe(wi),
            Node::TwoSided { front, back } => {
                if wi.z < 0.0 {
                    self.smooth_node(*back, twosided::flip(wi))
                } else {
                    self.smooth_node(*front, wi)
                }
            }
            Node::Mask { nested, opacity } => *opacity > 0.0 && self.smooth_node(*nested, wi),
            Node::Blend { weight, nested } => {
                (*weight < 1.0 && self.smooth_node(nested[0], wi))
                    || (*weight > 0.0 && self.smooth_node(nested[1], wi))
            }
            // The perturbed frame may turn wi to either side: ask the nested BSDF with both.
            Node::Perturb { nested, .. } => {
                self.smooth_node(*nested, wi) || self.smooth_node(*nested, twosided::flip(wi))
            }
            Node::Null => false,
        }
    }
}

/// Light passing straight through (Mitsuba's `Null` lobe): `wo = −wi`, a delta event of
/// probability `pdf` and weight 1.
pub(crate) fn null_sample(wi: Vec3, pdf: f32) -> BsdfSample {
    BsdfSample {
        wo: -wi,
        pdf,
        weight: Spectrum::ONE,
        eta: 1.0,
        delta: true,
        null: true,
    }
}
