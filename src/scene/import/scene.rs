//! The scene-level conversion: sensor → `[camera]` (+ `[render]`), shapes → `[[shapes]]`,
//! emitters → `emission` and `[environment]`, integrator → `[integrator]`.

use std::path::Path;
use std::rc::Rc;

use glam::{DMat3, DMat4, DQuat, DVec3};

use super::bsdf::{emitter_colour, fmt3, Materials};
use super::objects::{Obj, Objects};
use super::toml_out::{self, Section, TVal};
use super::{relative_path, serialized, sun, ImportError, Imported, Warnings};

pub fn convert(
    objects: &Objects,
    version: &str,
    xml_path: &Path,
    toml_dir: &Path,
    mesh_dir: &Path,
    skip_missing: bool,
) -> Result<Imported, ImportError> {
    let mut w = Warnings::default();
    let mut materials = Materials::new(objects, toml_dir);
    materials.mitsuba3 = version.starts_with('3');
    let mut camera = None;
    let mut render = Section::new("render");
    let mut integrator = None;
    let mut shapes = Vec::new();
    let mut environment: Option<Section> = None;
    let mut converted = serialized::ConvertedMeshes::new(mesh_dir);
    for obj in &objects.top {
        match obj.class.as_str() {
            "sensor" => {
                if camera.is_some() {
                    w.warn(&obj.loc, "a second <sensor>: plexus renders the first one only");
                    continue;
                }
                camera = Some(sensor(objects, obj, &mut render, &mut w)?);
            }
            "integrator" => integrator = Some(integrator_section(obj, &mut w)?),
            "shape" => {
                if let Some(s) = shape(objects, obj, &mut materials, toml_dir, &mut converted, skip_missing, &mut w)? {
                    shapes.push(s);
                }
            }
            "emitter" => {
                if let Some(env) = emitter(obj, toml_dir, &mut w)? {
                    if environment.is_some() {
                        w.warn(
                            &obj.loc,
                            format!("{}: plexus takes one environment; the first one is kept", obj.describe()),
                        );
                    } else {
                        environment = Some(env);
                    }
                }
            }
            "bsdf" | "texture" => {} // Converted where shapes use them.
            other => {
                w.warn(&obj.loc, format!("<{other} type=\"{}\"> is not supported and was ignored", obj.plugin));
                for p in &obj.props {
                    p.used.set(true);
                }
            }
        }
    }
    // After every shape has converted the BSDFs it uses (which report their own parameters).
    for obj in objects.top.iter().filter(|o| !matches!(o.class.as_str(), "bsdf" | "texture")) {
        report_unused(obj, &mut w);
    }
    let camera = camera.ok_or_else(|| {
        ImportError::file(&xml_path.display().to_string(), "the scene has no <sensor>: plexus needs a camera")
    })?;
    // BSDFs defined but used by no shape are not written.
    let mut sections = vec![camera];
    sections.extend(materials.sections);
    sections.extend(shapes);
    sections.extend(environment);
    sections.extend(integrator);
    if !render.entries.is_empty() {
        sections.push(render);
    }
    let preamble = vec![
        format!("Imported by `plexus import` from {} (Mitsuba scene version {version}).", xml_path.display()),
        "Mesh and texture paths are relative to this file. What the import changed is noted at each table".into(),
        "and was printed as warnings.".into(),
    ];
    Ok(Imported { toml: toml_out::write(&preamble, &sections), warnings: w, converted: converted.descriptions() })
}

/// Warns about every parameter of `obj` (and of nested helper objects) that nobody used.
fn report_unused(obj: &Obj, w: &mut Warnings) {
    for p in obj.unused() {
        w.warn(&p.loc, format!("{} of {} is not supported and was ignored", p.describe(), obj.describe()));
    }
}

fn sensor(objects: &Objects, s: &Rc<Obj>, render: &mut Section, w: &mut Warnings) -> Result<Section, ImportError> {
    match s.plugin.as_str() {
        "perspective" => {}
        "thinlens" => {
            w.warn(&s.loc, "thinlens sensor rendered as a pinhole: depth of field is not modelled");
            s.ignore(&["aperture_radius", "focus_distance"]);
        }
        other => {
            return Err(ImportError::at(
                &s.loc,
                format!("sensor '{other}' is not supported (plexus has a perspective pinhole camera)"),
            ))
        }
    }
    // The pinhole has no clip planes and no focus; these change nothing in the image.
    s.ignore(&["near_clip", "far_clip", "focus_distance", "shutter_open", "shutter_close"]);
    let (mut width, mut height) = (768i64, 576i64);
    for (film, _, _) in s.children(objects, "film")? {
        width = film.int("width", 768)?;
        height = film.int("height", 576)?;
        film.ignore(&[
            "banner",
            "file_format",
            "pixel_format",
            "component_format",
            "gamma",
            "high_quality_edges",
            "tonemap_method",
            "exposure",
            "attach_log",
            "sample_border",
            "compensate",
        ]);
        for key in ["crop_offset_x", "crop_offset_y", "crop_width", "crop_height"] {
            if film.take(key).is_some() {
                w.warn(&film.loc, format!("film '{key}' is not supported: the whole image is rendered"));
            }
        }
        let filters = film.children(objects, "rfilter")?;
        match filters.first() {
            None => w.warn(
                &film.loc,
                "no reconstruction filter given: Mitsuba's default gaussian is rendered with plexus's box filter",
            ),
            Some((f, _, _)) if f.plugin == "box" => {}
            Some((f, _, _)) => {
                w.warn(&f.loc, format!("reconstruction filter '{}' is rendered with plexus's box filter", f.plugin));
                f.ignore(&["stddev", "radius", "b", "c", "lobes"]);
            }
        }
        for (f, _, _) in &filters {
            report_unused(f, w);
        }
        report_unused(&film, w);
    }
    for (sampler, _, _) in s.children(objects, "sampler")? {
        let spp = sampler.int("sample_count", 4)?;
        if spp > 0 {
            render.set("spp", TVal::Int(spp));
        }
        let seed = sampler.int("seed", 0)?;
        if seed > 0 {
            render.set("seed", TVal::Int(seed));
        }
        if !matches!(
            sampler.plugin.as_str(),
            "independent" | "stratified" | "multijitter" | "ldsampler" | "halton" | "sobol" | "orthogonal"
        ) {
            w.warn(&sampler.loc, format!("sampler '{}' is replaced by plexus's independent sampling", sampler.plugin));
        }
        sampler.ignore(&["dimension", "scramble", "jitter"]);
        report_unused(&sampler, w);
    }
    if width <= 0 || height <= 0 {
        return Err(ImportError::at(&s.loc, format!("film size must be positive, got {width}×{height}")));
    }
    let (wf, hf) = (width as f64, height as f64);
    let fov = s.float("fov", f64::NAN)?;
    let fov_y = if fov.is_nan() {
        // Mitsuba 0.6 also accepts a 35 mm equivalent focal length.
        let focal = match s.string("focal_length")? {
            Some((f, loc)) => f
                .trim_end_matches("mm")
                .trim()
                .parse::<f64>()
                .map_err(|_| ImportError::at(&loc, format!("expected a focal length like '50mm', got '{f}'")))?,
            None => 50.0,
        };
        // Along the diagonal of a 36×24 mm film.
        let diag_fov = 2.0 * (36f64.hypot(24.0) / (2.0 * focal)).atan().to_degrees();
        vertical_fov(diag_fov, "diagonal", wf, hf)
    } else {
        let axis = s.string("fov_axis")?.map_or("x".to_string(), |(a, _)| a);
        if !matches!(axis.as_str(), "x" | "y" | "smaller" | "larger" | "diagonal") {
            return Err(ImportError::at(
                &s.loc,
                format!("fov_axis must be x, y, smaller, larger or diagonal, got '{axis}'"),
            ));
        }
        vertical_fov(fov, &axis, wf, hf)
    };
    if !(fov_y > 0.0 && fov_y < 180.0) {
        return Err(ImportError::at(&s.loc, format!("field of view out of range: {fov_y}° vertical")));
    }
    let m = s.transform("to_world")?.map_or(DMat4::IDENTITY, |(m, _)| m);
    let position = m.transform_point3(DVec3::ZERO);
    let forward = m.transform_vector3(DVec3::Z);
    let up = m.transform_vector3(DVec3::Y);
    let x = m.transform_vector3(DVec3::X);
    if forward.length_squared() == 0.0 || up.cross(forward).length_squared() == 0.0 {
        return Err(ImportError::at(&s.loc, "the sensor's to_world is degenerate"));
    }
    // Mitsuba's camera space has +x to the left (left = up × dir); a to_world that maps +x to the
    // right mirrors the image, which a pinhole given by position, look_at and up cannot do.
    if x.dot(up.cross(forward)) < 0.0 {
        w.warn(&s.loc, "the sensor's to_world mirrors the image (negative determinant): rendered unmirrored");
    }
    let mut cam = Section::new("camera");
    cam.comments.push(format!("{} at {}", s.describe(), s.loc));
    cam.set("position", TVal::vec3(position.to_array()));
    cam.set("look_at", TVal::vec3((position + forward.normalize()).to_array()));
    cam.set("up", TVal::vec3(up.normalize().to_array()));
    cam.set("fov", TVal::Num(fov_y));
    cam.set("resolution", TVal::Arr(vec![TVal::Int(width), TVal::Int(height)]));
    Ok(cam)
}

/// Mitsuba's `fov` along `axis` as plexus's vertical field of view, degrees.
pub fn vertical_fov(fov: f64, axis: &str, width: f64, height: f64) -> f64 {
    let t = (fov.to_radians() / 2.0).tan();
    let ty = match axis {
        "y" => t,
        "x" => t * height / width,
        "smaller" if width < height => t * height / width,
        "smaller" => t,
        "larger" if width > height => t * height / width,
        "larger" => t,
        _ => t * height / width.hypot(height), // diagonal
    };
    2.0 * ty.atan().to_degrees()
}

fn integrator_section(obj: &Obj, w: &mut Warnings) -> Result<Section, ImportError> {
    let mut sec = Section::new("integrator");
    sec.comments.push(format!("{} at {}", obj.describe(), obj.loc));
    let kind = match obj.plugin.as_str() {
        "path" | "volpath" | "volpath_simple" | "prb" => "pt",
        "bdpt" => "bdpt",
        "pssmlt" | "mlt" => "pssmlt",
        other => {
            w.warn(
                &obj.loc,
                format!(
                    "integrator '{other}' is rendered with plexus's path tracer (pt); choose another with --integrator"
                ),
            );
            "pt"
        }
    };
    sec.set("type", TVal::str(kind));
    let depth = obj.int("max_depth", -1)?;
    // Mitsuba counts path edges (1: only emitters seen directly), plexus counts bounces.
    if depth > 1 {
        sec.set("max_depth", TVal::Int(depth - 1));
    } else if depth == 1 || depth == 0 {
        w.warn(
            &obj.loc,
            format!("max_depth {depth} (emitters seen directly only) is rendered with one bounce, plexus's minimum"),
        );
        sec.set("max_depth", TVal::Int(1));
    }
    let rr = obj.int("rr_depth", -1)?;
    if rr > 0 && kind == "pt" {
        sec.set("rr_depth", TVal::Int((rr - 1).max(1)));
    }
    // The parameters of other integrators (photon counts, passes, ...) do not apply to the one
    // chosen; the warning above says the integrator was replaced.
    for p in obj.unused() {
        p.used.set(true);
    }
    Ok(sec)
}

fn matrix_tval(m: &DMat4) -> TVal {
    let rows = (0..3).map(|r| TVal::Arr((0..4).map(|c| TVal::Num(m.col(c)[r])).collect())).collect::<Vec<_>>();
    let mut all = rows;
    all.push(TVal::Arr(vec![TVal::Num(0.0), TVal::Num(0.0), TVal::Num(0.0), TVal::Num(1.0)]));
    TVal::Arr(all)
}

fn shape(
    objects: &Objects,
    s: &Rc<Obj>,
    materials: &mut Materials,
    toml_dir: &Path,
    converted: &mut serialized::ConvertedMeshes,
    skip_missing: bool,
    w: &mut Warnings,
) -> Result<Option<Section>, ImportError> {
    let mut sec = Section::new("shapes");
    sec.array = true;
    sec.comments.push(format!("{} at {}", s.describe(), s.loc));
    let mut m = s.transform("to_world")?.map_or(DMat4::IDENTITY, |(m, _)| m);
    let rel = |p: &Path| relative_path(toml_dir, p).to_string_lossy().replace('\\', "/");
    let file_of = |s: &Obj, w: &mut Warnings| -> Result<Option<std::path::PathBuf>, ImportError> {
        let (f, loc) = s
            .string("filename")?
            .ok_or_else(|| ImportError::at(&s.loc, format!("{} needs a 'filename'", s.describe())))?;
        let path = s.dir.join(&f);
        if !path.is_file() && s.plugin != "serialized" {
            let msg = format!("mesh file '{}' not found", path.display());
            if skip_missing {
                w.warn(&loc, format!("{msg}: the shape is left out (--skip-missing-meshes)"));
                for p in &s.props {
                    p.used.set(true);
                }
                return Ok(None);
            }
            return Err(ImportError::at(&loc, format!("{msg} (--skip-missing-meshes leaves such shapes out)")));
        }
        Ok(Some(path))
    };
    match s.plugin.as_str() {
        "obj" | "ply" => {
            let Some(path) = file_of(s, w)? else { return Ok(None) };
            sec.set("type", TVal::str(s.plugin.clone()));
            sec.set("file", TVal::str(rel(&path)));
            s.ignore(&["flip_tex_coords", "max_smooth_angle"]);
        }
        "serialized" => {
            let Some(path) = file_of(s, w)? else { return Ok(None) };
            let index = s.int("shape_index", 0)?;
            if index < 0 {
                return Err(ImportError::at(&s.loc, format!("shape_index must be ≥ 0, got {index}")));
            }
            let stem = path.file_stem().map(|x| x.to_string_lossy().into_owned()).unwrap_or_default();
            let ply_name = format!("{stem}_{index}.ply");
            let ply = if path.is_file() {
                let mesh = serialized::read(&path, index as usize)
                    .map_err(|e| ImportError::at(&s.loc, format!("mesh '{}': {e}", path.display())))?;
                let (out, note) = converted.convert(&path, index, &mesh).map_err(|e| ImportError::at(&s.loc, e))?;
                if let Some(note) = note {
                    w.warn(&s.loc, note);
                }
                out
            } else {
                // The PLY this conversion writes, made earlier (e.g. shipped without the original).
                let beside = path.with_file_name(&ply_name);
                if !beside.is_file() {
                    return Err(ImportError::at(
                        &s.loc,
                        format!(
                            "mesh file '{}' not found (nor a converted '{}' beside it)",
                            path.display(),
                            beside.display()
                        ),
                    ));
                }
                w.warn(
                    &s.loc,
                    format!(
                        "'{}' is missing: using its converted meshes (<name>_<shape_index>.ply) beside it",
                        path.display()
                    ),
                );
                beside
            };
            sec.set("type", TVal::str("ply"));
            sec.set("file", TVal::str(rel(&ply)));
        }
        "rectangle" => sec.set("type", TVal::str("quad")),
        "cube" => sec.set("type", TVal::str("box")),
        "disk" => sec.set("type", TVal::str("disk")),
        "sphere" => {
            sec.set("type", TVal::str("sphere"));
            let center = s.vector("center")?.unwrap_or(DVec3::ZERO);
            let radius = s.float("radius", 1.0)?;
            if !(radius > 0.0) {
                return Err(ImportError::at(&s.loc, format!("sphere radius must be > 0, got {radius}")));
            }
            m = m * DMat4::from_translation(center) * DMat4::from_scale(DVec3::splat(radius));
        }
        other => {
            w.warn(&s.loc, format!("shape '{other}' is not supported and was left out of the scene"));
            for p in &s.props {
                p.used.set(true);
            }
            return Ok(None);
        }
    }
    let bsdfs = s.children(objects, "bsdf")?;
    let material = match bsdfs.first() {
        Some((b, _, _)) => materials.material(b, w)?,
        None => materials.default_material(),
    };
    if bsdfs.len() > 1 {
        w.warn(&s.loc, "a shape with several BSDFs: the first is used");
    }
    sec.set("material", TVal::str(material));
    for (e, _, _) in s.children(objects, "emitter")? {
        if e.plugin != "area" {
            w.warn(&e.loc, format!("emitter '{}' attached to a shape is not supported and was ignored", e.plugin));
            continue;
        }
        let p = e.take("radiance").ok_or_else(|| ImportError::at(&e.loc, "an area emitter needs 'radiance'"))?;
        let mut c = emitter_colour(p, &p.loc)?;
        let scale = e.float("scale", 1.0)?;
        c = c.map(|v| v * scale);
        if c.iter().any(|&v| v < 0.0) {
            return Err(ImportError::at(&p.loc, format!("radiance must not be negative, got {}", fmt3(c))));
        }
        let weight = e.float("sampling_weight", 1.0)?;
        if weight != 1.0 {
            w.warn(&e.loc, format!("sampling_weight {weight} ignored: plexus selects lights by power"));
        }
        sec.set("emission", TVal::Tab(vec![("radiance".into(), TVal::colour(c))]));
        report_unused(&e, w);
    }
    if s.bool("face_normals", false)? {
        sec.set("face_normals", TVal::Bool(true));
    }
    if s.bool("flip_normals", false)? {
        sec.set("flip_normals", TVal::Bool(true));
    }
    if m != DMat4::IDENTITY {
        sec.set("transform", TVal::Tab(vec![("matrix".into(), matrix_tval(&m))]));
    }
    Ok(Some(sec))
}

/// An environment emitter as `[environment]`; None for emitters plexus cannot take (warned).
fn emitter(e: &Rc<Obj>, toml_dir: &Path, w: &mut Warnings) -> Result<Option<Section>, ImportError> {
    let mut sec = Section::new("environment");
    sec.comments.push(format!("{} at {}", e.describe(), e.loc));
    match e.plugin.as_str() {
        "constant" => {
            let p = e.take("radiance").ok_or_else(|| ImportError::at(&e.loc, "a constant emitter needs 'radiance'"))?;
            let c = emitter_colour(p, &p.loc)?;
            sec.set("type", TVal::str("constant"));
            sec.set("radiance", TVal::colour(c));
            let scale = e.float("scale", 1.0)?;
            if scale != 1.0 {
                sec.set("scale", TVal::Num(scale));
            }
        }
        "envmap" => {
            let (f, loc) =
                e.string("filename")?.ok_or_else(|| ImportError::at(&e.loc, "an envmap needs a 'filename'"))?;
            let path = e.dir.join(&f);
            if !path.is_file() {
                return Err(ImportError::at(&loc, format!("environment map '{}' not found", path.display())));
            }
            if !path.extension().is_some_and(|x| x.eq_ignore_ascii_case("exr")) {
                return Err(ImportError::at(
                    &loc,
                    format!("environment map '{}': plexus reads OpenEXR environment maps only", path.display()),
                ));
            }
            sec.set("type", TVal::str("image"));
            sec.set("file", TVal::str(relative_path(toml_dir, &path).to_string_lossy().replace('\\', "/")));
            let scale = e.float("scale", 1.0)?;
            if scale != 1.0 {
                sec.set("scale", TVal::Num(scale));
            }
            let m = e.transform("to_world")?;
            let (rot, loc) = match m {
                Some((m, loc)) => (DMat3::from_mat4(m), Some(loc)),
                None => (DMat3::IDENTITY, None),
            };
            // Mitsuba (0.6 and 3, envmap.cpp) looks up u = atan2(x, -z)/2π (mod 1) in the map's
            // frame, plexus u = atan2(z, x)/2π: Mitsuba's azimuth is plexus's plus 90°, which
            // R_y(+90°) (glam's, turning atan2(z, x) by -90°) undoes, so plexus's `rotate` is
            // to_world · R_y(90°) (applied first: R_y(90°), then to_world). Checked against Mitsuba
            // 3's renders of the living room's sky in scripts/crosscheck.py.
            let det = rot.determinant();
            let ortho = (rot.transpose() * rot - DMat3::IDENTITY).to_cols_array().iter().all(|v| v.abs() < 1e-4);
            let rot = if det > 0.0 && ortho {
                rot
            } else {
                if let Some(loc) = &loc {
                    w.warn(loc, "envmap to_world is not a rotation (scaled or mirrored): its rotation part is used");
                }
                orthonormalise(rot)
            };
            let total = rot * DMat3::from_rotation_y(std::f64::consts::FRAC_PI_2);
            let q = DQuat::from_mat3(&total);
            let (axis, angle) = q.to_axis_angle();
            // Below a thousandth of a degree the rotation is rounding (the 4.4e-8 of a written cos 90°).
            if angle.to_degrees().abs() > 1e-3 {
                sec.set(
                    "rotate",
                    TVal::Tab(vec![
                        ("axis".into(), TVal::vec3(axis.to_array())),
                        ("angle".into(), TVal::Num(angle.to_degrees())),
                    ]),
                );
            }
        }
        "sunsky" | "sun" | "sky" => {
            sec.set("type", TVal::str(e.plugin.clone()));
            // Mitsuba's sky is y-up in its local frame: to_world places the sun computed from the
            // date (an explicit `sunDirection` is already in world space) and the zenith alike.
            let to_world = e.transform("to_world")?.map(|(m, _)| m);
            let dir = match e.vector("sun_direction")? {
                Some(d) => d,
                None => {
                    let t = sun::SunTime {
                        // The ranges of a calendar date and a place on Earth (hour 24 is the
                        // next midnight, a leap second is second 60).
                        year: e.int_in("year", 2010, -4712..=9999)?,
                        month: e.int_in("month", 7, 1..=12)?,
                        day: e.int_in("day", 10, 1..=31)?,
                        hour: e.float_in("hour", 15.0, 0.0..=24.0)?,
                        minute: e.float_in("minute", 0.0, 0.0..=60.0)?,
                        second: e.float_in("second", 0.0, 0.0..=61.0)?,
                        latitude: e.float_in("latitude", 35.6894, -90.0..=90.0)?,
                        longitude: e.float_in("longitude", 139.6917, -180.0..=360.0)?,
                        timezone: e.float_in("timezone", 9.0, -14.0..=14.0)?,
                    };
                    let local = sun::sun_direction(&t);
                    to_world.unwrap_or(DMat4::IDENTITY).transform_vector3(local)
                }
            };
            if dir.length_squared() == 0.0 {
                return Err(ImportError::at(&e.loc, "sun_direction must not be zero"));
            }
            sec.set("sun_direction", TVal::vec3(dir.normalize().to_array()));
            if let Some(m) = to_world {
                let up = m.transform_vector3(DVec3::Y);
                if !(up.length_squared() > 0.0) {
                    return Err(ImportError::at(&e.loc, "to_world maps the sky's zenith (0, 1, 0) to zero"));
                }
                sec.set("up", TVal::vec3(up.normalize().to_array()));
            }
            if e.plugin != "sun" {
                sec.set("turbidity", TVal::Num(e.float("turbidity", 3.0)?));
                sec.set("albedo", TVal::Num(e.float("albedo", 0.15)?));
            } else {
                sec.set("turbidity", TVal::Num(e.float("turbidity", 3.0)?));
            }
            if e.plugin != "sky" {
                sec.set("sun_scale", TVal::Num(e.float("sun_scale", 1.0)?));
            }
            if e.plugin != "sun" {
                sec.set("sky_scale", TVal::Num(e.float("sky_scale", 1.0)?));
            }
            let radius_scale = e.float("sun_radius_scale", 1.0)?;
            if radius_scale != 1.0 {
                w.warn(
                    &e.loc,
                    format!("sun_radius_scale {radius_scale} is not supported: the sun keeps its real size"),
                );
            }
            e.ignore(&["resolution", "stretch", "extend", "scale"]);
        }
        other => {
            w.warn(&e.loc, format!("emitter '{other}' is not supported (plexus has area lights and one environment; no point, spot or directional lights) and was left out"));
            for p in &e.props {
                p.used.set(true);
            }
            return Ok(None);
        }
    }
    Ok(Some(sec))
}

fn orthonormalise(m: DMat3) -> DMat3 {
    let x = m.x_axis.normalize_or_zero();
    let y = (m.y_axis - x * x.dot(m.y_axis)).normalize_or_zero();
    let z = x.cross(y);
    if x == DVec3::ZERO || y == DVec3::ZERO {
        DMat3::IDENTITY
    } else {
        DMat3::from_cols(x, y, z)
    }
}
