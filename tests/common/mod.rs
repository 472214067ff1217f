//! Helpers shared by the integration tests (each test file includes this with `mod common;`).

#![allow(dead_code)]

pub mod agreement;
pub mod binary;
pub mod ensemble;
pub mod inputs;
pub mod scenes;
