//! Actors spawned in asynchronous mode are shown to CARLA's clients before
//! the spawn is answered. CARLA 0.9.16's client reads an actor's state from
//! the last world state it received, and `actor.destroy()` on an actor no
//! world state has held yet is dropped on the client's side ("attempting
//! to destroy an actor that is already dead"): a script that spawns and at
//! once destroys would leak the actor. In asynchronous mode the server
//! steps on its own, so the gateway waits for the first frame holding the
//! new actors and sends it before answering. The client reads world
//! states on its streaming connection and answers on its RPC one, so this
//! shortens the window rather than closing it. In synchronous mode no
//! frame comes before the next tick, as on CARLA.

use std::time::{Duration, Instant};

use shared_types::{ActorKind, Command, CommandKind, VehicleSpec};

use super::Session;
use crate::convert;
use crate::locks::lock;
use crate::stream::{self, ActorInfo};

/// The longest a spawn's answer waits for a frame holding the new actors.
const SHOWN_WITHIN: Duration = Duration::from_secs(1);

impl Session {
    /// Until a frame holds actor `id`, just spawned by `command`, the
    /// gateway knows it from the spawn: where, what and how big (so
    /// `get_physics_control`, `bounding_box` and the calls that keep part
    /// of its state answer at once, as CARLA's do). The next frame's
    /// actors replace it.
    pub(super) fn provisional(&self, id: u32, command: &Command) {
        let [a, b, c, _] = command.params;
        let (kind, extent) = match CommandKind::from_u32(command.kind) {
            Some(CommandKind::SpawnBox) => (ActorKind::Box, [a, b, c]),
            Some(CommandKind::SpawnSphere) => (ActorKind::Sphere, [a, a, a]),
            Some(CommandKind::SpawnCapsule) => (ActorKind::Capsule, [a, b, a]),
            Some(CommandKind::SpawnWalker) => (ActorKind::Walker, [a, b, a]),
            Some(CommandKind::SpawnVehicle) => match VehicleSpec::from_params(command.params) {
                Ok(spec) => (ActorKind::Vehicle, spec.half_extents),
                Err(_) => return,
            },
            _ => return,
        };
        let info = ActorInfo {
            kind: kind as u32,
            extent: convert::vector(extent),
            position: command.vector,
            rotation: command.rotation,
            ..ActorInfo::default()
        };
        lock(&self.hub.actors).entry(id).or_insert(info);
    }

    /// In asynchronous mode, sends CARLA's clients the first frame holding
    /// every actor of `spawned` (a sensor is in every world state from its
    /// spawn on); gives up quietly after [`SHOWN_WITHIN`].
    pub(super) fn show_spawned(&mut self, spawned: &[u32]) {
        let bodies: Vec<u64> = spawned
            .iter()
            .filter(|&&id| !crate::wire::is_sensor(id))
            .map(|&id| u64::from(id))
            .collect();
        if bodies.is_empty() || self.ticker.is_some() {
            return;
        }
        let Some(client) = self.client.as_mut() else {
            return;
        };
        if client.get_settings().map_or(true, |s| s.synchronous_mode) {
            return;
        }
        let pid = client.server_pid();
        let deadline = Instant::now() + SHOWN_WITHIN;
        while let Some(left) = deadline.checked_duration_since(Instant::now()) {
            let Ok(view) = client.wait_for_frame(left) else {
                return;
            };
            let actors = view.actors();
            if bodies.iter().all(|id| actors.iter().any(|a| a.id == *id)) {
                stream::publish(&self.hub, &view, pid);
                return;
            }
        }
    }
}
