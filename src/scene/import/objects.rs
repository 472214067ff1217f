//! Mitsuba objects (a plugin with its parameters) built from the element tree, with `ref`s resolved
//! by id and every parameter remembering whether the importer used it, so that whatever it did
//! not use is reported by name and line instead of being dropped silently.

use std::cell::Cell;
use std::collections::HashMap;
use std::path::Path;
use std::rc::Rc;
use std::sync::Arc;

use glam::{DMat4, DVec3};

use super::colour::{self, Spectrum};
use super::numbers::{parse_f64, parse_list};
use super::xml::{Element, Loc};
use super::ImportError;

/// A parameter value.
#[derive(Clone, Debug)]
pub enum Value {
    Float(f64),
    Int(i64),
    Bool(bool),
    Str(String),
    Spectrum(Spectrum),
    Vector(DVec3),
    Transform(DMat4),
    Object(Rc<Obj>),
    /// `<ref id="..."/>`, resolved through `Objects::get`.
    Ref(String),
}

#[derive(Debug)]
pub struct Prop {
    /// Normalised name; nested objects without a name get "" (a shape's bsdf, emitter, ...).
    pub name: String,
    pub value: Value,
    pub loc: Loc,
    pub used: Cell<bool>,
}

/// One plugin instance: `<bsdf type="diffuse" id="white">...</bsdf>`.
#[derive(Debug)]
pub struct Obj {
    /// Element tag: bsdf, shape, emitter, sensor, texture, film, rfilter, sampler, integrator, ...
    pub class: String,
    /// The `type` attribute.
    pub plugin: String,
    pub id: Option<String>,
    pub loc: Loc,
    /// Relative file names resolve against this directory (the file the element is in).
    pub dir: Arc<Path>,
    pub props: Vec<Prop>,
}

/// Every object of the scene and the id table.
pub struct Objects {
    pub top: Vec<Rc<Obj>>,
    ids: HashMap<String, Rc<Obj>>,
    /// Ids of the objects being built (the enclosing elements), to refuse a ref to one of them.
    building: Vec<String>,
}

const OBJECT_TAGS: &[&str] = &[
    "bsdf",
    "shape",
    "emitter",
    "sensor",
    "texture",
    "film",
    "rfilter",
    "sampler",
    "integrator",
    "medium",
    "phase",
    "volume",
    "spectrum_plugin",
];

impl Objects {
    pub fn build(root: &Element) -> Result<Objects, ImportError> {
        let mut objects = Objects { top: Vec::new(), ids: HashMap::new(), building: Vec::new() };
        for child in &root.children {
            if OBJECT_TAGS.contains(&child.tag.as_str()) {
                let obj = objects.object(child)?;
                objects.top.push(obj);
            } else {
                return Err(ImportError::at(
                    &child.loc,
                    format!("unexpected <{}> at the top level of the scene", child.tag),
                ));
            }
        }
        Ok(objects)
    }

    /// The object behind `v` (following a ref), or None when `v` is not an object.
    pub fn get(&self, v: &Value, loc: &Loc) -> Result<Option<Rc<Obj>>, ImportError> {
        match v {
            Value::Object(o) => Ok(Some(o.clone())),
            Value::Ref(id) => match self.ids.get(id) {
                Some(o) => Ok(Some(o.clone())),
                None => Err(ImportError::at(loc, format!("<ref id=\"{id}\"> names no object defined in the scene"))),
            },
            _ => Ok(None),
        }
    }

    fn object(&mut self, e: &Element) -> Result<Rc<Obj>, ImportError> {
        let plugin = e.attr("type").unwrap_or_default().to_string();
        if plugin.is_empty() {
            return Err(ImportError::at(&e.loc, format!("<{}> needs a 'type' attribute", e.tag)));
        }
        let id = e.attr("id").map(str::to_string);
        if let Some(id) = &id {
            if let Some(first) = self.ids.get(id) {
                return Err(ImportError::at(
                    &e.loc,
                    format!("id '{id}' is defined twice (first at {}:{})", first.loc.file, first.loc.line),
                ));
            }
            self.building.push(id.clone());
        }
        let mut props = Vec::new();
        for c in &e.children {
            props.push(self.prop(c)?);
        }
        if id.is_some() {
            self.building.pop();
        }
        let obj = Rc::new(Obj {
            class: e.tag.clone(),
            plugin,
            id: e.attr("id").map(str::to_string),
            loc: e.loc.clone(),
            dir: e.dir.clone(),
            props,
        });
        if let Some(id) = &obj.id {
            self.ids.insert(id.clone(), obj.clone());
        }
        Ok(obj)
    }

    fn prop(&mut self, e: &Element) -> Result<Prop, ImportError> {
        let name = e.name().unwrap_or_default();
        let attr =
            |k: &str| e.attr(k).ok_or_else(|| ImportError::at(&e.loc, format!("<{}> needs a '{k}' attribute", e.tag)));
        let value = match e.tag.as_str() {
            "float" => Value::Float(parse_f64(attr("value")?, &e.loc)?),
            "integer" => {
                let v = attr("value")?;
                Value::Int(
                    v.trim().parse().map_err(|_| ImportError::at(&e.loc, format!("expected an integer, got '{v}'")))?,
                )
            }
            "boolean" => Value::Bool(match attr("value")?.trim() {
                "true" | "True" | "1" => true,
                "false" | "False" | "0" => false,
                other => return Err(ImportError::at(&e.loc, format!("expected true or false, got '{other}'"))),
            }),
            "string" => Value::Str(attr("value")?.to_string()),
            "rgb" => Value::Spectrum(Spectrum::Rgb(colour::parse_rgb(attr("value")?, &e.loc)?)),
            "srgb" => Value::Spectrum(Spectrum::Rgb(colour::parse_srgb(attr("value")?, &e.loc)?)),
            "spectrum" => {
                if let Some(f) = e.attr("filename") {
                    return Err(ImportError::at(
                        &e.loc,
                        format!("spectrum files ('{f}') are not supported: give the value as rgb or as wavelength:value pairs"),
                    ));
                }
                Value::Spectrum(colour::parse_spectrum(attr("value")?, &e.loc)?)
            }
            "vector" | "point" => {
                if let Some(v) = e.attr("value") {
                    let n = parse_list(v, &e.loc)?;
                    if n.len() != 3 {
                        return Err(ImportError::at(&e.loc, format!("expected three numbers, got '{v}'")));
                    }
                    Value::Vector(DVec3::new(n[0], n[1], n[2]))
                } else {
                    let c = |k: &str| e.attr(k).map_or(Ok(0.0), |v| parse_f64(v, &e.loc));
                    Value::Vector(DVec3::new(c("x")?, c("y")?, c("z")?))
                }
            }
            "transform" => Value::Transform(super::transform::parse(e)?),
            "ref" => {
                // Mitsuba resolves a ref to an object defined before it; a ref to an enclosing
                // object would be a cycle (and endless recursion when converting it).
                let id = attr("id")?;
                if self.building.iter().any(|b| b == id) {
                    return Err(ImportError::at(
                        &e.loc,
                        format!("<ref id=\"{id}\"> is inside the object it names: a reference cycle"),
                    ));
                }
                if !self.ids.contains_key(id) {
                    return Err(ImportError::at(
                        &e.loc,
                        format!("<ref id=\"{id}\"> names no object defined before it in the scene"),
                    ));
                }
                Value::Ref(id.to_string())
            }
            t if OBJECT_TAGS.contains(&t) => Value::Object(self.object(e)?),
            other => return Err(ImportError::at(&e.loc, format!("unsupported element <{other}>"))),
        };
        Ok(Prop { name, value, loc: e.loc.clone(), used: Cell::new(false) })
    }
}

impl Prop {
    /// What the parameter is, for "ignored" warnings: `parameter 'name'`, or the nested object
    /// (inline or by ref), which has no name.
    pub fn describe(&self) -> String {
        match (&self.value, self.name.is_empty()) {
            (Value::Object(o), true) => format!("nested {}", o.describe()),
            (Value::Ref(id), true) => format!("<ref id=\"{id}\">"),
            _ => format!("parameter '{}'", self.name),
        }
    }
}

impl Obj {
    /// The first parameter called `name`, marked as used.
    pub fn take(&self, name: &str) -> Option<&Prop> {
        let p = self.props.iter().find(|p| p.name == name)?;
        p.used.set(true);
        Some(p)
    }
    /// Marks parameters that have no effect in plexus and need no warning.
    pub fn ignore(&self, names: &[&str]) {
        for p in &self.props {
            if names.contains(&p.name.as_str()) {
                p.used.set(true);
            }
        }
    }
    pub fn float(&self, name: &str, default: f64) -> Result<f64, ImportError> {
        match self.take(name) {
            None => Ok(default),
            Some(p) => match &p.value {
                Value::Float(v) => Ok(*v),
                Value::Int(v) => Ok(*v as f64),
                Value::Spectrum(Spectrum::Rgb(c)) if c[0] == c[1] && c[1] == c[2] => Ok(c[0]),
                Value::Spectrum(Spectrum::Uniform(v)) => Ok(*v),
                _ => Err(ImportError::at(
                    &p.loc,
                    format!("'{name}' of <{} type=\"{}\"> must be a number", self.class, self.plugin),
                )),
            },
        }
    }
    /// [`Obj::float`] that must lie in `range`: a value outside it means nothing (a month 13, a
    /// latitude 1000) and is refused, naming the range, instead of rendering something else.
    pub fn float_in(&self, name: &str, default: f64, range: std::ops::RangeInclusive<f64>) -> Result<f64, ImportError> {
        self.within(name, self.float(name, default)?, range)
    }
    /// [`Obj::int`] that must lie in `range` (see [`Obj::float_in`]).
    pub fn int_in(&self, name: &str, default: i64, range: std::ops::RangeInclusive<i64>) -> Result<i64, ImportError> {
        self.within(name, self.int(name, default)?, range)
    }
    /// `v`, the value of parameter `name`, if it lies in `range`; else an error at the parameter.
    fn within<T: PartialOrd + std::fmt::Display>(
        &self,
        name: &str,
        v: T,
        range: std::ops::RangeInclusive<T>,
    ) -> Result<T, ImportError> {
        if range.contains(&v) {
            return Ok(v);
        }
        let loc = self.props.iter().find(|p| p.name == name).map_or(&self.loc, |p| &p.loc);
        Err(ImportError::at(
            loc,
            format!("'{name}' of {} must be in [{}, {}], got {v}", self.describe(), range.start(), range.end()),
        ))
    }
    pub fn int(&self, name: &str, default: i64) -> Result<i64, ImportError> {
        match self.take(name) {
            None => Ok(default),
            Some(p) => match &p.value {
                Value::Int(v) => Ok(*v),
                Value::Float(v) if v.fract() == 0.0 => Ok(*v as i64),
                _ => Err(ImportError::at(&p.loc, format!("'{name}' must be an integer"))),
            },
        }
    }
    pub fn bool(&self, name: &str, default: bool) -> Result<bool, ImportError> {
        match self.take(name) {
            None => Ok(default),
            Some(p) => match &p.value {
                Value::Bool(v) => Ok(*v),
                _ => Err(ImportError::at(&p.loc, format!("'{name}' must be a boolean"))),
            },
        }
    }
    pub fn string(&self, name: &str) -> Result<Option<(String, Loc)>, ImportError> {
        match self.take(name) {
            None => Ok(None),
            Some(p) => match &p.value {
                Value::Str(s) => Ok(Some((s.clone(), p.loc.clone()))),
                _ => Err(ImportError::at(&p.loc, format!("'{name}' must be a string"))),
            },
        }
    }
    pub fn vector(&self, name: &str) -> Result<Option<DVec3>, ImportError> {
        match self.take(name) {
            None => Ok(None),
            Some(p) => match &p.value {
                Value::Vector(v) => Ok(Some(*v)),
                _ => Err(ImportError::at(&p.loc, format!("'{name}' must be a vector or point"))),
            },
        }
    }
    pub fn transform(&self, name: &str) -> Result<Option<(DMat4, Loc)>, ImportError> {
        match self.take(name) {
            None => Ok(None),
            Some(p) => match &p.value {
                Value::Transform(m) => Ok(Some((*m, p.loc.clone()))),
                _ => Err(ImportError::at(&p.loc, format!("'{name}' must be a <transform>"))),
            },
        }
    }
    /// Nested objects of `class` (inline or by ref) in the order written, each marked as used.
    pub fn children(&self, objects: &Objects, class: &str) -> Result<Vec<(Rc<Obj>, Loc, String)>, ImportError> {
        let mut out = Vec::new();
        for p in &self.props {
            if let Some(o) = objects.get(&p.value, &p.loc)? {
                if o.class == class {
                    p.used.set(true);
                    out.push((o, p.loc.clone(), p.name.clone()));
                }
            }
        }
        Ok(out)
    }
    /// The parameters nobody used, for the "ignored" warnings.
    pub fn unused(&self) -> impl Iterator<Item = &Prop> {
        self.props.iter().filter(|p| !p.used.get())
    }
    /// `<bsdf type="diffuse" id="white">` for messages.
    pub fn describe(&self) -> String {
        match &self.id {
            Some(id) => format!("<{} type=\"{}\" id=\"{id}\">", self.class, self.plugin),
            None => format!("<{} type=\"{}\">", self.class, self.plugin),
        }
    }
}
