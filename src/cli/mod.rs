//! The command line: clap definitions, dispatch, and the error edge. Every failure ends as one line
//! `error: ...` on stderr and an exit code: 2 for bad input or usage (scene files, settings, output
//! paths, arguments), 1 for failures at run time (writing an image, an internal error).

mod bench;
mod compare;
mod converge;
mod import;
mod info;
mod merge;
mod options;
mod outputs;
mod progress;
mod reference;
mod render;
mod render_run;
mod resume;
mod state_io;
mod stats_json;
mod warnings;

use clap::{Parser, Subcommand};

/// Exit code for bad input or usage.
pub const EXIT_BAD_INPUT: i32 = 2;
/// Exit code for failures at run time.
pub const EXIT_RUNTIME: i32 = 1;

/// plexus: a physically based renderer for difficult light transport.
#[derive(Debug, Parser)]
#[command(name = "plexus", version, about, max_term_width = 100)]
struct Cli {
    #[command(subcommand)]
    command: Commands,
}

#[derive(Debug, Subcommand)]
enum Commands {
    /// Render a scene (the built-in Cornell box when no scene is given).
    Render(render::RenderArgs),
    /// Print what a scene contains: triangles, emitters, materials, portals, bounds, memory.
    Info(info::InfoArgs),
    /// Compare an image with a reference: MSE, relative MSE, PSNR, ratio of means, error map.
    Compare(compare::CompareArgs),
    /// Error against a reference vs render time for several integrators, budgets and seeds.
    Converge(converge::ConvergeArgs),
    /// Continue a checkpointed or interrupted render from its state file (.pxstate).
    Resume(resume::ResumeArgs),
    /// Combine the shards of a render (`render --shard K/N`) into its image.
    Merge(merge::MergeArgs),
    /// Render a reference image (long, seeded, optionally at a reduced resolution).
    Reference(reference::ReferenceArgs),
    /// Accelerator throughput (Embree, the in-house BVH, a bare Embree loop, the path tracer) on a
    /// generated scene of more than a million triangles; prints a Markdown table.
    Bench(bench::BenchArgs),
    /// Convert a Mitsuba scene (0.5/0.6 or 3 XML) to a plexus TOML scene; warnings name what changed.
    Import(import::ImportArgs),
    // Further verbs (compare, converge, bench, ...) go here, one variant each, with their
    // argument struct in their own file under src/cli/ and one arm in `run` below.
}

/// An error caused by what the user gave us (arguments, files, settings): exit code 2.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadInput(pub String);

/// Wraps any error as bad input (exit code 2), keeping its message.
pub fn bad_input(e: impl std::fmt::Display) -> anyhow::Error {
    anyhow::Error::new(BadInput(e.to_string()))
}

/// The thread count a command uses: the explicit one (`option` names it) checked against
/// `job::MAX_THREADS`, else all cores up to that bound.
pub fn resolve_threads(explicit: Option<usize>, option: &str) -> anyhow::Result<usize> {
    match explicit {
        Some(n) => {
            plexus::job::check_threads(n, option).map_err(bad_input)?;
            Ok(n)
        }
        None => Ok(std::thread::available_parallelism().map_or(1, |n| n.get()).min(plexus::job::MAX_THREADS)),
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Commands::Render(args) => render::run(args),
        Commands::Info(args) => info::run(args),
        Commands::Compare(args) => compare::run_compare(&args),
        Commands::Converge(args) => converge::run_converge(&args),
        Commands::Reference(args) => reference::run_reference(&args),
        Commands::Resume(args) => resume::run(args),
        Commands::Merge(args) => merge::run(args),
        Commands::Bench(args) => bench::run_bench(&args),
        Commands::Import(args) => import::run(args),
    }
}

/// The exit code an error deserves.
fn exit_code(e: &anyhow::Error) -> i32 {
    use plexus::integrator::RenderError;
    for cause in e.chain() {
        if cause.is::<BadInput>() || cause.is::<plexus::scene::SceneError>() {
            return EXIT_BAD_INPUT;
        }
        if let Some(e) = cause.downcast_ref::<plexus::state::StateError>() {
            use plexus::state::StateError;
            return match e {
                StateError::Write { .. } | StateError::Encode(_) => EXIT_RUNTIME,
                _ => EXIT_BAD_INPUT,
            };
        }
        if let Some(r) = cause.downcast_ref::<RenderError>() {
            return match r {
                RenderError::ThreadPool(_) => EXIT_RUNTIME,
                RenderError::State(plexus::state::StateError::Write { .. } | plexus::state::StateError::Encode(_)) => {
                    EXIT_RUNTIME
                }
                _ => EXIT_BAD_INPUT,
            };
        }
    }
    EXIT_RUNTIME
}

/// Prints `error: <message>` as one line (causes joined by ": ").
fn print_error(e: &anyhow::Error) {
    let msg = format!("{e:#}").replace('\n', " ");
    eprintln!("error: {msg}");
}

/// Runs the command line and returns the process exit code.
pub fn main() -> i32 {
    // A panic is a bug in plexus, but the user still gets one line, not a backtrace.
    std::panic::set_hook(Box::new(|info| {
        let msg = if let Some(s) = info.payload().downcast_ref::<&str>() {
            (*s).to_string()
        } else if let Some(s) = info.payload().downcast_ref::<String>() {
            s.clone()
        } else {
            "unknown panic".to_string()
        };
        let at = info.location().map(|l| format!(" at {}:{}", l.file(), l.line())).unwrap_or_default();
        eprintln!("error: internal error (a bug in plexus): {}{at}", msg.replace('\n', " "));
    }));

    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let code = if e.use_stderr() { EXIT_BAD_INPUT } else { 0 };
            // clap formats usage errors itself ("error: ..." plus a usage hint); help and version
            // go to stdout with exit code 0.
            let _ = e.print();
            return code;
        }
    };
    match std::panic::catch_unwind(|| run(cli)) {
        Ok(Ok(())) => 0,
        Ok(Err(e)) => {
            if let Some(i) = e.downcast_ref::<state_io::Interrupted>() {
                eprintln!("{i}");
                return plexus::interrupt::EXIT_INTERRUPTED;
            }
            print_error(&e);
            exit_code(&e)
        }
        Err(_) => EXIT_RUNTIME,
    }
}
