//! Hand-made input files for the tests that feed plexus what a hostile or careless user could
//! (tests/commands/trust.rs, tests/commands/fuzz/, tests/commands/cli.rs): a small Mitsuba scene, `.serialized` meshes with
//! any counts, FIFOs.

use std::io::Write;
use std::path::Path;

/// A Mitsuba 3 scene, 8×6 pixels: a floor under a rectangle lamp, seen from above. `head` follows
/// `<scene ...>` on its line (start it with a line break to put elements on line 2 on), the sensor
/// has id `sensor_id`, and `tail` stands before `</scene>`.
pub fn mitsuba_scene(head: &str, sensor_id: &str, tail: &str) -> String {
    format!(
        r#"<scene version="3.0.0">{head}
  <sensor type="perspective" id="{sensor_id}">
    <float name="fov" value="50"/>
    <transform name="to_world"><lookat origin="0, 3, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/><rfilter type="box"/></film>
  </sensor>
  <shape type="rectangle">
    <transform name="to_world"><scale value="2"/><rotate x="1" angle="-90"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.5, 0.5, 0.5"/></bsdf>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><scale value="0.5"/><rotate x="1" angle="90"/><translate y="2"/></transform>
    <emitter type="area"><rgb name="radiance" value="5, 5, 5"/></emitter>
  </shape>
{tail}
</scene>
"#
    )
}

/// One mesh of a `.serialized` file (positions and triangles only), with the triangle count its
/// header declares: the triangles' own count, unless a test makes the header lie.
pub struct SerializedMesh {
    pub positions: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
    pub declared_triangles: u64,
}

impl SerializedMesh {
    /// One triangle whose third vertex stands at `height` (which tells meshes apart).
    pub fn triangle(height: f32) -> SerializedMesh {
        SerializedMesh {
            positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, height]],
            triangles: vec![[0, 1, 2]],
            declared_triangles: 1,
        }
    }
}

/// The bytes of a Mitsuba `.serialized` file (format version 4) holding `meshes`.
pub fn serialized(meshes: &[SerializedMesh]) -> Vec<u8> {
    let mut data = Vec::new();
    let mut offsets = Vec::new();
    for mesh in meshes {
        offsets.push(data.len() as u64);
        data.extend_from_slice(&0x041Cu16.to_le_bytes());
        data.extend_from_slice(&4u16.to_le_bytes());
        let mut body = Vec::new();
        body.extend_from_slice(&0u32.to_le_bytes()); // flags: positions and indices only
        body.extend_from_slice(b"mesh\0");
        body.extend_from_slice(&(mesh.positions.len() as u64).to_le_bytes());
        body.extend_from_slice(&mesh.declared_triangles.to_le_bytes());
        for v in mesh.positions.iter().flatten() {
            body.extend_from_slice(&v.to_le_bytes());
        }
        for i in mesh.triangles.iter().flatten() {
            body.extend_from_slice(&i.to_le_bytes());
        }
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(&body).expect("compress");
        data.extend_from_slice(&z.finish().expect("compress"));
    }
    for o in &offsets {
        data.extend_from_slice(&o.to_le_bytes());
    }
    data.extend_from_slice(&(meshes.len() as u32).to_le_bytes());
    data
}

/// `n` one-triangle meshes (`SerializedMesh::triangle` at heights 1, 2, ...) as a file.
pub fn serialized_triangles(n: usize) -> Vec<u8> {
    serialized(&(0..n).map(|m| SerializedMesh::triangle(1.0 + m as f32)).collect::<Vec<_>>())
}

/// Makes a FIFO at `path` (nobody writes to it: a reader that opens it blocks).
pub fn mkfifo(path: &Path) {
    let c = std::ffi::CString::new(path.to_str().expect("UTF-8 path")).expect("no NUL");
    // SAFETY: `c` is a NUL-terminated path that outlives the call.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0, "mkfifo {}", path.display());
}
