//! The memory a render holds and the memory the process may use: the types an estimate is made of
//! (`SceneMemory`, measured on the built scene; `RenderMemory`, the scene plus the buffers that grow
//! with the budget's dimensions), the process's available memory and the check between them. Each
//! integrator's estimate of its own buffers is `integrator::memory_estimate`'s; `plexus info` prints the
//! same estimate that `render` checks.
//!
//! Every count is checked arithmetic, so that a scene, film or Markov chain setup that would not
//! fit is refused with its size instead of aborting on allocation. The estimate is a lower bound:
//! it omits scratch state, so a render it refuses certainly would not have fitted. The scene is
//! already built when the estimate is checked (mesh readers bound their allocations by the file
//! sizes, `input_file`), so its bytes are part of what the process holds: see `available_memory`.

use super::LimitError;

/// Bytes the built scene holds, by part.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct SceneMemory {
    pub meshes: u64,
    /// The triangles' corner copies the scene keeps for shading (`Scene::keep_corners_if_room`),
    /// made after the accelerator's build: they and `accel_build` are never held at once.
    pub corners: u64,
    pub accel: u64,
    /// Bytes the accelerator held only while it was built, on top of `accel` (`Accel::
    /// peak_memory_bytes` minus `memory_bytes`): part of the process's peak, freed before rendering.
    pub accel_build: u64,
    /// Light distributions and environment texels.
    pub lights: u64,
    /// Image textures' texels (each shared image once; `Scene::texture_memory_bytes`).
    pub textures: u64,
}

impl SceneMemory {
    /// The scene's peak: what it holds while rendering, or while its accelerator was built (the
    /// build's temporaries instead of the corner copies), whichever is more.
    pub fn total(&self) -> u64 {
        self.meshes
            .saturating_add(self.accel)
            .saturating_add(self.accel_build.max(self.corners))
            .saturating_add(self.lights)
            .saturating_add(self.textures)
    }
}

/// The memory of a render: the scene it renders, its film, pass buffers and integrator state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct RenderMemory {
    /// The built scene (zero until `with_scene`).
    pub scene: SceneMemory,
    /// Film sums (all MLT depth layers) and the output image.
    pub film: u64,
    /// One pass of splat buffers.
    pub pass_buffers: u64,
    /// Markov chain integrators only: bootstrap targets and chains.
    pub chains: u64,
}

impl RenderMemory {
    pub fn total(&self) -> u64 {
        self.scene.total().saturating_add(self.film).saturating_add(self.pass_buffers).saturating_add(self.chains)
    }
    /// This estimate with the scene's bytes.
    pub fn with_scene(self, scene: SceneMemory) -> RenderMemory {
        RenderMemory { scene, ..self }
    }
}

/// The refusal of a byte count that overflows u64.
pub fn too_large(what: &str) -> LimitError {
    LimitError(format!("the memory of {what} overflows a 64-bit byte count"))
}

/// `a × b` bytes of `what`, or its refusal.
pub fn mul(a: u64, b: u64, what: &str) -> Result<u64, LimitError> {
    a.checked_mul(b).ok_or_else(|| too_large(what))
}

/// `a + b` bytes of `what`, or its refusal.
pub fn add(a: u64, b: u64, what: &str) -> Result<u64, LimitError> {
    a.checked_add(b).ok_or_else(|| too_large(what))
}

/// The memory this process may use in all, its scene included: the cgroup's `memory.max` when
/// it is set and finite, else the kernel's `MemAvailable` plus `held` (the bytes the process
/// already holds for the scene, which `MemAvailable`, read after the scene was built, no longer
/// counts); the smaller of the two when both are known. `None` when neither can be read (then
/// nothing is refused).
pub fn available_memory(held: u64) -> Option<u64> {
    let cgroup = std::fs::read_to_string("/sys/fs/cgroup/memory.max").ok().and_then(|s| s.trim().parse::<u64>().ok());
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok().and_then(|text| {
        text.lines()
            .find_map(|l| l.strip_prefix("MemAvailable:"))
            .and_then(|rest| rest.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
            .and_then(|kib| kib.checked_mul(1024))
            .map(|bytes| bytes.saturating_add(held))
    });
    match (cgroup, meminfo) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// Bytes as GiB for messages.
pub fn gib(bytes: u64) -> f64 {
    bytes as f64 / (1u64 << 30) as f64
}

/// Refuses a render whose estimate exceeds `available` bytes, naming the estimate's parts.
pub fn check_fits(memory: &RenderMemory, width: u32, height: u32, available: Option<u64>) -> Result<(), LimitError> {
    let Some(available) = available else { return Ok(()) };
    if memory.total() > available {
        return Err(LimitError(format!(
            "a {width}x{height} render needs at least {:.2} GiB (scene {:.2}: meshes {:.2} and their corners {:.2}, \
             accelerator {:.2}, lights {:.2}, textures {:.2}; film {:.2}, pass buffers {:.2}, chains {:.2}) but only {:.2} GiB are \
             available to the process; lower the resolution{}",
            gib(memory.total()),
            gib(memory.scene.total()),
            gib(memory.scene.meshes),
            gib(memory.scene.corners),
            gib(memory.scene.accel),
            gib(memory.scene.lights),
            gib(memory.scene.textures),
            gib(memory.film),
            gib(memory.pass_buffers),
            gib(memory.chains),
            gib(available),
            if memory.chains > 0 { ", max_depth, bootstrap or chains (emlt: ensemble_size or pairs)" } else { "" }
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_check_counts_every_part_and_the_scene() {
        let m = RenderMemory { scene: SceneMemory::default(), film: 1 << 40, pass_buffers: 1 << 30, chains: 0 };
        assert!(check_fits(&m, 65536, 65536, Some(m.total() - 1)).is_err());
        assert!(check_fits(&m, 65536, 65536, Some(m.total())).is_ok());
        assert!(check_fits(&m, 65536, 65536, None).is_ok());
        // The scene's bytes count too.
        let scene = SceneMemory { meshes: 1, corners: 0, accel: 2, accel_build: 0, lights: 3, textures: 4 };
        let with = m.with_scene(scene);
        assert_eq!(with.total(), m.total() + 10);
        assert!(check_fits(&with, 65536, 65536, Some(m.total())).is_err());
        // The corner copies are made once the build's temporaries are freed: the larger counts.
        let built = SceneMemory { meshes: 10, corners: 5, accel: 20, accel_build: 8, lights: 1, textures: 2 };
        assert_eq!(built.total(), 10 + 20 + 8 + 1 + 2);
        assert_eq!(SceneMemory { corners: 9, ..built }.total(), 10 + 20 + 9 + 1 + 2);
        assert!(mul(u64::MAX, 2, "x").is_err() && add(u64::MAX, 1, "x").is_err());
    }
}
