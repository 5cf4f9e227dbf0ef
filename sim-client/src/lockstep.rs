//! [`Participant`]: a client the server waits for, frame by frame, in
//! synchronous mode.

use std::time::{Duration, Instant};

use std::cell::RefCell;

use iceoryx2::prelude::*;
use shared_types::{
    LockstepKind, LockstepRequest, LockstepResponse, ResponseStatus, ServiceNames, WorldName,
    MAX_LOCKSTEP_WINDOW,
};
use simbus_transport::spec::WorldServices;
use simbus_transport::Bus;
use tracing::{debug, info};

use crate::open::{wake_notifier, OpenFailure};
use crate::rpc::{client_error, open_service, Pending, RequestPort, Wait};
use crate::RequestError;

type PendingDone = Pending<LockstepRequest, LockstepResponse>;

/// Membership in a world's lockstep: in synchronous mode the server steps
/// frame N+1 only when the tick has arrived **and** every participant has
/// called [`Participant::done`] for frame N — or, for a participant that
/// joined with a window of W frames ([`Client::join_lockstep_with_window`]),
/// for frame N − W. A participant that dies is dropped by the server.
/// Dropping the handle leaves.
///
/// [`Client::join_lockstep_with_window`]: crate::Client::join_lockstep_with_window
///
/// A server runs on a thread here, so the example runs as a test; one
/// thread ticks and takes part, where a program would do each in its own
/// process:
///
/// ```
/// use std::time::Duration;
/// use sim_client::Client;
/// use shared_types::WorldSettings;
///
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// # use std::sync::{atomic::{AtomicBool, Ordering}, Arc};
/// # let name = format!("doc-{}-{}", "participant", std::process::id());
/// # let stop = Arc::new(AtomicBool::new(false));
/// # let server = {
/// #     let (stop, world) = (stop.clone(), shared_types::WorldName::new(&name)?);
/// #     std::thread::spawn(move || {
/// #         let mut config = sim_server::ServerConfig::new(world);
/// #         config.settings.fixed_delta_seconds = Some(0.01);
/// #         config.realtime = true;
/// #         sim_server::Server::start(config).and_then(|mut s| s.run(&stop))
/// #     })
/// # };
/// let client = Client::connect(&name, Duration::from_secs(5))?;
/// let mut ticker = client.claim_ticker()?;
/// let sync = WorldSettings { synchronous_mode: true, ..client.get_settings()? };
/// ticker.apply_settings(sync)?;
/// let participant = client.join_lockstep("my-traffic")?;
/// assert_eq!(client.status()?.participants, 1);
/// let (episode, mut frame) = participant.joined_at();
/// for _ in 0..5 {
///     // ... send this frame's commands with client.apply_batch_sync(..) ...
///     participant.done(episode, frame)?; // the server may step past `frame`
///     let next = ticker.tick(Duration::from_secs(5))?;
///     assert_eq!(next, frame + 1);
///     frame = next;
/// }
/// participant.leave();
/// # drop(ticker);
/// # stop.store(true, Ordering::Relaxed);
/// # server.join().expect("server thread")?;
/// # Ok(())
/// # }
/// ```
///
/// # Threads
///
/// Neither [`Send`] nor [`Sync`]: its iceoryx2 ports belong to the thread
/// that opened them. A thread that needs one joins there, from a client of its own.
///
/// ```compile_fail
/// fn to_another_thread<T: Send>(_: T) {}
/// # fn f(handle: sim_client::Participant) {
/// to_another_thread(handle); // its ports belong to this thread
/// # }
/// ```
pub struct Participant {
    world: WorldName,
    port: RequestPort<LockstepRequest, LockstepResponse>,
    name: String,
    server_pid: u32,
    joined: (u64, u64),
    window: u32,
    /// The answer to the last `done`, read at the next one: a participant
    /// the server dropped learns it there.
    last_done: RefCell<Option<PendingDone>>,
    // Declared last: ports drop before their node.
    _node: Node<Bus>,
}

impl Participant {
    /// Joins `world`'s lockstep as `name` with a window of `window` frames.
    pub(crate) fn join_with_window(
        world: &WorldName,
        server_pid: u32,
        (name, window): (&str, u32),
        timeout: Duration,
    ) -> Result<Self, RequestError> {
        if window > MAX_LOCKSTEP_WINDOW {
            return Err(RequestError::WindowTooLarge {
                window,
                max: MAX_LOCKSTEP_WINDOW,
            });
        }
        let names = ServiceNames::new(world);
        // Named after the participant, so node lists (`top`) say who it is
        // (plain "lockstep" for a name iceoryx2 cannot take).
        let node = simbus_transport::node(&format!("lockstep:{name}"))
            .or_else(|_| simbus_transport::node("lockstep"))
            .map_err(|e| RequestError::transport("node", e))?;
        let deadline = Instant::now() + timeout;
        let specs =
            WorldServices::new(&names).map_err(|e| RequestError::transport("service name", e))?;
        let missing = || RequestError::Timeout {
            world: world.to_string(),
            timeout,
        };
        let service = open_service(deadline, || specs.lockstep.open(&node))
            .map_err(|e| RequestError::transport("lockstep service", e))?
            .ok_or_else(missing)?;
        let port = service.client_builder().create().map_err(|e| {
            let max = service.static_config().max_clients();
            client_error(e, max, "lockstep participants", "lockstep client")
        })?;
        let wake = wake_notifier(&node, &names, deadline)
            .map_err(OpenFailure::into_request)?
            .ok_or_else(missing)?;
        let mut participant = Self {
            world: world.clone(),
            port: RequestPort::new(
                port,
                Some(wake),
                specs.lockstep.doorbell,
                "request send",
                world.as_str(),
                server_pid,
            ),
            name: name.to_owned(),
            server_pid,
            joined: (0, 0),
            window,
            last_done: RefCell::new(None),
            _node: node,
        };
        let response = participant.request(LockstepKind::Join, 0, 0, timeout)?;
        participant.joined = (response.episode, response.frame);
        info!(
            world = %participant.world,
            frame = response.frame,
            window,
            "joined the lockstep"
        );
        Ok(participant)
    }

    /// How many frames the world may run ahead of this participant's last
    /// [`Participant::done`].
    pub fn window(&self) -> u32 {
        self.window
    }

    /// The (episode, frame) current when this participant joined: the first
    /// frame the server waits for its `done`.
    pub fn joined_at(&self) -> (u64, u64) {
        self.joined
    }

    /// Done with `frame` of `episode`: the server may step past it.
    ///
    /// It steps once the tick is there and every other participant is done
    /// too. Send the frame's commands *before* (with `apply_batch_sync`) so
    /// they land in the next step.
    ///
    /// Does not wait for the server. Fails with
    /// [`RequestError::NotParticipant`] when the server answered an earlier
    /// `done` saying it no longer waits for this participant (it was
    /// dropped after the lockstep timeout): frames went on without it.
    ///
    /// # Errors
    ///
    /// Returns [`RequestError::NotParticipant`] if the server answered an
    /// earlier `done` saying it no longer waits for this participant (see
    /// [`Participant::check`]), any other error that answer carried
    /// ([`RequestError::ProtocolMismatch`], ...), and
    /// [`RequestError::Transport`] if iceoryx2 cannot send this `done`.
    pub fn done(&self, episode: u64, frame: u64) -> Result<(), RequestError> {
        self.check()?;
        let pending = self.send(LockstepKind::Done, episode, frame)?;
        *self.last_done.borrow_mut() = Some(pending);
        Ok(())
    }

    /// Whether the server still counts this participant, from the answer
    /// to the last [`Participant::done`] if it has come (no waiting).
    ///
    /// # Errors
    ///
    /// Returns [`RequestError::NotParticipant`] if the answer to the last
    /// `done` says the server dropped this participant (it kept a tick waiting
    /// past the server's `--lockstep-timeout`),
    /// [`RequestError::ProtocolMismatch`] or [`RequestError::Unreachable`] if
    /// that answer says so, and [`RequestError::Transport`] if iceoryx2 fails
    /// to receive it. No answer yet is `Ok(())`.
    pub fn check(&self) -> Result<(), RequestError> {
        let mut last = self.last_done.borrow_mut();
        let Some(pending) = last.as_ref() else {
            return Ok(());
        };
        let answer = self.port.try_answer(pending);
        if !matches!(answer, Ok(None)) {
            *last = None; // answered (or failed): nothing more comes
        }
        let Some(response) = answer? else {
            return Ok(()); // not answered yet
        };
        if response.status == ResponseStatus::NotParticipant as u32 {
            return Err(RequestError::NotParticipant {
                world: self.world.to_string(),
            });
        }
        Ok(())
    }

    /// Leaves the lockstep: the server stops waiting for this participant.
    pub fn leave(self) {
        // Drop sends the leave.
    }

    fn send(
        &self,
        kind: LockstepKind,
        episode: u64,
        frame: u64,
    ) -> Result<PendingDone, RequestError> {
        self.port.send(self.message(kind, episode, frame))
    }

    /// A request of `kind` from this participant.
    fn message(&self, kind: LockstepKind, episode: u64, frame: u64) -> LockstepRequest {
        LockstepRequest {
            window: self.window,
            ..LockstepRequest::new(kind, &self.name, episode, frame)
        }
    }

    /// Sends a request and waits up to `timeout` for its answer.
    fn request(
        &self,
        kind: LockstepKind,
        episode: u64,
        frame: u64,
        timeout: Duration,
    ) -> Result<LockstepResponse, RequestError> {
        let response =
            self.port
                .request(self.message(kind, episode, frame), timeout, Wait::Backoff)?;
        if response.status == ResponseStatus::Refused as u32 {
            return Err(RequestError::WindowTooLarge {
                window: self.window,
                max: MAX_LOCKSTEP_WINDOW,
            });
        }
        if response.status != ResponseStatus::Ok as u32 {
            return Err(RequestError::UnknownAnswer {
                status: response.status,
            });
        }
        Ok(response)
    }
}

impl Drop for Participant {
    fn drop(&mut self) {
        // Fire and forget: the server drops the participant either way
        // once this process is gone.
        if let Err(e) = self.send(LockstepKind::Leave, 0, 0) {
            debug!("leaving the lockstep: {e}");
        }
    }
}

impl std::fmt::Debug for Participant {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Participant")
            .field("world", &self.world)
            .field("name", &self.name)
            .field("server_pid", &self.server_pid)
            .field("joined", &self.joined)
            .field("window", &self.window)
            .finish_non_exhaustive()
    }
}
