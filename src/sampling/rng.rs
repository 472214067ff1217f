use rand::Rng as _;
use rand_distr::StandardNormal;
use rand_pcg::Pcg64Mcg;

/// A deterministic random stream. Streams are derived from (seed, stream index) — a pixel, a
/// tile, a chain — never from thread identity or timing, so a render is reproducible bit for bit.
/// Serialisable (`rand_pcg`'s `serde1`) so that a chain's stream is saved in checkpoints.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Rng(Pcg64Mcg);

impl Rng {
    /// The stream `stream` of the render seeded with `seed`.
    pub fn new(seed: u64, stream: u64) -> Rng {
        let a = splitmix64(seed ^ 0x9E37_79B9_7F4A_7C15);
        let b = splitmix64(stream.wrapping_add(a));
        let state = ((a as u128) << 64) | (b as u128);
        Rng(Pcg64Mcg::new(state | 1))
    }
    /// A uniform number in [0, 1).
    #[inline]
    pub fn uniform(&mut self) -> f32 {
        // 24 random mantissa bits: exactly representable, never 1.0.
        (self.0.gen::<u32>() >> 8) as f32 * (1.0 / 16_777_216.0)
    }
    /// A uniform number in [0, 1) with double precision.
    #[inline]
    pub fn uniform_f64(&mut self) -> f64 {
        (self.0.gen::<u64>() >> 11) as f64 * (1.0 / 9_007_199_254_740_992.0)
    }
    /// A standard normal deviate (`rand_distr`'s ziggurat), in double precision.
    #[inline]
    pub fn standard_normal(&mut self) -> f64 {
        self.0.sample(StandardNormal)
    }
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.0.gen::<u64>()
    }
}

/// SplitMix64 finaliser: decorrelates nearby seeds and stream indices.
pub fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let a: Vec<f32> = (0..4)
            .map({
                let mut r = Rng::new(7, 3);
                move |_| r.uniform()
            })
            .collect();
        let b: Vec<f32> = (0..4)
            .map({
                let mut r = Rng::new(7, 3);
                move |_| r.uniform()
            })
            .collect();
        let c: Vec<f32> = (0..4)
            .map({
                let mut r = Rng::new(7, 4);
                move |_| r.uniform()
            })
            .collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert!(a.iter().all(|&x| (0.0..1.0).contains(&x)));
    }
}
