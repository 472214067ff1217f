//! Procedurally generated meshes, deterministic for a seed: displaced spheres, height fields and
//! closed boxes, for scenes too large to ship as files (the `plexus bench` scene, accelerator
//! tests). They enter a scene through `load_scene_str_with_meshes`, like any other shape.

use glam::{Vec2, Vec3};

use crate::geometry::TriangleMesh;
use crate::sampling::{sample_uniform_sphere, Rng};

/// A smooth, deterministic pseudo-random function on the unit sphere (or plane): a sum of a few
/// sinusoids with random directions, frequencies and phases drawn from `seed`, in [-1, 1].
#[derive(Clone, Debug)]
pub struct Waves {
    waves: Vec<(Vec3, f32)>,
}

impl Waves {
    pub fn new(seed: u64, count: usize, frequency: f32) -> Waves {
        let mut rng = Rng::new(seed, 0x5741_5645);
        let waves = (0..count)
            .map(|k| {
                let dir = sample_uniform_sphere([rng.uniform(), rng.uniform()]);
                let f = frequency * (1.0 + k as f32 * 0.7) * (0.75 + 0.5 * rng.uniform());
                (dir * f, rng.uniform() * std::f32::consts::TAU)
            })
            .collect();
        Waves { waves }
    }
    pub fn eval(&self, p: Vec3) -> f32 {
        let sum: f32 =
            self.waves.iter().enumerate().map(|(k, (w, phase))| (w.dot(p) + phase).sin() / (k + 1) as f32).sum();
        let norm: f32 = (1..=self.waves.len()).map(|k| 1.0 / k as f32).sum();
        sum / norm
    }
}

/// A closed latitude–longitude sphere of `2 · n_phi · (n_theta − 1)` triangles whose radius is
/// displaced by `amplitude · radius · Waves(seed)`; poles and the seam share their vertices.
pub fn displaced_sphere(
    center: Vec3,
    radius: f32,
    n_theta: u32,
    n_phi: u32,
    amplitude: f32,
    seed: u64,
) -> TriangleMesh {
    let n_theta = n_theta.max(2);
    let n_phi = n_phi.max(3);
    let waves = Waves::new(seed, 6, 3.0);
    let point = |dir: Vec3| center + dir * radius * (1.0 + amplitude * waves.eval(dir));
    let mut p = vec![point(Vec3::Y)];
    for i in 1..n_theta {
        let theta = std::f32::consts::PI * i as f32 / n_theta as f32;
        for j in 0..n_phi {
            let phi = std::f32::consts::TAU * j as f32 / n_phi as f32;
            let dir = Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin());
            p.push(point(dir));
        }
    }
    p.push(point(-Vec3::Y));
    let south = p.len() as u32 - 1;
    let ring = |i: u32, j: u32| 1 + (i - 1) * n_phi + j % n_phi;
    let mut f = Vec::with_capacity(2 * (n_phi * (n_theta - 1)) as usize);
    for j in 0..n_phi {
        f.push([0, ring(1, j + 1), ring(1, j)]);
        f.push([south, ring(n_theta - 1, j), ring(n_theta - 1, j + 1)]);
    }
    for i in 1..n_theta - 1 {
        for j in 0..n_phi {
            let (a, b, c, d) = (ring(i, j), ring(i, j + 1), ring(i + 1, j + 1), ring(i + 1, j));
            f.push([a, b, c]);
            f.push([a, c, d]);
        }
    }
    TriangleMesh::new(p, f, None, None).expect("the generated sphere is a valid mesh")
}

/// A height field over `[min.x, max.x] × [min.y, max.y]` (in x and z) with `n × n` quads, height
/// `base + amplitude · Waves(seed)`.
pub fn terrain(min: Vec2, max: Vec2, base: f32, amplitude: f32, n: u32, seed: u64) -> TriangleMesh {
    let n = n.max(1);
    let waves = Waves::new(seed, 8, 0.6);
    let mut p = Vec::with_capacity(((n + 1) * (n + 1)) as usize);
    for i in 0..=n {
        for j in 0..=n {
            let x = min.x + (max.x - min.x) * j as f32 / n as f32;
            let z = min.y + (max.y - min.y) * i as f32 / n as f32;
            let h = base + amplitude * waves.eval(Vec3::new(x, 0.0, z));
            p.push(Vec3::new(x, h, z));
        }
    }
    let v = |i: u32, j: u32| i * (n + 1) + j;
    let mut f = Vec::with_capacity((2 * n * n) as usize);
    for i in 0..n {
        for j in 0..n {
            f.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
            f.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
        }
    }
    TriangleMesh::new(p, f, None, None).expect("the generated terrain is a valid mesh")
}

/// The inside of the box `[min, max]` as 12 triangles.
pub fn room(min: Vec3, max: Vec3) -> TriangleMesh {
    let p = (0..8)
        .map(|k| {
            Vec3::new(
                if k & 1 == 0 { min.x } else { max.x },
                if k & 2 == 0 { min.y } else { max.y },
                if k & 4 == 0 { min.z } else { max.z },
            )
        })
        .collect();
    let quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]];
    let f = quads.iter().flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]]).collect();
    TriangleMesh::new(p, f, None, None).expect("the generated room is a valid mesh")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generated_meshes_are_closed_and_sized_as_documented() {
        let s = displaced_sphere(Vec3::ZERO, 1.0, 8, 16, 0.1, 3);
        assert_eq!(s.triangle_count(), 2 * 16 * 7);
        // Closed: every edge is shared by exactly two triangles, in opposite directions.
        let mut edges = std::collections::HashMap::new();
        for [a, b, c] in s.indices() {
            for e in [(*a, *b), (*b, *c), (*c, *a)] {
                *edges.entry(e).or_insert(0) += 1;
            }
        }
        for (&(a, b), &n) in &edges {
            assert_eq!(n, 1, "edge {a}-{b} used twice in the same direction");
            assert_eq!(edges.get(&(b, a)), Some(&1), "edge {a}-{b} has no twin");
        }
        assert_eq!(terrain(Vec2::ZERO, Vec2::ONE, 0.0, 0.1, 10, 1).triangle_count(), 200);
        assert_eq!(room(Vec3::ZERO, Vec3::ONE).triangle_count(), 12);
    }
}
