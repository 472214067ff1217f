use glam::{Vec2, Vec3};

use super::binary::{read_binary_in_chunks, CHUNK};
use super::*;
use crate::scene::raw_mesh::RawMesh;

fn read(bytes: &[u8]) -> Result<RawMesh, String> {
    let mut r = bytes;
    let header = parse_header(&mut r, bytes.len() as u64)?;
    read_binary(&header, r)
}

fn header(format: &str, vertex_props: &str, face_props: &str, nv: usize, nf: usize) -> Vec<u8> {
    format!(
        "ply\nformat {format} 1.0\ncomment test\nelement vertex {nv}\n{vertex_props}element face {nf}\n\
         {face_props}end_header\n"
    )
    .into_bytes()
}

#[test]
fn reads_both_endiannesses_with_normals_uvs_fans_and_extra_properties() {
    for big in [false, true] {
        let format = if big { "binary_big_endian" } else { "binary_little_endian" };
        let vp = "property double x\nproperty float y\nproperty float z\nproperty uchar red\n\
                  property float nx\nproperty float ny\nproperty float nz\nproperty float s\nproperty float t\n";
        let fp = "property uchar flags\nproperty list uchar uint vertex_indices\nproperty list int float junk\n";
        let mut b = header(format, vp, fp, 4, 1);
        let f32b = |v: f32| if big { v.to_be_bytes() } else { v.to_le_bytes() };
        for k in 0..4 {
            let x = k as f64;
            b.extend(if big { x.to_be_bytes() } else { x.to_le_bytes() });
            b.extend(f32b(k as f32 + 0.5));
            b.extend(f32b(-1.0));
            b.push(7);
            for v in [0.0, 0.0, 1.0, 0.25 * k as f32, 0.5] {
                b.extend(f32b(v));
            }
        }
        b.push(9);
        b.push(4);
        for i in [0u32, 1, 2, 3] {
            b.extend(if big { i.to_be_bytes() } else { i.to_le_bytes() });
        }
        b.extend(if big { 1i32.to_be_bytes() } else { 1i32.to_le_bytes() });
        b.extend(f32b(3.0));
        let m = read(&b).expect("valid");
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.positions[2], Vec3::new(2.0, 2.5, -1.0));
        assert_eq!(m.indices, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(m.normals.as_deref().map(|n| n[3]), Some(Vec3::Z));
        assert_eq!(m.uvs.as_deref().map(|u| u[1]), Some(Vec2::new(0.25, 0.5)));
        assert!(m.positions.capacity() > m.positions.len(), "room for the padding vertex");
    }
}

/// A little-endian PLY of `nv` vertices (vertex k at (k, 2k, -k)) and `faces`, each face's
/// record a flag byte, the index list and a float (fixed-size records around the list).
fn polygons(nv: usize, faces: &[Vec<i32>]) -> Vec<u8> {
    let vp = "property float x\nproperty float y\nproperty float z\n";
    let fp = "property uchar flags\nproperty list uchar int vertex_indices\nproperty float quality\n";
    let mut b = header("binary_little_endian", vp, fp, nv, faces.len());
    for k in 0..nv {
        for v in [k as f32, 2.0 * k as f32, -(k as f32)] {
            b.extend(v.to_le_bytes());
        }
    }
    for f in faces {
        b.push(1);
        b.push(f.len() as u8);
        f.iter().for_each(|i| b.extend(i.to_le_bytes()));
        b.extend(0.5f32.to_le_bytes());
    }
    b
}

fn read_in_chunks(bytes: &[u8], chunk: usize) -> Result<RawMesh, String> {
    let mut r = bytes;
    let header = parse_header(&mut r, bytes.len() as u64)?;
    read_binary_in_chunks(&header, r, chunk)
}

/// The batched readers (vertex records, and face records while their count stays the same)
/// against the face-by-face reader's results and errors, across batch boundaries: batches of
/// 40 bytes hold three vertices or two triangle records (18 bytes each), so every kind of face
/// meets a boundary somewhere. Wrong variants this catches: a batch with a quad among
/// triangles kept (its corners read as a triangle), a dropped batch not re-read, an error naming
/// the batch's first face instead of the culprit.
#[test]
fn batched_records_read_like_single_faces_across_batch_boundaries() {
    let tri = |k: i32| vec![k % 9, (k + 1) % 9, (k + 2) % 9];
    let mut faces: Vec<Vec<i32>> = (0..7).map(tri).collect();
    faces.push(vec![0, 1, 2, 3]);
    faces.extend((0..5).map(tri));
    faces.extend([vec![4, 5, 6, 7, 8], vec![1, 2, 3, 4, 5]]);
    faces.extend((0..4).map(tri));
    let expected: Vec<[u32; 3]> =
        faces.iter().flat_map(|f| (1..f.len() - 1).map(move |t| [f[0], f[t], f[t + 1]].map(|i| i as u32))).collect();
    let bytes = polygons(9, &faces);
    for chunk in [1, 20, 40, 64, 1 << 20] {
        let m = read_in_chunks(&bytes, chunk).expect("valid");
        assert_eq!(m.indices, expected, "chunk {chunk}");
        assert_eq!(m.positions.len(), 9);
        assert_eq!(m.positions[7], Vec3::new(7.0, 14.0, -7.0), "chunk {chunk}");
    }
    // All quads: read in batches too, as fans.
    let quads: Vec<Vec<i32>> = (0..6).map(|k| vec![k, k + 1, k + 2, k + 3]).collect();
    let m = read_in_chunks(&polygons(9, &quads), 40).expect("quads");
    assert_eq!(m.indices.len(), 12);
    assert_eq!(m.indices[10..], [[5, 6, 7], [5, 7, 8]]);

    // Errors name the culprit face, wherever it is in its batch.
    for chunk in [40, 64, 1 << 20] {
        let mut bad = faces.clone();
        bad[10][1] = -3;
        let e = read_in_chunks(&polygons(9, &bad), chunk).expect_err("negative");
        assert!(e.contains("face 10: vertex index -3 is negative"), "chunk {chunk}: {e}");
        let mut two = faces.clone();
        two[14] = vec![1, 2];
        let e = read_in_chunks(&polygons(9, &two), chunk).expect_err("two");
        assert!(e.contains("face 14: expected at least 3 vertices"), "chunk {chunk}: {e}");
        // Truncated inside face 16's index list (faces 17 and 18 are 18-byte triangles). A
        // body cut inside the vertices is refused by the header's bound before any batch.
        let ok = polygons(9, &faces);
        let face_16_end = ok.len() - 2 * 18;
        let e = read_in_chunks(&ok[..face_16_end - 5], chunk).expect_err("truncated");
        assert!(e.contains("ends inside face 16 of 19"), "chunk {chunk}: {e}");
    }
}

#[test]
fn malformed_bodies_are_errors_naming_the_element() {
    let vp = "property float x\nproperty float y\nproperty float z\n";
    let fp = "property list uchar int vertex_indices\n";
    let mut ok = header("binary_little_endian", vp, fp, 3, 1);
    ok.extend([0u8; 36]);
    ok.push(3);
    for i in [0i32, 1, 2] {
        ok.extend(i.to_le_bytes());
    }
    assert_eq!(read(&ok).expect("valid").indices, vec![[0, 1, 2]]);
    // Truncated inside the face's list.
    let e = read(&ok[..ok.len() - 2]).expect_err("truncated");
    assert!(e.contains("ends inside face 0 of 1"), "{e}");
    // A negative index.
    let mut neg = ok.clone();
    let n = neg.len();
    neg[n - 4..].copy_from_slice(&(-5i32).to_le_bytes());
    assert!(read(&neg).expect_err("negative").contains("vertex index -5 is negative"));
    // Two vertices in a face.
    let mut two = ok.clone();
    two[n - 13] = 2;
    assert!(read(&two).expect_err("two").contains("at least 3 vertices"));
    // A list count that lies: it meets the end of the file, not an allocation.
    let mut lie = ok.clone();
    lie[n - 13] = 255;
    assert!(read(&lie).expect_err("lie").contains("ends inside face 0"));
    // Missing pieces and unknown types.
    let no_z = header("binary_little_endian", "property float x\nproperty float y\n", fp, 0, 0);
    assert!(read(&no_z).expect_err("no z").contains("no property 'z'"));
    let float_list = header("binary_little_endian", vp, "property list uchar float vertex_indices\n", 0, 0);
    assert!(read(&float_list).expect_err("floats").contains("not an integer list"));
    let odd = header("binary_little_endian", "property quad x\n", fp, 0, 0);
    assert!(read(&odd).expect_err("type").contains("unknown property type 'quad'"));
    assert!(read(b"plx\nformat ascii 1.0\nend_header\n").expect_err("magic").contains("start with"));
}

/// A face's other list longer than the read buffer (read item by item) makes no triangles:
/// before this fix the fan step after it ran for every list, so a long list ahead of the
/// index list took `fan.len() - 1` of an empty fan (a panic), and one after it repeated the
/// face's triangles.
#[test]
fn long_lists_other_than_the_indices_make_no_triangles() {
    let vp = "property float x\nproperty float y\nproperty float z\n";
    let long = CHUNK / 4 + 10;
    for before in [true, false] {
        let (indices, extra) = ("property list uchar int vertex_indices\n", "property list int float weights\n");
        let fp = if before { format!("{extra}{indices}") } else { format!("{indices}{extra}") };
        let mut b = header("binary_little_endian", vp, &fp, 3, 1);
        b.extend([0u8; 36]);
        let mut weights = (long as i32).to_le_bytes().to_vec();
        weights.extend(std::iter::repeat_n(0u8, 4 * long));
        let mut tri = vec![3u8];
        for i in [0i32, 1, 2] {
            tri.extend(i.to_le_bytes());
        }
        if before {
            b.extend(&weights);
            b.extend(&tri);
        } else {
            b.extend(&tri);
            b.extend(&weights);
        }
        assert_eq!(read(&b).expect("valid").indices, vec![[0, 1, 2]], "long list before the indices: {before}");
    }
}
