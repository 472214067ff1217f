//! PLACEHOLDER until the FFI work lands.
