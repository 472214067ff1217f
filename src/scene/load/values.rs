//! Scalar values of a scene file checked with their key path: vectors, colours, reflectances,
//! roughness, index of refraction, subdivision counts, and the ranges plexus renders correctly.

use glam::Vec3;

use super::Builder;
use crate::scene::desc::ColorDesc;
use crate::scene::error::{fmt3, SceneError};
use crate::spectrum::Rgb;

impl Builder<'_> {
    pub(super) fn finite_vec(&self, key: &str, v: [f32; 3]) -> Result<Vec3, SceneError> {
        let v3 = Vec3::from(v);
        if v3.is_finite() {
            Ok(v3)
        } else {
            Err(self.err(key, format!("expected three finite numbers, got {}", fmt3(v))))
        }
    }

    /// A colour whose every component passes `ok` (and is finite).
    pub(super) fn color(
        &self,
        key: &str,
        c: ColorDesc,
        what: &str,
        ok: impl Fn(f32) -> bool,
    ) -> Result<Rgb, SceneError> {
        if c.0.iter().all(|&v| v.is_finite() && ok(v)) {
            Ok(Rgb::from(c.0))
        } else {
            Err(self.err(key, format!("expected [r, g, b] with {what}, got {}", fmt3(c.0))))
        }
    }

    pub(super) fn reflectance(&self, key: &str, c: Option<ColorDesc>, default: f32) -> Result<Rgb, SceneError> {
        match c {
            None => Ok(Rgb::splat(default)),
            Some(c) => self.color(key, c, "every component in [0, 1]", |v| (0.0..=1.0).contains(&v)),
        }
    }

    pub(super) fn roughness(&self, key: &str, r: Option<f32>) -> Result<f32, SceneError> {
        match r {
            None => Ok(DEFAULT_ROUGHNESS),
            Some(a) if (0.0..=MAX_ROUGHNESS).contains(&a) => Ok(a),
            Some(a) => {
                Err(self.err(key, format!("expected a number in [0, {MAX_ROUGHNESS}] (the GGX alpha), got {a}")))
            }
        }
    }

    pub(super) fn ior(&self, key: &str, ior: Option<f32>) -> Result<f32, SceneError> {
        match ior {
            None => Ok(DEFAULT_IOR),
            Some(v) if v > 0.0 && v.is_finite() => Ok(v),
            Some(v) => Err(self.err(key, format!("expected a number > 0, got {v}"))),
        }
    }

    pub(super) fn subdivisions(
        &self,
        key: &str,
        v: Option<i64>,
        default: u32,
        min: i64,
        max: i64,
    ) -> Result<u32, SceneError> {
        match v {
            None => Ok(default),
            Some(n) if (min..=max).contains(&n) => Ok(n as u32),
            Some(n) => Err(self.err(key, format!("expected an integer in [{min}, {max}], got {n}"))),
        }
    }

    /// Splits a transform error "sub.key: message" into the key path and the message.
    pub(super) fn split_err(&self, prefix: &str, e: &str) -> SceneError {
        match e.split_once(": ") {
            Some((sub, msg)) if !sub.contains(' ') => self.err(format!("{prefix}.{sub}"), msg),
            _ => self.err(prefix, e),
        }
    }
}

/// The largest GGX α a material may have. At α = 1 the microfacets are already as rough as any
/// measured surface, and far beyond it GGX is a cosine-like lobe that changes no more; past about
/// 1e9 its α⁴ overflows f32 and contributions become non-finite. 100 keeps every rough material
/// plexus renders far from that.
pub const MAX_ROUGHNESS: f32 = 100.0;

/// The smallest scene extent (in scene units) plexus renders correctly; see `Builder::check_scale`.
pub const MIN_EXTENT: f32 = 1e-9;
/// The largest scene extent and coordinate plexus renders correctly; see `Builder::check_scale`.
pub const MAX_EXTENT: f32 = 1e12;

/// The largest radiance component (after `scale`) an emitter or environment texel may have. The
/// integrators multiply radiance by path throughputs (BSDF/pdf ratios, and G·A/pdf factors of
/// sampled light points: A/h² reaches 1e14 for a point 1e-7 of the scene's extent from a light's
/// plane) before the film sums it in f64 and writes the image in f32 (at most 3.4e38): 1e20 leaves
/// those factors 18 decades of headroom. Environment texels of 3e38 (which once rendered black
/// or wrote Inf pixels) are far beyond it.
pub const MAX_RADIANCE: f32 = 1e20;

/// Roughness (GGX alpha) when a conductor or plastic gives none.
pub const DEFAULT_ROUGHNESS: f32 = 0.1;
/// Index of refraction when a dielectric or plastic gives none (glass).
pub const DEFAULT_IOR: f32 = 1.5;
