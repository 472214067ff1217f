//! Dimensions 0–3 of Burley's Owen-scrambled, index-shuffled Sobol sequence (Burley 2020,
//! "Practical Hash-based Owen Scrambling", JCGT 9(4)) for indices below 2^16: the one 4D set
//! [`SobolStream`](super::SobolStream) pads with, evaluated bit for bit as the `sobol_burley`
//! crate's `sample_4d(index, 0, seed)` evaluates it.
//!
//! # Why not the crate
//!
//! The renderer asks for a fresh set (a fresh seed) at every path vertex, so the set's cost is a
//! direct share of the path tracer's time: `sobol_burley::sample_4d` was 14.9% of pt's CPU time
//! on the Cornell box and 13.4% on the door (`perf record`). The crate is general
//! (256 dimensions, any set): its Sobol product walks the index's set bits one by one (a loop of
//! unpredictable length) and it is built for baseline x86-64, where its four-lane multiplies are
//! emulated. Here the set is always dimension set 0 and the index has 16 bits, so the Sobol
//! matrix–vector product is two lookups in 256-entry tables, one per byte of the index (8 KiB,
//! L1 resident); the hashes are plain `u32` arithmetic, compiled also for SSE4.1 (chosen at run
//! time), and two sets are computed per call so their dependency chains overlap; with AVX2 (also
//! chosen at run time) the two sets share one chain of eight-lane operations.
//!
//! Measured (thread CPU time, medians of 15 interleaved rounds of 2^20 sets, load 8–13 on the
//! 2-core machine; [`tests::sobol_set_cost`]): 36.5 ns per set for the crate against 11.1 ns here
//! (3.3×) when sets are independent, 45.2 against 15.5 ns (2.9×) when each pair's seed waits for
//! the previous numbers. In the render the sets' share is 7.2% (Cornell box) and 6.0% (door) with
//! this module, about 2.2× less time; the images are bit for bit the same. docs/lab/sampling.md,
//! "The Sobol sets' cost", has the commands and the whole-render figures. That is the reason this
//! module exists beside a maintained crate that computes the same numbers.
//!
//! The crate stays as the test oracle (a dev-dependency): every index of 16 seeds must give the
//! crate's bits, and the stream must read the crate's sets in the same places.
//!
//! # The construction (Burley 2020, Sec. 3–5)
//!
//! A point is `owen_d(sobol_d(shuffle(i)))` for dimension d:
//! - `shuffle` is a nested uniform (Owen) scramble of the index's bits under a hash of the seed
//!   (Burley Sec. 4): it permutes the sequence's points in an order that keeps every power-of-two
//!   prefix a (0, m, s)-net, so different seeds give independent sequences.
//! - `sobol_d` is the Sobol generator-matrix product for dimension d (direction numbers from Joe
//!   and Kuo 2008, computed below at compile time).
//! - `owen_d` Owen-scrambles the result with a per-dimension hash of the seed (Burley Sec. 3).
//!
//! Both scrambles are Laine–Karras-style hashes on the bit-*reversed* integer (Burley Sec. 3,
//! `nested_uniform_scramble`): in reversed order a multiply carries only toward the input's less
//! significant digits, so each output digit depends on the digits above it, which is what makes
//! the hash a nested uniform scramble. Bit identity with the crate fixes the constants: the hash's
//! multipliers are the improved Laine–Karras hash of Vegard (psychopath.io, "Building a Better LK
//! Hash", 2021) and the seed hash is a two-multiply integer hash from Wellons's hash-prospector;
//! the per-dimension salts and the seed multiplier are the crate's. Everything works on
//! reversed bits, so the tables hold bit-reversed direction numbers and the result is reversed
//! once at the end.

/// Joe and Kuo's primitive polynomials and initial direction numbers ("new-joe-kuo-6.21201",
/// Joe & Kuo 2008, "Constructing Sobol sequences with better two-dimensional projections") for
/// Sobol dimensions 1–3: degree s, the polynomial's inner coefficients a (a_1 the most significant
/// of s − 1 bits) and the initial m_1..m_s. Dimension 0 is the van der Corput sequence.
const JOE_KUO: [(usize, u32, [u32; 3]); 3] = [(1, 0, [1, 0, 0]), (2, 1, [1, 3, 0]), (3, 1, [1, 3, 1])];

/// Bits of the index the sequence uses (2^16 points).
const INDEX_BITS: usize = 16;

/// The direction numbers v_k (k = 0..16, as 32-bit fractions) of Sobol dimension `dim` ≤ 3:
/// v_k = m_k / 2^(k+1) for k < s, then Bratley and Fox's recurrence
/// v_k = a_1 v_{k−1} ⊕ … ⊕ a_{s−1} v_{k−s+1} ⊕ v_{k−s} ⊕ (v_{k−s} >> s).
const fn direction_numbers(dim: usize) -> [u32; INDEX_BITS] {
    let mut v = [0u32; INDEX_BITS];
    let mut k = 0;
    if dim == 0 {
        while k < INDEX_BITS {
            v[k] = 1 << (31 - k);
            k += 1;
        }
        return v;
    }
    let (s, a, m) = JOE_KUO[dim - 1];
    while k < INDEX_BITS {
        if k < s {
            v[k] = m[k] << (31 - k);
        } else {
            let mut x = v[k - s] ^ (v[k - s] >> s);
            let mut j = 1;
            while j < s {
                if (a >> (s - 1 - j)) & 1 == 1 {
                    x ^= v[k - j];
                }
                j += 1;
            }
            v[k] = x;
        }
        k += 1;
    }
    v
}

/// What a set is computed from: the Sobol product tables and the scrambles' salts (one value,
/// so the tests can check that a single wrong entry or salt is caught).
#[derive(Clone)]
struct SetConstants {
    /// `sobol_bytes[h][b][d]`: dimension d's Sobol product (bit-reversed) of the index bits
    /// 8h..8h+8 given by byte `b` of the bit-reversed index — bit 7 − j of `b` is index bit 8h + j.
    /// A 16-bit index's product is the XOR of its two bytes' entries (the product is linear over
    /// GF(2)). 2 × 256 × 16 bytes = 8 KiB.
    sobol_bytes: [[[u32; 4]; 256]; 2],
    /// Salt of the index shuffle's seed hash.
    shuffle_salt: u32,
    /// Multiplier of the seed in the per-dimension scrambles, so that a structured seed does not
    /// cancel against the dimension.
    scramble_seed_multiplier: u32,
    /// Per-dimension salts of the Owen scrambles.
    scramble_salts: [u32; 4],
}

/// The crate's salts and multiplier (bit identity), the tables from Joe and Kuo's numbers.
static SET_CONSTANTS: SetConstants = SetConstants {
    sobol_bytes: sobol_byte_tables(),
    shuffle_salt: 0x79c6_8e4a,
    scramble_seed_multiplier: 0x9c8f_2d3b,
    scramble_salts: [0x912f_69ba, 0x174f_18ab, 0x691e_72ca, 0xb40c_c1b8],
};

const fn sobol_byte_tables() -> [[[u32; 4]; 256]; 2] {
    let v = [direction_numbers(0), direction_numbers(1), direction_numbers(2), direction_numbers(3)];
    let mut tables = [[[0u32; 4]; 256]; 2];
    let mut h = 0;
    while h < 2 {
        let mut b = 0;
        while b < 256 {
            let mut d = 0;
            while d < 4 {
                let mut x = 0u32;
                let mut j = 0;
                while j < 8 {
                    if (b >> (7 - j)) & 1 == 1 {
                        x ^= v[d][8 * h + j].reverse_bits();
                    }
                    j += 1;
                }
                tables[h][b][d] = x;
                d += 1;
            }
            b += 1;
        }
        h += 1;
    }
    tables
}

/// A 32-bit integer hash (two multiplies, three xorshifts: hash-prospector's) of a seed, with a
/// fixed xor first so that 0 does not map to 0.
#[inline(always)]
fn seed_hash(mut n: u32) -> u32 {
    n ^= 0xe6fe_3beb;
    n ^= n >> 16;
    n = n.wrapping_mul(0x7feb_352d);
    n ^= n >> 15;
    n = n.wrapping_mul(0x846c_a68b);
    n ^ (n >> 16)
}

/// Nested uniform (Owen) scramble of a bit-reversed integer keyed by a well-mixed `scramble`
/// (Burley Sec. 3, Laine–Karras form with Vegard's constants): every step maps bit k of the
/// result from bits ≤ k of the input, i.e. from the digits at or above it in unreversed order.
#[inline(always)]
fn owen_scramble_reversed(mut x: u32, scramble: u32) -> u32 {
    x ^= x.wrapping_mul(0x3d20_adea);
    x = x.wrapping_add(scramble);
    x = x.wrapping_mul((scramble >> 16) | 1);
    x ^= x.wrapping_mul(0x0552_6c56);
    x ^ x.wrapping_mul(0x53a2_2864)
}

/// Sets `seeds[0]` and `seeds[1]` of point `index` (< 2^16), dimensions 0–3, given as
/// `index_reversed` = `index.reverse_bits()` (a stream reverses its index once). Each is equal bit
/// for bit to `sobol_burley::sample_4d(index, 0, seed)`.
///
/// Two sets per call because one set is a chain of dependent multiplies (about 60 cycles from
/// seed to floats) with little for the processor to overlap: the second set's chain runs beside
/// the first, so a pair costs little more than one set's latency. The stream reads its sets in
/// order and asks for them two at a time.
#[inline]
pub(super) fn sobol_set_pair(index_reversed: u32, seeds: [u32; 2]) -> [[f32; 4]; 2] {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked just above), which the function is compiled for.
        return unsafe { sobol_set_pair_avx2(&SET_CONSTANTS, index_reversed, seeds) };
    }
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("sse4.1") && std::arch::is_x86_feature_detected!("ssse3") {
        // SAFETY: the CPU has both features the function is compiled for (checked just above).
        return unsafe { sobol_set_pair_sse41(index_reversed, seeds) };
    }
    sobol_set_pair_from(&SET_CONSTANTS, index_reversed, seeds)
}

/// [`sobol_set_pair`] compiled for SSE4.1 and SSSE3 (x86-64-v2, every x86-64 CPU since about
/// 2008): the four dimensions' multiplies become one `pmulld` each instead of baseline x86-64's
/// two-`pmuludq`-and-shuffles emulation, and the bit reversal two `pshufb` nibble lookups.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse4.1,ssse3")]
fn sobol_set_pair_sse41(index_reversed: u32, seeds: [u32; 2]) -> [[f32; 4]; 2] {
    sobol_set_pair_from(&SET_CONSTANTS, index_reversed, seeds)
}

/// [`sobol_set_pair`] in AVX2's eight 32-bit lanes: both sets' four dimensions in one register
/// (lanes 0–3 the first set, 4–7 the second), so the per-dimension seed hashes, the Owen
/// scrambles, the bit reversals and the conversions are one chain of 256-bit operations instead
/// of two chains of 128-bit ones; the index shuffles stay scalar. The same operations on the same
/// integers as [`sobol_set_from`], so the same bits (`sets_are_the_crates_bit_for_bit` checks this
/// path and the SSE4.1 one against the crate).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn sobol_set_pair_avx2(c: &SetConstants, index_reversed: u32, seeds: [u32; 2]) -> [[f32; 4]; 2] {
    use std::arch::x86_64::*;
    let sobol_of = |seed: u32| {
        let shuffled = owen_scramble_reversed(index_reversed, seed_hash(seed ^ c.shuffle_salt));
        let high = &c.sobol_bytes[0][(shuffled >> 24) as usize];
        let low = &c.sobol_bytes[1][((shuffled >> 16) & 0xFF) as usize];
        [high[0] ^ low[0], high[1] ^ low[1], high[2] ^ low[2], high[3] ^ low[3]]
    };
    let (s0, s1) = (sobol_of(seeds[0]), sobol_of(seeds[1]));
    let (t0, t1) =
        (seeds[0].wrapping_mul(c.scramble_seed_multiplier), seeds[1].wrapping_mul(c.scramble_seed_multiplier));
    let salts = c.scramble_salts;
    let mut out = [[0.0f32; 4]; 2];
    // SAFETY: AVX2 is enabled for this function; the loads and the store are unaligned ones of
    // exactly the arrays' 32 bytes.
    unsafe {
        let lanes = |a: [u32; 4], b: [u32; 4]| {
            let v = [a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3]];
            _mm256_loadu_si256(v.as_ptr().cast())
        };
        let mul = |x: __m256i, k: u32| _mm256_mullo_epi32(x, _mm256_set1_epi32(k as i32));
        let x = lanes(s0, s1);
        // seed_hash(seed_term ^ salt_d) in every lane.
        let mut n = _mm256_xor_si256(lanes([t0; 4], [t1; 4]), lanes(salts, salts));
        n = _mm256_xor_si256(n, _mm256_set1_epi32(0xe6fe_3beb_u32 as i32));
        n = _mm256_xor_si256(n, _mm256_srli_epi32::<16>(n));
        n = mul(n, 0x7feb_352d);
        n = _mm256_xor_si256(n, _mm256_srli_epi32::<15>(n));
        n = mul(n, 0x846c_a68b);
        let scramble = _mm256_xor_si256(n, _mm256_srli_epi32::<16>(n));
        // owen_scramble_reversed(x, scramble).
        let mut x = _mm256_xor_si256(x, mul(x, 0x3d20_adea));
        x = _mm256_add_epi32(x, scramble);
        x = _mm256_mullo_epi32(x, _mm256_or_si256(_mm256_srli_epi32::<16>(scramble), _mm256_set1_epi32(1)));
        x = _mm256_xor_si256(x, mul(x, 0x0552_6c56));
        x = _mm256_xor_si256(x, mul(x, 0x53a2_2864));
        // reverse_bits of each lane: the bytes' order reversed, then each byte's bits by nibble
        // lookups.
        let byte_swap = _mm256_setr_epi8(
            3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12, 3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12,
        );
        let x = _mm256_shuffle_epi8(x, byte_swap);
        let nibble_reversed = _mm256_setr_epi8(
            0x0, 0x8, 0x4, 0xc, 0x2, 0xa, 0x6, 0xe, 0x1, 0x9, 0x5, 0xd, 0x3, 0xb, 0x7, 0xf, 0x0, 0x8, 0x4, 0xc, 0x2,
            0xa, 0x6, 0xe, 0x1, 0x9, 0x5, 0xd, 0x3, 0xb, 0x7, 0xf,
        );
        let low_nibbles = _mm256_set1_epi8(0x0f);
        let lo = _mm256_and_si256(x, low_nibbles);
        let hi = _mm256_and_si256(_mm256_srli_epi16::<4>(x), low_nibbles);
        let reversed = _mm256_or_si256(
            _mm256_slli_epi16::<4>(_mm256_shuffle_epi8(nibble_reversed, lo)),
            _mm256_shuffle_epi8(nibble_reversed, hi),
        );
        // The top 23 bits as a float in [0, 1): (n >> 9) · 2^−23, as `sobol_set_from`.
        let mantissa = _mm256_or_si256(_mm256_srli_epi32::<9>(reversed), _mm256_set1_epi32(0x3f80_0000));
        let v = _mm256_sub_ps(_mm256_castsi256_ps(mantissa), _mm256_set1_ps(1.0));
        _mm256_storeu_ps(out.as_mut_ptr().cast(), v);
    }
    out
}

#[inline(always)]
fn sobol_set_pair_from(c: &SetConstants, index_reversed: u32, seeds: [u32; 2]) -> [[f32; 4]; 2] {
    // Written out, not `seeds.map(..)`: the closure `map` calls is not inlined, so it would be
    // compiled without the caller's SSE4.1 and the two chains would run one after the other.
    [sobol_set_from(c, index_reversed, seeds[0]), sobol_set_from(c, index_reversed, seeds[1])]
}

/// The set under the constants `c` (the tests' wrong variants change one of them).
#[inline(always)]
fn sobol_set_from(c: &SetConstants, index_reversed: u32, seed: u32) -> [f32; 4] {
    // Burley Sec. 4: shuffle the index (only its top 16 reversed bits are used).
    let shuffled = owen_scramble_reversed(index_reversed, seed_hash(seed ^ c.shuffle_salt));
    let high = &c.sobol_bytes[0][(shuffled >> 24) as usize];
    let low = &c.sobol_bytes[1][((shuffled >> 16) & 0xFF) as usize];
    let seed_term = seed.wrapping_mul(c.scramble_seed_multiplier);
    let mut out = [0.0; 4];
    for d in 0..4 {
        let sobol = high[d] ^ low[d];
        let scrambled = owen_scramble_reversed(sobol, seed_hash(seed_term ^ c.scramble_salts[d]));
        // The top 23 bits as a float in [0, 1): exact, (n >> 9) · 2^−23.
        out[d] = f32::from_bits((scrambled.reverse_bits() >> 9) | 0x3f80_0000) - 1.0;
    }
    out
}

#[cfg(test)]
mod tests {
    use std::hint::black_box;

    use super::*;
    use crate::sampling::rng::splitmix64;

    /// The compile-time direction numbers are the crate's (the Sobol product of every single
    /// index bit, unscrambled).
    #[test]
    fn direction_numbers_are_joe_kuos() {
        for d in 0..4 {
            for (k, vk) in direction_numbers(d).iter().enumerate() {
                let one_bit_reversed = (1u32 << k).reverse_bits();
                assert_eq!(
                    sobol_burley::parts::sobol_rev(one_bit_reversed, d as u32),
                    vk.reverse_bits(),
                    "d {d} k {k}"
                );
            }
        }
    }

    /// Seeds of the oracle comparison: the extremes, a structured one, and the kind
    /// `SobolStream` passes (the low half of splitmix64 of consecutive keys).
    fn oracle_seeds(n_hashed: u64) -> Vec<u32> {
        let mut seeds = vec![0, 1, u32::MAX, 0x8000_0000];
        seeds.extend((0..n_hashed).map(|k| splitmix64(k) as u32));
        seeds
    }

    /// Sets (of all 2^16 indices under each seed) whose bits differ from the crate's.
    fn sets_unlike_the_crate(set: impl Fn(u32, u32) -> [f32; 4], seeds: &[u32]) -> usize {
        let mut unlike = 0;
        for &seed in seeds {
            for index in 0..1u32 << 16 {
                let ours = set(index.reverse_bits(), seed).map(f32::to_bits);
                let crates = sobol_burley::sample_4d(index, 0, seed).map(f32::to_bits);
                unlike += (ours != crates) as usize;
            }
        }
        unlike
    }

    /// Every index of 16 seeds gives the crate's bits (4 · 2^20 numbers) in either place of a
    /// pair, both as the renderer calls it (the SSE4.1 code on this machine) and compiled for
    /// baseline x86-64.
    #[test]
    fn sets_are_the_crates_bit_for_bit() {
        let seeds = oracle_seeds(12);
        assert_eq!(sets_unlike_the_crate(|i, seed| sobol_set_pair(i, [seed, !seed])[0], &seeds), 0);
        assert_eq!(sets_unlike_the_crate(|i, seed| sobol_set_pair(i, [seed ^ 0x5555, seed])[1], &seeds), 0);
        assert_eq!(sets_unlike_the_crate(|i, seed| sobol_set_from(&SET_CONSTANTS, i, seed), &seeds), 0);
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("sse4.1") && std::arch::is_x86_feature_detected!("ssse3") {
                // SAFETY: the features were detected just above.
                let sse = |i, seeds| unsafe { sobol_set_pair_sse41(i, seeds) };
                assert_eq!(sets_unlike_the_crate(|i, seed| sse(i, [seed, !seed])[0], &seeds), 0);
                assert_eq!(sets_unlike_the_crate(|i, seed| sse(i, [seed ^ 0x5555, seed])[1], &seeds), 0);
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: AVX2 was detected just above.
                let avx = |i, seeds| unsafe { sobol_set_pair_avx2(&SET_CONSTANTS, i, seeds) };
                assert_eq!(sets_unlike_the_crate(|i, seed| avx(i, [seed, !seed])[0], &seeds), 0);
                assert_eq!(sets_unlike_the_crate(|i, seed| avx(i, [seed ^ 0x5555, seed])[1], &seeds), 0);
            }
        }
    }

    /// The comparison catches a single wrong bit of one table entry (a Sobol product used by
    /// 1/256 of the indices), a per-dimension salt off by one, and a wrong shuffle salt.
    #[test]
    fn a_wrong_table_entry_or_salt_is_caught() {
        let seeds = oracle_seeds(2);
        let mut entry = SET_CONSTANTS.clone();
        entry.sobol_bytes[1][0x5a][2] ^= 1 << 12;
        let mut salt = SET_CONSTANTS.clone();
        salt.scramble_salts[3] ^= 1;
        let mut shuffle = SET_CONSTANTS.clone();
        shuffle.shuffle_salt ^= 1 << 31;
        for (name, c) in [("table entry", entry), ("dimension salt", salt), ("shuffle salt", shuffle)] {
            let unlike = sets_unlike_the_crate(|i, seed| sobol_set_from(&c, i, seed), &seeds);
            eprintln!("wrong {name}: {unlike} of {} sets differ", seeds.len() << 16);
            assert!(unlike > 0, "wrong {name} not caught");
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: AVX2 was detected just above.
                let avx = |i, seed: u32| unsafe { sobol_set_pair_avx2(&c, i, [!seed, seed])[1] };
                let unlike = sets_unlike_the_crate(avx, &seeds);
                assert!(unlike > 0, "wrong {name} not caught in the AVX2 pair");
            }
        }
    }

    /// Nanoseconds per set, this module against `sobol_burley::sample_4d`, as `SobolStream`
    /// calls them (a splitmix64 seed per set, two sets per call of ours; the index reversal
    /// counted here although the stream does it once per index), and the same with each pair's
    /// seeds depending on the previous pair's numbers (latency, as in a path whose next vertex
    /// waits for its numbers). Medians of 15 interleaved rounds of 2^20 sets, in thread CPU time.
    /// A benchmark, not a test: `cargo test --release --lib sobol_set_cost -- --ignored
    /// --nocapture`.
    #[test]
    #[ignore]
    fn sobol_set_cost() {
        const SETS: u32 = 1 << 20;
        /// This thread's CPU time in seconds (not wall time: the machine is shared).
        fn thread_cpu_seconds() -> f64 {
            let mut t = libc::timespec { tv_sec: 0, tv_nsec: 0 };
            // SAFETY: `t` is a valid timespec to write; the clock id is a constant Linux knows.
            unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) };
            t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9
        }
        /// Per set, `pair` computing sets 2k and 2k + 1 of index k mod 2^16; `CHAINED`: their
        /// seeds depend on the numbers of the pair before (a constant, so that the independent
        /// loop carries no dependency through a select).
        fn ns_per_set<const CHAINED: bool>(pair: impl Fn(u32, [u32; 2]) -> [[f32; 4]; 2]) -> f64 {
            let start = thread_cpu_seconds();
            let mut sum = 0u32;
            for k in 0..SETS / 2 {
                let link = if CHAINED { (sum & 1) as u64 } else { 0 };
                let seeds = [splitmix64((2 * k as u64) ^ link) as u32, splitmix64((2 * k + 1) as u64 ^ link) as u32];
                for v in pair(black_box(k & 0xFFFF), seeds) {
                    sum ^= v[0].to_bits() ^ v[1].to_bits() ^ v[2].to_bits() ^ v[3].to_bits();
                }
            }
            black_box(sum);
            (thread_cpu_seconds() - start) * 1e9 / SETS as f64
        }
        let crates = |index, seeds: [u32; 2]| seeds.map(|seed| sobol_burley::sample_4d(index, 0, seed));
        let ours = |index: u32, seeds| sobol_set_pair(index.reverse_bits(), seeds);
        let baseline = |index: u32, seeds| sobol_set_pair_from(&SET_CONSTANTS, index.reverse_bits(), seeds);
        let mut times: [Vec<f64>; 6] = Default::default();
        for _ in 0..15 {
            times[0].push(ns_per_set::<false>(crates));
            times[1].push(ns_per_set::<true>(crates));
            times[2].push(ns_per_set::<false>(ours));
            times[3].push(ns_per_set::<true>(ours));
            times[4].push(ns_per_set::<false>(baseline));
            times[5].push(ns_per_set::<true>(baseline));
        }
        let [c, c_chained, o, o_chained, b, b_chained] = times.map(|mut t| {
            t.sort_by(f64::total_cmp);
            t[7]
        });
        println!(
            "ns per 4D set (thread CPU, median of 15 rounds of 2^20 sets, seed hash included), \
             independent / chained: sobol_burley::sample_4d {c:.2} / {c_chained:.2}; sobol_set_pair \
             {o:.2} / {o_chained:.2} (crate ÷ ours {:.2}× / {:.2}×); sobol_set_pair for baseline \
             x86-64 {b:.2} / {b_chained:.2} ({:.2}× / {:.2}×)",
            c / o,
            c_chained / o_chained,
            c / b,
            c_chained / b_chained
        );
    }
}
