//! Path vertices as bidirectional path tracing stores them: position and normals, the throughput
//! `beta` of the subpath up to the vertex, and the densities of sampling the vertex from either
//! side in AREA measure (solid angle for vertices at infinity), as Veach's thesis Sec. 10.2 and
//! pbrt-v4 Sec. 13.4 keep them for the MIS ratio recurrence.

use glam::{Vec2, Vec3};

use crate::geometry::{Frame, SurfaceInteraction};
use crate::material::{Bsdf, TransportMode};
use crate::scene::Scene;
use crate::spectrum::Rgb;

/// What a vertex is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum VertexKind {
    /// The pinhole (the first vertex of every camera subpath, or the camera point a `t = 1`
    /// connection samples).
    Camera,
    /// A point on an emitter that starts a light subpath (or that a `s = 1` connection samples);
    /// for an environment, a vertex at infinity (`infinite`).
    Light,
    /// A surface hit (possibly on an emitter: the `s = 0` technique uses it as a light vertex), or,
    /// with `infinite`, a camera ray that escaped to the environment.
    Surface,
}

/// One vertex of a camera or light subpath.
#[derive(Clone, Copy, Debug, serde::Serialize, serde::Deserialize)]
pub struct Vertex {
    pub kind: VertexKind,
    pub p: Vec3,
    /// Conservative error bound of `p` (for robust shadow rays).
    pub p_error: Vec3,
    /// Unit geometric normal; zero for the camera and for vertices at infinity (not on a surface).
    pub ng: Vec3,
    /// Shading frame (surface vertices); its `n` is the shading normal.
    pub frame: Frame,
    /// Unit direction towards the previous vertex of the same subpath (surface vertices).
    pub wo: Vec3,
    /// For vertices at infinity: the unit direction light travels, from the environment into the
    /// scene.
    pub dir: Vec3,
    /// Index into `Scene::materials` (surface vertices).
    pub material: u32,
    /// Surface coordinates, where the material's textures are looked up (surface vertices).
    pub uv: Vec2,
    /// Index into `Scene::lights` of the emitter at this vertex (light vertices, emissive surfaces,
    /// escaped camera rays when the scene has an environment).
    pub light: Option<u32>,
    /// Whether the vertex is at infinity (an environment emitter).
    pub infinite: bool,
    /// Whether the direction leaving this vertex along the subpath was drawn from a delta lobe:
    /// no technique can connect at such a vertex.
    pub delta: bool,
    /// Radiance for camera subpaths, importance for light subpaths.
    pub mode: TransportMode,
    /// Throughput of the subpath up to and including this vertex (f·cos / pdf products, with the
    /// emitted radiance or camera importance of the first vertex folded in).
    pub beta: Rgb,
    /// Area density of sampling this vertex from the previous one of its subpath.
    pub pdf_fwd: f32,
    /// Area density of sampling this vertex from the next one (as the opposite subpath would).
    pub pdf_rev: f32,
}

impl Vertex {
    /// Whether a vertex read from a state file (untrusted numbers) can be used in `scene`: finite
    /// geometry, and a material and emitter the scene has (its vertices become rays and lookups).
    pub fn is_valid_in(&self, scene: &Scene) -> bool {
        [self.p, self.p_error, self.ng, self.frame.s, self.frame.t, self.frame.n, self.wo, self.dir]
            .iter()
            .all(|x| x.is_finite())
            && self.uv.is_finite()
            && (self.material as usize) < scene.materials.len().max(1)
            && self.light.is_none_or(|l| (l as usize) < scene.lights.len())
    }

    fn blank(kind: VertexKind, mode: TransportMode) -> Vertex {
        Vertex {
            kind,
            p: Vec3::ZERO,
            p_error: Vec3::ZERO,
            ng: Vec3::ZERO,
            frame: Frame::from_normal(Vec3::Z),
            wo: Vec3::ZERO,
            dir: Vec3::ZERO,
            material: 0,
            uv: Vec2::ZERO,
            light: None,
            infinite: false,
            delta: false,
            mode,
            beta: Rgb::ZERO,
            pdf_fwd: 0.0,
            pdf_rev: 0.0,
        }
    }

    /// The pinhole at `p` with throughput `beta`.
    pub fn camera(p: Vec3, beta: Rgb) -> Vertex {
        Vertex { p, beta, ..Vertex::blank(VertexKind::Camera, TransportMode::Radiance) }
    }

    /// A point on area light `light` with geometric normal `n`.
    pub fn area_light(light: u32, p: Vec3, n: Vec3, beta: Rgb, pdf_fwd: f32) -> Vertex {
        Vertex {
            p,
            // Points sampled on triangles by barycentric interpolation: the same bound as a hit.
            p_error: crate::geometry::gamma(7) * p.abs(),
            ng: n,
            frame: Frame::from_normal(n),
            light: Some(light),
            beta,
            pdf_fwd,
            ..Vertex::blank(VertexKind::Light, TransportMode::Importance)
        }
    }

    /// An environment emitter seen as a vertex at infinity; light travels along `dir`.
    pub fn environment_light(light: u32, dir: Vec3, beta: Rgb, pdf_fwd: f32) -> Vertex {
        Vertex {
            dir,
            light: Some(light),
            infinite: true,
            beta,
            pdf_fwd,
            ..Vertex::blank(VertexKind::Light, TransportMode::Importance)
        }
    }

    /// A camera ray that left the scene in direction `d`: the environment `light` (if any) as a
    /// vertex at infinity, so that the `s = 0` technique can count it.
    pub fn escaped(light: Option<u32>, d: Vec3, beta: Rgb, pdf_fwd_solid_angle: f32) -> Vertex {
        Vertex {
            dir: -d,
            light,
            infinite: true,
            beta,
            pdf_fwd: pdf_fwd_solid_angle,
            ..Vertex::blank(VertexKind::Surface, TransportMode::Radiance)
        }
    }

    /// A surface hit reached along a ray from the previous vertex.
    pub fn surface(scene: &Scene, si: &SurfaceInteraction, wo: Vec3, beta: Rgb, mode: TransportMode) -> Vertex {
        let shape = &scene.shapes[si.geom_id as usize];
        Vertex {
            p: si.p,
            p_error: si.p_error,
            ng: si.ng,
            frame: si.shading,
            wo,
            material: shape.material,
            uv: si.uv,
            light: shape.light,
            beta,
            ..Vertex::blank(VertexKind::Surface, mode)
        }
    }

    /// Whether the vertex lies on a surface (has a normal that cosines are taken against).
    #[inline]
    pub fn on_surface(&self) -> bool {
        self.ng != Vec3::ZERO
    }

    /// Whether an emitter sits at this vertex (an area light, an environment, an emissive surface).
    #[inline]
    pub fn is_light(&self) -> bool {
        self.kind == VertexKind::Light || self.light.is_some()
    }

    /// Whether a connection can be made here: a surface with a non-delta BSDF, an emitter point or
    /// the camera (pbrt's `IsConnectible`; there are no delta lights or cameras with a lens here).
    pub fn connectible(&self, scene: &Scene) -> bool {
        match self.kind {
            VertexKind::Camera | VertexKind::Light => true,
            VertexKind::Surface => !self.infinite && !scene.materials[self.material as usize].is_specular(),
        }
    }

    /// Unit direction from this vertex towards `other` (towards the environment when `other` is at
    /// infinity).
    #[inline]
    pub fn dir_to(&self, other: &Vertex) -> Vec3 {
        if other.infinite {
            -other.dir
        } else if self.infinite {
            self.dir
        } else {
            (other.p - self.p).normalize_or_zero()
        }
    }

    /// The BSDF at this surface vertex (its material's textures looked up at its uv).
    pub fn bsdf(&self, scene: &Scene) -> Bsdf {
        scene.bsdf(self.material, self.uv)
    }

    /// BSDF value for light scattered at this surface vertex between `wo` and the direction to
    /// `next`, including the shading-normal correction for importance transport (Veach's thesis
    /// Sec. 5.3, pbrt-v4 Eq. 13.9) so that the adjoint BSDF is used on light subpaths.
    pub fn f(&self, scene: &Scene, next: &Vertex) -> Rgb {
        let wi = self.dir_to(next);
        self.f_dir(scene, wi)
    }

    /// `f` towards a world direction `wi`.
    pub fn f_dir(&self, scene: &Scene, wi: Vec3) -> Rgb {
        if self.kind != VertexKind::Surface || self.infinite {
            return Rgb::ZERO;
        }
        let wo_l = self.frame.to_local(self.wo);
        let wi_l = self.frame.to_local(wi);
        let f = self.bsdf(scene).eval(wo_l, wi_l, self.mode);
        f * shading_correction(self.mode, self.wo, wi, self.frame.n, self.ng)
    }

    /// Converts a solid-angle density at this vertex of sampling the direction towards `next` into
    /// an area density at `next` (solid angle is kept for vertices at infinity).
    pub fn convert_density(&self, pdf: f32, next: &Vertex) -> f32 {
        if next.infinite {
            return pdf;
        }
        let w = next.p - self.p;
        let d2 = w.length_squared();
        if d2 == 0.0 {
            return 0.0;
        }
        let inv_d2 = 1.0 / d2;
        let mut pdf = pdf * inv_d2;
        if next.on_surface() {
            pdf *= next.ng.dot(w * inv_d2.sqrt()).abs();
        }
        pdf
    }

    /// Area density at `next` of sampling it from this vertex, having arrived from `prev`
    /// (pbrt-v4's `Vertex::PDF`). At the camera and at light vertices, the density of their
    /// directional sampling; at surfaces, the BSDF's density (with transport `mode` of the subpath
    /// that would do the sampling).
    pub fn pdf(&self, scene: &Scene, prev: Option<&Vertex>, next: &Vertex) -> f32 {
        match self.kind {
            VertexKind::Light => return self.pdf_light(scene, next),
            VertexKind::Camera => {
                let d = self.dir_to(next);
                let (_, pdf_dir) = scene.camera.pdf_we(d);
                return self.convert_density(pdf_dir, next);
            }
            VertexKind::Surface => {}
        }
        if self.infinite {
            return 0.0;
        }
        let Some(prev) = prev else { return 0.0 };
        let wp = self.frame.to_local(self.dir_to(prev));
        let wn = self.frame.to_local(self.dir_to(next));
        let pdf = self.bsdf(scene).pdf(wp, wn, self.mode);
        self.convert_density(pdf, next)
    }

    /// Area density at `next` (solid angle... for surfaces, area) of the emitter at this vertex
    /// emitting towards it (pbrt-v4's `PDFLight`). For an environment, the density of the ray's
    /// origin on the disk perpendicular to its direction, converted to area at `next` by the
    /// cosine alone.
    pub fn pdf_light(&self, scene: &Scene, next: &Vertex) -> f32 {
        let Some(li) = self.light else { return 0.0 };
        let light = &scene.lights[li as usize];
        if self.infinite {
            let (pdf_pos, _) = light.pdf_emission(next.p, self.dir, self.dir);
            let mut pdf = pdf_pos;
            if next.on_surface() {
                pdf *= next.ng.dot(self.dir).abs();
            }
            return pdf;
        }
        let w = self.dir_to(next);
        let (_, pdf_dir) = light.pdf_emission(self.p, self.ng, w);
        self.convert_density(pdf_dir, next)
    }

    /// Density of choosing this emitter point as the origin of a light subpath that continues to
    /// `next` (pbrt-v4's `PDFLightOrigin`): light selection times the area density of the point,
    /// or, at infinity, times the solid-angle density of the direction.
    pub fn pdf_light_origin(&self, scene: &Scene, next: &Vertex) -> f32 {
        let Some(li) = self.light else { return 0.0 };
        let light = &scene.lights[li as usize];
        let distribution = &scene.light_sampler.distribution;
        if distribution.is_empty() {
            return 0.0;
        }
        let pmf = distribution.pdf_discrete(li as usize);
        if self.infinite {
            pmf * light.pdf_li(next.p, -self.dir, Vec3::ZERO, Vec3::ZERO)
        } else {
            let w = self.dir_to(next);
            let (pdf_pos, _) = light.pdf_emission(self.p, self.ng, w);
            pmf * pdf_pos
        }
    }

    /// Radiance the emitter at this vertex sends towards `towards` (zero when nothing emits here).
    pub fn le(&self, scene: &Scene, towards: &Vertex) -> Rgb {
        let Some(li) = self.light else { return Rgb::ZERO };
        let light = &scene.lights[li as usize];
        if self.infinite {
            // The environment radiance seen when looking along -dir.
            return light.environment_radiance(-self.dir);
        }
        let w = self.dir_to(towards);
        light.emitted(self.ng, w)
    }
}

/// The factor that turns f(wo, wi) with shading normals into the adjoint BSDF for importance
/// transport: |wo·ns| |wi·ng| / (|wo·ng| |wi·ns|) (Veach's thesis Eq. 5.17; pbrt-v4 Eq. 10.17).
/// One for radiance.
#[inline]
pub fn shading_correction(mode: TransportMode, wo: Vec3, wi: Vec3, ns: Vec3, ng: Vec3) -> f32 {
    if mode == TransportMode::Radiance {
        return 1.0;
    }
    let num = wo.dot(ns).abs() * wi.dot(ng).abs();
    let den = wo.dot(ng).abs() * wi.dot(ns).abs();
    if den == 0.0 {
        0.0
    } else {
        num / den
    }
}

/// The generalised geometry term between two vertices without visibility: cosines at surface
/// vertices (shading normals, as the throughput uses them) over the squared distance.
pub fn geometry_term(a: &Vertex, b: &Vertex) -> f32 {
    let d = b.p - a.p;
    let d2 = d.length_squared();
    if d2 == 0.0 {
        return 0.0;
    }
    let w = d / d2.sqrt();
    let mut g = 1.0 / d2;
    if a.on_surface() {
        g *= a.frame.n.dot(w).abs();
    }
    if b.on_surface() {
        g *= b.frame.n.dot(w).abs();
    }
    g
}
