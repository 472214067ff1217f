//! Tests of sampling as a map: delta lobes hit with their discrete probabilities, every lobe's
//! sampler inverted back to its uniforms (round trips, and inverted uniforms distributed as
//! sampled), and the sampled direction's Jacobian equal to 1/pdf.

use glam::Vec3;

use super::tests::*;
use super::*;
use crate::sampling::chi2::{chi2_1d, chi2_test_bin_masses, jacobian_det_surface, Chi2Config};
use crate::sampling::Rng;

/// Delta lobes as discrete masses. The count k of reflections among n samples is Binomial(n, F);
/// we require |k − nF| ≤ 5 σ with σ = √(n F (1 − F)) (two-sided normal tail 5.7e-7 per check;
/// over the 12 checks here the family-wise false-rejection probability is below 1e-5). Every
/// sample must also land exactly on its lobe's direction with throughput f|cos|/pdf equal to the
/// lobe's weight over its probability.
#[test]
fn delta_lobes_have_their_discrete_probabilities() {
    let n = 200_000usize;
    let mut rng = Rng::new(17, 0);
    let mut cases: Vec<(Vec3, f32)> = ANGLES.iter().map(|&t| (dir(t, 0.7), 1.5)).collect();
    // From inside: below the critical angle (41.8° for 1.5), and beyond it (total internal reflection).
    for &t in &[0.0f32, 30.0, 41.0, 60.0] {
        let w = dir(t, 2.0);
        cases.push((Vec3::new(w.x, w.y, -w.z), 1.5));
    }
    for &t in &[0.0f32, 70.0] {
        cases.push((dir(t, 1.0), 1.0 / 1.33));
    }
    for (wo, ior) in cases {
        let m = Material::Dielectric { ior };
        let fr = fresnel_dielectric(wo.z, ior);
        let f = fr.reflectance as f64;
        let mut reflected = 0usize;
        for _ in 0..n {
            let s = m.sample(wo, rng_u3(&mut rng), MODE).expect("dielectric always samples");
            assert!(s.delta && s.pdf > 0.0);
            let throughput = s.f * s.wi.z.abs() / s.pdf;
            if s.lobe == 0 {
                reflected += 1;
                assert!((s.wi - fresnel::reflect_z(wo)).length() < 1e-6);
                assert!((throughput - Rgb::ONE).abs().max_element() < 1e-5, "{throughput:?}");
                assert_eq!(s.eta, 1.0, "reflection crosses no interface");
            } else {
                assert!(s.wi.z * wo.z < 0.0);
                let expect = 1.0 / (fr.eta_ti * fr.eta_ti);
                assert!((throughput - Rgb::splat(expect)).abs().max_element() < 1e-5 * expect);
                // The record's η is the one whose square the radiance throughput was divided by.
                assert!((s.eta * s.eta * expect - 1.0).abs() < 1e-5, "eta {} vs eta_ti {}", s.eta, fr.eta_ti);
                let si = m.sample(wo, [0.99999, 0.5, 0.5], TransportMode::Importance).unwrap();
                if si.lobe == 1 {
                    assert!((si.f * si.wi.z.abs() / si.pdf - Rgb::ONE).abs().max_element() < 1e-5);
                }
            }
        }
        let sigma = (n as f64 * f * (1.0 - f)).sqrt();
        let dev = (reflected as f64 - n as f64 * f).abs();
        assert!(dev <= 5.0 * sigma + 1e-9, "wo {wo:?}: {reflected} reflections of {n}, expected F = {f}");
    }
    // The mirror: one lobe, probability 1, throughput = reflectance.
    let m = Material::Mirror { reflectance: Rgb::new(0.9, 0.8, 0.7) };
    for &t in &ANGLES {
        let wo = dir(t, 0.7);
        let s = m.sample(wo, rng_u3(&mut rng), MODE).unwrap();
        assert_eq!(s.pdf, 1.0);
        assert!((s.f * s.wi.z / s.pdf - Rgb::new(0.9, 0.8, 0.7)).abs().max_element() < 1e-5);
        assert_eq!(m.pdf(wo, s.wi, MODE), 0.0);
        assert_eq!(m.eval(wo, s.wi, MODE), Rgb::ZERO);
        assert!(m.sample(-wo, rng_u3(&mut rng), MODE).is_none(), "mirror is one-sided");
    }
}

/// Distance between direction uniforms, the second taken modulo 1 (the GGX warp's polar map has a
/// seam at u[2] = 0 ≡ 1; the cosine warp has none, where this changes nothing).
pub(super) fn u_dist(a: [f32; 2], b: [f32; 2]) -> f32 {
    let d1 = (a[1] - b[1]).abs();
    (a[0] - b[0]).abs().max(d1.min(1.0 - d1))
}

/// invert(sample(u)) = u within 1e-4 for the smooth single-lobe materials (their direction maps are
/// injective); u[0] is unused by them and comes back as γ[1] (Eq. 40 with the whole [0, 1)).
/// At 89.9° the GGX lobe is cut by the horizon and strongly anisotropic, so a direction rounded to
/// f32 pins u down less tightly: there the bound is 1e-3 (measured worst below, printed).
/// `invert` may refuse (ill-conditioned, see INVERT_DIRECTION_TOLERANCE) for at most 0.1%.
#[test]
fn smooth_lobes_round_trip() {
    let mut rng = Rng::new(23, 0);
    let mut materials = vec![Material::Diffuse { reflectance: Rgb::splat(0.5) }];
    for &a in &ALPHAS[1..] {
        materials.push(conductor(a));
    }
    for m in &materials {
        for &theta in &ANGLES {
            let wo = dir(theta, 0.7);
            let (mut worst, mut refused, mut total) = (0.0f32, 0, 0);
            for _ in 0..20_000 {
                let u = rng_u3(&mut rng);
                let Some(s) = m.sample(wo, u, MODE) else { continue };
                total += 1;
                let gamma = rng_u4(&mut rng);
                let Some(inv) = m.invert(wo, s.wi, MODE, gamma) else {
                    refused += 1;
                    continue;
                };
                assert_eq!(inv.lobe_choice_prob, 1.0);
                assert!((inv.jacobian - s.pdf).abs() <= 1e-4 * s.pdf, "{} vs {}", inv.jacobian, s.pdf);
                assert!((inv.u[0] - gamma[1]).abs() < 1e-6);
                let d = u_dist([inv.u[1], inv.u[2]], [u[1], u[2]]);
                worst = worst.max(d);
                let bound = if theta < 89.0 { 1e-4 } else { 1e-3 };
                assert!(d < bound, "{m:?} wo {wo:?} u {u:?} -> {:?}", inv.u);
            }
            eprintln!("{m:?} {theta}°: worst |du| {worst:e}, refused {refused} of {total}");
            assert!(refused * 1000 <= total, "{m:?} {theta}°: refused {refused} of {total}");
        }
    }
}

/// Near-mirror lobes (α = 1e-4, 1e-3): a lobe ~α wide while a sampled direction is rounded to f32
/// (~6e-8), so u is recovered only to about 6e-8/α times the warp's condition (the worst |Δu| is
/// printed, not bounded). What must hold is sample(invert(x)) = x: `invert` re-samples and
/// refuses beyond INVERT_DIRECTION_TOLERANCE, and it may refuse at most 0.1% of sampled directions.
#[test]
fn near_mirror_round_trip() {
    let mut rng = Rng::new(29, 0);
    for &alpha in &[1e-4f32, 1e-3] {
        let m = conductor(alpha);
        for &theta in &ANGLES {
            let wo = dir(theta, 0.7);
            let (mut worst_u, mut refused, mut total) = (0.0f32, 0, 0);
            for _ in 0..5_000 {
                let u = rng_u3(&mut rng);
                let Some(s) = m.sample(wo, u, MODE) else { continue };
                total += 1;
                let Some(inv) = m.invert(wo, s.wi, MODE, rng_u4(&mut rng)) else {
                    refused += 1;
                    continue;
                };
                worst_u = worst_u.max(u_dist([inv.u[1], inv.u[2]], [u[1], u[2]]));
                let again = m.sample(wo, inv.u, MODE).expect("accepted inverse re-samples");
                assert!((again.wi - s.wi).length() * conditioning(wo, s.wi) <= INVERT_DIRECTION_TOLERANCE);
            }
            eprintln!("alpha {alpha} {theta}°: worst |du| {worst_u:e}, refused {refused} of {total}");
            assert!(refused * 1000 <= total, "refused {refused} of {total}");
        }
    }
}

/// Mixtures and delta lobes: sample(invert(x)) = x; when the inverse picks the lobe that produced x
/// the direction uniforms match too; and jacobian / lobe_choice_prob is the mixture pdf (Eq. 42/44).
#[test]
fn mixtures_and_deltas_round_trip() {
    let mut rng = Rng::new(31, 0);
    let mut materials: Vec<Material> = ALPHAS.iter().map(|&a| plastic(a)).collect();
    materials.push(Material::Dielectric { ior: 1.5 });
    materials.push(Material::Mirror { reflectance: Rgb::ONE });
    let (mut refused, mut total) = (0usize, 0usize);
    for m in &materials {
        for &theta in &ANGLES {
            for side in [1.0f32, -1.0] {
                let w = dir(theta, 0.7);
                let wo = Vec3::new(w.x, w.y, side * w.z);
                for _ in 0..5_000 {
                    let u = rng_u3(&mut rng);
                    let Some(s) = m.sample(wo, u, MODE) else { continue };
                    let gamma = rng_u4(&mut rng);
                    total += 1;
                    let Some(inv) = m.invert(wo, s.wi, MODE, gamma) else {
                        refused += 1;
                        continue;
                    };
                    let again = m.sample(wo, inv.u, MODE).expect("inverted uniforms sample");
                    let err = (again.wi - s.wi).length();
                    let ok =
                        if s.delta { err == 0.0 } else { err * conditioning(wo, s.wi) <= INVERT_DIRECTION_TOLERANCE };
                    assert!(ok, "{m:?}: {:?} vs {:?}", again.wi, s.wi);
                    assert_eq!(again.lobe, inv.lobe);
                    assert_eq!(inv.delta, s.delta);
                    if s.delta {
                        assert_eq!(inv.lobe, s.lobe, "delta lobes never overlap");
                        assert_eq!(inv.lobe_choice_prob, 1.0);
                        assert!((inv.jacobian - s.pdf).abs() < 1e-6);
                        assert_eq!([inv.u[1], inv.u[2]], [gamma[2], gamma[3]]);
                    } else {
                        let mixture = inv.jacobian / inv.lobe_choice_prob;
                        assert!((mixture - s.pdf).abs() <= 1e-3 * s.pdf, "{mixture} vs {}", s.pdf);
                        if inv.lobe == s.lobe && theta < 89.0 {
                            assert!(u_dist([inv.u[1], inv.u[2]], [u[1], u[2]]) < 1e-3, "{m:?} {u:?} {:?}", inv.u);
                        }
                    }
                }
            }
        }
    }
    eprintln!("mixtures: refused {refused} of {total}");
    assert!(refused * 1000 <= total, "refused {refused} of {total}");
}

/// |S_spec|: the fraction of a rough plastic's coating uniforms (u[1], u[2]) for which `sample`
/// succeeds, counted on the sampler (`reflection_success_probability`; its error ≲ 1e-3 is ≈ 2 of
/// the ~2,500 expected per χ² bin, whose noise is ~50). Measured: 0.912 for α = 0.3 at 45°, 0.839
/// for α = 0.5 at 60°.
fn specular_success_probability(m: &Material, wo: Vec3) -> f64 {
    let Material::RoughPlastic { alpha, .. } = *m else { return 1.0 };
    reflection_success_probability(alpha, wo)
}

/// The inverse's u are distributed as the paper says: if u is uniform, wi = sample(u), and the
/// inverse picks lobe t by T(t) (Eq. 44), u[0] uniformly inside its interval (Eq. 40) and inverts
/// the direction map, then the inverted u are again uniform over the set S of u for which `sample`
/// succeeds (the stationary-distribution argument of RJMLT Sec. 5). For the plastic, S misses the
/// specular uniforms whose reflection falls below the horizon, so relative to all samples the
/// density of u[0] is P_succ(lobe(u[0])) and that of (u[1], u[2]) is α_s 1[spec succeeds] + α_d,
/// the rest being the sampler's failures. For
/// the dielectric every u succeeds and u[0] is uniform. Chi-square tests at this module's Šidák
/// level.
#[test]
fn inverted_uniforms_are_distributed_as_sampled() {
    // The expected density of u[0] is a step at the lobe boundary p_s, which falls inside a bin:
    // a deep minimum subdivision lets the adaptive quadrature locate the step (with the default
    // depth its error estimate can miss it and misstate that bin's expectation).
    let cfg = Chi2Config {
        res: [40, 1],
        samples: 100_000,
        test_count: CHI2_TESTS_MATERIAL,
        min_depth: 10,
        max_depth: 20,
        ..Chi2Config::default()
    };
    let invert_once = |m: &Material, wo: Vec3, rng: &mut Rng| -> Option<[f32; 3]> {
        let s = m.sample(wo, rng_u3(rng), MODE)?;
        Some(m.invert(wo, s.wi, MODE, rng_u4(rng))?.u)
    };
    let dielectric = Material::Dielectric { ior: 1.5 };
    let wo = dir(80.0, 0.7);
    let out = chi2_1d(&cfg, [0.0, 1.0], 40, |rng| invert_once(&dielectric, wo, rng).map(|u| f64::from(u[0])), |_| 1.0);
    assert!(out.passed, "dielectric u[0]: {}", out.message);

    let dark = Material::RoughPlastic { alpha: 0.5, plastic: Plastic::new(Rgb::splat(0.3), Rgb::ONE, 1.5, false) };
    for (i, (m, wo)) in [(plastic(0.3), dir(45.0, 0.7)), (dark, dir(60.0, 0.7))].into_iter().enumerate() {
        let [ps, pd] = m.lobe_probabilities(wo);
        let succ = specular_success_probability(&m, wo);
        assert!(succ > 0.5 && succ <= 1.0 + 1e-6, "{succ}");
        // Densities relative to all samples: the sampler's failures (a specular reflection below
        // the horizon, probability p_s (1 − |S_spec|)) fall into the χ² harness's "failed" cell,
        // whose expectation is 1 − ∫ pdf. (Dividing by |S| here, as before, made the failures
        // unexpected; the harness pooled them into bin 2 and the inverse looked biased.)
        let out = chi2_1d(
            &cfg,
            [0.0, 1.0],
            41 + i as u64,
            |rng| invert_once(&m, wo, rng).map(|u| f64::from(u[0])),
            |x| if x < ps as f64 { succ } else { 1.0 },
        );
        assert!(out.passed, "{m:?} u[0]: {}", out.message);
        if i == 1 {
            // The density is p_d + p_s·1[specular sampling succeeds at (u1, u2)]: an indicator of a
            // set only the sampler decides, so each bin's mass is counted on a 64×64 midpoint grid
            // inside it rather than by quadrature (which must bisect along the whole boundary).
            // The grid's error is confined to cells the boundary crosses: about 1/16 · 1024 of a
            // bin's 4096 cells, each off by at most half its mass, on average far less; ≤ 1% of
            // a bin's ~390 expected counts against a noise of ~20.
            let ggx = Ggx::new(0.5);
            let cfg2 = Chi2Config { res: [16, 16], ..cfg.clone() };
            const SUB: usize = 64;
            let out = chi2_test_bin_masses(
                &cfg2,
                [0.0, 1.0],
                [0.0, 1.0],
                44,
                |rng| invert_once(&m, wo, rng).map(|u| [f64::from(u[1]), f64::from(u[2])]),
                |a, b| {
                    let mut ok = 0usize;
                    for i in 0..SUB {
                        for j in 0..SUB {
                            let u1 = a[0] + (a[1] - a[0]) * (i as f64 + 0.5) / SUB as f64;
                            let u2 = b[0] + (b[1] - b[0]) * (j as f64 + 0.5) / SUB as f64;
                            if ggx.sample_reflection(wo, [u1 as f32, u2 as f32]).is_some_and(|(wi, _)| wi.z > 0.0) {
                                ok += 1;
                            }
                        }
                    }
                    let area = (a[1] - a[0]) * (b[1] - b[0]);
                    area * (ps as f64 * ok as f64 / (SUB * SUB) as f64 + pd as f64)
                },
            );
            assert!(out.passed, "{m:?} (u[1], u[2]): {}", out.message);
        }
    }
}

/// The numerical Jacobian of each smooth lobe's direction map, |∂wi/∂u1 × ∂wi/∂u2| by central
/// differences (step 1e-3 for a lobe of width ≥ 0.05), equals 1/p_t(wi) within 1e-2 relative
/// (RJMLT Sec. 4: |J[S]| = 1/p for a diffeomorphism). Points within 5e-3 of the concentric map's
/// seams (its diagonals |2u1−1| = |2u2−1|, where it is only piecewise smooth), within 0.02 of the
/// square's edges (the polar map's √u1 and the lift √(1 − r²) are singular at u1 = 0 and 1), or whose direction is within 0.05 of the horizon are skipped as singular.
#[test]
fn direction_maps_have_jacobian_one_over_pdf() {
    let h = 1e-3;
    let mut rng = Rng::new(37, 0);
    let mut lobes: Vec<(Material, usize)> = vec![(Material::Diffuse { reflectance: Rgb::ONE }, 0)];
    for &a in &[0.05f32, 0.3, 1.0] {
        lobes.push((conductor(a), 0));
        lobes.push((plastic(a), plastic::SPECULAR));
    }
    lobes.push((plastic(0.3), plastic::DIFFUSE));
    let mut checked = 0;
    let mut worst = 0.0f64;
    for (m, t) in &lobes {
        for &theta in &ANGLES[..3] {
            let wo = dir(theta, 0.7);
            let map = |u: [f64; 2]| -> Option<[f64; 3]> {
                let w = m.sample_lobe(*t, wo, [u[0] as f32, u[1] as f32])?.as_dvec3();
                Some([w.x, w.y, w.z])
            };
            for _ in 0..300 {
                let u = [f64::from(rng.uniform()), f64::from(rng.uniform())];
                let (a, b) = (2.0 * u[0] - 1.0, 2.0 * u[1] - 1.0);
                if (a.abs() - b.abs()).abs() < 5e-3 || u.iter().any(|&x| !(0.02..0.98).contains(&x)) {
                    continue;
                }
                let neighbours = [[u[0] - h, u[1]], [u[0] + h, u[1]], [u[0], u[1] - h], [u[0], u[1] + h], u];
                let Some(ws) = neighbours.iter().map(|&v| map(v)).collect::<Option<Vec<_>>>() else { continue };
                if ws.iter().any(|w| w[2] < 0.05) {
                    continue;
                }
                let det = jacobian_det_surface(|v| map(v).unwrap_or([0.0; 3]), u, h);
                let wi = Vec3::new(ws[4][0] as f32, ws[4][1] as f32, ws[4][2] as f32);
                let pdf = f64::from(m.lobe_pdf(*t, wo, wi));
                let rel = (det * pdf - 1.0).abs();
                worst = worst.max(rel);
                assert!(rel < 1e-2, "{m:?} lobe {t} wo {wo:?} u {u:?}: |J| = {det}, 1/pdf = {}", 1.0 / pdf);
                checked += 1;
            }
        }
    }
    eprintln!("Jacobian check: {checked} points, worst relative error {worst:e}");
    assert!(checked > 3000, "too few regular points checked: {checked}");
}
