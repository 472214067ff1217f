//! Veach's lens perturbation (Veach & Guibas 1997 Sec. 5.4.1): move the path's raster position by
//! the truncated reciprocal offset ([`RasterKernel`]), retrace the specular chain from the camera
//! to the first non-specular vertex x_k (`retrace`), and reconnect x_k to the unchanged x_{k+1}.
//! Suitable for paths (L|D) D S* E read from the light: x_1 … x_{k−1} specular, x_k not, and
//! x_{k+1} (if any) not specular, so that the edge x_k x_{k+1} can be a connection; when x_k is the
//! emitter itself (E S* L) there is nothing to reconnect.
//!
//! # Transition density
//! In the module's delta-stripped area measure of y_1 … y_k (path_space module docs):
//!
//!   T(x̄ → ȳ) = p_r(ȳ.raster − x̄.raster) · W·H · p_film(ω_0) · Π_{j<k} |cos θ_{j+1}|/d_j²
//!
//! p_r per unit film area in pixels² (the kernel), W·H/A the pixels per unit of the film at
//! distance 1 (area A), p_film(ω) = 1/(A cos³θ) the film's conversion to solid angle at the
//! pinhole (`Camera::pdf_we`), then the retrace's solid angle → area factors (`retrace_jacobian`).
//! The kernel is symmetric in the raster offset, so in f(ȳ)T(ȳ→x̄)/(f(x̄)T(x̄→ȳ)) it cancels, as do
//! the camera terms and every traced edge's G (they are in f too): what remains is the BSDFs at
//! y_k and x_{k+1} and the connection edge's G(y_k, x_{k+1}), the one edge nothing traced.

use glam::{DVec2, Vec2};

use super::path_state::{Interaction, PathState, PathVertex};
use super::reciprocal_kernel::RasterKernel;
use super::retrace::{first_non_specular, retrace, retrace_jacobian};
use super::strategy::Strategy;
use super::PathContext;
use crate::sampling::Rng;
use crate::stats::Counters;

/// The lens perturbation (module docs).
#[derive(Clone, Copy, Debug, Default)]
pub struct Lens {
    /// Tests only: T as if the connection edge had been traced (times G(y_k, x_{k+1})/G(x_k,
    /// x_{k+1}), normalised at x̄ so that only its shape is wrong), the deliberately wrong variant
    /// the χ² test must reject: it would drop G from the acceptance.
    #[cfg(any(test, feature = "testing"))]
    pub connection_g_in_t: bool,
}

/// Where the lens perturbation's retrace ends on `path` (the first non-specular vertex x_k), if
/// the strategy is suitable there (module docs).
pub fn lens_chain_end(path: &[PathVertex]) -> Option<usize> {
    let n = path.len();
    if n < 2 {
        return None;
    }
    let k = first_non_specular(path)?;
    if k + 1 < n && !path[k + 1].connectible() {
        return None;
    }
    if path[k].interaction == Interaction::Emitter && k + 1 != n {
        return None;
    }
    Some(k)
}

/// The density per unit solid angle at the pinhole of the direction through `to.raster` when the
/// raster offset from `from.raster` has density `p_px` per pixel² (module docs).
pub fn raster_to_solid_angle(ctx: &PathContext, to: &PathState, p_px: f64) -> f64 {
    let camera = &ctx.scene.camera;
    let d0 = to.vertices[0].vertex.dir_to(&to.vertices[1].vertex);
    let per_solid_angle = camera.pdf_we(d0).1 as f64;
    p_px * camera.width as f64 * camera.height as f64 * per_solid_angle
}

/// The film position `raster + offset`, if on the film.
pub fn offset_raster(ctx: &PathContext, raster: Vec2, offset: DVec2) -> Option<Vec2> {
    let camera = &ctx.scene.camera;
    let r = raster.as_dvec2() + offset;
    let inside = r.x >= 0.0 && r.y >= 0.0 && r.x < camera.width as f64 && r.y < camera.height as f64;
    inside.then(|| r.as_vec2())
}

/// G(x_k, x_{k+1}) = |cos θ_k| |cos θ_{k+1}| / d² with geometric normals (the wrong variant's).
#[cfg(any(test, feature = "testing"))]
fn connection_g(path: &[PathVertex], k: usize) -> f64 {
    let (a, b) = (&path[k].vertex, &path[k + 1].vertex);
    let cos_a = a.ng.as_dvec3().dot(a.dir_to(b).as_dvec3()).abs();
    super::retrace::solid_angle_to_area(a, b) * cos_a
}

impl Strategy for Lens {
    type Kernel = RasterKernel;
    type Move = ();

    fn name(&self) -> &'static str {
        "lens"
    }

    fn is_perturbation(&self) -> bool {
        true
    }

    fn suitable(&self, _ctx: &PathContext, path: &PathState) -> bool {
        lens_chain_end(&path.vertices).is_some()
    }

    fn propose(
        &self,
        ctx: &PathContext,
        path: &PathState,
        kernel: &RasterKernel,
        rng: &mut Rng,
        counters: &mut Counters,
    ) -> Option<(PathState, ())> {
        let x = &path.vertices;
        let k = lens_chain_end(x)?;
        let offset = kernel.sample([rng.uniform_f64(), rng.uniform_f64()]);
        let raster = offset_raster(ctx, path.raster, offset)?;
        let ray = ctx.scene.camera.ray_through(raster);
        let new = retrace(ctx, x, 0, k, &x[0].vertex, ray.d, counters)?;
        let vertices: Vec<PathVertex> = x[..1].iter().copied().chain(new).chain(x[k + 1..].iter().copied()).collect();
        Some((PathState::from_path_vertices(ctx, vertices, counters), ()))
    }

    fn transition(&self, ctx: &PathContext, kernel: &RasterKernel, from: &PathState, to: &PathState, _: &()) -> f64 {
        let (x, y) = (&from.vertices, &to.vertices);
        let Some(k) = lens_chain_end(x) else { return 0.0 };
        if y.len() != x.len() || lens_chain_end(y) != Some(k) {
            return 0.0;
        }
        let offset = (to.raster - from.raster).as_dvec2();
        #[allow(unused_mut)]
        let mut t = raster_to_solid_angle(ctx, to, kernel.density(offset)) * retrace_jacobian(ctx.scene, y, 0, k);
        #[cfg(any(test, feature = "testing"))]
        if self.connection_g_in_t && k + 1 < y.len() {
            t *= connection_g(y, k) / connection_g(x, k);
        }
        if t.is_finite() {
            t
        } else {
            0.0
        }
    }

    fn reverse(&self, _: &()) {}
}
