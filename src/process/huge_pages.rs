//! Transparent huge pages: on for large arrays that are read at random places, textures' texels,
//! meshes' positions and indices, and the BVH's nodes, leaf packets and ids. With 4 KiB pages such
//! reads miss the TLB as well as the cache (a 2 MiB page covers 512 times as much); Linux backs
//! memory with 2 MiB pages where it is asked to (`madvise(MADV_HUGEPAGE)`, which a
//! `transparent_hugepage/enabled` of `madvise` requires) and the region is 2 MiB-aligned. Hints
//! only: where they are refused or unsupported, the memory and its contents are the same, only the
//! page size differs.

use std::mem::MaybeUninit;
use std::ops::{Deref, DerefMut};
use std::sync::atomic::{AtomicBool, AtomicI64, Ordering};

use rayon::prelude::*;

/// The x86-64 (and common aarch64) transparent huge page size.
pub(crate) const HUGE_PAGE: usize = 2 << 20;

/// Arrays of at most this many bytes are placed on huge pages ([`HugeArray`]). Above it they stay
/// on 4 KiB pages: the first touch of a huge page zeroes 2 MiB at once, which in this VM costs
/// about four times as much per byte as 4 KiB faults ([`BuildSwitch`]'s comment: 28–33% of the
/// 10M-triangle load was `clear_page_erms`), and the arrays of
/// such scenes are read too sparsely for the TLB to be what limits them.
pub(crate) const HUGE_PAGE_ARRAY_BYTES: usize = 64 << 20;

/// Arrays of fewer bytes stay on the heap: 4 KiB pages' TLB reach (the second-level TLB's 1,500 or
/// more entries cover 6 MiB) holds them, and a 2 MiB page would more than double them.
pub(crate) const HUGE_PAGE_MIN_BYTES: usize = 1 << 20;

/// Asks Linux to back the 2 MiB-aligned part of `v`'s (still untouched) allocation with huge pages,
/// before it is filled. Bilinear lookups read texels at random places of a large image (every
/// bounce off a textured surface); with 4 KiB pages most of them also miss the TLB (the door's
/// images span ~7,500 pages).
pub(crate) fn advise_huge_pages<T>(v: &Vec<T>) {
    #[cfg(target_os = "linux")]
    {
        let start = v.as_ptr() as usize;
        let end = start + v.capacity() * std::mem::size_of::<T>();
        let (first, last) = (start.next_multiple_of(HUGE_PAGE), end & !(HUGE_PAGE - 1));
        if last > first {
            // SAFETY: [first, last) lies inside the allocation `v` owns; MADV_HUGEPAGE only
            // changes how the kernel backs those pages, not what they hold or who may use them.
            unsafe { libc::madvise(first as *mut libc::c_void, last - first, libc::MADV_HUGEPAGE) };
        }
    }
}

/// `v` with room for `spare` more elements. When it holds 1–64 MiB, moved into a fresh allocation
/// whose 2 MiB-aligned part is advised for huge pages before it is written; otherwise `v` itself
/// (a larger array is not copied: the 10M-triangle scene's load would hold both copies at once).
/// A `Vec` rather than a [`HugeArray`]: the meshes' arrays are read through slices in the path
/// tracer's innermost loop, where `HugeArray`'s two storages cost a branch per access and enough
/// code to change the inliner's choices (the door's pt 8% slower, docs/lab/performance.md).
pub(crate) fn on_huge_pages<T: Copy>(mut v: Vec<T>, spare: usize) -> Vec<T> {
    if !(HUGE_PAGE_MIN_BYTES..=HUGE_PAGE_ARRAY_BYTES).contains(&std::mem::size_of_val(&v[..])) {
        v.reserve_exact(spare);
        return v;
    }
    let mut copy = Vec::with_capacity(v.len() + spare);
    advise_huge_pages(&copy);
    copy.extend_from_slice(&v);
    copy
}

/// An empty `Vec` with room for `capacity` elements, advised for huge pages (before anything is
/// written) when it holds 1–64 MiB, as [`on_huge_pages`] places an array it is given.
pub(crate) fn vec_for_random_reads<T>(capacity: usize) -> Vec<T> {
    let v = Vec::with_capacity(capacity);
    if (HUGE_PAGE_MIN_BYTES..=HUGE_PAGE_ARRAY_BYTES).contains(&(capacity * std::mem::size_of::<T>())) {
        advise_huge_pages(&v);
    }
    v
}

/// A fixed-length array of `Copy` elements which, when it holds between [`HUGE_PAGE_MIN_BYTES`]
/// and [`HUGE_PAGE_ARRAY_BYTES`] bytes, lives in its own 2 MiB-aligned anonymous mapping (its
/// length rounded up to whole huge pages) advised for huge pages before it is first written;
/// otherwise (or where the mapping fails) in a `Vec`. Reads as a slice either way.
pub(crate) struct HugeArray<T: Copy> {
    storage: Storage<T>,
}

enum Storage<T> {
    Heap(Vec<T>),
    /// `len` initialised elements at `ptr`, the start of a mapping of `bytes` bytes (a multiple of
    /// `HUGE_PAGE`, at a `HUGE_PAGE`-aligned address) that this array owns, advised for huge
    /// pages. Only made on Linux.
    Mapped {
        ptr: *mut T,
        len: usize,
        bytes: usize,
    },
}

// SAFETY: a `HugeArray` owns its elements like a `Vec` (the mapping is not shared with anything
// else), so it may move between and be shared by threads as its elements may.
unsafe impl<T: Copy + Send> Send for HugeArray<T> {}
// SAFETY: as above; `&HugeArray` only hands out `&[T]`.
unsafe impl<T: Copy + Sync> Sync for HugeArray<T> {}

impl<T: Copy + Send + Sync> HugeArray<T> {
    /// The elements of `iter`, written in parallel straight into the array's memory (no copy).
    pub(crate) fn from_par_iter<I: IndexedParallelIterator<Item = T>>(iter: I) -> Self {
        let len = iter.len();
        match Self::map(len) {
            Some(Storage::Mapped { ptr, len, bytes }) => {
                // SAFETY: the mapping holds at least `len` elements of `T` at the aligned `ptr`,
                // writable and owned by nothing else; `MaybeUninit` makes no claim on them.
                let slots = unsafe { std::slice::from_raw_parts_mut(ptr.cast::<MaybeUninit<T>>(), len) };
                slots.par_iter_mut().zip(iter).for_each(|(slot, x)| {
                    slot.write(x);
                });
                // Every slot was written once by the zip above (`iter.len() == len`).
                HugeArray { storage: Storage::Mapped { ptr, len, bytes } }
            }
            _ => HugeArray { storage: Storage::Heap(iter.collect()) },
        }
    }

    /// The elements of `v`: copied into a huge-page mapping when its size calls for one, else
    /// kept as they are (no copy).
    pub(crate) fn from_vec(v: Vec<T>) -> Self {
        match Self::map(v.len()) {
            Some(Storage::Mapped { ptr, len, bytes }) => {
                // SAFETY: the fresh mapping holds `len` elements at `ptr` and does not overlap `v`.
                unsafe { std::ptr::copy_nonoverlapping(v.as_ptr(), ptr, len) };
                HugeArray { storage: Storage::Mapped { ptr, len, bytes } }
            }
            _ => HugeArray { storage: Storage::Heap(v) },
        }
    }
}

impl<T: Copy> HugeArray<T> {
    /// A fresh advised mapping for `len` elements (not yet written), or `None` where the array
    /// stays on the heap.
    fn map(len: usize) -> Option<Storage<T>> {
        let size = len.checked_mul(std::mem::size_of::<T>())?;
        if !(HUGE_PAGE_MIN_BYTES..=HUGE_PAGE_ARRAY_BYTES).contains(&size) || std::mem::align_of::<T>() > HUGE_PAGE {
            return None;
        }
        #[cfg(target_os = "linux")]
        {
            let bytes = size.next_multiple_of(HUGE_PAGE);
            // One huge page more than needed, so that an aligned start lies inside; the rest is
            // unmapped again.
            let reserve = bytes + HUGE_PAGE;
            // SAFETY: a new private anonymous mapping: it aliases nothing.
            let base = unsafe {
                libc::mmap(
                    std::ptr::null_mut(),
                    reserve,
                    libc::PROT_READ | libc::PROT_WRITE,
                    libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                    -1,
                    0,
                )
            };
            if base == libc::MAP_FAILED {
                return None;
            }
            let (base, start) = (base as usize, (base as usize).next_multiple_of(HUGE_PAGE));
            // SAFETY: both ranges lie inside the mapping just made, outside [start, start + bytes),
            // and nothing refers to them.
            unsafe {
                if start > base {
                    libc::munmap(base as *mut libc::c_void, start - base);
                }
                let tail = base + reserve - (start + bytes);
                if tail > 0 {
                    libc::munmap((start + bytes) as *mut libc::c_void, tail);
                }
            }
            // SAFETY: [start, start + bytes) is the untouched mapping this array will own;
            // MADV_HUGEPAGE changes only the page size the kernel backs it with.
            // A refusal (a kernel without transparent huge pages) leaves 4 KiB pages: no error.
            unsafe { libc::madvise(start as *mut libc::c_void, bytes, libc::MADV_HUGEPAGE) };
            Some(Storage::Mapped { ptr: start as *mut T, len, bytes })
        }
        #[cfg(not(target_os = "linux"))]
        None
    }

    /// Bytes the array holds: the heap allocation's capacity, or the whole mapping (resident in
    /// full once touched, with huge pages).
    pub(crate) fn bytes(&self) -> usize {
        match &self.storage {
            Storage::Heap(v) => v.capacity() * std::mem::size_of::<T>(),
            Storage::Mapped { bytes, .. } => *bytes,
        }
    }
}

impl<T: Copy> Deref for HugeArray<T> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        match &self.storage {
            Storage::Heap(v) => v,
            // SAFETY: `len` initialised elements at `ptr`, owned by `self` (see `Storage`).
            Storage::Mapped { ptr, len, .. } => unsafe { std::slice::from_raw_parts(*ptr, *len) },
        }
    }
}

impl<T: Copy> DerefMut for HugeArray<T> {
    fn deref_mut(&mut self) -> &mut [T] {
        match &mut self.storage {
            Storage::Heap(v) => v,
            // SAFETY: as in `deref`, and `&mut self` makes the access exclusive.
            Storage::Mapped { ptr, len, .. } => unsafe { std::slice::from_raw_parts_mut(*ptr, *len) },
        }
    }
}

impl<T: Copy> Drop for HugeArray<T> {
    fn drop(&mut self) {
        #[cfg(target_os = "linux")]
        if let Storage::Mapped { ptr, bytes, .. } = self.storage {
            // SAFETY: the mapping is this array's own; `T: Copy` needs no drop of its elements.
            unsafe { libc::munmap(ptr.cast(), bytes) };
        }
    }
}

/// Whether the kernel records huge-page advice (`hg` in `/proc/self/smaps`'s `VmFlags`) for the
/// mapping that holds `p`, for the tests.
/// Whether the kernel may back the process's new memory with transparent huge pages while Embree
/// builds. Embree asks for them (`madvise(MADV_HUGEPAGE)`) for every array it allocates; the first
/// touch of a huge page zeroes 2 MB at once, which in a virtual machine whose free memory the host
/// has reclaimed costs about 3 s per GB against 0.7 s in 4 kB pages (measured on the 2-core KVM
/// guest: docs/lab/performance.md). The build's largest temporary, its primitive array (32 bytes a
/// triangle, filled once before the tree is built), gains nothing from huge pages: while a commit
/// is armed, an allocation of at least `threshold` bytes turns them off for the process
/// (`PR_SET_THP_DISABLE`, which the kernel checks at each page fault), and the next smaller one
/// (the tree's nodes and leaves, which rays traverse and which keep their huge pages) turns them
/// back on. The commit turns them back on in any case when it returns. Only the speed of page
/// faults depends on this; what Embree builds is the same. `accel::embree` reports its
/// allocations here from Embree's memory monitor.
#[derive(Default)]
pub(crate) struct BuildSwitch {
    threshold: AtomicI64,
    disabled: AtomicBool,
}

impl BuildSwitch {
    pub(crate) fn arm(&self, threshold: i64) {
        self.threshold.store(threshold, Ordering::Relaxed);
    }

    pub(crate) fn allocation(&self, bytes: isize) {
        let threshold = self.threshold.load(Ordering::Relaxed);
        if threshold <= 0 || bytes <= 0 {
            return;
        }
        let disable = bytes as i64 >= threshold;
        if self.disabled.swap(disable, Ordering::Relaxed) != disable {
            set_huge_pages(!disable);
        }
    }

    pub(crate) fn disarm(&self) {
        self.threshold.store(0, Ordering::Relaxed);
        if self.disabled.swap(false, Ordering::Relaxed) {
            set_huge_pages(true);
        }
    }
}

/// Lets (or stops) the kernel back this process's new memory with transparent huge pages where
/// they were asked for. A failure (an old kernel) changes only the speed of page faults.
fn set_huge_pages(allowed: bool) {
    #[cfg(target_os = "linux")]
    // SAFETY: PR_SET_THP_DISABLE takes one integer argument and touches no memory of ours.
    unsafe {
        libc::prctl(libc::PR_SET_THP_DISABLE, libc::c_ulong::from(!allowed), 0, 0, 0);
    }
    #[cfg(not(target_os = "linux"))]
    let _ = allowed;
}

#[cfg(all(test, target_os = "linux"))]
pub(crate) fn advised_for_huge_pages<T>(p: *const T) -> bool {
    vm_flags_at(p as usize).is_some_and(|f| f.split_whitespace().any(|w| w == "hg"))
}

/// The `VmFlags` of the mapping that holds `addr` in `/proc/self/smaps`.
#[cfg(all(test, target_os = "linux"))]
fn vm_flags_at(addr: usize) -> Option<String> {
    let smaps = std::fs::read_to_string("/proc/self/smaps").ok()?;
    let mut inside = false;
    for line in smaps.lines() {
        let range = line.split_whitespace().next().and_then(|r| r.split_once('-'));
        if let Some((lo, hi)) =
            range.and_then(|(a, b)| Some((usize::from_str_radix(a, 16).ok()?, usize::from_str_radix(b, 16).ok()?)))
        {
            inside = (lo..hi).contains(&addr);
        } else if let Some(flags) = line.strip_prefix("VmFlags:").filter(|_| inside) {
            return Some(flags.trim().to_string());
        }
    }
    None
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;

    #[test]
    fn arrays_between_the_bounds_get_an_advised_aligned_mapping() {
        // Between the bounds (parallel fill and copy): an aligned mapping whose huge-page advice
        // the kernel records (`hg` in smaps' VmFlags), and the same elements.
        let n = 3_000_000usize; // 12 MB of u32
        let filled = HugeArray::from_par_iter((0..n as u32).into_par_iter().map(|i| i.wrapping_mul(2_654_435_761)));
        let copied = HugeArray::from_vec((0..n as u32).map(|i| i.wrapping_mul(2_654_435_761)).collect());
        for a in [&filled, &copied] {
            assert!(advised_for_huge_pages(a.as_ptr()), "no huge-page advice on the mapping");
            assert_eq!(a.as_ptr() as usize % HUGE_PAGE, 0);
            assert_eq!(a.bytes(), (4 * n).next_multiple_of(HUGE_PAGE));
            assert_eq!(a.len(), n);
        }
        assert!(filled
            .iter()
            .zip(copied.iter())
            .enumerate()
            .all(|(i, (&f, &c))| f == c && f == (i as u32).wrapping_mul(2_654_435_761)));
        // Below and above the bounds: plain heap memory.
        let small = HugeArray::from_vec(vec![7u8; HUGE_PAGE_MIN_BYTES - 1]);
        let large = HugeArray::from_par_iter(rayon::iter::repeat_n(7u8, HUGE_PAGE_ARRAY_BYTES + 1));
        for a in [&small, &large] {
            assert!(!advised_for_huge_pages(a.as_ptr()), "a heap array advised");
            assert!(a.iter().all(|&x| x == 7));
        }
        assert_eq!(large.len(), HUGE_PAGE_ARRAY_BYTES + 1);
    }

    /// The huge-page switch of a large build (`BuildSwitch`): off for an allocation of at least the
    /// threshold (the primitive array), on again for the next smaller one (the tree's blocks) and
    /// when the commit disarms it; untouched when not armed. Read back with PR_GET_THP_DISABLE.
    #[test]
    #[cfg(target_os = "linux")]
    fn huge_pages_are_off_only_for_the_build_primitive_array() {
        // SAFETY: PR_GET_THP_DISABLE takes no argument and touches no memory of ours.
        let disabled = || unsafe { libc::prctl(libc::PR_GET_THP_DISABLE, 0, 0, 0, 0) } == 1;
        let h = BuildSwitch::default();
        h.allocation(1 << 30);
        assert!(!disabled(), "not armed: no change");
        h.arm(1000);
        h.allocation(999);
        assert!(!disabled(), "below the threshold");
        h.allocation(1000);
        assert!(disabled(), "the primitive array");
        h.allocation(-1000);
        assert!(disabled(), "a release changes nothing");
        h.allocation(64);
        assert!(!disabled(), "the tree's blocks");
        h.allocation(5000);
        assert!(disabled());
        h.disarm();
        assert!(!disabled(), "the commit's end");
        h.allocation(5000);
        assert!(!disabled(), "disarmed");
    }
}
