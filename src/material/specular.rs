//! Perfect mirror: a single delta lobe at the reflection of `wo` about the normal.

use glam::Vec3;

use super::fresnel::reflect_z;
use super::DELTA_DIRECTION_TOLERANCE;
use crate::spectrum::Rgb;

/// The mirror direction, or `None` when `wo` is not strictly above the horizon.
#[inline]
pub fn sample(wo: Vec3) -> Option<Vec3> {
    (wo.z > 0.0).then(|| reflect_z(wo))
}

/// f·|cos θi| of the delta lobe: the reflectance (no Fresnel falloff, as the scene gives it).
#[inline]
pub fn weight(reflectance: Rgb) -> Rgb {
    reflectance
}

/// Whether `wi` is the mirror direction of `wo` (within `DELTA_DIRECTION_TOLERANCE`).
pub fn matches(wo: Vec3, wi: Vec3) -> bool {
    wo.z > 0.0 && (reflect_z(wo) - wi).length() <= DELTA_DIRECTION_TOLERANCE
}
