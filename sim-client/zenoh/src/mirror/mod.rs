//! The mirroring bridge, on another host: the world's services created in
//! this host's shared memory, as a server would create them; every frame
//! and capture received from the exporting bridge published there; every
//! local request forwarded as a Zenoh query and its replies sent back (a
//! tick as a publication, its answer coming with its frame).
//!
//! The mirror is the local clients' server: frames carry its pid, so a
//! local client notices when the mirror dies. While the exporter cannot be
//! reached, every request is answered at once with
//! [`ResponseStatus::Unreachable`]; frames missed meanwhile are reported as
//! a gap, never invented.
//!
//! The mirror is a [`Mirror`] with one `on_…` method per event; its one
//! wait point is the wake-up listener of this host's world, which local
//! clients notify after a request and Zenoh's callbacks after queueing an
//! event.

mod answers;
mod events;
mod local;
mod query;

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, TryRecvError};
use std::time::{Duration, Instant};

use shared_types::limits::WorldLimits;
use shared_types::{
    FixedText, ResponseStatus, ServiceNames, TickRequest, TickRequestKind, TickResponse,
};
use simbus_transport::stamps::{self, Stage};
use tracing::{info, warn};
use zenoh::bytes::ZBytes;
use zenoh::qos::CongestionControl;
use zenoh::sample::Locality;
use zenoh::Wait as _;

use self::answers::{
    answer_local, refuse_local, request_bytes, send_tick, sender_pid, status_answer,
    unreachable_answer, Answered,
};
use self::events::Event;
use self::local::{Active, Local, LocalServices, SensorPorts};
use self::query::{hello, Hello, Link};
use crate::error::{Chain, MirrorError, QueryError};
use crate::side::{Notice, Side};
use crate::tagged;
use crate::wire::{self, BridgeKeys, Forwarded};

/// How long a tick's answer waits here for its frame.
const HOLD_LIMIT: Duration = Duration::from_secs(2);

/// How often held answers and the local ticker's life are checked (and
/// how soon `stop` is seen): the mirror's one deadline.
const LIVENESS_PERIOD: Duration = Duration::from_millis(100);

/// A forwarded request: the local request and whether it was answered.
struct InFlight {
    local: Local,
    answered: bool,
    /// For a tick sent as a publication, when: it ends unanswered after
    /// the link's timeout (a query's end is Zenoh's).
    put_at: Option<Instant>,
}

/// This host's name, as remote tickers are reported (`host/node`).
fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_owned())
        .ok()
        .filter(|h| !h.is_empty())
        .unwrap_or_else(|| "mirror".to_owned())
}

/// Mirrors `world`, exported at `endpoint`, into this host's shared memory
/// until `stop`.
pub(crate) fn run(side: Side<'_>) -> Result<(), MirrorError> {
    let keys = BridgeKeys::new(side.world);
    let names = ServiceNames::new(side.world);
    let zid = side.session.zid().to_string();
    let Hello {
        status,
        mut header,
        actors,
    } = hello(
        &side.session,
        &keys,
        side.world,
        side.endpoint,
        side.timeout,
        side.stop,
    )?;
    let limits = WorldLimits {
        max_clients: status.report.max_clients.max(1) as usize,
        max_sensor_readers: status.report.max_sensor_readers.max(1) as usize,
    };
    let local = LocalServices::create(&names, &limits)?;
    header.server_pid = std::process::id();
    local.publish_frame(&header, &actors)?;
    let (events, incoming) = mpsc::channel::<Event>();
    let _declared = events::declare(&side.session, &keys, &names, &events)?;
    (side.notice)(Notice::Mirroring {
        world: side.world.clone(),
        endpoint: side.endpoint.to_owned(),
        server_pid: status.report.server_pid,
        frame: header.timestamp.frame,
    });
    info!(world = %side.world, zid = %zid, "mirroring");
    let asks = side
        .session
        .declare_publisher(keys.tick_asks())
        .congestion_control(CongestionControl::Block)
        .express(true)
        .allowed_destination(Locality::Remote)
        .wait()
        .map_err(MirrorError::zenoh("declaring a publisher"))?;
    let link = Link {
        session: &side.session,
        keys: &keys,
        names: &names,
        zid: &zid,
        events,
        timeout: side.options.request_timeout,
        poll: side.options.poll,
        asks,
    };
    let mut mirror = Mirror::new(
        link,
        local,
        limits,
        (header.episode, header.timestamp.frame),
    );
    let result = mirror.serve(&incoming, side.stop, side.notice);
    info!(dropped = mirror.dropped, "mirror ended");
    result
}

/// The mirror: this host's side of the world, one `on_…` per event.
struct Mirror<'a> {
    link: Link<'a>,
    local: LocalServices,
    limits: WorldLimits,
    /// This host's name, for remote tickers' node names.
    host: String,
    /// The last frame published here (episode, frame).
    last: (u64, u64),
    sensors: SensorPorts,
    in_flight: HashMap<u64, InFlight>,
    /// Tick answers waiting for their frame, and since when.
    held: Vec<(Active<TickRequest, TickResponse>, TickResponse, Instant)>,
    next_id: u64,
    /// Whether the exporter is reachable.
    linked: bool,
    /// The local ticker (pid, name as forwarded), released if it dies.
    local_ticker: Option<(u32, String)>,
    next_liveness_check: Instant,
    /// Until when the mirror looks for events before it sleeps.
    poll_until: Instant,
    dropped: u64,
    requests: Vec<Local>,
}

impl<'a> Mirror<'a> {
    fn new(link: Link<'a>, local: LocalServices, limits: WorldLimits, last: (u64, u64)) -> Self {
        Self {
            link,
            local,
            limits,
            host: host_name(),
            last,
            sensors: SensorPorts::default(),
            in_flight: HashMap::new(),
            held: Vec::new(),
            next_id: 0,
            linked: true,
            local_ticker: None,
            next_liveness_check: Instant::now(),
            poll_until: Instant::now(),
            dropped: 0,
            requests: Vec::new(),
        }
    }

    /// Serves until `stop`, telling `notice` when the link goes and comes.
    fn serve(
        &mut self,
        incoming: &Receiver<Event>,
        stop: &AtomicBool,
        notice: &mut dyn FnMut(Notice),
    ) -> Result<(), MirrorError> {
        while !stop.load(Ordering::Relaxed) {
            loop {
                match incoming.try_recv() {
                    // Local clients are rung as soon as the frame is out
                    // (their wake-up overlaps the answers' sending) and
                    // again once answers it carries for this mirror are sent.
                    Ok(Event::Frame(bytes, attached)) => {
                        self.on_frame(&bytes)?;
                        self.local.notify();
                        if attached.is_some_and(|a| self.on_tick_answers(&a.to_bytes())) {
                            self.local.notify();
                        }
                    }
                    Ok(Event::Capture(bytes)) => self.on_capture(&bytes.to_bytes()),
                    Ok(Event::TickAnswers(bytes)) => {
                        if self.on_tick_answers(&bytes.to_bytes()) {
                            self.local.notify();
                        }
                    }
                    Ok(Event::Reply(id, reply)) => {
                        if self.on_reply(id, reply) {
                            self.local.notify();
                        }
                    }
                    Ok(Event::Done(id)) => self.on_done(id),
                    Ok(Event::Exporter(alive)) => self.on_exporter(alive, notice),
                    Err(TryRecvError::Empty) => break,
                    Err(TryRecvError::Disconnected) => return Ok(()),
                }
            }
            self.on_local_requests()?;
            if Instant::now() >= self.next_liveness_check {
                self.next_liveness_check = Instant::now() + LIVENESS_PERIOD;
                self.on_liveness_check();
            }
            // The one wait point: local clients and Zenoh's callbacks (after
            // queueing an event) ring the wake-up listener (see
            // `local::wake`); a ring that came meanwhile ends it at once.
            let now = Instant::now();
            let left = self.next_liveness_check.saturating_duration_since(now);
            let poll_for = self.poll_until.saturating_duration_since(now);
            self.local.wait(poll_for, left)?;
        }
        Ok(())
    }

    /// A frame from the exporter, read straight from Zenoh's payload into
    /// a loaned sample and published here; the tick answers held for it go
    /// (the caller rings local clients).
    fn on_frame(&mut self, payload: &ZBytes) -> Result<(), MirrorError> {
        let mut reader = wire::Slices::new(payload.slices());
        let mut header = match wire::frame_header(&mut reader, payload.len()) {
            Ok(header) => header,
            Err(e) => {
                self.dropped += 1;
                warn!(dropped = self.dropped, "dropped a frame publication: {e}");
                return Ok(());
            }
        };
        let key = (header.episode, header.timestamp.frame);
        let last = self.last;
        if key <= last {
            return Ok(());
        }
        let sync = header.settings.synchronous_mode != 0;
        if sync && header.episode == last.0 && key.1 > last.1 + 1 {
            warn!(
                from = last.1 + 1,
                to = key.1 - 1,
                "frames {}..={} never arrived (the link was down); they are not invented",
                last.1 + 1,
                key.1 - 1
            );
        }
        self.last = key;
        header.server_pid = std::process::id();
        self.local.publish_frame_with(&header, |_| {
            reader.read().unwrap_or_else(bytemuck::Zeroable::zeroed)
        })?;
        stamps::stamp(Stage::MirrorPublishes, key.1);
        let mut answered = false;
        self.held.retain(|(active, answer, _)| {
            if answer.frame > key.1 {
                return true;
            }
            send_tick(active, *answer);
            answered = true;
            false
        });
        if answered {
            stamps::stamp(Stage::MirrorAnswers, key.1);
            self.answered_tick();
        }
        Ok(())
    }

    /// Tick answers from the exporter (published, or attached to a frame
    /// just published here): each of this mirror's in-flight requests
    /// named is answered as a reply would be; a final answer ends it (a
    /// query's own reply, which may follow, then finds nothing in flight).
    /// Whether any was this mirror's: the caller then rings local clients.
    fn on_tick_answers(&mut self, bytes: &[u8]) -> bool {
        let entries = match tagged::decode::<TickResponse>(bytes, "tick answers") {
            Ok(entries) => entries,
            Err(e) => {
                self.dropped += 1;
                warn!(dropped = self.dropped, "dropped tick answers: {e}");
                return false;
            }
        };
        let zid = self.link.zid.as_bytes();
        let mut answered = false;
        for entry in entries.iter().filter(|e| e.mirror == zid) {
            if !self.in_flight.contains_key(&entry.id) {
                continue;
            }
            let interim = entry.value.status == ResponseStatus::WaitingForParticipants as u32;
            let bytes = wire::bytes_of(&entry.value).to_vec();
            answered |= self.on_reply(entry.id, Ok(ZBytes::from(bytes)));
            if !interim {
                self.in_flight.remove(&entry.id);
            }
        }
        answered
    }

    /// A capture from the exporter, published here.
    fn on_capture(&mut self, bytes: &[u8]) {
        match wire::decode_capture(bytes) {
            Ok((header, payload)) => {
                let published = self.sensors.publish(
                    self.link.names,
                    &self.limits,
                    &self.local,
                    &header,
                    payload,
                );
                if let Err(e) = published {
                    self.dropped += 1;
                    warn!(
                        dropped = self.dropped,
                        sensor = header.sensor_id,
                        "dropped a capture: {}",
                        Chain(&e)
                    );
                } else {
                    self.local.notify();
                }
            }
            Err(e) => {
                self.dropped += 1;
                warn!(dropped = self.dropped, "dropped a capture publication: {e}");
            }
        }
    }

    /// The exporter's reply to forwarded request `id`, sent to its local
    /// client (a tick's once its frame is published here); whether the
    /// request was in flight here: the caller then rings local clients.
    fn on_reply(&mut self, id: u64, reply: Result<ZBytes, QueryError>) -> bool {
        let Some(flight) = self.in_flight.get_mut(&id) else {
            return false;
        };
        flight.answered = true;
        let answered = match reply {
            Ok(payload) => answer_local(
                &flight.local,
                &payload.to_bytes(),
                self.link.names,
                &self.limits,
                &self.local,
                &mut self.sensors,
                &mut self.local_ticker,
            ),
            Err(e) => {
                warn!("the exporter refused a request: {e}");
                refuse_local(&flight.local, ResponseStatus::Refused);
                Answered::Sent
            }
        };
        match answered {
            Answered::Sent => {}
            Answered::Unreadable(why) => {
                self.dropped += 1;
                warn!(
                    dropped = self.dropped,
                    "an answer from the exporter is unreadable: {why}"
                );
                unreachable_answer(&flight.local);
            }
            Answered::AfterFrame(answer) => {
                if let Some(InFlight {
                    local: Local::Tick(active, _),
                    ..
                }) = self.in_flight.remove(&id)
                {
                    if answer.frame <= self.last.1 {
                        send_tick(&active, *answer);
                        stamps::stamp(Stage::MirrorAnswers, answer.frame);
                        self.answered_tick();
                    } else {
                        self.held.push((active, *answer, Instant::now()));
                    }
                }
            }
        }
        true
    }

    /// Forwarded request `id` gets no more replies: without any, the
    /// exporter is out of reach.
    fn on_done(&mut self, id: u64) {
        if let Some(flight) = self.in_flight.remove(&id) {
            if !flight.answered {
                unreachable_answer(&flight.local);
                self.local.notify();
            }
        }
    }

    /// The exporter's liveliness token came or went.
    fn on_exporter(&mut self, alive: bool, notice: &mut dyn FnMut(Notice)) {
        if alive == self.linked {
            return;
        }
        self.linked = alive;
        if alive {
            info!("the exporting bridge is reachable again");
            notice(Notice::LinkUp);
            return;
        }
        warn!("the exporting bridge is out of reach; requests are answered 'unreachable'");
        notice(Notice::LinkDown);
        for (_, flight) in self.in_flight.drain() {
            if !flight.answered {
                unreachable_answer(&flight.local);
            }
        }
        for (active, _, _) in self.held.drain(..) {
            let _ = active.send_copy(status_answer(ResponseStatus::Unreachable));
        }
        // The exporter releases the ownership it held for us (or claims it
        // again from a resumed server: the ticker's next tick names it).
        self.local_ticker = None;
        self.local.notify();
    }

    /// Local requests: forwarded, or answered 'unreachable' at once.
    fn on_local_requests(&mut self) -> Result<(), MirrorError> {
        self.local.connect_new_subscribers();
        self.local.receive_requests(&mut self.requests)?;
        let mut requests = std::mem::take(&mut self.requests);
        for mut request in requests.drain(..) {
            if let Local::Tick(active, payload) = &mut request {
                payload.pid = sender_pid(active.header());
                let name = format!("{}/{}", self.host, payload.node_name.to_string_lossy());
                payload.node_name = FixedText::new(&name);
            }
            if !self.linked {
                unreachable_answer(&request);
                self.local.notify();
                continue;
            }
            let put_at = match &request {
                // A tick goes as a publication, its answer comes as one
                // (or with its frame): no Zenoh query on the tick's path.
                Local::Tick(_, payload)
                    if TickRequestKind::from_u32(payload.kind) == Some(TickRequestKind::Tick) =>
                {
                    let frame = self.last.1 + 1;
                    stamps::stamp(Stage::MirrorTakes, frame);
                    stamps::expect(frame);
                    self.next_id += 1;
                    self.link.ask_tick(payload, self.next_id);
                    stamps::stamp(Stage::MirrorAsked, frame);
                    Some(Instant::now())
                }
                _ => {
                    let (service, bytes) = request_bytes(&request);
                    self.forward(service, bytes);
                    None
                }
            };
            self.in_flight.insert(
                self.next_id,
                InFlight {
                    local: request,
                    answered: false,
                    put_at,
                },
            );
        }
        self.requests = requests;
        Ok(())
    }

    /// A tick's answer went to the local ticker: its next tick, which a
    /// ticker in a loop sends at once, is looked for before the mirror
    /// sleeps (the server's hybrid window after a frame, here).
    fn answered_tick(&mut self) {
        self.poll_until = Instant::now() + self.link.poll;
    }

    /// Forwards `bytes` to `service` under a new id, returned.
    fn forward(&mut self, service: Forwarded, bytes: Vec<u8>) -> u64 {
        self.next_id += 1;
        self.link.forward(service, bytes, self.next_id);
        self.next_id
    }

    /// A tick answer whose frame never came (a new episode, a lost
    /// publication) goes anyway; a local ticker that died is released.
    fn on_liveness_check(&mut self) {
        let timeout = self.link.timeout;
        let late = |_: &u64, flight: &mut InFlight| {
            flight.put_at.is_some_and(|at| at.elapsed() >= timeout)
        };
        for (_, flight) in self.in_flight.extract_if(late) {
            if !flight.answered {
                unreachable_answer(&flight.local);
                self.local.notify();
            }
        }
        self.held.retain(|(active, answer, since)| {
            if since.elapsed() < HOLD_LIMIT {
                return true;
            }
            warn!(
                frame = answer.frame,
                "the frame of a tick's answer did not arrive; answering without it"
            );
            send_tick(active, *answer);
            false
        });
        if let Some((pid, name)) = self.local_ticker.clone() {
            if !sim_client::process_alive(pid) {
                info!(pid, "the local ticker died; releasing its ownership");
                let mut release = TickRequest::new(TickRequestKind::Release, &name);
                release.pid = pid;
                self.forward(Forwarded::Tick, wire::bytes_of(&release).to_vec());
                self.local_ticker = None;
            }
        }
    }
}

impl std::fmt::Debug for Mirror<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Mirror")
            .field("last", &self.last)
            .field("linked", &self.linked)
            .field("in_flight", &self.in_flight.len())
            .finish()
    }
}
