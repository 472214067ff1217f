//! `integrator = "emlt"`: Algorithm 1 of the paper on the path-space chain.
//!
//! - **Bootstrap and ensembles** (Sec. 3.4): pmlt's BDPT bootstrap estimates b; the 2|X| chains
//!   (X = chains 0 … |X| − 1, Y the rest) are started by resampling it, exactly as pmlt starts its
//!   chains (`path_space::chain`), each chain with its own stream from (seed, chain index).
//! - **Iterations** (Algorithm 1): every chain of X takes `it` = max(1, ⌊W·H/(|X| + |Y|)⌋) steps of
//!   pmlt's Metropolis–Hastings `step` (the paper's ⌊W·H/(|X|+|Y|)⌋ is 0 for images smaller than the
//!   ensembles) with the strategies bidirectional, linear lens, linear caustic, linear
//!   multi-chain, anisotropic path and environment (`EmltSettings::perturbations`
//!   switches them), the guided ones
//!   reading Y (its paths and its tree, rebuilt here at each swap, `tree`); then X and Y swap. X's
//!   chains run in parallel on the driver as its units, Y fixed: the complementary split that
//!   keeps the parallel update valid (`toy` module docs). Splats are pmlt's expected values.
//! - **Normalisation**: as pmlt, the film times b·P/N, N the iterations of all chains.
//!
//! Determinism: a chain's proposals read only its own stream, its path and Y (fixed during the
//! half-iteration); the driver applies the chains' splats in chain order. So the image depends on
//! the seed and the settings only, not on the thread count.

use std::sync::Arc;
use std::time::{Duration, Instant};

use serde::Serialize;

use super::anisotropic_path::{AnisotropicPath, GuideContext};
use super::environment::Environment;
use super::guide::{GuideCounts, GuideReport, GuideView};
use super::linear::{GuidedKernel, LinearCaustic, LinearLens, LinearMultiChain};
use super::settings::EmltSettings;
use crate::film::Accumulator;
use crate::integrator::driver::{Driver, PassSet, Passes, RunControl, RunStart, Slot};
use crate::integrator::path_space::bidirectional::{Bidirectional, LengthKernel};
use crate::integrator::path_space::caustic::CausticKernel;
use crate::integrator::path_space::chain::{new_stats, step, ChainUnit};
use crate::integrator::path_space::kernel::RasterKernel;
use crate::integrator::path_space::multichain::MultiChainKernel;
use crate::integrator::path_space::{Entry, PathContext, Pmlt, PmltSettings, StrategySet};
use crate::integrator::pss::bootstrap::run_bootstrap;
use crate::integrator::{Budget, Integrator, Progress, RenderError, RenderJob, RenderOutput};
use crate::sampling::Distribution1D;
use crate::scene::Scene;
use crate::stats::AcceptanceCount;

/// The guided strategies with counts: linear lens, linear caustic, linear multi-chain, anisotropic
/// path (whose counts are per fit: Gaussian fits as guided, degenerate ones as fallbacks) and
/// environment.
const GUIDED_STRATEGIES: usize = 5;

/// Ensemble MLT (module docs).
#[derive(Clone, Debug, Default)]
pub struct Emlt {
    pub settings: EmltSettings,
    /// The linear lens perturbation (a value, so that tests can render with a deliberately wrong
    /// one).
    pub linear_lens: LinearLens,
    /// The anisotropic path perturbation (a value for the same reason).
    pub anisotropic_path: AnisotropicPath,
    /// The linear caustic perturbation (a value for the same reason).
    pub linear_caustic: LinearCaustic,
    /// The bidirectional mutation (a value for the same reason).
    pub bidirectional: Bidirectional,
}

/// The ensemble part of the JSON statistics.
#[derive(Debug, Default, Serialize)]
pub struct EnsembleReport {
    pub ensemble_size: u64,
    pub iterations_per_swap: u64,
    pub swaps: u64,
    pub tree_rebuild_seconds: f64,
    /// Signatures (buckets) in the last tree built.
    pub signatures: usize,
    pub guided: Vec<GuideReport>,
    /// Guided proposals over all proposals of the guided strategies (guided + fallback).
    pub guided_share: f64,
}

impl Emlt {
    pub fn from_params(params: &toml::Table) -> Result<Emlt, RenderError> {
        Ok(Emlt { settings: EmltSettings::from_params(params)?, ..Emlt::default() })
    }

    /// The pmlt whose bootstrap and chain start this render shares.
    fn pmlt(&self) -> Pmlt {
        let s = &self.settings;
        let settings = PmltSettings {
            max_depth: s.max_depth,
            bootstrap: s.bootstrap,
            chains: 2 * s.ensemble_size,
            mis: s.mis,
            bidirectional: s.bidirectional,
            ..PmltSettings::default()
        };
        Pmlt {
            settings,
            bidirectional: Bidirectional::default(),
            lens: Default::default(),
            caustic: Default::default(),
            portal: Default::default(),
        }
    }

    /// The strategies of a half-iteration, the guided ones reading `view`.
    fn strategies(
        &self,
        scene: &Scene,
        view: &Arc<GuideView>,
        counts: &[Arc<GuideCounts>; GUIDED_STRATEGIES],
    ) -> StrategySet {
        let camera = &scene.camera;
        let raster = RasterKernel::veach(camera.width, camera.height);
        let s = &self.settings;
        // The ablation switch (`EmltSettings::perturbations`) zeroes the weights it turns off.
        let weights = s.guided_weights();
        StrategySet {
            entries: vec![
                Box::new(Entry { strategy: self.bidirectional, kernel: LengthKernel, weight: s.bidirectional }),
                Box::new(Entry {
                    strategy: self.linear_lens,
                    kernel: GuidedKernel { view: view.clone(), plain: raster, counts: counts[0].clone() },
                    weight: weights[0],
                }),
                Box::new(Entry {
                    strategy: self.linear_caustic,
                    kernel: GuidedKernel {
                        view: view.clone(),
                        plain: CausticKernel::from_lens(&raster, camera),
                        counts: counts[1].clone(),
                    },
                    weight: weights[1],
                }),
                Box::new(Entry {
                    strategy: LinearMultiChain { lens: self.linear_lens },
                    kernel: GuidedKernel {
                        view: view.clone(),
                        plain: MultiChainKernel::new(raster),
                        counts: counts[2].clone(),
                    },
                    weight: weights[2],
                }),
                Box::new(Entry {
                    strategy: self.anisotropic_path,
                    kernel: GuideContext { view: view.clone(), counts: counts[3].clone() },
                    weight: weights[3],
                }),
                Box::new(Entry {
                    strategy: Environment { kernel: s.environment_kernel },
                    kernel: GuideContext { view: view.clone(), counts: counts[4].clone() },
                    weight: weights[4],
                }),
            ],
        }
    }
}

impl Integrator for Emlt {
    fn name(&self) -> &'static str {
        "emlt"
    }

    fn settings_json(&self) -> serde_json::Value {
        serde_json::to_value(&self.settings).unwrap_or(serde_json::Value::Null)
    }

    fn supports_sessions(&self) -> bool {
        false
    }

    fn render(&self, scene: &Scene, job: &RenderJob, progress: &dyn Progress) -> Result<RenderOutput, RenderError> {
        let start_time = Instant::now();
        let (width, height) = (scene.camera.width, scene.camera.height);
        let pixels = width as u64 * height as u64;
        crate::integrator::check_budget(job.budget, width, height, "budget")?;
        let driver = Driver::new(job, width, height)?;
        let pmlt = self.pmlt();
        let max_depth = self.settings.max_depth as usize;
        let ctx = PathContext { scene, max_depth };
        let bctx = pmlt.bdpt_context(scene);
        let e = self.settings.ensemble_size;
        let counts: [Arc<GuideCounts>; GUIDED_STRATEGIES] = Default::default();
        // A set with an empty view: the names and order of the statistics.
        let empty = Arc::new(GuideView::new(Vec::new(), &self.settings, width, height));
        let names = self.strategies(scene, &empty, &counts);
        drop(empty);

        let time_budget = match job.budget {
            Budget::Seconds(s) => Some(s),
            _ => None,
        };
        let boot = run_bootstrap(
            &driver,
            progress,
            1,
            self.settings.bootstrap,
            time_budget,
            |_| pmlt.new_slot(&names),
            |_, i, slot, counters| pmlt.bootstrap_sample(&bctx, job.seed, i, slot, counters, None),
        );
        let b = boot.sums[0] / boot.paths.max(1) as f64;
        let mut counters = boot.counters.clone();
        let mut stats = new_stats(max_depth, &names);
        let mut report = EnsembleReport { ensemble_size: e, ..EnsembleReport::default() };
        let mut film = Accumulator::new(width as usize, height as usize);
        let mut warnings = Vec::new();
        if b > 0.0 {
            // Both ensembles, started in parallel (one driver pass whose units are the chains).
            let start = Distribution1D::new(&boot.targets[0]);
            let slots = |_| pmlt.new_slot(&names);
            let init: Vec<(u64, Option<ChainUnit>)> = (0..2 * e).map(|c| (c, None)).collect();
            let started = driver.run(
                init,
                Passes::Count(1),
                progress,
                slots,
                |_, (c, unit), slot| {
                    let mut candidates = Vec::new();
                    let Slot { state, counters, .. } = slot;
                    *unit = Some(pmlt.start_chain(*c, &start, &ctx, &bctx, job.seed, state, counters, &mut candidates));
                    0
                },
                None,
            );
            counters.merge(&started.counters);
            let mut chains: Vec<ChainUnit> = started.units.into_iter().filter_map(|(_, u)| u).collect();
            let unstarted = chains.iter().filter(|u| !(u.current.f_star > 0.0)).count();
            if unstarted > 0 {
                warnings.push(format!("{unstarted} of {} chains found no start path; they splat nothing", 2 * e));
            }
            let mut y: Vec<ChainUnit> = chains.split_off(e as usize);
            let mut x = chains;

            let it = (pixels / (2 * e)).max(1);
            report.iterations_per_swap = it;
            let halves = match job.budget {
                Budget::SamplesPerPixel(mpp) => (mpp * pixels).div_ceil(e * it),
                Budget::Seconds(_) => u64::MAX,
            };
            progress.set_total(halves.saturating_mul(e * it));
            progress.message("mutating");
            let mut last = Duration::ZERO;
            // Previews at swaps (the only points where every chain of X has moved the same number
            // of times), normalised as the final image is.
            let preview_every = progress.preview_interval().map(Duration::from_secs_f64);
            let mut last_preview = Instant::now();
            for half in 0..halves {
                if let Budget::Seconds(s) = job.budget {
                    let now = start_time.elapsed();
                    if half > 0 && (now + last).as_secs_f64() > s {
                        break;
                    }
                }
                let half_start = Instant::now();
                // The tree over Y, rebuilt at each swap (Algorithm 1, line 12).
                let rebuild = Instant::now();
                let paths = y.iter_mut().map(|u| std::mem::take(&mut u.current)).collect();
                let view = Arc::new(GuideView::new(paths, &self.settings, width, height));
                report.tree_rebuild_seconds += rebuild.elapsed().as_secs_f64();
                report.signatures = view.tree.signatures();
                let set = self.strategies(scene, &view, &counts);
                let run_start = RunStart {
                    units: std::mem::take(&mut x),
                    next_pass: 0,
                    film: Some(std::mem::replace(&mut film, Accumulator::new(0, 0))),
                    saved_slot: None,
                    passes: PassSet::ALL,
                };
                let out = driver.run_from(
                    run_start,
                    Passes::Count(1),
                    progress,
                    |_| pmlt.new_slot(&set),
                    |_, unit: &mut ChainUnit, slot| {
                        let Slot { state, film, counters, .. } = slot;
                        for _ in 0..it {
                            step(&ctx, &set, &mut unit.current, &mut unit.rng, &mut state.stats, film, counters);
                        }
                        it
                    },
                    None,
                    RunControl::default(),
                    None,
                );
                film = out.film;
                x = out.units;
                counters.merge(&out.counters);
                for s in &out.slot_states {
                    stats.merge(&s.stats);
                }
                drop(set);
                let view =
                    Arc::try_unwrap(view).map_err(|_| RenderError::Settings("guide view still shared".into()))?;
                for (u, p) in y.iter_mut().zip(view.paths) {
                    u.current = p;
                }
                std::mem::swap(&mut x, &mut y);
                report.swaps += 1;
                last = half_start.elapsed();
                if preview_every.is_some_and(|every| last_preview.elapsed() >= every) {
                    let n: u64 = stats.per_depth.iter().map(|d| d.iterations).sum();
                    if n > 0 {
                        progress.preview(&film.to_image(b * pixels as f64 / n as f64));
                    }
                    last_preview = Instant::now();
                }
            }
        } else {
            warnings.push(format!(
                "no bootstrap path ({} BDPT samples) carried light to the camera: the image is black.",
                boot.paths
            ));
        }

        let n: u64 = stats.per_depth.iter().map(|d| d.iterations).sum();
        let scale = if n > 0 { b * pixels as f64 / n as f64 } else { 0.0 };
        let image = film.to_image(scale);
        let b_depth: Vec<f64> =
            stats.per_depth.iter().map(|d| if n > 0 { b * d.iterations as f64 / n as f64 } else { 0.0 }).collect();
        stats.passes = report.swaps;
        stats.segment_length = report.iterations_per_swap;
        stats.bootstrap_paths_per_depth = boot.paths;
        stats.bootstrap_seconds = boot.elapsed.as_secs_f64();
        stats.warnings = warnings;
        stats.finish(pixels, &b_depth, &b_depth);
        for s in stats.strategies.iter().flatten() {
            counters
                .strategies
                .insert(s.name.clone(), AcceptanceCount { proposed: s.selected, accepted: s.accepted as f64 });
        }
        report.guided = vec![
            counts[0].report("linear_lens"),
            counts[1].report("linear_caustic"),
            counts[2].report("linear_multi_chain"),
            counts[3].report("anisotropic_path"),
            counts[4].report("environment"),
        ];
        let (g, f) = report.guided.iter().fold((0, 0), |(g, f), r| (g + r.guided, f + r.fallback));
        report.guided_share = if g + f > 0 { g as f64 / (g + f) as f64 } else { 0.0 };
        let mut extra = serde_json::to_value(&stats).unwrap_or(serde_json::Value::Null);
        if let Some(map) = extra.as_object_mut() {
            if b > 0.0 {
                map.insert("b".into(), serde_json::json!(b));
            }
            map.insert("ensemble".into(), serde_json::to_value(&report).unwrap_or(serde_json::Value::Null));
        }
        Ok(RenderOutput { image, layers: Vec::new(), counters, wall_time: start_time.elapsed(), extra_stats: extra })
    }
}
