//! Which of a network's signals each light or sign actor is: the server's
//! light and sign actors stand where `shared_types::roads` puts the
//! signals, so each is known by where its head stands.

use std::collections::HashMap;

use shared_types::roads::{RoadNetwork, Signal, SignalKind};
use shared_types::{ActorKind, ActorState, LightState};

/// How far from a signal's head a light or sign actor may stand and still
/// be that signal, metres.
const MATCH_DISTANCE: f32 = 0.5;

/// A signal's head in simbus's world axes.
pub fn head(signal: &Signal) -> [f32; 3] {
    let p = signal.pose;
    [p.x as f32, signal.height() as f32, -p.y as f32]
}

/// The index in `network.signals` of the signal light or sign `actor` is,
/// or `None` for any other actor or one standing where no signal is.
pub fn signal_index(network: &RoadNetwork, actor: &ActorState) -> Option<usize> {
    let kind = actor.actor_kind();
    if !matches!(kind, Some(ActorKind::TrafficLight | ActorKind::TrafficSign)) {
        return None;
    }
    network.signals.iter().position(|signal| {
        let lit = signal.kind == SignalKind::TrafficLight;
        let h = head(signal);
        let d = (0..3)
            .map(|i| (h[i] - actor.position[i]).powi(2))
            .sum::<f32>();
        lit == (kind == Some(ActorKind::TrafficLight)) && d.sqrt() < MATCH_DISTANCE
    })
}

/// What each light of a frame shows, by its signal's OpenDRIVE id (what
/// [`crate::Planner::step`] reads), with each actor matched once.
#[derive(Debug, Default)]
pub struct LightStates {
    /// Each light actor's signal id (`None`: it matches none).
    signal_of: HashMap<u64, Option<u32>>,
    states: HashMap<u32, LightState>,
}

impl LightStates {
    /// Takes in a frame's `actors` on `network`'s roads; returns what each
    /// signal's light shows.
    pub fn observe(
        &mut self,
        network: &RoadNetwork,
        actors: &[ActorState],
    ) -> &HashMap<u32, LightState> {
        self.states.clear();
        for actor in actors {
            let Some(light) = actor.light() else {
                continue;
            };
            let signal = *self
                .signal_of
                .entry(actor.id)
                .or_insert_with(|| signal_index(network, actor).map(|i| network.signals[i].id));
            if let Some(signal) = signal {
                self.states.insert(signal, light.state);
            }
        }
        &self.states
    }

    /// What each signal's light showed in the last frame observed.
    pub fn states(&self) -> &HashMap<u32, LightState> {
        &self.states
    }
}
