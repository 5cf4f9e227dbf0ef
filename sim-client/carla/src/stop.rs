//! How the gateway waits for CARLA clients and for its stop, in one place
//! and without a period: `poll(2)` on the RPC listener and on a socket
//! that [`Stop::stop`] writes to. Nothing reads a flag on a timer.

use std::io::{self, Write};
use std::net::TcpListener;
use std::os::fd::{AsFd, AsRawFd, BorrowedFd};
use std::os::unix::net::UnixStream;

/// Ends [`crate::serve`] from any thread (a Ctrl-C handler's included):
/// the gateway sleeps on its listener and on this, so it wakes for a
/// connection or for the stop, never to look at a flag.
///
/// Once stopped it stays stopped: a [`crate::serve`] given it returns at
/// once.
#[derive(Debug)]
pub struct Stop {
    /// [`Stop::stop`] writes a byte here (never blocking).
    waker: UnixStream,
    /// Readable once stopped; never read, so it stays readable.
    woken: UnixStream,
}

impl Stop {
    /// A stop not yet given. Fails only where the process has no file
    /// descriptors left.
    ///
    /// # Errors
    ///
    /// Returns the [`io::Error`] of creating or configuring the socket pair
    /// behind it (`EMFILE` when the process has no file descriptors left).
    pub fn new() -> io::Result<Self> {
        let (waker, woken) = UnixStream::pair()?;
        waker.set_nonblocking(true)?;
        Ok(Self { waker, woken })
    }

    /// Stops the gateway. Never blocks; calling it again changes nothing.
    pub fn stop(&self) {
        // A full buffer (stopped many times over) is stopped all the same.
        let _ = (&self.waker).write(&[1]);
    }

    /// Whether [`Stop::stop`] was called.
    pub fn is_stopped(&self) -> bool {
        matches!(ready(&[self.woken.as_fd()], 0), Ok(ready) if ready[0])
    }
}

/// What woke [`wait`].
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum Woken {
    /// [`Stop::stop`] was called.
    Stopped,
    /// A connection waits on the listener.
    Connection,
}

/// Waits, with no deadline, until `listener` has a connection to accept or
/// `stop` is given; a stop wins over a connection.
pub(crate) fn wait(listener: &TcpListener, stop: &Stop) -> io::Result<Woken> {
    let ready = ready(&[stop.woken.as_fd(), listener.as_fd()], -1)?;
    Ok(if ready[0] {
        Woken::Stopped
    } else {
        Woken::Connection
    })
}

/// Which of `fds` are readable (or closed, or failed: whatever a read
/// would report at once), waiting up to `timeout_ms` (-1: no deadline)
/// for one to be. Retried when a signal interrupts it.
fn ready<const N: usize>(fds: &[BorrowedFd<'_>; N], timeout_ms: i32) -> io::Result<[bool; N]> {
    let mut polled = fds.map(|fd| libc::pollfd {
        fd: fd.as_raw_fd(),
        events: libc::POLLIN,
        revents: 0,
    });
    loop {
        // SAFETY: `polled` is an array of `N` initialised `pollfd`s that
        // outlives the call, and `N` is its length; every descriptor in it
        // is borrowed from an open socket for the call's duration.
        let n = unsafe { libc::poll(polled.as_mut_ptr(), N as libc::nfds_t, timeout_ms) };
        if n >= 0 {
            return Ok(polled.map(|p| p.revents != 0));
        }
        let e = io::Error::last_os_error();
        if e.kind() != io::ErrorKind::Interrupted {
            return Err(e);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stop_wakes_the_wait_and_stays_given() {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let stop = Stop::new().unwrap();
        assert!(!stop.is_stopped());
        stop.stop();
        stop.stop();
        assert!(stop.is_stopped());
        assert_eq!(wait(&listener, &stop).unwrap(), Woken::Stopped);
        assert_eq!(wait(&listener, &stop).unwrap(), Woken::Stopped);
    }

    #[test]
    fn a_waiting_connection_wakes_the_wait_and_a_stop_wins_over_it() {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let stop = Stop::new().unwrap();
        let _client = std::net::TcpStream::connect(listener.local_addr().unwrap()).unwrap();
        assert_eq!(wait(&listener, &stop).unwrap(), Woken::Connection);
        stop.stop();
        assert_eq!(wait(&listener, &stop).unwrap(), Woken::Stopped);
    }

    #[test]
    fn a_stop_from_another_thread_wakes_a_blocked_wait() {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let stop = Stop::new().unwrap();
        std::thread::scope(|s| {
            let waiting = s.spawn(|| wait(&listener, &stop).unwrap());
            stop.stop();
            assert_eq!(waiting.join().unwrap(), Woken::Stopped);
        });
    }
}
