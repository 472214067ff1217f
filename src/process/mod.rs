//! What plexus does to its own process, and why: the settings that change how the operating
//! system and the CPU run it, never what it computes (an image is the same with or without them).
//!
//! - **Transparent huge pages** ([`huge_pages`]). Large arrays read at random places (textures'
//!   texels, meshes, the BVH's nodes) are advised for 2 MiB pages, since with 4 KiB pages those
//!   reads miss the TLB as well as the cache; arrays too small for that to matter, or so large
//!   that zeroing 2 MiB at a time on first touch costs more than the TLB saves, stay on 4 KiB
//!   pages. While Embree builds a large scene the process turns huge pages off for the build's
//!   primitive array (filled once, then freed) and back on for the tree that rays traverse
//!   (`huge_pages::BuildSwitch`, fed by Embree's memory monitor).
//! - **Flush-to-zero and denormals-are-zero** ([`denormals`]) on every thread that traces rays:
//!   Embree asks for them for speed, and with them on everywhere the two accelerators do the same
//!   arithmetic. The flags are per thread, so every pool sets them in its threads' start handler
//!   (`integrator::driver`, `bench`).
//!
//! Both are hints about speed: where the kernel refuses or the CPU lacks them, only timings change.

pub mod denormals;
pub(crate) mod huge_pages;
