//! The town's traffic lights and signs as CARLA's client sees them. The
//! server's light and sign actors stand where `shared_types::roads` puts
//! the town's signals, so each is known by where it stands: its OpenDRIVE
//! id (`sign_id`, what `world.get_traffic_light(landmark)` matches), its
//! junction's group, its trigger volume (where a vehicle is "at" it, the
//! box CARLA's client reads as `trigger_volume`), and, per vehicle, the
//! light or stop sign it is at.

use std::collections::HashMap;
use std::sync::OnceLock;

use shared_types::roads::{self, RoadNetwork, Signal, SignalKind};
use shared_types::scene::SceneName;
use shared_types::{ActorState, LightState};

use crate::convert;
use crate::wire::{CarlaLight, VehicleSignals};

/// Height of the trigger volume's centre above the road, metres, and its
/// half height.
const TRIGGER_HEIGHT: f32 = 1.0;

/// The town's roads (the only scene with signals).
fn town() -> &'static RoadNetwork {
    static TOWN: OnceLock<RoadNetwork> = OnceLock::new();
    TOWN.get_or_init(|| roads::network(SceneName::Town))
}

/// A point on the ground in OpenDRIVE's axes as simbus's.
fn simbus_point(x: f64, y: f64, up: f32) -> [f32; 3] {
    [x as f32, up, -y as f32]
}

/// The lights and signs seen in the world's frames.
#[derive(Debug, Default)]
pub(crate) struct Signals {
    /// The signal (an index into the town's) of each light or sign actor.
    of_actor: HashMap<u32, usize>,
    /// The actor of each signal (by its OpenDRIVE id), as last seen.
    actor_of: HashMap<u32, u32>,
    /// The last frame's lights and what each shows (kept, not allocated
    /// per frame).
    frame_lights: Vec<(u32, LightState)>,
    /// The times set through the gateway, per light: green, yellow, red
    /// (the server's own default until then).
    times: HashMap<u32, [f32; 3]>,
}

/// CARLA's default green, yellow and red times, seconds (the server's).
pub(crate) const DEFAULT_TIMES: [f32; 3] = [10.0, 3.0, 2.0];

impl Signals {
    /// Takes in a frame's `actors`: what its lights show, and the lights
    /// and signs not seen before.
    pub(crate) fn observe(&mut self, actors: &[ActorState]) {
        self.frame_lights.clear();
        for actor in actors {
            if let Some(light) = actor.light() {
                self.frame_lights
                    .push((convert::actor_id(actor.id), light.state));
            }
            let id = convert::actor_id(actor.id);
            if self.of_actor.contains_key(&id) {
                continue;
            }
            if let Some(index) = simbus_traffic::signal_index(town(), actor) {
                self.of_actor.insert(id, index);
                self.actor_of.insert(town().signals[index].id, id);
            }
        }
    }

    /// What each light of the last frame observed shows, by its signal's
    /// OpenDRIVE id, into `out`.
    pub(crate) fn light_states(&self, out: &mut HashMap<u32, LightState>) {
        out.clear();
        for &(actor, state) in &self.frame_lights {
            if let Some(signal) = self.signal(actor) {
                out.insert(signal.id, state);
            }
        }
    }

    /// The signal actor `id` is.
    pub(crate) fn signal(&self, id: u32) -> Option<&'static Signal> {
        self.of_actor.get(&id).map(|&i| &town().signals[i])
    }

    /// CARLA's type id of light or sign actor `id`.
    pub(crate) fn type_id(&self, id: u32) -> Option<String> {
        Some(match self.signal(id)?.kind {
            SignalKind::TrafficLight => "traffic.traffic_light".to_owned(),
            SignalKind::Stop => "traffic.stop".to_owned(),
            SignalKind::SpeedLimit(kmh) => format!("traffic.speed_limit.{kmh}"),
        })
    }

    /// Records the times set on light `id` (those given).
    pub(crate) fn set_times(&mut self, id: u32, times: [Option<f32>; 3]) {
        let slot = self.times.entry(id).or_insert(DEFAULT_TIMES);
        for (slot, time) in slot.iter_mut().zip(times) {
            if let Some(t) = time {
                *slot = t;
            }
        }
    }

    /// CARLA's `TrafficLightData` of light `actor`, if it is one.
    pub(crate) fn light(&self, actor: &ActorState) -> Option<CarlaLight> {
        let reading = actor.light()?;
        let id = convert::actor_id(actor.id);
        let signal = self.signal(id)?;
        Some(CarlaLight {
            sign_id: signal.id,
            times: self.times.get(&id).copied().unwrap_or(DEFAULT_TIMES),
            elapsed: reading.elapsed_seconds as f32,
            pole: signal.pole,
            frozen: reading.frozen,
            state: reading.state as u8,
        })
    }

    /// The OpenDRIVE id of sign `id`.
    pub(crate) fn sign_id(&self, id: u32) -> Option<u32> {
        self.signal(id)
            .filter(|s| s.kind != SignalKind::TrafficLight)
            .map(|s| s.id)
    }

    /// What a vehicle at `position` heading as `rotation` (simbus's) is
    /// at in the last frame observed: a light (its state), a stop sign
    /// (red, not a light: the traffic manager's all-way stop), or nothing
    /// (green). A frame without lights (another scene than the town) has
    /// no signals.
    pub(crate) fn vehicle(&self, position: [f32; 3], rotation: [f32; 4]) -> VehicleSignals {
        let mut signals = VehicleSignals::default();
        if self.frame_lights.is_empty() {
            return signals;
        }
        let forward = simbus_pose::rotate(rotation, [1.0, 0.0, 0.0]);
        let heading = f64::from((-forward[2]).atan2(forward[0]));
        let (x, y) = (f64::from(position[0]), -f64::from(position[2]));
        let Some(signal) = town().signal_at(x, y, heading) else {
            return signals;
        };
        match signal.kind {
            SignalKind::TrafficLight => {
                let actor = self.actor_of.get(&signal.id).copied();
                let state = actor.and_then(|a| self.frame_lights.iter().find(|l| l.0 == a));
                if let (Some(actor), Some(&(_, state))) = (actor, state) {
                    signals.at_light = true;
                    signals.light_id = actor;
                    signals.light_state = state as u8;
                }
            }
            SignalKind::Stop => signals.light_state = LightState::Red as u8,
            SignalKind::SpeedLimit(_) => {}
        }
        signals
    }

    /// The lights of light `id`'s junction (itself too), in pole order.
    pub(crate) fn group(&self, id: u32) -> Option<Vec<u32>> {
        let junction = self.signal(id)?.junction?;
        Some(
            town()
                .lights_of(junction)
                .filter_map(|s| self.actor_of.get(&s.id).copied())
                .collect(),
        )
    }

    /// The trigger volume of light or sign `id` in its own frame (CARLA's
    /// axes: the actor faces the traffic's way): centre and half extents.
    pub(crate) fn trigger_volume(
        &self,
        id: u32,
        position: [f32; 3],
        rotation: [f32; 4],
    ) -> Option<([f32; 3], [f32; 3])> {
        let signal = self.signal(id)?;
        if matches!(signal.kind, SignalKind::SpeedLimit(_)) {
            return None;
        }
        let (centre, [half_length, half_width]) = signal.trigger();
        let world = simbus_point(centre.x, centre.y, TRIGGER_HEIGHT);
        let offset = [0, 1, 2].map(|i| world[i] - position[i]);
        let [x, y, z, w] = rotation;
        let local = simbus_pose::rotate([-x, -y, -z, w], offset);
        Some((
            convert::vector(local),
            [half_length as f32, half_width as f32, TRIGGER_HEIGHT],
        ))
    }
}
