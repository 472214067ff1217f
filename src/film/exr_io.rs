//! PLACEHOLDER: EXR reading with the exr crate.
