//! Traffic that drives itself on simbus's scenes.
//!
//! [`Lanes`] are a scene's roads as vehicles travel them (each driving
//! lane in its direction of travel, what it leads into, its stop lines and
//! speed limits, where a point is on it); a [`Planner`] turns one frame
//! into one [`Control`] per vehicle it drives — lane following, a seeded
//! way at each junction, speed limits and curves, red lights and stop
//! signs, distance to vehicles and walkers — with what CARLA's
//! `TrafficManager` calls set in [`Parameters`]. The same frames and
//! parameters give the same controls.
//!
//! The CARLA gateway's traffic manager drives with it, and so do the
//! Python package's driving environments (`simbus.gym`).
//!
//! ```
//! use shared_types::{roads, scene::SceneName};
//! use simbus_traffic::{Lanes, Planner};
//!
//! let lanes = Lanes::new(roads::network(SceneName::Town));
//! let spawn = lanes.network().spawn_points()[0];
//! // Spawn points are in CARLA's axes (y to the right): OpenDRIVE's y is -y.
//! let [x, y, _] = spawn.location;
//! let on = lanes.locate(x, -y, -spawn.rotation[1].to_radians()).expect("on a lane");
//! assert!(on.left.abs() < 0.1);
//! let mut planner = Planner::default();
//! planner.register(7, 42);
//! assert_eq!(planner.vehicles().collect::<Vec<_>>(), [7]);
//! ```

mod lanes;
mod lights;
mod parameters;
mod planner;

pub use lanes::{wrap, LaneRef, Lanes, OnLane, StopLine};
pub use lights::{head, signal_index, LightStates};
pub use parameters::{
    Change, GlobalChange, Globals, Parameters, Turn, VehicleChange, VehicleParameters,
};
pub use planner::{Control, Planner};
