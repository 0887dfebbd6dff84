//! Materials and textures of the scene, built once from their descriptions: leaf BSDFs with
//! their constant parameters (and Fresnel tables, and the sampling weights Mitsuba derives
//! from the textures' means), the textures that vary the others, and the adapters nesting
//! other materials by index. Equal BSDF descriptions (a `<bsdf id>` used by many shapes)
//! become one material, and a bitmap used by several textures is loaded once.

use crate::bsdf::{BsdfParam, PluginCache};
use crate::error::{Error, Result};
use crate::material::{Material, MAX_NODES};
use crate::scene::description::{BsdfDesc, TextureDesc, VolumeDesc};
use crate::spectrum::Mode;
use crate::texture::bitmap::{BitmapTexture, Format, TexImage};
use crate::texture::{
    Checkerboard, ColorValue, Lookup, MeshAttributeTexture, Texture, UvTransform, VolumeTexture,
};
use glam::{DMat4, DVec3, Vec3};
use std::path::PathBuf;
use std::sync::Arc;

/// Builds the scene's material list.
#[derive(Default)]
pub struct MaterialBuilder {
    pub materials: Vec<Material>,
    /// Descriptions already built, with their material index.
    built: Vec<(BsdfDesc, u32)>,
    /// Bitmaps already loaded, by file, `raw` and storage format: an image shared by
    /// several textures (or emitters) is read and stored once.
    images: Vec<((PathBuf, bool, Format), Arc<TexImage>)>,
    /// What the BSDF plugins keep across the scene's BSDFs (roughplastic's coating tables,
    /// ~0.1 s each).
    plugins: PluginCache,
    /// World space to the space the scene is built in (volume textures are looked up there).
    pub shift: DMat4,
    /// RGB or spectral: which form of each constant colour is built.
    pub mode: Mode,
}

impl MaterialBuilder {
    /// The index of the material for `d`, building it (and what it nests) if needed.
    pub fn material(&mut self, d: &BsdfDesc) -> Result<u32> {
        if let Some((_, i)) = self.built.iter().find(|(b, _)| b == d) {
            return Ok(*i);
        }
        let m = self.build(d)?;
        let i = self.materials.len() as u32;
        self.materials.push(m);
        if Material::node_count(&self.materials, i).is_none() {
            return Err(Error::Invalid(format!(
                "a BSDF nests more than {MAX_NODES} BSDFs and adapters"
            )));
        }
        self.built.push((d.clone(), i));
        Ok(i)
    }

    fn build(&mut self, d: &BsdfDesc) -> Result<Material> {
        Ok(match d {
            BsdfDesc::TwoSided { front, back } => Material::TwoSided {
                front: self.material(front)?,
                back: self.material(back)?,
            },
            BsdfDesc::Mask { opacity, nested } => Material::Mask {
                opacity: self.texture_for(opacity, Lookup::One)?,
                nested: self.material(nested)?,
            },
            BsdfDesc::Blend { weight, nested } => Material::Blend {
                weight: self.texture_for(weight, Lookup::One)?,
                nested: [self.material(&nested[0])?, self.material(&nested[1])?],
            },
            BsdfDesc::NormalMap {
                normalmap,
                nested,
                flip_invalid_normals,
                use_shadowing_function,
            } => Material::NormalMap {
                normalmap: self.texture_for(normalmap, Lookup::Three)?,
                nested: self.material(nested)?,
                flip_invalid_normals: *flip_invalid_normals,
                use_shadowing_function: *use_shadowing_function,
            },
            BsdfDesc::BumpMap {
                height,
                scale,
                nested,
                flip_invalid_normals,
                use_shadowing_function,
            } => Material::BumpMap {
                height: self.texture_for(height, Lookup::One)?,
                scale: *scale as f32,
                nested: self.material(nested)?,
                flip_invalid_normals: *flip_invalid_normals,
                use_shadowing_function: *use_shadowing_function,
            },
            BsdfDesc::Null => Material::Null,
            leaf => self.leaf(leaf)?,
        })
    }

    /// A leaf BSDF: the template with every parameter at its texture's mean (constants at
    /// their value), and the textures of the parameters that vary.
    fn leaf(&mut self, d: &BsdfDesc) -> Result<Material> {
        let mut textures: Vec<(BsdfParam, Texture)> = Vec::new();
        // A colour parameter: its constant value or its texture's mean (for the template).
        let mut param = |this: &mut Self, p: BsdfParam, t: &TextureDesc| -> Result<Vec3> {
            let lookup = if p.is_scalar() {
                Lookup::One
            } else {
                Lookup::Spectrum
            };
            let tex = this.texture_for(t, lookup)?;
            let v = match &tex {
                Texture::Constant { rgb, scalar } => {
                    if p.is_scalar() {
                        Vec3::splat(*scalar)
                    } else {
                        *rgb
                    }
                }
                other => Vec3::splat(other.mean()),
            };
            if !tex.is_constant() {
                textures.push((p, tex));
            }
            Ok(v)
        };
        use BsdfParam as P;
        let template = match d {
            BsdfDesc::Table { plugin, params } => {
                let info = crate::bsdf::table_plugin(plugin)
                    .ok_or_else(|| Error::Invalid(format!("no BSDF plugin named '{plugin}'")))?;
                let mut values = Vec::with_capacity(params.len());
                for (i, (spec, t)) in info.params.iter().zip(params).enumerate() {
                    let i = i as u8;
                    let slot = if spec.is_scalar() {
                        P::TableScalar(i)
                    } else {
                        P::TableColor(i)
                    };
                    values.push(if spec.kind.texture_allowed() {
                        param(self, slot, t)?.as_dvec3()
                    } else {
                        // Plain numbers, flags, choices and IORs exactly as given.
                        DVec3::splat(t.constant_scalar().unwrap_or(spec.default))
                    });
                }
                (info.build)(&values, &mut self.plugins)
            }
            _ => unreachable!("adapters are built by MaterialBuilder::build"),
        };
        Ok(Material::Leaf { template, textures })
    }

    /// A texture from its description that will be looked up as `lookup`: in spectral mode,
    /// one clear error where Mitsuba's spectral variants refuse that lookup at render time
    /// ([`Texture::spectral_refusal`]).
    pub fn texture_for(&mut self, d: &TextureDesc, lookup: Lookup) -> Result<Texture> {
        let t = self.texture(d)?;
        if self.mode == Mode::Spectral {
            if let Some(e) = t.spectral_refusal(lookup) {
                return Err(match d {
                    TextureDesc::Bitmap(b) => {
                        Error::scene(&b.location, format!("{}: {e}", b.filename.display()))
                    }
                    _ => Error::Invalid(e),
                });
            }
        }
        Ok(t)
    }

    /// A texture from its description.
    pub fn texture(&mut self, d: &TextureDesc) -> Result<Texture> {
        Ok(match d {
            TextureDesc::Constant { rgb, scalar, .. } if self.mode == Mode::Rgb => {
                Texture::Constant {
                    rgb: rgb.as_vec3(),
                    scalar: *scalar as f32,
                }
            }
            TextureDesc::Constant {
                rgb,
                scalar,
                spectral,
            } => {
                let value = ColorValue::spectral(spectral);
                match &value {
                    // A flat spectrum is that value at every wavelength: the RGB form serves
                    // (and keeps such materials prebuilt).
                    ColorValue::Uniform { value: v, .. } if value.is_constant() => {
                        Texture::Constant {
                            rgb: Vec3::splat(*v),
                            scalar: *v,
                        }
                    }
                    _ => Texture::Spectral {
                        scalar: value.spectral_mean().unwrap_or(*scalar as f32),
                        value: Box::new(value),
                        rgb: rgb.as_vec3(),
                    },
                }
            }
            TextureDesc::Raw(v) => Texture::Constant {
                rgb: v.as_vec3(),
                scalar: v.x as f32,
            },
            TextureDesc::Checkerboard {
                color0,
                color1,
                to_uv,
            } => Texture::Checkerboard(Box::new(Checkerboard {
                color0: self.texture(color0)?,
                color1: self.texture(color1)?,
                to_uv: UvTransform::from_mat3(*to_uv),
            })),
            TextureDesc::MeshAttribute { name, scale } => {
                Texture::MeshAttribute(MeshAttributeTexture {
                    name: name.clone(),
                    scale: *scale as f32,
                    spectral: self.mode == Mode::Spectral,
                })
            }
            TextureDesc::Bitmap(b) => {
                let key = (b.filename.clone(), b.raw, b.format);
                let image = match self.images.iter().find(|(k, _)| *k == key) {
                    Some((_, img)) => img.clone(),
                    None => {
                        let img = match self.mode {
                            Mode::Rgb => TexImage::load_with_format(&b.filename, b.raw, b.format),
                            Mode::Spectral => TexImage::load_spectral(&b.filename, b.raw, b.format),
                        }
                        .map_err(|e| Error::scene(&b.location, e))?;
                        let img = Arc::new(img);
                        self.images.push((key, img.clone()));
                        img
                    }
                };
                Texture::Bitmap(BitmapTexture::new(image, b.filter, b.wrap, b.to_uv))
            }
            TextureDesc::Volume(v) => {
                let scalar = match v {
                    // Mitsuba's `constvolume::eval_1`: the value's `mean()` (in spectral
                    // mode the spectrum's, as for a constant texture).
                    VolumeDesc::Constant { value, .. } => {
                        let rgb = TextureDesc::color(value.clone())
                            .constant_scalar()
                            .unwrap_or(0.0) as f32;
                        match self.mode {
                            Mode::Rgb => rgb,
                            Mode::Spectral => ColorValue::spectral(&value.spectral)
                                .spectral_mean()
                                .unwrap_or(rgb),
                        }
                    }
                    VolumeDesc::Grid { .. } => 0.0,
                };
                Texture::Volume(VolumeTexture::new(
                    super::volume(v, self.shift, self.mode)?,
                    scalar,
                ))
            }
        })
    }
}
