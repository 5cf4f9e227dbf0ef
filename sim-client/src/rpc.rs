//! Waiting for the answer to a request, with a timeout and a liveness check
//! of the server, blocking on an event, backing off, or spinning.

use std::fmt::Debug;
use std::time::{Duration, Instant};

use iceoryx2::pending_response::PendingResponse;
use iceoryx2::port::listener::{Listener, ListenerWaitError};
use iceoryx2::prelude::*;

use shared_types::{ResponseStatus, PROTOCOL_VERSION};

use crate::frames::{HYBRID_SPIN, LIVENESS_PERIOD};
use crate::WaitMode;
use crate::{process_alive, RequestError};

/// Refuses an answer from a server of another protocol version, or one that
/// refused ours.
pub(crate) fn check_protocol(version: u32, status: u32) -> Result<(), RequestError> {
    if version != PROTOCOL_VERSION || status == ResponseStatus::ProtocolMismatch as u32 {
        return Err(RequestError::ProtocolMismatch {
            client: PROTOCOL_VERSION,
        });
    }
    Ok(())
}

/// How to pass the time until the answer arrives.
pub(crate) enum Wait<'a> {
    /// Poll for [`HYBRID_SPIN`], then sleep 10 µs, doubling up to 1 ms (for
    /// requests without an event).
    Backoff,
    /// Sleep on an event the server notifies right after answering.
    Event(&'a Listener<ipc::Service>),
    /// Poll in a tight loop.
    Spin,
    /// Poll for [`HYBRID_SPIN`], then sleep on the event.
    Hybrid(&'a Listener<ipc::Service>),
}

impl<'a> Wait<'a> {
    /// The wait for an answer announced by `listener`, as `mode` says.
    pub(crate) fn for_mode(mode: WaitMode, listener: &'a Listener<ipc::Service>) -> Self {
        match mode {
            WaitMode::Block => Wait::Event(listener),
            WaitMode::Spin => Wait::Spin,
            WaitMode::Hybrid => Wait::Hybrid(listener),
        }
    }
}

/// The response to `pending`, waiting up to `timeout`. With a known
/// `server_pid` (non-zero), a dead server ends the wait early.
pub(crate) fn await_response<Req, Resp>(
    pending: &PendingResponse<ipc::Service, Req, (), Resp, ()>,
    timeout: Duration,
    world: &str,
    server_pid: u32,
    wait: Wait<'_>,
) -> Result<Resp, RequestError>
where
    Req: Debug + ZeroCopySend,
    Resp: Debug + ZeroCopySend + Copy,
{
    await_with(
        || {
            pending
                .receive()
                .map(|response| response.map(|r| *r.payload()))
                .map_err(|e| RequestError::transport("response receive", e))
        },
        timeout,
        world,
        server_pid,
        wait,
    )
}

/// The response header and a copy of the slice payload of `pending`.
pub(crate) fn await_slice_response<Req, ReqHeader, Resp, RespHeader>(
    pending: &PendingResponse<ipc::Service, Req, ReqHeader, [Resp], RespHeader>,
    timeout: Duration,
    world: &str,
    server_pid: u32,
    wait: Wait<'_>,
) -> Result<(RespHeader, Vec<Resp>), RequestError>
where
    Req: Debug + IceoryxSend + ?Sized,
    ReqHeader: Debug + ZeroCopySend,
    Resp: Debug + ZeroCopySend + Copy,
    RespHeader: Debug + ZeroCopySend + Copy,
{
    await_with(
        || {
            pending
                .receive()
                .map(|r| r.map(|r| (*r.user_header(), r.payload().to_vec())))
                .map_err(|e| RequestError::transport("response receive", e))
        },
        timeout,
        world,
        server_pid,
        wait,
    )
}

/// Calls `receive` until it yields, waiting between calls as `wait` says,
/// for at most `timeout`; a dead server (non-zero `server_pid`) ends it early.
pub(crate) fn await_with<T>(
    mut receive: impl FnMut() -> Result<Option<T>, RequestError>,
    timeout: Duration,
    world: &str,
    server_pid: u32,
    wait: Wait<'_>,
) -> Result<T, RequestError> {
    let start = Instant::now();
    let deadline = start + timeout;
    let mut backoff = Duration::from_micros(10);
    let mut next_liveness_check = start + LIVENESS_PERIOD;
    loop {
        if let Some(response) = receive()? {
            return Ok(response);
        }
        let now = Instant::now();
        if now >= deadline {
            return Err(RequestError::Timeout {
                world: world.to_owned(),
                timeout,
            });
        }
        if now >= next_liveness_check {
            if server_pid != 0 && !process_alive(server_pid) {
                return Err(RequestError::ServerGone {
                    world: world.to_owned(),
                    pid: server_pid,
                });
            }
            next_liveness_check = now + LIVENESS_PERIOD;
        }
        let remaining = (deadline - now).min(next_liveness_check - now);
        match wait {
            Wait::Spin => std::hint::spin_loop(),
            Wait::Hybrid(_) if now - start < HYBRID_SPIN => std::hint::spin_loop(),
            // An answer usually comes within microseconds: poll briefly first.
            Wait::Backoff if now - start < HYBRID_SPIN => std::hint::spin_loop(),
            Wait::Backoff => {
                std::thread::sleep(backoff.min(remaining));
                backoff = (backoff * 2).min(Duration::from_millis(1));
            }
            Wait::Event(listener) | Wait::Hybrid(listener) => {
                match listener.timed_wait(|_| {}, remaining) {
                    Ok(_) | Err(ListenerWaitError::InterruptSignal) => {}
                    Err(e) => return Err(RequestError::transport("event wait", e)),
                }
            }
        }
    }
}
