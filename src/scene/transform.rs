//! Object-to-world transforms of shapes and portals: building them from the scene file and
//! applying them to positions and normals.

use glam::{Mat3, Mat4, Vec3};

use super::desc::{Rotations, TransformDesc};
use super::error::fmt3;
use super::raw_mesh::RawMesh;

/// The rotation that applies `rotations` in the order given (the first one first).
pub fn rotation_matrix(rotations: &Rotations) -> Result<Mat3, String> {
    let mut r = Mat3::IDENTITY;
    for (i, rot) in rotations.0.iter().enumerate() {
        let axis = Vec3::from(rot.axis);
        let where_ = if rotations.0.len() > 1 { format!("rotate[{i}]") } else { "rotate".to_string() };
        if !axis.is_finite() || axis.length_squared() == 0.0 {
            return Err(format!("{where_}.axis: expected a non-zero finite vector, got {}", fmt3(rot.axis)));
        }
        if !rot.angle.is_finite() {
            return Err(format!("{where_}.angle: expected a finite number of degrees, got {}", rot.angle));
        }
        r = Mat3::from_axis_angle(axis.normalize(), rot.angle.to_radians()) * r;
    }
    Ok(r)
}

/// The object-to-world matrix `translate · rotate · scale`, or the explicit `matrix` (rows).
/// Errors name the offending key relative to the transform table.
pub fn matrix_from_desc(desc: &TransformDesc) -> Result<Mat4, String> {
    let m = if let Some(rows) = desc.matrix {
        if desc.translate.is_some() || desc.rotate.is_some() || desc.scale.is_some() {
            return Err("matrix: expected either 'matrix' or 'translate'/'rotate'/'scale', not both".to_string());
        }
        if rows.iter().flatten().any(|v| !v.is_finite()) {
            return Err("matrix: expected finite numbers, got a NaN or infinity".to_string());
        }
        if rows[3] != [0.0, 0.0, 0.0, 1.0] {
            let [a, b, c, d] = rows[3];
            return Err(format!("matrix: expected an affine matrix (last row [0, 0, 0, 1]), got [{a}, {b}, {c}, {d}]"));
        }
        // The file lists rows; glam stores columns.
        Mat4::from_cols_array_2d(&rows).transpose()
    } else {
        let s = desc.scale.map_or(Vec3::ONE, |s| Vec3::from(s.0));
        if !s.is_finite() {
            return Err(format!("scale: expected finite numbers, got {}", fmt3(s.to_array())));
        }
        let r = match &desc.rotate {
            Some(rot) => rotation_matrix(rot)?,
            None => Mat3::IDENTITY,
        };
        let t = Vec3::from(desc.translate.unwrap_or([0.0; 3]));
        if !t.is_finite() {
            return Err(format!("translate: expected finite numbers, got {}", fmt3(t.to_array())));
        }
        Mat4::from_translation(t) * Mat4::from_mat3(r) * Mat4::from_scale(s)
    };
    // In f64: the determinant is a cube of the scale, which overflows (or flushes to zero) in f32
    // for scales within the validated range (a box scaled by 1e13, say).
    let det = Mat3::from_mat4(m).as_dmat3().determinant();
    if det == 0.0 || !det.is_finite() {
        return Err(format!("expected an invertible transform, got determinant {det}"));
    }
    Ok(m)
}

/// Moves `mesh` into world space: positions by `m`, normals by its inverse transpose. A
/// mirroring transform (negative determinant) reverses the winding so that the geometric normal
/// (from the winding) keeps pointing to the same side of the surface as before.
pub fn apply(mesh: &mut RawMesh, m: &Mat4) {
    let linear = Mat3::from_mat4(*m).as_dmat3();
    // In f64, as the determinant in `matrix_from_desc`: the inverse divides by it.
    let normal_matrix = linear.inverse().transpose();
    for p in &mut mesh.positions {
        *p = m.transform_point3(*p);
    }
    if let Some(normals) = &mut mesh.normals {
        for n in normals.iter_mut() {
            *n = (normal_matrix * n.as_dvec3()).normalize_or_zero().as_vec3();
        }
    }
    if linear.determinant() < 0.0 {
        flip_winding(mesh);
    }
}

/// Swaps the front and back of every triangle (winding and shading normals).
pub fn flip_orientation(mesh: &mut RawMesh) {
    flip_winding(mesh);
    if let Some(normals) = &mut mesh.normals {
        for n in normals.iter_mut() {
            *n = -*n;
        }
    }
}

fn flip_winding(mesh: &mut RawMesh) {
    for tri in &mut mesh.indices {
        tri.swap(1, 2);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::desc::{RotateDesc, ScaleDesc};

    fn tri() -> RawMesh {
        RawMesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            indices: vec![[0, 1, 2]],
            normals: Some(vec![Vec3::Z; 3]),
            uvs: None,
        }
    }

    fn geometric_normal(m: &RawMesh) -> Vec3 {
        let [a, b, c] = m.indices[0].map(|i| m.positions[i as usize]);
        (b - a).cross(c - a).normalize()
    }

    #[test]
    fn scale_rotate_translate_order() {
        let desc = TransformDesc {
            translate: Some([1.0, 2.0, 3.0]),
            rotate: Some(Rotations(vec![RotateDesc { axis: [0.0, 0.0, 1.0], angle: 90.0 }])),
            scale: Some(ScaleDesc([2.0, 1.0, 1.0])),
            matrix: None,
        };
        let m = matrix_from_desc(&desc).unwrap();
        // x scaled to 2, rotated onto +y, then translated.
        let p = m.transform_point3(Vec3::X);
        assert!((p - Vec3::new(1.0, 4.0, 3.0)).length() < 1e-5, "{p}");
    }

    #[test]
    fn rotations_apply_in_order() {
        let rot = Rotations(vec![
            RotateDesc { axis: [0.0, 0.0, 1.0], angle: 90.0 },
            RotateDesc { axis: [1.0, 0.0, 0.0], angle: 90.0 },
        ]);
        // X -> Y (about z), then Y -> Z (about x).
        let v = rotation_matrix(&rot).unwrap() * Vec3::X;
        assert!((v - Vec3::Z).length() < 1e-5, "{v}");
    }

    #[test]
    fn matrix_rows_are_rows() {
        let desc = TransformDesc {
            matrix: Some([[1.0, 0.0, 0.0, 5.0], [0.0, 1.0, 0.0, 6.0], [0.0, 0.0, 1.0, 7.0], [0.0, 0.0, 0.0, 1.0]]),
            ..Default::default()
        };
        let m = matrix_from_desc(&desc).unwrap();
        assert_eq!(m.transform_point3(Vec3::ZERO), Vec3::new(5.0, 6.0, 7.0));
    }

    #[test]
    fn mirror_keeps_the_front_side() {
        let mut m = tri();
        let before = geometric_normal(&m);
        apply(&mut m, &Mat4::from_scale(Vec3::new(1.0, 1.0, -1.0)));
        // The surface was mirrored through z = 0; its front now faces -z and both the winding and
        // the shading normals must agree on that.
        let after = geometric_normal(&m);
        assert!((before - Vec3::Z).length() < 1e-6);
        assert!((after + Vec3::Z).length() < 1e-6, "{after}");
        assert!((m.normals.as_ref().unwrap()[0] + Vec3::Z).length() < 1e-6);
    }

    #[test]
    fn normals_use_the_inverse_transpose() {
        let mut m = RawMesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            indices: vec![[0, 1, 2]],
            normals: Some(vec![Vec3::new(1.0, 1.0, 0.0).normalize(); 3]),
            uvs: None,
        };
        // Stretching x by 2 tilts a 45° normal towards y: n' ∝ (1/2, 1, 0).
        apply(&mut m, &Mat4::from_scale(Vec3::new(2.0, 1.0, 1.0)));
        let n = m.normals.unwrap()[0];
        assert!((n - Vec3::new(0.5, 1.0, 0.0).normalize()).length() < 1e-6, "{n}");
    }

    #[test]
    fn rejects_singular_and_mixed() {
        let singular = TransformDesc { scale: Some(ScaleDesc([1.0, 0.0, 1.0])), ..Default::default() };
        assert!(matrix_from_desc(&singular).unwrap_err().contains("determinant"));
        let mixed = TransformDesc {
            translate: Some([0.0; 3]),
            matrix: Some([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]),
            ..Default::default()
        };
        assert!(matrix_from_desc(&mixed).unwrap_err().starts_with("matrix:"));
    }
}
