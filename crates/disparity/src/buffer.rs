//! Large zero-initialised working buffers. On Linux they are anonymous mappings advised to use
//! transparent huge pages, so a multi-hundred-megabyte aggregation volume costs a few hundred
//! page faults instead of tens of thousands; elsewhere (or if the mapping fails) a `Vec`.

/// A zero-initialised `[T]` of plain integers, freed on drop.
pub(crate) struct ZeroedBuffer<T: Copy> {
    ptr: *mut T,
    len: usize,
    /// Bytes mapped, or 0 when the memory belongs to `fallback`.
    mapped: usize,
    fallback: Vec<T>,
}

// SAFETY: the buffer owns its memory exclusively, like a `Vec<T>`.
unsafe impl<T: Copy + Send> Send for ZeroedBuffer<T> {}
// SAFETY: shared access only reads, like `&[T]`.
unsafe impl<T: Copy + Sync> Sync for ZeroedBuffer<T> {}

/// Below this size the page-fault saving is not worth a system call.
const MAP_THRESHOLD: usize = 4 << 20;

impl<T: Copy + Default> ZeroedBuffer<T> {
    /// `len` zero values; `T` must be an integer type (all-zero bytes is its zero).
    pub(crate) fn new(len: usize) -> Self {
        let bytes = len.checked_mul(std::mem::size_of::<T>()).expect("buffer size overflows usize");
        #[cfg(target_os = "linux")]
        if bytes >= MAP_THRESHOLD {
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
                return ZeroedBuffer { ptr: ptr.cast(), len, mapped: bytes, fallback: Vec::new() };
            }
        }
        let mut fallback = vec![T::default(); len];
        ZeroedBuffer { ptr: fallback.as_mut_ptr(), len, mapped: 0, fallback }
    }

    pub(crate) fn as_mut_slice(&mut self) -> &mut [T] {
        if self.mapped == 0 {
            return &mut self.fallback;
        }
        // SAFETY: `ptr` is a live mapping of `len` zero-initialised (then only integer-written)
        // values of `T`, page aligned, and `&mut self` makes this borrow exclusive.
        unsafe { std::slice::from_raw_parts_mut(self.ptr, self.len) }
    }
}

impl<T: Copy> Drop for ZeroedBuffer<T> {
    fn drop(&mut self) {
        #[cfg(target_os = "linux")]
        if self.mapped > 0 {
            // SAFETY: unmapping exactly the mapping made in `new`, which no borrow outlives.
            unsafe { libc::munmap(self.ptr.cast(), self.mapped) };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buffers_start_zeroed_and_are_writable() {
        for len in [0usize, 10, (MAP_THRESHOLD / 2) + 7] {
            let mut b = ZeroedBuffer::<u16>::new(len);
            let s = b.as_mut_slice();
            assert_eq!(s.len(), len);
            assert!(s.iter().all(|&v| v == 0));
            s.iter_mut().enumerate().for_each(|(i, v)| *v = i as u16);
            assert!(s.iter().enumerate().all(|(i, &v)| v == i as u16));
        }
    }
}
