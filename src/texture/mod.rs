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

use crate::film::oiio::ReadImage;
use crate::film::tonemap::srgb_eotf;
use crate::spectrum::Rgb;

/// A decoded bitmap: linear RGB, row 0 at the top, every texel in [0, 1].
#[derive(Clone, Debug, PartialEq)]
pub struct TexelImage {
    pub width: usize,
    pub height: usize,
    pub texels: Vec<Rgb>,
}

impl TexelImage {
    /// Converts a read image: one or two channels are grey (a second, alpha, is ignored), three or
    /// more are RGB (a fourth, alpha, is ignored: opacity is its own parameter). `srgb` decodes
    /// the sRGB transfer function. Texels are clamped to [0, 1] (NaN to 0): every colour parameter
    /// is a reflectance or an opacity.
    pub fn from_read(img: &ReadImage, srgb: bool) -> TexelImage {
        let decode = |v: f32| {
            let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
            if srgb {
                srgb_eotf(v)
            } else {
                v
            }
        };
        let texels = img
            .data
            .chunks_exact(img.channels)
            .map(|p| {
                if p.len() >= 3 {
                    Rgb::new(decode(p[0]), decode(p[1]), decode(p[2]))
                } else {
                    Rgb::splat(decode(p[0]))
                }
            })
            .collect();
        TexelImage { width: img.width, height: img.height, texels }
    }

    /// Bytes held by the texels.
    pub fn memory_bytes(&self) -> usize {
        self.texels.len() * std::mem::size_of::<Rgb>()
    }

    #[inline]
    fn texel(&self, i: i64, j: i64) -> Rgb {
        let x = i.rem_euclid(self.width as i64) as usize;
        let y = j.rem_euclid(self.height as i64) as usize;
        self.texels[y * self.width + x]
    }

    /// Bilinear lookup with wrap-around at texture-space point (s, t), t = 0 at the top row.
    pub fn bilinear(&self, s: f32, t: f32) -> Rgb {
        // Reduce to one period first so that large uvs keep their fractional precision.
        let x = f64::from(s).rem_euclid(1.0) * self.width as f64 - 0.5;
        let y = f64::from(t).rem_euclid(1.0) * self.height as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let (i, j) = (x0 as i64, y0 as i64);
        let top = self.texel(i, j) * (1.0 - fx) + self.texel(i + 1, j) * fx;
        let bottom = self.texel(i, j + 1) * (1.0 - fx) + self.texel(i + 1, j + 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// The mean texel (what `info` reports for a textured parameter).
    pub fn mean(&self) -> Rgb {
        let sum: glam::DVec3 = self.texels.iter().map(|t| t.as_dvec3()).sum();
        (sum / self.texels.len().max(1) as f64).as_vec3()
    }
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
    pub fn eval(&self, uv: Vec2) -> Rgb {
        match self {
            Texture::Bitmap { image, uscale, vscale } => {
                let (s, t) = Texture::st(uv, *uscale, *vscale);
                image.bilinear(s, t)
            }
            Texture::Checkerboard { colour0, colour1, uscale, vscale } => {
                let (s, t) = Texture::st(uv, *uscale, *vscale);
                let upper = |x: f32| f64::from(x).rem_euclid(1.0) > 0.5;
                if upper(s) == upper(t) {
                    *colour0
                } else {
                    *colour1
                }
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
