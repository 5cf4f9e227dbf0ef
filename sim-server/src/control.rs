//! The control domain: the control service (status, settings, load and
//! reload) and the wake-up event clients notify after any request — the
//! one place the server loop sleeps.

use iceoryx2::service::port_factory::PortFactory as _;
use std::time::Duration;

use iceoryx2::port::listener::{Listener, ListenerWaitError};
use iceoryx2::port::server::Server as RequestServer;
use shared_types::limits::WorldLimits;
use shared_types::{
    ControlRequest, ControlResponse, Doorbell, FixedText, RequestKind, ResponseStatus,
    SettingsError, WorldName, WorldSettings, PROTOCOL_VERSION,
};
use simbus_transport::Bus;
use tracing::{debug, info, warn};

use crate::error::PortError;
use crate::ports::{sender_pid, Transport};
use crate::scene::Scene;

/// Below this, waits are plain sleeps (event timeouts are this coarse).
const COARSE_WAIT: Duration = Duration::from_millis(5);

type ControlServer = RequestServer<Bus, ControlRequest, (), ControlResponse, ()>;

/// The control service and the wake-up listener.
#[derive(Debug)]
pub(crate) struct Control {
    port: ControlServer,
    /// The previous server's clients (their requests are dropped).
    earlier: simbus_transport::EarlierClients,
    wake: Listener<Bus>,
    /// The doorbells rung since [`Control::take_rung`].
    rung: Rung,
}

/// Doorbells rung on the wake-up event: which services hold requests.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct Rung(u32);

impl Rung {
    /// Every service: what a full pass looks at.
    pub(crate) const ALL: Rung = Rung(u32::MAX);

    /// Notes event id `id` (from another process: an id this version does
    /// not know stands for [`Doorbell::Any`]).
    fn ring(&mut self, id: usize) {
        let bell = u32::try_from(id)
            .ok()
            .and_then(Doorbell::from_u32)
            .unwrap_or(Doorbell::Any);
        self.0 |= 1 << bell as u32;
    }

    /// Whether any doorbell rang.
    pub(crate) fn any(self) -> bool {
        self.0 != 0
    }

    /// Whether the service of `bell` may hold requests: its doorbell or
    /// [`Doorbell::Any`] rang.
    pub(crate) fn has(self, bell: Doorbell) -> bool {
        self.0 & (1 << Doorbell::Any as u32 | 1 << bell as u32) != 0
    }
}

impl Control {
    /// Opens the control service (admitting one server: a second live
    /// server on the world is refused) and the wake-up event.
    pub(crate) fn open(
        transport: &Transport,
        world: &WorldName,
        limits: &WorldLimits,
    ) -> Result<Self, PortError> {
        use iceoryx2::service::port_factory::server::ServerCreateError;
        let (node, services) = (&transport.node, &transport.services);
        let service = services
            .control
            .open_or_create(node, limits)
            .map_err(|e| PortError::transport("control service", e))?;
        let earlier = simbus_transport::EarlierClients::of(service.dynamic_config());
        let port = service.server_builder().create().map_err(|e| match e {
            ServerCreateError::ExceedsMaxSupportedServers => PortError::AlreadyRunning {
                world: world.to_string(),
            },
            e => PortError::transport("control server", e),
        })?;
        let wake = services
            .control_wake
            .open_or_create(node, limits)
            .map_err(|e| PortError::transport("control wake-up service", e))?
            .listener_builder()
            .create()
            .map_err(|e| PortError::transport("control wake-up listener", e))?;
        Ok(Self {
            port,
            earlier,
            wake,
            rung: Rung::default(),
        })
    }

    /// Sleeps up to `timeout`, waking early when a client sends any request.
    ///
    /// The event listener's timeout is rounded up to the kernel's tick (a
    /// few milliseconds), so the last stretch before a due frame is a plain,
    /// precise sleep.
    pub(crate) fn idle(&mut self, timeout: Duration) -> Result<(), PortError> {
        if timeout <= COARSE_WAIT {
            std::thread::sleep(timeout);
            return Ok(());
        }
        self.wait_for_request(timeout - COARSE_WAIT)
    }

    /// Sleeps until a client announces a request, or about `timeout` passed
    /// (as coarse as the event's timeouts: for waits that need no precise
    /// end, such as a synchronous world waiting for its tick).
    pub(crate) fn wait_for_request(&mut self, timeout: Duration) -> Result<(), PortError> {
        let rung = &mut self.rung;
        let waited = self
            .wake
            .timed_wait(|event| rung.ring(event.id.as_value()), timeout);
        simbus_transport::stamps::woke();
        match waited {
            // A signal (Ctrl-C) ends the sleep early; the loop looks at the flag.
            Ok(_) | Err(ListenerWaitError::InterruptSignal) => Ok(()),
            Err(e) => Err(PortError::transport("control wake-up wait", e)),
        }
    }

    /// The doorbells rung since the last call (every client rings its
    /// service's after sending a request): taken before the domains answer,
    /// so only the services rung are looked at, and the loop rings the
    /// frame-ready event after answering what was announced (a client
    /// waiting for an answer on that event, the Zenoh exporter, wakes).
    /// Costs no system call.
    pub(crate) fn take_rung(&mut self) -> Result<Rung, PortError> {
        let rung = &mut self.rung;
        match self.wake.try_wait(|event| rung.ring(event.id.as_value())) {
            Ok(_) | Err(ListenerWaitError::InterruptSignal) => {}
            Err(e) => return Err(PortError::transport("control wake-up wait", e)),
        }
        Ok(std::mem::take(&mut self.rung))
    }

    /// Answers every pending control request: each is decoded into the
    /// call it makes, which `answer` carries out on the world.
    pub(crate) fn handle(
        &mut self,
        mut answer: impl FnMut(ControlCall) -> ControlResponse,
    ) -> Result<(), PortError> {
        while let Some(request) = self
            .port
            .receive()
            .map_err(|e| PortError::transport("control receive", e))?
        {
            if self.earlier.sent(request.header()) {
                debug!("dropped a request from a client of the previous server");
                continue;
            }
            // Who asks is the sending port's process as iceoryx2 recorded
            // it, never the pid the request claims: a reset while a ticker
            // holds the world is the ticker's alone.
            let response = answer(decode(request.payload(), sender_pid(request.header())));
            if let Err(e) = request.send_copy(response) {
                debug!("control response not delivered (client gone?): {e:?}");
            }
        }
        Ok(())
    }
}

/// A control request, decoded: what a client asks of the world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum ControlCall {
    /// Hello, status or get settings: the world's status.
    Status,
    /// Refused before it reaches the world (protocol version, unknown
    /// request or scene), with this status.
    Refuse(ResponseStatus),
    /// Settings that cannot be read (a substep rule this version does not
    /// know): refused with this error, changing nothing.
    RefuseSettings(SettingsError),
    /// New settings from `pid`, a client named `name`.
    ApplySettings {
        /// The settings asked for, normalized.
        settings: WorldSettings,
        /// The client's process.
        pid: u32,
        /// The client's name.
        name: FixedText,
    },
    /// Save the world in memory (from `pid`).
    SaveSnapshot {
        /// The client's process.
        pid: u32,
    },
    /// Restore snapshot `id` as a new episode (from `pid`).
    RestoreSnapshot {
        /// The snapshot.
        id: u64,
        /// The client's process.
        pid: u32,
    },
    /// List the snapshots.
    ListSnapshots,
    /// Forget snapshot `id` (from `pid`).
    DropSnapshot {
        /// The snapshot.
        id: u64,
        /// The client's process.
        pid: u32,
    },
    /// Load `scene` (`None`: reload the current one) as a new episode.
    Load {
        /// The scene to load; `None` for a reload.
        scene: Option<Scene>,
        /// Back to the default settings too.
        reset: bool,
        /// The client's process.
        pid: u32,
    },
}

/// `request` from process `pid` (the transport's word for it, not the
/// request's `client_pid`, which is only logged).
fn decode(request: &ControlRequest, pid: u32) -> ControlCall {
    if request.protocol_version != PROTOCOL_VERSION {
        warn!(
            client_pid = pid,
            client_version = request.protocol_version,
            "refused a request: protocol version {} is not the server's {PROTOCOL_VERSION}",
            request.protocol_version
        );
        return ControlCall::Refuse(ResponseStatus::ProtocolMismatch);
    }
    match RequestKind::from_u32(request.kind) {
        Some(RequestKind::Hello) => {
            debug!(
                client_pid = pid,
                claimed_pid = request.client_pid,
                "client connected"
            );
            ControlCall::Status
        }
        Some(RequestKind::GetSettings | RequestKind::Status) => ControlCall::Status,
        Some(RequestKind::ApplySettings) => match request.settings.settings() {
            Ok(settings) => ControlCall::ApplySettings {
                settings: settings.normalized(),
                pid,
                name: request.client_name,
            },
            Err(error) => {
                info!(client_pid = pid, "refused settings: {error}");
                ControlCall::RefuseSettings(error)
            }
        },
        Some(kind @ (RequestKind::LoadWorld | RequestKind::ReloadWorld)) => {
            let scene = match kind {
                RequestKind::LoadWorld => match request.scene.to_string_lossy().parse() {
                    Ok(scene) => Some(scene),
                    Err(e) => {
                        info!(client_pid = pid, "refused to load: {e}");
                        return ControlCall::Refuse(ResponseStatus::UnknownScene);
                    }
                },
                _ => None,
            };
            ControlCall::Load {
                scene,
                reset: request.flags & ControlRequest::RESET_SETTINGS != 0,
                pid,
            }
        }
        Some(RequestKind::SaveSnapshot) => ControlCall::SaveSnapshot { pid },
        Some(RequestKind::RestoreSnapshot) => ControlCall::RestoreSnapshot {
            id: request.snapshot,
            pid,
        },
        Some(RequestKind::ListSnapshots) => ControlCall::ListSnapshots,
        Some(RequestKind::DropSnapshot) => ControlCall::DropSnapshot {
            id: request.snapshot,
            pid,
        },
        None => ControlCall::Refuse(ResponseStatus::UnknownRequest),
    }
}

/// What settings from a client that is not the ticker do while a ticker
/// holds the world. Only the ticker changes settings; anyone may leave
/// synchronous mode (CARLA's escape hatch), which ends the ticker's
/// ownership.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum WhileTicked {
    /// The same settings: nothing changes.
    Unchanged,
    /// Synchronous mode left, nothing else: the ticker's ownership ends.
    EndsOwnership,
    /// Any other change: refused.
    Refused,
}

impl WhileTicked {
    /// What `requested` does to `current` while a ticker holds the world.
    pub(crate) fn of(current: WorldSettings, requested: WorldSettings) -> Self {
        let leaving_sync = current.synchronous_mode
            && requested
                == WorldSettings {
                    synchronous_mode: false,
                    ..current
                };
        if leaving_sync {
            Self::EndsOwnership
        } else if requested != current {
            Self::Refused
        } else {
            Self::Unchanged
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_doorbell_admits_its_service_and_any_admits_every_service() {
        let mut rung = Rung::default();
        assert!(!rung.any());
        rung.ring(Doorbell::Tick.event_id());
        assert!(rung.any() && rung.has(Doorbell::Tick));
        assert!(!rung.has(Doorbell::Batch) && !rung.has(Doorbell::Control));
        rung.ring(Doorbell::Batch.event_id());
        assert!(rung.has(Doorbell::Batch) && !rung.has(Doorbell::Recorder));

        let mut any = Rung::default();
        any.ring(Doorbell::Any.event_id());
        assert!(Doorbell::ALL.into_iter().all(|bell| any.has(bell)));
        assert!(Doorbell::ALL.into_iter().all(|bell| Rung::ALL.has(bell)));
    }

    #[test]
    fn an_id_this_version_does_not_know_rings_every_service() {
        for id in [Doorbell::MAX_ID + 1, 31, 32, usize::MAX] {
            let mut rung = Rung::default();
            rung.ring(id);
            assert!(Doorbell::ALL.into_iter().all(|bell| rung.has(bell)), "{id}");
        }
    }
}
