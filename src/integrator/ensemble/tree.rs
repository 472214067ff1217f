//! The index over the complementary ensemble Y (the paper's Sec. 3.1.1): paths grouped by their
//! **signature**, the path length and the interaction type of every vertex (camera, diffuse, glossy,
//! specular, emitter; Heckbert's notation), so that the subset Υ of Y matching a path is found in
//! O(1) in |Y|.
//!
//! # Interaction types and the roughness threshold
//! The types are the path's own `Interaction`s (`path_space::vertex::material_interaction`):
//! specular = a delta lobe (mirror, smooth dielectric: roughness exactly 0, the only surfaces the
//! specular-chain retrace follows deterministically); glossy = any other non-Lambertian BSDF (rough
//! conductor, rough plastic, rough dielectric) at any roughness α > 0; diffuse = Lambertian. The
//! roughness threshold between specular and glossy is therefore 0: a GGX surface of α = 0.001 is
//! glossy, as it is for the perturbations (it cannot be retraced deterministically).
//!
//! # The structure
//! The paper's tree over (length, types) has the signature as its leaf; we store the leaves in a
//! hash map from the signature (one byte per vertex) to a contiguous range of Y's path indices,
//! sorted by signature when the tree is built. A lookup hashes the query path's signature once:
//! O(n) in its vertex count (≤ max_depth + 2), O(1) in |Y|. The tree is rebuilt at each swap of X and
//! Y (Algorithm 1, line 12), in O(|Y| log |Y|).
//!
//! # Υ: a deterministic subset of size M
//! Υ is M consecutive paths of the matching bucket (wrapping around), starting at an offset the
//! caller draws from the chain's own stream (`subset`): uniformly, independently of the path, so
//! the offset's probability is the same for a move and its reverse and cancels (the paper uses a
//! counter stored with the ensemble; a counter shared across threads would make the image depend on
//! the scheduling, a per-chain draw does not). A bucket of at most M paths is Υ whole. The reverse
//! move must see the same Υ: the guided strategies reject any proposal whose signature differs from
//! the current path's, and record the offset in their move.
//!
//! Each bucket is ordered along the Morton (Z-order) curve of its paths' raster positions, so that
//! M consecutive members are a compact patch of the film wherever the offset starts: the spread
//! b_res of Υ then measures how densely the signature covers the film (a bucket of n paths spread
//! over the film gives patches of about M/n of it; a signature clustered in a small region gives
//! smaller ones), which is what Sec. 3.4's α adapts to. In the order of Y's indices a slice of a
//! large bucket is scattered over the whole film (b_res near 1) and α stays at α_s whatever the
//! signature. Υ is still a function of Y and the recorded offset only, never of the current path
//! beyond its signature, so neither Υ's nor α's probability enters the acceptance ratio.
//!
//! M defaults to 32 (`EmltSettings::subset_size`): the paper leaves M to its supplementary material;
//! 32 keeps a linear lens proposal's similarity weights (one Eq. 9 product per member of Υ) cheaper
//! than the path evaluation it guides, while a bucket's spread on the film (b_res, Sec. 3.4) is
//! still estimated from enough points.

use std::collections::HashMap;

use crate::integrator::path_space::{Interaction, PathState};

/// A path's signature: one byte per vertex, its interaction type (module docs).
pub fn signature(path: &PathState) -> Vec<u8> {
    path.vertices.iter().map(|v| interaction_code(v.interaction)).collect()
}

/// A vertex's byte of the signature.
fn interaction_code(interaction: Interaction) -> u8 {
    match interaction {
        Interaction::Camera => 0,
        Interaction::Diffuse => 1,
        Interaction::Glossy => 2,
        Interaction::Specular => 3,
        Interaction::Emitter => 4,
    }
}

/// The Morton (Z-order) code of a raster position: x and y in 1/16 of a pixel (clamped to
/// [0, 2³²)), their bits interleaved (x in the even bits).
pub fn morton(raster: glam::Vec2) -> u64 {
    fn spread(v: u32) -> u64 {
        let mut v = v as u64;
        v = (v | (v << 16)) & 0x0000_ffff_0000_ffff;
        v = (v | (v << 8)) & 0x00ff_00ff_00ff_00ff;
        v = (v | (v << 4)) & 0x0f0f_0f0f_0f0f_0f0f;
        v = (v | (v << 2)) & 0x3333_3333_3333_3333;
        v = (v | (v << 1)) & 0x5555_5555_5555_5555;
        v
    }
    // `as` saturates: NaN and negatives to 0, beyond the range to u32::MAX.
    let q = |c: f32| (c * 16.0) as u32;
    spread(q(raster.x)) | (spread(q(raster.y)) << 1)
}

/// Whether two paths have the same signature (length and every vertex's type).
pub fn same_signature(a: &PathState, b: &PathState) -> bool {
    a.len() == b.len() && a.vertices.iter().zip(&b.vertices).all(|(x, y)| x.interaction == y.interaction)
}

/// The index over an ensemble's paths (module docs).
#[derive(Debug, Default)]
pub struct EnsembleTree {
    /// Path indices sorted by signature, then by the Morton code of the raster position (module
    /// docs): each bucket is a contiguous range.
    order: Vec<u32>,
    buckets: HashMap<Vec<u8>, (u32, u32)>,
}

impl EnsembleTree {
    /// The tree over `paths` (paths with f = 0 are left out: they guide nothing).
    pub fn build(paths: &[&PathState]) -> EnsembleTree {
        let mut keyed: Vec<(Vec<u8>, u64, u32)> = paths
            .iter()
            .enumerate()
            .filter(|(_, p)| p.f_star > 0.0)
            .map(|(i, p)| (signature(p), morton(p.raster), i as u32))
            .collect();
        keyed.sort();
        let mut buckets: HashMap<Vec<u8>, (u32, u32)> = HashMap::new();
        for (at, (sig, _, _)) in keyed.iter().enumerate() {
            buckets.entry(sig.clone()).and_modify(|(_, len)| *len += 1).or_insert((at as u32, 1));
        }
        EnsembleTree { order: keyed.into_iter().map(|(_, _, i)| i).collect(), buckets }
    }

    /// The indices of the paths with `path`'s signature (empty when none).
    pub fn bucket(&self, path: &PathState) -> &[u32] {
        // The signature on the stack for the usual lengths: a lookup per proposal allocates nothing.
        let mut key = [0u8; 32];
        let found = if path.len() <= key.len() {
            for (k, v) in key.iter_mut().zip(&path.vertices) {
                *k = interaction_code(v.interaction);
            }
            self.buckets.get(&key[..path.len()])
        } else {
            self.buckets.get(&signature(path))
        };
        match found {
            Some(&(start, len)) => &self.order[start as usize..(start + len) as usize],
            None => &[],
        }
    }

    /// Υ: up to `m` indices of `path`'s bucket, consecutive from `offset` modulo the bucket's size
    /// (the whole bucket when it holds at most `m`), in a fixed order.
    pub fn subset(&self, path: &PathState, offset: u64, m: usize) -> Vec<u32> {
        let bucket = self.bucket(path);
        if bucket.len() <= m {
            return bucket.to_vec();
        }
        let start = (offset % bucket.len() as u64) as usize;
        (0..m).map(|i| bucket[(start + i) % bucket.len()]).collect()
    }

    /// Number of distinct signatures.
    pub fn signatures(&self) -> usize {
        self.buckets.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::bdpt::Vertex;
    use crate::integrator::path_space::PathVertex;
    use crate::spectrum::Rgb;

    fn path(types: &[Interaction], f: f64) -> PathState {
        let v = Vertex::camera(glam::Vec3::ZERO, Rgb::ONE);
        PathState {
            vertices: types.iter().map(|&interaction| PathVertex { vertex: v, interaction }).collect(),
            f_star: f,
            ..PathState::default()
        }
    }

    /// Buckets hold exactly the paths of one signature (zero paths left out); Υ is the whole bucket
    /// up to M, else M consecutive members from the offset, wrapping.
    #[test]
    fn buckets_and_subsets() {
        use Interaction::*;
        let a = [Camera, Diffuse, Emitter];
        let b = [Camera, Specular, Diffuse, Emitter];
        let c = [Camera, Glossy, Emitter];
        let paths: Vec<PathState> = (0..10)
            .map(|i| match i % 3 {
                0 => path(&a, 1.0),
                1 => path(&b, 1.0),
                _ => path(&c, if i == 5 { 0.0 } else { 1.0 }),
            })
            .collect();
        let refs: Vec<&PathState> = paths.iter().collect();
        let tree = EnsembleTree::build(&refs);
        assert_eq!(tree.signatures(), 3);
        assert_eq!(tree.bucket(&path(&a, 1.0)), &[0, 3, 6, 9]);
        assert_eq!(tree.bucket(&path(&c, 1.0)), &[2, 8]);
        assert!(tree.bucket(&path(&[Camera, Diffuse, Diffuse, Emitter], 1.0)).is_empty());
        assert_eq!(tree.subset(&path(&a, 1.0), 3, 2), vec![9, 0]);
        assert_eq!(tree.subset(&path(&a, 1.0), 7, 8), vec![0, 3, 6, 9]);
        assert!(same_signature(&path(&a, 1.0), &paths[3]) && !same_signature(&paths[0], &paths[1]));
    }
}
