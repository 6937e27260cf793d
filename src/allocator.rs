//! The allocator settings of the command line, also included by `examples/time_pipeline.rs`
//! (so its in-process timings allocate as the CLI does).

/// Lets glibc hand freed memory to the next allocation instead of returning it to the system. By
/// default every buffer of 128 KiB or more is a fresh mapping, and a pair runs through many
/// image-sized buffers (grey views, census images, maps between post-processing steps), each
/// paying page faults on first touch: 4–13 % of the matching time on the Middlebury scenes
/// (docs/performance.md). Buffers above 32 MiB (the largest allowed) are still mapped apart,
/// and the aggregation volume has its own mapping.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
pub fn reuse_freed_memory() {
    // SAFETY: `mallopt` only tunes the allocator; called before any other thread exists.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 1 << 30);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
pub fn reuse_freed_memory() {}
