//! Whether client processes still live, by iceoryx2's dead-node detection
//! (it works for SIGKILL too). One node list answers for every process the
//! server watches in one sweep.

use iceoryx2::node::NodeView;
use iceoryx2::prelude::*;
use simbus_transport::Bus;

/// The process ids of every live iceoryx2 node, or `None` when the node
/// list cannot be read (then nobody is declared dead).
pub(crate) fn living_pids() -> Option<Vec<u32>> {
    let mut pids = Vec::new();
    let listed = Node::<Bus>::list(Config::global_config(), |state| {
        if let NodeState::Alive(view) = &state {
            if let Some(details) = view.details() {
                pids.push(details.process_id().value() as u32);
            }
        }
        CallbackProgression::Continue
    });
    listed.ok().map(|()| pids)
}

/// A liveness check over one node list: `alive(pid)` is true unless the
/// list was read and holds no live node of `pid`.
#[derive(Debug)]
pub(crate) struct LiveProcesses(Option<Vec<u32>>);

impl LiveProcesses {
    /// Reads the node list once.
    pub(crate) fn now() -> Self {
        Self(living_pids())
    }

    /// Whether `pid` has a live node (or the list could not be read).
    pub(crate) fn alive(&self, pid: u32) -> bool {
        self.0.as_ref().is_none_or(|pids| pids.contains(&pid))
    }
}

/// Fast death notice for the processes the server waits on (the ticker,
/// lockstep participants): a pidfd per process, probed with one
/// non-blocking `poll(2)` as the loop passes by (the loop wakes at least
/// every [`PidWatch::PROBE_PERIOD`] while something is watched). A readable
/// pidfd means the process exited; the node list then confirms, as it also
/// decides for a pid the kernel gave no pidfd for.
#[derive(Debug, Default)]
pub(crate) struct PidWatch {
    entries: Vec<Watched>,
}

/// One watched process.
#[derive(Debug)]
struct Watched {
    pid: u32,
    /// `None` once reported, or if no pidfd could be opened.
    fd: Option<std::os::fd::OwnedFd>,
    reported: bool,
}

impl PidWatch {
    /// How often the server's loop wakes to probe while it watches.
    pub(crate) const PROBE_PERIOD: std::time::Duration = std::time::Duration::from_millis(4);

    /// Watches exactly `pids`: opens pidfds for new ones, closes the rest
    /// (no allocation once the set is known: the loop calls this often).
    pub(crate) fn watch(&mut self, pids: impl Iterator<Item = u32> + Clone) {
        self.entries.retain(|e| pids.clone().any(|p| p == e.pid));
        for pid in pids {
            if !self.entries.iter().any(|e| e.pid == pid) {
                self.entries.push(Watched {
                    pid,
                    fd: pidfd_open(pid),
                    reported: false,
                });
            }
        }
    }

    /// Whether anything is left to probe.
    pub(crate) fn is_idle(&self) -> bool {
        self.entries.iter().all(|e| e.reported)
    }

    /// Whether every watched process has a pidfd that has not fired: its
    /// death will then be noticed by the probe alone, and the loop needs no
    /// periodic node-list sweep (one costs ~1–2 ms of directory reads, a
    /// stall for whatever arrives meanwhile).
    pub(crate) fn covers_all(&self) -> bool {
        self.entries.iter().all(|e| e.fd.is_some() && !e.reported)
    }

    /// The watched processes that exited since the last call, and those
    /// that could not be watched. Each pid is reported once while it stays
    /// watched: a pid the node list still shows alive cannot trigger sweeps
    /// over and over (the periodic sweep keeps covering it).
    pub(crate) fn exited(&mut self) -> Vec<u32> {
        use std::os::fd::AsRawFd;
        let mut polled = Vec::new();
        let mut owners = Vec::new();
        for (i, e) in self.entries.iter().enumerate() {
            if let (Some(fd), false) = (&e.fd, e.reported) {
                polled.push(libc::pollfd {
                    fd: fd.as_raw_fd(),
                    events: libc::POLLIN,
                    revents: 0,
                });
                owners.push(i);
            }
        }
        let mut gone: Vec<usize> = (0..self.entries.len())
            .filter(|&i| !self.entries[i].reported && self.entries[i].fd.is_none())
            .collect();
        if !polled.is_empty() {
            // SAFETY: `polled` is a valid array of `polled.len()` pollfds
            // whose descriptors this struct owns; a zero timeout never blocks.
            let ready = unsafe { libc::poll(polled.as_mut_ptr(), polled.len() as libc::nfds_t, 0) };
            if ready > 0 {
                gone.extend(
                    polled
                        .iter()
                        .zip(&owners)
                        .filter(|(p, _)| p.revents != 0)
                        .map(|(_, &i)| i),
                );
            }
        }
        gone.into_iter()
            .map(|i| {
                let e = &mut self.entries[i];
                e.reported = true;
                e.fd = None;
                e.pid
            })
            .collect()
    }
}

/// A pidfd for `pid`, or `None` if the process is gone (or not visible).
fn pidfd_open(pid: u32) -> Option<std::os::fd::OwnedFd> {
    use std::os::fd::FromRawFd;
    let pid = libc::pid_t::try_from(pid).ok()?;
    // SAFETY: pidfd_open(2) takes a pid and flags and returns a new file
    // descriptor or -1; it touches no memory of ours.
    let fd = unsafe { libc::syscall(libc::SYS_pidfd_open, pid, 0) };
    let fd = i32::try_from(fd).ok().filter(|&fd| fd >= 0)?;
    // SAFETY: `fd` is a fresh descriptor returned to us and owned by nobody else.
    Some(unsafe { std::os::fd::OwnedFd::from_raw_fd(fd) })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_watched_process_that_exits_is_seen_at_once() {
        let mut child = std::process::Command::new("sleep")
            .arg("30")
            .spawn()
            .expect("sleep");
        let mut watch = PidWatch::default();
        watch.watch([child.id()].into_iter());
        assert!(watch.exited().is_empty() && !watch.is_idle());
        child.kill().expect("kill");
        // The pidfd turns readable when the process exits (reaped or not).
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(5);
        loop {
            let exited = watch.exited();
            if !exited.is_empty() {
                assert_eq!(exited, [child.id()]);
                break;
            }
            assert!(std::time::Instant::now() < deadline, "exit never seen");
            std::thread::yield_now();
        }
        // Reported once.
        assert!(watch.exited().is_empty() && watch.is_idle());
        child.wait().expect("reap");
        watch.watch(std::iter::empty());
        assert!(watch.is_idle());
        // A pid with no process cannot be watched: reported for the node
        // list to decide, once.
        watch.watch([u32::MAX / 2].into_iter());
        assert_eq!(watch.exited(), [u32::MAX / 2]);
        assert!(watch.exited().is_empty());
    }
}
