//! How a render is run beyond its job: from a saved state, as a shard, until told to stop, with
//! periodic checkpoints. Integrators take a [`Session`] in `Integrator::run_session` and hand
//! back the image with the [`RenderState`] it reached.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use super::RenderState;
use crate::job::{RenderOutput, RunControl};

/// Shard `index` of `count` (0-based): the render's work units dealt into `count` disjoint sets —
/// passes p with p mod count = index for pt, BDPT and light tracing; chains c with c mod count =
/// index for the Markov chain integrators.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    pub index: u64,
    pub count: u64,
}

impl Shard {
    /// Whether unit (pass or chain) `i` belongs to the shard.
    pub fn contains(&self, i: u64) -> bool {
        i % self.count == self.index
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl FromStr for Shard {
    type Err = String;
    /// `K/N` with 0 ≤ K < N ≤ 2^20.
    fn from_str(s: &str) -> Result<Shard, String> {
        let bad = || format!("'{s}': expected K/N, the K-th (0-based) of N shards, 0 <= K < N <= 1048576");
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let (index, count) = (k.trim().parse::<u64>().map_err(|_| bad())?, n.trim().parse::<u64>().map_err(|_| bad())?);
        if count == 0 || count > 1 << 20 || index >= count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }
}

/// How to run a render (everything defaults to a whole render from the start, never stopped).
#[derive(Clone, Copy, Default)]
pub struct Session<'a> {
    /// When to stop early and how often to offer checkpoints (driver pass boundaries).
    pub control: RunControl<'a>,
    /// Receives the state at each periodic checkpoint (`control.checkpoint_every`).
    pub checkpoint: Option<&'a dyn Fn(RenderState)>,
    /// Continue this state (a checkpoint) instead of starting anew; its header has been checked.
    pub resume: Option<&'a RenderState>,
    /// Render only this shard's work units.
    pub shard: Option<Shard>,
}

/// What a session produced: the normalised image of what was rendered (all of it, a resumed
/// render's earlier runs included) and the state to save.
pub struct SessionOutput {
    pub output: RenderOutput,
    pub state: RenderState,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_parse_and_partition() {
        assert_eq!("1/3".parse::<Shard>(), Ok(Shard { index: 1, count: 3 }));
        for bad in ["3/3", "1", "a/2", "0/0", "-1/2", "1/2/3"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
        let shards: Vec<Shard> = (0..3).map(|index| Shard { index, count: 3 }).collect();
        for unit in 0..10 {
            assert_eq!(shards.iter().filter(|s| s.contains(unit)).count(), 1);
        }
    }
}
