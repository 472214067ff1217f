//! Depth 0 outside the chains (`direct_emission = "camera"`): the emitters seen directly rendered
//! by a stratified camera estimator beside the chains, which then carry depths ≥ 1 only.
//!
//! **Why.** Depth 0 is the radiance of the emitters the camera sees, an indicator of their outline
//! on the film times their radiance: one camera ray per sample estimates it, and a pixel wholly
//! inside an emitter's image is exact with one sample. In the chains it is a depth like any other,
//! chosen ∝ b_0 (MMLT paper, Sec. 4): where an emitter is in view, b_0 is the largest b_d (b_d is
//! the depth's image luminance over n_d = d + 2, and n_0 = 1), so most iterations go to the one
//! depth that needs the fewest.
//!
//! **The estimator.** In every pass, chain unit c renders one camera sample of each pixel of its
//! share of the film, pixels [c·P/C, (c+1)·P/C) in row-major order (P pixels, C chains: every
//! pixel belongs to exactly one unit). Sample k of pixel (x, y) is point k of the pixel's own
//! Owen-scrambled Sobol sequence under a key of its own (`PixelSampler::sobol_stream`), k the
//! number of passes the unit has rendered (`ChainUnit::direct_passes`, saved with the unit): the
//! film position within the pixel, the camera ray, and the technique s = 0, t = 2 evaluated as a
//! depth-0 chain state evaluates it (`evaluate_technique`: the emitted radiance with its MIS weight,
//! 1 at depth 0). Its value goes to the pixel's entry of the film's depth-0 layer (MMLT, RJMLT:
//! depth 0's own layer; PSSMLT: a second layer after the chains'), and the layer's image is each
//! pixel's sum ÷ its samples (the owning unit's passes). The chains' layers keep their own
//! normalisation n_d·b_d·P / iterations_d (`Mlt::normalised_image`), which never assumed the
//! iterations ∝ b_d, so the two images add.
//!
//! **State.** The depth-0 sums are in the film and each unit carries its passes, so a checkpoint,
//! its resumption and merged shards hold the same numbers as the uninterrupted render; a unit's
//! samples depend on (seed, pixel, its passes) only, not on the threads.

use glam::UVec2;

use super::{Mlt, SlotState};
use crate::film::{Accumulator, SplatBuffer};
use crate::integrator::bdpt::{evaluate_technique, generate_camera_subpath, BdptContext, FilmRegion};
use crate::integrator::pss::mlt_settings::{DirectEmission, MltVariant};
use crate::sampling::PixelSampler;
use crate::spectrum::is_finite;
use crate::stats::Counters;

/// Distinguishes the camera estimator's pixel sequences from any other use of per-pixel Sobol
/// points under the render seed.
const DIRECT_CAMERA_SEED_SALT: u64 = 0xD1EC_7CA3_E7A0_0000;

/// Sobol streams of a camera sample (`PixelSampler::stream` numbering: 0 camera, 2 connection).
const CAMERA_SAMPLE_STREAM: u32 = 0;
const CONNECTION_SAMPLE_STREAM: u32 = 2;

/// The pixels, row-major indices [first, end), whose depth-0 samples chain unit `unit` of `chains`
/// renders on a film of `pixels` pixels: consecutive shares that cover the film exactly once.
pub(super) fn unit_pixels(unit: u64, chains: u64, pixels: u64) -> (u64, u64) {
    let share = |c: u64| ((c as u128 * pixels as u128) / chains.max(1) as u128) as u64;
    (share(unit), share(unit + 1))
}

impl Mlt {
    /// Whether depth 0 is rendered by the camera estimator (module docs).
    pub(super) fn direct_from_camera(&self) -> bool {
        self.settings.direct_emission == DirectEmission::Camera
    }

    /// The film's layers: one per depth slot of the chains (`depth_count`), and for PSSMLT with
    /// the camera estimator one more for depth 0 (MMLT and RJMLT keep it in depth 0's layer).
    pub(super) fn film_layers(&self) -> usize {
        self.depth_count() + (self.variant == MltVariant::Pssmlt && self.direct_from_camera()) as usize
    }

    /// The layer of the camera estimator's depth-0 sums, if it renders depth 0.
    pub(super) fn direct_layer(&self) -> Option<usize> {
        self.direct_from_camera().then(|| if self.variant == MltVariant::Pssmlt { 1 } else { 0 })
    }

    /// Whether the chains render depth slot `d`: every slot, except MMLT's and RJMLT's depth 0 when
    /// the camera estimator renders it (PSSMLT's one slot then holds depths ≥ 1).
    pub(super) fn chains_render(&self, d: usize) -> bool {
        !(d == 0 && self.variant != MltVariant::Pssmlt && self.direct_from_camera())
    }

    /// One camera sample of depth 0 at pixel (`x`, `y`), its sample `index`: the radiance of the
    /// emitter the camera ray hits, with the MIS weight a depth-0 state's technique has, added to
    /// the pixel in `layer` of `film` (each layer `layer_height` rows).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn direct_sample_at(
        &self,
        ctx: &BdptContext,
        seed: u64,
        (x, y): (u32, u32),
        index: u64,
        (layer, layer_height): (usize, usize),
        slot: &mut SlotState,
        film: &mut SplatBuffer,
        counters: &mut Counters,
    ) {
        let key = seed ^ DIRECT_CAMERA_SEED_SALT;
        let mut camera = PixelSampler::sobol_stream(key, x, y, index, CAMERA_SAMPLE_STREAM);
        let raster = generate_camera_subpath(
            ctx,
            FilmRegion::Pixel(UVec2::new(x, y)),
            &mut camera,
            2,
            &mut slot.camera,
            counters,
        );
        if slot.camera.len() < 2 {
            return;
        }
        let mut connection = PixelSampler::sobol_stream(key, x, y, index, CONNECTION_SAMPLE_STREAM);
        let Some(c) = evaluate_technique(
            ctx,
            &[],
            &slot.camera,
            0,
            2,
            raster,
            &mut connection,
            &mut slot.scratch,
            counters,
            None,
        ) else {
            return;
        };
        let value = c.weighted();
        if !is_finite(value) {
            counters.nonfinite_dropped += 1;
        } else if value != crate::spectrum::Rgb::ZERO {
            // The pixel itself, not the raster position: x + u rounds to x + 1 for u near 1 at
            // large x in f32.
            film.add(x as usize, layer * layer_height + y as usize, value);
        }
    }

    /// Chain unit `unit`'s depth-0 samples of one pass (`unit_pixels`), sample `index` of each of
    /// its pixels, to the film's depth-0 layer. Returns the samples taken.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn direct_pass(
        &self,
        ctx: &BdptContext,
        seed: u64,
        unit: u64,
        index: u64,
        slot: &mut SlotState,
        film: &mut SplatBuffer,
        counters: &mut Counters,
    ) -> u64 {
        let Some(layer) = self.direct_layer() else { return 0 };
        let camera = &ctx.scene.camera;
        let (width, height) = (camera.width as u64, camera.height as u64);
        let (first, end) = unit_pixels(unit, self.settings.chains, width * height);
        for i in first..end {
            let pixel = ((i % width) as u32, (i / width) as u32);
            self.direct_sample_at(ctx, seed, pixel, index, (layer, height as usize), slot, film, counters);
        }
        end - first
    }

    /// The per-pixel sample counts of the depth-0 layer: each pixel has its owning unit's passes
    /// (a unit missing from `units`, another shard's, leaves its pixels at 0). `passes` yields
    /// (unit index, passes rendered).
    pub(super) fn direct_counts(&self, pixels: usize, passes: impl Iterator<Item = (u64, u64)>) -> Vec<u64> {
        let mut counts = vec![0u64; pixels];
        for (unit, n) in passes {
            let (first, end) = unit_pixels(unit, self.settings.chains, pixels as u64);
            counts[first as usize..end as usize].iter_mut().for_each(|c| *c = n);
        }
        counts
    }

    /// The depth-0 image of `film`'s layer `layer`: each pixel's sum ÷ its samples `counts`.
    pub(super) fn direct_image_sums(film: &Accumulator, layer: usize, counts: &[u64]) -> Vec<[f64; 3]> {
        let pixels = counts.len();
        film.sums()[layer * pixels..(layer + 1) * pixels]
            .iter()
            .zip(counts)
            .map(|(s, &n)| if n > 0 { s.map(|v| v / n as f64) } else { [0.0; 3] })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::unit_pixels;

    /// The units' shares cover every pixel exactly once, in order, with more chains than pixels
    /// and fewer.
    #[test]
    fn unit_pixels_cover_the_film_once() {
        for (chains, pixels) in [(1u64, 7u64), (3, 7), (7, 7), (1000, 256), (24, 3072), (5, 0)] {
            let mut next = 0;
            for c in 0..chains {
                let (first, end) = unit_pixels(c, chains, pixels);
                assert_eq!(first, next, "{chains} chains, {pixels} pixels: unit {c}");
                assert!(end >= first);
                next = end;
            }
            assert_eq!(next, pixels, "{chains} chains, {pixels} pixels");
        }
    }
}
