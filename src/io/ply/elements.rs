//! Assembling the `vertex` and `face` elements into the mesh: the required properties, the
//! texture-coordinate and colour renames, Mitsuba's grouping of the other properties into
//! attributes (`find_other_fields`), and the per-record checks.

use super::header::{lossy, Element, Type};
use super::values::{is_three, to_f32, to_index, Data, Value};
use crate::io::mesh::{MeshAttribute, MeshData};
use std::collections::{HashMap, HashSet};

fn find(names: &[Vec<u8>], name: &[u8]) -> Option<usize> {
    names.iter().position(|n| n == name)
}

fn has(names: &[Vec<u8>], name: &[u8]) -> bool {
    find(names, name).is_some()
}

/// Renames the first field called `from` to `to` (Mitsuba renames in place, by name).
fn rename(names: &mut [Vec<u8>], from: &[u8], to: &[u8]) {
    if let Some(i) = find(names, from) {
        names[i] = to.to_vec();
    }
}

/// An attribute to fill: its name and the source field of each channel.
struct AttributePlan {
    name: String,
    fields: Vec<usize>,
}

const POSTFIXES: [&[u8; 4]; 4] = [b"xr01", b"yg12", b"zb23", b"wa34"];

/// Mitsuba's `find_other_fields`: colours first, then the `PREFIX_C` groups, in field order.
/// `names` are the element's field names (after the texture-coordinate renames); colour
/// renames are applied to it too.
fn find_attributes(
    kind: &str,
    names: &mut [Vec<u8>],
    types: &[Type],
    reserved: &[&[u8]],
    warnings: &mut Vec<String>,
) -> Result<Vec<AttributePlan>, String> {
    let mut plans: Vec<(String, Vec<Vec<u8>>)> = Vec::new();
    if !(has(names, b"r") && has(names, b"g") && has(names, b"b"))
        && has(names, b"red")
        && has(names, b"green")
        && has(names, b"blue")
    {
        rename(names, b"red", b"r");
        rename(names, b"green", b"g");
        rename(names, b"blue", b"b");
        if has(names, b"alpha") {
            rename(names, b"alpha", b"a");
        }
    }
    if let (Some(r), true, true) = (find(names, b"r"), has(names, b"g"), has(names, b"b")) {
        let mut channels: Vec<Vec<u8>> = vec![b"r".to_vec(), b"g".to_vec(), b"b".to_vec()];
        if has(names, b"a") {
            channels.push(b"a".to_vec());
        }
        if !types[r].is_float() {
            warnings.push(format!(
                "attribute \"{kind}color\" has integer components: Mitsuba expects colours \
                 in [0, 1] and does not rescale them"
            ));
        }
        plans.push((format!("{kind}color"), channels));
    }
    let is_reserved = |n: &[u8]| reserved.contains(&n) || matches!(n, b"r" | b"g" | b"b" | b"a");

    struct Scan {
        prefix: Vec<u8>,
        category: usize,
        level: usize,
        reading: bool,
        encountered: HashSet<Vec<u8>>,
    }
    impl Scan {
        fn reset(&mut self) {
            self.prefix.clear();
            self.category = 0;
            self.level = 0;
            self.reading = false;
        }
        fn flush(
            &mut self,
            kind: &str,
            out: &mut Vec<(String, Vec<Vec<u8>>)>,
            w: &mut Vec<String>,
        ) {
            let full = format!("{kind}{}", lossy(&self.prefix));
            if self.level != 1 && self.level != 3 {
                w.push(format!(
                    "attribute \"{full}\" ignored: it must have 1 or 3 fields (had {})",
                    self.level
                ));
                self.reset();
                return;
            }
            let channels = (0..self.level)
                .map(|k| {
                    let mut n = self.prefix.clone();
                    n.push(b'_');
                    n.push(POSTFIXES[k][self.category]);
                    n
                })
                .collect();
            let suffix = if self.category == 1 { "_color" } else { "" };
            out.push((format!("{full}{suffix}"), channels));
            self.encountered.insert(std::mem::take(&mut self.prefix));
            self.reset();
        }
    }
    let mut s = Scan {
        prefix: Vec::new(),
        category: 0,
        level: 0,
        reading: false,
        encountered: HashSet::new(),
    };
    let n = names.len();
    let mut i = 0;
    'scan: while i < n {
        'field: {
            let name = &names[i];
            if is_reserved(name) {
                break 'field;
            }
            let Some(us) = name.iter().rposition(|&c| c == b'_') else {
                warnings.push(format!(
                    "property \"{}\" ignored: attributes need a \"_\" suffix",
                    lossy(name)
                ));
                if s.reading {
                    s.flush(kind, &mut plans, warnings);
                }
                break 'field;
            };
            if name.len() - us - 1 != 1 {
                warnings.push(format!(
                    "property \"{}\" ignored: the suffix must be one character",
                    lossy(name)
                ));
                if s.reading {
                    s.flush(kind, &mut plans, warnings);
                }
                break 'field;
            }
            let prefix = name[..us].to_vec();
            let ch = name[us + 1];
            if s.reading && prefix != s.prefix {
                s.flush(kind, &mut plans, warnings);
            }
            if !s.reading && s.encountered.contains(&prefix) {
                warnings.push(format!(
                    "property \"{}\" ignored: prefix already used",
                    lossy(name)
                ));
                while i < n && names[i].starts_with(&prefix) {
                    i += 1;
                }
                if i == n {
                    break 'scan;
                }
                break 'field; // Mitsuba's loop increment then skips one more field.
            }
            if !s.reading {
                let Some(category) = POSTFIXES[0].iter().position(|&c| c == ch) else {
                    warnings.push(format!(
                        "property \"{}\" ignored: an attribute cannot start with suffix '{}'",
                        lossy(name),
                        ch as char
                    ));
                    break 'field;
                };
                s.reading = true;
                s.category = category;
                s.prefix = prefix;
            } else if POSTFIXES.get(s.level).map(|p| p[s.category]) != Some(ch) {
                warnings.push(format!(
                    "attribute \"{kind}{}\" ignored: invalid suffix sequence",
                    lossy(&prefix)
                ));
                s.reset();
                while i < n && names[i].starts_with(&prefix) {
                    i += 1;
                }
                if i == n {
                    break 'scan;
                }
                // No `continue` in Mitsuba here: the level is counted up for the next
                // attribute and the field at `i` is skipped by the loop increment.
            }
            s.level += 1;
        }
        i += 1;
    }
    if s.reading {
        s.flush(kind, &mut plans, warnings);
    }

    let mut first: HashMap<&[u8], usize> = HashMap::new();
    for (i, n) in names.iter().enumerate().rev() {
        first.insert(n, i);
    }
    let mut out: Vec<AttributePlan> = Vec::new();
    let mut used = HashSet::new();
    for (name, channels) in plans {
        if !used.insert(name.clone()) {
            return Err(format!("attribute \"{name}\" defined twice"));
        }
        let fields = channels
            .iter()
            .map(|c| {
                first
                    .get(c.as_slice())
                    .copied()
                    .ok_or_else(|| format!("missing property \"{}\"", lossy(c)))
            })
            .collect::<Result<Vec<_>, _>>()?;
        out.push(AttributePlan { name, fields });
    }
    Ok(out)
}

/// Mitsuba's converter rejects an element whose renames (`s`/`t`/`texture_u`/`texture_v` to
/// `u`/`v`, `red`... to `r`...) left two fields with one name.
fn check_unique(names: &[Vec<u8>], el: &str) -> Result<(), String> {
    let mut seen = HashSet::new();
    for n in names {
        if !seen.insert(n) {
            return Err(format!(
                "the \"{el}\" element has two properties that Mitsuba both calls \"{}\"",
                lossy(n)
            ));
        }
    }
    Ok(())
}

fn require(names: &[Vec<u8>], name: &[u8], el: &str) -> Result<usize, String> {
    find(names, name)
        .ok_or_else(|| format!("the \"{el}\" element has no property \"{}\"", lossy(name)))
}

/// Checks the list counts of one record of a converted element.
fn check_lists(el: &Element, values: &[Value], r: usize) -> Result<(), String> {
    for (f, v) in el.fields.iter().zip(values) {
        if f.list_count && !is_three(*v) {
            let n = match v {
                Value::Int(i) => i.to_string(),
                Value::Float(x) => x.to_string(),
            };
            return Err(if el.name == b"face" {
                format!(
                    "face {r} has {n} vertices: Mitsuba reads triangles only (no quads or \
                     polygons)"
                )
            } else {
                format!(
                    "list \"{}\" of \"{}\" record {r} has {n} items; Mitsuba reads exactly 3",
                    lossy(&f.name[..f.name.len() - ".count".len()]),
                    lossy(&el.name)
                )
            });
        }
    }
    Ok(())
}

fn new_attributes(plans: &[AttributePlan], rows: usize) -> Vec<MeshAttribute> {
    plans
        .iter()
        .map(|p| MeshAttribute {
            name: p.name.clone(),
            channels: p.fields.len(),
            values: Vec::with_capacity(rows * p.fields.len()),
        })
        .collect()
}

fn push_attributes(
    attrs: &mut [MeshAttribute],
    plans: &[AttributePlan],
    el: &Element,
    values: &[Value],
) {
    for (a, p) in attrs.iter_mut().zip(plans) {
        a.values
            .extend(p.fields.iter().map(|&f| to_f32(values[f], el.fields[f].ty)));
    }
}

pub(super) fn read_vertices(
    el: Element,
    data: &mut Data,
    mesh: &mut MeshData,
    warnings: &mut Vec<String>,
) -> Result<(), String> {
    let count = data.check_count(&el)?;
    let mut names: Vec<Vec<u8>> = el.fields.iter().map(|f| f.name.clone()).collect();
    let types: Vec<Type> = el.fields.iter().map(|f| f.ty).collect();
    let pos = [
        require(&names, b"x", "vertex")?,
        require(&names, b"y", "vertex")?,
        require(&names, b"z", "vertex")?,
    ];
    let normal = match (
        find(&names, b"nx"),
        find(&names, b"ny"),
        find(&names, b"nz"),
    ) {
        (Some(a), Some(b), Some(c)) => Some([a, b, c]),
        _ => None,
    };
    if !(has(&names, b"u") && has(&names, b"v")) {
        if has(&names, b"texture_u") && has(&names, b"texture_v") {
            rename(&mut names, b"texture_u", b"u");
            rename(&mut names, b"texture_v", b"v");
        } else if has(&names, b"s") && has(&names, b"t") {
            rename(&mut names, b"s", b"u");
            rename(&mut names, b"t", b"v");
        }
    }
    let uv = match (find(&names, b"u"), find(&names, b"v")) {
        (Some(a), Some(b)) => Some([a, b]),
        _ => None,
    };
    let reserved: [&[u8]; 8] = [b"x", b"y", b"z", b"nx", b"ny", b"nz", b"u", b"v"];
    let plans = find_attributes("vertex_", &mut names, &types, &reserved, warnings)?;
    check_unique(&names, "vertex")?;

    let f = |values: &[Value], i: usize| to_f32(values[i], el.fields[i].ty);
    mesh.positions = Vec::with_capacity(count);
    let mut normals = normal.map(|_| Vec::with_capacity(count));
    let mut uvs = uv.map(|_| Vec::with_capacity(count));
    let mut attrs = new_attributes(&plans, count);
    let mut values = Vec::with_capacity(el.fields.len());
    for r in 0..count {
        data.record(&el, r, &mut values)?;
        check_lists(&el, &values, r)?;
        let p = pos.map(|i| f(&values, i));
        if !p.iter().all(|c| c.is_finite()) {
            return Err(format!("vertex {r} has a non-finite position {p:?}"));
        }
        mesh.positions.push(p);
        if let (Some(out), Some(idx)) = (normals.as_mut(), normal) {
            out.push(idx.map(|i| f(&values, i)));
        }
        if let (Some(out), Some(idx)) = (uvs.as_mut(), uv) {
            out.push(idx.map(|i| f(&values, i)));
        }
        push_attributes(&mut attrs, &plans, &el, &values);
    }
    mesh.normals = normals;
    mesh.uvs = uvs;
    mesh.vertex_attributes = attrs;
    Ok(())
}

pub(super) fn read_faces(
    el: Element,
    data: &mut Data,
    mesh: &mut MeshData,
    warnings: &mut Vec<String>,
) -> Result<(), String> {
    let count = data.check_count(&el)?;
    let mut names: Vec<Vec<u8>> = el.fields.iter().map(|f| f.name.clone()).collect();
    let types: Vec<Type> = el.fields.iter().map(|f| f.ty).collect();
    if !has(&names, b"vertex_index.count") && !has(&names, b"vertex_indices.count") {
        return Err("the \"face\" element has no vertex_index/vertex_indices list".into());
    }
    let idx = [
        require(&names, b"i0", "face")?,
        require(&names, b"i1", "face")?,
        require(&names, b"i2", "face")?,
    ];
    let reserved: [&[u8]; 5] = [
        b"vertex_index.count",
        b"vertex_indices.count",
        b"i0",
        b"i1",
        b"i2",
    ];
    let plans = find_attributes("face_", &mut names, &types, &reserved, warnings)?;
    check_unique(&names, "face")?;
    mesh.triangles = Vec::with_capacity(count);
    let mut attrs = new_attributes(&plans, count);
    let mut values = Vec::with_capacity(el.fields.len());
    for r in 0..count {
        data.record(&el, r, &mut values)?;
        check_lists(&el, &values, r)?;
        let mut tri = [0u32; 3];
        for (t, &i) in tri.iter_mut().zip(&idx) {
            *t = to_index(values[i], el.fields[i].ty)
                .ok_or_else(|| format!("face {r} has a vertex index that is not a number"))?;
        }
        mesh.triangles.push(tri);
        push_attributes(&mut attrs, &plans, &el, &values);
    }
    mesh.face_attributes = attrs;
    Ok(())
}
