//! The adapter's loop: each frame of the world onto ROS 2, controls and
//! ticks from ROS into the world.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use ros2_client::Publisher;
use shared_types::{ActorKind, ActorState, SensorInfo, WorldSettings};
use sim_client::{Client, FrameView, Participant, WaitError, WaitMode};
use tracing::{debug, info, warn};

use crate::dds::{Dds, Qos};
use crate::msg::{
    Clock, Header, MarkerArray, TfMessage, Time, Transform, TransformStamped, Vector3,
};
use crate::outputs::{SensorOut, VehicleOut};
use crate::routes::{Naming, Selection};
use crate::{axes, scene, Config, Event, Published, Ros2Error};

mod controls;
mod ticking;

use ticking::Ticking;

/// How often the adapter looks for sensors and vehicles spawned since.
const LOOK_EVERY: Duration = Duration::from_millis(500);
/// The longest a wait for a frame runs before the stop flag is read again.
const SLICE: Duration = Duration::from_millis(100);
/// The same while ticking from ROS: tick messages are read between waits.
const TICKING_SLICE: Duration = Duration::from_millis(1);
/// How often the ROS peers ticking the world are counted.
const PEER_CHECK: Duration = Duration::from_millis(100);

/// An adapter to be run, whose [`Selection`] another thread may change
/// while it runs (the gateway's `enable_for_ros`).
#[derive(Debug)]
pub struct Bridge {
    config: Config,
    selection: Arc<Mutex<Selection>>,
}

impl Bridge {
    /// An adapter with `config` (its selection shared from now on).
    pub fn new(config: Config) -> Self {
        let selection = Arc::new(Mutex::new(config.selection.clone()));
        Self { config, selection }
    }

    /// The selection the running adapter reads every frame.
    pub fn selection(&self) -> Arc<Mutex<Selection>> {
        self.selection.clone()
    }

    /// Runs the adapter on `world` until `stop` is set (see [`run`]).
    ///
    /// # Errors
    ///
    /// As [`run`].
    pub fn run(
        &self,
        world: &str,
        stop: &AtomicBool,
        on_event: impl FnMut(Event),
    ) -> Result<Published, Ros2Error> {
        Run::start(world, &self.config, self.selection.clone(), on_event)?.serve(stop)
    }
}

/// Publishes `world` on ROS 2 as `config` says until `stop` is set, telling
/// `on_event` what happens. Returns what was published.
///
/// # Errors
///
/// Returns [`Ros2Error::Refused`] for a bad configuration (nothing is
/// started), [`Ros2Error::Connect`] if the world's server does not answer
/// within the timeout, [`Ros2Error::Dds`] / [`Ros2Error::Topic`] if DDS
/// cannot join the domain or make a topic, [`Ros2Error::Tick`] if
/// [`Config::tick_from_ros`] cannot claim the ticker (another client ticks:
/// the error names it) or a tick fails, [`Ros2Error::Settings`] if
/// synchronous mode cannot be entered, and [`Ros2Error::Wait`] /
/// [`Ros2Error::Sensors`] if the world's server goes away.
pub fn run(
    world: &str,
    config: &Config,
    stop: &AtomicBool,
    on_event: impl FnMut(Event),
) -> Result<Published, Ros2Error> {
    Bridge::new(config.clone()).run(world, stop, on_event)
}

/// One running adapter.
struct Run<F> {
    config: Config,
    naming: Naming,
    client: Client,
    clock: Publisher<Clock>,
    tf: Publisher<TfMessage>,
    tf_static: Publisher<TfMessage>,
    markers: Option<Publisher<MarkerArray>>,
    sensors: BTreeMap<u64, SensorOut>,
    vehicles: BTreeMap<u64, VehicleOut>,
    ticking: Option<Ticking>,
    participant: Option<Participant>,
    shared: Arc<Mutex<Selection>>,
    /// The selection as last applied.
    selection: Selection,
    last_look: Option<Instant>,
    /// The sensors' mounts last sent on `/tf_static`.
    mounts: Vec<TransformStamped>,
    /// The last frame's actors.
    actors: Vec<ActorState>,
    /// The last frame published: (episode, frame).
    last: Option<(u64, u64)>,
    published: Published,
    on_event: F,
    /// Last: the publishers and subscriptions above go before their node.
    dds: Dds,
}

impl<F: FnMut(Event)> Run<F> {
    fn start(
        world: &str,
        config: &Config,
        shared: Arc<Mutex<Selection>>,
        mut on_event: F,
    ) -> Result<Self, Ros2Error> {
        if config.domain_id > 232 {
            return Err(Ros2Error::Refused(format!(
                "ROS domain id {} is out of range: 0..=232",
                config.domain_id
            )));
        }
        if config.tick_from_ros && !(config.delta_seconds.is_finite() && config.delta_seconds > 0.0)
        {
            return Err(Ros2Error::Refused(format!(
                "--delta-seconds must be a positive number of seconds, not {}",
                config.delta_seconds
            )));
        }
        let mut client = Client::connect(world, config.timeout)?;
        client.set_request_timeout(config.timeout);
        client.set_wait_mode(WaitMode::Hybrid);
        // The world's actors now (the current frame, which a new reader
        // gets once): the sensors' parents and the vehicles before a tick.
        let actors = client.wait_for_frame(config.timeout)?.actors().to_vec();
        check_selection(&client, &config.selection, &actors)?;
        let node = format!("simbus_{}", sanitize(world));
        let mut dds = Dds::join(config.domain_id, &node, config.lockstep)?;
        let naming = config.naming.clone();
        // CARLA's clock is latched like its other topics (a reader asking
        // for transient local gets it); simbus's keeps every tick.
        let clock_qos = match naming {
            Naming::Carla => Qos::Carla,
            Naming::Simbus { .. } => Qos::Clock,
        };
        let clock = dds.publisher("/clock", clock_qos)?;
        let tf = dds.publisher("/tf", Qos::Reliable)?;
        let tf_static = dds.publisher("/tf_static", Qos::Latched)?;
        let markers = if config.markers {
            Some(dds.publisher(&naming.world_topic("markers"), Qos::Reliable)?)
        } else {
            None
        };
        let mut ticking = None;
        let mut participant = None;
        if config.tick_from_ros {
            let ticks = dds.subscription(&naming.world_topic("tick"))?;
            let mut ticker = client.claim_ticker_as(&format!("ros2-{node}"))?;
            ticker.apply_settings(WorldSettings {
                synchronous_mode: true,
                fixed_delta_seconds: Some(config.delta_seconds),
                ..client.get_settings()?
            })?;
            on_event(Event::TickerClaimed);
            ticking = Some(Ticking {
                ticks,
                ticker: Some(ticker),
                had_peer: false,
                counted: None,
            });
        } else {
            participant = Some(client.join_lockstep(&format!("ros2:{node}"))?);
        }
        on_event(Event::Ready {
            domain_id: dds.domain_id(),
            node,
            ticker: ticking.is_some(),
        });
        Ok(Self {
            config: config.clone(),
            naming,
            client,
            clock,
            tf,
            tf_static,
            markers,
            sensors: BTreeMap::new(),
            vehicles: BTreeMap::new(),
            ticking,
            participant,
            shared,
            selection: Selection::default(),
            last_look: None,
            mounts: Vec::new(),
            actors,
            last: None,
            published: Published::default(),
            on_event,
            dds,
        })
    }

    fn serve(mut self, stop: &AtomicBool) -> Result<Published, Ros2Error> {
        while !stop.load(Ordering::Relaxed) {
            self.serve_ticks()?;
            let slice = if self.ticking.is_some() {
                TICKING_SLICE
            } else {
                SLICE
            };
            let frame = match self.client.wait_for_frame(slice) {
                Ok(frame) => frame,
                // A paused world (synchronous, nobody ticking): keep serving.
                Err(WaitError::Timeout { .. }) => {
                    let actors = std::mem::take(&mut self.actors);
                    let looked = self.look(&actors);
                    self.actors = actors;
                    looked?;
                    continue;
                }
                Err(e) => return Err(e.into()),
            };
            let key = (frame.episode(), frame.frame());
            if self.last.is_some_and(|last| last >= key) {
                continue; // the current frame, given again to a new reader
            }
            self.published.missed_frames += frame.missed();
            // Kept for the looks between frames (no allocation once grown).
            self.actors.clear();
            self.actors.extend_from_slice(frame.actors());
            self.look(frame.actors())?;
            self.publish(&frame);
            self.apply_controls();
            self.last = Some(key);
            if let Some(p) = &self.participant {
                if let Err(e) = p.done(frame.episode(), frame.frame()) {
                    warn!("the ROS 2 adapter left the lockstep: {e}");
                    self.participant = None;
                }
            }
        }
        if let Some(ticking) = &mut self.ticking {
            if let Some(ticker) = ticking.ticker.take() {
                let _ = ticker.release();
            }
        }
        Ok(self.published)
    }

    /// Applies the shared selection if it changed, and looks for sensors
    /// and vehicles come or gone (at most every [`LOOK_EVERY`] unless the
    /// selection changed).
    fn look(&mut self, actors: &[ActorState]) -> Result<(), Ros2Error> {
        let current = self
            .shared
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone();
        let changed = current != self.selection;
        if !changed && self.last_look.is_some_and(|at| at.elapsed() < LOOK_EVERY) {
            return Ok(());
        }
        self.selection = current;
        self.last_look = Some(Instant::now());
        let infos: Vec<SensorInfo> = self.client.list_sensors()?;
        let wanted =
            |id: u64, s: &Selection| s.sensors.as_ref().is_none_or(|only| only.contains(&id));
        let (naming, selection) = (&self.naming, &self.selection);
        // Sensors gone, no longer selected, or renamed (their topics change).
        self.sensors.retain(|id, out| {
            infos.iter().find(|i| i.id == *id).is_some_and(|info| {
                let parent = (info.spec.attach_to != 0)
                    .then(|| naming.parent_frame(info.spec.attach_to, actors, selection));
                wanted(*id, selection)
                    && naming.sensor_topic(*id, parent.as_deref(), selection) == out.topic
            })
        });
        for info in &infos {
            if self.sensors.contains_key(&info.id) || !wanted(info.id, &self.selection) {
                continue;
            }
            let sensor = match self.client.sensor(info.id) {
                Ok(sensor) => sensor,
                Err(e) => {
                    debug!("sensor {} not published: {e}", info.id);
                    continue;
                }
            };
            let parent = (info.spec.attach_to != 0).then(|| {
                self.naming
                    .parent_frame(info.spec.attach_to, actors, &self.selection)
            });
            let topic = self
                .naming
                .sensor_topic(info.id, parent.as_deref(), &self.selection);
            let frame = self.naming.sensor_frame(info.id, &self.selection);
            if let Some(out) = SensorOut::new(&mut self.dds, &self.naming, sensor, &topic, &frame)?
            {
                info!(sensor = info.id, topic = %out.topic, "publishing");
                (self.on_event)(Event::Publishing {
                    sensor: info.id,
                    topic: out.topic.clone(),
                });
                self.sensors.insert(info.id, out);
            }
        }
        self.send_mounts(&infos, actors);
        self.look_for_vehicles(actors)
    }

    /// `/tf_static`: each published sensor's mount on its parent (or in
    /// `map`), and each camera's optical frame; sent when they change.
    fn send_mounts(&mut self, infos: &[SensorInfo], actors: &[ActorState]) {
        let mut mounts = Vec::new();
        for info in infos.iter().filter(|i| self.sensors.contains_key(&i.id)) {
            let spec = info.spec;
            let parent = if spec.attach_to == 0 {
                scene::MAP.to_owned()
            } else {
                self.naming
                    .parent_frame(spec.attach_to, actors, &self.selection)
            };
            let frame = self.naming.sensor_frame(info.id, &self.selection);
            let [x, y, z] = axes::vector(spec.position);
            mounts.push(TransformStamped {
                header: Header::new(0, &parent),
                child_frame_id: frame.clone(),
                transform: Transform {
                    translation: Vector3 { x, y, z },
                    rotation: axes::quaternion(spec.rotation),
                },
            });
            let optical = self.naming.image_frame(&frame);
            if spec.camera().is_some() && optical != frame {
                mounts.push(TransformStamped {
                    header: Header::new(0, &frame),
                    child_frame_id: optical,
                    transform: Transform {
                        translation: Vector3::default(),
                        rotation: axes::OPTICAL,
                    },
                });
            }
        }
        if mounts != self.mounts && !mounts.is_empty() {
            if self
                .tf_static
                .publish(TfMessage {
                    transforms: mounts.clone(),
                })
                .is_err()
            {
                self.published.send_failures += 1;
            }
            self.mounts = mounts;
        }
    }

    /// Odometry and control topics for each vehicle selected.
    fn look_for_vehicles(&mut self, actors: &[ActorState]) -> Result<(), Ros2Error> {
        if actors.is_empty() {
            return Ok(());
        }
        let selected = |a: &ActorState, s: &Selection| {
            a.actor_kind() == Some(ActorKind::Vehicle)
                && s.vehicles.as_ref().is_none_or(|only| only.contains(&a.id))
        };
        let present: BTreeSet<u64> = actors
            .iter()
            .filter(|a| selected(a, &self.selection))
            .map(|a| a.id)
            .collect();
        self.vehicles.retain(|id, _| present.contains(id));
        for actor in actors.iter().filter(|a| present.contains(&a.id)) {
            if self.vehicles.contains_key(&actor.id) {
                continue;
            }
            let Some(frame) = self.naming.actor_frame(actor, &self.selection) else {
                continue;
            };
            let topic = self.naming.vehicle_topic(&frame);
            let out = VehicleOut::new(&mut self.dds, &self.naming, &topic, &frame)?;
            self.vehicles.insert(actor.id, out);
        }
        Ok(())
    }

    /// Everything of `frame`: the clock, the transforms, the odometry, the
    /// markers and each sensor's captures of it.
    fn publish(&mut self, frame: &FrameView) {
        let elapsed_ns = frame.timestamp().elapsed_ns;
        let actors = frame.actors();
        let mut failures = 0;
        let mut sent = |ok: bool| failures += u64::from(!ok);
        sent(
            self.clock
                .publish(Clock {
                    clock: Time::from_ns(elapsed_ns),
                })
                .is_ok(),
        );
        let (naming, selection) = (&self.naming, &self.selection);
        let tf = scene::transforms(actors, elapsed_ns, |a| naming.actor_frame(a, selection));
        sent(self.tf.publish(tf).is_ok());
        for actor in actors {
            if let Some(vehicle) = self.vehicles.get(&actor.id) {
                let odometry = scene::odometry(actor, elapsed_ns, &vehicle.frame);
                sent(vehicle.odometry.publish(odometry).is_ok());
            }
        }
        if let Some(markers) = &self.markers {
            sent(markers.publish(scene::markers(actors, elapsed_ns)).is_ok());
        }
        let mut gone = Vec::new();
        for (id, out) in &mut self.sensors {
            let mut captures = Vec::new();
            for capture in out.sensor.queue() {
                match capture {
                    Ok(c) => captures.push(c),
                    Err(e) => {
                        debug!("sensor {id} ended: {e}");
                        gone.push(*id);
                        break;
                    }
                }
            }
            for capture in &captures {
                sent(out.publish(capture));
                self.published.captures += 1;
            }
        }
        for id in gone {
            self.sensors.remove(&id);
        }
        self.published.send_failures += failures;
        self.published.frames += 1;
    }
}

/// Refuses a selection naming a vehicle or sensor the world does not have
/// (now: one spawned later is not yet known).
fn check_selection(
    client: &Client,
    selection: &Selection,
    actors: &[ActorState],
) -> Result<(), Ros2Error> {
    if let Some(vehicles) = &selection.vehicles {
        let known: BTreeSet<u64> = actors
            .iter()
            .filter(|a| a.actor_kind() == Some(ActorKind::Vehicle))
            .map(|a| a.id)
            .collect();
        if let Some(unknown) = vehicles.iter().find(|v| !known.contains(v)) {
            return Err(Ros2Error::Unknown(format!(
                "vehicle {unknown} is not in world '{}' (its vehicles: {known:?})",
                client.world()
            )));
        }
    }
    if let Some(sensors) = &selection.sensors {
        let known: BTreeSet<u64> = client.list_sensors()?.iter().map(|i| i.id).collect();
        if let Some(unknown) = sensors.iter().find(|s| !known.contains(s)) {
            return Err(Ros2Error::Unknown(format!(
                "sensor {unknown} is not in world '{}' (its sensors: {known:?})",
                client.world()
            )));
        }
    }
    Ok(())
}

/// `world` as a ROS node name's part: letters, digits and `_`.
fn sanitize(world: &str) -> String {
    world
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect()
}
