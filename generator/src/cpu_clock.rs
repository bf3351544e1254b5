//! The calling thread's CPU time, for `vtgen bench`'s "CPU outside the rasterizer": wall-clock
//! stage times on a loaded machine count the time a thread waits for a core, CPU time does not.

use std::time::Duration;

/// CPU time the calling thread has used so far; None where the platform has no per-thread clock.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
pub fn thread_cpu_time() -> Option<Duration> {
    let mut t = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: clock_gettime writes the timespec it is given and nothing else.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut t) };
    (rc == 0).then(|| Duration::new(t.tv_sec as u64, t.tv_nsec as u32))
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
pub fn thread_cpu_time() -> Option<Duration> {
    None
}

/// CPU time (user + system) the whole process has used so far; None where not available.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
pub fn process_cpu_time() -> Option<Duration> {
    // SAFETY: getrusage fills the struct it is given; an all-zero rusage is a valid value.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    let rc = unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) };
    let tv = |t: libc::timeval| Duration::new(t.tv_sec as u64, 1000 * t.tv_usec as u32);
    (rc == 0).then(|| tv(u.ru_utime) + tv(u.ru_stime))
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
pub fn process_cpu_time() -> Option<Duration> {
    None
}

/// One stage's clock: the wall time and the calling thread's CPU time since it was started.
#[derive(Debug, Clone, Copy)]
pub struct StageClock {
    wall: std::time::Instant,
    cpu: Option<Duration>,
}

impl StageClock {
    pub fn start() -> Self {
        StageClock { wall: std::time::Instant::now(), cpu: thread_cpu_time() }
    }

    /// Wall time since the start.
    pub fn wall(&self) -> Duration {
        self.wall.elapsed()
    }

    /// The thread's CPU time since the start (zero without a per-thread clock).
    pub fn cpu(&self) -> Duration {
        cpu_since(self.cpu)
    }
}

/// CPU time of the calling thread between `start` and now (zero without a per-thread clock).
pub fn cpu_since(start: Option<Duration>) -> Duration {
    match (start, thread_cpu_time()) {
        (Some(a), Some(b)) => b.saturating_sub(a),
        _ => Duration::ZERO,
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_thread_clock_counts_work_and_not_sleep() {
        let Some(t0) = super::thread_cpu_time() else { return };
        std::thread::sleep(std::time::Duration::from_millis(50));
        let slept = super::cpu_since(Some(t0));
        let t1 = super::thread_cpu_time();
        let mut x = 0u64;
        let start = std::time::Instant::now();
        while start.elapsed() < std::time::Duration::from_millis(50) {
            x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
        }
        let worked = super::cpu_since(t1);
        assert!(slept < std::time::Duration::from_millis(25), "sleeping 50 ms counted {slept:?} of CPU");
        assert!(worked > slept, "50 ms of work counted {worked:?}, sleep {slept:?}");
    }
}
