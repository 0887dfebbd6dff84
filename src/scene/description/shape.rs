//! Shapes: `rectangle`, `cube`, `disk`, `sphere`, `cylinder`, meshes from `obj`, `ply` and
//! `serialized` files, `sdfgrid`, and `shapegroup` + `instance`.

use super::*;

#[derive(Clone, Debug, PartialEq)]
pub enum ShapeKind {
    Rectangle,
    Cube,
    Disk,
    Sphere {
        center: DVec3,
        radius: f64,
    },
    Cylinder {
        p0: DVec3,
        p1: DVec3,
        radius: f64,
    },
    Obj {
        filename: PathBuf,
        face_normals: bool,
        flip_tex_coords: bool,
    },
    Ply {
        filename: PathBuf,
        face_normals: bool,
        flip_tex_coords: bool,
    },
    /// Mitsuba's `serialized` mesh format; `shape_index` picks one mesh of the file.
    Serialized {
        filename: PathBuf,
        shape_index: u32,
        face_normals: bool,
    },
    /// Mitsuba's `sdfgrid`: the zero level set of a signed distance grid (a `.vol` file)
    /// over the unit cube; `analytic_normals` selects `normals="analytic"` over "smooth".
    SdfGrid {
        filename: PathBuf,
        analytic_normals: bool,
    },
    /// Mitsuba's `instance` of a `shapegroup`: index into `SceneDescription::shape_groups`.
    Instance {
        group: usize,
    },
}

#[derive(Clone, Debug, PartialEq)]
pub struct ShapeDesc {
    pub kind: ShapeKind,
    pub to_world: DMat4,
    pub flip_normals: bool,
    pub bsdf: BsdfDesc,
    pub emitter: Option<EmitterDesc>,
    /// The emitter's `sampling_weight` (1 without an emitter).
    pub emitter_weight: f64,
    /// Indices into [`SceneDescription::media`] of the media inside and outside the shape.
    pub interior: Option<usize>,
    pub exterior: Option<usize>,
    pub location: Location,
}

/// Mitsuba's `shapegroup`: shapes made available for instancing, invisible on their own.
#[derive(Clone, Debug, PartialEq)]
pub struct ShapeGroupDesc {
    pub shapes: Vec<ShapeDesc>,
    pub location: Location,
}

/// Reads Mitsuba's `silhouette_sampling_weight` (every shape): a weight of its projective
/// differentiable integrators, which have no part in rendering an image.
fn silhouette_weight(p: &mut Props, o: &Object) -> Result<()> {
    let w = p.float("silhouette_sampling_weight", 1.0)?;
    if !(w >= 0.0 && w.is_finite()) {
        return Err(Error::scene(
            &o.location,
            format!(
                "silhouette_sampling_weight of {} must be finite and >= 0, got {w}",
                describe(o)
            ),
        ));
    }
    Ok(())
}

/// Reads `face_normals` (every mesh format).
fn face_normals(p: &mut Props) -> Result<bool> {
    p.boolean("face_normals", false)
}

pub(super) fn shape_desc(cx: &Ctx, o: &Arc<Object>) -> Result<ShapeDesc> {
    let mut p = Props::new(o);
    let to_world = p.transform("to_world")?;
    let mut instance_of = None;
    silhouette_weight(&mut p, o)?;
    let kind = match o.plugin.as_str() {
        // Mitsuba's rectangle and cube are meshes and take `face_normals`; their faces are
        // flat, so face and vertex normals are the same.
        "rectangle" => {
            face_normals(&mut p)?;
            ShapeKind::Rectangle
        }
        "cube" => {
            face_normals(&mut p)?;
            ShapeKind::Cube
        }
        "disk" => ShapeKind::Disk,
        "sphere" => {
            let center = p.point("center", DVec3::ZERO)?;
            let radius = p.float("radius", 1.0)?;
            positive(radius, "radius", o)?;
            ShapeKind::Sphere { center, radius }
        }
        "cylinder" => {
            let p0 = p.point("p0", DVec3::ZERO)?;
            let p1 = p.point("p1", DVec3::Z)?;
            let radius = p.float("radius", 1.0)?;
            positive(radius, "radius", o)?;
            if !(p0.is_finite() && p1.is_finite()) || p0 == p1 {
                return Err(Error::scene(
                    &o.location,
                    format!(
                        "p0 and p1 of {} must be distinct finite points",
                        describe(o)
                    ),
                ));
            }
            ShapeKind::Cylinder { p0, p1, radius }
        }
        "obj" => ShapeKind::Obj {
            filename: file_parameter(cx, &mut p, o)?,
            face_normals: face_normals(&mut p)?,
            flip_tex_coords: p.boolean("flip_tex_coords", true)?,
        },
        "ply" => ShapeKind::Ply {
            filename: file_parameter(cx, &mut p, o)?,
            face_normals: face_normals(&mut p)?,
            flip_tex_coords: p.boolean("flip_tex_coords", false)?,
        },
        "serialized" => {
            let filename = file_parameter(cx, &mut p, o)?;
            let shape_index = p.int("shape_index", 0)?;
            if !(0..=u32::MAX as i64).contains(&shape_index) {
                return Err(Error::scene(
                    &o.location,
                    format!(
                        "shape_index of {} must be >= 0, got {shape_index}",
                        describe(o)
                    ),
                ));
            }
            ShapeKind::Serialized {
                filename,
                shape_index: shape_index as u32,
                face_normals: face_normals(&mut p)?,
            }
        }
        "sdfgrid" => {
            let filename = file_parameter(cx, &mut p, o)?;
            let analytic_normals = match p.string("normals")? {
                None | Some(("smooth", _)) => false,
                Some(("analytic", _)) => true,
                Some((s, loc)) => {
                    return Err(Error::scene(
                        loc,
                        format!(
                            "invalid normals mode '{s}' of {}: must be \"analytic\" or \"smooth\"",
                            describe(o)
                        ),
                    ))
                }
            };
            ShapeKind::SdfGrid {
                filename,
                analytic_normals,
            }
        }
        "instance" => {
            let mut group = None;
            for Child { object: c, .. } in &o.children {
                if c.tag != "shape" || c.plugin != "shapegroup" {
                    return Err(Error::scene(
                        &c.location,
                        format!(
                            "{} cannot be nested in {}: an instance takes one shapegroup",
                            describe(c),
                            describe(o)
                        ),
                    ));
                }
                if group.is_some() {
                    return Err(Error::scene(
                        &c.location,
                        format!("{} takes a single shapegroup", describe(o)),
                    ));
                }
                group = Some(shape_group(cx, c)?);
            }
            let group = group.ok_or_else(|| {
                Error::scene(
                    &o.location,
                    format!("{} needs a <ref> to a shapegroup", describe(o)),
                )
            })?;
            instance_of = Some(group);
            ShapeKind::Instance { group }
        }
        "shapegroup" => {
            return Err(Error::scene(
                &o.location,
                format!(
                    "{} can only be declared at the scene level (and used by instances)",
                    describe(o)
                ),
            ))
        }
        _ => return Err(unsupported_plugin(o)),
    };
    // Mitsuba's meshes and analytic shapes take flip_normals; an instance does not.
    let flip_normals = if instance_of.is_some() {
        false
    } else {
        p.boolean("flip_normals", false)?
    };
    p.finish()?;
    if !to_world.is_finite() {
        return Err(Error::scene(
            &o.location,
            format!("to_world of {} is not finite", describe(o)),
        ));
    }
    let mut bsdf = None;
    let mut emitter = None;
    let mut interior = None;
    let mut exterior = None;
    if instance_of.is_none() {
        for Child { name, object: c } in &o.children {
            if c.tag == "medium" {
                let slot = match name.as_deref() {
                    Some("interior") => &mut interior,
                    Some("exterior") => &mut exterior,
                    _ => {
                        return Err(Error::scene(
                            &c.location,
                            format!(
                                "a medium in {} must be named \"interior\" or \"exterior\"",
                                describe(o)
                            ),
                        ))
                    }
                };
                if slot.is_some() {
                    return Err(Error::scene(
                        &c.location,
                        format!(
                            "{} has two {} media",
                            describe(o),
                            name.as_deref().unwrap_or("")
                        ),
                    ));
                }
                *slot = Some(medium_index(cx, c)?);
                continue;
            }
            match c.tag.as_str() {
                // Mitsuba keeps a texture nested in a shape as a named attribute of the shape
                // (for its Python API's eval_attribute); no BSDF or emitter reads it. Checked.
                "texture" => {
                    super::texture::texture_desc(cx, c, crate::spectrum::ColorRole::Reflectance)?;
                }
                // A shape that is a sensor (Mitsuba's irradiancemeter) measures, it renders
                // no image.
                "sensor" => {
                    return Err(Error::scene(
                        &c.location,
                        format!(
                            "unsupported plugin {}: penumbra does not implement sensors attached to shapes (Mitsuba's irradiancemeter)",
                            describe(c)
                        ),
                    ))
                }
                "bsdf" if bsdf.is_none() => bsdf = Some(bsdf_desc(cx, c)?),
                "emitter" if emitter.is_none() => emitter = Some(area_emitter_desc(cx, c)?),
                "bsdf" | "emitter" => {
                    return Err(Error::scene(
                        &c.location,
                        format!("{} has more than one <{}>", describe(o), c.tag),
                    ))
                }
                _ => return Err(unexpected_child(o, c)),
            }
        }
    }
    if emitter.is_some() && matches!(kind, ShapeKind::SdfGrid { .. }) {
        return Err(Error::scene(
            &o.location,
            format!("{} cannot carry an emitter", describe(o)),
        ));
    }
    // Mitsuba gives a shape without a BSDF a diffuse one: reflectance 0.5, or 0 (black) when
    // the shape is an emitter, so that a visible light does not also reflect.
    let bsdf = bsdf.unwrap_or_else(|| {
        if emitter.is_some() {
            BsdfDesc::diffuse(TextureDesc::value(0.0))
        } else {
            BsdfDesc::default_diffuse()
        }
    });
    let (emitter, emitter_weight) = match emitter {
        Some((e, w)) => (Some(e), w),
        None => (None, 1.0),
    };
    Ok(ShapeDesc {
        kind,
        to_world,
        flip_normals,
        bsdf,
        emitter,
        emitter_weight,
        interior,
        exterior,
        location: o.location.clone(),
    })
}

/// The index of the shape group declared by `o` in `cx.groups`, parsing it on first use.
/// Mitsuba refuses emitters, nested groups and instances inside a group.
pub(super) fn shape_group(cx: &Ctx, o: &Arc<Object>) -> Result<usize> {
    let key = Arc::as_ptr(o);
    if let Some(i) = cx.groups.borrow().iter().position(|(k, _)| *k == key) {
        return Ok(i);
    }
    // Read by Mitsuba's Shape base class; a group is placed by its instances' transforms
    // and ignores its own, as Mitsuba's ShapeGroup does.
    let mut p = Props::new(o);
    p.transform("to_world")?;
    silhouette_weight(&mut p, o)?;
    p.finish()?;
    let mut shapes = Vec::new();
    for Child { object: c, .. } in &o.children {
        if c.tag != "shape" {
            return Err(unexpected_child(o, c));
        }
        if matches!(c.plugin.as_str(), "shapegroup" | "instance") {
            return Err(Error::scene(
                &c.location,
                format!("{} cannot be nested in a shapegroup", describe(c)),
            ));
        }
        let s = shape_desc(cx, c)?;
        if s.interior.is_some() || s.exterior.is_some() {
            return Err(Error::scene(
                &c.location,
                "penumbra does not support media on shapes inside a shapegroup",
            ));
        }
        if s.emitter.is_some() {
            return Err(Error::scene(
                &c.location,
                "instancing of emitters is not supported (as in Mitsuba): a shape in a shapegroup cannot carry an emitter",
            ));
        }
        shapes.push(s);
    }
    let mut groups = cx.groups.borrow_mut();
    groups.push((
        key,
        ShapeGroupDesc {
            shapes,
            location: o.location.clone(),
        },
    ));
    Ok(groups.len() - 1)
}
