//! The complementary ensemble as the guided strategies see it: Y's paths with their tree, the
//! subset Υ of a path, its film spread b_res and α (Sec. 3.1 and 3.4), and the statistics of the
//! guided strategies (guided vs fallback proposals, time in similarity).

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use serde::Serialize;

use super::settings::EmltSettings;
use super::similarity::path_similarity;
use super::tree::EnsembleTree;
use crate::integrator::path_space::PathState;

/// Counts of one guided strategy, summed over threads (atomics: sums do not depend on the order,
/// and nothing the image depends on reads them).
#[derive(Debug, Default)]
pub struct GuideCounts {
    /// Proposals made with a guide from Υ.
    pub guided: AtomicU64,
    /// Proposals made by the plain perturbation because |Υ| < 2 (Sec. 3.4).
    pub fallback: AtomicU64,
    /// Proposals rejected because their signature changed (so Υ would differ for the reverse).
    pub signature_changed: AtomicU64,
    /// Nanoseconds spent computing similarity weights (Eq. 8–9).
    pub similarity_ns: AtomicU64,
}

/// The plain-number copy of [`GuideCounts`] for the JSON report.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct GuideReport {
    pub name: String,
    pub guided: u64,
    pub fallback: u64,
    pub signature_changed: u64,
    pub similarity_seconds: f64,
}

impl GuideCounts {
    pub fn report(&self, name: &str) -> GuideReport {
        GuideReport {
            name: name.to_string(),
            guided: self.guided.load(Ordering::Relaxed),
            fallback: self.fallback.load(Ordering::Relaxed),
            signature_changed: self.signature_changed.load(Ordering::Relaxed),
            similarity_seconds: self.similarity_ns.load(Ordering::Relaxed) as f64 * 1e-9,
        }
    }

    pub fn add(&self, other: &GuideReport) {
        self.guided.fetch_add(other.guided, Ordering::Relaxed);
        self.fallback.fetch_add(other.fallback, Ordering::Relaxed);
        self.signature_changed.fetch_add(other.signature_changed, Ordering::Relaxed);
        self.similarity_ns.fetch_add((other.similarity_seconds * 1e9) as u64, Ordering::Relaxed);
    }
}

/// The complementary ensemble Y, fixed while X is updated (the paper's Sec. 3).
pub struct GuideView {
    /// Y's current paths, by their index in Y.
    pub paths: Vec<PathState>,
    pub tree: EnsembleTree,
    pub settings: EmltSettings,
    pub film: (f64, f64),
}

impl GuideView {
    pub fn new(paths: Vec<PathState>, settings: &EmltSettings, width: u32, height: u32) -> GuideView {
        let refs: Vec<&PathState> = paths.iter().collect();
        let tree = EnsembleTree::build(&refs);
        GuideView { paths, tree, settings: settings.clone(), film: (width as f64, height as f64) }
    }

    /// Υ of `path` for the offset a proposal drew (`tree` module docs).
    pub fn subset(&self, path: &PathState, offset: u64) -> Vec<u32> {
        self.tree.subset(path, offset, self.settings.subset_size as usize)
    }

    /// b_res of Υ: the area of the bounding box of its members' raster positions over the film's
    /// (Sec. 3.4, "a ratio of the bounding box … to the image plane resolution").
    pub fn b_res(&self, subset: &[u32]) -> f64 {
        let mut lo = glam::DVec2::splat(f64::INFINITY);
        let mut hi = glam::DVec2::splat(f64::NEG_INFINITY);
        for &i in subset {
            let r = self.paths[i as usize].raster.as_dvec2();
            lo = lo.min(r);
            hi = hi.max(r);
        }
        let extent = (hi - lo).max(glam::DVec2::ZERO);
        (extent.x * extent.y) / (self.film.0 * self.film.1)
    }

    /// α of the linear kernels for Υ (Sec. 3.4, `EmltSettings::alpha`).
    pub fn alpha(&self, subset: &[u32]) -> f64 {
        self.settings.alpha(self.b_res(subset))
    }

    /// The similarity weights S(x̄, v̄, j, k) (Eq. 9) of Υ's members, timed into `counts`.
    pub fn weights(&self, x: &PathState, subset: &[u32], j: usize, k: usize, counts: &GuideCounts) -> Vec<f64> {
        let start = Instant::now();
        let w = subset.iter().map(|&i| path_similarity(&x.vertices, &self.paths[i as usize].vertices, j, k)).collect();
        counts.similarity_ns.fetch_add(start.elapsed().as_nanos() as u64, Ordering::Relaxed);
        w
    }
}

/// The index chosen ∝ `weights` with the uniform `u`, and its probability; None when all are 0.
pub fn choose_weighted(weights: &[f64], u: f64) -> Option<(usize, f64)> {
    let total: f64 = weights.iter().sum();
    if !(total > 0.0) || !total.is_finite() {
        return None;
    }
    let mut target = u * total;
    let mut last = None;
    for (i, &w) in weights.iter().enumerate() {
        if w > 0.0 {
            last = Some(i);
            if target < w {
                return Some((i, w / total));
            }
            target -= w;
        }
    }
    last.map(|i| (i, weights[i] / total))
}

/// The index of the largest weight (the first on ties), if any is positive.
pub fn best_match(weights: &[f64]) -> Option<usize> {
    let mut best: Option<usize> = None;
    for (i, &w) in weights.iter().enumerate() {
        if w > 0.0 && best.is_none_or(|b| w > weights[b]) {
            best = Some(i);
        }
    }
    best
}
