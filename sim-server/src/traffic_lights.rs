//! Traffic lights and signs. Each junction's lights are a group that turns them
//! green one after another (green, yellow, then red all round before the
//! next), in simulation time, from whole nanoseconds — so a light's state
//! is the same in every run of the same frames. Scripts may show a state
//! on a light (it holds until the group's cycle next changes that light),
//! change its times, freeze a group where it is or start its cycle again
//! (CARLA's `TrafficLight` API). A sign says what it says for good.

use serde::{Deserialize, Serialize};
use shared_types::NANOS_PER_SECOND;
use shared_types::{LightReading, LightState, SignReading};

/// How long a light stays green by default, seconds (CARLA's).
pub(crate) const GREEN_SECONDS: f64 = 10.0;
/// ... yellow.
pub(crate) const YELLOW_SECONDS: f64 = 3.0;
/// ... red once its turn ends, all the group's lights red (CARLA's
/// clearance time).
pub(crate) const RED_SECONDS: f64 = 2.0;

/// Seconds as whole nanoseconds (times are checked finite and bounded).
fn nanos(seconds: f64) -> u64 {
    (seconds * NANOS_PER_SECOND as f64).round().max(0.0) as u64
}

/// One light.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Light {
    actor: u64,
    /// Its group, an index into [`TrafficLights::groups`].
    group: usize,
    state: LightState,
    /// Time in its group's phase if it is the group's current light,
    /// else zero (CARLA's elapsed time).
    elapsed_ns: u64,
    /// Green, yellow and red times.
    times_ns: [u64; 3],
}

/// Where a group's cycle is with its current light.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
enum Phase {
    Green,
    Yellow,
    /// The current light's turn has ended: every light red.
    Red,
}

/// One junction's lights, in pole order.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Group {
    /// The junction's number (the scene's).
    junction: u32,
    /// Indices into [`TrafficLights::lights`], by pole index.
    poles: Vec<usize>,
    /// The pole whose turn it is.
    current: usize,
    phase: Phase,
    /// Time in the phase.
    timer_ns: u64,
    frozen: bool,
}

/// Every traffic light and sign of a world.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub(crate) struct TrafficLights {
    /// In actor-id order.
    lights: Vec<Light>,
    groups: Vec<Group>,
    /// The signs, in actor-id order.
    signs: Vec<(u64, SignReading)>,
}

impl TrafficLights {
    /// Adds sign `actor` (ids increasing), saying `sign`.
    pub(crate) fn add_sign(&mut self, actor: u64, sign: SignReading) {
        self.signs.push((actor, sign));
    }

    /// What sign `actor` says.
    pub(crate) fn sign(&self, actor: u64) -> Option<SignReading> {
        let i = self.signs.binary_search_by_key(&actor, |s| s.0).ok()?;
        Some(self.signs[i].1)
    }

    /// Adds light `actor` (ids increasing) as pole `pole` of junction
    /// `junction`'s group; the group starts again (its first pole green).
    pub(crate) fn add(&mut self, actor: u64, junction: u32, pole: u32) {
        let index = self.lights.len();
        let group = match self.groups.iter().position(|g| g.junction == junction) {
            Some(g) => g,
            None => {
                self.groups.push(Group {
                    junction,
                    poles: Vec::new(),
                    current: 0,
                    phase: Phase::Green,
                    timer_ns: 0,
                    frozen: false,
                });
                self.groups.len() - 1
            }
        };
        self.lights.push(Light {
            actor,
            group,
            state: LightState::Red,
            elapsed_ns: 0,
            times_ns: [GREEN_SECONDS, YELLOW_SECONDS, RED_SECONDS].map(nanos),
        });
        let poles = &mut self.groups[group].poles;
        let at = (pole as usize).min(poles.len());
        poles.insert(at, index);
        self.reset_group(group);
    }

    fn index_of(&self, actor: u64) -> Option<usize> {
        self.lights.binary_search_by_key(&actor, |l| l.actor).ok()
    }

    /// What light `actor` shows, for how long, and whether its group is
    /// frozen.
    pub(crate) fn reading(&self, actor: u64) -> Option<LightReading> {
        let light = &self.lights[self.index_of(actor)?];
        Some(LightReading {
            state: light.state,
            elapsed_seconds: light.elapsed_ns as f64 / NANOS_PER_SECOND as f64,
            frozen: self.groups[light.group].frozen,
        })
    }

    /// Moves every group that is not frozen on by `delta_ns`.
    pub(crate) fn advance(&mut self, delta_ns: u64) {
        for g in 0..self.groups.len() {
            if self.groups[g].frozen || self.groups[g].poles.is_empty() {
                continue;
            }
            self.groups[g].timer_ns += delta_ns;
            let cycle_ns: u64 = self.groups[g]
                .poles
                .iter()
                .map(|&l| self.lights[l].times_ns.iter().sum::<u64>())
                .sum();
            if cycle_ns == 0 {
                // Every phase zero long: the cycle stands where it is.
                self.groups[g].timer_ns = 0;
            }
            loop {
                let group = &self.groups[g];
                let light = &self.lights[group.poles[group.current]];
                let phase_ns = light.times_ns[group.phase as usize];
                if group.timer_ns < phase_ns || cycle_ns == 0 {
                    break;
                }
                self.groups[g].timer_ns -= phase_ns;
                self.next_phase(g);
            }
            self.count_elapsed(g);
        }
    }

    /// The elapsed time of group `g`'s lights, as CARLA counts it: the
    /// current light's time in its phase, zero for those waiting.
    fn count_elapsed(&mut self, g: usize) {
        let group = &self.groups[g];
        for (pole, &index) in group.poles.iter().enumerate() {
            self.lights[index].elapsed_ns = if pole == group.current {
                group.timer_ns
            } else {
                0
            };
        }
    }

    /// The group's next phase: green to yellow to red on its current
    /// light, then the next light green.
    fn next_phase(&mut self, g: usize) {
        let group = &mut self.groups[g];
        let (phase, state) = match group.phase {
            Phase::Green => (Phase::Yellow, LightState::Yellow),
            Phase::Yellow => (Phase::Red, LightState::Red),
            Phase::Red => {
                group.current = (group.current + 1) % group.poles.len();
                (Phase::Green, LightState::Green)
            }
        };
        group.phase = phase;
        let light = group.poles[group.current];
        self.show(light, state);
    }

    /// Light `index` shows `state` from now.
    fn show(&mut self, index: usize, state: LightState) {
        self.lights[index].state = state;
    }

    /// Group `g` from the start: its first pole green, the others red.
    fn reset_group(&mut self, g: usize) {
        let group = &mut self.groups[g];
        group.current = 0;
        group.phase = Phase::Green;
        group.timer_ns = 0;
        for (pole, &index) in group.poles.iter().enumerate() {
            self.lights[index].state = if pole == 0 {
                LightState::Green
            } else {
                LightState::Red
            };
        }
        self.count_elapsed(g);
    }

    /// Light `actor` shows `state` until its group's cycle changes it;
    /// false if `actor` is no light.
    pub(crate) fn set_state(&mut self, actor: u64, state: LightState) -> bool {
        let Some(index) = self.index_of(actor) else {
            return false;
        };
        self.show(index, state);
        true
    }

    /// Sets the green, yellow and red times of light `actor` that are
    /// given (seconds, checked by the caller); false if it is no light.
    pub(crate) fn set_times(&mut self, actor: u64, times: [Option<f32>; 3]) -> bool {
        let Some(index) = self.index_of(actor) else {
            return false;
        };
        for (slot, time) in self.lights[index].times_ns.iter_mut().zip(times) {
            if let Some(seconds) = time {
                *slot = nanos(f64::from(seconds));
            }
        }
        true
    }

    /// Light `actor`'s green, yellow and red times, seconds.
    #[cfg(test)]
    pub(crate) fn times(&self, actor: u64) -> Option<[f64; 3]> {
        let light = &self.lights[self.index_of(actor)?];
        Some(light.times_ns.map(|t| t as f64 / NANOS_PER_SECOND as f64))
    }

    /// The groups that `actor` names: its own for a light, all for 0;
    /// `None` for another actor.
    fn groups_of(&self, actor: u64) -> Option<Vec<usize>> {
        if actor == 0 {
            return Some((0..self.groups.len()).collect());
        }
        self.index_of(actor).map(|i| vec![self.lights[i].group])
    }

    /// Freezes or unfreezes light `actor`'s group (0: every group);
    /// false if `actor` is neither 0 nor a light.
    pub(crate) fn freeze(&mut self, actor: u64, frozen: bool) -> bool {
        let Some(groups) = self.groups_of(actor) else {
            return false;
        };
        for g in groups {
            self.groups[g].frozen = frozen;
        }
        true
    }

    /// Starts light `actor`'s group's cycle again (0: every group's);
    /// false if `actor` is neither 0 nor a light.
    pub(crate) fn reset(&mut self, actor: u64) -> bool {
        let Some(groups) = self.groups_of(actor) else {
            return false;
        };
        for g in groups {
            self.reset_group(g);
        }
        true
    }

    /// Sets light `actor` to a recorded reading (a replay).
    pub(crate) fn restore(&mut self, actor: u64, reading: LightReading) {
        if let Some(index) = self.index_of(actor) {
            let light = &mut self.lights[index];
            light.state = reading.state;
            light.elapsed_ns = nanos(reading.elapsed_seconds);
            let group = light.group;
            self.groups[group].frozen = reading.frozen;
        }
    }
}

#[cfg(test)]
mod tests;
