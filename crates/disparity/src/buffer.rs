//! Large working buffers whose every entry is written before it is read (the aggregation volume,
//! the strip's kept costs). On Linux they are anonymous mappings advised to use transparent huge
//! pages, so a multi-hundred-megabyte aggregation volume costs a few hundred page faults instead
//! of tens of thousands; elsewhere (or if the mapping fails) a zeroed `Vec`.
//!
//! In a process that asked for it ([`keep_strip_buffers`]: a batch, the Python package) a freed
//! mapping is kept (up to [`KEPT_BYTES`] in all) for the next call's buffers: a matcher called
//! again (a Python loop, a video stream) then neither faults its volume in nor has the kernel zero
//! it, as OpenCV's matchers keep their buffers between calls (docs/perf-notes.md). A one-shot run
//! does not keep them: its post-processing would hold them beside its own buffers.

use std::sync::atomic::{AtomicBool, Ordering};
#[cfg(target_os = "linux")]
use std::sync::Mutex;

/// Whether freed mappings are kept ([`keep_strip_buffers`]).
static KEEPING: AtomicBool = AtomicBool::new(false);

/// Keeps the matcher's largest working buffers (the aggregation strip and its cost rows, up to
/// 64 MiB in the process) after each call for the next call of the same size, instead of returning
/// them to the system: for a process that matches pair after pair, where the system would
/// otherwise fault them in and zero them again on every call (5–25 % of a warm call's match time
/// on the Middlebury pairs). While it is on, the two-pass aggregation's 8-bit passes (AVX-512) also
/// keep each strip row's matching costs for the second pass instead of computing them twice (a
/// fresh buffer for them costs a one-shot call more in page faults than it saves). Off by
/// default; the command line's batch and the Python package turn it on. `false` returns the kept
/// buffers to the system. Maps are the same either way.
///
/// ```
/// stereo_disparity::keep_strip_buffers(true);
/// // ... match a stream of pairs ...
/// stereo_disparity::keep_strip_buffers(false);
/// ```
pub fn keep_strip_buffers(keep: bool) {
    KEEPING.store(keep, Ordering::Relaxed);
    #[cfg(target_os = "linux")]
    if !keep {
        KEPT.lock().unwrap_or_else(|e| e.into_inner()).drain(..).for_each(unmap);
    }
}

/// Whether [`keep_strip_buffers`] is on: a buffer mapped for this call is likely to be reused
/// by the next one, so its page faults are paid once per process rather than once per call.
pub(crate) fn keeping() -> bool {
    KEEPING.load(Ordering::Relaxed)
}

/// A `[T]` of plain integers, freed (or kept for reuse) on drop. Its contents are unspecified: zero
/// when fresh, what its last user wrote when reused.
pub(crate) struct ScratchBuffer<T: Copy> {
    ptr: *mut T,
    len: usize,
    /// Bytes mapped, or 0 when the memory belongs to `fallback`.
    mapped: usize,
    fallback: Vec<T>,
}

// SAFETY: the buffer owns its memory exclusively, like a `Vec<T>`.
unsafe impl<T: Copy + Send> Send for ScratchBuffer<T> {}
// SAFETY: shared access only reads, like `&[T]`.
unsafe impl<T: Copy + Sync> Sync for ScratchBuffer<T> {}

/// Smaller buffers come from the allocator (tiny pairs: not worth a system call).
#[cfg_attr(not(target_os = "linux"), allow(dead_code))]
const MAP_THRESHOLD: usize = 1 << 20;

/// Freed mappings kept for reuse, in bytes at most: the default strip volume and its kept costs
/// (16 MiB each, `memory::DEFAULT_STRIP_BYTES`) for two pairs matched at once. Larger mappings
/// (a volume sized by `--max-memory` for a huge pair) go back to the system.
#[cfg_attr(not(target_os = "linux"), allow(dead_code))]
const KEPT_BYTES: usize = 64 << 20;

/// A kept mapping: its address and length in bytes.
#[cfg(target_os = "linux")]
struct Mapping {
    addr: usize,
    bytes: usize,
}

/// The kept mappings, oldest first.
#[cfg(target_os = "linux")]
static KEPT: Mutex<Vec<Mapping>> = Mutex::new(Vec::new());

/// A kept mapping of at least `bytes` (and at most twice that, so a small buffer does not pin a
/// large one), the smallest such. Without one the kept mappings are first returned to the system
/// (the pairs' sizes changed), so a pair of another size does not hold them beside its own.
#[cfg(target_os = "linux")]
fn take_kept(bytes: usize) -> Option<Mapping> {
    let mut kept = KEPT.lock().unwrap_or_else(|e| e.into_inner());
    let fitting = kept
        .iter()
        .enumerate()
        .filter(|(_, m)| m.bytes >= bytes && m.bytes / 2 <= bytes)
        .min_by_key(|(_, m)| m.bytes)
        .map(|(i, _)| i);
    match fitting {
        Some(i) => Some(kept.remove(i)),
        None => {
            kept.drain(..).for_each(unmap);
            None
        }
    }
}

/// Returns a mapping to the system.
#[cfg(target_os = "linux")]
fn unmap(mapping: Mapping) {
    // SAFETY: a whole mapping made in `ScratchBuffer::new` that no buffer or borrow holds any more
    // (a kept one, or the one a buffer being dropped owned).
    unsafe { libc::munmap(mapping.addr as *mut libc::c_void, mapping.bytes) };
}

/// Keeps `mapping` for reuse, returning the oldest kept ones to the system past [`KEPT_BYTES`].
#[cfg(target_os = "linux")]
fn keep(mapping: Mapping) {
    let mut kept = KEPT.lock().unwrap_or_else(|e| e.into_inner());
    kept.push(mapping);
    while kept.iter().map(|m| m.bytes).sum::<usize>() > KEPT_BYTES {
        unmap(kept.remove(0));
    }
}

impl<T: Copy + Default> ScratchBuffer<T> {
    /// `len` values; `T` must be an integer type (every bit pattern is a value).
    pub(crate) fn new(len: usize) -> Self {
        let bytes = len.checked_mul(std::mem::size_of::<T>()).expect("buffer size overflows usize");
        #[cfg(target_os = "linux")]
        if bytes >= MAP_THRESHOLD {
            if let Some(m) = take_kept(bytes) {
                return Self::mapped(m.addr as *mut T, len, m.bytes);
            }
            // SAFETY: an anonymous private mapping has no preconditions; the result is checked.
            let ptr = unsafe {
                libc::mmap(
                    std::ptr::null_mut(),
                    bytes,
                    libc::PROT_READ | libc::PROT_WRITE,
                    libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                    -1,
                    0,
                )
            };
            if ptr != libc::MAP_FAILED {
                // SAFETY: advice on our own fresh mapping; failure is harmless (4 KiB pages).
                unsafe { libc::madvise(ptr, bytes, libc::MADV_HUGEPAGE) };
                return Self::mapped(ptr.cast(), len, bytes);
            }
        }
        let mut fallback = vec![T::default(); len];
        Self::garbled(ScratchBuffer { ptr: fallback.as_mut_ptr(), len, mapped: 0, fallback })
    }

    fn mapped(ptr: *mut T, len: usize, bytes: usize) -> Self {
        Self::garbled(ScratchBuffer { ptr, len, mapped: bytes, fallback: Vec::new() })
    }

    /// Debug builds (the tests) start every buffer with garbage, so that an entry read before it
    /// is written gives another map than the scalar reference's.
    fn garbled(mut buffer: Self) -> Self {
        if cfg!(debug_assertions) {
            let s = buffer.as_mut_slice();
            // SAFETY: `T` is a plain integer (see `new`): any bytes are one of its values.
            unsafe { std::ptr::write_bytes(s.as_mut_ptr(), 0xA5, s.len()) };
        }
        buffer
    }

    pub(crate) fn as_mut_slice(&mut self) -> &mut [T] {
        if self.mapped == 0 {
            return &mut self.fallback;
        }
        // SAFETY: `ptr` is a live mapping of `len` values of `T` (zero-initialised by the system,
        // then only integer-written), page aligned, and `&mut self` makes this borrow exclusive.
        unsafe { std::slice::from_raw_parts_mut(self.ptr, self.len) }
    }
}

impl<T: Copy> Drop for ScratchBuffer<T> {
    fn drop(&mut self) {
        #[cfg(target_os = "linux")]
        if self.mapped > 0 {
            let mapping = Mapping { addr: self.ptr as usize, bytes: self.mapped };
            if self.mapped <= KEPT_BYTES && KEEPING.load(Ordering::Relaxed) {
                keep(mapping);
            } else {
                unmap(mapping);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buffers_have_their_length_and_are_writable() {
        for len in [0usize, 10, (MAP_THRESHOLD / 2) + 7, MAP_THRESHOLD * 2] {
            for _ in 0..2 {
                // The second time round, possibly the mapping the first one kept.
                let mut b = ScratchBuffer::<u16>::new(len);
                let s = b.as_mut_slice();
                assert_eq!(s.len(), len);
                s.iter_mut().enumerate().for_each(|(i, v)| *v = i as u16);
                assert!(s.iter().enumerate().all(|(i, &v)| v == i as u16));
            }
        }
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn freed_mappings_are_kept_within_the_bound() {
        keep_strip_buffers(true);
        let many: Vec<_> = (0..6).map(|_| ScratchBuffer::<u32>::new(KEPT_BYTES / 16)).collect();
        drop(many);
        let within = KEPT.lock().unwrap().iter().map(|m| m.bytes).sum::<usize>() <= KEPT_BYTES;
        // Process-wide state: the other tests of this binary run with the default again.
        keep_strip_buffers(false);
        assert!(within);
    }
}
