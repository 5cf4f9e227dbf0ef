//! The blocking floor: two processes ping-pong a counter through two words
//! on a shared page, each sleeping in `futex(FUTEX_WAIT)` until the other
//! wakes it — one kernel wake-up per hop and nothing else, the least a
//! blocking exchange between processes can cost.

use std::fs::OpenOptions;
use std::path::Path;
use std::sync::atomic::{AtomicU32, Ordering};

use simbus_process::ChildGuard;

use crate::stats::Latencies;

use crate::support::{spawn_peer, Placement};

/// Two 32-bit words on a page mapped shared: `ping` (to the peer) and `pong`.
pub(crate) struct SharedWords {
    base: *mut AtomicU32,
}

impl SharedWords {
    const LEN: usize = 4096;

    /// Maps `path` (created and sized if needed).
    pub(crate) fn map(path: &Path) -> anyhow::Result<Self> {
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(path)?;
        file.set_len(Self::LEN as u64)?;
        // SAFETY: maps LEN bytes of a file we opened read-write, shared;
        // the result is checked before use and unmapped on drop.
        let base = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                Self::LEN,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_SHARED,
                std::os::fd::AsRawFd::as_raw_fd(&file),
                0,
            )
        };
        anyhow::ensure!(
            base != libc::MAP_FAILED,
            "mmap: {}",
            std::io::Error::last_os_error()
        );
        Ok(Self { base: base.cast() })
    }

    fn word(&self, i: usize) -> &AtomicU32 {
        // SAFETY: the page holds 1024 aligned u32 words and lives as long as
        // `self`; AtomicU32 has u32's layout.
        unsafe { &*self.base.add(i) }
    }

    fn ping(&self) -> &AtomicU32 {
        self.word(0)
    }

    fn pong(&self) -> &AtomicU32 {
        self.word(16)
    }

    /// The measuring side: sends ping `n` (the one after `n - 1`) and
    /// sleeps until the peer has answered it.
    pub(crate) fn ping_pong(&self, n: u32) {
        post(self.ping(), n);
        wait(self.pong(), n.wrapping_sub(1));
    }

    /// The peer's side: sleeps until a ping other than `last` comes, and
    /// returns it.
    pub(crate) fn next_ping(&self, last: u32) -> u32 {
        wait(self.ping(), last);
        self.ping().load(Ordering::Acquire)
    }

    /// The peer's side: answers ping `n`.
    pub(crate) fn answer(&self, n: u32) {
        post(self.pong(), n);
    }
}

impl Drop for SharedWords {
    fn drop(&mut self) {
        // SAFETY: unmaps exactly the mapping made in `map`.
        unsafe {
            libc::munmap(self.base.cast(), Self::LEN);
        }
    }
}

/// Sleeps until `word` no longer holds `old`.
fn wait(word: &AtomicU32, old: u32) {
    while word.load(Ordering::Acquire) == old {
        // SAFETY: FUTEX_WAIT on a valid, aligned, mapped word; it returns at
        // once if the word changed, and spurious wake-ups loop.
        unsafe {
            libc::syscall(
                libc::SYS_futex,
                word.as_ptr(),
                libc::FUTEX_WAIT,
                old,
                std::ptr::null::<libc::timespec>(),
            );
        }
    }
}

/// Stores `value` into `word` and wakes its sleeper.
fn post(word: &AtomicU32, value: u32) {
    word.store(value, Ordering::Release);
    // SAFETY: FUTEX_WAKE of one waiter on a valid, aligned, mapped word.
    unsafe {
        libc::syscall(libc::SYS_futex, word.as_ptr(), libc::FUTEX_WAKE, 1);
    }
}

/// The peer's side: answers every ping with a pong, until it is killed.
pub(crate) fn peer(path: &str) -> anyhow::Result<()> {
    let words = SharedWords::map(Path::new(path))?;
    println!("ready");
    // The bench zeroed the words before starting us; reading `ping` here
    // instead could already see its first ping and then wait for a second.
    let mut last = 0;
    loop {
        last = words.next_ping(last);
        words.answer(last);
    }
}

/// The floor exchange: a futex round trip with a peer process. Returns the
/// peer (stopped on drop) and one round trip per call.
pub(crate) fn exchange() -> anyhow::Result<(ChildGuard, impl FnMut() -> anyhow::Result<()>)> {
    let path = std::env::temp_dir().join(format!("simbus-bench-futex-{}", std::process::id()));
    let words = SharedWords::map(&path)?;
    words.ping().store(0, Ordering::Release);
    words.pong().store(0, Ordering::Release);
    let (peer, ready) = spawn_peer("futex", &path.to_string_lossy())?;
    let _ = std::fs::remove_file(&path);
    anyhow::ensure!(ready == "ready", "the futex peer did not start: {ready}");
    let mut n = 0u32;
    Ok((peer, move || {
        n = n.wrapping_add(1);
        words.ping_pong(n);
        anyhow::ensure!(
            words.pong().load(Ordering::Acquire) == n,
            "futex ping-pong out of order"
        );
        Ok(())
    }))
}

/// `iterations` futex round trips, one every `pace` (zero: back to back),
/// as the floor beside another benchmark's rows.
pub(crate) fn floor(iterations: u64, pace: std::time::Duration) -> anyhow::Result<Latencies> {
    floor_placed(iterations, pace, Placement::Unpinned)
}

/// [`floor`] with this process and the peer pinned as `placement` says
/// (unpinned again after).
pub(crate) fn floor_placed(
    iterations: u64,
    pace: std::time::Duration,
    placement: Placement,
) -> anyhow::Result<Latencies> {
    let (peer, round_trip) = exchange()?;
    placement.apply(&[peer.id()])?;
    let measured = paced(iterations, pace, round_trip);
    Placement::Unpinned.apply(&[])?;
    drop(peer);
    measured
}

/// `iterations` of `round_trip`, one every `pace`, after a tenth as many
/// not counted.
fn paced(
    iterations: u64,
    pace: std::time::Duration,
    mut round_trip: impl FnMut() -> anyhow::Result<()>,
) -> anyhow::Result<Latencies> {
    for _ in 0..iterations / 10 {
        round_trip()?;
    }
    let mut latencies = Latencies::new();
    for _ in 0..iterations {
        if !pace.is_zero() {
            std::thread::sleep(pace);
        }
        let start = std::time::Instant::now();
        round_trip()?;
        latencies.record(start.elapsed().as_nanos() as u64);
    }
    Ok(latencies)
}
