//! The default scene: the Cornell box, compiled into the binary from the same file that ships as
//! `scenes/cornell-box.toml`, so the two cannot drift apart.

use std::path::Path;

use super::{load_scene_str, LoadedScene, SceneError};
use crate::accel::AccelKind;

/// The text of `scenes/cornell-box.toml`.
pub const CORNELL_BOX_TOML: &str = include_str!("../../scenes/cornell-box.toml");

/// Builds the built-in Cornell box (inline shapes only, so it needs no files at run time).
pub fn builtin_cornell_box(accel: Option<AccelKind>) -> Result<LoadedScene, SceneError> {
    load_scene_str(CORNELL_BOX_TOML, Path::new(""), "<built-in cornell-box>", accel)
}
