//! [`DrivingWorld`]: one world of `simbus.gym`'s driving task, stepped from
//! Rust. Its ego vehicles' observations are written straight into rows of
//! the caller's batch arrays (EnvPool's design: no Python object per
//! environment on the hot path), its traffic driven by
//! `simbus_traffic`'s planner in this process, its episodes started by
//! restoring one snapshot.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Duration;

use numpy::{
    PyReadonlyArray2, PyReadwriteArray1, PyReadwriteArray2, PyReadwriteArray3, PyReadwriteArray4,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use shared_types::roads::{self, LANE_WIDTH, SIDEWALK_WIDTH};
use shared_types::scene::SceneName;
use shared_types::{ActorState, Command, WorldSettings};
use sim_client::{Client, SnapshotId, TickInFlight, Ticker};
use simbus_traffic::{Control, LightStates, Parameters, Planner};

use super::task::{self, Ego, Outcome, TaskSpec, REWARD_TERMS};
use crate::args::seconds;
use crate::errors::{self, message, raise};
use crate::gil::detached;

mod episode;
mod sensors;

pub(crate) use sensors::Captures;
use sensors::EgoSensor;

/// Metres between the places vehicles may start.
const START_SPACING: f64 = 12.0;
/// How high above the road vehicles are put, metres.
const VEHICLE_DROP: f32 = 1.1;
/// A walker's radius and half height (CARLA's adult), metres.
const WALKER_SIZE: (f32, f32) = (0.25, 0.9);
/// How fast walkers walk, m/s.
const WALKER_SPEED: f32 = 1.4;
/// Frames the world runs after its actors are spawned, before the
/// episodes' snapshot is saved (the vehicles settle on their wheels).
const SETTLE_FRAMES: u32 = 20;
/// The discrete actions: (steer, throttle minus brake).
const DISCRETE: [(f32, f32); 9] = [
    (0.0, 0.0),
    (0.0, 0.6),
    (0.0, -0.6),
    (0.3, 0.4),
    (-0.3, 0.4),
    (0.6, 0.2),
    (-0.6, 0.2),
    (0.0, 1.0),
    (0.0, -1.0),
];

/// A scene's lanes, built once per process and scene.
fn lanes_of(scene: SceneName) -> Arc<simbus_traffic::Lanes> {
    static LANES: OnceLock<Mutex<HashMap<String, Arc<simbus_traffic::Lanes>>>> = OnceLock::new();
    let mut lanes = LANES
        .get_or_init(Mutex::default)
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    lanes
        .entry(scene.to_string())
        .or_insert_with(|| Arc::new(simbus_traffic::Lanes::new(roads::network(scene))))
        .clone()
}

/// One ego's (steer, pedal) from its row of actions: two numbers in
/// -1..=1 (clamped), or in discrete mode the index of one of [`DISCRETE`].
fn ego_action(discrete: bool, row: [Option<f32>; 2]) -> PyResult<(f32, f32)> {
    if discrete {
        let index = row[0].unwrap_or(f32::NAN);
        if !(index >= 0.0 && (index as usize) < DISCRETE.len() && index.fract() == 0.0) {
            return Err(PyValueError::new_err(format!(
                "a discrete action is 0..{}, not {index}",
                DISCRETE.len()
            )));
        }
        return Ok(DISCRETE[index as usize]);
    }
    match row {
        [Some(steer), Some(pedal)] if steer.is_finite() && pedal.is_finite() => {
            Ok((steer.clamp(-1.0, 1.0), pedal.clamp(-1.0, 1.0)))
        }
        _ => Err(PyValueError::new_err(
            "an action is two finite numbers: steer and pedal",
        )),
    }
}

/// A walker of the traffic: the lane whose sidewalk it walks and which way.
#[derive(Debug, Clone, Copy)]
struct Walker {
    id: u64,
    lane: simbus_traffic::LaneRef,
    forward: bool,
    /// Where on the far sidewalk it is crossing to (OpenDRIVE's axes).
    crossing: Option<(f64, f64)>,
}

/// One world of the driving task: its connection, its ticker and its
/// episode's state. Bound to the thread that made it.
#[pyclass(module = "simbus._simbus", unsendable)]
pub(crate) struct DrivingWorld {
    client: Client,
    ticker: Ticker,
    lanes: Arc<simbus_traffic::Lanes>,
    spec: TaskSpec,
    egos: Vec<Ego>,
    traffic: Vec<u64>,
    walkers: Vec<Walker>,
    cameras: Vec<EgoSensor>,
    camera_size: Option<(u32, u32)>,
    lidars: Vec<EgoSensor>,
    lidar_size: Option<(u32, u32)>,
    planner: Planner,
    parameters: Parameters,
    lights: LightStates,
    /// The walkers' choices (cross or turn back), seeded per episode.
    walker_rng: ChaCha8Rng,
    /// How often a walker at its sidewalk's end crosses (0..=1).
    cross_factor: f64,
    /// Road crossings walkers finished this episode.
    crossings: u64,
    snapshot: SnapshotId,
    actors: Vec<ActorState>,
    time: (f64, f64),
    frame: u64,
    in_flight: Option<TickInFlight>,
    /// The frame of a step whose answer `ready` took.
    answered: Option<u64>,
    commands: Vec<Command>,
    controls: Vec<Control>,
    /// Each ego's last outcome (kept: the hot path allocates nothing).
    outcomes: Vec<Outcome>,
    steps: u64,
    max_steps: u64,
    timeout: Duration,
    discrete: bool,
}

impl std::fmt::Debug for DrivingWorld {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DrivingWorld")
            .field("world", &self.client.world().as_str())
            .field("frame", &self.frame)
            .field("egos", &self.egos.len())
            .finish_non_exhaustive()
    }
}

fn error(e: impl std::error::Error) -> PyErr {
    raise("Error", message(&e))
}

#[pymethods]
impl DrivingWorld {
    /// Connects to `world`, claims its ticker, sets a fixed step in
    /// synchronous mode, loads the town, spawns the egos, traffic and
    /// walkers, lets them settle and saves the snapshot every episode
    /// starts from.
    #[new]
    #[pyo3(signature = (world, *, scene = "town", egos = 1, vehicles = 0, walkers = 0, cross_factor = 0.5, delta_seconds = 0.1, max_substep_delta_time = 0.02, actors = 6, route_points = 10, route_length = 300.0, weights = [1.0, 10.0, 0.1, 5.0, 5.0], end_on_collision = true, max_episode_steps = 1000, camera = None, lidar = None, discrete = false, timeout = 10.0))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        world: &str,
        scene: &str,
        egos: usize,
        vehicles: usize,
        walkers: usize,
        cross_factor: f64,
        delta_seconds: f64,
        max_substep_delta_time: f64,
        actors: usize,
        route_points: usize,
        route_length: f64,
        weights: [f32; REWARD_TERMS],
        end_on_collision: bool,
        max_episode_steps: u64,
        camera: Option<(u32, u32)>,
        lidar: Option<(u32, u32)>,
        discrete: bool,
        timeout: f64,
    ) -> PyResult<Self> {
        let timeout = seconds("timeout", timeout)?;
        let scene: SceneName = scene
            .parse()
            .map_err(|e| PyValueError::new_err(format!("scene: {e}")))?;
        if egos == 0 || egos > 64 {
            return Err(PyValueError::new_err(format!(
                "egos must be 1..=64, not {egos}"
            )));
        }
        if vehicles > 200 || walkers > 200 {
            return Err(PyValueError::new_err(
                "at most 200 vehicles and 200 walkers",
            ));
        }
        if !(0.0..=1.0).contains(&cross_factor) {
            return Err(PyValueError::new_err(format!(
                "cross_factor is 0..=1 (how often a walker crosses), not {cross_factor}"
            )));
        }
        if !(route_length.is_finite() && route_length > 0.0) {
            return Err(PyValueError::new_err(
                "route_length must be a positive number of metres",
            ));
        }
        if actors > 64 || route_points > 64 {
            return Err(PyValueError::new_err(
                "at most 64 actors and 64 route points observed",
            ));
        }
        let client =
            detached(py, (), |()| Client::connect(world, timeout)).map_err(errors::connect)?;
        let mut ticker = client.claim_ticker().map_err(errors::tick)?;
        let settings = WorldSettings {
            synchronous_mode: true,
            fixed_delta_seconds: Some(delta_seconds),
            substepping: true,
            max_substep_delta_time,
            max_substeps: 16,
            ..client.get_settings().map_err(errors::request)?
        };
        ticker.apply_settings(settings).map_err(errors::settings)?;
        let name = scene.to_string();
        detached(py, &client, |c| c.load_world(&name, false)).map_err(errors::load)?;
        let spec = TaskSpec {
            actors,
            route_points,
            route_length,
            weights,
            end_on_collision,
        };
        let mut this = Self {
            client,
            ticker,
            lanes: lanes_of(scene),
            spec,
            egos: Vec::new(),
            traffic: Vec::new(),
            walkers: Vec::new(),
            cameras: Vec::new(),
            camera_size: camera,
            lidars: Vec::new(),
            lidar_size: lidar,
            planner: Planner::default(),
            parameters: Parameters::default(),
            lights: LightStates::default(),
            walker_rng: task::episode_rng(0, 3),
            cross_factor,
            crossings: 0,
            snapshot: SnapshotId(0),
            actors: Vec::new(),
            time: (0.0, delta_seconds),
            frame: 0,
            in_flight: None,
            answered: None,
            commands: Vec::new(),
            controls: Vec::new(),
            outcomes: Vec::new(),
            steps: 0,
            max_steps: max_episode_steps,
            timeout,
            discrete,
        };
        this.populate(py, egos, vehicles, walkers)?;
        Ok(this)
    }

    /// Floats in one ego's observation row.
    #[getter]
    fn row(&self) -> usize {
        self.spec.row()
    }

    /// The world's name.
    #[getter]
    fn world(&self) -> &str {
        self.client.world().as_str()
    }

    /// The server's process id.
    #[getter]
    fn server_pid(&self) -> u32 {
        self.client.server_pid()
    }

    /// The frame last read.
    #[getter]
    fn frame(&self) -> u64 {
        self.frame
    }

    /// The ego vehicles' actor ids.
    #[getter]
    fn egos(&self) -> Vec<u64> {
        self.egos.iter().map(|e| e.id).collect()
    }

    /// The traffic's vehicles' and walkers' actor ids.
    #[getter]
    fn traffic(&self) -> (Vec<u64>, Vec<u64>) {
        (
            self.traffic.clone(),
            self.walkers.iter().map(|w| w.id).collect(),
        )
    }

    /// Road crossings the walkers finished this episode.
    #[getter]
    fn crossings(&self) -> u64 {
        self.crossings
    }

    /// Steps since the episode began (0 right after a reset).
    #[getter]
    fn episode_steps(&self) -> u64 {
        self.steps
    }

    /// The simulation time of the frame last read, seconds.
    #[getter]
    fn elapsed_seconds(&self) -> f64 {
        self.time.0
    }

    /// Starts an episode from the snapshot: the egos and traffic put where
    /// `seed` says, the traffic's way seeded by it; writes each ego's
    /// observation into `obs` (one row per ego) and returns the frame.
    fn reset(
        &mut self,
        py: Python<'_>,
        seed: u64,
        mut obs: PyReadwriteArray2<'_, f32>,
        camera: Option<PyReadwriteArray4<'_, u8>>,
        lidar: Option<PyReadwriteArray3<'_, f32>>,
    ) -> PyResult<u64> {
        if let Some(tick) = self.in_flight.take() {
            detached(py, (&mut self.ticker, tick), |(t, tick)| {
                t.finish_tick(tick)
            })
            .map_err(errors::tick)?;
        }
        self.answered = None;
        self.client
            .restore_snapshot(self.snapshot)
            .map_err(crate::durability::snapshot_error)?;
        let mut rng = task::episode_rng(seed, 1);
        let places = task::start_places(&self.lanes, START_SPACING);
        let mut order: Vec<usize> = (0..places.len()).collect();
        for i in 0..order.len() {
            let j = rng.random_range(i..order.len());
            order.swap(i, j);
        }
        self.commands.clear();
        let vehicles: Vec<u64> = self
            .egos
            .iter()
            .map(|e| e.id)
            .chain(self.traffic.iter().copied())
            .collect();
        for (&id, &index) in vehicles.iter().zip(&order) {
            let (lane, progress) = places[index];
            let (at, rotation) = task::placed(self.lanes.point(lane, progress, 0.0), VEHICLE_DROP);
            self.commands.push(Command::set_transform(id, at, rotation));
        }
        for walker in &mut self.walkers {
            let (lane, progress) = places[rng.random_range(0..places.len())];
            walker.lane = lane;
            walker.forward = rng.random_bool(0.5);
            walker.crossing = None;
            let side = -(LANE_WIDTH + SIDEWALK_WIDTH) / 2.0;
            let (at, rotation) = task::placed(self.lanes.point(lane, progress, side), 1.0);
            self.commands
                .push(Command::set_transform(walker.id, at, rotation));
        }
        self.walker_rng = task::episode_rng(seed, 3);
        self.crossings = 0;
        self.planner = Planner::default();
        for &id in &self.traffic {
            self.planner.register(id as u32, seed);
        }
        self.client
            .apply_batch(&self.commands)
            .map_err(errors::request)?;
        self.reopen_sensors()?;
        let timeout = self.timeout;
        let frame = detached(py, &mut self.ticker, |t| t.tick(timeout)).map_err(errors::tick)?;
        self.read(py, frame)?;
        let mut route_rng = task::episode_rng(seed, 2);
        for ego in &mut self.egos {
            let start = self
                .actors
                .iter()
                .find(|a| a.id == ego.id)
                .map(|a| {
                    let f = task::Flat::of(a);
                    shared_types::roads::Pose2::new(f.x, f.y, f.hdg)
                })
                .unwrap_or(shared_types::roads::Pose2::new(0.0, 0.0, 0.0));
            ego.route =
                task::Route::plan(&self.lanes, start, self.spec.route_length, &mut route_rng);
            ego.last = [0.0, 0.0];
        }
        self.steps = 0;
        self.outcomes = self.write(&mut obs, Captures { camera, lidar })?;
        Ok(frame)
    }

    /// Sends the egos' `actions` (one row each: steer and throttle minus
    /// brake in -1..=1, or one discrete action index in column 0) with the
    /// traffic's controls, and the tick; `finish` collects the frame.
    fn send(&mut self, actions: PyReadonlyArray2<'_, f32>) -> PyResult<()> {
        if self.in_flight.is_some() || self.answered.is_some() {
            return Err(raise(
                "Error",
                "a step is already in flight: finish it first",
            ));
        }
        let actions = actions.as_array();
        if actions.nrows() != self.egos.len() {
            return Err(PyValueError::new_err(format!(
                "{} rows of actions for {} egos",
                actions.nrows(),
                self.egos.len()
            )));
        }
        // Every row checked before anything changes: a bad one changes nothing.
        for action in actions.rows() {
            ego_action(
                self.discrete,
                [action.get(0).copied(), action.get(1).copied()],
            )?;
        }
        self.commands.clear();
        for (ego, action) in self.egos.iter_mut().zip(actions.rows()) {
            let (steer, pedal) = ego_action(
                self.discrete,
                [action.get(0).copied(), action.get(1).copied()],
            )?;
            ego.last = [steer, pedal];
            self.commands.push(Command::vehicle_control(
                ego.id,
                pedal.max(0.0),
                steer,
                (-pedal).max(0.0),
                false,
            ));
        }
        self.planner.step(
            &self.lanes,
            &self.actors,
            self.lights.states(),
            self.time,
            &self.parameters,
            &mut self.controls,
        );
        self.commands
            .extend(self.controls.iter().map(|c| c.command()));
        self.walk();
        self.client
            .apply_batch(&self.commands)
            .map_err(errors::request)?;
        self.in_flight = Some(self.ticker.send_tick(self.timeout).map_err(errors::tick)?);
        Ok(())
    }

    /// Whether the step sent has its frame (no waiting).
    fn ready(&mut self) -> PyResult<bool> {
        let Some(tick) = self.in_flight.as_mut() else {
            return Ok(true);
        };
        match self.ticker.poll_tick(tick).map_err(errors::tick)? {
            Some(frame) => {
                self.in_flight = None;
                self.answered = Some(frame);
                Ok(true)
            }
            None => Ok(false),
        }
    }

    /// Waits for the step's frame and writes each ego's observation into
    /// `obs`, its reward into `reward`, whether its episode ended into
    /// `terminated` and `truncated`, and its reward terms into `terms`.
    #[pyo3(signature = (obs, reward, terminated, truncated, terms, camera = None, lidar = None))]
    #[allow(clippy::too_many_arguments)]
    fn finish(
        &mut self,
        py: Python<'_>,
        mut obs: PyReadwriteArray2<'_, f32>,
        mut reward: PyReadwriteArray1<'_, f32>,
        mut terminated: PyReadwriteArray1<'_, bool>,
        mut truncated: PyReadwriteArray1<'_, bool>,
        mut terms: PyReadwriteArray2<'_, f32>,
        camera: Option<PyReadwriteArray4<'_, u8>>,
        lidar: Option<PyReadwriteArray3<'_, f32>>,
    ) -> PyResult<u64> {
        let frame = match (self.in_flight.take(), self.answered.take()) {
            (Some(tick), _) => detached(py, (&mut self.ticker, tick), |(t, tick)| {
                t.finish_tick(tick)
            })
            .map_err(errors::tick)?,
            (None, Some(frame)) => frame,
            (None, None) => return Err(raise("Error", "no step was sent: send actions first")),
        };
        self.read(py, frame)?;
        self.steps += 1;
        let outcomes = self.write(&mut obs, Captures { camera, lidar })?;
        let truncate = self.steps >= self.max_steps;
        let (mut reward, mut terminated, mut truncated, mut terms) = (
            reward.as_array_mut(),
            terminated.as_array_mut(),
            truncated.as_array_mut(),
            terms.as_array_mut(),
        );
        for (i, outcome) in outcomes.iter().enumerate() {
            if let Some(r) = reward.get_mut(i) {
                *r = task::reward(&outcome.terms, &self.spec.weights);
            }
            if let Some(t) = terminated.get_mut(i) {
                *t = outcome.terminated;
            }
            if let Some(t) = truncated.get_mut(i) {
                *t = truncate && !outcome.terminated;
            }
            if let Some(mut row) = terms.rows_mut().into_iter().nth(i) {
                for (slot, term) in row.iter_mut().zip(&outcome.terms) {
                    *slot = *term;
                }
            }
        }
        self.outcomes = outcomes;
        Ok(frame)
    }

    /// Forgets a step in flight and closes the sensors' readers; the world
    /// is given back (its ticker released) when this object goes.
    fn close(&mut self) -> PyResult<()> {
        self.in_flight = None;
        self.close_sensors();
        Ok(())
    }
}
