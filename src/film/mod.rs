//! Images and accumulation. Every worker accumulates into its own buffer (splats to any pixel
//! included); buffers are merged in worker order, so the same seed and thread count give a
//! bit-identical image.

pub mod exr_io;
pub mod oiio;
pub mod tonemap;

use glam::Vec2;

use crate::spectrum::Rgb;

/// A linear-RGB floating-point image, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<Rgb>,
}

impl Image {
    pub fn new(width: usize, height: usize) -> Image {
        Image { width, height, pixels: vec![Rgb::ZERO; width * height] }
    }
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> Rgb {
        self.pixels[y * self.width + x]
    }
    /// Mean of all pixels, per channel, accumulated in f64.
    pub fn mean(&self) -> [f64; 3] {
        let mut s = [0.0f64; 3];
        for p in &self.pixels {
            s[0] += p.x as f64;
            s[1] += p.y as f64;
            s[2] += p.z as f64;
        }
        let n = self.pixels.len().max(1) as f64;
        [s[0] / n, s[1] / n, s[2] / n]
    }
    /// Whether every pixel is finite.
    pub fn all_finite(&self) -> bool {
        self.pixels.iter().all(|p| crate::spectrum::is_finite(*p))
    }
}

/// One worker's accumulation buffer, in f64 so that long renders do not lose small contributions.
#[derive(Clone, Debug)]
pub struct Accumulator {
    pub width: usize,
    pub height: usize,
    sums: Vec<[f64; 3]>,
}

impl Accumulator {
    pub fn new(width: usize, height: usize) -> Accumulator {
        Accumulator { width, height, sums: vec![[0.0; 3]; width * height] }
    }
    /// Adds `value` to pixel (x, y). Non-finite values must be filtered by the caller (and counted).
    #[inline]
    pub fn add(&mut self, x: usize, y: usize, value: Rgb) {
        debug_assert!(crate::spectrum::is_finite(value));
        let s = &mut self.sums[y * self.width + x];
        s[0] += value.x as f64;
        s[1] += value.y as f64;
        s[2] += value.z as f64;
    }
    /// Adds `value` to the pixel containing the continuous raster position (box filter); positions
    /// off the film are ignored. Returns whether it landed.
    #[inline]
    pub fn splat(&mut self, raster: Vec2, value: Rgb) -> bool {
        if !(raster.x >= 0.0 && raster.y >= 0.0) {
            return false;
        }
        let (x, y) = (raster.x as usize, raster.y as usize);
        if x >= self.width || y >= self.height {
            return false;
        }
        self.add(x, y, value);
        true
    }
    /// Adds another buffer into this one.
    pub fn merge(&mut self, other: &Accumulator) {
        for (a, b) in self.sums.iter_mut().zip(&other.sums) {
            a[0] += b[0];
            a[1] += b[1];
            a[2] += b[2];
        }
    }
    /// Adds `other · scale` into this buffer.
    pub fn merge_scaled(&mut self, other: &Accumulator, scale: f64) {
        for (a, b) in self.sums.iter_mut().zip(&other.sums) {
            a[0] += b[0] * scale;
            a[1] += b[1] * scale;
            a[2] += b[2] * scale;
        }
    }
    /// Sums buffers in the order given (worker 0 first): the fixed order that makes renders
    /// reproducible.
    pub fn merge_in_order(buffers: &[Accumulator]) -> Option<Accumulator> {
        let mut iter = buffers.iter();
        let mut total = iter.next()?.clone();
        for b in iter {
            total.merge(b);
        }
        Some(total)
    }
    /// The image `sums · scale`.
    pub fn to_image(&self, scale: f64) -> Image {
        Image {
            width: self.width,
            height: self.height,
            pixels: self
                .sums
                .iter()
                .map(|s| Rgb::new((s[0] * scale) as f32, (s[1] * scale) as f32, (s[2] * scale) as f32))
                .collect(),
        }
    }
    /// The image with each pixel divided by its own count (`counts[i]` samples at pixel i).
    pub fn to_image_per_pixel(&self, counts: &[u64]) -> Image {
        Image {
            width: self.width,
            height: self.height,
            pixels: self
                .sums
                .iter()
                .zip(counts)
                .map(|(s, &n)| {
                    let k = if n > 0 { 1.0 / n as f64 } else { 0.0 };
                    Rgb::new((s[0] * k) as f32, (s[1] * k) as f32, (s[2] * k) as f32)
                })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splat_lands_in_its_pixel_and_off_film_is_ignored() {
        let mut a = Accumulator::new(4, 3);
        assert!(a.splat(Vec2::new(2.5, 1.2), Rgb::ONE));
        assert!(!a.splat(Vec2::new(4.0, 1.0), Rgb::ONE));
        assert!(!a.splat(Vec2::new(-0.1, 1.0), Rgb::ONE));
        assert!(!a.splat(Vec2::new(f32::NAN, 1.0), Rgb::ONE));
        let img = a.to_image(1.0);
        assert_eq!(img.get(2, 1), Rgb::ONE);
        assert_eq!(img.pixels.iter().map(|p| p.x).sum::<f32>(), 1.0);
    }
}
