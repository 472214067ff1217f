//! `plexus merge`'s library half: combining the shards of one render into the state of the whole
//! render. Films are summed in shard order (so the result does not depend on the order the files
//! are given in); the integrator merges its own parts (units' states, statistics).

use std::path::PathBuf;

use super::{StateError, StateFile, StateHeader};

/// Merges shards `files` (path, contents) of one render. Refused with one sentence: headers that
/// differ (scene, plexus version, integrator settings, seed, budget, resolution), a file that is
/// not a shard, shards of different counts, a shard given twice (overlapping units), a missing
/// shard, an interrupted shard.
pub fn merge_states(
    files: &[(PathBuf, StateFile)],
    merge_parts: impl Fn(&[&[u8]]) -> Result<Vec<u8>, StateError>,
) -> Result<StateFile, StateError> {
    let mismatch = |m: String| Err(StateError::Mismatch(m));
    let Some((first_path, first)) = files.first() else {
        return mismatch("nothing to merge".into());
    };
    let a = &first.header;
    for (path, file) in files {
        let b = &file.header;
        let (x, y) = (first_path.display(), path.display());
        let differs: Option<String> = if b.plexus_version != a.plexus_version {
            Some(format!("plexus versions ({} and {})", a.plexus_version, b.plexus_version))
        } else if b.sampling_revision != a.sampling_revision {
            Some(format!("sampling revisions ({} and {})", a.sampling_revision, b.sampling_revision))
        } else if b.scene_hash != a.scene_hash {
            Some(format!("scenes ({} and {})", a.scene, b.scene))
        } else if (&b.integrator, &b.params, &b.settings) != (&a.integrator, &a.params, &a.settings) {
            Some(format!("integrator settings ({} {} and {} {})", a.integrator, a.settings, b.integrator, b.settings))
        } else if b.seed != a.seed {
            Some(format!("seeds ({} and {})", a.seed, b.seed))
        } else if b.budget != a.budget {
            Some(format!("budgets ({:?} and {:?})", a.budget, b.budget))
        } else if (b.width, b.height) != (a.width, a.height) || file.state.unit_count != first.state.unit_count {
            Some("resolutions".into())
        } else {
            None
        };
        if let Some(what) = differs {
            return mismatch(format!("{x} and {y} are shards of different renders: different {what}"));
        }
        let Some(shard) = b.shard else {
            return mismatch(format!("{y} is a whole render, not a shard: its units overlap every shard's"));
        };
        if shard.count == 0 || shard.index >= shard.count {
            return mismatch(format!("{y} claims to be shard {shard}, which no render has"));
        }
        if file.state.units != Some(shard) {
            return mismatch(format!(
                "{y} is labelled shard {shard}, but its film holds the units of {}",
                file.state.units.map_or("the whole render".to_string(), |s| format!("shard {s}"))
            ));
        }
        if a.shard.is_some_and(|s| s.count != shard.count) {
            return mismatch(format!(
                "{x} and {y} split the render differently (shards {} and {shard})",
                a.shard.map_or(String::new(), |s| s.to_string())
            ));
        }
        if !file.state.complete {
            return mismatch(format!("{y} is an interrupted shard: render it again before merging"));
        }
    }
    let count = a.shard.map_or(1, |s| s.count);
    let mut order: Vec<&(PathBuf, StateFile)> = files.iter().collect();
    order.sort_by_key(|(_, f)| f.header.shard.map_or(0, |s| s.index));
    for pair in order.windows(2) {
        if pair[0].1.header.shard == pair[1].1.header.shard {
            return mismatch(format!(
                "{} and {} are the same shard {}: their units overlap",
                pair[0].0.display(),
                pair[1].0.display(),
                pair[0].1.header.shard.map_or(String::new(), |s| s.to_string())
            ));
        }
    }
    if order.len() as u64 != count {
        let missing: Vec<String> = (0..count)
            .filter(|k| !order.iter().any(|(_, f)| f.header.shard.is_some_and(|s| s.index == *k)))
            .take(8)
            .map(|k| format!("{k}/{count}"))
            .collect();
        return mismatch(format!("shard(s) {} missing: merge all {count} shards of the render", missing.join(", ")));
    }

    let mut state = order[0].1.state.clone();
    for (_, file) in &order[1..] {
        let s = &file.state;
        if (s.film_width, s.film_height) != (state.film_width, state.film_height) {
            return mismatch("the shards' films differ in size".into());
        }
        for (a, b) in state.film.iter_mut().zip(&s.film) {
            a[0] += b[0];
            a[1] += b[1];
            a[2] += b[2];
        }
        state.counters.merge(&s.counters);
        state.passes_done = state.passes_done.max(s.passes_done);
    }
    let parts: Vec<&[u8]> = order.iter().map(|(_, f)| f.state.part.as_slice()).collect();
    state.part = merge_parts(&parts)?;
    state.wall_time_s = 0.0;
    state.units = None;
    let header = StateHeader { threads: 0, shard: None, ..a.clone() };
    Ok(StateFile { header, state })
}
