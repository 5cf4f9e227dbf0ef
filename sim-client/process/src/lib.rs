//! Child processes that are stopped and reaped when dropped: the demo's
//! server, and every process the tests and benchmarks start, so nothing is
//! ever left behind, whatever ended the run.

use std::process::{Child, ExitStatus};
use std::time::{Duration, Instant};

/// Sends `signal` (e.g. `libc::SIGTERM`) to `pid`.
///
/// # Errors
///
/// Returns an error of kind [`InvalidInput`](std::io::ErrorKind::InvalidInput)
/// if `pid` does not fit a `pid_t`, and the OS error of `kill(2)` otherwise:
/// `ESRCH` if no such process exists, `EPERM` if this process may not signal
/// it, `EINVAL` for an unknown `signal`.
pub fn send_signal(pid: u32, signal: i32) -> std::io::Result<()> {
    let pid = libc::pid_t::try_from(pid)
        .map_err(|_| std::io::Error::from(std::io::ErrorKind::InvalidInput))?;
    // SAFETY: kill(2) has no memory-safety preconditions; a stale pid at worst
    // yields ESRCH, which is returned as an error.
    if unsafe { libc::kill(pid, signal) } == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// A child process that is stopped and reaped when dropped: SIGTERM first,
/// SIGKILL if it has not exited within the grace period.
#[derive(Debug)]
pub struct ChildGuard {
    child: Option<Child>,
    grace: Duration,
}

impl ChildGuard {
    /// Guards `child`, giving it `grace` to exit after SIGTERM.
    pub fn new(child: Child, grace: Duration) -> Self {
        Self {
            child: Some(child),
            grace,
        }
    }

    /// The child's process id.
    pub fn id(&self) -> u32 {
        self.child.as_ref().map_or(0, Child::id)
    }

    /// The child itself (for its pipes).
    pub fn child_mut(&mut self) -> &mut Child {
        self.child.as_mut().expect("child present until stopped")
    }

    /// Whether the child has exited (it is reaped if so).
    ///
    /// # Errors
    ///
    /// Returns the [`std::io::Error`] of [`Child::try_wait`] if the child's
    /// status cannot be read.
    pub fn try_wait(&mut self) -> std::io::Result<Option<ExitStatus>> {
        self.child_mut().try_wait()
    }

    /// Waits up to `timeout` for the child to exit by itself.
    ///
    /// # Errors
    ///
    /// Returns the [`std::io::Error`] of [`Child::try_wait`] if the child's
    /// status cannot be read; running out of time is `Ok(None)`, not an error.
    pub fn wait_timeout(&mut self, timeout: Duration) -> std::io::Result<Option<ExitStatus>> {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(status) = self.try_wait()? {
                return Ok(Some(status));
            }
            if Instant::now() >= deadline {
                return Ok(None);
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// SIGKILL, no grace, then reap.
    ///
    /// # Errors
    ///
    /// Returns the [`std::io::Error`] of [`Child::wait`] if the child cannot be
    /// reaped. (A failed SIGKILL, for a child that already exited, is not an
    /// error.)
    pub fn kill(&mut self) -> std::io::Result<ExitStatus> {
        let child = self.child_mut();
        let _ = child.kill();
        child.wait()
    }

    /// SIGTERM, wait up to the grace period, SIGKILL if needed; reaps the
    /// child and returns how it ended.
    ///
    /// # Errors
    ///
    /// Returns the [`std::io::Error`] of [`Child::try_wait`] or [`Child::wait`]
    /// if the child's status cannot be read or it cannot be reaped.
    pub fn stop(&mut self) -> std::io::Result<ExitStatus> {
        if let Some(status) = self.try_wait()? {
            return Ok(status);
        }
        let _ = send_signal(self.id(), libc::SIGTERM);
        match self.wait_timeout(self.grace)? {
            Some(status) => Ok(status),
            None => self.kill(),
        }
    }
}

impl Drop for ChildGuard {
    fn drop(&mut self) {
        if self.child.is_some() {
            let _ = self.stop();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn this_process_is_alive_and_a_reaped_child_is_not() {
        assert!(sim_client::process_alive(std::process::id()));
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let pid = child.id();
        child.wait().unwrap();
        assert!(!sim_client::process_alive(pid));
    }

    #[test]
    fn a_zombie_is_not_alive() {
        let child = std::process::Command::new("true").spawn().unwrap();
        let pid = child.id();
        let mut guard = ChildGuard::new(child, Duration::from_secs(1));
        // Until reaped the child is a zombie.
        let deadline = Instant::now() + Duration::from_secs(5);
        while sim_client::process_alive(pid) && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!(!sim_client::process_alive(pid));
        assert!(guard.stop().unwrap().success());
    }

    #[test]
    fn dropping_the_guard_stops_and_reaps_the_child() {
        let child = std::process::Command::new("sleep")
            .arg("30")
            .spawn()
            .unwrap();
        let pid = child.id();
        drop(ChildGuard::new(child, Duration::from_secs(1)));
        assert!(!sim_client::process_alive(pid));
    }
}
