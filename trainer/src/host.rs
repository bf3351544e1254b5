//! The host process: the allocator settings a CPU training run needs, and the process's CPU time
//! (`vtpose bench --train`'s CPU share).

/// Keeps the memory a training step frees for the next step.
///
/// A step allocates and frees a few hundred MB of tensors, most of them larger than glibc's
/// default mmap threshold: glibc then maps each one fresh from the kernel and unmaps it on free,
/// so every step page-faults and zeroes that memory again, and with two threads stepping the
/// faults contend on the process's memory map. Raising the mmap threshold to its maximum (32 MB)
/// and the trim threshold to 1 GB keeps the freed blocks in the heap. Measured with `vtpose bench
/// --train` on the CPU experiment's network (docs/training.md): about 1.6x the steps per second.
/// Other platforms' allocators are left as they are.
pub fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only changes malloc's parameters; called before any thread starts.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 1 << 30);
    }
}

/// CPU seconds (user and system) this process has used, where the platform reports them.
pub fn process_cpu_seconds() -> Option<f64> {
    #[cfg(unix)]
    {
        let mut usage = std::mem::MaybeUninit::<libc::rusage>::zeroed();
        // SAFETY: getrusage writes a whole `rusage` into the pointer it is given on success.
        let usage = unsafe {
            if libc::getrusage(libc::RUSAGE_SELF, usage.as_mut_ptr()) != 0 {
                return None;
            }
            usage.assume_init()
        };
        let secs = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
        Some(secs(usage.ru_utime) + secs(usage.ru_stime))
    }
    #[cfg(not(unix))]
    {
        None
    }
}
