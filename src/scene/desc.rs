//! The TOML schema of a scene file, as serde structs. Every table rejects unknown keys; ranges and
//! combinations are checked afterwards in `load`, where the key path of each value is known.
//!
//! Tables whose keys depend on a `type` (materials, shapes, environment) are flat structs with
//! every key optional, so that a key belonging to another type gets a precise message ("key 'ior'
//! does not apply to type 'diffuse'") instead of serde's generic one for tagged enums, and so that
//! toml's error spans (line numbers) survive deserialisation.

use std::collections::BTreeMap;
use std::fmt;

use serde::de::{self, Deserializer, MapAccess, SeqAccess, Visitor};
use serde::Deserialize;

use crate::accel::AccelKind;

/// A whole scene file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDesc {
    pub camera: CameraDesc,
    #[serde(default)]
    pub materials: BTreeMap<String, MaterialDesc>,
    #[serde(default)]
    pub shapes: Vec<ShapeDesc>,
    pub environment: Option<EnvironmentDesc>,
    #[serde(default)]
    pub portals: Vec<PortalDesc>,
    /// `type` plus free parameters, checked later by the integrator's own settings.
    pub integrator: Option<toml::Table>,
    pub render: Option<RenderSettingsDesc>,
}

/// `[camera]`: a pinhole.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDesc {
    pub position: [f32; 3],
    pub look_at: [f32; 3],
    #[serde(default = "default_up")]
    pub up: [f32; 3],
    /// Vertical field of view, degrees.
    pub fov: f32,
    /// `[width, height]`; signed so that a negative value gets a range message, not a type error.
    pub resolution: [i64; 2],
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

/// `[materials.NAME]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialDesc {
    #[serde(rename = "type")]
    pub kind: String,
    pub reflectance: Option<ColourParam>,
    pub ior: Option<f32>,
    pub roughness: Option<f32>,
    pub eta: Option<ColorDesc>,
    pub k: Option<ColorDesc>,
    #[serde(alias = "color")]
    pub colour: Option<ColourParam>,
    pub diffuse: Option<ColourParam>,
    /// Plastic: the coating's tint (Mitsuba's specularReflectance).
    pub specular: Option<ColourParam>,
    /// Plastic: Mitsuba's `nonlinear` base model.
    pub nonlinear: Option<bool>,
    /// The back side behaves as the front (Mitsuba's `twosided`).
    pub two_sided: Option<bool>,
    /// 1 opaque (default) … 0 invisible (Mitsuba's `mask`).
    pub opacity: Option<ColourParam>,
}

impl MaterialDesc {
    /// The keys present besides `type`, for "does not apply to this type" checks.
    pub fn present_keys(&self) -> Vec<&'static str> {
        let mut keys = Vec::new();
        let mut push = |present: bool, k: &'static str| {
            if present {
                keys.push(k)
            }
        };
        push(self.reflectance.is_some(), "reflectance");
        push(self.ior.is_some(), "ior");
        push(self.roughness.is_some(), "roughness");
        push(self.eta.is_some(), "eta");
        push(self.k.is_some(), "k");
        push(self.colour.is_some(), "colour");
        push(self.diffuse.is_some(), "diffuse");
        push(self.specular.is_some(), "specular");
        push(self.nonlinear.is_some(), "nonlinear");
        push(self.two_sided.is_some(), "two_sided");
        push(self.opacity.is_some(), "opacity");
        keys
    }
}

/// A colour parameter: a number, `[r, g, b]`, or a texture table.
#[derive(Debug, Clone)]
pub enum ColourParam {
    Constant(ColorDesc),
    Texture(TextureDesc),
}

/// `{ texture = "bitmap", file = "...", uscale, vscale, srgb }` or
/// `{ texture = "checkerboard", colour0, colour1, uscale, vscale }`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TextureDesc {
    pub texture: String,
    pub file: Option<String>,
    pub uscale: Option<f32>,
    pub vscale: Option<f32>,
    pub srgb: Option<bool>,
    #[serde(alias = "color0")]
    pub colour0: Option<ColorDesc>,
    #[serde(alias = "color1")]
    pub colour1: Option<ColorDesc>,
}

impl<'de> Deserialize<'de> for ColourParam {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        const EXPECTING: &str =
            "a number, [r, g, b] or a texture table { texture = \"bitmap\" | \"checkerboard\", ... }";
        impl<'de> Visitor<'de> for V {
            type Value = ColourParam;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str(EXPECTING)
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<ColourParam, E> {
                Triple(EXPECTING).visit_f64(v).map(|c| ColourParam::Constant(ColorDesc(c)))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<ColourParam, E> {
                Triple(EXPECTING).visit_i64(v).map(|c| ColourParam::Constant(ColorDesc(c)))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<ColourParam, E> {
                Triple(EXPECTING).visit_u64(v).map(|c| ColourParam::Constant(ColorDesc(c)))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, seq: A) -> Result<ColourParam, A::Error> {
                Triple(EXPECTING).visit_seq(seq).map(|c| ColourParam::Constant(ColorDesc(c)))
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<ColourParam, A::Error> {
                TextureDesc::deserialize(de::value::MapAccessDeserializer::new(map)).map(ColourParam::Texture)
            }
        }
        d.deserialize_any(V)
    }
}

/// One `[[shapes]]` entry.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShapeDesc {
    #[serde(rename = "type")]
    pub kind: String,
    /// Mesh file for `obj` and `ply`, relative to the scene file.
    pub file: Option<String>,
    pub material: String,
    pub emission: Option<EmissionDesc>,
    pub transform: Option<TransformDesc>,
    /// Tessellation of `disk` (segments) and `sphere` (rings; twice as many segments).
    pub subdivisions: Option<i64>,
    /// Ignore the file's vertex normals and shade with the flat triangle normal.
    pub face_normals: Option<bool>,
    /// Turn the surface inside out (e.g. to light the inside of a sphere with one-sided emission).
    pub flip_normals: Option<bool>,
}

/// `emission = { radiance = [r, g, b], scale = 1.0, two_sided = false }`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EmissionDesc {
    pub radiance: ColorDesc,
    #[serde(default = "one")]
    pub scale: f32,
    #[serde(default)]
    pub two_sided: bool,
}

fn one() -> f32 {
    1.0
}

/// `transform = { translate, rotate, scale }` (applied scale, then rotations in order, then
/// translation) or `transform = { matrix = [[..4..] ×4] }` (rows, column vectors).
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransformDesc {
    pub translate: Option<[f32; 3]>,
    pub rotate: Option<Rotations>,
    pub scale: Option<ScaleDesc>,
    pub matrix: Option<[[f32; 4]; 4]>,
}

/// `{ axis = [x, y, z], angle = degrees }`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RotateDesc {
    pub axis: [f32; 3],
    pub angle: f32,
}

/// One rotation or a list of them, applied in order.
#[derive(Debug, Clone)]
pub struct Rotations(pub Vec<RotateDesc>);

impl<'de> Deserialize<'de> for Rotations {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Rotations;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("{ axis = [x, y, z], angle = degrees } or a list of them")
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<Rotations, A::Error> {
                let r = RotateDesc::deserialize(de::value::MapAccessDeserializer::new(map))?;
                Ok(Rotations(vec![r]))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Rotations, A::Error> {
                let mut out = Vec::new();
                while let Some(r) = seq.next_element::<RotateDesc>()? {
                    out.push(r);
                }
                Ok(Rotations(out))
            }
        }
        d.deserialize_any(V)
    }
}

/// `scale = s` (uniform) or `scale = [x, y, z]`.
#[derive(Debug, Clone, Copy)]
pub struct ScaleDesc(pub [f32; 3]);

impl<'de> Deserialize<'de> for ScaleDesc {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let c = Triple::deserialize(d, "a number or [x, y, z]")?;
        Ok(ScaleDesc(c))
    }
}

/// An RGB colour: `[r, g, b]`, or one number for grey.
#[derive(Debug, Clone, Copy)]
pub struct ColorDesc(pub [f32; 3]);

impl<'de> Deserialize<'de> for ColorDesc {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let c = Triple::deserialize(d, "a number or [r, g, b]")?;
        Ok(ColorDesc(c))
    }
}

/// A number or a list of exactly three numbers.
struct Triple(&'static str);

impl Triple {
    fn deserialize<'de, D: Deserializer<'de>>(d: D, expecting: &'static str) -> Result<[f32; 3], D::Error> {
        d.deserialize_any(Triple(expecting))
    }
}

impl<'de> Visitor<'de> for Triple {
    type Value = [f32; 3];
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str(self.0)
    }
    fn visit_f64<E: de::Error>(self, v: f64) -> Result<[f32; 3], E> {
        Ok([v as f32; 3])
    }
    fn visit_i64<E: de::Error>(self, v: i64) -> Result<[f32; 3], E> {
        Ok([v as f32; 3])
    }
    fn visit_u64<E: de::Error>(self, v: u64) -> Result<[f32; 3], E> {
        Ok([v as f32; 3])
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<[f32; 3], A::Error> {
        let mut out = [0.0f32; 3];
        for (i, slot) in out.iter_mut().enumerate() {
            *slot = seq.next_element::<f32>()?.ok_or_else(|| de::Error::invalid_length(i, &self))?;
        }
        if seq.next_element::<de::IgnoredAny>()?.is_some() {
            return Err(de::Error::invalid_length(4, &self));
        }
        Ok(out)
    }
}

/// `[environment]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentDesc {
    #[serde(rename = "type")]
    pub kind: String,
    /// `constant`: the radiance from every direction.
    pub radiance: Option<ColorDesc>,
    /// `image`: an equirectangular EXR, relative to the scene file.
    pub file: Option<String>,
    pub scale: Option<f32>,
    pub rotate: Option<Rotations>,
    /// `sunsky`, `sun`, `sky`: direction towards the sun (world space).
    pub sun_direction: Option<[f32; 3]>,
    /// `sunsky`, `sun`, `sky`: the sky's zenith in world space (default +y).
    pub up: Option<[f32; 3]>,
    pub turbidity: Option<f32>,
    /// Ground albedo (below the horizon).
    pub albedo: Option<f32>,
    pub sun_scale: Option<f32>,
    pub sky_scale: Option<f32>,
}

/// One `[[portals]]` entry: `corner`, `edge_u`, `edge_v`, or a unit quad placed by `transform`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PortalDesc {
    pub corner: Option<[f32; 3]>,
    pub edge_u: Option<[f32; 3]>,
    pub edge_v: Option<[f32; 3]>,
    pub transform: Option<TransformDesc>,
}

/// `[render]`.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderSettingsDesc {
    pub spp: Option<i64>,
    pub time: Option<f64>,
    pub seed: Option<i64>,
    pub threads: Option<i64>,
    pub accel: Option<AccelKind>,
    #[serde(default)]
    pub output: Vec<String>,
}
