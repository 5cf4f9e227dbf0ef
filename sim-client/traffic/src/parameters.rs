//! What CARLA's `TrafficManager` API sets: the traffic manager's global
//! parameters and each vehicle's, as its RPC calls change them.

use std::collections::HashMap;

/// CARLA's `RoadOption`s a route (`set_route`) is made of.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Turn {
    /// Turn left.
    Left,
    /// Turn right.
    Right,
    /// Go straight on.
    Straight,
}

impl Turn {
    /// CARLA's `RoadOption` byte (`Void 0, Left 1, Right 2, Straight 3,
    /// LaneFollow 4, ChangeLaneLeft 5, ChangeLaneRight 6, RoadEnd 7`):
    /// the turns a route takes at junctions; the others are not turns.
    pub fn from_road_option(option: u8) -> Option<Self> {
        match option {
            1 => Some(Self::Left),
            2 => Some(Self::Right),
            3 => Some(Self::Straight),
            _ => None,
        }
    }
}

/// One vehicle's parameters (CARLA's per-vehicle setters); `None`: the
/// global value.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct VehicleParameters {
    /// Percent below the speed limit (negative: above).
    pub speed_difference: Option<f32>,
    /// km/h, in place of the speed limit.
    pub desired_speed: Option<f32>,
    /// Metres to the right of the lane's centre.
    pub lane_offset: Option<f32>,
    /// Metres kept to the vehicle ahead.
    pub distance: Option<f32>,
    /// Percent of steps a red light is run.
    pub running_light: f32,
    /// Percent of steps a stop sign is run.
    pub running_sign: f32,
    /// Percent of steps walkers are not braked for.
    pub ignore_walkers: f32,
    /// Percent of steps vehicles are not braked for.
    pub ignore_vehicles: f32,
    /// Whether the traffic manager sets the vehicle's lights.
    pub update_lights: bool,
    /// Actors this vehicle does not brake for (`collision_detection(…, False)`).
    pub ignored: Vec<u32>,
    /// Points to drive through, CARLA's axes (`set_path`).
    pub path: Vec<[f32; 3]>,
    /// Turns to take at the next junctions (`set_route`).
    pub route: Vec<Turn>,
    /// Kept and answered only (one lane each way: nowhere to change to).
    pub auto_lane_change: bool,
    /// Kept only.
    pub keep_right: f32,
    /// Kept only.
    pub random_left: f32,
    /// Kept only.
    pub random_right: f32,
}

/// The traffic manager's global parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct Globals {
    /// Percent below the speed limit (negative: above).
    pub speed_difference: f32,
    /// Metres to the right of the lanes' centre.
    pub lane_offset: f32,
    /// Metres kept to the vehicle ahead.
    pub distance: f32,
    /// The seed of every vehicle's randomness.
    pub seed: u64,
    /// CARLA's synchronous mode for the traffic manager (simbus's is in
    /// step with the world in both: kept and answered).
    pub synchronous: bool,
    /// Kept only: every vehicle is simulated in full.
    pub hybrid_physics: bool,
    /// Kept only.
    pub hybrid_radius: f32,
    /// Kept only.
    pub osm_mode: bool,
    /// Kept only.
    pub respawn_dormant: bool,
    /// Kept only.
    pub respawn_bounds: [f32; 2],
}

impl Default for Globals {
    fn default() -> Self {
        Self {
            speed_difference: 0.0,
            lane_offset: 0.0,
            // CARLA's `MIN_SAFE_INTERVAL_LENGTH`-like standstill gap.
            distance: 2.5,
            seed: 0,
            synchronous: false,
            hybrid_physics: false,
            hybrid_radius: 50.0,
            osm_mode: true,
            respawn_dormant: false,
            respawn_bounds: [25.0, 50.0],
        }
    }
}

/// One change a traffic-manager call makes.
#[derive(Debug, Clone, PartialEq)]
pub enum Change {
    /// Drive these vehicles (`set_autopilot(True)`).
    Register(Vec<u32>),
    /// Stop driving these vehicles.
    Unregister(Vec<u32>),
    /// Every vehicle unregistered (`shut_down`).
    ShutDown,
    /// A change to one vehicle.
    Vehicle(u32, VehicleChange),
    /// A change to every vehicle.
    Global(GlobalChange),
}

/// A per-vehicle setter.
#[derive(Debug, Clone, PartialEq)]
pub enum VehicleChange {
    /// Percent below the speed limit (negative: above).
    SpeedDifference(f32),
    /// km/h in place of the speed limit.
    DesiredSpeed(f32),
    /// Metres right of the lane's centre.
    LaneOffset(f32),
    /// Metres kept to the vehicle ahead.
    Distance(f32),
    /// Percent of steps a red light is run.
    RunningLight(f32),
    /// Percent of steps a stop sign is run.
    RunningSign(f32),
    /// Percent of steps walkers are not braked for.
    IgnoreWalkers(f32),
    /// Percent of steps vehicles are not braked for.
    IgnoreVehicles(f32),
    /// Whether the traffic manager sets the vehicle's lights.
    UpdateLights(bool),
    /// Whether to brake for that actor.
    CollisionDetection(u32, bool),
    /// Points to drive through, CARLA's axes.
    Path(Vec<[f32; 3]>),
    /// Turns to take at the next junctions.
    Route(Vec<Turn>),
    /// Kept only (one lane each way).
    AutoLaneChange(bool),
    /// Kept only.
    KeepRight(f32),
    /// Kept only.
    RandomLeft(f32),
    /// Kept only.
    RandomRight(f32),
}

/// A global setter.
#[derive(Debug, Clone, PartialEq)]
pub enum GlobalChange {
    /// Percent below the speed limit (negative: above).
    SpeedDifference(f32),
    /// Metres right of the lane's centre.
    LaneOffset(f32),
    /// Metres kept to the vehicle ahead.
    Distance(f32),
    /// The seed of every vehicle's randomness.
    Seed(u64),
    /// CARLA's synchronous mode (kept).
    Synchronous(bool),
    /// Kept only.
    HybridPhysics(bool),
    /// Kept only.
    HybridRadius(f32),
    /// Kept only.
    OsmMode(bool),
    /// Kept only.
    RespawnDormant(bool),
    /// Kept only.
    RespawnBounds([f32; 2]),
}

/// Every parameter, as the changes so far left them.
#[derive(Debug, Clone, Default)]
pub struct Parameters {
    /// The global parameters.
    pub globals: Globals,
    /// Each vehicle's own.
    pub vehicles: HashMap<u32, VehicleParameters>,
}

impl Parameters {
    /// Applies a per-vehicle or global change (registrations are the
    /// driver's).
    pub fn apply(&mut self, change: &Change) {
        match change {
            Change::Register(_) | Change::Unregister(_) | Change::ShutDown => {}
            Change::Global(g) => {
                let globals = &mut self.globals;
                match *g {
                    GlobalChange::SpeedDifference(v) => globals.speed_difference = v,
                    GlobalChange::LaneOffset(v) => globals.lane_offset = v,
                    GlobalChange::Distance(v) => globals.distance = v,
                    GlobalChange::Seed(v) => globals.seed = v,
                    GlobalChange::Synchronous(v) => globals.synchronous = v,
                    GlobalChange::HybridPhysics(v) => globals.hybrid_physics = v,
                    GlobalChange::HybridRadius(v) => globals.hybrid_radius = v,
                    GlobalChange::OsmMode(v) => globals.osm_mode = v,
                    GlobalChange::RespawnDormant(v) => globals.respawn_dormant = v,
                    GlobalChange::RespawnBounds(v) => globals.respawn_bounds = v,
                }
            }
            Change::Vehicle(id, v) => {
                let p = self.vehicles.entry(*id).or_default();
                match v {
                    VehicleChange::SpeedDifference(x) => p.speed_difference = Some(*x),
                    VehicleChange::DesiredSpeed(x) => p.desired_speed = Some(*x),
                    VehicleChange::LaneOffset(x) => p.lane_offset = Some(*x),
                    VehicleChange::Distance(x) => p.distance = Some(*x),
                    VehicleChange::RunningLight(x) => p.running_light = *x,
                    VehicleChange::RunningSign(x) => p.running_sign = *x,
                    VehicleChange::IgnoreWalkers(x) => p.ignore_walkers = *x,
                    VehicleChange::IgnoreVehicles(x) => p.ignore_vehicles = *x,
                    VehicleChange::UpdateLights(x) => p.update_lights = *x,
                    VehicleChange::CollisionDetection(other, detect) => {
                        p.ignored.retain(|o| o != other);
                        if !detect {
                            p.ignored.push(*other);
                        }
                    }
                    VehicleChange::Path(points) => p.path.clone_from(points),
                    VehicleChange::Route(turns) => p.route.clone_from(turns),
                    VehicleChange::AutoLaneChange(x) => p.auto_lane_change = *x,
                    VehicleChange::KeepRight(x) => p.keep_right = *x,
                    VehicleChange::RandomLeft(x) => p.random_left = *x,
                    VehicleChange::RandomRight(x) => p.random_right = *x,
                }
            }
        }
    }
}
