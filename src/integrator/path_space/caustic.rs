//! Veach's caustic perturbation (Veach & Guibas 1997 Sec. 5.4.2): for a path whose camera end is
//! E D S+ (D|L) — the camera sees a non-specular x_1 lit through a specular chain x_2 … x_{j−1}
//! from the non-specular x_j (the pivot) — perturb the direction leaving x_j towards x_{j−1} by the
//! truncated reciprocal kernel, retrace the chain towards the camera (`retrace`) to a new x_1, and
//! connect x_1 to the pinhole: the raster position moves. The rest of the path, x_j …, is kept.
//!
//! # Kernel width
//! The kernel's range is the lens perturbation's angular range scaled by |x_0 x_1| / ℓ, ℓ = Σ
//! |x_i x_{i+1}| over the chain x_1 … x_j (Veach's rule: turning the pivot's direction by θ moves
//! x_1 by about θ·ℓ, which the camera sees as an angle θ·ℓ/|x_0 x_1|, so that scaling makes the
//! image move by about as much as a lens perturbation). The width depends on the path, so T(x̄ →
//! ȳ) uses the width from x̄ and T(ȳ → x̄) the width from ȳ (the kernel is not symmetric between
//! paths of different widths).
//!
//! # Transition density
//! In the delta-stripped area measure of y_1 … y_{j−1} (path_space module docs):
//!
//!   T(x̄ → ȳ) = p_θ(x̄)(ω_y | ω_x) · Π |cos θ_next|/d² over the traced edges y_j → … → y_1
//!              · Π h(y_i) over the chain's refractions y_2 … y_{j−1},
//!
//! p_θ per unit solid angle at the pivot (`DirectionKernel::density`). The path measure at the
//! pivot is projected solid angle in f (its g carries |cos θ| at x_j), the kernel's solid angle is
//! not: so the acceptance keeps the ratio |cos θ_j(ȳ)| / |cos θ_j(x̄)| through f — nothing cancels
//! it, and a T per unit projected solid angle would drop it (the wrong variant the χ² test rejects).
//! The retrace runs towards the camera, against the direction f strips each specular vertex's δ
//! in, so each refraction contributes its measure factor h = η_a² |cos θ_a| / (η_b² |cos θ_b|)
//! (`density` module docs; `retrace::retrace_jacobian` includes it).

use super::path_state::{Interaction, PathState, PathVertex};
use super::reciprocal_kernel::{DirectionKernel, RasterKernel};
#[cfg(any(test, feature = "testing"))]
use super::retrace::retrace_measure_factor;
use super::retrace::{first_non_specular, retrace, retrace_jacobian};
use super::strategy::Strategy;
use super::PathContext;
use crate::camera::Camera;
use crate::sampling::Rng;
use crate::stats::Counters;

/// The caustic perturbation's kernel: the lens perturbation's range as an angle at the camera,
/// which each path scales (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CausticKernel {
    pub lens_angle: DirectionKernel,
}

impl CausticKernel {
    /// The angles the lens kernel's r_1 and r_2 pixels subtend at the centre of `camera`'s film.
    pub fn from_lens(lens: &RasterKernel, camera: &Camera) -> CausticKernel {
        let per_pixel = 2.0 * camera.tan_half_fov as f64 / camera.height as f64;
        CausticKernel { lens_angle: DirectionKernel { theta_min: lens.r1 * per_pixel, theta_max: lens.r2 * per_pixel } }
    }

    /// The direction kernel at the pivot `j` of `path` (module docs, "Kernel width").
    pub fn at(&self, path: &[PathVertex], j: usize) -> Option<DirectionKernel> {
        let length = |a: usize| (path[a + 1].vertex.p - path[a].vertex.p).as_dvec3().length();
        let eye = length(0);
        let chain: f64 = (1..j).map(length).sum();
        let factor = eye / chain;
        (factor.is_finite() && factor > 0.0).then(|| self.lens_angle.scaled(factor))
    }
}

/// The caustic perturbation (module docs).
#[derive(Clone, Copy, Debug, Default)]
pub struct Caustic {
    /// Tests only: T per unit projected solid angle at the pivot (times |cos θ_j(x̄)|/|cos θ_j(ȳ)|,
    /// normalised at x̄ so that only its shape is wrong), the deliberately wrong variant the χ²
    /// test must reject: it would drop the pivot's |cos| from the acceptance.
    #[cfg(any(test, feature = "testing"))]
    pub omit_pivot_cos: bool,
    /// Tests only: T without the refractions' measure factors Π h (the retrace towards the camera
    /// taken as if it ran towards the light), the deliberately wrong variant the agreement tests on
    /// scenes whose Π h ≠ 1 must reject.
    #[cfg(any(test, feature = "testing"))]
    pub omit_refraction_measure: bool,
}

/// The pivot x_j of the caustic perturbation on `path`, if it is suitable there (module docs).
pub fn caustic_pivot(path: &[PathVertex]) -> Option<usize> {
    let n = path.len();
    if n < 4 || !matches!(path[1].interaction, Interaction::Diffuse | Interaction::Glossy) {
        return None;
    }
    if path[2].interaction != Interaction::Specular {
        return None;
    }
    let j = (2..n).find(|&i| path[i].interaction != Interaction::Specular)?;
    (!path[j].vertex.infinite).then_some(j)
}

impl Strategy for Caustic {
    type Kernel = CausticKernel;
    type Move = ();

    fn name(&self) -> &'static str {
        "caustic"
    }

    fn is_perturbation(&self) -> bool {
        true
    }

    fn suitable(&self, _ctx: &PathContext, path: &PathState) -> bool {
        caustic_pivot(&path.vertices).is_some()
    }

    fn propose(
        &self,
        ctx: &PathContext,
        path: &PathState,
        kernel: &CausticKernel,
        rng: &mut Rng,
        counters: &mut Counters,
    ) -> Option<(PathState, ())> {
        let x = &path.vertices;
        let j = caustic_pivot(x)?;
        let k = kernel.at(x, j)?;
        let axis = x[j].vertex.dir_to(&x[j - 1].vertex).as_dvec3();
        let dir = k.sample(axis, [rng.uniform_f64(), rng.uniform_f64()]).as_vec3();
        let new = retrace(ctx, x, j, 1, &x[j].vertex, dir, counters)?;
        let vertices: Vec<PathVertex> =
            x[..1].iter().copied().chain(new.into_iter().rev()).chain(x[j..].iter().copied()).collect();
        Some((PathState::from_path_vertices(ctx, vertices, counters), ()))
    }

    fn transition(&self, ctx: &PathContext, kernel: &CausticKernel, from: &PathState, to: &PathState, _: &()) -> f64 {
        let (x, y) = (&from.vertices, &to.vertices);
        let Some(j) = caustic_pivot(x) else { return 0.0 };
        if y.len() != x.len() || caustic_pivot(y) != Some(j) || first_non_specular(y) != Some(1) {
            return 0.0;
        }
        // The width from the path the move leaves (module docs).
        let Some(k) = kernel.at(x, j) else { return 0.0 };
        let axis = x[j].vertex.dir_to(&x[j - 1].vertex).as_dvec3();
        let dir = y[j].vertex.dir_to(&y[j - 1].vertex).as_dvec3();
        #[allow(unused_mut)]
        let mut t = k.density(axis, dir) * retrace_jacobian(ctx.scene, y, j, 1);
        #[cfg(any(test, feature = "testing"))]
        if self.omit_pivot_cos {
            let n = y[j].vertex.frame.n.as_dvec3();
            t *= n.dot(axis).abs() / n.dot(dir).abs();
        }
        #[cfg(any(test, feature = "testing"))]
        if self.omit_refraction_measure {
            t /= retrace_measure_factor(ctx.scene, y, j, 1);
        }
        if t.is_finite() {
            t
        } else {
            0.0
        }
    }

    fn reverse(&self, _: &()) {}
}
