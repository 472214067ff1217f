//! The path tracer's render: each tile's samples in the film's order, the camera rays of eight
//! consecutive samples traced as one packet (`Scene::hits_coherent`) before each of their paths goes
//! on from its hit (`PathTracer::li_from_hit`).

use glam::{Vec2, Vec3};

use super::PathTracer;
use crate::geometry::Ray;
use crate::integrator::driver::{ImageIntegrator, ImageRender, ImageRun, Slot};
use crate::integrator::{Progress, RenderError, RenderJob};
use crate::sampling::{PixelSampler, SamplerKind, SobolStream, UniformSource};
use crate::scene::Scene;
use crate::spectrum::{is_finite, Rgb};
use crate::state::Session;

/// Camera rays traced together (`Scene::hits_coherent`): Embree's packet width.
const CAMERA_PACKET: usize = crate::accel::embree::PACKET_WIDTH;

impl PathTracer {
    /// The render with its unnormalised film (`Integrator::render` keeps only the output).
    pub fn render_run(&self, scene: &Scene, job: &RenderJob, progress: &dyn Progress) -> Result<ImageRun, RenderError> {
        self.render_run_session(scene, job, progress, Session::default(), false)
    }
}

impl ImageIntegrator for PathTracer {
    /// [`Self::render_run`] under a session (`crate::state`): resumed, sharded, stopped early;
    /// with `save`, `ImageRun::state` holds the state reached.
    fn render_run_session(
        &self,
        scene: &Scene,
        job: &RenderJob,
        progress: &dyn Progress,
        session: Session,
        save: bool,
    ) -> Result<ImageRun, RenderError> {
        let render = ImageRender::new(job, scene.camera.width, scene.camera.height, progress)?
            .with_session(session, save)?
            .with_sampler(self.settings.sampler);
        // `li` adds only finite contributions, but their sum can still overflow.
        let record = |x: u32, y: u32, l: Rgb, slot: &mut Slot<()>| {
            if is_finite(l) {
                slot.film.add(x as usize, y as usize, l);
            } else {
                slot.counters.nonfinite_dropped += 1;
            }
        };
        let camera_ray =
            |x: u32, y: u32, u: [f32; 2]| scene.camera.ray_through(Vec2::new(x as f32 + u[0], y as f32 + u[1]));
        // The camera rays of CAMERA_PACKET consecutive samples (one pixel's, then its
        // neighbour's) are made first and traced as one packet, and then each path goes on from
        // its hit, in the same order. A Sobol sample's numbers are its own stream's; the
        // independent sampler's come from the work item's generator, the packet's eight camera
        // positions first and then each path's numbers.
        let sobol = self.settings.sampler == SamplerKind::Sobol;
        let (run, _) = render.run_tiles(
            |_| (),
            |samples, rng, slot| {
                let mut streams: [SobolStream; CAMERA_PACKET] = std::array::from_fn(|_| SobolStream::new(0, 0));
                let mut pixels = [(0, 0); CAMERA_PACKET];
                let mut rays = [Ray::new(Vec3::ZERO, Vec3::Z); CAMERA_PACKET];
                let mut hits = [None; CAMERA_PACKET];
                let mut order = samples.iter();
                loop {
                    let mut n = 0;
                    for (x, y, index) in order.by_ref().take(CAMERA_PACKET) {
                        let u = if sobol {
                            streams[n] = PixelSampler::sobol_stream(samples.seed, x, y, index, 0);
                            streams[n].next_2d()
                        } else {
                            rng.next_2d()
                        };
                        rays[n] = camera_ray(x, y, u);
                        pixels[n] = (x, y);
                        n += 1;
                    }
                    if n == 0 {
                        break;
                    }
                    scene.hits_coherent(&rays[..n], &mut hits[..n]);
                    for k in 0..n {
                        let counters = &mut slot.counters;
                        let l = if sobol {
                            self.li_from_hit(scene, rays[k], hits[k], &mut streams[k], counters)
                        } else {
                            self.li_from_hit(scene, rays[k], hits[k], rng, counters)
                        };
                        record(pixels[k].0, pixels[k].1, l, slot);
                    }
                }
            },
        );
        Ok(run)
    }
}
