//! The uniforms of one pixel sample for the image-space integrators (pt, BDPT, light tracing):
//! either the work item's independent stream (`SamplerKind::Independent`), or an Owen-scrambled
//! Sobol sequence per pixel (`SamplerKind::Sobol`: Burley 2020, "Practical Hash-based Owen
//! Scrambling", JCGT 9(4), evaluated by the child module `burley` bit for bit as the
//! `sobol_burley` crate does, about 3× cheaper; the crate is its test oracle).
//!
//! # The Sobol layout
//!
//! Sample `i` of pixel (x, y) is point `i` of a sequence keyed by (render seed, x, y): each pixel
//! gets its own scramble and index shuffle (Burley Sec. 4), so the error of neighbouring pixels is
//! decorrelated noise, not structure. The dimensions are *padded* in sets of four (Burley Sec. 5):
//! a set is Sobol dimensions 0–3 under a seed of its own, so the four numbers of a set are
//! jointly stratified and different sets are independent. A consumer reads whole blocks per vertex
//! (`UniformSource::next_n`: film position 2, a light sample 4, a BSDF sample and its roulette
//! number 4, …), and a read of at most four numbers that does not fit in what is left of the
//! current set starts the next set, so a vertex's numbers come from one stratified set and the
//! set that vertex `k` reads depends only on the vertices before it on the same stream
//! (dimension-stable). BDPT's camera, light and connection subpaths read separate streams
//! ([`PixelSampler::stream`]), keyed apart, so a longer camera path does not shift the light
//! path's dimensions.
//!
//! A sequence holds 2^16 points (as in `sobol_burley`); sample 2^16·j + i is point i of the sequence
//! keyed also by j, a further independent scramble — still unbiased, merely no longer stratified
//! against the first 2^16.
//!
//! Everything is a function of (seed, pixel, sample index, stream, position): pass p's sample
//! indices are p · (samples per pass) onwards (`ImageRender::run`), never from threads or
//! timing, so renders stay bit-for-bit deterministic and pass shards merge to the unsharded render.

use serde::{Deserialize, Serialize};

use super::rng::splitmix64;
use super::{Rng, UniformSource};

mod burley;

/// Which numbers an image-space integrator's samples read (`sampler` setting).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SamplerKind {
    /// The work item's pseudo-random stream, read in order by every sample of its tile (the light
    /// tracer's default, which gains nothing from Sobol points).
    Independent,
    /// Owen-scrambled Sobol points per pixel (the module docs), the default of pt and BDPT: MSE at
    /// equal samples 0.2–0.6× the independent sampler's on the three Cornell scenes, within the
    /// noise on the door (docs/lab/benchmarks-history.md, "Sobol sampling at equal samples").
    #[default]
    Sobol,
}

/// The key of pixel (x, y)'s Sobol sequences under the render seed `seed`.
fn sobol_pixel_key(seed: u64, x: u32, y: u32) -> u64 {
    splitmix64(splitmix64(seed ^ 0x5851_F42D_4C95_7F2D) ^ (((y as u64) << 32) | x as u64))
}

/// The uniforms of one sample of one pixel: hands out a stream per subpath.
pub struct PixelSampler<'a> {
    kind: SamplerKind,
    rng: &'a mut Rng,
    /// Hash of (seed, pixel): the pixel's sequence.
    key: u64,
    index: u64,
}

impl<'a> PixelSampler<'a> {
    /// Sample `index` (counted over the whole render) of pixel (x, y) under `seed`; `rng` is the
    /// work item's stream, which the independent sampler reads.
    pub fn new(kind: SamplerKind, rng: &'a mut Rng, seed: u64, x: u32, y: u32, index: u64) -> PixelSampler<'a> {
        let key = match kind {
            SamplerKind::Independent => 0,
            SamplerKind::Sobol => sobol_pixel_key(seed, x, y),
        };
        PixelSampler { kind, rng, key, index }
    }

    /// Stream `k` of sample `index` of pixel (x, y) under the Sobol sampler, owned: the numbers
    /// `PixelSampler::new(SamplerKind::Sobol, ..).stream(k)` gives, for a caller that holds
    /// several samples' streams at once (they need no `Rng`).
    pub fn sobol_stream(seed: u64, x: u32, y: u32, index: u64, k: u32) -> SobolStream {
        SobolStream::of_sequence(sobol_pixel_key(seed, x, y), k, index)
    }

    /// Stream `k` of this sample (pt reads 0; BDPT's camera, light and connection subpaths 0, 1,
    /// 2). The independent sampler's streams are all the item's one stream, read on in order.
    pub fn stream(&mut self, k: u32) -> SampleStream<'_> {
        match self.kind {
            SamplerKind::Independent => SampleStream::Independent(self.rng),
            SamplerKind::Sobol => SampleStream::Sobol(SobolStream::of_sequence(self.key, k, self.index)),
        }
    }
}

/// One stream of a [`PixelSampler`].
pub enum SampleStream<'a> {
    Independent(&'a mut Rng),
    Sobol(SobolStream),
}

impl UniformSource for SampleStream<'_> {
    #[inline]
    fn next_1d(&mut self) -> f32 {
        match self {
            SampleStream::Independent(rng) => rng.uniform(),
            SampleStream::Sobol(s) => s.next_1d(),
        }
    }
    #[inline]
    fn next_2d(&mut self) -> [f32; 2] {
        self.next_n()
    }
    #[inline]
    fn next_n<const N: usize>(&mut self) -> [f32; N] {
        match self {
            SampleStream::Independent(rng) => rng.next_n(),
            SampleStream::Sobol(s) => s.next_n(),
        }
    }
    /// Sobol: the branch's own stream ([`SobolStream::branch`]); independent: the item's stream
    /// read on, as every stream of the independent sampler is.
    fn with_branch<R>(&mut self, k: u32, f: impl FnOnce(&mut Self) -> R) -> R {
        match self {
            SampleStream::Independent(_) => f(self),
            SampleStream::Sobol(s) => f(&mut SampleStream::Sobol(s.branch(k))),
        }
    }
}

/// Point `index` of a padded Owen-scrambled Sobol sequence keyed by `key`, read in 4D sets (the
/// module docs). Set `s` is Burley's dimensions 0–3 under the seed splitmix64(key ⊕ s); sets are
/// computed two at a time (`burley::sobol_set_pair`), which does not change what is read.
#[derive(Clone, Debug)]
pub struct SobolStream {
    key: u64,
    /// The point's index (< 2^16), bit-reversed as `burley` takes it.
    index_reversed: u32,
    /// The pair of sets being read (its number): sets 2·pair and 2·pair + 1, and their values.
    pair: u32,
    values: [[f32; 4]; 2],
    /// Next position in the pair's eight values (set `position / 4`, number `position % 4`);
    /// 8 = both sets are used up.
    position: usize,
}

impl SobolStream {
    /// Stream `k` of point `index` of the padded sequence keyed by `key` (a pixel's, or the MLT
    /// bootstrap's over the whole film): streams are keyed apart, and points 2^16·j onwards come
    /// from a further scramble keyed by j (module docs).
    pub fn of_sequence(key: u64, k: u32, index: u64) -> SobolStream {
        SobolStream::new(splitmix64(key ^ ((k as u64 + 1) << 48) ^ (index >> 16)), (index & 0xFFFF) as u32)
    }

    /// `index` < 2^16.
    pub fn new(key: u64, index: u32) -> SobolStream {
        debug_assert!(index < 1 << 16);
        SobolStream { key, index_reversed: index.reverse_bits(), pair: u32::MAX, values: [[0.0; 4]; 2], position: 8 }
    }

    /// The stream of branch `k` ≥ 1 of a path split at a vertex: the same point index (so a
    /// pixel's samples stay stratified in every branch) of a sequence keyed by this stream's key and
    /// `k`, read from its first set (so a branch's dimensions do not depend on the path before it).
    pub fn branch(&self, k: u32) -> SobolStream {
        SobolStream::new(splitmix64(self.key ^ 0xB7A4_C1D5_0000_0000 ^ k as u64), self.index_reversed.reverse_bits())
    }

    fn start_next_pair(&mut self) {
        self.pair = self.pair.wrapping_add(1);
        let first_set = self.pair.wrapping_mul(2);
        let seed = |set: u32| splitmix64(self.key ^ set as u64) as u32;
        self.values = burley::sobol_set_pair(self.index_reversed, [seed(first_set), seed(first_set.wrapping_add(1))]);
        self.position = 0;
    }
}

impl UniformSource for SobolStream {
    #[inline]
    fn next_1d(&mut self) -> f32 {
        if self.position == 8 {
            self.start_next_pair();
        }
        let v = self.values[self.position / 4][self.position % 4];
        self.position += 1;
        v
    }
    fn next_2d(&mut self) -> [f32; 2] {
        self.next_n()
    }
    fn with_branch<R>(&mut self, k: u32, f: impl FnOnce(&mut Self) -> R) -> R {
        f(&mut self.branch(k))
    }
    /// A block of `N` numbers: from one set if `N` ≤ 4 (starting the next set when the rest of
    /// the current one is too short), else from the start of a fresh set on.
    ///
    /// A block of at most four is copied out of its set at once (one check for a new pair, one
    /// copy), not read number by number through `next_1d` (a check and a load at a computed
    /// index per number: callgrind put 3% of the door's instructions there); the numbers are
    /// the same.
    #[inline]
    fn next_n<const N: usize>(&mut self) -> [f32; N] {
        let used_of_set = self.position % 4;
        if used_of_set != 0 && used_of_set + N > 4 {
            self.position += 4 - used_of_set;
        }
        let mut u = [0.0; N];
        if N <= 4 {
            if self.position == 8 {
                self.start_next_pair();
            }
            // The block fits in what is left of the set (the skip above), so it does not cross
            // into the next set or past the pair.
            let (set, used) = (self.position / 4, self.position % 4);
            u.copy_from_slice(&self.values[set][used..used + N]);
            self.position += N;
        } else {
            for x in &mut u {
                *x = self.next_1d();
            }
        }
        u
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn points(kind: SamplerKind, x: u32, y: u32, n: u64, stream: u32) -> Vec<[f32; 4]> {
        let mut rng = Rng::new(5, 0);
        (0..n)
            .map(|i| {
                let mut p = PixelSampler::new(kind, &mut rng, 5, x, y, i);
                let mut s = p.stream(stream);
                let a: [f32; 2] = s.next_2d();
                let b: [f32; 2] = s.next_2d();
                [a[0], a[1], b[0], b[1]]
            })
            .collect()
    }

    /// Number of the 16×16 cells of the unit square that `n` = 256 points leave empty.
    fn empty_cells(p: &[[f32; 2]]) -> usize {
        let mut hit = [false; 256];
        for q in p {
            hit[(q[0] * 16.0) as usize * 16 + (q[1] * 16.0) as usize] = true;
        }
        hit.iter().filter(|h| !**h).count()
    }

    /// The first 256 film positions of a pixel are a (0, 8, 2)-net: one point in each of the
    /// 16×16 cells (Sobol's first two dimensions form a (0, 2)-sequence, which Owen scrambling
    /// keeps). Independent points, the wrong variant, leave about 256/e ≈ 94 cells empty in
    /// expectation (the test asserts more than 60 for them, so both halves can fail).
    #[test]
    fn film_positions_stratify_and_independent_ones_do_not() {
        let take = |kind| -> Vec<[f32; 2]> { points(kind, 3, 7, 256, 0).iter().map(|p| [p[0], p[1]]).collect() };
        assert_eq!(empty_cells(&take(SamplerKind::Sobol)), 0);
        let independent = empty_cells(&take(SamplerKind::Independent));
        assert!(independent > 60, "independent points left {independent} cells empty");
    }

    /// Pixels, streams and seeds get different sequences; the same arguments the same bits; the
    /// numbers are in [0, 1).
    #[test]
    fn sequences_are_keyed_and_reproducible() {
        let a = points(SamplerKind::Sobol, 3, 7, 64, 0);
        assert_eq!(a, points(SamplerKind::Sobol, 3, 7, 64, 0));
        assert_ne!(a, points(SamplerKind::Sobol, 4, 7, 64, 0));
        assert_ne!(a, points(SamplerKind::Sobol, 3, 7, 64, 1));
        assert!(a.iter().flatten().all(|v| (0.0..1.0).contains(v)));
        let mut rng = Rng::new(0, 0);
        let other_seed: [f32; 2] = PixelSampler::new(SamplerKind::Sobol, &mut rng, 6, 3, 7, 0).stream(0).next_2d();
        assert_ne!([a[0][0], a[0][1]], other_seed);
    }

    /// A block that does not fit in the rest of a set starts the next one: reading 1 then 4
    /// gives the same 4 as reading 2 then 4 (both skip to set 1), and a second stream's sets are
    /// not the first's.
    #[test]
    fn blocks_start_a_set_when_they_do_not_fit() {
        let mut s = SobolStream::new(9, 17);
        s.next_1d();
        let after_one: [f32; 4] = s.next_n();
        let mut t = SobolStream::new(9, 17);
        let _: [f32; 2] = t.next_n();
        let after_two: [f32; 4] = t.next_n();
        assert_eq!(after_one, after_two);
        let mut r = SobolStream::new(9, 17);
        let first: [f32; 4] = r.next_n();
        let (a, b) = (first[1], r.next_1d());
        assert_ne!(a, b);
    }

    /// The stream reads what it read when it called `sobol_burley::sample_4d` one set at a time
    /// (the renderer's images stay bit for bit the same): 4096 streams under random read
    /// patterns (blocks of 1 to 6 numbers) against that stream, rebuilt here.
    #[test]
    fn streams_read_the_crates_sets_in_the_same_places() {
        /// `SobolStream` as it was before sets were computed in-house, two at a time.
        struct CrateStream {
            key: u64,
            index: u32,
            set: u32,
            values: [f32; 4],
            position: usize,
        }
        impl CrateStream {
            fn next_1d(&mut self) -> f32 {
                if self.position == 4 {
                    self.start_next_set();
                }
                self.position += 1;
                self.values[self.position - 1]
            }
            fn start_next_set(&mut self) {
                self.set = self.set.wrapping_add(1);
                self.values = sobol_burley::sample_4d(self.index, 0, splitmix64(self.key ^ self.set as u64) as u32);
                self.position = 0;
            }
            fn next_n(&mut self, n: usize) -> Vec<f32> {
                if self.position + n > 4 && self.position != 0 {
                    self.start_next_set();
                }
                (0..n).map(|_| self.next_1d()).collect()
            }
        }
        fn block(s: &mut SobolStream, n: usize) -> Vec<f32> {
            match n {
                1 => s.next_n::<1>().to_vec(),
                2 => s.next_n::<2>().to_vec(),
                3 => s.next_n::<3>().to_vec(),
                4 => s.next_n::<4>().to_vec(),
                5 => s.next_n::<5>().to_vec(),
                _ => s.next_n::<6>().to_vec(),
            }
        }
        let mut pattern = Rng::new(11, 0);
        for k in 0..4096u64 {
            let (key, index) = (splitmix64(k), (splitmix64(!k) & 0xFFFF) as u32);
            let mut ours = SobolStream::new(key, index);
            let mut crates = CrateStream { key, index, set: u32::MAX, values: [0.0; 4], position: 4 };
            for _ in 0..12 {
                let n = 1 + (pattern.uniform() * 6.0) as usize;
                if n == 1 && pattern.uniform() < 0.5 {
                    assert_eq!(ours.next_1d().to_bits(), crates.next_1d().to_bits(), "stream {k}");
                } else {
                    let (a, b) = (block(&mut ours, n), crates.next_n(n));
                    assert_eq!(
                        a.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                        b.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                        "stream {k}, block of {n}"
                    );
                }
            }
        }
    }

    /// Each coordinate of a set is uniform: over 4096 points of 64 pixels' sequences the mean of
    /// every coordinate is within 4σ of 1/2 (σ = 1/√(12·N) for independent points; stratified
    /// ones are closer).
    #[test]
    fn coordinates_are_uniform() {
        let mut sums = [0.0f64; 4];
        let mut count = 0.0;
        for px in 0..64 {
            for p in points(SamplerKind::Sobol, px, 0, 64, 2) {
                for (s, v) in sums.iter_mut().zip(p) {
                    *s += v as f64;
                }
                count += 1.0;
            }
        }
        let sigma = 1.0 / (12.0f64 * count).sqrt();
        for s in sums {
            assert!((s / count - 0.5).abs() < 4.0 * sigma, "mean {}", s / count);
        }
    }
}
