//! CARLA 0.9.16's native ROS 2 (`--ros2`) through the gateway: the sensors
//! a script enables (`sensor.enable_for_ros()`) published by the
//! `simbus-ros2` adapter under CARLA's names (`/carla/<parent's
//! ros_name>/<ros_name>/image`, …), `/clock` every frame, and each `hero`
//! vehicle driven from `/carla/<ros_name>/vehicle_control_cmd` and
//! `ackermann_control_cmd`.
//!
//! The adapter runs on a thread of its own as a client of the world (a
//! lockstep participant: in synchronous mode a frame's messages are out
//! before the next tick is answered); it comes back when a server does.

use std::collections::BTreeSet;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use simbus_ros2::{Bridge, Config, Naming, Selection};
use tracing::{info, warn};

use crate::blueprints::Description;

/// How long the adapter waits before trying a world without a server again.
const RETRY: Duration = Duration::from_secs(1);

/// The sensors scripts enabled and the names they gave, and the adapter
/// publishing them (when the gateway runs with `--ros2`).
#[derive(Debug, Default)]
pub(crate) struct Ros2 {
    /// What the adapter publishes; `None` without `--ros2` (the calls are
    /// answered as CARLA without `--ros2` answers them: nothing is sent).
    selection: Option<Arc<Mutex<Selection>>>,
    /// The sensors enabled (also without `--ros2`: `is_enabled_for_ros`).
    enabled: Mutex<BTreeSet<u64>>,
    stop: Arc<AtomicBool>,
}

impl Ros2 {
    /// Starts the adapter on `world`, DDS domain `domain_id`.
    pub(crate) fn start(world: &str, domain_id: u16, timeout: Duration) -> Self {
        let bridge = Bridge::new(Config {
            domain_id,
            naming: Naming::Carla,
            selection: Selection {
                sensors: Some(BTreeSet::new()),
                vehicles: Some(BTreeSet::new()),
                ..Selection::default()
            },
            markers: false,
            timeout,
            ..Config::default()
        });
        let selection = bridge.selection();
        let stop = Arc::new(AtomicBool::new(false));
        let (world, stopped) = (world.to_owned(), stop.clone());
        let spawned = std::thread::Builder::new()
            .name("carla-ros2".into())
            .spawn(move || {
                while !stopped.load(Ordering::Relaxed) {
                    match bridge.run(&world, &stopped, |event| info!("ROS 2: {event:?}")) {
                        Ok(published) => info!("ROS 2 adapter stopped: {published:?}"),
                        Err(e) => warn!("ROS 2 adapter: {e}; trying again"),
                    }
                    std::thread::sleep(RETRY);
                }
            });
        if let Err(e) = spawned {
            warn!("no thread for the ROS 2 adapter: {e}");
        }
        Self {
            selection: Some(selection),
            enabled: Mutex::default(),
            stop,
        }
    }

    fn with(&self, change: impl FnOnce(&mut Selection)) {
        if let Some(selection) = &self.selection {
            change(&mut selection.lock().unwrap_or_else(PoisonError::into_inner));
        }
    }

    /// A spawned actor's ROS names, as CARLA registers them: a sensor is
    /// named by its `ros_name` (else `actor<id>`); an actor with a
    /// `ros_name` is named by it (a sensor's parent in its topics); a
    /// vehicle whose `role_name` is `hero` takes control from ROS.
    pub(crate) fn spawned(&self, carla_id: u32, description: &Description) {
        let ros_name = description
            .value("ros_name")
            .filter(|n| simbus_ros2::routes::is_segment(n))
            .map(str::to_owned);
        let name = ros_name
            .clone()
            .unwrap_or_else(|| format!("actor{carla_id}"));
        if let Some(sensor) = crate::wire::simbus_id(carla_id) {
            self.with(|s| {
                s.sensor_names.insert(sensor, name);
            });
            return;
        }
        let hero = description.value("role_name") == Some("hero");
        let actor = u64::from(carla_id);
        self.with(|s| {
            if hero || ros_name.is_some() {
                s.actor_names.insert(actor, name);
            }
            if hero {
                s.vehicles.get_or_insert_with(BTreeSet::new).insert(actor);
            }
        });
    }

    /// `enable_sensor_for_ros` / `disable_sensor_for_ros` on simbus sensor
    /// `sensor`.
    pub(crate) fn enable(&self, sensor: u64, on: bool) {
        let mut enabled = self.enabled.lock().unwrap_or_else(PoisonError::into_inner);
        if on {
            enabled.insert(sensor);
        } else {
            enabled.remove(&sensor);
        }
        if self.selection.is_none() && on {
            warn!("a sensor was enabled for ROS 2, but the gateway runs without --ros2: nothing is published");
        }
        self.with(|s| {
            let sensors = s.sensors.get_or_insert_with(BTreeSet::new);
            if on {
                sensors.insert(sensor);
            } else {
                sensors.remove(&sensor);
            }
        });
    }

    /// `is_sensor_enabled_for_ros`.
    pub(crate) fn is_enabled(&self, sensor: u64) -> bool {
        self.enabled
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .contains(&sensor)
    }
}

impl Drop for Ros2 {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}
