//! The `[materials]` tables: BSDF parameters, textures (bitmap files read once per file and
//! decoding, shared by every parameter that names them), two-sidedness and opacity.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;

use super::Builder;
use crate::material::{ColourSlot, Material, Opacity, Plastic, SurfaceMaterial};
use crate::scene::desc::{ColourParam, MaterialDesc, TextureDesc};
use crate::scene::SceneError;
use crate::spectrum::{luminance, Rgb};
use crate::texture::{TexelImage, Texture};

/// Images already read during this load, by (path, sRGB decoding).
type ImageCache = BTreeMap<(PathBuf, bool), Arc<TexelImage>>;

/// Roughness of a dielectric that gives none: smooth (the delta-lobe `Dielectric`).
const DIELECTRIC_DEFAULT_ROUGHNESS: f32 = 0.0;

impl Builder<'_> {
    pub(super) fn materials(
        &self,
        descs: &BTreeMap<String, MaterialDesc>,
    ) -> Result<(Vec<SurfaceMaterial>, BTreeMap<String, u32>), SceneError> {
        let mut materials = Vec::with_capacity(descs.len());
        let mut index = BTreeMap::new();
        let mut cache = ImageCache::new();
        for (name, d) in descs {
            index.insert(name.clone(), materials.len() as u32);
            materials.push(self.material(name, d, &mut cache)?);
        }
        Ok((materials, index))
    }

    fn material(&self, name: &str, d: &MaterialDesc, cache: &mut ImageCache) -> Result<SurfaceMaterial, SceneError> {
        let key = |k: &str| format!("materials.{name}.{k}");
        let allowed: &[&str] = match d.kind.as_str() {
            "diffuse" | "mirror" => &["reflectance", "two_sided", "opacity"],
            "dielectric" => &["ior", "roughness", "opacity"],
            "conductor" => &["roughness", "eta", "k", "colour", "two_sided", "opacity"],
            "plastic" => &["diffuse", "specular", "roughness", "ior", "nonlinear", "two_sided", "opacity"],
            other => {
                return Err(self.err(
                    key("type"),
                    format!("expected one of: diffuse, mirror, dielectric, conductor, plastic, got '{other}'"),
                ))
            }
        };
        for k in d.present_keys() {
            if k == "two_sided" && d.kind == "dielectric" {
                return Err(self.err(
                    key("two_sided"),
                    "a dielectric cannot be two-sided: its two sides are different media (Mitsuba refuses \
                     'twosided' around a transmissive BSDF too)",
                ));
            }
            if !allowed.contains(&k) {
                return Err(self.err(
                    format!("materials.{name}"),
                    format!("key '{k}' does not apply to type '{}' (expected: type, {})", d.kind, allowed.join(", ")),
                ));
            }
        }
        // Colour parameters: the constant (or the default) now, the texture bound below.
        let mut textures: Vec<(ColourSlot, Texture)> = Vec::new();
        let mut colour =
            |slot: ColourSlot, k: &str, p: &Option<ColourParam>, default: f32| -> Result<Rgb, SceneError> {
                match p {
                    None => Ok(Rgb::splat(default)),
                    Some(ColourParam::Constant(c)) => self.reflectance(&key(k), Some(*c), default),
                    Some(ColourParam::Texture(t)) => {
                        let tex = self.texture(&key(k), t, cache)?;
                        let mean = tex.mean();
                        textures.push((slot, tex));
                        Ok(mean)
                    }
                }
            };
        let template = match d.kind.as_str() {
            "diffuse" => {
                Material::Diffuse { reflectance: colour(ColourSlot::Reflectance, "reflectance", &d.reflectance, 0.5)? }
            }
            "mirror" => {
                Material::Mirror { reflectance: colour(ColourSlot::Reflectance, "reflectance", &d.reflectance, 1.0)? }
            }
            "dielectric" => {
                let ior = self.ior(&key("ior"), d.ior)?;
                let alpha =
                    self.roughness(&key("roughness"), Some(d.roughness.unwrap_or(DIELECTRIC_DEFAULT_ROUGHNESS)))?;
                if alpha > 0.0 {
                    Material::RoughDielectric { alpha, ior }
                } else {
                    Material::Dielectric { ior }
                }
            }
            "conductor" => {
                let alpha = self.roughness(&key("roughness"), d.roughness)?;
                match (&d.colour, d.eta, d.k) {
                    (Some(_), None, None) => {
                        Material::conductor_from_colour(alpha, colour(ColourSlot::Colour, "colour", &d.colour, 0.0)?)
                    }
                    (None, Some(eta), Some(k)) => {
                        let eta = self.color(&key("eta"), eta, "every component > 0", |v| v > 0.0)?;
                        let k = self.color(&key("k"), k, "every component ≥ 0", |v| v >= 0.0)?;
                        Material::RoughConductor { alpha, eta, k }
                    }
                    _ => {
                        return Err(self.err(
                            format!("materials.{name}"),
                            "a conductor needs either 'colour' or both 'eta' and 'k' (and not both forms)",
                        ))
                    }
                }
            }
            "plastic" => {
                let ior = self.ior(&key("ior"), d.ior)?;
                if ior < 1.0 {
                    return Err(self.err(key("ior"), format!("expected a coating index ≥ 1, got {ior}")));
                }
                let diffuse = colour(ColourSlot::Diffuse, "diffuse", &d.diffuse, 0.5)?;
                let specular = colour(ColourSlot::Specular, "specular", &d.specular, 1.0)?;
                let alpha = self.roughness(&key("roughness"), d.roughness)?;
                Material::RoughPlastic {
                    alpha,
                    plastic: Plastic::new(diffuse, specular, ior, d.nonlinear.unwrap_or(false)).with_roughness(alpha),
                }
            }
            _ => unreachable!("material type checked above"),
        };
        let mut m = SurfaceMaterial::new(template, d.two_sided.unwrap_or(false));
        for (slot, tex) in textures {
            m = m.with_texture(slot, tex);
        }
        match &d.opacity {
            None => {}
            Some(ColourParam::Constant(c)) => {
                let c = self.reflectance(&key("opacity"), Some(*c), 1.0)?;
                m = m.with_opacity(Opacity::Constant(luminance(c).clamp(0.0, 1.0)));
            }
            Some(ColourParam::Texture(t)) => {
                m = m.with_opacity(Opacity::Texture(self.texture(&key("opacity"), t, cache)?))
            }
        }
        Ok(m)
    }

    /// A texture table (see docs/scene-format.md).
    fn texture(&self, key: &str, t: &TextureDesc, cache: &mut ImageCache) -> Result<Texture, SceneError> {
        let scale = |k: &str, v: Option<f32>| -> Result<f32, SceneError> {
            match v {
                None => Ok(1.0),
                Some(s) if s.is_finite() && s != 0.0 => Ok(s),
                Some(s) => Err(self.err(format!("{key}.{k}"), format!("expected a finite, non-zero number, got {s}"))),
            }
        };
        let (uscale, vscale) = (scale("uscale", t.uscale)?, scale("vscale", t.vscale)?);
        let refuse = |k: &str, present: bool| -> Result<(), SceneError> {
            if present {
                Err(self.err(key, format!("key '{k}' does not apply to texture '{}'", t.texture)))
            } else {
                Ok(())
            }
        };
        match t.texture.as_str() {
            "bitmap" => {
                refuse("colour0", t.colour0.is_some())?;
                refuse("colour1", t.colour1.is_some())?;
                let file = t
                    .file
                    .as_deref()
                    .ok_or_else(|| self.err(key, "a 'bitmap' texture needs 'file' (an image OpenImageIO reads)"))?;
                let path = self.base_dir.join(file);
                let read =
                    crate::film::oiio::read_image(&path).map_err(|e| self.err(format!("{key}.file"), e.to_string()))?;
                // An explicit `srgb` wins; then what the file says; then 8-bit (integer) data is
                // sRGB-encoded and float data linear.
                let srgb = t.srgb.or(read.srgb).unwrap_or(!read.is_float);
                let image =
                    cache.entry((path, srgb)).or_insert_with(|| Arc::new(TexelImage::from_read(read, srgb))).clone();
                Ok(Texture::Bitmap { image, uscale, vscale })
            }
            "checkerboard" => {
                refuse("file", t.file.is_some())?;
                refuse("srgb", t.srgb.is_some())?;
                // Mitsuba's defaults.
                let colour0 = self.reflectance(&format!("{key}.colour0"), t.colour0, 0.4)?;
                let colour1 = self.reflectance(&format!("{key}.colour1"), t.colour1, 0.2)?;
                Ok(Texture::Checkerboard { colour0, colour1, uscale, vscale })
            }
            other => {
                Err(self.err(format!("{key}.texture"), format!("expected one of: bitmap, checkerboard, got '{other}'")))
            }
        }
    }
}

impl Builder<'_> {
    /// `[environment] type = "sunsky" | "sun" | "sky"` (see `crate::light::sunsky`).
    pub(super) fn sunsky(
        &self,
        env: &crate::scene::desc::EnvironmentDesc,
        bounds: &crate::geometry::Aabb,
    ) -> Result<crate::light::Light, SceneError> {
        use crate::light::sunsky::{bake, world_to_sky, SunSky, SunSkyParts};
        let parts = match env.kind.as_str() {
            "sun" => SunSkyParts::Sun,
            "sky" => SunSkyParts::Sky,
            _ => SunSkyParts::Both,
        };
        // A finite, non-zero direction, normalised (scaled by its largest component first, so
        // that no finite input overflows the length).
        let unit = |d: [f32; 3]| {
            let v = glam::Vec3::from(d);
            let m = v.abs().max_element();
            (v.is_finite() && m > 0.0).then(|| (v / m).normalize())
        };
        let show = |d: [f32; 3]| format!("[{}, {}, {}]", d[0], d[1], d[2]);
        let up_desc = env.up.unwrap_or([0.0, 1.0, 0.0]);
        let up = unit(up_desc).ok_or_else(|| {
            self.err(
                "environment.up",
                format!("expected a finite, non-zero direction (the zenith), got {}", show(up_desc)),
            )
        })?;
        // The model is y-up: bake in the frame where `up` is +y, then compose that rotation into
        // the map's world-to-map rotation.
        let to_sky = world_to_sky(up);
        let d = env.sun_direction.ok_or_else(|| {
            self.err(
                "environment",
                format!("a '{}' environment needs 'sun_direction' ([x, y, z], towards the sun)", env.kind),
            )
        })?;
        let sun = unit(d).map(|s| (to_sky * s).normalize()).filter(|s| s.y > 0.0).ok_or_else(|| {
            self.err(
                "environment.sun_direction",
                format!(
                    "expected a finite direction above the horizon (sun_direction · up > 0, up = {}), got {}",
                    show(up_desc),
                    show(d)
                ),
            )
        })?;
        let number = |k: &str, v: Option<f32>, default: f32, lo: f32, hi: f32| -> Result<f32, SceneError> {
            let x = v.unwrap_or(default);
            if x.is_finite() && (lo..=hi).contains(&x) {
                Ok(x)
            } else {
                Err(self.err(format!("environment.{k}"), format!("expected a number in [{lo}, {hi}], got {x}")))
            }
        };
        let p = SunSky {
            parts,
            sun_direction: sun,
            // Preetham's fit covers turbidity 2 to 10.
            turbidity: number("turbidity", env.turbidity, 3.0, 2.0, 10.0)?,
            albedo: number("albedo", env.albedo, 0.15, 0.0, 1.0)?,
            sun_scale: number("sun_scale", env.sun_scale, 1.0, 0.0, f32::MAX)?,
            sky_scale: number("sky_scale", env.sky_scale, 1.0, 0.0, f32::MAX)?,
        };
        let map = bake(&p).in_world(to_sky);
        Ok(crate::light::Light::ImageEnvironment(crate::light::ImageEnvironment::new(
            map.width,
            map.height,
            map.texels,
            1.0,
            map.to_local,
            *bounds,
        )))
    }
}
