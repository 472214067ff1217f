use glam::Vec3;

/// A ray `o + t d` for `t` in `[t_min, t_max]`. `d` need not be normalised, but every integrator
/// in plexus passes unit directions so that `t` is a distance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub o: Vec3,
    pub d: Vec3,
    pub t_min: f32,
    pub t_max: f32,
}

impl Ray {
    pub fn new(o: Vec3, d: Vec3) -> Self {
        Ray { o, d, t_min: 0.0, t_max: f32::INFINITY }
    }
    pub fn segment(o: Vec3, d: Vec3, t_max: f32) -> Self {
        Ray { o, d, t_min: 0.0, t_max }
    }
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.o + self.d * t
    }
}

/// The closest hit reported by an accelerator. Barycentrics follow Embree's convention:
/// the hit point is `(1 - b1 - b2) v0 + b1 v1 + b2 v2`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub geom_id: u32,
    pub prim_id: u32,
    pub b1: f32,
    pub b2: f32,
}

/// Axis-aligned bounding box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Aabb::EMPTY
    }
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb { min: Vec3::splat(f32::INFINITY), max: Vec3::splat(f32::NEG_INFINITY) };
    pub fn from_point(p: Vec3) -> Self {
        Aabb { min: p, max: p }
    }
    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }
    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb { min: self.min.min(o.min), max: self.max.max(o.max) }
    }
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }
    pub fn extent(&self) -> Vec3 {
        if self.is_empty() {
            Vec3::ZERO
        } else {
            self.max - self.min
        }
    }
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }
    pub fn surface_area(&self) -> f32 {
        let e = self.extent();
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }
    /// Centre and radius of a sphere that contains the box.
    pub fn bounding_sphere(&self) -> (Vec3, f32) {
        if self.is_empty() {
            return (Vec3::ZERO, 0.0);
        }
        let c = self.center();
        (c, (self.max - c).length())
    }
}

/// Offsets `p` along the normal `n` by the error bound `p_error`, on the side that `w` points to,
/// then rounds each coordinate one ulp further away (pbrt-v4's OffsetRayOrigin, Sec. 6.8.6), so a
/// ray spawned from the result cannot re-intersect the surface it leaves at any scene scale.
///
/// Branch-free: the signs of the offset's components are those of a random direction's, so the
/// three "up, down or neither" branches of the textbook form were mispredicted about half the
/// time (5–9% of the path tracer's profile on the Cornell box). The result is bit for
/// bit the textbook form's (`next_float_up`/`next_float_down`, kept with the tests that compare them).
#[inline(always)]
pub fn offset_ray_origin(p: Vec3, p_error: Vec3, n: Vec3, w: Vec3) -> Vec3 {
    let d = n.abs().dot(p_error);
    let d = if w.dot(n) < 0.0 { -d } else { d };
    let offset = n * d;
    let po = p + offset;
    step_by_sign3(po, offset)
}

/// [`step_by_sign`] of each coordinate of `v` by the sign of the same coordinate of `dir`.
///
/// On x86-64 the three coordinates are stepped at once in SSE2 lanes (the same integer operations
/// on the bits, as masks): the scalar form was 45 instructions a spawned ray, 2.6% of the door's
/// instructions (callgrind). Bit for bit the scalar form
/// (`simd_step_is_the_scalar_step_bit_for_bit`).
#[inline(always)]
fn step_by_sign3(v: Vec3, dir: Vec3) -> Vec3 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        // SAFETY: SSE2 is part of x86-64; the intrinsics only compute on registers.
        unsafe {
            let vf = _mm_set_ps(0.0, v.z, v.y, v.x);
            let df = _mm_set_ps(0.0, dir.z, dir.y, dir.x);
            let zero = _mm_setzero_ps();
            let bits = _mm_castps_si128(vf);
            // All ones where the step is up / down (a zero or NaN `dir`: neither).
            let up = _mm_castps_si128(_mm_cmpgt_ps(df, zero));
            let down = _mm_castps_si128(_mm_cmplt_ps(df, zero));
            let magnitude = _mm_and_si128(bits, _mm_set1_epi32(0x7fff_ffff));
            // Away from zero: stepping up from a positive value or down from a negative one.
            let grows = _mm_xor_si128(up, _mm_srai_epi32::<31>(bits));
            let finite = _mm_cmplt_epi32(magnitude, _mm_set1_epi32(0x7f80_0000));
            let ones = _mm_set1_epi32(-1);
            // +1 (subtracting the all-ones mask) where growing and finite, −1 where not growing.
            let stepped =
                _mm_add_epi32(_mm_sub_epi32(bits, _mm_and_si128(grows, finite)), _mm_andnot_si128(grows, ones));
            let at_zero = _mm_cmpeq_epi32(magnitude, _mm_setzero_si128());
            let from_zero = _mm_or_si128(_mm_and_si128(down, _mm_set1_epi32(i32::MIN)), _mm_set1_epi32(1));
            let stepped = _mm_or_si128(_mm_and_si128(at_zero, from_zero), _mm_andnot_si128(at_zero, stepped));
            let moving = _mm_or_si128(up, down);
            let out = _mm_castsi128_ps(_mm_or_si128(_mm_and_si128(moving, stepped), _mm_andnot_si128(moving, bits)));
            let mut lanes = [0.0f32; 4];
            _mm_storeu_ps(lanes.as_mut_ptr(), out);
            Vec3::new(lanes[0], lanes[1], lanes[2])
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    Vec3::new(step_by_sign(v.x, dir.x), step_by_sign(v.y, dir.y), step_by_sign(v.z, dir.z))
}

/// `next_float_up(v)` when `dir > 0`, `next_float_down(v)` when `dir < 0`, `v` otherwise (a zero or
/// NaN `dir`), computed on the bits with masks rather than selects (LLVM turned a select on the
/// direction back into a branch). Equal to those two bit for bit for every non-NaN `v`.
#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
#[inline(always)]
fn step_by_sign(v: f32, dir: f32) -> f32 {
    const SIGN: u32 = 0x8000_0000;
    const INFINITY_BITS: u32 = 0x7f80_0000;
    let bits = v.to_bits();
    let magnitude = bits & !SIGN;
    let (up, down) = ((dir > 0.0) as u32, (dir < 0.0) as u32);
    // Away from zero (the magnitude grows) when stepping up from a positive value or down from a
    // negative one: +1 on the bits, except that an infinity stays put; towards zero: −1.
    let grows = up ^ (bits >> 31);
    let finite = (magnitude < INFINITY_BITS) as u32;
    let stepped = bits.wrapping_add(grows & finite).wrapping_sub(grows ^ 1);
    // From either zero: the smallest subnormal of the side stepped to.
    let from_zero = (down << 31) | 1;
    let at_zero = 0u32.wrapping_sub((magnitude == 0) as u32);
    let stepped = (stepped & !at_zero) | (from_zero & at_zero);
    let moving = 0u32.wrapping_sub(up | down);
    f32::from_bits((stepped & moving) | (bits & !moving))
}

/// A ray leaving the point `(p, p_error)` with geometric normal `n` in direction `d`.
#[inline]
pub fn spawn_ray(p: Vec3, p_error: Vec3, n: Vec3, d: Vec3) -> Ray {
    Ray::new(offset_ray_origin(p, p_error, n, d), d)
}

/// A shadow ray from `(p, p_error, n)` towards the point `(q, q_error, nq)`; both ends are offset so
/// that neither surface occludes the segment. The direction is normalised; `t_max` stops just short
/// of the offset target.
#[inline]
pub fn spawn_ray_to(p: Vec3, p_error: Vec3, n: Vec3, q: Vec3, q_error: Vec3, nq: Vec3) -> Ray {
    let po = offset_ray_origin(p, p_error, n, q - p);
    let qo = offset_ray_origin(q, q_error, nq, p - q);
    let d = qo - po;
    let len = d.length();
    if !(len > 0.0) || !len.is_finite() {
        return Ray { o: po, d: Vec3::Z, t_min: 0.0, t_max: 0.0 };
    }
    Ray { o: po, d: d / len, t_min: 0.0, t_max: len * (1.0 - 1e-4) }
}

/// The next float above `v` (the textbook form, against which `step_by_sign` is tested).
#[cfg(test)]
fn next_float_up(v: f32) -> f32 {
    if v.is_infinite() && v > 0.0 {
        return v;
    }
    let v = if v == -0.0 { 0.0 } else { v };
    let bits = v.to_bits();
    let bits = if v >= 0.0 { bits + 1 } else { bits - 1 };
    f32::from_bits(bits)
}

/// The next float below `v` (as `next_float_up`).
#[cfg(test)]
fn next_float_down(v: f32) -> f32 {
    if v.is_infinite() && v < 0.0 {
        return v;
    }
    let v = if v == 0.0 { -0.0 } else { v };
    let bits = v.to_bits();
    let bits = if v > 0.0 { bits - 1 } else { bits + 1 };
    f32::from_bits(bits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn next_float_moves_one_ulp() {
        assert!(next_float_up(1.0) > 1.0);
        assert!(next_float_down(1.0) < 1.0);
        assert!(next_float_up(0.0) > 0.0);
        assert!(next_float_down(0.0) < 0.0);
        assert!(next_float_up(-1.0) > -1.0);
        assert_eq!(next_float_up(1.0).to_bits() - 1.0f32.to_bits(), 1);
    }

    /// The values where a one-ulp step goes wrong if it goes wrong anywhere: signed zeros,
    /// subnormals, the extremes, infinities, and a few ordinary ones (no NaN).
    const SPECIAL_FLOATS: [f32; 14] = [
        0.0,
        -0.0,
        f32::from_bits(1),
        -f32::from_bits(1),
        f32::MIN_POSITIVE,
        -f32::MIN_POSITIVE,
        f32::MAX,
        f32::MIN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        1.0,
        -1.0,
        1e5,
        -3.5e-20,
    ];

    /// The branch-free step is the textbook one bit for bit: on the special values (zeros,
    /// subnormals, the largest finite values, infinities) and on a million random bit patterns,
    /// for each of the three directions. (NaN `v` is left out: both give a NaN, with different
    /// payloads.)
    #[test]
    fn step_by_sign_matches_next_float() {
        let specials = SPECIAL_FLOATS;
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let random = (0..1_000_000).map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            f32::from_bits((state >> 32) as u32)
        });
        for v in specials.into_iter().chain(random).filter(|v| !v.is_nan()) {
            for (dir, want) in [(1.0f32, next_float_up(v)), (-1.0, next_float_down(v)), (0.0, v), (f32::NAN, v)] {
                let got = step_by_sign(v, dir);
                assert_eq!(got.to_bits(), want.to_bits(), "v = {v:e} ({:#x}), dir {dir}", v.to_bits());
            }
        }
    }

    /// The SSE2 step of three coordinates is the scalar step of each, bit for bit: every pair of
    /// the special values (signed zeros, subnormals, extremes, infinities, NaNs) as value and
    /// direction, and a million random bit patterns each with a random direction (any bits,
    /// zeros and NaNs included). A wrong lane mask (`finite` from `<=`, stepping infinities) fails
    /// on the infinities.
    #[test]
    fn simd_step_is_the_scalar_step_bit_for_bit() {
        let specials: Vec<f32> = SPECIAL_FLOATS.into_iter().chain([f32::NAN, -f32::NAN]).collect();
        let same = |v: Vec3, dir: Vec3| {
            let got = step_by_sign3(v, dir);
            let want = [step_by_sign(v.x, dir.x), step_by_sign(v.y, dir.y), step_by_sign(v.z, dir.z)];
            for (g, w) in got.to_array().into_iter().zip(want) {
                // NaN values: both NaN (payloads may differ), as in `step_by_sign_matches_next_float`.
                assert!(g.to_bits() == w.to_bits() || (g.is_nan() && w.is_nan()), "v {v:?} dir {dir:?}");
            }
        };
        for &a in &specials {
            for &b in &specials {
                same(Vec3::new(a, b, a), Vec3::new(b, a, -b));
            }
        }
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            f32::from_bits((state >> 32) as u32)
        };
        for _ in 0..1_000_000 {
            let v = Vec3::new(next(), next(), next());
            let pick = |x: f32| match x.to_bits() & 7 {
                0 => 0.0,
                1 => -0.0,
                _ => x,
            };
            let dir = Vec3::new(pick(next()), pick(next()), pick(next()));
            same(v, dir);
        }
    }

    #[test]
    fn offset_leaves_the_surface_on_the_side_of_w() {
        let p = Vec3::new(1e5, 2.0, 3.0);
        let err = Vec3::splat(1e5 * 1e-6);
        let n = Vec3::Y;
        let up = offset_ray_origin(p, err, n, Vec3::Y);
        let down = offset_ray_origin(p, err, n, -Vec3::Y);
        assert!(up.y > p.y && down.y < p.y);
    }
}
