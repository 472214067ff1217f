//! The Markov chain integrators' side of the driver (PSSMLT, MMLT and RJMLT in `pss/mlt`,
//! path-space MLT in `path_space`), as `image.rs` is the image-space integrators': what a chain
//! render does around its passes for its [`Session`] — where it resumes from, how many passes it
//! runs, its checkpoints, the state it reaches ([`ChainSession`]) — and how the shards' parts of
//! its states merge ([`merge_chain_parts`]). The integrator keeps what is its own: the bootstrap,
//! the chains' kernel, the statistics, the normalisation.

use std::time::{Duration, Instant};

use serde::de::DeserializeOwned;
use serde::Serialize;

use super::{Passes, Slot};
use crate::film::Accumulator;
use crate::integrator::{Budget, Progress, RenderError};
use crate::state::{decode, encode, RenderState, Session, StateError, UnitState};
use crate::stats::Counters;

/// A chain integrator's part of a render state (`crate::state`): its own fields (the bootstrap,
/// the merged statistics) and its chains.
pub trait ChainPart: Serialize + DeserializeOwned {
    /// The chains, by their index in the whole render, each written through `UnitState`.
    fn units_mut(&mut self) -> &mut Vec<(u64, Vec<u8>)>;
    /// Adds another shard's statistics, refusing a shard that did not start from the same
    /// bootstrap (the chains are `merge_chain_parts`' to add).
    fn absorb(&mut self, other: &Self) -> Result<(), StateError>;
}

/// Merges the parts of a render's shards, given in shard order: the first part absorbs the others
/// (`ChainPart::absorb`), and the chains are put in chain order, refusing a chain in two shards.
pub fn merge_chain_parts<P: ChainPart>(parts: &[&[u8]]) -> Result<Vec<u8>, RenderError> {
    let mut merged: Option<P> = None;
    for bytes in parts {
        let mut part: P = decode(bytes)?;
        match merged.as_mut() {
            None => merged = Some(part),
            Some(m) => {
                m.absorb(&part)?;
                m.units_mut().append(part.units_mut());
            }
        }
    }
    let mut merged = merged.ok_or_else(|| StateError::Mismatch("no shard".into()))?;
    let units = merged.units_mut();
    units.sort_by_key(|(index, _)| *index);
    if let Some(pair) = units.windows(2).find(|pair| pair[0].0 == pair[1].0) {
        return Err(StateError::Mismatch(format!("chain {} is in two shards: their units overlap", pair[0].0)).into());
    }
    Ok(encode(&merged)?)
}

/// The chains as a state keeps them: each one's index in the whole render (`index`) and its bytes.
pub fn save_units<U: UnitState>(units: &[U], index: impl Fn(&U) -> u64) -> Result<Vec<(u64, Vec<u8>)>, StateError> {
    units.iter().map(|u| Ok((index(u), u.save()?))).collect()
}

/// The chains of a state, in its order.
pub fn load_units<U: UnitState>(saved: &[(u64, Vec<u8>)]) -> Result<Vec<U>, StateError> {
    saved.iter().map(|(_, bytes)| U::load(bytes)).collect()
}

/// The counters of a pass boundary: `before` (the bootstrap's and the chains' start) and the
/// slots', merged in slot order.
pub fn boundary_counters<S>(before: &Counters, slots: &[Slot<S>]) -> Counters {
    let mut counters = before.clone();
    for slot in slots {
        counters.merge(&slot.counters);
    }
    counters
}

/// The slots' states at the end of a run merged in slot order into the first (`merge`).
pub fn merge_slot_states<S>(slots: Vec<S>, merge: impl Fn(&mut S, &S)) -> Result<S, RenderError> {
    let mut slots = slots.into_iter();
    let mut merged = slots.next().ok_or_else(|| RenderError::Settings("no worker ran".into()))?;
    for s in slots {
        merge(&mut merged, &s);
    }
    Ok(merged)
}

/// The render-level figures of a chain render's output.
pub struct Tally {
    pub passes: u64,
    /// Mutations per chain and pass.
    pub segment: u64,
    pub counters: Counters,
    pub wall: Duration,
}

/// What a chain render does for its session: the clock (started when the render began, so the
/// bootstrap is inside a time budget and the wall time), the wall time of the runs a resumed render
/// continues, the pass schedule of its budget and the states it saves. A shard's state carries no
/// time, so its bytes depend on its chains only.
pub struct ChainSession<'s> {
    session: &'s Session<'s>,
    started: Instant,
    /// Wall time of the runs a resumed render continues.
    earlier: Duration,
    /// Chains of the whole render (a state's `unit_count`).
    chains: u64,
    /// A sample budget's passes: its state is complete after them.
    total_passes: Option<u64>,
}

impl<'s> ChainSession<'s> {
    /// Starts the render's clock. A shard holds the chains whose index it `contains` (every
    /// `count`-th from its index): one whose index is not below `chains` would hold none, render
    /// nothing and say it had succeeded, so it is refused.
    pub fn new(session: &'s Session<'s>, chains: u64) -> Result<ChainSession<'s>, RenderError> {
        if let Some(shard) = session.shard {
            if shard.index >= chains {
                return Err(RenderError::Limit(format!(
                    "shard {shard} would render nothing: this render has {chains} chains, so it splits into at \
                     most {chains} shards"
                )));
            }
        }
        Ok(ChainSession { session, started: Instant::now(), earlier: Duration::ZERO, chains, total_passes: None })
    }

    pub fn session(&self) -> &'s Session<'s> {
        self.session
    }

    /// The state the session resumes and its part, if it resumes one; refused unless its film is
    /// `film_width`×`film_height` and it has the render's chains.
    pub fn resumed<P: DeserializeOwned>(
        &mut self,
        film_width: u32,
        film_height: u32,
    ) -> Result<Option<(&'s RenderState, P)>, RenderError> {
        let Some(state) = self.session.resume else { return Ok(None) };
        if (state.film_width, state.film_height) != (film_width, film_height) || state.unit_count != self.chains {
            return Err(StateError::Mismatch("the checkpoint's film or chains do not match the scene".into()).into());
        }
        let part = decode(&state.part)?;
        self.earlier = Duration::try_from_secs_f64(state.wall_time_s).unwrap_or_default();
        Ok(Some((state, part)))
    }

    /// The passes of `budget` from pass `next_pass` on, with the progress total: a sample budget's
    /// `mpp` mutations per pixel over `pixels` in passes of `per_pass` mutations (`segment` per
    /// chain, `chains` chains run here), or what is left of a time budget, of which the bootstrap
    /// and the chains' start took their share.
    #[allow(clippy::too_many_arguments)]
    pub fn passes(
        &mut self,
        budget: Budget,
        pixels: u64,
        per_pass: u64,
        segment: u64,
        chains: usize,
        next_pass: u64,
        progress: &dyn Progress,
    ) -> Passes {
        match budget {
            Budget::SamplesPerPixel(mpp) => {
                let n = (mpp * pixels).div_ceil(per_pass);
                progress.set_total(n.saturating_sub(next_pass) * segment * chains as u64);
                self.total_passes = Some(n);
                Passes::Count(n)
            }
            Budget::Seconds(s) => Passes::Seconds((s - self.started.elapsed().as_secs_f64()).max(0.0)),
        }
    }

    /// Time this run has taken.
    pub fn elapsed(&self) -> Duration {
        self.started.elapsed()
    }

    /// Time the render has taken, the runs it continues included.
    pub fn wall(&self) -> Duration {
        self.started.elapsed() + self.earlier
    }

    /// `seconds` as a state records them: 0 in a shard.
    pub fn saved_seconds(&self, seconds: f64) -> f64 {
        if self.session.shard.is_some() {
            0.0
        } else {
            seconds
        }
    }

    /// Whether the budget is spent after `passes_done` passes (never for a time budget).
    pub fn complete_at(&self, passes_done: u64) -> bool {
        self.total_passes.is_some_and(|n| passes_done >= n)
    }

    /// The state of `film` (which it takes), the counters and the integrator's `part` after
    /// `passes_done` passes, `wall` into the render.
    pub fn state(
        &self,
        film: Accumulator,
        counters: &Counters,
        part: &impl Serialize,
        passes_done: u64,
        complete: bool,
        wall: Duration,
    ) -> Result<RenderState, StateError> {
        Ok(RenderState {
            passes_done,
            unit_count: self.chains,
            film_width: film.width as u32,
            film_height: film.height as u32,
            film: film.into_sums(),
            counters: counters.clone(),
            part: encode(part)?,
            complete,
            interrupted: false,
            wall_time_s: self.saved_seconds(wall.as_secs_f64()),
            units: self.session.shard,
        })
    }

    /// Hands the state `make` builds at a pass boundary to the session's checkpoint sink, or says
    /// on `progress` why there is none.
    pub fn checkpoint(&self, progress: &dyn Progress, make: impl FnOnce() -> Result<RenderState, StateError>) {
        let Some(sink) = self.session.checkpoint else { return };
        match make() {
            Ok(state) => sink(state),
            Err(e) => progress.message(&format!("checkpoint not written: {e}")),
        }
    }

    /// The end of a run of `passes` passes (`stopped` early or not): with a `part` (a render
    /// that saves), the state, which takes the film (the film returned is then empty); without,
    /// the film.
    #[allow(clippy::too_many_arguments)]
    pub fn finish(
        &self,
        film: Accumulator,
        counters: &Counters,
        part: Option<impl Serialize>,
        passes: u64,
        complete: bool,
        stopped: bool,
        wall: Duration,
    ) -> Result<(Accumulator, Option<RenderState>), StateError> {
        let Some(part) = part else { return Ok((film, None)) };
        let mut state = self.state(film, counters, &part, passes, complete, wall)?;
        state.interrupted = stopped;
        Ok((Accumulator::new(0, 0), Some(state)))
    }
}
