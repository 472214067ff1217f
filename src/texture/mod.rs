//! Textures for colour parameters: bitmaps (read through OpenImageIO, decoded to linear RGB,
//! looked up bilinearly with wrap-around) and the checkerboard. Only scenes that name a texture
//! build any of this; a constant colour never passes through here.
//!
//! # The uv convention (its one home)
//! A mesh's (u, v) are used as OBJ and PLY files store them, v = 0 at the image's bottom. The
//! texture space point is (s, t) = (u · uscale, (1 − v) · vscale), t = 0 at the image's top row:
//! this is Mitsuba's, which flips v when it loads a mesh and then looks up with v = 0 at the top.
//! Texel (i, j) (column i, row j from the top) is centred at ((i + ½)/W, (j + ½)/H); lookups
//! interpolate the four nearest centres bilinearly and wrap around in both directions.

use std::sync::Arc;

use glam::Vec2;

use crate::film::oiio::{ReadImage, ReadPixels};
use crate::film::tonemap::srgb_eotf;
use crate::prefetch::prefetch;
use crate::process::huge_pages::advise_huge_pages;
use crate::spectrum::Rgb;

/// A decoded bitmap: linear RGB, row 0 at the top, every texel in [0, 1].
#[derive(Clone, Debug, PartialEq)]
pub struct TexelImage {
    pub width: usize,
    pub height: usize,
    storage: TexelStorage,
    /// The mean texel, computed once when the image is made: every material the image drives
    /// asks for it (twice at load), and it runs over every texel (3% of the door's load when it
    /// ran each time).
    mean: Rgb,
}

/// How the texels are held. An 8-bit image (every value one of 256 levels, as OpenImageIO hands
/// out a JPEG or PNG) keeps its byte codes and the 256 decoded values they stand for: the same
/// f32 texels as the `Linear` form bit for bit, in a quarter of the memory, so that a lookup's
/// four texels miss the cache less often (the door's three photographs take 30 MB instead of
/// 118 MB).
#[derive(Clone, Debug, PartialEq)]
enum TexelStorage {
    Linear(Vec<Rgb>),
    Coded { codes: Vec<[u8; 3]>, decoded: Box<[f32; 256]> },
}

impl TexelImage {
    /// An image from linear texels, row 0 at the top (`width·height` of them).
    pub fn from_texels(width: usize, height: usize, texels: Vec<Rgb>) -> TexelImage {
        assert_eq!(texels.len(), width * height, "texel count");
        TexelImage::new(width, height, TexelStorage::Linear(texels))
    }

    fn new(width: usize, height: usize, storage: TexelStorage) -> TexelImage {
        let mut image = TexelImage { width, height, storage, mean: Rgb::ZERO };
        let n = width * height;
        let sum: glam::DVec3 = (0..n).map(|k| image.texel(k % width, k / width).as_dvec3()).sum();
        image.mean = (sum / n.max(1) as f64).as_vec3();
        image
    }

    /// Converts a read image: one or two channels are grey (a second, alpha, is ignored), three or
    /// more are RGB (a fourth, alpha, is ignored: opacity is its own parameter). `srgb` decodes
    /// the sRGB transfer function. Texels are clamped to [0, 1] (NaN to 0): every colour parameter
    /// is a reflectance or an opacity.
    pub fn from_read(img: ReadImage, srgb: bool) -> TexelImage {
        let decode = |v: f32| {
            let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
            if srgb {
                srgb_eotf(v)
            } else {
                v
            }
        };
        let (width, height, channels) = (img.width, img.height, img.channels.max(1));
        // One or two channels are grey; three or more RGB (`ReadPixels::Rgb8` reads the same).
        let pixel = |p: &[f32]| if p.len() >= 3 { [p[0], p[1], p[2]] } else { [p[0]; 3] };
        match img.data {
            ReadPixels::Rgb8 { texels, levels } => {
                let decoded = Box::new(levels.map(decode));
                TexelImage::new(width, height, TexelStorage::Coded { codes: texels, decoded })
            }
            ReadPixels::Float(data) => {
                let pixels = data.chunks_exact(channels);
                let count = data.len() / channels;
                if let Some(levels) = eight_bit_levels(&data) {
                    let code = |v: f32| (v * 255.0).round() as u8;
                    let mut codes = Vec::with_capacity(count);
                    advise_huge_pages(&codes);
                    codes.extend(pixels.map(|p| pixel(p).map(code)));
                    let decoded = Box::new(levels.map(decode));
                    return TexelImage::new(width, height, TexelStorage::Coded { codes, decoded });
                }
                let mut texels = Vec::with_capacity(count);
                advise_huge_pages(&texels);
                texels.extend(pixels.map(|p| Rgb::from_array(pixel(p).map(decode))));
                TexelImage::new(width, height, TexelStorage::Linear(texels))
            }
        }
    }

    /// Bytes held by the texels.
    pub fn memory_bytes(&self) -> usize {
        match &self.storage {
            TexelStorage::Linear(t) => t.len() * std::mem::size_of::<Rgb>(),
            TexelStorage::Coded { codes, decoded } => codes.len() * 3 + std::mem::size_of_val(&**decoded),
        }
    }

    /// Whether the texels are held as 8-bit codes.
    pub fn is_coded(&self) -> bool {
        matches!(self.storage, TexelStorage::Coded { .. })
    }

    /// Texel (i, j): column i, row j from the top.
    pub fn texel(&self, i: usize, j: usize) -> Rgb {
        let k = j * self.width + i;
        match &self.storage {
            TexelStorage::Linear(t) => t[k],
            TexelStorage::Coded { codes, decoded } => Rgb::from_array(codes[k].map(|c| decoded[c as usize])),
        }
    }

    /// Bilinear lookup with wrap-around at texture-space point (s, t), t = 0 at the top row.
    pub fn bilinear(&self, s: f32, t: f32) -> Rgb {
        let (i0, i1, fx) = wrapped_neighbours(s, self.width);
        let (j0, j1, fy) = wrapped_neighbours(t, self.height);
        let (row0, row1) = (j0 * self.width, j1 * self.width);
        #[inline(always)]
        fn blend(texel: impl Fn(usize) -> Rgb, [row0, row1, i0, i1]: [usize; 4], fx: f32, fy: f32) -> Rgb {
            let top = texel(row0 + i0) * (1.0 - fx) + texel(row0 + i1) * fx;
            let bottom = texel(row1 + i0) * (1.0 - fx) + texel(row1 + i1) * fx;
            top * (1.0 - fy) + bottom * fy
        }
        let corners = [row0, row1, i0, i1];
        match &self.storage {
            TexelStorage::Linear(t) => blend(|k| t[k], corners, fx, fy),
            TexelStorage::Coded { codes, decoded } => {
                blend(|k| Rgb::from_array(codes[k].map(|c| decoded[c as usize])), corners, fx, fy)
            }
        }
    }

    /// Asks the cache for the four texels `bilinear(s, t)` will read (a hint: no effect on any
    /// value). A lookup at a random hit misses the cache on most of the door's photographs; the
    /// path tracer issues this as soon as the hit's uv is known and traces a shadow ray while the
    /// texels arrive (docs/lab/performance.md).
    #[inline(always)]
    pub fn prefetch(&self, s: f32, t: f32) {
        let (i0, i1, _) = wrapped_neighbours(s, self.width);
        let (j0, j1, _) = wrapped_neighbours(t, self.height);
        let (row0, row1) = (j0 * self.width, j1 * self.width);
        for k in [row0 + i0, row0 + i1, row1 + i0, row1 + i1] {
            match &self.storage {
                TexelStorage::Linear(t) => t.get(k).map(prefetch),
                TexelStorage::Coded { codes, .. } => codes.get(k).map(prefetch),
            };
        }
    }

    /// The mean texel (what `info` reports for a textured parameter).
    pub fn mean(&self) -> Rgb {
        self.mean
    }
}

/// When every value of `data` is one of the 256 levels of an 8-bit image (within 1e-3 of c/255 and
/// the same f32 wherever it stands for the same level c), those values by level (c/255 for a level
/// that does not occur): the image can be held as codes and decoded bit for bit. `None` otherwise
/// (a float image, a 16-bit one).
fn eight_bit_levels(data: &[f32]) -> Option<[f32; 256]> {
    let mut seen: [Option<u32>; 256] = [None; 256];
    for &v in data {
        if !(0.0..=1.0).contains(&v) {
            return None;
        }
        let level = (v * 255.0).round();
        if (v * 255.0 - level).abs() > 1e-3 {
            return None;
        }
        match &mut seen[level as usize] {
            Some(bits) if *bits != v.to_bits() => return None,
            slot => *slot = Some(v.to_bits()),
        }
    }
    Some(std::array::from_fn(|c| seen[c].map_or(c as f32 / 255.0, f32::from_bits)))
}

/// s − ⌊s⌋ in [0, 1], bit for bit `s.rem_euclid(1.0)` up to the sign of a zero (NaN for an
/// infinite or NaN s), without the `fmod` and `floor` library calls (this build targets baseline
/// x86-64, which has no rounding instruction). For |s| < 2⁵² both are one rounding of the same exact
/// value: `rem_euclid` takes the exact s − trunc(s) and, when it is negative, rounds its sum with 1;
/// here ⌊s⌋ is exact (truncation, stepped down for a negative non-integer) and s − ⌊s⌋ is rounded
/// once. Beyond 2⁵² every f64 is an integer and the fraction is 0 (NaN for ±∞, as `fmod` gives).
#[inline]
fn fraction(s: f64) -> f64 {
    const TWO_POW_52: f64 = 4_503_599_627_370_496.0;
    if !(s.abs() < TWO_POW_52) {
        return if s.is_finite() { 0.0 } else { f64::NAN };
    }
    let truncated = s as i64 as f64;
    let floor = if truncated > s { truncated - 1.0 } else { truncated };
    s - floor
}

/// The two texel indices (of `n` along one axis) whose centres bracket texture coordinate `s`,
/// wrapped around, and the weight of the second: the one-axis half of `TexelImage::bilinear`.
/// The coordinate is reduced to one period first so that large uvs keep their fractional precision;
/// the arithmetic is the reference's (`tests::bilinear_reference`), the wrap is two selects
/// instead of two integer divisions.
#[inline]
fn wrapped_neighbours(s: f32, n: usize) -> (usize, usize, f32) {
    let x = fraction(f64::from(s)) * n as f64 - 0.5;
    // x ∈ [−0.5, n − 0.5] (or NaN, which casts to 0), so ⌊x⌋ ∈ [−1, n − 1]: truncation, stepped
    // down below 0.
    let truncated = x as i64;
    let floor = if truncated as f64 > x { truncated - 1 } else { truncated };
    let weight = (x - floor as f64) as f32;
    let first = if floor < 0 { n - 1 } else { floor as usize };
    let second = if first + 1 >= n { 0 } else { first + 1 };
    (first, second, weight)
}

/// A colour-valued texture.
#[derive(Clone, Debug, PartialEq)]
pub enum Texture {
    /// A bitmap, shared by every parameter that names the same file with the same decoding.
    Bitmap { image: Arc<TexelImage>, uscale: f32, vscale: f32 },
    /// `colour0` where ⌊2s⌋ and ⌊2t⌋ have the same parity, `colour1` elsewhere (Mitsuba's
    /// checkerboard: its two halves of each unit square per axis).
    Checkerboard { colour0: Rgb, colour1: Rgb, uscale: f32, vscale: f32 },
}

impl Texture {
    /// Texture-space point of the surface uv (see the module doc).
    #[inline]
    fn st(uv: Vec2, uscale: f32, vscale: f32) -> (f32, f32) {
        (uv.x * uscale, (1.0 - uv.y) * vscale)
    }

    /// The colour at surface coordinates `uv`.
    #[inline(always)]
    pub fn eval(&self, uv: Vec2) -> Rgb {
        match self {
            Texture::Bitmap { image, uscale, vscale } => {
                let (s, t) = Texture::st(uv, *uscale, *vscale);
                image.bilinear(s, t)
            }
            Texture::Checkerboard { colour0, colour1, .. } => {
                if self.checker_square(uv) == 0 {
                    *colour0
                } else {
                    *colour1
                }
            }
        }
    }

    /// Asks the cache for the texels `eval(uv)` will read (bitmaps; a checkerboard reads none).
    #[inline(always)]
    pub fn prefetch(&self, uv: Vec2) {
        if let Texture::Bitmap { image, uscale, vscale } = self {
            let (s, t) = Texture::st(uv, *uscale, *vscale);
            image.prefetch(s, t);
        }
    }

    /// Whether lookups read texels from memory (a bitmap), not only arithmetic (a checkerboard).
    pub fn reads_texels(&self) -> bool {
        matches!(self, Texture::Bitmap { .. })
    }

    /// For a checkerboard, which of its two colours covers `uv` (0 for `colour0`, 1 for
    /// `colour1`); 0 for a bitmap.
    #[inline]
    pub fn checker_square(&self, uv: Vec2) -> usize {
        match self {
            Texture::Bitmap { .. } => 0,
            Texture::Checkerboard { uscale, vscale, .. } => {
                let (s, t) = Texture::st(uv, *uscale, *vscale);
                let upper = |x: f32| fraction(f64::from(x)) > 0.5;
                usize::from(upper(s) != upper(t))
            }
        }
    }

    /// The mean colour over one period.
    pub fn mean(&self) -> Rgb {
        match self {
            Texture::Bitmap { image, .. } => image.mean(),
            Texture::Checkerboard { colour0, colour1, .. } => (*colour0 + *colour1) * 0.5,
        }
    }

    /// The bitmap behind this texture, if any (for memory accounting of shared images).
    pub fn image(&self) -> Option<&Arc<TexelImage>> {
        match self {
            Texture::Bitmap { image, .. } => Some(image),
            Texture::Checkerboard { .. } => None,
        }
    }
}

#[cfg(test)]
mod tests;
