//! Requests: one typed request port for every request service (control,
//! tick, batch, lockstep, sensors, recorder) that sends, wakes the server,
//! awaits the answer (with a deadline and a liveness check of the server,
//! through the client's one wait loop) and checks it (protocol version,
//! a mirror's "unreachable").

use std::fmt::Debug;
use std::time::{Duration, Instant};

use iceoryx2::pending_response::PendingResponse;
use iceoryx2::port::client::Client as RequestClient;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::ReceiveError;
use iceoryx2::prelude::*;
use iceoryx2::service::builder::request_response::RequestResponseOpenError;
use iceoryx2::service::port_factory::client::ClientCreateError;
use shared_types::limits::MAX_CLIENTS_FLAG;
use shared_types::{
    BatchResponseHeader, CommandResult, ControlResponse, DebugResponseHeader, DebugShape, Doorbell,
    LockstepResponse, RecorderResponse, Response, ResponseStatus, SensorInfo, SensorResponseHeader,
    TickResponse, PROTOCOL_VERSION,
};
use simbus_transport::Bus;
use tracing::debug;

use crate::open::open_with_retry;
pub(crate) use crate::wait::Wait;
use crate::wait::{self, Stop};
use crate::{Client, RequestError};

/// A pending answer on a [`RequestPort`].
pub(crate) type Pending<Req, Resp, ReqHeader = (), RespHeader = ()> =
    PendingResponse<Bus, Req, ReqHeader, Resp, RespHeader>;

/// Wakes the server after a request was sent.
pub(crate) trait Wake {
    /// Rings `doorbell` (the service that holds the request) on the
    /// server's wake-up event.
    fn wake(&self, doorbell: Doorbell) -> Result<(), RequestError>;
}

impl Wake for Notifier<Bus> {
    fn wake(&self, doorbell: Doorbell) -> Result<(), RequestError> {
        if let Err(e) = self.notify_with_custom_event_id(EventId::new(doorbell.event_id())) {
            debug!("wake-up not delivered: {e:?}");
        }
        Ok(())
    }
}

/// A client wakes the server with its control port's notifier (opening it
/// first if need be): one notifier per client, whatever ports it uses.
impl Wake for Client {
    fn wake(&self, doorbell: Doorbell) -> Result<(), RequestError> {
        self.wake_server(doorbell)
    }
}

/// A request as the caller hands it to [`RequestPort::send`]: a fixed-size
/// payload, or a header and a slice.
pub(crate) trait Outgoing<Req, ReqHeader>
where
    Req: Debug + IceoryxSend + ?Sized,
    ReqHeader: Debug + ZeroCopySend,
{
    /// Writes the request into `client`'s shared memory and sends it.
    fn send_on<Resp, RespHeader>(
        self,
        client: &RequestClient<Bus, Req, ReqHeader, Resp, RespHeader>,
        what: &'static str,
    ) -> Result<Pending<Req, Resp, ReqHeader, RespHeader>, RequestError>
    where
        Resp: Debug + IceoryxSend + ?Sized,
        RespHeader: Debug + ZeroCopySend;
}

impl<Req: Debug + ZeroCopySend + Copy> Outgoing<Req, ()> for Req {
    fn send_on<Resp, RespHeader>(
        self,
        client: &RequestClient<Bus, Req, (), Resp, RespHeader>,
        what: &'static str,
    ) -> Result<Pending<Req, Resp, (), RespHeader>, RequestError>
    where
        Resp: Debug + IceoryxSend + ?Sized,
        RespHeader: Debug + ZeroCopySend,
    {
        client
            .send_copy(self)
            .map_err(|e| RequestError::transport(what, e))
    }
}

impl<Req, ReqHeader> Outgoing<[Req], ReqHeader> for (ReqHeader, &[Req])
where
    Req: Debug + ZeroCopySend + Copy + 'static,
    ReqHeader: Debug + ZeroCopySend + Default,
{
    fn send_on<Resp, RespHeader>(
        self,
        client: &RequestClient<Bus, [Req], ReqHeader, Resp, RespHeader>,
        what: &'static str,
    ) -> Result<Pending<[Req], Resp, ReqHeader, RespHeader>, RequestError>
    where
        Resp: Debug + IceoryxSend + ?Sized,
        RespHeader: Debug + ZeroCopySend,
    {
        let (header, items) = self;
        let mut request = client
            .loan_slice_uninit(items.len())
            .map_err(|e| RequestError::transport("batch loan", e))?;
        *request.user_header_mut() = header;
        request
            .write_from_slice(items)
            .send()
            .map_err(|e| RequestError::transport(what, e))
    }
}

/// An answer with a slice payload, copied out: the header carries its
/// protocol version and status.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct SliceAnswer<Header, T> {
    /// The response header.
    pub header: Header,
    /// The payload.
    pub items: Vec<T>,
}

impl<Header: Response, T> Response for SliceAnswer<Header, T> {
    fn protocol_version(&self) -> u32 {
        self.header.protocol_version()
    }
    fn status(&self) -> u32 {
        self.header.status()
    }
}

/// An answer payload, as a request service's response type: how it is
/// received and copied out.
pub(crate) trait Answer<Header: Debug + ZeroCopySend>: Debug + IceoryxSend {
    /// The copy the caller gets.
    type Owned: Response;
    /// The next answer on `pending`, copied out, if one came.
    fn receive<Req, ReqHeader>(
        pending: &Pending<Req, Self, ReqHeader, Header>,
    ) -> Result<Option<Self::Owned>, ReceiveError>
    where
        Req: Debug + IceoryxSend + ?Sized,
        ReqHeader: Debug + ZeroCopySend;
}

macro_rules! fixed_answers {
    ($($t:ty),*) => {$(
        impl Answer<()> for $t {
            type Owned = $t;
            fn receive<Req, ReqHeader>(
                pending: &Pending<Req, Self, ReqHeader, ()>,
            ) -> Result<Option<$t>, ReceiveError>
            where
                Req: Debug + IceoryxSend + ?Sized,
                ReqHeader: Debug + ZeroCopySend,
            {
                pending.receive().map(|r| r.map(|r| *r.payload()))
            }
        }
    )*};
}
fixed_answers!(
    ControlResponse,
    TickResponse,
    LockstepResponse,
    RecorderResponse
);

macro_rules! slice_answers {
    ($($t:ty => $h:ty),*) => {$(
        impl Answer<$h> for [$t] {
            type Owned = SliceAnswer<$h, $t>;
            fn receive<Req, ReqHeader>(
                pending: &Pending<Req, Self, ReqHeader, $h>,
            ) -> Result<Option<Self::Owned>, ReceiveError>
            where
                Req: Debug + IceoryxSend + ?Sized,
                ReqHeader: Debug + ZeroCopySend,
            {
                pending.receive().map(|r| {
                    r.map(|r| SliceAnswer {
                        header: *r.user_header(),
                        items: r.payload().to_vec(),
                    })
                })
            }
        }
    )*};
}
slice_answers!(
    CommandResult => BatchResponseHeader,
    SensorInfo => SensorResponseHeader,
    DebugShape => DebugResponseHeader
);

/// How a request port's errors name it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PortNames {
    /// The service ("sensor service").
    pub(crate) service: &'static str,
    /// The client port ("sensor client").
    pub(crate) client: &'static str,
    /// A send on it ("sensor send").
    pub(crate) send: &'static str,
    /// Its clients, in a full service's error ("clients sending sensor
    /// requests").
    pub(crate) clients: &'static str,
}

/// A typed request port of one world's service: send, wake, await, check.
/// A port opened on its own node has its own wake-up notifier; the ports
/// of a [`Client`] wake the server through the client's.
pub(crate) struct RequestPort<Req, Resp, ReqHeader = (), RespHeader = ()>
where
    Req: Debug + IceoryxSend + ?Sized,
    Resp: Debug + IceoryxSend + ?Sized,
    ReqHeader: Debug + ZeroCopySend,
    RespHeader: Debug + ZeroCopySend,
{
    client: RequestClient<Bus, Req, ReqHeader, Resp, RespHeader>,
    wake: Option<Notifier<Bus>>,
    /// Rung after each request: the server then looks at this service only.
    doorbell: Doorbell,
    /// What a failed send says it was doing.
    what: &'static str,
    world: String,
    server_pid: u32,
}

impl<Req, Resp, ReqHeader, RespHeader> RequestPort<Req, Resp, ReqHeader, RespHeader>
where
    Req: Debug + IceoryxSend + ?Sized,
    Resp: Answer<RespHeader> + ?Sized,
    ReqHeader: Debug + ZeroCopySend,
    RespHeader: Debug + ZeroCopySend,
{
    /// Requests on `client` to the server of `world` (pid `server_pid`, 0
    /// if unknown), woken with `wake` if given (otherwise by the caller's
    /// [`Wake`]) ringing `doorbell` (the service's, from its description);
    /// `what` names a failed send.
    pub(crate) fn new(
        client: RequestClient<Bus, Req, ReqHeader, Resp, RespHeader>,
        wake: Option<Notifier<Bus>>,
        doorbell: Doorbell,
        what: &'static str,
        world: &str,
        server_pid: u32,
    ) -> Self {
        Self {
            client,
            wake,
            doorbell,
            what,
            world: world.to_owned(),
            server_pid,
        }
    }

    /// Rings `doorbell` with this port's notifier (for requests on other
    /// ports), if it has one.
    pub(crate) fn wake(&self, doorbell: Doorbell) {
        if let Some(notifier) = &self.wake {
            // A lost wake-up is logged, not an error of the request.
            let _ = Wake::wake(notifier, doorbell);
        }
    }

    /// Sends `request` and wakes the server with `wake`; the answer comes
    /// on the returned pending response.
    pub(crate) fn send_waking(
        &self,
        request: impl Outgoing<Req, ReqHeader>,
        wake: &(impl Wake + ?Sized),
    ) -> Result<Pending<Req, Resp, ReqHeader, RespHeader>, RequestError> {
        let pending = request.send_on(&self.client, self.what)?;
        wake.wake(self.doorbell)?;
        Ok(pending)
    }

    /// Sends `request` and wakes the server with this port's notifier.
    pub(crate) fn send(
        &self,
        request: impl Outgoing<Req, ReqHeader>,
    ) -> Result<Pending<Req, Resp, ReqHeader, RespHeader>, RequestError> {
        self.send_waking(request, self)
    }

    /// The next answer on `pending`, waiting up to `timeout` as `wait`
    /// says, checked by [`check_answer`] (any other status is the caller's).
    pub(crate) fn answer(
        &self,
        pending: &Pending<Req, Resp, ReqHeader, RespHeader>,
        timeout: Duration,
        wait: Wait<'_>,
    ) -> Result<Resp::Owned, RequestError> {
        let answer = await_with(
            || Resp::receive(pending).map_err(|e| RequestError::transport("response receive", e)),
            timeout,
            &self.world,
            self.server_pid,
            wait,
        )?;
        check_answer(&answer, &self.world)?;
        Ok(answer)
    }

    /// The answer on `pending` if it has come (no waiting), checked.
    pub(crate) fn try_answer(
        &self,
        pending: &Pending<Req, Resp, ReqHeader, RespHeader>,
    ) -> Result<Option<Resp::Owned>, RequestError> {
        let answer =
            Resp::receive(pending).map_err(|e| RequestError::transport("response receive", e))?;
        if let Some(answer) = &answer {
            check_answer(answer, &self.world)?;
        }
        Ok(answer)
    }

    /// Sends `request`, wakes the server with `wake`, and waits up to
    /// `timeout` for its checked answer.
    pub(crate) fn request_waking(
        &self,
        request: impl Outgoing<Req, ReqHeader>,
        wake: &(impl Wake + ?Sized),
        timeout: Duration,
        wait: Wait<'_>,
    ) -> Result<Resp::Owned, RequestError> {
        let pending = self.send_waking(request, wake)?;
        self.answer(&pending, timeout, wait)
    }

    /// Sends `request` and waits up to `timeout` for its checked answer.
    pub(crate) fn request(
        &self,
        request: impl Outgoing<Req, ReqHeader>,
        timeout: Duration,
        wait: Wait<'_>,
    ) -> Result<Resp::Owned, RequestError> {
        self.request_waking(request, self, timeout, wait)
    }
}

/// A port with its own notifier wakes the server with it.
impl<Req, Resp, ReqHeader, RespHeader> Wake for RequestPort<Req, Resp, ReqHeader, RespHeader>
where
    Req: Debug + IceoryxSend + ?Sized,
    Resp: Debug + IceoryxSend + ?Sized,
    ReqHeader: Debug + ZeroCopySend,
    RespHeader: Debug + ZeroCopySend,
{
    fn wake(&self, doorbell: Doorbell) -> Result<(), RequestError> {
        match &self.wake {
            Some(notifier) => Wake::wake(notifier, doorbell),
            None => Ok(()),
        }
    }
}

/// Opens a request service with `open`, retrying while the server is
/// still creating it, until `deadline`. `Ok(None)` when it never appeared.
pub(crate) fn open_service<F>(
    deadline: Instant,
    open: impl FnMut() -> Result<F, RequestResponseOpenError>,
) -> Result<Option<F>, RequestResponseOpenError> {
    open_with_retry(deadline, open, |e| {
        matches!(
            e,
            RequestResponseOpenError::DoesNotExist | RequestResponseOpenError::HangsInCreation
        )
    })
}

/// A client port that could not be created: [`RequestError::Full`] (`full`
/// names the port kind, `max` the limit) when the service admits no more.
pub(crate) fn client_error(
    error: ClientCreateError,
    max: usize,
    full: &'static str,
    what: &'static str,
) -> RequestError {
    match error {
        ClientCreateError::ExceedsMaxSupportedClients => RequestError::Full {
            what: full,
            max,
            flag: MAX_CLIENTS_FLAG,
        },
        e => RequestError::transport(what, e),
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

/// Calls `receive` until it yields, waiting between calls as `wait` says,
/// for at most `timeout`; a dead server (non-zero `server_pid`) ends it early.
fn await_with<T>(
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
        Stop::Interrupted => RequestError::Interrupted {
            world: world.to_owned(),
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
