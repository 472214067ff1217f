//! The `plexus` command as a user runs it: the CLI, hostile and careless inputs (trust, fuzz, hostile), interrupts, limits, checkpoints and states, and the docs and scripts kept true.
//!
//! One test binary for these modules: each binary links the whole library, and on two cores
//! linking dominated the suite's build when every file was its own binary.

#[path = "../common/mod.rs"]
mod common;

mod cli;
mod docs;
mod fuzz;
mod hostile;
mod interrupt;
mod limits;
mod scripts;
mod state;
mod trust;
