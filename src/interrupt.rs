//! Ctrl-C and SIGTERM. The first signal sets [`stop_flag`], which the driver checks at
//! pass boundaries: the render finishes its pass, and the command line writes the image, the JSON
//! and a checkpoint before exiting with 130. A second signal exits with 130 without writing
//! anything more, and leaves no temporary file behind: every output is written by
//! [`write_atomically`] (a hidden `.*.plexus-tmp-HOST-PID-*` file renamed into place when complete;
//! the next write of the same file removes those a killed process left), and a
//! second signal that finds such a write under way lets that one file finish (or fail) and exits
//! when it ends; with none under way it exits at once. A third signal exits at once regardless,
//! removing the temporary files being written first ([`TempGuard`]).
//!
//! Why the second signal waits for the write: a file comes into being by name (the temporary
//! file's creation, and OpenImageIO's own open of that name) in a system call that a signal
//! handler cannot order itself against. A handler that removed the registered names and exited
//! at once left a temporary file or an output-check probe in 15 of 1,200 renders
//! (`scripts/stress_second_interrupt.py`), the file created just before its name was registered;
//! waiting for the write left none in 1,200, and the second signal ended the process 8.5 ms after
//! it was sent (median; 7.4 ms before, max 91 ms).
//!
//! The handler does only what a signal handler may (POSIX async-signal-safe calls: `write`,
//! `unlink`, `_exit`, and atomics): the temporary files' names live in a fixed table of atomic
//! pointers to C strings, which the handler takes (swaps out) before unlinking, so a guard being
//! dropped on another thread never frees a name the handler is reading.

use std::ffi::CString;
use std::os::unix::ffi::OsStrExt;
use std::path::Path;
use std::ptr;
use std::sync::atomic::{AtomicBool, AtomicPtr, AtomicUsize, Ordering};

/// Exit status after an interrupt (128 + SIGINT, as shells report it).
pub const EXIT_INTERRUPTED: i32 = 130;

static STOP: AtomicBool = AtomicBool::new(false);
/// Set by the second signal: quit as soon as no file is being written.
static QUIT: AtomicBool = AtomicBool::new(false);
/// Live [`FileWriting`] sections.
static FILES_BEING_WRITTEN: AtomicUsize = AtomicUsize::new(0);

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
        say(b"\ninterrupted: finishing the current pass, then writing the image and a checkpoint (interrupt again to quit without them)\n");
        return;
    }
    // Sequentially consistent against `FileWriting`'s drop (a count decrement, then a read of
    // QUIT): of this store-then-load and that decrement-then-load, at least one sees the other's
    // write, so either this handler sees no write under way or the last writer sees QUIT.
    let third = QUIT.swap(true, Ordering::SeqCst);
    if third || FILES_BEING_WRITTEN.load(Ordering::SeqCst) == 0 {
        quit_now();
    }
    say(b"\ninterrupted again: quitting as soon as the file being written is complete (interrupt a third time to quit now)\n");
}

/// Writes `msg` to stderr from a signal handler.
fn say(msg: &[u8]) {
    // SAFETY: `write` is async-signal-safe; the buffer is valid for its length.
    unsafe { libc::write(2, msg.as_ptr() as *const libc::c_void, msg.len()) };
}

/// Removes the temporary files being written and exits with 130.
fn quit_now() -> ! {
    remove_temp_files(|_| true);
    // SAFETY: `_exit` is async-signal-safe and never returns.
    unsafe { libc::_exit(EXIT_INTERRUPTED) }
}

/// A file being written: while one lives, a second signal does not exit but leaves the exit to
/// the last of them to end (its drop). Enter it before the file's name is created and keep it
/// until the file is renamed into place or removed.
#[must_use = "the section ends when this is dropped"]
pub struct FileWriting(());

impl FileWriting {
    /// Starts writing a file. After a second signal no new file is started: the thread waits here
    /// for the exit that the files still being written will make. Sections do not nest (no writer
    /// starts a file while writing one); a nested one would wait for itself, until a third signal.
    pub fn enter() -> FileWriting {
        FILES_BEING_WRITTEN.fetch_add(1, Ordering::SeqCst);
        let section = FileWriting(());
        if QUIT.load(Ordering::SeqCst) {
            drop(section);
            // Another file is still being written and exits when it ends.
            loop {
                std::thread::park();
            }
        }
        section
    }
}

impl Drop for FileWriting {
    fn drop(&mut self) {
        if FILES_BEING_WRITTEN.fetch_sub(1, Ordering::SeqCst) == 1 && QUIT.load(Ordering::SeqCst) {
            quit_now();
        }
    }
}

/// Writes the file `path` whole or not at all, under Ctrl-C too: `write` fills a hidden temporary
/// file beside it (given its path and the open file; writers that open it by name may ignore the
/// file), which is then renamed over `path`. On any error the temporary file is removed; the
/// temporary files of earlier writes of `path` by processes that were killed are removed first
/// (`remove_stale_temp_files`). With
/// `keep_extension` the temporary name ends in `path`'s extension (OpenImageIO chooses the format
/// by it). The file is created with mode 0666 before the umask, as `std::fs::write` would create it
/// (tempfile's own default is 0600).
pub fn write_atomically<E>(
    path: &Path,
    keep_extension: bool,
    io_error: impl Fn(std::io::Error) -> E,
    write: impl FnOnce(&Path, &mut std::fs::File) -> Result<(), E>,
) -> Result<(), E> {
    use std::os::unix::fs::PermissionsExt;
    // Declared first, so dropped last: after the rename, or the temporary file's removal.
    let _writing = FileWriting::enter();
    let dir = directory_of(path);
    let name = |p: Option<&std::ffi::OsStr>| p.map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let (base, suffix) = match (keep_extension, path.extension()) {
        (true, Some(ext)) => (format!(".{}.plexus-tmp-", name(path.file_stem())), format!(".{}", name(Some(ext)))),
        _ => (format!(".{}.plexus-tmp-", name(path.file_name())), String::new()),
    };
    let owner = TempOwner::this_process();
    remove_stale_temp_files(dir, &base, &suffix, &owner);
    let mut file = tempfile::Builder::new()
        .prefix(&format!("{base}{}-", owner.tag()))
        .suffix(&suffix)
        .permissions(std::fs::Permissions::from_mode(0o666))
        .tempfile_in(dir)
        .map_err(&io_error)?;
    // For a third signal, which does not wait.
    let _guard = TempGuard::new(file.path());
    let temp = file.path().to_path_buf();
    write(&temp, file.as_file_mut())?;
    file.persist(path).map_err(|e| io_error(e.error))?;
    Ok(())
}

/// Who writes a temporary file, as its name records it (`.NAME.plexus-tmp-HOST-PID-XXXXXX`): the
/// host, so that a process on another machine writing into a shared directory (a cluster's
/// batch) is never taken for a dead one here, and the process id.
struct TempOwner {
    host: String,
    pid: u32,
}

impl TempOwner {
    fn this_process() -> TempOwner {
        TempOwner { host: host_name(), pid: std::process::id() }
    }

    fn tag(&self) -> String {
        format!("{}-{}", self.host, self.pid)
    }
}

/// This machine's name, reduced to characters that cannot be confused with the name's
/// separators ('-' included); "host" when it cannot be read.
fn host_name() -> String {
    let mut buf = [0u8; 256];
    // SAFETY: `buf` is writable for its length; gethostname writes at most that many bytes.
    let ok = unsafe { libc::gethostname(buf.as_mut_ptr() as *mut libc::c_char, buf.len()) } == 0;
    let len = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
    let name: String =
        String::from_utf8_lossy(&buf[..len]).chars().filter(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
    if ok && !name.is_empty() {
        name
    } else {
        "host".into()
    }
}

/// Whether process `pid` of this machine is gone: `kill(pid, 0)` fails with ESRCH. A process
/// that exists but belongs to another user (EPERM) is alive.
fn process_is_gone(pid: u32) -> bool {
    let Ok(pid) = libc::pid_t::try_from(pid) else { return false };
    // SAFETY: signal 0 sends nothing; it only checks that the process exists.
    let r = unsafe { libc::kill(pid, 0) };
    r == -1 && std::io::Error::last_os_error().raw_os_error() == Some(libc::ESRCH)
}

/// Removes the temporary files of earlier writes of the same file (`base` and `suffix` of its
/// temporary names) left by processes of this machine that no longer exist: a process killed
/// with SIGKILL (or a crash of the machine) mid-write cannot remove its own. Only regular files
/// are removed, never links; files of live processes and of other machines are left alone, as
/// are names that do not parse as `base` HOST-PID-XXXXXX `suffix` (older plexus versions wrote
/// no owner). Best effort: a directory that cannot be listed is left as it is.
fn remove_stale_temp_files(dir: &Path, base: &str, suffix: &str, owner: &TempOwner) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    let host_prefix = format!("{base}{}-", owner.host);
    for entry in entries.flatten() {
        let file_name = entry.file_name();
        let Some(name) = file_name.to_str() else { continue };
        let Some(rest) = name.strip_prefix(&host_prefix).and_then(|r| r.strip_suffix(suffix)) else { continue };
        let Some((pid, random)) = rest.split_once('-') else { continue };
        let Ok(pid) = pid.parse::<u32>() else { continue };
        if random.is_empty() || pid == owner.pid || !process_is_gone(pid) {
            continue;
        }
        let path = entry.path();
        if std::fs::symlink_metadata(&path).is_ok_and(|m| m.file_type().is_file()) {
            let _ = std::fs::remove_file(&path);
        }
    }
}

/// The directory a file `path` is created in: its parent, or "." for a bare name.
pub fn directory_of(path: &Path) -> &Path {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    }
}

/// Unlinks every registered temporary file `which` selects (on quitting: all of them) before
/// exiting. `which` must be async-signal-safe too.
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

/// Registers a temporary file for removal by a signal that quits while the guard lives. Drop it
/// once the file is renamed into place or removed.
struct TempGuard {
    slot: Option<(usize, *mut libc::c_char)>,
}

impl TempGuard {
    fn new(path: &Path) -> TempGuard {
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

    /// A write removes the temporary files a killed process of this machine left for the same
    /// file, and nothing else: not a live process's, not another machine's, not another file's,
    /// not a link, not a name without an owner.
    #[test]
    fn a_write_removes_what_a_killed_writer_left() {
        let dir = tempfile::tempdir().expect("temp dir");
        let d = dir.path();
        let host = host_name();
        let mut child = std::process::Command::new("true").spawn().expect("spawn true");
        let dead = child.id();
        child.wait().expect("wait");
        assert!(process_is_gone(dead), "the child has exited");
        let stale = d.join(format!(".o.pxstate.plexus-tmp-{host}-{dead}-aB3xYz"));
        let stale_exr = d.join(format!(".o.plexus-tmp-{host}-{dead}-Qw12er.exr"));
        let live = d.join(format!(".o.pxstate.plexus-tmp-{host}-1-aB3xYz"));
        let elsewhere = d.join(format!(".o.pxstate.plexus-tmp-otherhost-{dead}-aB3xYz"));
        let other_file = d.join(format!(".p.pxstate.plexus-tmp-{host}-{dead}-aB3xYz"));
        let unowned = d.join(".o.pxstate.plexus-tmp-aB3xYz");
        let target = d.join("kept");
        let link = d.join(format!(".o.pxstate.plexus-tmp-{host}-{dead}-LiNk00"));
        for p in [&stale, &stale_exr, &live, &elsewhere, &other_file, &unowned, &target] {
            std::fs::write(p, "x").expect("write");
        }
        std::os::unix::fs::symlink(&target, &link).expect("symlink");
        let write = |name: &str, keep_extension: bool| {
            write_atomically(&d.join(name), keep_extension, |e| e, |_, f| std::io::Write::write_all(f, b"state"))
                .expect("write")
        };
        write("o.pxstate", false);
        assert!(!stale.exists(), "a dead process's temporary file of the same file is removed");
        for p in [&stale_exr, &live, &elsewhere, &other_file, &unowned, &target] {
            assert!(p.exists(), "{} is not this write's to remove", p.display());
        }
        assert!(std::fs::symlink_metadata(&link).is_ok(), "a link is never removed");
        write("o.exr", true);
        assert!(!stale_exr.exists(), "with the extension kept too");
        let left: Vec<_> = std::fs::read_dir(d)
            .expect("list")
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.contains(&format!("-{}-", std::process::id())))
            .collect();
        assert!(left.is_empty(), "the writes left their own temporary files: {left:?}");
    }

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
