//! The perturbations' transition densities against what `propose` realises (χ²), each with the
//! deliberately wrong variant issue 14 names.
//!
//! Bins are over the variables a proposal samples, measured back from the proposed path: for the
//! lens perturbation of a path whose first vertex is diffuse (no specular vertex between it and the
//! camera), the new first vertex's position on its wall, in polar coordinates (ln ρ, φ) around the
//! old one (area dA = ρ² d(ln ρ) dφ); for the caustic perturbation, whose retrace runs through a
//! glass sphere, the direction at the pivot, (ln θ, φ) around the old one (dω = θ sin θ d(ln θ) dφ),
//! with T divided by the retrace's area factor Π |cos θ_next|/d² (which is how the delta-stripped
//! measure counts the chain's vertices per unit solid angle at the pivot). A bin's expected mass
//! is T integrated over it (adaptive Gauss–Kronrod, `chi2_test`); proposals that fail, change the
//! path's structure or fall outside the domain go to the extra cell with mass 1 − Σ.

use glam::{DVec3, Vec3};

use super::caustic::{caustic_pivot, Caustic, CausticKernel};
use super::kernel::{basis, DirectionKernel, RasterKernel};
use super::lens::Lens;
use super::retrace::retrace;
use super::state::{with_role, Interaction, PathState, PathVertex};
use super::strategy::Strategy;
use super::tests::scene;
use super::PathContext;
use crate::integrator::bdpt::path::full_path;
use crate::integrator::bdpt::{
    evaluate_technique, generate_camera_subpath, generate_light_subpath, BdptContext, ConnectScratch, FilmRegion,
    MisHeuristic, Vertex,
};
use crate::material::TransportMode;
use crate::sampling::chi2::{chi2_test, Chi2Config, Chi2Outcome};
use crate::sampling::Rng;
use crate::spectrum::Rgb;
use crate::stats::Counters;

const TAU: f64 = std::f64::consts::TAU;

/// A path of BDPT's (s, t) technique from a seeded stream whose interaction kinds are `signature`
/// (camera first) and f > 0.
fn bdpt_path(ctx: &PathContext, s: usize, t: usize, signature: &[Interaction]) -> PathState {
    let bctx = BdptContext::new(ctx.scene, usize::MAX, MisHeuristic::Balance);
    let mut counters = Counters::default();
    let (mut camera, mut light) = (Vec::new(), Vec::new());
    for stream in 0..200_000 {
        let mut rng = Rng::new(23, stream);
        let raster = generate_camera_subpath(&bctx, FilmRegion::WholeFilm, &mut rng, t, &mut camera, &mut counters);
        generate_light_subpath(&bctx, &mut rng, s, &mut light, &mut counters);
        if camera.len() < t || light.len() < s {
            continue;
        }
        let mut scratch = ConnectScratch::default();
        let Some(c) =
            evaluate_technique(&bctx, &light, &camera, s, t, raster, &mut rng, &mut scratch, &mut counters, None)
        else {
            continue;
        };
        let path = PathState::new(ctx, &full_path(&light, &camera, &c), &mut counters);
        let kinds: Vec<Interaction> = path.vertices.iter().map(|v| v.interaction).collect();
        if path.f_star > 0.0 && kinds == signature {
            return path;
        }
    }
    panic!("no path {signature:?} found");
}

/// The χ² test of the lens perturbation on the Cornell box (32 × 32, Veach's kernel) from a path
/// (c, a, b, L) with a and b diffuse: bins over a′'s position on a's wall (module docs), 12 × 8,
/// ρ from 1e-3 to 0.25 of the camera distance.
fn chi2_of_lens(strategy: Lens, samples: usize) -> Chi2Outcome {
    use Interaction::*;
    let scene = scene("cornell-box", 32);
    let ctx = PathContext { scene: &scene, max_depth: 8 };
    let x = bdpt_path(&ctx, 2, 2, &[Camera, Diffuse, Diffuse, Emitter]);
    let kernel = RasterKernel::veach(32, 32);
    let a = x.vertices[1].vertex;
    let c = x.vertices[0].vertex;
    let n = a.ng.as_dvec3();
    let (s, t) = basis(n);
    let origin = a.p.as_dvec3();
    let scale = (origin - c.p.as_dvec3()).length();
    let range = [(1e-3 * scale).ln(), (0.25 * scale).ln()];
    let param = |p: DVec3| -> Option<[f64; 2]> {
        let d = p - origin;
        if d.dot(n).abs() > 1e-3 * scale {
            return None;
        }
        Some([d.length().ln(), d.dot(t).atan2(d.dot(s)).rem_euclid(TAU)])
    };
    // ȳ for a′ at (ln ρ, φ): the first hit of the camera ray towards that point, if it is that point.
    let path_at = |q: [f64; 2]| -> Option<PathState> {
        let rho = q[0].exp();
        let p = origin + (s * q[1].cos() + t * q[1].sin()) * rho;
        let dir = (p - c.p.as_dvec3()).normalize().as_vec3();
        let raster = scene.camera.raster_of(dir)?;
        let ray = scene.camera.ray_through(raster);
        let si = scene.intersect(&ray)?;
        if (si.p.as_dvec3() - p).length() > 1e-3 * scale {
            return None;
        }
        let v = with_role(&scene, Vertex::surface(&scene, &si, -ray.d, Rgb::ONE, TransportMode::Radiance), 1, 4);
        let vertices = vec![x.vertices[0], v, x.vertices[2], x.vertices[3]];
        Some(PathState { vertices, raster, f: glam::DVec3::ZERO, f_star: 0.0 })
    };
    let cfg = Chi2Config { res: [12, 8], samples, max_depth: 8, quad_eps: 1e-6, ..Chi2Config::default() };
    let mut counters = Counters::default();
    chi2_test(
        &cfg,
        range,
        [0.0, TAU],
        31,
        |rng| {
            let (y, _) = strategy.propose(&ctx, &x, &kernel, rng, &mut counters)?;
            (y.len() == 4).then(|| param(y.vertices[1].vertex.p.as_dvec3())).flatten()
        },
        |q| match path_at(q) {
            Some(y) => strategy.transition(&ctx, &kernel, &x, &y, &()) * (2.0 * q[0]).exp(),
            None => 0.0,
        },
    )
}

/// `Lens::transition` is the density `propose` realises (χ² above, 100,000 proposals, α = 1e-3).
/// Wrong variant: T as if the connection edge (a′, b) had been traced (× G(a′,b)/G(a,b), which
/// would drop G from the acceptance) must fail. Measured: χ² = 77.5, 69 dof, p = 0.23; the wrong
/// variant χ² = 1,773.9, p = 0.
#[test]
fn lens_transition_matches_the_proposal_density() {
    let right = chi2_of_lens(Lens::default(), 100_000);
    println!("lens, right T: {}", right.message);
    let wrong = chi2_of_lens(Lens { connection_g_in_t: true }, 100_000);
    println!("lens, T with the connection's G: {}", wrong.message);
    assert!(!wrong.passed, "a lens T with the connection's G passed: {}", wrong.message);
    assert!(right.passed, "{}", right.message);
}

/// The χ² test of the caustic perturbation on the glass Cornell box (32 × 32) from a caustic path
/// (c, floor, glass, glass, L) (BDPT's (4, 1) technique, light tracing): bins over the direction at the pivot L
/// (module docs), 12 × 8, θ over the kernel's range ± 0.1 in ln θ. The kernel is widened (the
/// lens angle up to 0.6 rad before the path's width factor) so that the pivot's cosine varies over
/// it by tens of per cent: at Veach's width (~0.01 rad here) no χ² could see a missing cosine, and
/// at 0.15 rad the wrong variant still passed (χ² = 107.2, 88 dof, p = 0.08).
fn chi2_of_caustic(strategy: Caustic, samples: usize) -> Chi2Outcome {
    use Interaction::*;
    let scene = scene("cornell-glass", 32);
    let ctx = PathContext { scene: &scene, max_depth: 8 };
    let x = bdpt_path(&ctx, 4, 1, &[Camera, Diffuse, Specular, Specular, Emitter]);
    let j = caustic_pivot(&x.vertices).expect("a caustic path");
    let kernel = CausticKernel { lens_angle: DirectionKernel { theta_min: 1e-3, theta_max: 0.6 } };
    let width = kernel.at(&x.vertices, j).expect("width");
    let pivot = x.vertices[j].vertex;
    let axis = pivot.dir_to(&x.vertices[j - 1].vertex).as_dvec3();
    let (s, t) = basis(axis);
    let polar = |d: DVec3| [axis.cross(d).length().atan2(axis.dot(d)).ln(), d.dot(t).atan2(d.dot(s)).rem_euclid(TAU)];
    let range = [width.theta_min.ln() - 0.1, width.theta_max.ln() + 0.1];
    let path_at = |q: [f64; 2]| -> Option<(PathState, f64)> {
        let theta = q[0].exp();
        let dir = s * (theta.sin() * q[1].cos()) + t * (theta.sin() * q[1].sin()) + axis * theta.cos();
        let mut counters = Counters::default();
        let new = retrace(&ctx, &x.vertices, j, 1, &pivot, dir.as_vec3(), &mut counters)?;
        let vertices: Vec<PathVertex> = x.vertices[..1]
            .iter()
            .copied()
            .chain(new.into_iter().rev())
            .chain(x.vertices[j..].iter().copied())
            .collect();
        // The chain's vertices per unit solid angle at the pivot, written out here: Π |cos|/d².
        let mut area = 1.0;
        for i in (1..j).rev() {
            let (from, to): (Vec3, &Vertex) = (vertices[i + 1].vertex.p, &vertices[i].vertex);
            let w = (to.p - from).as_dvec3();
            area *= (to.ng.as_dvec3().dot(w.normalize())).abs() / w.length_squared();
        }
        let c = vertices[0].vertex;
        let raster = scene.camera.raster_of(c.dir_to(&vertices[1].vertex)).unwrap_or(glam::Vec2::splat(-1.0));
        Some((PathState { vertices, raster, f: DVec3::ZERO, f_star: 0.0 }, area))
    };
    let cfg = Chi2Config { res: [12, 8], samples, max_depth: 8, quad_eps: 1e-6, ..Chi2Config::default() };
    let mut counters = Counters::default();
    chi2_test(
        &cfg,
        range,
        [0.0, TAU],
        37,
        |rng| {
            let (y, _) = strategy.propose(&ctx, &x, &kernel, rng, &mut counters)?;
            let same = y.vertices.iter().zip(&x.vertices).all(|(a, b)| a.interaction == b.interaction);
            (y.len() == x.len() && same)
                .then(|| polar(y.vertices[j].vertex.dir_to(&y.vertices[j - 1].vertex).as_dvec3()))
        },
        |q| match path_at(q) {
            Some((y, area)) if area > 0.0 => {
                let theta = q[0].exp();
                strategy.transition(&ctx, &kernel, &x, &y, &()) / area * theta * theta.sin()
            }
            _ => 0.0,
        },
    )
}

/// `Caustic::transition` is the density `propose` realises (χ² above, 1,000,000 proposals, α =
/// 1e-3: the pivot's cosine varies by only ~5% over the directions that still meet the sphere, and
/// at 100,000 proposals the wrong variant passed, χ² = 88.2, 71 dof, p = 0.08). Wrong variant: T per unit projected solid angle at the pivot (× |cos θ(x̄)|/|cos θ(ȳ)|,
/// which would drop the pivot's |cos| from the acceptance) must fail. Measured: χ² = 53.7, 73 dof,
/// p = 0.96; the wrong variant χ² = 191.9, p = 1.2e-12.
#[test]
fn caustic_transition_matches_the_proposal_density() {
    let right = chi2_of_caustic(Caustic::default(), 1_000_000);
    println!("caustic, right T: {}", right.message);
    let wrong = chi2_of_caustic(Caustic { omit_pivot_cos: true }, 1_000_000);
    println!("caustic, T without the pivot's |cos|: {}", wrong.message);
    assert!(!wrong.passed, "a caustic T without the pivot's |cos| passed: {}", wrong.message);
    assert!(right.passed, "{}", right.message);
}
