//! The two geometric tests the BVH is made of: the watertight ray–triangle test of Woop, Benthin
//! and Wald 2013 ("Watertight Ray/Triangle Intersection", JCGT 2(1)) and a conservative slab test
//! against axis-aligned boxes that cannot be fooled by `0 * inf = NaN`.

use glam::{Vec3, Vec4};

use crate::geometry::{gamma, Ray};

/// Everything a traversal precomputes once per ray.
#[derive(Clone, Copy, Debug)]
pub struct RayPre {
    pub o: Vec3,
    /// Component-wise `1 / d`; a zero component gives a signed infinity (wanted: see [`slab4_rows`]).
    pub inv_d: Vec3,
    /// Whether each component of `d` is negative (sign bit, so `-0.0` counts as negative, which
    /// matches the sign of the infinity in `inv_d`).
    pub neg: [bool; 3],
    /// The dominant axis of `d`; the watertight test permutes axes so that it becomes z, with
    /// `kx = kz + 1`, `ky = kz + 2` (mod 3). The paper also swaps kx and ky when `d[kz] < 0` to
    /// preserve the winding for back-face culling; this test is two-sided, and the swap would only
    /// flip the signs of U, V, W and T together, so it is left out.
    pub kz: usize,
    /// The direction as given, for the double-precision distance of [`plane_distance_f64`].
    d: Vec3,
    /// Shear constants (Sx, Sy, Sz) = (dx/dz, dy/dz, 1/dz) in the permuted frame.
    s: [f32; 3],
}

/// `1 + 2γ(3)`: pbrt-v4's factor (Sec. 6.8.2) that makes the far slab distance an upper bound of
/// the exact value despite the rounding of `(b - o)` and of the product with `1/d`.
#[inline]
pub(super) fn far_scale() -> f32 {
    1.0 + 2.0 * gamma(3)
}

impl RayPre {
    /// Precomputes the ray's constants; `None` when the direction is zero or not finite, or the
    /// origin not finite (such a ray hits nothing).
    #[inline]
    pub fn new(ray: &Ray) -> Option<RayPre> {
        let d = ray.d;
        if !d.is_finite() || !ray.o.is_finite() || d == Vec3::ZERO {
            return None;
        }
        let a = d.abs();
        let kz = if a.x > a.y {
            if a.x > a.z {
                0
            } else {
                2
            }
        } else if a.y > a.z {
            1
        } else {
            2
        };
        let kx = if kz == 2 { 0 } else { kz + 1 };
        let ky = if kx == 2 { 0 } else { kx + 1 };
        let da = d.to_array();
        let dz = da[kz];
        let s = [da[kx] / dz, da[ky] / dz, 1.0 / dz];
        Some(RayPre {
            o: ray.o,
            inv_d: Vec3::ONE / d,
            neg: [d.x.is_sign_negative(), d.y.is_sign_negative(), d.z.is_sign_negative()],
            kz,
            d,
            s,
        })
    }

    /// The vertex `p` relative to the ray origin, permuted so that the ray runs along +z and
    /// sheared so that it becomes the z axis (Eq. 2–3 of the paper), except that the z coordinate
    /// is only permuted; it is scaled by Sz later, only for triangles that pass the edge tests.
    /// The permutation is a const parameter: traversal is instantiated once per dominant axis so
    /// that the permutation costs nothing per triangle.
    #[inline(always)]
    fn transform<const KZ: usize>(&self, p: Vec3) -> (f32, f32, f32) {
        let a = p - self.o;
        let z = a[KZ];
        (a[(KZ + 1) % 3] - self.s[0] * z, a[(KZ + 2) % 3] - self.s[1] * z, z)
    }
}

/// `a·d − b·c` of the edge function, in single precision with a double-precision fallback when the
/// result is exactly zero: products of two f32 are exact in f64, so the fallback's sign is that of
/// the exact value (Sec. 4 of the paper). A nonzero f64 result too small for f32 keeps its sign as
/// the smallest normal f32.
#[inline(always)]
fn edge_exact(a: f32, d: f32, b: f32, c: f32) -> f32 {
    let e = (a as f64) * (d as f64) - (b as f64) * (c as f64);
    if e == 0.0 {
        0.0
    } else {
        let f = e as f32;
        if f != 0.0 {
            f
        } else if e > 0.0 {
            f32::MIN_POSITIVE
        } else {
            -f32::MIN_POSITIVE
        }
    }
}

/// Watertight intersection of the ray behind `pre` with the triangle `(v0, v1, v2)`, both sides,
/// accepting `t` in `[t_min, t_max]`. Returns `(t, b1, b2)` in Embree's convention: the hit point is
/// `(1 − b1 − b2) v0 + b1 v1 + b2 v2`. Zero-area triangles (in the ray's projection) are never hit.
///
/// Watertight because a shared edge's function is computed from the same transformed vertices in
/// both triangles, with swapped roles that flip the sign exactly, and exact zeros are resolved in
/// double precision; points on an edge or vertex (all three functions ≥ 0 or all ≤ 0) count as hits.
#[inline]
pub fn intersect_triangle(
    pre: &RayPre,
    v0: Vec3,
    v1: Vec3,
    v2: Vec3,
    t_min: f32,
    t_max: f32,
) -> Option<(f32, f32, f32)> {
    match pre.kz {
        0 => intersect_triangle_k::<0>(pre, v0, v1, v2, t_min, t_max),
        1 => intersect_triangle_k::<1>(pre, v0, v1, v2, t_min, t_max),
        _ => intersect_triangle_k::<2>(pre, v0, v1, v2, t_min, t_max),
    }
}

/// [`intersect_triangle`] for rays whose dominant axis is `KZ` (`pre.kz == KZ`).
#[inline(always)]
pub fn intersect_triangle_k<const KZ: usize>(
    pre: &RayPre,
    v0: Vec3,
    v1: Vec3,
    v2: Vec3,
    t_min: f32,
    t_max: f32,
) -> Option<(f32, f32, f32)> {
    debug_assert_eq!(pre.kz, KZ);
    let (ax, ay, az) = pre.transform::<KZ>(v0);
    let (bx, by, bz) = pre.transform::<KZ>(v1);
    let (cx, cy, cz) = pre.transform::<KZ>(v2);

    // Scaled barycentric coordinates (Eq. 4): U weights v0, V weights v1, W weights v2.
    let mut u = cx * by - cy * bx;
    let mut v = ax * cy - ay * cx;
    let mut w = bx * ay - by * ax;
    if u == 0.0 || v == 0.0 || w == 0.0 {
        u = edge_exact(cx, by, cy, bx);
        v = edge_exact(ax, cy, ay, cx);
        w = edge_exact(bx, ay, by, ax);
    }
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }
    // Scaled hit distance (Eq. 5), then one division.
    let sz = pre.s[2];
    let t_scaled = u * (sz * az) + v * (sz * bz) + w * (sz * cz);
    let inv_det = 1.0 / det;
    let t = t_scaled * inv_det;
    // Written so that a NaN t (possible only through overflow) is rejected.
    if !(t >= t_min && t <= t_max) {
        return None;
    }
    // A hit whose t is not provably positive in f32 is decided in double precision. Without this, a
    // ray spawned from a surface can re-hit that surface at t ≈ 1e-6 (seen as false shadow-ray
    // occlusion on the Cornell box's walls, where Embree reported none): its origin is offset to the
    // front of the surface past the hit point's error bound, so the exact t is ≤ 0, but f32 rounding
    // made it positive. δt bounds the rounding error of t from the magnitudes of the transformed
    // vertices and edge functions (pbrt-v4 Sec. 6.8.4, "Conservative ray–triangle t"). It is loose for
    // large triangles seen at grazing angles: on the Cornell box's 556 × 549 wall it was 0.20 for a
    // real hit at t = 0.18, and rejecting every t ≤ δt let that ray through the wall. pbrt can afford
    // the rejection because its offsets keep real hits beyond δt; here the sign of t is the question,
    // and f64 answers it: products and sums of f32 values carry ~1e-16 relative error, so the sign is
    // right unless the origin lies within ~1e-13 of the triangle's plane.
    let max_zt = az.abs().max(bz.abs()).max(cz.abs()) * sz.abs();
    let max_xt = ax.abs().max(bx.abs()).max(cx.abs());
    let max_yt = ay.abs().max(by.abs()).max(cy.abs());
    let delta_z = gamma(3) * max_zt;
    let delta_x = gamma(5) * (max_xt + max_zt);
    let delta_y = gamma(5) * (max_yt + max_zt);
    let delta_e = 2.0 * (gamma(2) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = u.abs().max(v.abs()).max(w.abs());
    let delta_t = 3.0 * (gamma(3) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * inv_det.abs();
    if t <= delta_t {
        let exact = plane_distance_f64(pre.o, pre.d, v0, v1, v2);
        if !(exact > 0.0 && exact >= t_min as f64 && exact <= t_max as f64) {
            return None;
        }
        return Some((exact as f32, v * inv_det, w * inv_det));
    }
    Some((t, v * inv_det, w * inv_det))
}

/// Four triangles' vertices in SIMD rows, for [`intersect4_k`]: row `3 * i + axis` holds coordinate
/// `axis` of vertex `i` of the four triangles (lanes). 144 bytes, the same 36 per triangle as
/// three `Vec3`s; lanes a leaf does not fill are NaN and masked off by the caller.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(16))]
pub struct Tri4 {
    pub v: [[f32; 4]; 9],
}

impl Tri4 {
    pub const EMPTY: Tri4 = Tri4 { v: [[f32::NAN; 4]; 9] };

    pub fn set(&mut self, lane: usize, tri: [Vec3; 3]) {
        for (i, p) in tri.iter().enumerate() {
            for axis in 0..3 {
                self.v[3 * i + axis][lane] = p[axis];
            }
        }
    }

    pub fn get(&self, lane: usize) -> [Vec3; 3] {
        let r = &self.v;
        std::array::from_fn(|i| Vec3::new(r[3 * i][lane], r[3 * i + 1][lane], r[3 * i + 2][lane]))
    }
}

/// What [`intersect4_k`] (`N = 4`) or [`intersect8_k_avx`] (`N = 8`) found: the lanes hit within
/// the interval and, per lane, `t`, `b1`, `b2` (meaningful in the hit lanes only).
#[derive(Clone, Copy, Debug)]
pub struct Hits<const N: usize> {
    pub mask: u32,
    pub t: [f32; N],
    pub b1: [f32; N],
    pub b2: [f32; N],
}

pub type Hits4 = Hits<4>;

impl<const N: usize> Hits<N> {
    const NONE: Hits<N> = Hits { mask: 0, t: [0.0; N], b1: [0.0; N], b2: [0.0; N] };

    /// The nearest hit lane, the last of equals: the lane a sequential loop that accepts
    /// `t <= t_max` and lowers `t_max` to each hit would end with.
    #[inline(always)]
    pub fn nearest(&self) -> Option<usize> {
        let mut mask = self.mask;
        let mut best: Option<usize> = None;
        while mask != 0 {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            if best.is_none_or(|b| self.t[lane] <= self.t[b]) {
                best = Some(lane);
            }
        }
        best
    }
}

/// [`intersect_triangle_k`] on the four triangles of `tri` at once (the lanes set in `valid`), each
/// against the same `[t_min, t_max]`. Every lane's answer is bit for bit the scalar test's: the
/// SIMD path does the scalar test's f32 operations in the same order (Rust contracts nothing into
/// FMA), and a packet with a lane that needs the scalar test's special cases (an edge function
/// exactly zero, or an accepted `t` within its rounding bound δt, or non-finite bounds) is handed
/// to the scalar test lane by lane.
#[inline(always)]
pub fn intersect4_k<const KZ: usize>(pre: &RayPre, tri: &Tri4, valid: u32, t_min: f32, t_max: f32) -> Hits4 {
    debug_assert_eq!(pre.kz, KZ);
    let kx = (KZ + 1) % 3;
    let ky = (KZ + 2) % 3;
    let row = |i: usize| Vec4::from_array(tri.v[i]);
    let (ox, oy, oz) = (Vec4::splat(pre.o[kx]), Vec4::splat(pre.o[ky]), Vec4::splat(pre.o[KZ]));
    let (s0, s1, sz) = (Vec4::splat(pre.s[0]), Vec4::splat(pre.s[1]), Vec4::splat(pre.s[2]));
    // `RayPre::transform`, four lanes at once.
    let vertex = |i: usize| {
        let z = row(3 * i + KZ) - oz;
        ((row(3 * i + kx) - ox) - s0 * z, (row(3 * i + ky) - oy) - s1 * z, z)
    };
    let (ax, ay, az) = vertex(0);
    let (bx, by, bz) = vertex(1);
    let (cx, cy, cz) = vertex(2);
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    let zero = Vec4::ZERO;
    let scalar = |lanes: u32| {
        let mut h = Hits4 { mask: 0, t: [0.0; 4], b1: [0.0; 4], b2: [0.0; 4] };
        for lane in 0..4 {
            if lanes & (1 << lane) != 0 {
                let [a, b, c] = tri.get(lane);
                if let Some((t, b1, b2)) = intersect_triangle_k::<KZ>(pre, a, b, c, t_min, t_max) {
                    h.mask |= 1 << lane;
                    (h.t[lane], h.b1[lane], h.b2[lane]) = (t, b1, b2);
                }
            }
        }
        h
    };
    if (u.cmpeq(zero) | v.cmpeq(zero) | w.cmpeq(zero)).bitmask() & valid != 0 {
        return scalar(valid);
    }
    let outside = (u.cmplt(zero) | v.cmplt(zero) | w.cmplt(zero)) & (u.cmpgt(zero) | v.cmpgt(zero) | w.cmpgt(zero));
    let det = u + v + w;
    let t_scaled = u * (sz * az) + v * (sz * bz) + w * (sz * cz);
    let inv_det = Vec4::ONE / det;
    let t = t_scaled * inv_det;
    let inside = t.cmpge(Vec4::splat(t_min)) & t.cmple(Vec4::splat(t_max)) & det.cmpne(zero);
    let mask = inside.bitmask() & !outside.bitmask() & valid;
    if mask == 0 {
        return Hits4 { mask: 0, t: [0.0; 4], b1: [0.0; 4], b2: [0.0; 4] };
    }
    // δt as in the scalar test (see there); lanes with t ≤ δt (or a NaN δt) go to the scalar test.
    let max_zt = az.abs().max(bz.abs()).max(cz.abs()) * sz.abs();
    let max_xt = ax.abs().max(bx.abs()).max(cx.abs());
    let max_yt = ay.abs().max(by.abs()).max(cy.abs());
    let (g2, g3, g5) = (Vec4::splat(gamma(2)), Vec4::splat(gamma(3)), Vec4::splat(gamma(5)));
    let delta_z = g3 * max_zt;
    let delta_x = g5 * (max_xt + max_zt);
    let delta_y = g5 * (max_yt + max_zt);
    let delta_e = Vec4::splat(2.0) * (g2 * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = u.abs().max(v.abs()).max(w.abs());
    let delta_t = Vec4::splat(3.0) * (g3 * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * inv_det.abs();
    if t.cmpgt(delta_t).bitmask() & mask != mask {
        return scalar(valid);
    }
    Hits4 { mask, t: t.to_array(), b1: (v * inv_det).to_array(), b2: (w * inv_det).to_array() }
}

/// [`intersect4_k`] on two packets at once in AVX (lanes 0–3 from `lo`, 4–7 from `hi`): the same
/// f32 operations in the same order on eight lanes (`vmaxps` and the `_OQ` comparisons are the
/// SSE ones lane by lane; `cmpne` is unordered as SSE's `cmpneqps`), so every lane's answer is
/// [`intersect4_k`]'s, hence the scalar test's, bit for bit. Against one `t_max` for both packets,
/// where the two-packet loop lowered it after the first: the nearest lane (last of equals) is the
/// same either way.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
pub fn intersect8_k_avx<const KZ: usize>(
    pre: &RayPre,
    lo: &Tri4,
    hi: &Tri4,
    valid: u32,
    t_min: f32,
    t_max: f32,
) -> Hits<8> {
    use std::arch::x86_64::*;
    debug_assert_eq!(pre.kz, KZ);
    let kx = (KZ + 1) % 3;
    let ky = (KZ + 2) % 3;
    // SAFETY: each row of a `Tri4` is four contiguous f32, what each 128-bit half loads.
    let row = |i: usize| unsafe { _mm256_loadu2_m128(hi.v[i].as_ptr(), lo.v[i].as_ptr()) };
    let splat = |x: f32| _mm256_set1_ps(x);
    let (sub, mul, add) = (
        |a: __m256, b: __m256| _mm256_sub_ps(a, b),
        |a: __m256, b: __m256| _mm256_mul_ps(a, b),
        |a: __m256, b: __m256| _mm256_add_ps(a, b),
    );
    let max = |a: __m256, b: __m256| _mm256_max_ps(a, b);
    let abs = |a: __m256| _mm256_andnot_ps(splat(-0.0), a);
    let bits = |a: __m256| _mm256_movemask_ps(a) as u32;
    let (ox, oy, oz) = (splat(pre.o[kx]), splat(pre.o[ky]), splat(pre.o[KZ]));
    let (s0, s1, sz) = (splat(pre.s[0]), splat(pre.s[1]), splat(pre.s[2]));
    let vertex = |i: usize| {
        let z = sub(row(3 * i + KZ), oz);
        (sub(sub(row(3 * i + kx), ox), mul(s0, z)), sub(sub(row(3 * i + ky), oy), mul(s1, z)), z)
    };
    let (ax, ay, az) = vertex(0);
    let (bx, by, bz) = vertex(1);
    let (cx, cy, cz) = vertex(2);
    let u = sub(mul(cx, by), mul(cy, bx));
    let v = sub(mul(ax, cy), mul(ay, cx));
    let w = sub(mul(bx, ay), mul(by, ax));
    let zero = _mm256_setzero_ps();
    let (eq, lt, gt) = (
        |a: __m256| _mm256_cmp_ps::<_CMP_EQ_OQ>(a, zero),
        |a: __m256| _mm256_cmp_ps::<_CMP_LT_OQ>(a, zero),
        |a: __m256| _mm256_cmp_ps::<_CMP_GT_OQ>(a, zero),
    );
    let scalar = |lanes: u32| {
        let mut h = Hits::<8>::NONE;
        for lane in 0..8 {
            if lanes & (1 << lane) != 0 {
                let [a, b, c] = if lane < 4 { lo.get(lane) } else { hi.get(lane - 4) };
                if let Some((t, b1, b2)) = intersect_triangle_k::<KZ>(pre, a, b, c, t_min, t_max) {
                    h.mask |= 1 << lane;
                    (h.t[lane], h.b1[lane], h.b2[lane]) = (t, b1, b2);
                }
            }
        }
        h
    };
    if bits(_mm256_or_ps(_mm256_or_ps(eq(u), eq(v)), eq(w))) & valid != 0 {
        return scalar(valid);
    }
    let outside =
        bits(_mm256_or_ps(_mm256_or_ps(lt(u), lt(v)), lt(w))) & bits(_mm256_or_ps(_mm256_or_ps(gt(u), gt(v)), gt(w)));
    let det = add(add(u, v), w);
    let t_scaled = add(add(mul(u, mul(sz, az)), mul(v, mul(sz, bz))), mul(w, mul(sz, cz)));
    let inv_det = _mm256_div_ps(splat(1.0), det);
    let t = mul(t_scaled, inv_det);
    let inside = bits(_mm256_cmp_ps::<_CMP_GE_OQ>(t, splat(t_min)))
        & bits(_mm256_cmp_ps::<_CMP_LE_OQ>(t, splat(t_max)))
        & bits(_mm256_cmp_ps::<_CMP_NEQ_UQ>(det, zero));
    let mask = inside & !outside & valid;
    if mask == 0 {
        return Hits::<8>::NONE;
    }
    let max_zt = mul(max(max(abs(az), abs(bz)), abs(cz)), abs(sz));
    let max_xt = max(max(abs(ax), abs(bx)), abs(cx));
    let max_yt = max(max(abs(ay), abs(by)), abs(cy));
    let (g2, g3, g5) = (splat(gamma(2)), splat(gamma(3)), splat(gamma(5)));
    let delta_z = mul(g3, max_zt);
    let delta_x = mul(g5, add(max_xt, max_zt));
    let delta_y = mul(g5, add(max_yt, max_zt));
    let delta_e = mul(splat(2.0), add(add(mul(mul(g2, max_xt), max_yt), mul(delta_y, max_xt)), mul(delta_x, max_yt)));
    let max_e = max(max(abs(u), abs(v)), abs(w));
    let delta_t = mul(
        mul(splat(3.0), add(add(mul(mul(g3, max_e), max_zt), mul(delta_e, max_zt)), mul(delta_z, max_e))),
        abs(inv_det),
    );
    if bits(_mm256_cmp_ps::<_CMP_GT_OQ>(t, delta_t)) & mask != mask {
        return scalar(valid);
    }
    let mut h = Hits::<8> { mask, ..Hits::<8>::NONE };
    // SAFETY: each destination is eight f32, what the unaligned 256-bit store writes.
    unsafe {
        _mm256_storeu_ps(h.t.as_mut_ptr(), t);
        _mm256_storeu_ps(h.b1.as_mut_ptr(), mul(v, inv_det));
        _mm256_storeu_ps(h.b2.as_mut_ptr(), mul(w, inv_det));
    }
    h
}

/// The ray parameter t at which `o + t·d` meets the plane of `(v0, v1, v2)`, in double precision:
/// t = n·(v0 − o) / n·d with n = (v1 − v0) × (v2 − v0). Differences of f32 values are exact in f64,
/// so only the products round. NaN when the ray is parallel to the plane.
#[inline(never)]
fn plane_distance_f64(o: Vec3, d: Vec3, v0: Vec3, v1: Vec3, v2: Vec3) -> f64 {
    let f = |v: Vec3| [v.x as f64, v.y as f64, v.z as f64];
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let (o, d, v0, v1, v2) = (f(o), f(d), f(v0), f(v1), f(v2));
    let (e1, e2) = (sub(v1, v0), sub(v2, v0));
    let n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
    let denom = dot(n, d);
    if denom == 0.0 {
        return f64::NAN;
    }
    dot(n, sub(v0, o)) / denom
}

/// Slab test of four boxes against the ray segment `[t_min, t_max]`: `row(i)` holds min x, min y,
/// min z, max x, max y, max z of the four boxes (i = 0..6, a node's layout). Returns the mask of
/// the boxes that overlap the segment and each box's entry distance. Conservative: the far distance of each
/// slab is scaled by `1 + 2γ(3)` (pbrt-v4 Sec. 6.8.2) so rounding never rejects a box the exact ray
/// touches. A zero direction component makes `1/d` infinite; if the origin lies exactly on that
/// slab's plane, `(b − o)·(1/d)` is `0 · inf = NaN`, meaning "the ray runs inside the plane": such a
/// slab is ignored (it does not restrict t), which is exact for the far plane and conservative for
/// the near one; `select` on an ordered comparison (false for NaN) keeps the running bound.
#[inline(always)]
fn slab4_rows(pre: &RayPre, row: impl Fn(usize) -> Vec4, t_min: f32, t_max: f32) -> (u32, Vec4) {
    let mut near = Vec4::splat(t_min);
    let mut far = Vec4::splat(t_max);
    let scale = Vec4::splat(far_scale());
    for axis in 0..3 {
        let (lo, hi) = (row(axis), row(axis + 3));
        let (n, f) = if pre.neg[axis] { (hi, lo) } else { (lo, hi) };
        let o = Vec4::splat(pre.o[axis]);
        let inv = Vec4::splat(pre.inv_d[axis]);
        let tn = (n - o) * inv;
        let tf = (f - o) * inv * scale;
        near = Vec4::select(tn.cmpgt(near), tn, near);
        far = Vec4::select(tf.cmplt(far), tf, far);
    }
    (near.cmple(far).bitmask(), near)
}

/// [`slab4_rows`] on the eight boxes of an 8-wide node (`rows[i]` as `row(i)` there, eight lanes),
/// in baseline x86-64 code: each half of the node by the SSE test. [`slab8_ray_avx`] is the same test in one AVX
/// pass, bit for bit.
#[inline(always)]
pub fn slab8(pre: &RayPre, rows: &[[f32; 8]; 6], t_min: f32, t_max: f32) -> (u32, [f32; 8]) {
    let (lo_mask, lo_near) = slab4_rows(pre, |i| Vec4::from_slice(&rows[i][..4]), t_min, t_max);
    let (hi_mask, hi_near) = slab4_rows(pre, |i| Vec4::from_slice(&rows[i][4..]), t_min, t_max);
    let mut near = [0.0; 8];
    near[..4].copy_from_slice(&lo_near.to_array());
    near[4..].copy_from_slice(&hi_near.to_array());
    (lo_mask | hi_mask << 4, near)
}

/// [`slab8`] with AVX: the eight lanes in one 256-bit vector. `max`/`min` are the selects of
/// [`slab4_rows`]: `vmaxps(a, b)` is `a > b ? a : b`, returning `b` when either is NaN, which is
/// `select(a.cmpgt(b), a, b)` exactly (likewise `vminps` and `cmplt`), so every lane's result is
/// [`slab8`]'s bit for bit.
/// (Tests only: traversals call [`slab8_ray_avx`].)
#[cfg(all(test, target_arch = "x86_64"))]
#[target_feature(enable = "avx2,fma")]
#[inline]
pub fn slab8_avx(pre: &RayPre, rows: &[[f32; 8]; 6], t_min: f32, t_max: f32) -> (u32, [f32; 8]) {
    let mut near = [0.0f32; 8];
    let mask = slab8_ray_avx(&SlabRay::new(pre, t_min), rows, &[0; 8], t_max, &mut near);
    (mask, near)
}

/// The per-ray constants of [`slab8_ray_avx`], computed once per traversal rather than at each
/// node: the origin, `1/d` and `t_min` in all eight lanes, and the row of each axis's near and far
/// planes (which depend on the sign of `d` only), so that a node visit neither branches on the
/// signs nor broadcasts anything.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
pub struct SlabRay {
    o: [[f32; 8]; 3],
    inv: [[f32; 8]; 3],
    t_min: [f32; 8],
    near_row: [usize; 3],
    far_row: [usize; 3],
}

impl SlabRay {
    #[inline]
    pub fn new(pre: &RayPre, t_min: f32) -> SlabRay {
        let near_row = [0, 1, 2].map(|axis| if pre.neg[axis] { axis + 3 } else { axis });
        SlabRay {
            o: [0, 1, 2].map(|axis| [pre.o[axis]; 8]),
            inv: [0, 1, 2].map(|axis| [pre.inv_d[axis]; 8]),
            t_min: [t_min; 8],
            near_row,
            far_row: near_row.map(|row| if row < 3 { row + 3 } else { row - 3 }),
        }
    }
}

/// The AVX node test: `slab8_avx` with the ray's constants precomputed (`SlabRay`) and the unused slots of the node
/// (`count[k] == u32::MAX`) masked off: writes the eight entry distances to `near` and returns the
/// mask of the used slots whose box the ray overlaps. The same arithmetic as [`slab4_rows`], in
/// the same order, so the mask and distances are [`slab8`]'s bit for bit.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
pub fn slab8_ray_avx(ray: &SlabRay, rows: &[[f32; 8]; 6], count: &[u32; 8], t_max: f32, near: &mut [f32; 8]) -> u32 {
    use std::arch::x86_64::*;
    // SAFETY (all loads and the store): each pointer is to eight contiguous f32 or u32, what the
    // unaligned 256-bit access reads or writes; `near_row` and `far_row` hold rows below 6
    // (`SlabRay::new`).
    let row = |i: usize| unsafe { _mm256_loadu_ps(rows.as_ptr().add(i).cast()) };
    let splat = |v: &[f32; 8]| unsafe { _mm256_load_ps(v.as_ptr()) };
    let mut n8 = splat(&ray.t_min);
    let mut far = _mm256_set1_ps(t_max);
    let scale = _mm256_set1_ps(far_scale());
    for axis in 0..3 {
        let (n, f) = (row(ray.near_row[axis]), row(ray.far_row[axis]));
        let (o, inv) = (splat(&ray.o[axis]), splat(&ray.inv[axis]));
        let tn = _mm256_mul_ps(_mm256_sub_ps(n, o), inv);
        let tf = _mm256_mul_ps(_mm256_mul_ps(_mm256_sub_ps(f, o), inv), scale);
        n8 = _mm256_max_ps(tn, n8);
        far = _mm256_min_ps(tf, far);
    }
    let unused = unsafe { _mm256_cmpeq_epi32(_mm256_loadu_si256(count.as_ptr().cast()), _mm256_set1_epi32(-1)) };
    let hit = _mm256_andnot_ps(_mm256_castsi256_ps(unused), _mm256_cmp_ps::<_CMP_LE_OQ>(n8, far));
    unsafe { _mm256_storeu_ps(near.as_mut_ptr(), n8) };
    _mm256_movemask_ps(hit) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scalar view of [`slab8`]: one box in all eight slots (which must agree), and the same
    /// answer and entry distances from [`slab8_avx`] where the CPU has AVX2.
    fn slab(pre: &RayPre, min: Vec3, max: Vec3, t_min: f32, t_max: f32) -> bool {
        let rows = [min.x, min.y, min.z, max.x, max.y, max.z].map(|v| [v; 8]);
        let (mask, near) = slab8(pre, &rows, t_min, t_max);
        assert!(mask == 0 || mask == 0xff, "the eight slots disagree: {mask:b}");
        #[cfg(target_arch = "x86_64")]
        if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
            // SAFETY: the CPU has the features `slab8_avx` is compiled for.
            let (avx_mask, avx_near) = unsafe { slab8_avx(pre, &rows, t_min, t_max) };
            assert_eq!(avx_mask, mask);
            assert_eq!(avx_near.map(f32::to_bits), near.map(f32::to_bits));
        }
        mask != 0
    }

    /// The AVX node test leaves out the slots marked unused (`count == u32::MAX`) even where their
    /// box is overlapped, and reports the other slots as `slab8` does.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn node_test_masks_unused_slots() {
        if !(is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma")) {
            return;
        }
        let ray = Ray::new(Vec3::new(0.1, 0.2, -3.0), Vec3::new(0.05, -0.02, 1.0));
        let pre = RayPre::new(&ray).unwrap();
        // Slot k's box is overlapped for even k only; slots 2 and 5 are unused.
        let mut rows = [[0.0f32; 8]; 6];
        for k in 0..8 {
            let c = if k % 2 == 0 { Vec3::ZERO } else { Vec3::new(5.0, 5.0, 0.0) } + Vec3::splat(0.01 * k as f32);
            for (axis, row) in rows.iter_mut().enumerate() {
                row[k] = if axis < 3 { c[axis] - 0.5 } else { c[axis - 3] + 0.5 };
            }
        }
        let mut count = [0u32; 8];
        (count[2], count[5]) = (u32::MAX, u32::MAX);
        let (mask, near) = slab8(&pre, &rows, 0.0, f32::INFINITY);
        assert_eq!(mask, 0b0101_0101);
        let mut avx_near = [0.0f32; 8];
        // SAFETY: the CPU has AVX2 and FMA (checked above).
        let avx_mask = unsafe { slab8_ray_avx(&SlabRay::new(&pre, 0.0), &rows, &count, f32::INFINITY, &mut avx_near) };
        assert_eq!(avx_mask, 0b0101_0001);
        assert_eq!(avx_near.map(f32::to_bits), near.map(f32::to_bits));
    }

    fn hit(ray: &Ray, v: [Vec3; 3]) -> Option<(f32, f32, f32)> {
        intersect_triangle(&RayPre::new(ray)?, v[0], v[1], v[2], ray.t_min, ray.t_max)
    }

    #[test]
    fn barycentrics_follow_embree_convention_on_both_sides() {
        let tri = [Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0)];
        for (oz, dz) in [(2.0, -1.0), (-2.0, 1.0)] {
            let ray = Ray::new(Vec3::new(0.25, -0.5, oz), Vec3::new(0.0, 0.0, dz));
            let (t, b1, b2) = hit(&ray, tri).expect("the ray points at the triangle");
            assert!((t - 2.0).abs() < 1e-6);
            assert!((b1 - 0.375).abs() < 1e-6 && (b2 - 0.25).abs() < 1e-6, "{b1} {b2}");
            let p = (1.0 - b1 - b2) * tri[0] + b1 * tri[1] + b2 * tri[2];
            assert!((p - ray.at(t)).length() < 1e-6);
        }
        // An oblique ray along every dominant axis and sign.
        for axis in 0..3 {
            for sign in [-1.0f32, 1.0] {
                let rot = |p: Vec3| match axis {
                    0 => Vec3::new(p.z, p.x, p.y),
                    1 => Vec3::new(p.y, p.z, p.x),
                    _ => p,
                };
                let tri_r = tri.map(rot);
                let target = rot(Vec3::new(0.5, 0.0, 0.0));
                let o = rot(Vec3::new(0.2, 0.3, -3.0 * sign));
                let ray = Ray::new(o, (target - o).normalize());
                let (t, b1, b2) = hit(&ray, tri_r).expect("hit");
                let p = (1.0 - b1 - b2) * tri_r[0] + b1 * tri_r[1] + b2 * tri_r[2];
                assert!((p - target).length() < 1e-5 && (ray.at(t) - target).length() < 1e-5);
            }
        }
    }

    #[test]
    fn interval_and_degenerate_cases() {
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let o = Vec3::new(0.2, 0.2, 1.0);
        assert!(hit(&Ray::segment(o, -Vec3::Z, 0.999), tri).is_none());
        assert!(hit(&Ray::segment(o, -Vec3::Z, 1.0), tri).is_some(), "t_max is inclusive");
        assert!(hit(&Ray { o, d: -Vec3::Z, t_min: 1.0, t_max: f32::INFINITY }, tri).is_some());
        assert!(hit(&Ray { o, d: -Vec3::Z, t_min: 1.001, t_max: f32::INFINITY }, tri).is_none());
        assert!(hit(&Ray::new(o, Vec3::Z), tri).is_none(), "behind the origin");
        // Zero-area triangles: collinear and coincident vertices.
        assert!(hit(&Ray::new(o, -Vec3::Z), [Vec3::ZERO, Vec3::X, Vec3::X * 2.0]).is_none());
        assert!(hit(&Ray::new(Vec3::new(0.0, 0.0, 1.0), -Vec3::Z), [Vec3::ZERO; 3]).is_none());
        // A ray in the triangle's plane.
        assert!(hit(&Ray::new(Vec3::new(-1.0, 0.2, 0.0), Vec3::X), tri).is_none());
        // Invalid rays.
        assert!(RayPre::new(&Ray::new(o, Vec3::ZERO)).is_none());
        assert!(RayPre::new(&Ray::new(o, Vec3::new(f32::NAN, 0.0, 1.0))).is_none());
    }

    #[test]
    fn edges_and_vertices_count_as_hits() {
        let tri = [Vec3::ZERO, Vec3::new(4.0, 0.0, 0.0), Vec3::new(0.0, 4.0, 0.0)];
        for p in [Vec3::ZERO, Vec3::new(4.0, 0.0, 0.0), Vec3::new(2.0, 0.0, 0.0), Vec3::new(2.0, 2.0, 0.0)] {
            let ray = Ray::new(p + Vec3::Z, -Vec3::Z);
            assert!(hit(&ray, tri).is_some(), "{p}");
        }
    }

    /// A real hit inside f32's error bound δt is kept, a re-hit of the surface a ray was spawned from
    /// is not. The first ray is the one `tests/images/pt.rs`'s Embree/BVH comparison caught on the Cornell
    /// box: a grazing hit on the 556 × 549 red wall at t = 0.1766, where δt = 0.20. Rejecting every
    /// t ≤ δt (the code before) missed it and the path escaped through the wall.
    #[test]
    fn hits_within_the_rounding_bound_are_decided_in_double_precision() {
        let wall = [Vec3::new(556.0, 0.0, 0.0), Vec3::new(556.0, 0.0, 559.2), Vec3::new(556.0, 548.8, 559.2)];
        let wall2 = [wall[0], wall[2], Vec3::new(556.0, 548.8, 0.0)];
        let o = Vec3::new(5.5599854e2, 5.487997e2, 2.9819452e2);
        let d = Vec3::new(8.289657e-3, -7.8739053e-1, 6.1639875e-1);
        let ray = Ray::new(o, d);
        let found = hit(&ray, wall).or_else(|| hit(&ray, wall2));
        let (t, _, _) = found.expect("the grazing ray hits the wall");
        let expected = (556.0 - o.x as f64) / d.x as f64;
        assert!((t as f64 - expected).abs() < 1e-3 * expected, "t = {t}, expected {expected}");
        // A ray leaving a surface, its origin offset to the front by the spawn rule, does not hit it.
        let tri = [Vec3::new(-300.0, -300.0, 0.0), Vec3::new(300.0, -300.0, 0.0), Vec3::new(0.0, 300.0, 0.0)];
        for (i, dz) in [1e-4f32, 1e-2, 0.3, 1.0].into_iter().enumerate() {
            let p = Vec3::new(12.345 + i as f32, -7.25, 0.0);
            let leaving =
                crate::geometry::spawn_ray(p, Vec3::splat(1e-5), Vec3::Z, Vec3::new(0.7, 0.1, dz).normalize());
            assert!(hit(&leaving, tri).is_none(), "self-hit for dz = {dz}");
        }
    }

    #[test]
    fn slab_handles_rays_inside_a_face_plane() {
        let (min, max) = (Vec3::ZERO, Vec3::ONE);
        let test = |o: Vec3, d: Vec3| slab(&RayPre::new(&Ray::new(o, d)).unwrap(), min, max, 0.0, f32::INFINITY);
        // Origin exactly on the x = 0 face plane, moving inside that plane: 0 * inf = NaN.
        assert!(test(Vec3::new(0.0, -1.0, 0.5), Vec3::Y));
        assert!(test(Vec3::new(1.0, -1.0, 0.5), Vec3::Y));
        assert!(test(Vec3::new(1.0, 2.0, 1.0), -Vec3::Y));
        // A negative zero direction component must behave the same.
        assert!(test(Vec3::new(0.0, -1.0, 0.5), Vec3::new(-0.0, 1.0, 0.0)));
        // Parallel to a slab but outside it.
        assert!(!test(Vec3::new(-0.1, -1.0, 0.5), Vec3::Y));
        assert!(!test(Vec3::new(1.1, -1.0, 0.5), Vec3::new(-0.0, 1.0, 0.0)));
        // A flat box (zero extent in z) seen edge-on and face-on.
        let flat = |o: Vec3, d: Vec3| {
            slab(&RayPre::new(&Ray::new(o, d)).unwrap(), Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), 0.0, f32::INFINITY)
        };
        assert!(flat(Vec3::new(-1.0, 0.5, 0.0), Vec3::X));
        assert!(flat(Vec3::new(0.5, 0.5, 1.0), -Vec3::Z));
        assert!(!flat(Vec3::new(0.5, 0.5, 1.0), Vec3::Z));
        // Segment bounds.
        let pre = RayPre::new(&Ray::new(Vec3::new(0.5, 0.5, 3.0), -Vec3::Z)).unwrap();
        assert!(!slab(&pre, min, max, 0.0, 1.9));
        assert!(slab(&pre, min, max, 0.0, 2.0));
        assert!(!slab(&pre, min, max, 3.5, f32::INFINITY));
    }

    /// `intersect8_k_avx` against `intersect4_k` on each of its two packets, bit for bit, on random
    /// packets (with triangles sharing edges and vertices, so that exact zeros take the scalar path)
    /// and rays from near and far, with partial lane masks.
    #[test]
    fn eight_lane_avx_test_matches_the_four_lane_one() {
        #[cfg(target_arch = "x86_64")]
        if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
            let mut rng = crate::sampling::Rng::new(9, 0);
            let mut p = |s: f32| Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 2.0 * s - Vec3::splat(s);
            let (mut hits, mut cases) = (0, 0);
            for n in 0..20000 {
                let mut packets = [Tri4::EMPTY; 2];
                let shared = [p(1.0), p(1.0)];
                for lane in 0..8 {
                    let tri = if lane % 3 == 0 { [shared[0], shared[1], p(1.0)] } else { [p(1.0), p(1.0), p(1.0)] };
                    packets[lane / 4].set(lane % 4, tri);
                }
                let o = p([0.01, 3.0, 100.0][n % 3]);
                let ray = Ray::new(o, p(0.5) - o);
                let Some(pre) = RayPre::new(&ray) else { continue };
                let valid = if n % 2 == 0 { 0xff } else { 0x0f | ((1 << (1 + n % 4)) - 1) << 4 };
                let t_max = [f32::INFINITY, 1.0][n % 2];
                let (eight, four) = match pre.kz {
                    0 => (
                        // SAFETY: the CPU has the features `intersect8_k_avx` is compiled for.
                        unsafe { intersect8_k_avx::<0>(&pre, &packets[0], &packets[1], valid, 0.0, t_max) },
                        packets.map(|t| intersect4_k::<0>(&pre, &t, 0xf, 0.0, t_max)),
                    ),
                    1 => (
                        // SAFETY: as above.
                        unsafe { intersect8_k_avx::<1>(&pre, &packets[0], &packets[1], valid, 0.0, t_max) },
                        packets.map(|t| intersect4_k::<1>(&pre, &t, 0xf, 0.0, t_max)),
                    ),
                    _ => (
                        // SAFETY: as above.
                        unsafe { intersect8_k_avx::<2>(&pre, &packets[0], &packets[1], valid, 0.0, t_max) },
                        packets.map(|t| intersect4_k::<2>(&pre, &t, 0xf, 0.0, t_max)),
                    ),
                };
                let expected = (four[0].mask | four[1].mask << 4) & valid;
                assert_eq!(eight.mask, expected, "case {n}");
                for lane in (0..8).filter(|l| expected & (1 << l) != 0) {
                    let h = &four[lane / 4];
                    let k = lane % 4;
                    assert_eq!(
                        [eight.t[lane], eight.b1[lane], eight.b2[lane]].map(f32::to_bits),
                        [h.t[k], h.b1[k], h.b2[k]].map(f32::to_bits),
                        "case {n}, lane {lane}"
                    );
                }
                hits += expected.count_ones();
                cases += 1;
            }
            assert!(hits > 1000 && cases > 19000, "{hits} hits in {cases} cases");
        }
    }
}
