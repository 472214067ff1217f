//! Tests of the two-sided rule (`Bsdf`): from the back, a two-sided material samples, evaluates,
//! inverts and reflects exactly as from the front (χ² of its sampler against its pdf from the
//! back, albedo equality, invert round trips), and the one-sided material (the wrong variant) is
//! black from the back.

use glam::Vec3;

use super::tests::{albedo_quadrature, chi2_cfg, dir, rng_u3, rng_u4, CapParam};
use super::*;
use crate::sampling::chi2::{chi2_test, Chi2Config};
use crate::sampling::Rng;

/// χ² tests of this module expected to pass (Šidák family).
const CHI2_TESTS: usize = 4;

fn back(w: Vec3) -> Vec3 {
    Vec3::new(w.x, w.y, -w.z)
}

fn two_sided_materials() -> Vec<Material> {
    vec![
        Material::RoughPlastic { alpha: 0.2, plastic: Plastic::new(Rgb::new(0.8, 0.4, 0.1), Rgb::ONE, 1.5, false) },
        Material::conductor_from_colour(0.1, Rgb::new(0.9, 0.6, 0.3)),
    ]
}

/// From the back (wo below the frame's horizon): χ² of the two-sided BSDF's sampler against its
/// pdf, binned around the back side's mirror direction, at 30° and 75° (4 tests, family 1e-3).
#[test]
fn two_sided_back_chi2() {
    let cfg = Chi2Config { test_count: CHI2_TESTS, ..chi2_cfg() };
    let mut failures = Vec::new();
    for (i, m) in two_sided_materials().into_iter().enumerate() {
        let b = Bsdf { material: m, two_sided: true };
        for (j, theta) in [30.0f32, 75.0].into_iter().enumerate() {
            let wo = back(dir(theta, 0.7));
            let cap = CapParam::new(fresnel::reflect_z(wo));
            let out = chi2_test(
                &cfg,
                [0.0, 1.0],
                [0.0, 2.0 * std::f64::consts::PI],
                3000 + 10 * i as u64 + j as u64,
                |rng| b.sample(wo, rng_u3(rng), TransportMode::Radiance).and_then(|s| cap.to_param(s.wi)),
                |p| {
                    let (w, jac) = cap.direction_at(p);
                    f64::from(b.pdf(wo, w, TransportMode::Radiance)) * jac
                },
            );
            if !out.passed {
                failures.push(format!("{m:?} {theta}°: {}", out.message));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// ∫ f |cos| from the back equals the front's (the quadrature of `albedo_quadrature` on the
/// mirrored pair, 1e-5), and sampled throughputs agree sample by sample; the one-sided wrong
/// variant has albedo 0 from the back. Sample → invert → sample round trips from the back.
#[test]
fn two_sided_back_behaves_as_front() {
    let mut rng = Rng::new(67, 0);
    for m in two_sided_materials() {
        let two = Bsdf { material: m, two_sided: true };
        let one = Bsdf::from(m);
        for theta in [0.0f32, 45.0, 80.0] {
            let wo = dir(theta, 0.7);
            let front = albedo_quadrature(&m, wo, TransportMode::Radiance);
            let quad = |b: &Bsdf| {
                let cap = CapParam::new(fresnel::reflect_z(back(wo)));
                crate::sampling::chi2::integrate_2d_to(
                    |p| {
                        let (w, jac) = cap.direction_at(p);
                        f64::from(b.eval(back(wo), w, TransportMode::Radiance).x * w.z.abs()) * jac
                    },
                    [0.0, 1.0],
                    [0.0, 2.0 * std::f64::consts::PI],
                    [12, 12],
                    1e-7,
                    5,
                )
            };
            let from_back = quad(&two);
            assert!((from_back - f64::from(front.x)).abs() < 1e-5, "{m:?} {theta}°: {from_back} vs {}", front.x);
            assert_eq!(quad(&one), 0.0, "the one-sided material is black from the back");
            for _ in 0..500 {
                let u = rng_u3(&mut rng);
                let (Some(s), Some(f)) =
                    (two.sample(back(wo), u, TransportMode::Radiance), m.sample(wo, u, TransportMode::Radiance))
                else {
                    continue;
                };
                assert!(s.wi.z < 0.0 && (s.wi - back(f.wi)).length() < 1e-6 && s.pdf == f.pdf && s.f == f.f);
                let inv = two.invert(back(wo), s.wi, TransportMode::Radiance, rng_u4(&mut rng));
                if let Some(inv) = inv {
                    let again = two.sample(back(wo), inv.u, TransportMode::Radiance).expect("re-samples");
                    assert!((again.wi - s.wi).length() < 1e-4);
                }
                assert!(one.sample(back(wo), u, TransportMode::Radiance).is_none());
            }
        }
    }
}

/// A material whose only texture is a checkerboard picks one of two materials made once; they are
/// what the per-lookup conversion gives, bit for bit, on both squares (a textured conductor's η
/// and k from `conductor_from_colour`, a plastic's diffuse colour through `with_colours`). The
/// wrong variant (the squares' materials swapped) differs wherever the colours do.
#[test]
fn checkerboard_materials_are_the_per_lookup_ones() {
    use crate::texture::Texture;
    use glam::Vec2;
    let (c0, c1) = (Rgb::new(0.8, 0.7, 0.6), Rgb::new(0.2, 0.25, 0.3));
    let checker = Texture::Checkerboard { colour0: c0, colour1: c1, uscale: 20.0, vscale: 80.0 };
    let plastic = Plastic::new(Rgb::splat(0.5), Rgb::ONE, 1.5, false);
    let conductor = SurfaceMaterial::new(Material::conductor_from_colour(0.1, Rgb::ONE), true)
        .with_texture(ColourSlot::Colour, checker.clone());
    let rough_plastic = SurfaceMaterial::new(Material::RoughPlastic { alpha: 0.2, plastic }, false)
        .with_texture(ColourSlot::Diffuse, checker.clone());
    let mut rng = Rng::new(11, 0);
    let (mut squares, mut swapped_differs) = ([0usize; 2], 0usize);
    for _ in 0..4000 {
        let uv = Vec2::new(rng.uniform() * 3.0 - 1.0, rng.uniform() * 3.0 - 1.0);
        let colour = checker.eval(uv);
        squares[checker.checker_square(uv)] += 1;
        let got = conductor.bsdf_at(uv);
        assert_eq!(got.material, Material::conductor_from_colour(0.1, colour), "conductor at {uv:?}");
        assert!(got.two_sided);
        let want = Material::RoughPlastic { alpha: 0.2, plastic: plastic.with_colours(colour, plastic.specular) };
        assert_eq!(rough_plastic.bsdf_at(uv).material, want, "plastic at {uv:?}");
        let other = if colour == c0 { c1 } else { c0 };
        if Material::conductor_from_colour(0.1, other) != got.material {
            swapped_differs += 1;
        }
    }
    assert!(squares[0] > 1000 && squares[1] > 1000, "both squares probed: {squares:?}");
    assert_eq!(swapped_differs, 4000);
}
