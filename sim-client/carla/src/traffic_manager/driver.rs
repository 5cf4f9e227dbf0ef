//! The traffic manager's driver: a client of the world that joins its
//! lockstep while it drives vehicles, and for every frame applies the
//! calls due, computes the controls and sends them before saying it is
//! done with the frame (in synchronous mode the world waits for that).

use std::collections::HashMap;
use std::sync::Arc;
use std::time::Duration;

use shared_types::scene::SceneName;
use shared_types::{roads, Command, LightState};
use sim_client::{Client, Participant, WaitError};
use tracing::{debug, info, warn};

use super::Shared;
use crate::locks::lock;
use crate::signals::Signals;
use crate::stream::Hub;
use crate::wire::CarlaVehicleControl;
use simbus_traffic::{Change, Control, GlobalChange, Lanes, Parameters, Planner, VehicleChange};

/// How long a connection waits for the world's server.
const SERVER_WAIT: Duration = Duration::from_secs(5);
/// How long one wait for a frame lasts before the stop is looked at.
const FRAME_WAIT: Duration = Duration::from_millis(500);

/// What the driver keeps from frame to frame.
#[derive(Debug, Default)]
struct Driver {
    planner: Planner,
    parameters: Parameters,
    /// The lanes of the episode's scene (none: a map of its own, which
    /// the native traffic manager does not drive).
    lanes: Option<Lanes>,
    episode: Option<(u32, u64)>,
    signals: Signals,
    lights: HashMap<u32, LightState>,
    changes: Vec<Change>,
    controls: Vec<Control>,
    commands: Vec<Command>,
}

/// Drives until the traffic manager stops; reconnects when the server
/// comes back.
pub(super) fn run(shared: &Arc<Shared>, world: &str, hub: &Arc<Hub>) {
    let mut driver = Driver::default();
    while !shared.is_stopped() {
        let mut client = match Client::connect(world, SERVER_WAIT) {
            Ok(client) => client,
            Err(e) => {
                debug!("the traffic manager waits for the server: {e}");
                shared.set_joined(false);
                std::thread::sleep(Duration::from_millis(200));
                continue;
            }
        };
        client.set_every_frame(true);
        let Ok(status) = client.status() else {
            continue;
        };
        // In step with the world from the start: a script's first
        // vehicles are driven from a frame its own calls decide.
        let mut participant = join(&client, shared.port);
        shared.set_joined(participant.is_some());
        loop {
            if shared.is_stopped() {
                return;
            }
            let frame = match client.wait_for_frame(FRAME_WAIT) {
                Ok(frame) => frame,
                Err(WaitError::Timeout { .. }) => continue,
                Err(e) => {
                    warn!("the traffic manager lost the server: {e}");
                    break;
                }
            };
            let key = (status.run_pid, frame.episode());
            if driver.episode != Some(key) {
                // A load may have changed the scene.
                let scene = client
                    .status()
                    .ok()
                    .and_then(|s| s.scene.parse::<SceneName>().ok());
                driver.new_episode(key, scene, hub);
            }
            shared.due(
                (status.run_pid, frame.episode(), frame.frame()),
                &mut driver.changes,
            );
            driver.apply_changes(shared.port);
            if !driver.planner.is_empty() && !frame.header().is_replay() {
                driver.drive(&frame, hub);
            }
            if !driver.commands.is_empty() {
                if let Err(e) = client.apply_batch_sync(&driver.commands, false) {
                    debug!("the traffic manager's controls were refused: {e}");
                }
            }
            if participant.is_none() {
                participant = join(&client, shared.port);
            }
            if let Some(p) = &participant {
                if let Err(e) = p.done(frame.episode(), frame.frame()) {
                    warn!("the traffic manager left the lockstep: {e}");
                    participant = None;
                }
            }
        }
    }
}

/// Joins the world's lockstep as `traffic-manager:<port>`.
fn join(client: &Client, port: u16) -> Option<Participant> {
    match client.join_lockstep(&format!("traffic-manager:{port}")) {
        Ok(p) => Some(p),
        Err(e) => {
            warn!("the traffic manager could not join the lockstep: {e}");
            None
        }
    }
}

impl Driver {
    /// A new episode: its scene's lanes; its vehicles are new ones.
    fn new_episode(&mut self, key: (u32, u64), scene: Option<SceneName>, hub: &Hub) {
        self.episode = Some(key);
        let foreign = hub.maps.given(key).is_some_and(|m| m.is_foreign());
        self.lanes = match scene {
            Some(scene) if !foreign => Some(Lanes::new(roads::network(scene))),
            _ => None,
        };
        if self.lanes.is_none() {
            info!("the native traffic manager drives simbus's scenes' roads only: none here");
        }
        for id in self.planner.vehicles().collect::<Vec<_>>() {
            self.planner.unregister(id);
        }
        self.signals = Signals::default();
    }

    /// Applies the calls due.
    fn apply_changes(&mut self, port: u16) {
        self.commands.clear();
        let seed = |p: &Parameters| p.globals.seed;
        for change in std::mem::take(&mut self.changes) {
            match &change {
                Change::Register(ids) => {
                    for &id in ids {
                        self.planner.register(id, seed(&self.parameters));
                    }
                    info!(
                        port,
                        "the traffic manager drives {} more vehicles",
                        ids.len()
                    );
                }
                Change::Unregister(ids) => {
                    for &id in ids {
                        self.planner.unregister(id);
                    }
                }
                Change::ShutDown => {
                    for id in self.planner.vehicles().collect::<Vec<_>>() {
                        self.planner.unregister(id);
                    }
                }
                Change::Global(GlobalChange::Seed(s)) => {
                    self.planner.reseed(*s);
                    // As CARLA's: a new seed restarts every light's cycle.
                    self.commands.push(Command::reset_traffic_lights(0));
                }
                Change::Vehicle(id, VehicleChange::Path(points)) => {
                    self.planner.set_path(*id, points);
                }
                Change::Vehicle(id, VehicleChange::Route(turns)) => {
                    self.planner.set_route(*id, turns);
                }
                _ => {}
            }
            self.parameters.apply(&change);
        }
    }

    /// The controls for the frame, into `commands` (and what CARLA's
    /// clients read of them into the hub).
    fn drive(&mut self, frame: &sim_client::FrameView, hub: &Hub) {
        let Some(lanes) = &self.lanes else {
            return;
        };
        self.signals.observe(frame.actors());
        self.signals.light_states(&mut self.lights);
        let t = frame.timestamp();
        self.planner.step(
            lanes,
            frame.actors(),
            &self.lights,
            (t.elapsed_seconds(), t.delta_seconds()),
            &self.parameters,
            &mut self.controls,
        );
        let mut registry = lock(&hub.registry);
        for c in &self.controls {
            self.commands.push(c.command());
            registry.controls.insert(
                c.vehicle,
                CarlaVehicleControl {
                    throttle: c.throttle,
                    steer: -c.steer,
                    brake: c.brake,
                    ..CarlaVehicleControl::default()
                },
            );
            if let Some(flags) = c.lights {
                registry.vehicle_lights.insert(c.vehicle, flags);
            }
        }
    }
}
