//! The `plexus` command: a thin shell over the library (argument parsing, progress, exit codes).

mod cli;

fn main() {
    std::process::exit(cli::main());
}
