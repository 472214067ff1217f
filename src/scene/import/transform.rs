//! `<transform>`: `translate`, `rotate`, `scale`, `matrix` and `lookat` in the order written, each
//! applied after the ones before it (Mitsuba left-multiplies), in double precision.

use glam::{DMat3, DMat4, DVec3, DVec4};

use super::numbers::{parse_f64, parse_list};
use super::xml::{Element, Loc};
use super::ImportError;

pub fn parse(e: &Element) -> Result<DMat4, ImportError> {
    let mut m = DMat4::IDENTITY;
    for op in &e.children {
        let step = operation(op)?;
        m = step * m;
    }
    if !m.is_finite() {
        return Err(ImportError::at(&e.loc, "the transform is not finite"));
    }
    Ok(m)
}

/// x/y/z attributes (each defaulting to `default`), or one `value` attribute of three numbers (or
/// one, for a uniform `scale`).
fn xyz(e: &Element, default: f64) -> Result<DVec3, ImportError> {
    if let Some(v) = e.attr("value") {
        let n = parse_list(v, &e.loc)?;
        return match n.as_slice() {
            [s] => Ok(DVec3::splat(*s)),
            [x, y, z] => Ok(DVec3::new(*x, *y, *z)),
            _ => Err(ImportError::at(&e.loc, format!("expected one or three numbers, got '{v}'"))),
        };
    }
    let c = |k: &str| e.attr(k).map_or(Ok(default), |v| parse_f64(v, &e.loc));
    Ok(DVec3::new(c("x")?, c("y")?, c("z")?))
}

fn point(e: &Element, name: &str) -> Result<Option<DVec3>, ImportError> {
    let Some(v) = e.attr(name) else { return Ok(None) };
    let n = parse_list(v, &e.loc)?;
    match n.as_slice() {
        [x, y, z] => Ok(Some(DVec3::new(*x, *y, *z))),
        _ => Err(ImportError::at(&e.loc, format!("'{name}' expects three numbers, got '{v}'"))),
    }
}

fn operation(e: &Element) -> Result<DMat4, ImportError> {
    Ok(match e.tag.as_str() {
        "translate" => DMat4::from_translation(xyz(e, 0.0)?),
        "scale" => {
            let s = xyz(e, 1.0)?;
            if s.x * s.y * s.z == 0.0 {
                return Err(ImportError::at(&e.loc, "a scale of 0 makes the transform singular"));
            }
            DMat4::from_scale(s)
        }
        "rotate" => {
            let axis = match point(e, "axis")? {
                Some(a) => a,
                None => xyz(e, 0.0)?,
            };
            let angle = parse_f64(
                e.attr("angle").ok_or_else(|| ImportError::at(&e.loc, "<rotate> needs an 'angle' (degrees)"))?,
                &e.loc,
            )?;
            if axis.length_squared() == 0.0 {
                return Err(ImportError::at(&e.loc, "<rotate> needs a non-zero axis (x, y, z)"));
            }
            DMat4::from_axis_angle(axis.normalize(), angle.to_radians())
        }
        "matrix" => {
            let v = e.attr("value").ok_or_else(|| ImportError::at(&e.loc, "<matrix> needs a 'value'"))?;
            let n = parse_list(v, &e.loc)?;
            let m = match n.len() {
                // Row-major, points are column vectors.
                16 => {
                    // Mitsuba accepts any 4×4 matrix; plexus's shapes and cameras need an affine
                    // one (a projective bottom row would bend lines through the w divide).
                    if n[12..] != [0.0, 0.0, 0.0, 1.0] {
                        return Err(ImportError::at(
                            &e.loc,
                            format!(
                                "<matrix> has the bottom row ({}, {}, {}, {}): only affine transforms (0, 0, 0, 1) are supported",
                                n[12], n[13], n[14], n[15]
                            ),
                        ));
                    }
                    DMat4::from_cols_slice(&n).transpose()
                }
                9 => DMat4::from_mat3(DMat3::from_cols_slice(&n).transpose()),
                k => return Err(ImportError::at(&e.loc, format!("<matrix> expects 16 (or 9) numbers, got {k}"))),
            };
            if m.determinant() == 0.0 {
                return Err(ImportError::at(&e.loc, "the <matrix> is singular (determinant 0)"));
            }
            m
        }
        "lookat" => {
            let origin = point(e, "origin")?.ok_or_else(|| ImportError::at(&e.loc, "<lookat> needs 'origin'"))?;
            let target = point(e, "target")?.ok_or_else(|| ImportError::at(&e.loc, "<lookat> needs 'target'"))?;
            let up = point(e, "up")?.unwrap_or(DVec3::Y);
            look_at(origin, target, up, &e.loc)?
        }
        other => return Err(ImportError::at(&e.loc, format!("unsupported transform operation <{other}>"))),
    })
}

/// Mitsuba's look-at frame: columns left = up × dir, up' = dir × left, dir, origin (camera space
/// looks along +z with +x to the left).
fn look_at(origin: DVec3, target: DVec3, up: DVec3, loc: &Loc) -> Result<DMat4, ImportError> {
    let dir = (target - origin).normalize_or_zero();
    let left = up.normalize_or_zero().cross(dir);
    if dir == DVec3::ZERO || left.length_squared() < 1e-18 {
        return Err(ImportError::at(loc, "<lookat> needs a target apart from the origin and an up not along the view"));
    }
    let left = left.normalize();
    let new_up = dir.cross(left);
    Ok(DMat4::from_cols(
        left.extend(0.0),
        new_up.extend(0.0),
        dir.extend(0.0),
        DVec4::new(origin.x, origin.y, origin.z, 1.0),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;
    use std::sync::Arc;

    fn el(tag: &str, attrs: &[(&str, &str)], children: Vec<Element>) -> Element {
        Element {
            tag: tag.to_string(),
            attrs: attrs.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect(),
            children,
            loc: Loc { file: "t.xml".into(), line: 3 },
            dir: Arc::from(Path::new("")),
        }
    }

    #[test]
    fn operations_apply_in_order() {
        // scale x by 2, then rotate 90° about z, then translate: (1,0,0) → (2,0,0) → (0,2,0) → (0,2,5).
        let t = el(
            "transform",
            &[],
            vec![
                el("scale", &[("x", "2")], vec![]),
                el("rotate", &[("z", "1"), ("angle", "90")], vec![]),
                el("translate", &[("z", "5")], vec![]),
            ],
        );
        let p = parse(&t).unwrap().transform_point3(DVec3::X);
        assert!((p - DVec3::new(0.0, 2.0, 5.0)).length() < 1e-12, "{p}");
        let m = el("transform", &[], vec![el("matrix", &[("value", "1 0 0 4 0 1 0 5 0 0 1 6 0 0 0 1")], vec![])]);
        assert_eq!(parse(&m).unwrap().transform_point3(DVec3::ZERO), DVec3::new(4.0, 5.0, 6.0));
        let s = el("transform", &[], vec![el("scale", &[("value", "3")], vec![])]);
        assert_eq!(parse(&s).unwrap().transform_point3(DVec3::ONE), DVec3::splat(3.0));
    }

    #[test]
    fn lookat_columns_are_left_up_dir_origin() {
        let t = el(
            "transform",
            &[],
            vec![el("lookat", &[("origin", "0, 0, 5"), ("target", "0 0 0"), ("up", "0 1 0")], vec![])],
        );
        let m = parse(&t).unwrap();
        assert!((m.transform_vector3(DVec3::Z) - DVec3::new(0.0, 0.0, -1.0)).length() < 1e-12);
        // Looking down -z with +y up, the camera's +x (left) is world -x... seen from the camera,
        // left is world +x? dir = -z, up = +y: left = up × dir = y × (-z) = -x.
        assert!((m.transform_vector3(DVec3::X) - DVec3::new(-1.0, 0.0, 0.0)).length() < 1e-12);
        assert_eq!(m.transform_point3(DVec3::ZERO), DVec3::new(0.0, 0.0, 5.0));
        let bad = el("transform", &[], vec![el("lookat", &[("origin", "0 0 0"), ("target", "0 0 0")], vec![])]);
        assert!(parse(&bad).unwrap_err().to_string().contains("t.xml:3"));
    }
}
