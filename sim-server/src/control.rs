//! The control domain: the control service (status, settings, load and
//! reload) and the wake-up event clients notify after any request — the
//! one place the server loop sleeps.

use shared_types::Bus;
use std::time::{Duration, Instant};

use iceoryx2::port::listener::{Listener, ListenerWaitError};
use iceoryx2::port::server::Server as RequestServer;
use shared_types::limits::WorldLimits;
use shared_types::{
    ControlRequest, ControlResponse, RequestKind, ResponseStatus, WorldName, WorldSettings,
    PROTOCOL_VERSION,
};
use tracing::{debug, info, warn};

use crate::ports::{service_name, Transport};
use crate::server::Domains;
use crate::state::Refusal;
use crate::ticker::Ticker;
use crate::{Scene, ServerError};

/// Below this, waits are plain sleeps (event timeouts are this coarse).
const COARSE_WAIT: Duration = Duration::from_millis(5);

type ControlServer = RequestServer<Bus, ControlRequest, (), ControlResponse, ()>;

/// The control service and the wake-up listener.
#[derive(Debug)]
pub struct Control {
    port: ControlServer,
    wake: Listener<Bus>,
}

impl Control {
    /// Opens the control service (admitting one server: a second live
    /// server on the world is refused) and the wake-up event.
    pub fn open(
        transport: &Transport,
        world: &WorldName,
        limits: &WorldLimits,
    ) -> Result<Self, ServerError> {
        use iceoryx2::service::port_factory::server::ServerCreateError;
        let names = &transport.names;
        let port = transport
            .node
            .service_builder(&service_name(&names.control)?)
            .request_response::<ControlRequest, ControlResponse>()
            .max_servers(1)
            .max_clients(limits.max_clients)
            .max_nodes(limits.nodes())
            .max_active_requests_per_client(2)
            .max_response_buffer_size(2)
            .open_or_create()
            .map_err(|e| ServerError::transport("control service", e))?
            .server_builder()
            .create()
            .map_err(|e| match e {
                ServerCreateError::ExceedsMaxSupportedServers => ServerError::AlreadyRunning {
                    world: world.to_string(),
                },
                e => ServerError::transport("control server", e),
            })?;
        let wake = transport
            .node
            .service_builder(&service_name(&names.control_wake)?)
            .event()
            .max_listeners(limits.event_listeners())
            .max_notifiers(limits.max_clients)
            .max_nodes(limits.nodes())
            .open_or_create()
            .map_err(|e| ServerError::transport("control wake-up service", e))?
            .listener_builder()
            .create()
            .map_err(|e| ServerError::transport("control wake-up listener", e))?;
        Ok(Self { port, wake })
    }

    /// Sleeps up to `timeout`, waking early when a client sends any request.
    ///
    /// The event listener's timeout is rounded up to the kernel's tick (a
    /// few milliseconds), so the last stretch before a due frame is a plain,
    /// precise sleep.
    pub fn idle(&self, timeout: Duration) -> Result<(), ServerError> {
        if timeout <= COARSE_WAIT {
            std::thread::sleep(timeout);
            return Ok(());
        }
        self.wait_for_request(timeout - COARSE_WAIT)
    }

    /// Sleeps until a client announces a request, or about `timeout` passed
    /// (as coarse as the event's timeouts: for waits that need no precise
    /// end, such as a synchronous world waiting for its tick).
    pub fn wait_for_request(&self, timeout: Duration) -> Result<(), ServerError> {
        match self.wake.timed_wait(|_| {}, timeout) {
            // A signal (Ctrl-C) ends the sleep early; the loop looks at the flag.
            Ok(_) | Err(ListenerWaitError::InterruptSignal) => Ok(()),
            Err(e) => Err(ServerError::transport("control wake-up wait", e)),
        }
    }

    /// Answers every pending control request.
    pub(crate) fn handle(&mut self, world: &mut Domains) -> Result<(), ServerError> {
        while let Some(request) = self
            .port
            .receive()
            .map_err(|e| ServerError::transport("control receive", e))?
        {
            let response = answer(world, request.payload());
            if let Err(e) = request.send_copy(response) {
                debug!("control response not delivered (client gone?): {e:?}");
            }
        }
        Ok(())
    }
}

fn answer(world: &mut Domains, request: &ControlRequest) -> ControlResponse {
    if request.protocol_version != PROTOCOL_VERSION {
        warn!(
            client_pid = request.client_pid,
            client_version = request.protocol_version,
            "refused a request: protocol version {} is not the server's {PROTOCOL_VERSION}",
            request.protocol_version
        );
        return ControlResponse::refused(ResponseStatus::ProtocolMismatch, world.report());
    }
    match RequestKind::from_u32(request.kind) {
        Some(RequestKind::Hello) => {
            debug!(client_pid = request.client_pid, "client connected");
            ControlResponse::ok(world.report())
        }
        Some(RequestKind::GetSettings | RequestKind::Status) => ControlResponse::ok(world.report()),
        Some(RequestKind::ApplySettings) => apply_settings(world, request),
        Some(kind @ (RequestKind::LoadWorld | RequestKind::ReloadWorld)) => {
            let scene: Scene = match kind {
                RequestKind::LoadWorld => match request.scene.to_string_lossy().parse() {
                    Ok(scene) => scene,
                    Err(e) => {
                        info!(client_pid = request.client_pid, "refused to load: {e}");
                        return ControlResponse::refused(
                            ResponseStatus::UnknownScene,
                            world.report(),
                        );
                    }
                },
                _ => world.runtime.scene,
            };
            let reset = request.flags & ControlRequest::RESET_SETTINGS != 0;
            let ticker = world.ticker.owner_pid();
            if reset && ticker.is_some() && ticker != Some(request.client_pid) {
                // Resetting settings is a settings change: the ticker's
                // (its own process may).
                info!(
                    client_pid = request.client_pid,
                    "refused to reset settings: the ticker holds the world"
                );
                return ControlResponse::refused(ResponseStatus::NotTicker, world.report());
            }
            match world.load_world(scene, reset, request.client_pid, Instant::now()) {
                Ok(()) => ControlResponse::ok(world.report()),
                Err(e) => {
                    warn!("loading {scene} failed: {e}");
                    ControlResponse::refused(ResponseStatus::LoadFailed, world.report())
                }
            }
        }
        None => ControlResponse::refused(ResponseStatus::UnknownRequest, world.report()),
    }
}

/// Settings from a client that is not the ticker. While a ticker holds the
/// world only it changes settings; anyone may leave synchronous mode
/// (CARLA's escape hatch), which ends the ticker's ownership.
fn apply_settings(world: &mut Domains, request: &ControlRequest) -> ControlResponse {
    let settings = WorldSettings::from(request.settings).normalized();
    let current = world.runtime.settings;
    if let Some(ticker_pid) = world.ticker.owner_pid() {
        let leaving_sync = current.synchronous_mode
            && settings
                == WorldSettings {
                    synchronous_mode: false,
                    ..current
                };
        if leaving_sync {
            let by = Ticker::named(request.client_pid, request.client_name, world.clock.frame());
            world.ticker.revoke(by, &world.clock);
        } else if settings != current {
            info!(
                pid = request.client_pid,
                ticker_pid, "refused settings: the ticker holds the world"
            );
            return ControlResponse::refused(ResponseStatus::NotTicker, world.report());
        }
    }
    let next_frame = world.clock.frame() + 1;
    match world
        .runtime
        .change_settings(settings, false, request.client_pid, next_frame)
    {
        Ok(effective_frame) => ControlResponse {
            effective_frame,
            ..ControlResponse::ok(world.report())
        },
        Err(Refusal::Invalid(error)) => ControlResponse::invalid_settings(&error, world.report()),
        Err(Refusal::Status(status)) => ControlResponse::refused(status, world.report()),
    }
}
