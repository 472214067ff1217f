//! Images and accumulation. A render's film is an [`Accumulator`] of unnormalised f64 sums; a
//! work unit records its contributions (splats to any pixel included) in its own [`SplatBuffer`],
//! which the driver applies to the film in unit order, so the image depends on the work units only,
//! not on which thread ran them (`integrator::driver`).

pub mod exr_io;
pub mod oiio;
pub mod oiio_library;
pub mod png_io;
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
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Accumulator {
    pub width: usize,
    pub height: usize,
    sums: Vec<[f64; 3]>,
}

impl Accumulator {
    pub fn new(width: usize, height: usize) -> Accumulator {
        Accumulator { width, height, sums: vec![[0.0; 3]; width * height] }
    }
    /// A film holding `sums` (row-major, `width`×`height` of them): a saved state's film.
    pub fn from_sums(width: usize, height: usize, sums: Vec<[f64; 3]>) -> Accumulator {
        assert_eq!(sums.len(), width * height, "a {width}×{height} film");
        Accumulator { width, height, sums }
    }
    /// Adds `value` to pixel (x, y). Non-finite values must be filtered by the caller (and counted).
    #[inline]
    pub fn add(&mut self, x: usize, y: usize, value: Rgb) {
        self.add_at(y * self.width + x, value);
    }
    /// Adds `value` to the pixel containing the continuous raster position (box filter); positions
    /// off the film are ignored. Returns whether it landed.
    #[inline]
    pub fn splat(&mut self, raster: Vec2, value: Rgb) -> bool {
        match pixel_of(raster, self.width, self.height) {
            Some(index) => {
                self.add_at(index, value);
                true
            }
            None => false,
        }
    }
    #[inline]
    fn add_at(&mut self, index: usize, value: Rgb) {
        debug_assert!(crate::spectrum::is_finite(value));
        let s = &mut self.sums[index];
        s[0] += value.x as f64;
        s[1] += value.y as f64;
        s[2] += value.z as f64;
    }
    /// Adds a unit's recorded contributions, one by one in the order they were made: the same sums,
    /// bit for bit, as if the unit had added them to this film directly.
    pub fn apply(&mut self, buffer: &SplatBuffer) {
        debug_assert_eq!((buffer.width, buffer.height), (self.width, self.height));
        for &(index, value) in &buffer.splats {
            self.add_at(index as usize, value);
        }
    }
    /// The sums, taken out of the film (a state file's film).
    pub fn into_sums(self) -> Vec<[f64; 3]> {
        self.sums
    }
    /// The unnormalised sums, row-major: what a checkpoint or a merge of renders works on.
    pub fn sums(&self) -> &[[f64; 3]] {
        &self.sums
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

/// The pixel index of the continuous raster position on a `width`×`height` film (box filter), or
/// `None` off the film (NaN included).
#[inline]
fn pixel_of(raster: Vec2, width: usize, height: usize) -> Option<usize> {
    if !(raster.x >= 0.0 && raster.y >= 0.0) {
        return None;
    }
    let (x, y) = (raster.x as usize, raster.y as usize);
    (x < width && y < height).then_some(y * width + x)
}

/// One work unit's film contributions in one pass, in the order the unit made them (pixel index
/// and value, 16 bytes each). Recording them instead of adding them to a shared or per-thread film
/// is what lets the driver apply every unit's contributions in unit order: the film's sums then do
/// not depend on how units were spread over threads. The same `add`/`splat` calls as
/// [`Accumulator`]; cleared (capacity kept) once applied.
#[derive(Clone, Debug, Default)]
pub struct SplatBuffer {
    pub width: usize,
    pub height: usize,
    splats: Vec<(u32, Rgb)>,
}

impl SplatBuffer {
    /// A buffer for a film of at most 2^32 pixels (the driver refuses larger films).
    pub fn new(width: usize, height: usize) -> SplatBuffer {
        assert!(width * height <= u32::MAX as usize, "a film of {width}×{height} pixels has more than 2^32 pixels");
        SplatBuffer { width, height, splats: Vec::new() }
    }
    /// Records `value` for pixel (x, y). Non-finite values must be filtered by the caller (and
    /// counted).
    #[inline]
    pub fn add(&mut self, x: usize, y: usize, value: Rgb) {
        debug_assert!(x < self.width && y < self.height && crate::spectrum::is_finite(value));
        self.splats.push(((y * self.width + x) as u32, value));
    }
    /// Records `value` for the pixel containing the raster position (box filter); positions off
    /// the film are ignored. Returns whether it landed.
    #[inline]
    pub fn splat(&mut self, raster: Vec2, value: Rgb) -> bool {
        debug_assert!(crate::spectrum::is_finite(value));
        match pixel_of(raster, self.width, self.height) {
            Some(index) => {
                self.splats.push((index as u32, value));
                true
            }
            None => false,
        }
    }
    /// Records `value` for the pixel containing the raster position of a `width`×`layer_height`
    /// image stacked as rows [layer·layer_height, (layer+1)·layer_height) of this buffer's film
    /// (MLT's per-depth images); positions off that image are ignored, never moved into a
    /// neighbouring layer. Returns whether it landed.
    #[inline]
    pub fn splat_in_layer(&mut self, raster: Vec2, layer: usize, layer_height: usize, value: Rgb) -> bool {
        debug_assert!((layer + 1) * layer_height <= self.height && crate::spectrum::is_finite(value));
        match pixel_of(raster, self.width, layer_height) {
            Some(index) => {
                self.splats.push(((layer * layer_height * self.width + index) as u32, value));
                true
            }
            None => false,
        }
    }
    /// Number of recorded contributions.
    pub fn len(&self) -> usize {
        self.splats.len()
    }
    pub fn is_empty(&self) -> bool {
        self.splats.is_empty()
    }
    /// Forgets the contributions, keeping the allocation for the unit's next pass.
    pub fn clear(&mut self) {
        self.splats.clear();
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

    /// A layer splat lands in its layer's rows; a position below the layer's image is dropped, not
    /// moved into the next layer (which a plain `splat` at y + layer·height would do).
    #[test]
    fn layer_splat_stays_in_its_layer() {
        let mut buffer = SplatBuffer::new(4, 9);
        assert!(buffer.splat_in_layer(Vec2::new(2.5, 1.2), 1, 3, Rgb::ONE));
        assert!(!buffer.splat_in_layer(Vec2::new(2.5, 3.0), 1, 3, Rgb::ONE));
        assert!(!buffer.splat_in_layer(Vec2::new(-0.5, 1.0), 2, 3, Rgb::ONE));
        let mut film = Accumulator::new(4, 9);
        film.apply(&buffer);
        let img = film.to_image(1.0);
        assert_eq!(img.get(2, 4), Rgb::ONE);
        assert_eq!(img.pixels.iter().map(|p| p.x).sum::<f32>(), 1.0);
    }

    /// A recorded buffer applied to a film gives the same bits as adding to the film directly.
    #[test]
    fn applied_buffer_equals_direct_accumulation() {
        let mut direct = Accumulator::new(5, 4);
        let mut buffer = SplatBuffer::new(5, 4);
        let mut rng = crate::sampling::Rng::new(3, 0);
        for _ in 0..200 {
            let raster = Vec2::new(rng.uniform() * 6.0 - 0.5, rng.uniform() * 5.0 - 0.5);
            let value = Rgb::new(rng.uniform(), rng.uniform() * 1e-3, rng.uniform() * 1e3);
            assert_eq!(direct.splat(raster, value), buffer.splat(raster, value));
            direct.add(1, 2, value);
            buffer.add(1, 2, value);
        }
        let mut applied = Accumulator::new(5, 4);
        applied.apply(&buffer);
        let bits = |a: &Accumulator| a.sums.iter().flat_map(|s| s.map(f64::to_bits)).collect::<Vec<_>>();
        assert_eq!(bits(&applied), bits(&direct));
        buffer.clear();
        assert!(buffer.is_empty());
    }
}
