//! `<transform>` properties: each operation (`translate`, `rotate`, `scale`, `matrix`,
//! `lookat`) computed as Mitsuba computes it, and their composition into one matrix.

use super::elem::Elem;
use super::files::SourceFile;
use super::{Loader, Property, Value};
use crate::error::Result;
use glam::{DMat3, DMat4, DVec3};

impl Loader {
    /// Parses `<transform name="..">` and its operations into a property. Other nodes inside
    /// it, and whatever is inside an operation, are ignored, as in Mitsuba.
    pub(super) fn parse_transform(&mut self, file: &SourceFile, elem: &Elem) -> Result<Property> {
        elem.check_attrs(&["name"])?;
        let name = elem.property_name()?;
        let mut matrix = DMat4::IDENTITY;
        for child in elem.node.children() {
            let op = self.element(file, child)?;
            let m = transform_op(&op)?;
            if op.tag == "rotate" {
                let axis = op.xyz(&op.xyz_attrs()?, 0.0)?;
                if (axis.length_squared() - 1.0).abs() > 1e-6 {
                    self.warnings.push(format!(
                        "{}: {} has an axis of length {:.6}: Mitsuba does not normalise rotation axes, so this also scales and shears (penumbra does as Mitsuba)",
                        op.location,
                        op.desc,
                        axis.length()
                    ));
                }
            }
            // Each operation applies after the previous ones, as in Mitsuba.
            matrix = m * matrix;
            if !matrix.is_finite()
                || matrix
                    .abs()
                    .to_cols_array()
                    .iter()
                    .any(|x| *x > f32::MAX as f64)
            {
                return Err(op.error(format!(
                    "{} makes the transform {} non-finite or beyond single precision (3.4e38)",
                    op.desc, elem.desc
                )));
            }
        }
        Ok(Property {
            name,
            value: Value::Transform(matrix),
            location: elem.location.clone(),
        })
    }
}

/// The matrix of one operation inside a `<transform>`.
fn transform_op(op: &Elem) -> Result<DMat4> {
    let xyz_allowed = |extra: &[&'static str]| -> Vec<&'static str> {
        let mut allowed = vec!["x", "y", "z"];
        if op.get("value").is_some() {
            allowed.push("value");
        }
        allowed.extend_from_slice(extra);
        allowed
    };
    match op.tag.as_str() {
        "translate" => {
            let parts = op.xyz_attrs()?;
            op.check_attrs(&xyz_allowed(&[]))?;
            Ok(DMat4::from_translation(op.xyz(&parts, 0.0)?))
        }
        "scale" => {
            let parts = op.xyz_attrs()?;
            op.check_attrs(&xyz_allowed(&[]))?;
            Ok(DMat4::from_scale(op.xyz(&parts, 1.0)?))
        }
        "rotate" => {
            let parts = op.xyz_attrs()?;
            op.check_attrs(&xyz_allowed(&["angle"]))?;
            op.require("angle")?;
            let axis = op.xyz(&parts, 0.0)?;
            if axis == DVec3::ZERO {
                return Err(op.error(format!("{} has a zero rotation axis", op.desc)));
            }
            let angle = op.float_attr("angle")?;
            Ok(mitsuba_rotate(axis, angle))
        }
        "matrix" => {
            op.check_attrs(&["value"])?;
            let numbers = op.numbers(op.require("value")?)?;
            if let Ok(rows) = <[f64; 16]>::try_from(numbers.as_slice()) {
                Ok(DMat4::from_cols_array(&rows).transpose())
            } else if let Ok(rows) = <[f64; 9]>::try_from(numbers.as_slice()) {
                Ok(DMat4::from_mat3(DMat3::from_cols_array(&rows).transpose()))
            } else {
                Err(op.error(format!(
                    "<matrix> requires 16 (or 9) values, found {} in {}",
                    numbers.len(),
                    op.desc
                )))
            }
        }
        "lookat" => {
            op.check_attrs(&["origin", "target", "up"])?;
            let origin = op.vec3("origin", op.require("origin")?)?;
            let target = op.vec3("target", op.require("target")?)?;
            // An absent or empty `up` is zero: Mitsuba then picks one.
            let up = match op.get("up").filter(|up| !up.is_empty()) {
                Some(up) => op.vec3("up", up)?,
                None => DVec3::ZERO,
            };
            look_at(origin, target, up).map_err(|m| op.error(format!("{m} in {}", op.desc)))
        }
        _ => Err(op.error(format!(
            "unexpected {} inside <transform>: only translate, rotate, scale, matrix and lookat are allowed",
            op.desc
        ))),
    }
}

/// Mitsuba's `rotate`: cos θ · I + (1 − cos θ) · a aᵀ + sin θ · [a]×, with the axis `a` as
/// written, NOT normalised (Mitsuba 3.9.1's `Transform::rotate` does not normalise it). For a
/// unit axis this is the rotation by `angle` degrees about `a`; for another axis it also
/// scales and shears, and Mitsuba's own hello.xml (axis 0, 1, 1) relies on it. The parser
/// warns about such axes.
pub(super) fn mitsuba_rotate(a: DVec3, angle: f64) -> DMat4 {
    let (s, c) = angle.to_radians().sin_cos();
    let outer = DMat3::from_cols(a * a.x, a * a.y, a * a.z);
    let cross = DMat3::from_cols(
        DVec3::new(0.0, a.z, -a.y),
        DVec3::new(-a.z, 0.0, a.x),
        DVec3::new(a.y, -a.x, 0.0),
    );
    DMat4::from_mat3(DMat3::IDENTITY * c + outer * (1.0 - c) + cross * s)
}

/// Mitsuba's `dr::normalize`: `v · (1 / |v|)`, NaN for a zero vector (or one whose squared
/// length underflows).
fn mitsuba_normalize(v: DVec3) -> DVec3 {
    v * (1.0 / v.dot(v).sqrt())
}

/// Mitsuba's `look_at`: columns (left, new_up, dir, origin), with dir = normalize(target −
/// origin) and left = normalize(up × dir), computed as Mitsuba computes them; refused where
/// Mitsuba's result is NaN (target at origin, `up` parallel to the direction). An `up` of
/// exactly zero is replaced by Mitsuba's choice (`coordinate_system(dir)`).
fn look_at(origin: DVec3, target: DVec3, up: DVec3) -> std::result::Result<DMat4, String> {
    let dir = mitsuba_normalize(target - origin);
    if dir.is_nan() {
        return Err("target coincides with origin".to_string());
    }
    let up = if up == DVec3::ZERO {
        crate::geometry::coordinate_system(dir).0
    } else {
        up
    };
    let left = mitsuba_normalize(up.cross(dir));
    if left.is_nan() {
        return Err("up vector is parallel to the viewing direction".to_string());
    }
    let new_up = dir.cross(left);
    let m = DMat4::from_cols(
        left.extend(0.0),
        new_up.extend(0.0),
        dir.extend(0.0),
        origin.extend(1.0),
    );
    if m.is_finite() {
        Ok(m)
    } else {
        Err("non-finite look-at transform".to_string())
    }
}
