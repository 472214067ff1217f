//! Generates the Embree 3 bindings (bindgen over ffi/embree.h) and compiles the OpenImageIO shim
//! (ffi/oiio_shim.cpp) into a shared library linked to OpenImageIO, which plexus embeds and opens
//! on first use; plexus itself links embree3 only.
//!
//! Everything here needs Debian 12's development packages; when one is missing the build stops
//! with a message saying which and how to install them.

use std::env;
use std::path::{Path, PathBuf};

const INSTALL_HINT: &str = "install the native dependencies with: \
     sudo apt-get install -y libembree-dev libopenimageio-dev libclang-dev";

fn fail(what: &str) -> ! {
    // Cargo shows a failed build script's stderr; the hint is what a new user needs (a panic
    // would add a backtrace that says nothing useful).
    eprintln!("\n\nplexus build: {what}\n{INSTALL_HINT}\n");
    std::process::exit(1);
}

/// Include directories and library directories that pkg-config reports for `package`, or None if
/// pkg-config or the package is unavailable. Only the paths are taken: the libraries are linked by
/// name below, after checking they exist, so that a missing one gets the install hint.
fn pkg_config(package: &str) -> Option<(Vec<PathBuf>, Vec<PathBuf>)> {
    let library = pkg_config::Config::new().cargo_metadata(false).probe(package).ok()?;
    Some((library.include_paths, library.link_paths))
}

/// The first of `extra` followed by the system include directories that contains `header`.
fn find_header(header: &str, extra: &[PathBuf]) -> Option<PathBuf> {
    let system = [PathBuf::from("/usr/include"), PathBuf::from("/usr/local/include")];
    extra.iter().chain(system.iter()).find(|dir| dir.join(header).is_file()).cloned()
}

/// Whether a shared library `lib{name}.so` is in `extra` or one of the usual library directories
/// (including Debian's multiarch ones and `LIBRARY_PATH`).
fn find_library(name: &str, extra: &[PathBuf]) -> bool {
    let file = format!("lib{name}.so");
    let mut dirs: Vec<PathBuf> = extra.to_vec();
    if let Some(paths) = env::var_os("LIBRARY_PATH") {
        dirs.extend(env::split_paths(&paths));
    }
    for root in ["/usr/lib", "/usr/local/lib", "/lib", "/usr/lib64"] {
        dirs.push(PathBuf::from(root));
        // Multiarch subdirectories such as /usr/lib/x86_64-linux-gnu.
        if let Ok(entries) = std::fs::read_dir(root) {
            dirs.extend(entries.flatten().map(|e| e.path()).filter(|p| p.to_string_lossy().contains("-linux-")));
        }
    }
    dirs.iter().any(|dir| dir.join(&file).exists())
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=ffi/embree.h");
    println!("cargo:rerun-if-changed=ffi/oiio_shim.h");
    println!("cargo:rerun-if-changed=ffi/oiio_shim.cpp");
    println!("cargo:rerun-if-env-changed=EMBREE_DIR");
    println!("cargo:rerun-if-env-changed=LIBRARY_PATH");

    let out_dir = PathBuf::from(env::var("OUT_DIR").expect("cargo sets OUT_DIR"));

    // --- Embree 3: no pkg-config file on Debian, so look for the header and link by name. ---
    let embree_dir = env::var_os("EMBREE_DIR").map(PathBuf::from);
    let mut embree_includes = Vec::new();
    if let Some(dir) = &embree_dir {
        embree_includes.push(dir.join("include"));
        println!("cargo:rustc-link-search=native={}", dir.join("lib").display());
    }
    let Some(embree_include) = find_header("embree3/rtcore.h", &embree_includes) else {
        fail("the Embree 3 header <embree3/rtcore.h> was not found (package libembree-dev)");
    };
    let embree_libdirs: Vec<PathBuf> = embree_dir.iter().map(|d| d.join("lib")).collect();
    if !find_library("embree3", &embree_libdirs) {
        fail("the Embree 3 library libembree3.so was not found (package libembree-dev)");
    }
    println!("cargo:rustc-link-lib=dylib=embree3");

    // bindgen loads libclang at run time and panics if it cannot; turn that into the same hint.
    let header = Path::new("ffi/embree.h");
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let generated = std::panic::catch_unwind(|| {
        bindgen::Builder::default()
            .header(header.to_string_lossy())
            .clang_arg(format!("-I{}", embree_include.display()))
            .allowlist_function("rtc.*")
            .allowlist_type("RTC.*")
            .allowlist_var("RTC.*")
            .default_enum_style(bindgen::EnumVariation::Consts)
            .prepend_enum_name(false)
            .derive_default(true)
            .layout_tests(false)
            .generate()
    });
    std::panic::set_hook(default_hook);
    let bindings = match generated {
        Ok(Ok(b)) => b,
        Ok(Err(e)) => fail(&format!("bindgen could not process ffi/embree.h: {e}")),
        Err(_) => fail("bindgen could not run (libclang missing? package libclang-dev)"),
    };
    bindings
        .write_to_file(out_dir.join("embree_sys.rs"))
        .unwrap_or_else(|e| fail(&format!("could not write the Embree bindings to OUT_DIR: {e}")));

    // --- OpenImageIO: pkg-config when available, otherwise the system paths. ---
    let (oiio_includes, oiio_libdirs) = pkg_config("OpenImageIO").unwrap_or_default();
    if find_header("OpenImageIO/imageio.h", &oiio_includes).is_none() {
        fail("the OpenImageIO header <OpenImageIO/imageio.h> was not found (package libopenimageio-dev)");
    }
    for lib in ["OpenImageIO", "OpenImageIO_Util"] {
        if !find_library(lib, &oiio_libdirs) {
            fail(&format!("the library lib{lib}.so was not found (package libopenimageio-dev)"));
        }
    }
    for dir in &oiio_libdirs {
        println!("cargo:rustc-link-search=native={}", dir.display());
    }
    // The shim is a shared library of its own, embedded in plexus and opened on first use
    // (src/film/oiio.rs): linking OpenImageIO into plexus would make every process load it and
    // its ~260 dependencies at start, 0.22 s and 130 MB before `main`, even for renders that only
    // write EXR (which the `exr` crate writes).
    let mut build = cc::Build::new();
    build.cpp(true).std("c++17").pic(true);
    let compiler = build.get_compiler();
    let shim = out_dir.join("libplexus_oiio.so");
    let mut command = compiler.to_command();
    command.args(["-shared", "-Wall", "-Wextra", "-s", "-Wl,--no-undefined", "-Wl,--as-needed"]);
    command.arg("-Iffi");
    for dir in &oiio_includes {
        command.arg(format!("-I{}", dir.display()));
    }
    command.arg("ffi/oiio_shim.cpp").arg("-o").arg(&shim);
    for dir in &oiio_libdirs {
        command.arg(format!("-L{}", dir.display()));
    }
    command.args(["-lOpenImageIO", "-lOpenImageIO_Util"]);
    match command.output() {
        Ok(out) if out.status.success() => {
            // Warnings, shown by cargo only with -vv; a failure's output is in the message below.
            eprint!("{}", String::from_utf8_lossy(&out.stderr));
        }
        Ok(out) => fail(&format!(
            "compiling ffi/oiio_shim.cpp into {} failed:\n{}",
            shim.display(),
            String::from_utf8_lossy(&out.stderr)
        )),
        Err(e) => fail(&format!("could not run the C++ compiler {:?}: {e}", compiler.path())),
    }
}
