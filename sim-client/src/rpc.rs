//! Requests: one typed request port that sends, wakes the server, awaits
//! the answer (with a deadline and a liveness check of the server, through
//! the client's one wait loop) and checks its protocol version.

use shared_types::Bus;
use std::fmt::Debug;
use std::time::{Duration, Instant};

use iceoryx2::pending_response::PendingResponse;
use iceoryx2::port::client::Client as RequestClient;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::*;
use shared_types::{Response, ResponseStatus, PROTOCOL_VERSION};
use tracing::debug;

pub(crate) use crate::wait::Wait;
use crate::wait::{self, Stop};
use crate::RequestError;

/// A pending answer on a [`RequestPort`].
pub(crate) type Pending<Req, Resp> = PendingResponse<Bus, Req, (), Resp, ()>;

/// A typed request port of one world's service: send, wake, await, check.
pub(crate) struct RequestPort<Req, Resp>
where
    Req: Debug + ZeroCopySend + Copy,
    Resp: Debug + ZeroCopySend + Copy + Response,
{
    client: RequestClient<Bus, Req, (), Resp, ()>,
    wake: Notifier<Bus>,
    world: String,
    server_pid: u32,
}

impl<Req, Resp> RequestPort<Req, Resp>
where
    Req: Debug + ZeroCopySend + Copy,
    Resp: Debug + ZeroCopySend + Copy + Response,
{
    /// Requests on `client`, waking the server of `world` (pid
    /// `server_pid`, 0 if unknown) with `wake`.
    pub(crate) fn new(
        client: RequestClient<Bus, Req, (), Resp, ()>,
        wake: Notifier<Bus>,
        world: &str,
        server_pid: u32,
    ) -> Self {
        Self {
            client,
            wake,
            world: world.to_owned(),
            server_pid,
        }
    }

    /// The notifier that wakes the server (for requests on other ports).
    pub(crate) fn wake(&self) {
        if let Err(e) = self.wake.notify() {
            debug!("wake-up not delivered: {e:?}");
        }
    }

    /// Sends `request` and wakes the server; the answer comes on the
    /// returned pending response.
    pub(crate) fn send(&self, request: Req) -> Result<Pending<Req, Resp>, RequestError> {
        let pending = self
            .client
            .send_copy(request)
            .map_err(|e| RequestError::transport("request send", e))?;
        self.wake();
        Ok(pending)
    }

    /// The next answer on `pending`, waiting up to `timeout` as `wait`
    /// says, with its protocol version checked (its status is the caller's).
    pub(crate) fn answer(
        &self,
        pending: &Pending<Req, Resp>,
        timeout: Duration,
        wait: Wait<'_>,
    ) -> Result<Resp, RequestError> {
        let answer = await_response(pending, timeout, &self.world, self.server_pid, wait)?;
        check_answer(&answer, &self.world)?;
        Ok(answer)
    }

    /// Sends `request` and waits up to `timeout` for its checked answer.
    pub(crate) fn request(
        &self,
        request: Req,
        timeout: Duration,
        wait: Wait<'_>,
    ) -> Result<Resp, RequestError> {
        let pending = self.send(request)?;
        self.answer(&pending, timeout, wait)
    }
}

/// Refuses an answer from a server of another protocol version, one that
/// refused ours, or a mirror's "the world is unreachable" (its link to the
/// world's host is down): every request service's answer goes through it.
pub(crate) fn check_answer(answer: &impl Response, world: &str) -> Result<(), RequestError> {
    check_protocol(answer.protocol_version(), answer.status())?;
    if answer.status() == ResponseStatus::Unreachable as u32 {
        return Err(RequestError::Unreachable {
            world: world.to_owned(),
        });
    }
    Ok(())
}

/// Refuses an answer from a server of another protocol version, or one that
/// refused ours.
pub(crate) fn check_protocol(version: u32, status: u32) -> Result<(), RequestError> {
    if version != PROTOCOL_VERSION || status == ResponseStatus::ProtocolMismatch as u32 {
        return Err(RequestError::ProtocolMismatch {
            client: PROTOCOL_VERSION,
            server: Some(version),
        });
    }
    Ok(())
}

/// The response to `pending`, waiting up to `timeout`. With a known
/// `server_pid` (non-zero), a dead server ends the wait early.
pub(crate) fn await_response<Req, Resp>(
    pending: &PendingResponse<Bus, Req, (), Resp, ()>,
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
    pending: &PendingResponse<Bus, Req, ReqHeader, [Resp], RespHeader>,
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
    receive: impl FnMut() -> Result<Option<T>, RequestError>,
    timeout: Duration,
    world: &str,
    server_pid: u32,
    wait: Wait<'_>,
) -> Result<T, RequestError> {
    wait::until(Instant::now() + timeout, server_pid, wait, receive).map_err(|stop| match stop {
        Stop::Failed(e) => e,
        Stop::TimedOut => RequestError::Timeout {
            world: world.to_owned(),
            timeout,
        },
        Stop::ServerGone => RequestError::ServerGone {
            world: world.to_owned(),
            pid: server_pid,
        },
        Stop::Event(e) => RequestError::transport("event wait", e),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_protocol_mismatch_names_both_versions() {
        let newer = PROTOCOL_VERSION + 1;
        let e = check_protocol(newer, ResponseStatus::ProtocolMismatch as u32).unwrap_err();
        let message = e.to_string();
        assert!(
            message.contains(&format!("server speaks version {newer}"))
                && message.contains(&format!("client speaks version {PROTOCOL_VERSION}")),
            "{message}"
        );
        assert!(check_protocol(PROTOCOL_VERSION, ResponseStatus::Ok as u32).is_ok());
    }
}
