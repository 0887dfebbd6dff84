//! Materials: the scene's BSDF plugins with their textures, and the BSDF they become at a
//! shading point (pbrt-v4's `Material::GetBxDF`, Mitsuba's BSDFs that read textures).
//!
//! A [`Material`] is built once per `<bsdf>` of the scene. Leaf BSDFs (diffuse, conductors,
//! dielectrics, plastics) keep a template [`Bsdf`] with everything that does not vary over the
//! surface already computed (Fresnel tables, sampling weights from the textures' means, as
//! Mitsuba computes them), and the textures that drive their other parameters. Mitsuba's
//! adapter plugins nest other BSDFs by index into the scene's material list:
//!
//! | plugin | file | what it does |
//! |---|---|---|
//! | `twosided` | [`twosided`] | a one-sided BSDF (or two) seen from both sides |
//! | `mask` | [`mask`] | `opacity` of the nested BSDF, the rest passes through (null) |
//! | `blendbsdf` | [`blendbsdf`] | (1 − `weight`) · first + `weight` · second |
//! | `normalmap` | [`normalmap`] | the nested BSDF in a frame tilted by a normal map |
//! | `bumpmap` | [`bumpmap`] | the nested BSDF in a frame tilted by a height map's gradient |
//! | `null` | here | no interaction: light passes straight through |
//!
//! At a shading point, [`Material`]s become a [`ShadingBsdf`]: a small tree of plain BSDFs
//! with every texture looked up once, kept on the stack (no allocation).

pub mod blendbsdf;
pub mod bumpmap;
pub mod mask;
pub mod normalmap;
pub mod shading;
pub mod twosided;

pub use shading::{Node, ShadingBsdf, MAX_NODES};

use crate::bsdf::{Bsdf, BsdfParam};
use crate::geometry::Frame;
use crate::spectrum::Spectrum;
use crate::texture::{Texture, TextureContext};
use glam::Vec3;

/// A BSDF plugin of the scene, built once (a few per scene: size differences do not matter).
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum Material {
    /// A plain BSDF: `template` holds its constant parameters; `textures` set the others at
    /// each shading point.
    Leaf {
        template: Bsdf,
        textures: Vec<(BsdfParam, Texture)>,
    },
    /// Mitsuba's `twosided`: indices of the front and back materials (the same one twice when
    /// only one was given).
    TwoSided { front: u32, back: u32 },
    /// Mitsuba's `mask`.
    Mask { opacity: Texture, nested: u32 },
    /// Mitsuba's `blendbsdf`.
    Blend { weight: Texture, nested: [u32; 2] },
    /// Mitsuba's `normalmap`.
    NormalMap {
        normalmap: Texture,
        nested: u32,
        flip_invalid_normals: bool,
        use_shadowing_function: bool,
    },
    /// Mitsuba's `bumpmap`.
    BumpMap {
        height: Texture,
        scale: f32,
        nested: u32,
        flip_invalid_normals: bool,
        use_shadowing_function: bool,
    },
    /// Mitsuba's `null`.
    Null,
}

/// What building a [`ShadingBsdf`] needs of the shading point: the texture lookup context,
/// and for bump maps the shading frame, the position partials and the geometric normal (all
/// in world space).
#[derive(Clone, Copy, Debug)]
pub struct ShadingContext<'a> {
    pub tex: TextureContext<'a>,
    pub frame: Frame,
    pub dp_du: Vec3,
    pub dp_dv: Vec3,
    pub ng: Vec3,
}

impl Material {
    /// The plugin's name in scene files (a leaf's BSDF, or the adapter).
    pub fn plugin_name(&self) -> &'static str {
        match self {
            Material::Leaf { template, .. } => template.plugin_name(),
            Material::TwoSided { .. } => "twosided",
            Material::Mask { .. } => "mask",
            Material::Blend { .. } => "blendbsdf",
            Material::NormalMap { .. } => "normalmap",
            Material::BumpMap { .. } => "bumpmap",
            Material::Null => "null",
        }
    }

    /// The number of [`ShadingBsdf`] nodes the material at `root` of `materials` becomes, or
    /// `None` if it refers to a material that does not exist or nests deeper than the tree
    /// can hold (the scene builder refuses such a scene).
    pub fn node_count(materials: &[Material], root: u32) -> Option<usize> {
        fn count(m: &[Material], i: u32, depth: usize) -> Option<usize> {
            if depth > MAX_NODES {
                return None;
            }
            let children: &[u32] = match m.get(i as usize)? {
                Material::Leaf { .. } | Material::Null => &[],
                Material::TwoSided { front, back } => {
                    let f = count(m, *front, depth + 1)?;
                    let b = if back == front {
                        0
                    } else {
                        count(m, *back, depth + 1)?
                    };
                    return Some(1 + f + b);
                }
                Material::Mask { nested, .. }
                | Material::NormalMap { nested, .. }
                | Material::BumpMap { nested, .. } => std::slice::from_ref(nested),
                Material::Blend { nested, .. } => nested,
            };
            let mut n = 1;
            for c in children {
                n += count(m, *c, depth + 1)?;
            }
            Some(n)
        }
        count(materials, root, 0).filter(|&n| n <= MAX_NODES)
    }

    /// Whether material `root` is the same BSDF at every shading point: no texture other
    /// than a constant one and no normal or bump map anywhere in its tree. Such a material is
    /// built once per scene ([`crate::scene::Scene::bsdf_at`]) instead of at every hit.
    pub fn is_uniform(materials: &[Material], root: u32) -> bool {
        fn uniform(m: &[Material], i: u32, depth: usize) -> bool {
            if depth > MAX_NODES {
                return false;
            }
            let constant = |t: &[(BsdfParam, Texture)]| t.iter().all(|(_, t)| t.is_constant());
            match m.get(i as usize) {
                None => false,
                Some(Material::Leaf { textures, .. }) => constant(textures),
                Some(Material::Null) => true,
                Some(Material::TwoSided { front, back }) => {
                    uniform(m, *front, depth + 1) && uniform(m, *back, depth + 1)
                }
                Some(Material::Mask { opacity, nested }) => {
                    opacity.is_constant() && uniform(m, *nested, depth + 1)
                }
                Some(Material::Blend { weight, nested }) => {
                    weight.is_constant()
                        && uniform(m, nested[0], depth + 1)
                        && uniform(m, nested[1], depth + 1)
                }
                Some(Material::NormalMap { .. }) | Some(Material::BumpMap { .. }) => false,
            }
        }
        uniform(materials, root, 0)
    }

    /// The BSDF of material `root` at a shading point, every texture looked up once. The
    /// material must have passed [`Material::node_count`] (the scene builder checks).
    pub fn shading_bsdf(materials: &[Material], root: u32, ctx: &ShadingContext) -> ShadingBsdf {
        let mut out = ShadingBsdf::new();
        Self::shading_bsdf_into(materials, root, ctx, &mut out);
        out
    }

    /// [`Material::shading_bsdf`] written into `out` (cleared first), in place.
    pub fn shading_bsdf_into(
        materials: &[Material],
        root: u32,
        ctx: &ShadingContext,
        out: &mut ShadingBsdf,
    ) {
        out.clear();
        push(materials, root, ctx, out);
    }
}

/// A texture-driven parameter's value: the colour, or one value (`eval_1`) splatted.
#[inline]
fn lookup(param: BsdfParam, tex: &Texture, ctx: &ShadingContext) -> Spectrum {
    if param.is_scalar() {
        Spectrum::splat(tex.eval_1(&ctx.tex))
    } else {
        tex.eval(&ctx.tex)
    }
}

/// Appends the nodes of material `i` (and its children) to `out`; returns its node index.
fn push(materials: &[Material], i: u32, ctx: &ShadingContext, out: &mut ShadingBsdf) -> u8 {
    let Some(m) = materials.get(i as usize) else {
        return out.push(Node::Null);
    };
    match m {
        Material::Leaf { template, textures } => {
            let mut b = template.clone();
            for (param, tex) in textures {
                b.set_param(*param, lookup(*param, tex, ctx));
            }
            if !textures.is_empty() {
                b.params_set();
            }
            out.push(Node::Leaf(b))
        }
        Material::Null => out.push(Node::Null),
        Material::TwoSided { front, back } => {
            let at = out.push(Node::Null);
            let f = push(materials, *front, ctx, out);
            let b = if back == front {
                f
            } else {
                push(materials, *back, ctx, out)
            };
            out.set(at, Node::TwoSided { front: f, back: b });
            at
        }
        Material::Mask { opacity, nested } => {
            let at = out.push(Node::Null);
            let n = push(materials, *nested, ctx, out);
            let opacity = opacity.eval_1(&ctx.tex).clamp(0.0, 1.0);
            out.set(at, Node::Mask { opacity, nested: n });
            at
        }
        Material::Blend { weight, nested } => {
            let at = out.push(Node::Null);
            let a = push(materials, nested[0], ctx, out);
            let b = push(materials, nested[1], ctx, out);
            let weight = weight.eval_1(&ctx.tex).clamp(0.0, 1.0);
            out.set(
                at,
                Node::Blend {
                    weight,
                    nested: [a, b],
                },
            );
            at
        }
        Material::NormalMap {
            normalmap: map,
            nested,
            flip_invalid_normals,
            use_shadowing_function,
        } => {
            let at = out.push(Node::Null);
            let n = push(materials, *nested, ctx, out);
            let node = normalmap::node(map, ctx, *flip_invalid_normals, *use_shadowing_function, n);
            out.set(at, node);
            at
        }
        Material::BumpMap {
            height,
            scale,
            nested,
            flip_invalid_normals,
            use_shadowing_function,
        } => {
            let at = out.push(Node::Null);
            let n = push(materials, *nested, ctx, out);
            let node = bumpmap::node(
                height,
                *scale,
                ctx,
                *flip_invalid_normals,
                *use_shadowing_function,
                n,
            );
            out.set(at, node);
            at
        }
    }
}
