//! Mitsuba BSDFs and textures as `[materials.NAME]` tables.
//!
//! Wrappers become keys of the material they wrap: `twosided` → `two_sided = true`, `mask` →
//! `opacity`; `bumpmap`/`normalmap` keep their nested BSDF (with a warning). The leaf BSDFs map to
//! plexus's models: `diffuse`; `dielectric`/`roughdielectric` (`roughness` = GGX α);
//! `conductor`/`roughconductor` (η and k, named presets turned into numbers, `none` a mirror);
//! `plastic`/`roughplastic` (`diffuse`, `specular`, `nonlinear`). Everything else goes to the
//! nearest of them with a warning that says which.

use std::collections::HashMap;
use std::rc::Rc;

use super::colour::{self, conductor_f0, conductor_preset, named_ior};
use super::objects::{Obj, Objects, Value};
use super::toml_out::{Section, TVal};
use super::xml::Loc;
use super::{relative_path, ImportError, Warnings};

/// Mitsuba's default interior and exterior indices (its dielectric's bk7 and air).
const DEFAULT_INT_IOR: f64 = 1.5046;
const DEFAULT_EXT_IOR: f64 = 1.000277;
/// roughplastic's and the plastic family's default interior index (polypropylene).
const PLASTIC_INT_IOR: f64 = 1.49;

pub struct Materials<'a> {
    pub objects: &'a Objects,
    pub toml_dir: &'a std::path::Path,
    pub sections: Vec<Section>,
    names: HashMap<*const Obj, String>,
    taken: HashMap<String, usize>,
    /// Mitsuba 3 (version 3.x): a `conductor` without `material`, `eta` or `k` is its perfect
    /// mirror ("none"), where Mitsuba 0.5/0.6 default to copper.
    pub mitsuba3: bool,
}

impl<'a> Materials<'a> {
    pub fn new(objects: &'a Objects, toml_dir: &'a std::path::Path) -> Materials<'a> {
        Materials {
            objects,
            toml_dir,
            sections: Vec::new(),
            names: HashMap::new(),
            taken: HashMap::new(),
            mitsuba3: false,
        }
    }

    /// The material name for `obj`, converting it on first use.
    pub fn material(&mut self, obj: &Rc<Obj>, w: &mut Warnings) -> Result<String, ImportError> {
        if let Some(n) = self.names.get(&Rc::as_ptr(obj)) {
            return Ok(n.clone());
        }
        let base = obj.id.clone().unwrap_or_else(|| format!("{}_line{}", obj.plugin, obj.loc.line));
        let name = self.unique(&base);
        let mut sec = Section::new(format!("materials.{}", super::toml_out::key(&name)));
        sec.comments.push(format!("{} at {}", obj.describe(), obj.loc));
        self.bsdf(obj, &mut sec, w)?;
        self.names.insert(Rc::as_ptr(obj), name.clone());
        self.sections.push(sec);
        Ok(name)
    }

    /// The material of shapes without a BSDF: Mitsuba's default, diffuse 0.5.
    pub fn default_material(&mut self) -> String {
        let name = "mitsuba_default".to_string();
        if !self.taken.contains_key(&name) {
            self.taken.insert(name.clone(), 1);
            let mut sec = Section::new(format!("materials.{name}"));
            sec.comments.push("shapes without a BSDF: Mitsuba's default, diffuse with reflectance 0.5".into());
            sec.set("type", TVal::str("diffuse"));
            sec.set("reflectance", TVal::Num(0.5));
            self.sections.push(sec);
        }
        name
    }

    fn unique(&mut self, base: &str) -> String {
        let n = self.taken.entry(base.to_string()).or_insert(0);
        *n += 1;
        if *n == 1 {
            base.to_string()
        } else {
            format!("{base}_{n}")
        }
    }

    fn nested(&self, obj: &Obj, w: &mut Warnings) -> Result<Rc<Obj>, ImportError> {
        let inner = obj.children(self.objects, "bsdf")?;
        match inner.len() {
            0 => Err(ImportError::at(&obj.loc, format!("{} needs a nested <bsdf>", obj.describe()))),
            1 => Ok(inner[0].0.clone()),
            _ => {
                if obj.plugin == "twosided" {
                    w.warn(
                        &obj.loc,
                        "twosided with a different BSDF on the back: the front BSDF is used on both sides",
                    );
                } else {
                    w.warn(&obj.loc, format!("{} with several nested BSDFs: only the first is used", obj.plugin));
                }
                Ok(inner[0].0.clone())
            }
        }
    }

    fn bsdf(&mut self, obj: &Rc<Obj>, sec: &mut Section, w: &mut Warnings) -> Result<(), ImportError> {
        let o = obj.as_ref();
        match o.plugin.as_str() {
            "twosided" => {
                sec.set("two_sided", TVal::Bool(true));
                let inner = self.nested(o, w)?;
                return self.bsdf(&inner, sec, w);
            }
            "mask" => {
                let opacity = self.colour_param(o, "opacity", Some([0.5; 3]), false, w)?.unwrap_or(TVal::Num(0.5));
                sec.set("opacity", opacity);
                let inner = self.nested(o, w)?;
                return self.bsdf(&inner, sec, w);
            }
            "bumpmap" | "normalmap" => {
                w.warn(
                    &o.loc,
                    format!("{}: the {} is ignored; its nested BSDF is rendered without it", o.describe(), o.plugin),
                );
                o.ignore(&["map", "normalmap", "scale"]);
                for p in &o.props {
                    if matches!(&p.value, Value::Object(t) if t.class == "texture") {
                        p.used.set(true);
                    }
                }
                let inner = self.nested(o, w)?;
                return self.bsdf(&inner, sec, w);
            }
            "blendbsdf" | "coating" | "roughcoating" => {
                w.warn(&o.loc, format!("{} is not supported: its (first) nested BSDF is used alone", o.describe()));
                o.ignore(&[
                    "weight",
                    "alpha",
                    "thickness",
                    "sigma_a",
                    "int_ior",
                    "ext_ior",
                    "distribution",
                    "specular_reflectance",
                ]);
                let inner = self.nested(o, w)?;
                return self.bsdf(&inner, sec, w);
            }
            _ => {}
        }
        self.leaf(o, sec, w)?;
        // Light passes through a dielectric from both sides already; plexus's dielectric takes no
        // `two_sided` (Mitsuba, too, warns against wrapping one in `twosided`).
        if sec.entries.iter().any(|(k, v)| k == "type" && *v == TVal::str("dielectric")) && sec.remove("two_sided") {
            w.warn(
                &o.loc,
                format!(
                    "{} inside twosided: the wrapper is dropped (a dielectric is two-sided by nature)",
                    o.describe()
                ),
            );
        }
        for p in o.unused() {
            w.warn(&p.loc, format!("{} of {} is not supported and was ignored", p.describe(), o.describe()));
        }
        Ok(())
    }

    fn leaf(&mut self, o: &Obj, sec: &mut Section, w: &mut Warnings) -> Result<(), ImportError> {
        match o.plugin.as_str() {
            "diffuse" | "roughdiffuse" | "difftrans" => {
                if o.plugin != "diffuse" {
                    let what =
                        if o.plugin == "roughdiffuse" { "Oren–Nayar roughness" } else { "diffuse transmission" };
                    w.warn(
                        &o.loc,
                        format!("{} mapped to a Lambertian diffuse material: the {what} is not modelled", o.describe()),
                    );
                    o.ignore(&["alpha", "use_fast_approx"]);
                }
                sec.set("type", TVal::str("diffuse"));
                let name = if o.plugin == "difftrans" { "transmittance" } else { "reflectance" };
                if let Some(c) = self.colour_param(o, name, None, true, w)? {
                    sec.set("reflectance", c);
                }
            }
            "dielectric" | "roughdielectric" | "thindielectric" => {
                sec.set("type", TVal::str("dielectric"));
                let ior = self.ior(o, DEFAULT_INT_IOR)?;
                sec.set("ior", TVal::Num(ior));
                if o.plugin == "roughdielectric" {
                    sec.set("roughness", TVal::Num(self.alpha(o, w)?));
                } else if o.plugin == "thindielectric" {
                    w.warn(&o.loc, format!("{} mapped to a smooth dielectric: thin sheets are not modelled (light refracts into the surface)", o.describe()));
                }
                self.tint(o, "specular_reflectance", w);
                self.tint(o, "specular_transmittance", w);
            }
            "conductor" | "roughconductor" => self.conductor(o, sec, w)?,
            "plastic" | "roughplastic" => {
                sec.set("type", TVal::str("plastic"));
                if let Some(c) = self.colour_param(o, "diffuse_reflectance", None, true, w)? {
                    sec.set("diffuse", c);
                }
                if let Some(c) = self.colour_param(o, "specular_reflectance", None, false, w)? {
                    sec.set("specular", c);
                }
                let alpha = if o.plugin == "roughplastic" { self.alpha(o, w)? } else { 0.0 };
                sec.set("roughness", TVal::Num(alpha));
                sec.set("ior", TVal::Num(self.ior(o, PLASTIC_INT_IOR)?));
                if o.bool("nonlinear", false)? {
                    sec.set("nonlinear", TVal::Bool(true));
                }
            }
            "phong" | "ward" => {
                // A diffuse base under a glossy lobe: plastic, with the lobe's width as GGX α.
                let alpha = if o.plugin == "phong" {
                    let n = o.float("exponent", 30.0)?;
                    (2.0 / (n + 2.0)).sqrt()
                } else {
                    let ax = o.float("alpha_u", o.float("alpha", 0.1)?)?;
                    let ay = o.float("alpha_v", ax)?;
                    (ax * ay).sqrt()
                };
                o.ignore(&["variant"]);
                let diffuse = self.colour_param(o, "diffuse_reflectance", Some([0.5; 3]), true, w)?;
                let specular = self.colour_param(o, "specular_reflectance", Some([0.2; 3]), false, w)?;
                let black = diffuse == Some(TVal::Num(0.0));
                if black {
                    // No diffuse part: a rough metal of the specular colour is nearest.
                    sec.set("type", TVal::str("conductor"));
                    sec.set("roughness", TVal::Num(alpha));
                    if let Some(s) = specular {
                        sec.set("colour", s);
                    }
                    w.warn(
                        &o.loc,
                        format!(
                            "{} mapped to a GGX conductor with roughness {alpha:.3} and its specular colour",
                            o.describe()
                        ),
                    );
                } else {
                    sec.set("type", TVal::str("plastic"));
                    if let Some(d) = diffuse {
                        sec.set("diffuse", d);
                    }
                    if let Some(s) = specular {
                        sec.set("specular", s);
                    }
                    sec.set("roughness", TVal::Num(alpha));
                    w.warn(
                        &o.loc,
                        format!(
                            "{} mapped to plastic (diffuse base, GGX coat of roughness {alpha:.3}, ior 1.5)",
                            o.describe()
                        ),
                    );
                }
            }
            "null" => {
                sec.set("type", TVal::str("diffuse"));
                sec.set("opacity", TVal::Num(0.0));
                w.warn(&o.loc, format!("{} mapped to a fully transparent material (opacity 0)", o.describe()));
            }
            other => {
                sec.set("type", TVal::str("diffuse"));
                let base = ["base_color", "reflectance", "diffuse_reflectance"]
                    .into_iter()
                    .find(|n| o.props.iter().any(|p| p.name == *n));
                if let Some(n) = base {
                    if let Some(c) = self.colour_param(o, n, None, true, w)? {
                        sec.set("reflectance", c);
                    }
                }
                w.warn(
                    &o.loc,
                    format!(
                        "BSDF '{other}' is not supported: mapped to a diffuse material{}",
                        base.map_or(" of reflectance 0.5".to_string(), |n| format!(" with its '{n}'"))
                    ),
                );
            }
        }
        Ok(())
    }

    fn conductor(&mut self, o: &Obj, sec: &mut Section, w: &mut Warnings) -> Result<(), ImportError> {
        let alpha = if o.plugin == "roughconductor" { self.alpha(o, w)? } else { 0.0 };
        o.ignore(&["ext_eta"]);
        let preset = match o.string("material")? {
            None if self.mitsuba3 && !o.props.iter().any(|p| p.name == "eta" || p.name == "k") => {
                Some(("none".to_string(), o.loc.clone()))
            }
            preset => preset,
        };
        let (eta, k) = match (&preset, o.take("eta"), o.take("k")) {
            (_, Some(e), Some(k)) => (self.plain_colour(o, e, w)?, self.plain_colour(o, k, w)?),
            (Some((name, loc)), None, None) => {
                if name == "none" {
                    // Mitsuba's perfect reflector.
                    let tint = self.colour_param(o, "specular_reflectance", None, false, w)?;
                    if alpha == 0.0 {
                        sec.set("type", TVal::str("mirror"));
                        if let Some(t) = tint {
                            sec.set("reflectance", t);
                        }
                    } else {
                        sec.set("type", TVal::str("conductor"));
                        sec.set("roughness", TVal::Num(alpha));
                        sec.set("colour", tint.unwrap_or(TVal::Num(1.0)));
                    }
                    return Ok(());
                }
                match conductor_preset(name) {
                    Some(v) => v,
                    None => {
                        w.warn(
                            loc,
                            format!(
                                "conductor material '{name}' is not in plexus's table ({}): aluminium used",
                                colour::CONDUCTOR_PRESETS
                            ),
                        );
                        conductor_preset("Al").unwrap_or_default()
                    }
                }
            }
            (None, None, None) => conductor_preset("Cu").unwrap_or_default(), // Mitsuba 0.6's default.
            _ => {
                return Err(ImportError::at(
                    &o.loc,
                    format!("{} needs both 'eta' and 'k' (or a 'material')", o.describe()),
                ))
            }
        };
        sec.set("type", TVal::str("conductor"));
        sec.set("roughness", TVal::Num(alpha));
        match o.take("specular_reflectance") {
            None => {
                sec.set("eta", TVal::colour(eta));
                sec.set("k", TVal::colour(k));
            }
            Some(p) => {
                let p_loc = p.loc.clone();
                let f0 = conductor_f0(eta, k);
                match self.objects.get(&p.value, &p.loc)? {
                    Some(tex) if tex.class == "texture" => {
                        // A textured tint: the normal-incidence colour F0 · tint, as a texture.
                        let t = self.texture(&tex, Some(f0), w)?;
                        w.warn(&p_loc, "conductor with a textured specular_reflectance: written as the colour F0·texture (η, k give way to the colour mapping)");
                        sec.set("colour", t);
                    }
                    _ => {
                        let tint = self.plain_colour(o, p, w)?;
                        if tint == [1.0; 3] {
                            sec.set("eta", TVal::colour(eta));
                            sec.set("k", TVal::colour(k));
                        } else {
                            let c = [0, 1, 2].map(|i| (f0[i] * tint[i]).min(1.0));
                            w.warn(&p_loc, format!("conductor specular_reflectance {} folded into its normal-incidence colour (η, k replaced by colour {})", fmt3(tint), fmt3(c)));
                            sec.set("colour", TVal::colour(c));
                        }
                    }
                }
            }
        }
        Ok(())
    }

    /// GGX α of a rough BSDF (isotropic); Beckmann is mapped by the same α.
    fn alpha(&self, o: &Obj, w: &mut Warnings) -> Result<f64, ImportError> {
        let dist = o.string("distribution")?;
        let alpha = match (o.take("alpha_u").is_some(), o.take("alpha_v").is_some()) {
            (false, false) => o.float("alpha", 0.1)?,
            _ => {
                let (u, v) = (o.float("alpha_u", 0.1)?, o.float("alpha_v", 0.1)?);
                w.warn(
                    &o.loc,
                    format!("{}: anisotropic roughness ({u}, {v}) rendered isotropic with α = √(αu·αv)", o.describe()),
                );
                (u * v).sqrt()
            }
        };
        if let Some((d, loc)) = dist {
            match d.as_str() {
                "ggx" => {}
                "beckmann" | "phong" | "as" => {
                    w.warn(&loc, format!("microfacet distribution '{d}' rendered as GGX with the same α"));
                }
                other => return Err(ImportError::at(&loc, format!("unknown microfacet distribution '{other}'"))),
            }
        } else if o.plugin.starts_with("rough") && !o.loc.file.is_empty() {
            // Mitsuba's default distribution is Beckmann.
            w.warn(
                &o.loc,
                "no microfacet distribution given: Mitsuba's default Beckmann rendered as GGX with the same α",
            );
        }
        o.ignore(&["sample_visible"]);
        Ok(alpha)
    }

    /// int_ior / ext_ior (numbers or Mitsuba's names).
    fn ior(&self, o: &Obj, default_int: f64) -> Result<f64, ImportError> {
        let read = |name: &str, default: f64| -> Result<f64, ImportError> {
            match o.take(name) {
                None => Ok(default),
                Some(p) => match &p.value {
                    Value::Float(v) => Ok(*v),
                    Value::Int(v) => Ok(*v as f64),
                    Value::Str(s) => named_ior(s)
                        .ok_or_else(|| ImportError::at(&p.loc, format!("unknown index of refraction '{s}'"))),
                    _ => Err(ImportError::at(&p.loc, format!("'{name}' must be a number or a material name"))),
                },
            }
        };
        let (int, ext) = (read("int_ior", default_int)?, read("ext_ior", DEFAULT_EXT_IOR)?);
        if !(int > 0.0 && ext > 0.0) {
            return Err(ImportError::at(&o.loc, format!("indices of refraction must be > 0, got {int} and {ext}")));
        }
        Ok(int / ext)
    }

    fn tint(&self, o: &Obj, name: &str, w: &mut Warnings) {
        if let Some(p) = o.take(name) {
            let is_one = matches!(&p.value, Value::Spectrum(s) if s.to_rgb(false) == [1.0; 3])
                || matches!(&p.value, Value::Float(v) if *v == 1.0);
            if !is_one {
                w.warn(
                    &p.loc,
                    format!("'{name}' of {} is not supported (plexus's dielectric is clear): ignored", o.describe()),
                );
            }
        }
    }

    fn plain_colour(&self, o: &Obj, p: &super::objects::Prop, _w: &mut Warnings) -> Result<[f64; 3], ImportError> {
        match &p.value {
            Value::Spectrum(s) => Ok(s.to_rgb(false)),
            Value::Float(v) => Ok([*v; 3]),
            Value::Int(v) => Ok([*v as f64; 3]),
            _ => Err(ImportError::at(&p.loc, format!("'{}' of {} must be a colour", p.name, o.describe()))),
        }
    }

    /// A colour-valued parameter: a colour (clamped to [0, 1] when `reflectance`) or a texture
    /// table. None when absent (and no `default`).
    pub fn colour_param(
        &self,
        o: &Obj,
        name: &str,
        default: Option<[f64; 3]>,
        reflectance: bool,
        w: &mut Warnings,
    ) -> Result<Option<TVal>, ImportError> {
        let Some(p) = o.take(name) else { return Ok(default.map(TVal::colour)) };
        if let Some(t) = self.objects.get(&p.value, &p.loc)? {
            if t.class != "texture" {
                return Err(ImportError::at(
                    &p.loc,
                    format!("'{name}' must be a colour or a texture, got a <{}>", t.class),
                ));
            }
            return self.texture(&t, None, w).map(Some);
        }
        let mut c = self.plain_colour(o, p, w)?;
        if reflectance && c.iter().any(|&v| v > 1.0) {
            let clamped = c.map(|v| v.min(1.0));
            w.warn(
                &p.loc,
                format!("'{name}' {} exceeds 1 (not energy-conserving): clamped to {}", fmt3(c), fmt3(clamped)),
            );
            c = clamped;
        }
        if c.iter().any(|&v| v < 0.0) {
            return Err(ImportError::at(&p.loc, format!("'{name}' must not be negative, got {}", fmt3(c))));
        }
        Ok(Some(TVal::colour(c)))
    }

    /// A texture table; `factor` multiplies a checkerboard's colours (a conductor's F0).
    fn texture(&self, t: &Obj, factor: Option<[f64; 3]>, w: &mut Warnings) -> Result<TVal, ImportError> {
        let (us, vs) = self.uv_scale(t, w)?;
        let mut entries = Vec::new();
        match t.plugin.as_str() {
            "bitmap" => {
                let (file, loc) = t
                    .string("filename")?
                    .ok_or_else(|| ImportError::at(&t.loc, "a bitmap texture needs a 'filename'"))?;
                let path = t.dir.join(&file);
                if !path.is_file() {
                    return Err(ImportError::at(&loc, format!("texture file '{}' not found", path.display())));
                }
                entries.push(("texture".to_string(), TVal::str("bitmap")));
                entries.push((
                    "file".to_string(),
                    TVal::str(relative_path(self.toml_dir, &path).to_string_lossy().replace('\\', "/")),
                ));
                let gamma = t.float("gamma", -1.0)?;
                let raw = t.bool("raw", false)?;
                if raw || gamma == 1.0 {
                    entries.push(("srgb".to_string(), TVal::Bool(false)));
                } else if gamma != -1.0 && (gamma - 2.2).abs() > 1e-6 {
                    w.warn(
                        &t.loc,
                        format!(
                            "bitmap gamma {gamma} is not supported: the file's own encoding (sRGB for 8-bit) is used"
                        ),
                    );
                }
                if let Some((f, loc)) = t.string("filter_type")? {
                    if f != "bilinear" {
                        w.warn(&loc, format!("texture filter '{f}' is rendered bilinear"));
                    }
                }
                if let Some((m, loc)) = t.string("wrap_mode")?.or(t.string("wrap_mode_u")?) {
                    if m != "repeat" {
                        w.warn(&loc, format!("texture wrap mode '{m}' is rendered 'repeat'"));
                    }
                }
                t.ignore(&["wrap_mode_v", "cache", "max_anisotropy", "channel"]);
                if factor.is_some() {
                    w.warn(&t.loc, "a bitmap used as a conductor tint is rendered as the conductor's colour");
                }
            }
            "checkerboard" => {
                let f = factor.unwrap_or([1.0; 3]);
                let c = |name: &str, d: f64, w: &mut Warnings| -> Result<[f64; 3], ImportError> {
                    match t.take(name) {
                        None => Ok([d; 3]),
                        Some(p) => self.plain_colour(t, p, w),
                    }
                };
                let (c0, c1) = (c("color0", 0.4, w)?, c("color1", 0.2, w)?);
                let m = |a: [f64; 3]| TVal::colour([0, 1, 2].map(|i| a[i] * f[i]));
                entries.push(("texture".to_string(), TVal::str("checkerboard")));
                entries.push(("colour0".to_string(), m(c0)));
                entries.push(("colour1".to_string(), m(c1)));
            }
            other => {
                w.warn(&t.loc, format!("texture '{other}' is not supported: replaced by grey 0.5"));
                return Ok(TVal::Num(0.5));
            }
        }
        if us != 1.0 || vs != 1.0 {
            entries.push(("uscale".to_string(), TVal::Num(us)));
            entries.push(("vscale".to_string(), TVal::Num(vs)));
        }
        for p in t.unused() {
            w.warn(
                &p.loc,
                format!("parameter '{}' of <texture type=\"{}\"> is not supported and was ignored", p.name, t.plugin),
            );
        }
        Ok(TVal::Tab(entries))
    }

    /// uscale/vscale (Mitsuba 0.6) or the scale of `to_uv` (Mitsuba 3).
    fn uv_scale(&self, t: &Obj, w: &mut Warnings) -> Result<(f64, f64), ImportError> {
        let (mut us, mut vs) = (t.float("uscale", 1.0)?, t.float("vscale", 1.0)?);
        for off in ["uoffset", "voffset"] {
            if t.float(off, 0.0)? != 0.0 {
                w.warn(&t.loc, format!("texture '{off}' is not supported: ignored"));
            }
        }
        if let Some((m, loc)) = t.transform("to_uv")? {
            let (sx, sy) = (m.x_axis.x, m.y_axis.y);
            if m.x_axis.y != 0.0 || m.y_axis.x != 0.0 || m.w_axis.x != 0.0 || m.w_axis.y != 0.0 {
                w.warn(&loc, "to_uv with rotation or offset: only its scale is used");
            }
            us *= sx;
            vs *= sy;
        }
        Ok((us, vs))
    }
}

pub fn fmt3(c: [f64; 3]) -> String {
    format!("[{}, {}, {}]", c[0] as f32, c[1] as f32, c[2] as f32)
}

/// The first area emitter's radiance, as linear RGB.
pub fn emitter_colour(p: &super::objects::Prop, loc: &Loc) -> Result<[f64; 3], ImportError> {
    match &p.value {
        Value::Spectrum(s) => Ok(s.to_rgb(true)),
        Value::Float(v) => Ok([*v; 3]),
        Value::Int(v) => Ok([*v as f64; 3]),
        _ => Err(ImportError::at(loc, format!("'{}' must be a colour (textured emission is not supported)", p.name))),
    }
}
