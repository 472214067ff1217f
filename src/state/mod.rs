//! Render state files (`.pxstate`): checkpoints, interrupted renders and shards are one kind of
//! file (docs/architecture.md, "The render model"). A state is what the driver's
//! [`PassBoundary`](crate::integrator::driver::PassBoundary) names: the schedule position, the
//! film's unnormalised sums, the units' states (a chain's sampler, current path and large-step
//! totals), the slots' counters and statistics merged — plus the header that says which render it
//! belongs to.
//!
//! # The file
//!
//! `PXSTATE\n` (8 bytes), the format version (u32, little-endian), then the [`StateFile`] in
//! `bincode` 1 (fixed-width little-endian integers and IEEE floats, so every f64 sum comes back bit
//! for bit), then the SHA-256 of everything before it (32 bytes): a file whose bytes changed
//! after it was written (a flipped bit, a truncated copy) is refused as damaged before any of it
//! is used. The film is the bulk: 24 bytes per pixel (three f64 sums), 1.5 MiB at 256², 47.5 MiB
//! at 1920×1080; MLT's per-depth layers multiply that by the depth count (`max_depth` + 1). The
//! header carries the plexus version, the scene's hash (the scene file and every file it names,
//! [`scene_hash`]), the integrator with the parameters it was created from and the settings in
//! effect, the seed, threads, budget, resolution, unit count and shard. Files are written to a
//! hidden temporary file beside the target and renamed into place, so a reader (or an interrupt)
//! never sees half a state.
//!
//! # Integrators
//!
//! An integrator that can be checkpointed implements [`Integrator::run_session`] (render from a
//! [`Session`]: resume, shard, stop, periodic checkpoints), [`Integrator::output_of_state`] (the
//! normalised image of a state: resume's and merge's output) and [`Integrator::merge_parts`]. What
//! its units and slots carry is its own `part` of the state, written with [`encode`]; a unit type
//! implements [`UnitState`]. The driver holds what the integrators of a kind share around their
//! sessions: `ImageRender` and `ImagePart` for the image-space ones, `run_chains`, `ChainPart` and
//! `merge_chain_parts` for the Markov chain ones (`integrator::driver`).

mod merge;
mod scene_hash;
mod session;

use std::io::Write;
use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::job::Budget;
use crate::stats::Counters;

pub use merge::merge_states;
pub use scene_hash::{builtin_scene_hash, scene_hash};
pub use session::{Session, SessionOutput, Shard};

/// The first bytes of every state file.
pub const MAGIC: &[u8; 8] = b"PXSTATE\n";
/// The layout version of the file; a reader refuses any other. 2: the MLT bootstrap's per-depth
/// estimates carry their variances and depth 0's replicates, so a version-1
/// MLT state would not decode; every older state is refused by version instead of as "damaged".
/// 3: the body is followed by its SHA-256.
pub const FORMAT_VERSION: u32 = 3;
/// Bytes of the trailing digest.
const DIGEST_BYTES: usize = 32;
/// The plexus version that writes state files: a state of another version is refused (its
/// integrators may sample differently, so resuming would not continue the same render).
pub const PLEXUS_VERSION: &str = env!("CARGO_PKG_VERSION");
/// What the numbers of a render mean: which random numbers every integrator draws for what, and
/// what its state holds. A state (checkpoint or shard) is resumed or merged only by a plexus of
/// the same revision, since another revision would continue the render with other numbers and
/// blend two estimators. Bump it with every change that moves an image rendered with the same
/// scene, seed, settings and threads; `tests/images/golden.rs` renders each integrator once and fails
/// until it is bumped (its table records the images of this revision).
pub const SAMPLING_REVISION: u32 = 4;
/// The largest state file read: far beyond any film the memory checks allow, small enough that a
/// corrupt length prefix cannot make the reader allocate without bound.
const MAX_STATE_BYTES: u64 = 1 << 40;

/// Why a state could not be written, read or used.
#[derive(Debug, Error)]
pub enum StateError {
    #[error("cannot read the state file {}: {source}", path.display())]
    Read { path: PathBuf, source: std::io::Error },
    #[error("cannot write the state file {}: {source}", path.display())]
    Write { path: PathBuf, source: std::io::Error },
    #[error("{} is not a plexus state file", path.display())]
    NotAState { path: PathBuf },
    #[error("{} is a state file of format version {found}, this plexus reads version {FORMAT_VERSION}", path.display())]
    FormatVersion { path: PathBuf, found: u32 },
    #[error("{} is damaged or truncated: {message}", path.display())]
    Corrupt { path: PathBuf, message: String },
    /// The state does not belong to the render it is used with (scene, version, settings, ...).
    #[error("{0}")]
    Mismatch(String),
    #[error("cannot encode the render state: {0}")]
    Encode(String),
}

/// Which render a state belongs to. Two states can be resumed as, or merged into, one render only
/// if everything here but `threads`, `shard` and `wall_time_s` is equal.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StateHeader {
    pub plexus_version: String,
    /// [`SAMPLING_REVISION`] of the plexus that wrote it.
    pub sampling_revision: u32,
    /// The scene as given on the command line, made absolute (or `<built-in cornell-box>`).
    pub scene: String,
    /// SHA-256 of the scene file and every file it references ([`scene_hash`]).
    pub scene_hash: String,
    pub accel: String,
    pub integrator: String,
    /// The integrator's parameters (TOML) it is created from again on resume and merge.
    pub params: String,
    /// The integrator's settings in effect (JSON, defaults filled in).
    pub settings: String,
    pub seed: u64,
    /// Worker threads of the render; 0 in a shard, whose bytes do not depend on them.
    pub threads: usize,
    pub budget: Budget,
    pub width: u32,
    pub height: u32,
    /// Which units a shard covers; `None` for a whole render.
    pub shard: Option<Shard>,
    /// The images the render writes (absolute), where `plexus resume` writes them by default.
    pub outputs: Vec<PathBuf>,
}

/// What a render has done at a pass boundary: everything its continuation depends on.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RenderState {
    /// Schedule position: every pass below it (of the shard's set of passes) is done.
    pub passes_done: u64,
    /// The render's work units (tiles, chains) of the whole render, not only the shard's.
    pub unit_count: u64,
    /// The film's unnormalised sums (`Accumulator::sums`), `film_width` × `film_height` (MLT:
    /// the depths' layers stacked).
    pub film_width: u32,
    pub film_height: u32,
    pub film: Vec<[f64; 3]>,
    /// The slots' counters merged.
    pub counters: Counters,
    /// The integrator's own part (its units' states, merged slot statistics, MLT's bootstrap),
    /// written with [`encode`].
    pub part: Vec<u8>,
    /// Whether the budget is spent (a sample budget's last pass done).
    pub complete: bool,
    /// Whether the render stopped early (a signal, a test's stop).
    pub interrupted: bool,
    /// Seconds the render has taken so far, resumed runs included (0 in shards, whose bytes
    /// depend on their units only).
    pub wall_time_s: f64,
    /// The units whose work the film and parts hold: a shard's (`None`: all), recorded by the
    /// driver from the session it ran, apart from the header's label, so that a shard whose
    /// header was relabelled is refused by merge instead of summed as another shard.
    pub units: Option<Shard>,
}

/// A state file's contents.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct StateFile {
    pub header: StateHeader,
    pub state: RenderState,
}

/// What a unit (a chain) keeps between passes, saved in states. The default methods write the
/// type with serde through [`encode`]; a unit with derived state may override them.
pub trait UnitState: Sized {
    fn save(&self) -> Result<Vec<u8>, StateError>;
    fn load(bytes: &[u8]) -> Result<Self, StateError>;
}

impl<T: Serialize + DeserializeOwned> UnitState for T {
    fn save(&self) -> Result<Vec<u8>, StateError> {
        encode(self)
    }
    fn load(bytes: &[u8]) -> Result<Self, StateError> {
        decode(bytes)
    }
}

/// The state codec (bincode 1: exact floats, fixed-width integers).
pub fn encode<T: Serialize + ?Sized>(value: &T) -> Result<Vec<u8>, StateError> {
    bincode::serialize(value).map_err(|e| StateError::Encode(e.to_string()))
}

/// Reads what [`encode`] wrote.
pub fn decode<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, StateError> {
    use bincode::Options;
    bincode::DefaultOptions::new()
        .with_fixint_encoding()
        .allow_trailing_bytes()
        .with_limit(MAX_STATE_BYTES)
        .deserialize(bytes)
        .map_err(|e| StateError::Mismatch(format!("the integrator's part of the state does not decode: {e}")))
}

impl StateFile {
    /// Writes the file atomically: a hidden temporary file beside `path`, renamed into place when
    /// complete (removed on failure, and by the signal handler on a second interrupt).
    pub fn write(&self, path: &Path) -> Result<(), StateError> {
        let err = |source| StateError::Write { path: path.to_path_buf(), source };
        let bytes = self.to_bytes()?;
        crate::interrupt::write_atomically(path, false, err, |_, file| {
            file.write_all(&bytes).map_err(err)?;
            file.sync_data().map_err(err)
        })
    }

    /// The file's bytes: magic, format version, body, digest.
    pub fn to_bytes(&self) -> Result<Vec<u8>, StateError> {
        use sha2::Digest;
        let body = encode(self)?;
        let mut bytes = Vec::with_capacity(12 + body.len() + DIGEST_BYTES);
        bytes.extend_from_slice(MAGIC);
        bytes.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        bytes.extend_from_slice(&body);
        let digest = sha2::Sha256::digest(&bytes);
        bytes.extend_from_slice(&digest);
        Ok(bytes)
    }

    /// Reads a state file, refusing anything but a complete file of this format version.
    pub fn read(path: &Path) -> Result<StateFile, StateError> {
        let bytes = crate::input_file::read_regular(path, u64::MAX)
            .map_err(|e| StateError::Read { path: path.to_path_buf(), source: std::io::Error::other(e) })?;
        StateFile::from_bytes(&bytes, path)
    }

    /// Parses the bytes of a state file (`path` names it in messages).
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<StateFile, StateError> {
        if bytes.len() < 12 || &bytes[..8] != MAGIC {
            return Err(StateError::NotAState { path: path.to_path_buf() });
        }
        let mut version = [0u8; 4];
        version.copy_from_slice(&bytes[8..12]);
        let found = u32::from_le_bytes(version);
        if found != FORMAT_VERSION {
            return Err(StateError::FormatVersion { path: path.to_path_buf(), found });
        }
        use sha2::Digest;
        let damaged = |message: &str| StateError::Corrupt { path: path.to_path_buf(), message: message.to_string() };
        let Some(body_end) = bytes.len().checked_sub(DIGEST_BYTES).filter(|&end| end >= 12) else {
            return Err(damaged("too short to hold its checksum"));
        };
        if sha2::Sha256::digest(&bytes[..body_end]).as_slice() != &bytes[body_end..] {
            return Err(damaged("its checksum does not match its contents (changed or damaged since it was written)"));
        }
        let bytes = &bytes[..body_end];
        use bincode::Options;
        let file: StateFile = bincode::DefaultOptions::new()
            .with_fixint_encoding()
            .reject_trailing_bytes()
            .with_limit(MAX_STATE_BYTES)
            .deserialize(&bytes[12..])
            .map_err(|e| StateError::Corrupt { path: path.to_path_buf(), message: e.to_string() })?;
        let s = &file.state;
        if s.film.len() as u64 != s.film_width as u64 * s.film_height as u64 {
            return Err(StateError::Corrupt {
                path: path.to_path_buf(),
                message: format!("a {}×{} film with {} sums", s.film_width, s.film_height, s.film.len()),
            });
        }
        Ok(file)
    }

    /// Checks that this state can be continued by plexus `PLEXUS_VERSION` on a scene whose hash is
    /// `scene_hash`: one clear sentence naming what differs.
    pub fn check_resumable(&self, path: &Path, scene_hash: &str) -> Result<(), StateError> {
        let h = &self.header;
        let name = path.display();
        if h.plexus_version != PLEXUS_VERSION {
            return Err(StateError::Mismatch(format!(
                "{name} was written by plexus {}, this is plexus {PLEXUS_VERSION}: it cannot be resumed",
                h.plexus_version
            )));
        }
        if h.sampling_revision != SAMPLING_REVISION {
            return Err(StateError::Mismatch(format!(
                "{name} was rendered with sampling revision {}, this plexus samples with revision \
                 {SAMPLING_REVISION}: it would continue with other random numbers, so it cannot be resumed",
                h.sampling_revision
            )));
        }
        if h.scene_hash != scene_hash {
            return Err(StateError::Mismatch(format!(
                "{name} belongs to another scene: {} or a file it references has changed since the checkpoint",
                h.scene
            )));
        }
        if h.shard.is_some() {
            return Err(StateError::Mismatch(format!(
                "{name} is a shard: shards are merged (plexus merge), not resumed"
            )));
        }
        Ok(())
    }
}
