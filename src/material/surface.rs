//! The material of a shape as the scene gives it: a BSDF template, the colour parameters that
//! come from textures, two-sidedness and opacity. `bsdf_at` looks the textures up at a surface
//! point; a material without textures hands out its template unchanged (no lookup, no texture
//! machinery), and one without `opacity` is opaque without evaluating anything.

use glam::Vec2;

use super::{Bsdf, Material};
use crate::spectrum::{luminance, Rgb};
use crate::texture::Texture;

/// A colour parameter a texture can drive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColourSlot {
    /// `reflectance` of diffuse and mirror.
    Reflectance,
    /// `colour` of a conductor (its normal-incidence reflectance and edge tint).
    Colour,
    /// `diffuse` of plastic.
    Diffuse,
    /// `specular` of plastic.
    Specular,
}

/// Opacity of a surface (Mitsuba's `mask`): 1 opaque, 0 invisible.
#[derive(Clone, Debug, PartialEq)]
pub enum Opacity {
    Constant(f32),
    /// A texture's luminance (Mitsuba evaluates a mask's colour texture as one channel).
    Texture(Texture),
}

/// See the module doc.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceMaterial {
    /// The BSDF with every constant parameter; a textured parameter holds the texture's mean
    /// (what reports show), replaced at each lookup.
    pub template: Material,
    pub two_sided: bool,
    textures: Vec<(ColourSlot, Texture)>,
    /// When the only texture is a checkerboard: the material on each of its two squares, made
    /// once (a conductor's colour turned into η and k, a plastic's coating rebuilt), so that
    /// `bsdf_at` only picks one. The same values `set_slot` gives at every lookup.
    checker_materials: Option<[Material; 2]>,
    opacity: Option<Opacity>,
}

impl SurfaceMaterial {
    /// An untextured, opaque material.
    pub fn new(template: Material, two_sided: bool) -> SurfaceMaterial {
        SurfaceMaterial { template, two_sided, textures: Vec::new(), checker_materials: None, opacity: None }
    }

    /// Drives `slot` with `texture` (the template's value there becomes the texture's mean).
    pub fn with_texture(mut self, slot: ColourSlot, texture: Texture) -> SurfaceMaterial {
        self.template = set_slot(self.template, slot, texture.mean());
        self.textures.push((slot, texture));
        self.checker_materials = match self.textures.as_slice() {
            [(slot, Texture::Checkerboard { colour0, colour1, .. })] => {
                Some([set_slot(self.template, *slot, *colour0), set_slot(self.template, *slot, *colour1)])
            }
            _ => None,
        };
        self
    }

    /// Sets the opacity; a constant 1 is stored as "opaque" (nothing to evaluate).
    pub fn with_opacity(mut self, opacity: Opacity) -> SurfaceMaterial {
        self.opacity = match opacity {
            Opacity::Constant(a) if a >= 1.0 => None,
            o => Some(o),
        };
        self
    }

    /// The textures this material looks up (colour slots, then opacity).
    pub fn textures(&self) -> impl Iterator<Item = &Texture> {
        let opacity = match &self.opacity {
            Some(Opacity::Texture(t)) => Some(t),
            _ => None,
        };
        self.textures.iter().map(|(_, t)| t).chain(opacity)
    }

    /// Whether any colour parameter is textured.
    pub fn is_textured(&self) -> bool {
        !self.textures.is_empty()
    }

    /// Whether the surface can let rays through.
    pub fn is_masked(&self) -> bool {
        self.opacity.is_some()
    }

    /// The BSDF at surface coordinates `uv`.
    #[inline(always)]
    pub fn bsdf_at(&self, uv: Vec2) -> Bsdf {
        if self.textures.is_empty() {
            return Bsdf { material: self.template, two_sided: self.two_sided };
        }
        if let (Some(materials), [(_, checker)]) = (&self.checker_materials, self.textures.as_slice()) {
            return Bsdf { material: materials[checker.checker_square(uv)], two_sided: self.two_sided };
        }
        let mut m = self.template;
        for (slot, tex) in &self.textures {
            m = set_slot(m, *slot, tex.eval(uv));
        }
        Bsdf { material: m, two_sided: self.two_sided }
    }

    /// Whether `bsdf_at` reads bitmap texels (a colour parameter bound to an image).
    pub fn reads_texels(&self) -> bool {
        self.textures.iter().any(|(_, t)| t.reads_texels())
    }

    /// Asks the cache for the texels `bsdf_at(uv)` will read (a hint).
    #[inline(always)]
    pub fn prefetch_texels(&self, uv: Vec2) {
        for (_, tex) in &self.textures {
            tex.prefetch(uv);
        }
    }

    /// Opacity in [0, 1] at `uv` (1 for an unmasked material).
    #[inline]
    pub fn opacity_at(&self, uv: Vec2) -> f32 {
        match &self.opacity {
            None => 1.0,
            Some(Opacity::Constant(a)) => *a,
            Some(Opacity::Texture(t)) => luminance(t.eval(uv)).clamp(0.0, 1.0),
        }
    }

    pub fn is_specular(&self) -> bool {
        self.template.is_specular()
    }
}

/// `m` with its colour parameter `slot` set to `c` (a slot the material does not have is left
/// alone; the loader only binds slots a material has).
fn set_slot(m: Material, slot: ColourSlot, c: Rgb) -> Material {
    match (m, slot) {
        (Material::Diffuse { .. }, ColourSlot::Reflectance) => Material::Diffuse { reflectance: c },
        (Material::Mirror { .. }, ColourSlot::Reflectance) => Material::Mirror { reflectance: c },
        (Material::RoughConductor { alpha, .. }, ColourSlot::Colour) => Material::conductor_from_colour(alpha, c),
        (Material::RoughPlastic { alpha, plastic }, ColourSlot::Diffuse) => {
            Material::RoughPlastic { alpha, plastic: plastic.with_colours(c, plastic.specular) }
        }
        (Material::RoughPlastic { alpha, plastic }, ColourSlot::Specular) => {
            Material::RoughPlastic { alpha, plastic: plastic.with_colours(plastic.diffuse, c) }
        }
        (m, _) => m,
    }
}
