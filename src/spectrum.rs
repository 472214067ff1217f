//! Colour. plexus renders in linear sRGB primaries with three `f32` channels.

/// Linear RGB radiance, reflectance or throughput.
pub type Rgb = glam::Vec3;

/// Luminance (Rec. 709 / sRGB primaries): the scalar MCMC targets and light power use.
#[inline]
pub fn luminance(c: Rgb) -> f32 {
    0.212_671 * c.x + 0.715_160 * c.y + 0.072_169 * c.z
}

/// Whether every channel is finite.
#[inline]
pub fn is_finite(c: Rgb) -> bool {
    c.x.is_finite() && c.y.is_finite() && c.z.is_finite()
}

/// Whether every channel is zero.
#[inline]
pub fn is_black(c: Rgb) -> bool {
    c.x == 0.0 && c.y == 0.0 && c.z == 0.0
}
