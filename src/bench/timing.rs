//! Process timing and the machine facts a benchmark report records: wall-clock and CPU time of a
//! run, medians over repetitions, the CPU model and the load average.

use std::time::{Duration, Instant};

/// CPU time consumed so far by every thread of the process.
pub fn process_cpu_time() -> Duration {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `clock_gettime` only writes one `timespec` into the valid, exclusively borrowed `ts`.
    let status = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    if status != 0 {
        return Duration::ZERO;
    }
    Duration::new(ts.tv_sec.max(0) as u64, ts.tv_nsec.clamp(0, 999_999_999) as u32)
}

/// Wall-clock and process CPU time of one run.
#[derive(Clone, Copy, Debug)]
pub struct Timing {
    pub wall: Duration,
    pub cpu: Duration,
}

/// Runs `f`, timing it.
pub fn timed<T>(f: impl FnOnce() -> T) -> (Timing, T) {
    let (wall, cpu) = (Instant::now(), process_cpu_time());
    let value = f();
    (Timing { wall: wall.elapsed(), cpu: process_cpu_time().saturating_sub(cpu) }, value)
}

/// The median of `xs` (the mean of the middle two for an even count; 0 for none).
pub fn median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    let n = xs.len();
    if n == 0 {
        0.0
    } else if n % 2 == 1 {
        xs[n / 2]
    } else {
        0.5 * (xs[n / 2 - 1] + xs[n / 2])
    }
}

/// Medians of the wall-clock and CPU seconds of `runs`.
pub fn median_seconds(runs: &[Timing]) -> (f64, f64) {
    (
        median(runs.iter().map(|t| t.wall.as_secs_f64()).collect()),
        median(runs.iter().map(|t| t.cpu.as_secs_f64()).collect()),
    )
}

/// Medians over `reps` (at least one) runs of `f`'s wall-clock and CPU seconds.
pub fn time_median(reps: u32, mut f: impl FnMut() -> Timing) -> (f64, f64) {
    let runs: Vec<Timing> = (0..reps.max(1)).map(|_| f()).collect();
    median_seconds(&runs)
}

/// The CPU model name (Linux), for the report.
pub fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".to_string())
}

/// The 1-minute load average (Linux), for the report.
pub fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().map(str::to_string))
        .unwrap_or_else(|| "unknown".to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_and_even_counts() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![4.0, 1.0, 2.0, 3.0]), 2.5);
        assert_eq!(median(Vec::new()), 0.0);
    }
}
