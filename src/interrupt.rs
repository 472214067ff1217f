//! Ctrl-C and SIGTERM (issue 19). The first signal sets [`stop_flag`], which the driver checks at
//! pass boundaries: the render finishes its pass, and the command line writes the image, the JSON
//! and a checkpoint before exiting with 130. A second signal exits at once with 130 — but first
//! removes every temporary file being written ([`TempGuard`]), so that not even an interrupted
//! image, JSON or state file is left behind as a hidden `.*.plexus-tmp-*`.
//!
//! The handler does only what a signal handler may (POSIX async-signal-safe calls: `write`,
//! `unlink`, `_exit`, and atomics): the temporary files' names live in a fixed table of atomic
//! pointers to C strings, which the handler takes (swaps out) before unlinking, so a guard being
//! dropped on another thread never frees a name the handler is reading.

use std::ffi::CString;
use std::os::unix::ffi::OsStrExt;
use std::path::Path;
use std::ptr;
use std::sync::atomic::{AtomicBool, AtomicPtr, Ordering};

/// Exit status after an interrupt (128 + SIGINT, as shells report it).
pub const EXIT_INTERRUPTED: i32 = 130;

static STOP: AtomicBool = AtomicBool::new(false);

/// Temporary files being written, at most this many at once (a render writes one at a time; the
/// spare slots are for tests and future parallel writers). A file that finds no free slot is
/// written unguarded.
const SLOTS: usize = 64;
static TEMP_FILES: [AtomicPtr<libc::c_char>; SLOTS] = [const { AtomicPtr::new(ptr::null_mut()) }; SLOTS];

/// The flag the first SIGINT or SIGTERM sets (pass it to `RunControl::stop`).
pub fn stop_flag() -> &'static AtomicBool {
    &STOP
}

/// Installs the handler for SIGINT and SIGTERM.
pub fn install() -> std::io::Result<()> {
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        // SAFETY: `on_signal` only uses atomics and the async-signal-safe `write`, `unlink` and
        // `_exit`; it allocates nothing and takes no lock.
        unsafe { signal_hook::low_level::register(signal, on_signal)? };
    }
    Ok(())
}

fn on_signal() {
    if !STOP.swap(true, Ordering::SeqCst) {
        let msg = b"\ninterrupted: finishing the current pass, then writing the image and a checkpoint (interrupt again to quit at once)\n";
        // SAFETY: `write` is async-signal-safe; the buffer is valid for its length.
        unsafe { libc::write(2, msg.as_ptr() as *const libc::c_void, msg.len()) };
        return;
    }
    remove_temp_files(|_| true);
    // SAFETY: `_exit` is async-signal-safe and never returns.
    unsafe { libc::_exit(EXIT_INTERRUPTED) };
}

/// Unlinks every registered temporary file `which` selects (the second signal: all of them)
/// before exiting. `which` must be async-signal-safe too.
fn remove_temp_files(which: impl Fn(&std::ffi::CStr) -> bool) {
    for slot in &TEMP_FILES {
        // Taken out of the table first: from then on its guard cannot free it.
        let name = slot.swap(ptr::null_mut(), Ordering::SeqCst);
        if name.is_null() {
            continue;
        }
        // SAFETY: `name` is a NUL-terminated string from `CString::into_raw` that we now own.
        if !which(unsafe { std::ffi::CStr::from_ptr(name) }) {
            // Not ours to remove (tests select their own files): put it back for its guard. Should
            // the guard have been dropped meanwhile, the name stays registered and a later second
            // signal unlinks a path that no longer exists (a leak of a few bytes, nothing else).
            let _ = slot.compare_exchange(ptr::null_mut(), name, Ordering::SeqCst, Ordering::SeqCst);
            continue;
        }
        // SAFETY: as above; the name is leaked, the process is about to exit.
        unsafe { libc::unlink(name) };
    }
}

/// Registers a temporary file for removal by a second signal while the guard lives. Drop it once
/// the file is renamed into place or removed.
pub struct TempGuard {
    slot: Option<(usize, *mut libc::c_char)>,
}

impl TempGuard {
    pub fn new(path: &Path) -> TempGuard {
        let Ok(name) = CString::new(path.as_os_str().as_bytes()) else { return TempGuard { slot: None } };
        let raw = name.into_raw();
        for (i, slot) in TEMP_FILES.iter().enumerate() {
            if slot.compare_exchange(ptr::null_mut(), raw, Ordering::SeqCst, Ordering::SeqCst).is_ok() {
                return TempGuard { slot: Some((i, raw)) };
            }
        }
        // SAFETY: `raw` came from `into_raw` just above and was stored nowhere.
        drop(unsafe { CString::from_raw(raw) });
        TempGuard { slot: None }
    }
}

impl Drop for TempGuard {
    fn drop(&mut self) {
        let Some((i, raw)) = self.slot else { return };
        if TEMP_FILES[i].compare_exchange(raw, ptr::null_mut(), Ordering::SeqCst, Ordering::SeqCst).is_ok() {
            // SAFETY: we took our own pointer back out of the table, so nothing else can read it.
            drop(unsafe { CString::from_raw(raw) });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What the second signal does: a registered temporary file is removed, an unregistered one
    /// (its guard dropped) is not, and the guard of a removed file drops cleanly.
    #[test]
    fn registered_temporary_files_are_removed() {
        let dir = tempfile::tempdir().expect("temp dir");
        let (a, b) = (dir.path().join(".a.plexus-tmp-1"), dir.path().join("b"));
        std::fs::write(&a, "x").expect("write");
        std::fs::write(&b, "x").expect("write");
        let guard_a = TempGuard::new(&a);
        drop(TempGuard::new(&b));
        // Only this test's files: other tests may be writing images at the same time.
        remove_temp_files(|name| name.to_bytes().starts_with(dir.path().as_os_str().as_bytes()));
        assert!(!a.exists(), "the registered file is removed");
        assert!(b.exists(), "a file whose guard was dropped stays");
        drop(guard_a);
    }
}
