//! Sun and sky (`[environment] type = "sunsky" | "sun" | "sky"`), baked into an equirectangular
//! map that the image environment importance-samples (so MIS, BDPT and the MLT inverses handle it
//! as any environment map).
//!
//! - **Sky**: Preetham, Shirley and Smits 1999, "A Practical Analytic Model for Daylight": the
//!   Perez distribution F(θ, γ) = (1 + A e^{B/cos θ})(1 + C e^{Dγ} + E cos²γ) for Y, x and y with
//!   the paper's turbidity-linear coefficients (Appendix A.2), the zenith luminance and
//!   chromaticities of its Eq. A.1–A.3, xyY → XYZ → linear sRGB. Luminance in kcd/m² is divided by
//!   the luminous efficacy 683 lm/W (×1000), so one unit is 1 W m⁻² sr⁻¹ of 555 nm light.
//!   Mitsuba 3's `sunsky` is Hosek–Wilkie's model and Mitsuba 0.6's `sky` a Preetham variant with
//!   its own scaling: the two renderers' skies differ (a cross-check must give both the same map).
//! - **Sun**: a disk of angular radius 0.2667° (solid angle 6.8e-5 sr), radiance 1.6e9 cd/m²
//!   above the atmosphere (÷683), attenuated per channel (610, 550, 465 nm) by Rayleigh
//!   (τ = 0.008735 λ^−4.08) and aerosol (Ångström τ = β λ^−1.3, Preetham's β = 0.04608 T −
//!   0.04586) optical depths over the Kasten–Young air mass. Limb darkening is ignored.
//! - **Ground** (directions below the horizon): a Lambertian ground of `albedo` lit by the baked
//!   sky and sun, L = albedo·E/π (Preetham has no ground term; this uses Mitsuba's `albedo` key for
//!   what it names).
//!
//! The map's pole (+y of the map, row 0) is the sun, and the map has H = round(π/θ_sun) rows, so
//! row 0 — every texel with θ < π/H — is exactly the sun's disk (θ_sun re-rounded to π/H, within
//! 0.1%), of solid angle 2π(1 − cos θ_sun): the sun is a true small disk, not a delta light, and
//! its texels carry only sun.
//!
//! The model and `bake` work in the sky frame, y up. A scene whose zenith is another world
//! direction `up` (a Z-up Mitsuba scene, say) is baked in that frame and [`world_to_sky`] is
//! composed into the map's world-to-map rotation ([`BakedMap::in_world`]), so radiance lookups and
//! importance sampling both see the rotated sky.

use std::f64::consts::PI;

use glam::{DVec3, Mat3, Quat, Vec2, Vec3};

use super::environment::equirect_to_direction;
use crate::spectrum::Rgb;

/// Angular radius of the sun, radians (0.2667°).
pub const SUN_ANGULAR_RADIUS: f64 = 0.2667 * PI / 180.0;

/// Which parts to bake.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SunSkyParts {
    Sun,
    Sky,
    Both,
}

/// Validated parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SunSky {
    pub parts: SunSkyParts,
    /// Unit direction towards the sun in the sky frame (y up), above the horizon.
    pub sun_direction: Vec3,
    pub turbidity: f32,
    pub albedo: f32,
    pub sun_scale: f32,
    pub sky_scale: f32,
}

/// A baked map: `width`×`height` texels (row 0 at the map's +y) and the world-to-map rotation.
pub struct BakedMap {
    pub width: usize,
    pub height: usize,
    pub texels: Vec<Rgb>,
    pub to_local: Mat3,
}

impl BakedMap {
    /// The map of a sky baked in the sky frame, placed in a world whose rotation into that frame is
    /// `world_to_sky`: world → sky frame → map, so `to_local` becomes `to_local · world_to_sky`.
    pub fn in_world(mut self, world_to_sky: Mat3) -> BakedMap {
        self.to_local *= world_to_sky;
        self
    }
}

/// The rotation from world space into the sky frame for a sky whose zenith is the unit world
/// direction `up`: the shortest arc taking `up` to +y (any rotation about the zenith would do; the
/// shortest arc is the identity for `up` = +y, so y-up scenes bake exactly as before).
pub fn world_to_sky(up: Vec3) -> Mat3 {
    Mat3::from_quat(Quat::from_rotation_arc(up, Vec3::Y))
}

fn xyz_to_srgb(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(
        3.240_454_2 * x - 1.537_138_5 * y - 0.498_531_4 * z,
        -0.969_266 * x + 1.876_010_8 * y + 0.041_556 * z,
        0.055_643_4 * x - 0.204_025_9 * y + 1.057_225_2 * z,
    )
}

/// Perez coefficients (A..E) for Y, x, y at turbidity `t` (Preetham Appendix A.2).
fn perez_coefficients(t: f64) -> [[f64; 5]; 3] {
    [
        [0.1787 * t - 1.4630, -0.3554 * t + 0.4275, -0.0227 * t + 5.3251, 0.1206 * t - 2.5771, -0.0670 * t + 0.3703],
        [-0.0193 * t - 0.2592, -0.0665 * t + 0.0008, -0.0004 * t + 0.2125, -0.0641 * t - 0.8989, -0.0033 * t + 0.0452],
        [-0.0167 * t - 0.2608, -0.0950 * t + 0.0092, -0.0079 * t + 0.2102, -0.0441 * t - 1.6537, -0.0109 * t + 0.0529],
    ]
}

fn perez(c: &[f64; 5], cos_theta: f64, gamma: f64) -> f64 {
    (1.0 + c[0] * (c[1] / cos_theta.max(1e-3)).exp()) * (1.0 + c[2] * (c[3] * gamma).exp() + c[4] * gamma.cos().powi(2))
}

/// The Preetham sky: radiance (linear sRGB, see the module doc) towards world direction `w`
/// (y up, above the horizon) for the sun at `sun` (unit, above the horizon).
pub fn preetham_sky(turbidity: f64, sun: DVec3, w: DVec3) -> DVec3 {
    let t = turbidity;
    let theta_s = sun.y.clamp(-1.0, 1.0).acos();
    let chi = (4.0 / 9.0 - t / 120.0) * (PI - 2.0 * theta_s);
    let y_zenith = ((4.0453 * t - 4.9710) * chi.tan() - 0.2155 * t + 2.4192).max(0.0);
    let (s1, s2, s3) = (theta_s, theta_s * theta_s, theta_s * theta_s * theta_s);
    let x_zenith = t * t * (0.00166 * s3 - 0.00375 * s2 + 0.00209 * s1)
        + t * (-0.02903 * s3 + 0.06377 * s2 - 0.03202 * s1 + 0.00394)
        + (0.11693 * s3 - 0.21196 * s2 + 0.06052 * s1 + 0.25886);
    let yc_zenith = t * t * (0.00275 * s3 - 0.00610 * s2 + 0.00317 * s1)
        + t * (-0.04214 * s3 + 0.08970 * s2 - 0.04153 * s1 + 0.00516)
        + (0.15346 * s3 - 0.26756 * s2 + 0.06670 * s1 + 0.26688);
    let coeffs = perez_coefficients(t);
    let cos_theta = w.y;
    let gamma = w.dot(sun).clamp(-1.0, 1.0).acos();
    let value = |c: &[f64; 5], zenith: f64| zenith * perez(c, cos_theta, gamma) / perez(c, 1.0, theta_s);
    let lum = value(&coeffs[0], y_zenith) * 1000.0 / 683.0;
    let x = value(&coeffs[1], x_zenith);
    let y = value(&coeffs[2], yc_zenith).max(1e-6);
    xyz_to_srgb(x / y * lum, lum, (1.0 - x - y) / y * lum).max(DVec3::ZERO)
}

/// The sun's radiance (linear sRGB) at elevation given by `cos_zenith`.
pub fn sun_radiance(turbidity: f64, cos_zenith: f64) -> DVec3 {
    let zenith_deg = cos_zenith.clamp(0.0, 1.0).acos().to_degrees();
    // Kasten–Young (1989) relative optical air mass.
    let air_mass = 1.0 / (cos_zenith.max(0.0) + 0.50572 * (96.07995 - zenith_deg).powf(-1.6364));
    let beta = (0.04608 * turbidity - 0.04586).max(0.0);
    let transmittance = |lambda_um: f64| {
        let tau_rayleigh = 0.008735 * lambda_um.powf(-4.08);
        let tau_aerosol = beta * lambda_um.powf(-1.3);
        (-air_mass * (tau_rayleigh + tau_aerosol)).exp()
    };
    let l0 = 1.6e9 / 683.0;
    DVec3::new(transmittance(0.61), transmittance(0.55), transmittance(0.465)) * l0
}

/// Bakes `p` (see the module doc).
pub fn bake(p: &SunSky) -> BakedMap {
    let height = (PI / SUN_ANGULAR_RADIUS).round() as usize;
    let width = 2 * height;
    let sun = p.sun_direction.as_dvec3().normalize();
    // Map frame: its +y is the sun; rows of `to_local` are the map axes in world coordinates.
    let helper = if sun.x.abs() < 0.9 { DVec3::X } else { DVec3::Z };
    let ax = helper.cross(sun).normalize();
    let az = ax.cross(sun);
    let to_local = Mat3::from_cols(ax.as_vec3(), sun.as_vec3(), az.as_vec3()).transpose();
    let to_world = to_local.transpose();
    let t = f64::from(p.turbidity);
    let with_sky = p.parts != SunSkyParts::Sun;
    let with_sun = p.parts != SunSkyParts::Sky;
    let sun_l = sun_radiance(t, sun.y) * f64::from(p.sun_scale);
    let mut texels = vec![Rgb::ZERO; width * height];
    // Horizontal irradiance from above the horizon, for the ground.
    let mut irradiance = DVec3::ZERO;
    let mut below = Vec::new();
    for j in 0..height {
        let (theta0, theta1) = (PI * j as f64 / height as f64, PI * (j + 1) as f64 / height as f64);
        let texel_solid_angle = 2.0 * PI * (theta0.cos() - theta1.cos()) / width as f64;
        for i in 0..width {
            let d = equirect_to_direction(Vec2::new((i as f32 + 0.5) / width as f32, (j as f32 + 0.5) / height as f32));
            let w = (to_world * d).as_dvec3().normalize();
            let k = j * width + i;
            if w.y <= 0.0 {
                below.push(k);
                continue;
            }
            let l = if j == 0 {
                if with_sun {
                    sun_l
                } else {
                    DVec3::ZERO
                }
            } else if with_sky {
                preetham_sky(t, sun, w) * f64::from(p.sky_scale)
            } else {
                DVec3::ZERO
            };
            irradiance += l * w.y * texel_solid_angle;
            texels[k] = l.as_vec3();
        }
    }
    let ground = (irradiance * f64::from(p.albedo) / PI).as_vec3();
    for k in below {
        texels[k] = ground;
    }
    BakedMap { width, height, texels, to_local }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::Environment;

    /// The baked sun is a disk of the sun's solid angle: row 0's texels cover exactly
    /// 2π(1 − cos(π/H)), within 0.2% of 2π(1 − cos 0.2667°), and carry the sun's radiance; a
    /// direction 0.3° from the sun (outside the disk) gets sky, not sun (the wrong variant, a disk
    /// twice as wide, would give sun there).
    #[test]
    fn sun_is_a_disk_of_the_right_solid_angle() {
        let p = SunSky {
            parts: SunSkyParts::Both,
            sun_direction: Vec3::new(0.3, 0.8, 0.2).normalize(),
            turbidity: 3.0,
            albedo: 0.15,
            sun_scale: 1.0,
            sky_scale: 1.0,
        };
        let map = bake(&p);
        let omega_row0 = 2.0 * PI * (1.0 - (PI / map.height as f64).cos());
        let omega_sun = 2.0 * PI * (1.0 - SUN_ANGULAR_RADIUS.cos());
        assert!((omega_row0 / omega_sun - 1.0).abs() < 2e-3, "{omega_row0} vs {omega_sun}");
        let sun = sun_radiance(3.0, f64::from(p.sun_direction.y));
        assert!(map.texels[..map.width].iter().all(|t| (t.as_dvec3() - sun).abs().max_element() < 1e-3 * sun.x));
        assert!(map.texels[map.width..2 * map.width].iter().all(|t| t.x < 1e-3 * sun.x as f32));
        // The sun outshines the sky by ~1e5 and the horizontal irradiance is daylight-like.
        let zenith = preetham_sky(3.0, p.sun_direction.as_dvec3(), DVec3::Y);
        assert!(sun.y / zenith.y > 1e4 && zenith.min_element() > 0.0, "{sun:?} {zenith:?}");
        // Clear sky at the zenith is bluer than the sun.
        assert!(zenith.z / zenith.x > sun.z / sun.x);
    }

    /// A Z-up sky is the Y-up sky rotated: with `up` = +z and the sun rotated by Q = R_x(90°)
    /// (which takes +y to +z), radiance and the sampling pdf at Q·w equal those of the y-up sky at
    /// w, for w at the centres of a lattice of 494 texels of the y-up map (sun row, sky, ground;
    /// texel centres, so float rounding of the rotations cannot move a lookup to a neighbouring
    /// texel), to 1e-3 relative (the maps agree to ~1e-6). The wrong composition — the map baked
    /// in the sky frame with `world_to_sky` left out of `to_local` — fails it in 345 of the 494
    /// directions (measured; the rest are ground texels, uniform in both).
    #[test]
    fn up_rotates_the_sky_with_lookups_and_pdf() {
        use crate::geometry::Aabb;
        use crate::light::ImageEnvironment;
        let p = SunSky {
            parts: SunSkyParts::Both,
            sun_direction: Vec3::new(0.4, 0.5, -0.6).normalize(),
            turbidity: 4.0,
            albedo: 0.3,
            sun_scale: 1.0,
            sky_scale: 1.0,
        };
        let q = Mat3::from_rotation_x(std::f32::consts::FRAC_PI_2);
        assert!((q * Vec3::Y - Vec3::Z).length() < 1e-6);
        let bounds = Aabb { min: Vec3::splat(-1.0), max: Vec3::splat(1.0) };
        let env = |m: BakedMap| ImageEnvironment::new(m.width, m.height, m.texels, 1.0, m.to_local, bounds);
        let reference = bake(&p);
        let to_world_y = reference.to_local.transpose();
        let (width, height) = (reference.width, reference.height);
        let y_up = env(reference);
        // What the loader does for `up` = +z and `sun_direction` = Q·s.
        let to_sky = world_to_sky(Vec3::Z);
        let z_sky = SunSky { sun_direction: (to_sky * q * p.sun_direction).normalize(), ..p };
        let z_up = env(bake(&z_sky).in_world(to_sky));
        let wrong = env(bake(&z_sky));
        let close = |a: f32, b: f32| (a - b).abs() <= 1e-3 * a.abs().max(b.abs()) + 1e-12;
        let (mut n, mut wrong_fails) = (0, 0);
        for j in (0..height).step_by(37) {
            for i in (0..width).step_by(53) {
                let d =
                    equirect_to_direction(Vec2::new((i as f32 + 0.5) / width as f32, (j as f32 + 0.5) / height as f32));
                let w = (to_world_y * d).normalize();
                let (l, pdf) = (y_up.radiance(w), y_up.pdf_direction(w));
                let (lz, pdfz) = (z_up.radiance(q * w), z_up.pdf_direction(q * w));
                assert!((0..3).all(|c| close(l[c], lz[c])) && close(pdf, pdfz), "{w}: {l:?} {pdf} vs {lz:?} {pdfz}");
                let (lw, pdfw) = (wrong.radiance(q * w), wrong.pdf_direction(q * w));
                if !((0..3).all(|c| close(l[c], lw[c])) && close(pdf, pdfw)) {
                    wrong_fails += 1;
                }
                n += 1;
            }
        }
        assert_eq!(n, 494);
        assert!(wrong_fails > n / 2, "the wrong composition failed only {wrong_fails} of {n}");
    }
}
