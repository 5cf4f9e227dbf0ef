//! How the native traffic manager drives: every registered vehicle
//! follows its lane, picks a way at each junction with its own seeded
//! randomness (or the route or path it was given), keeps to the speed
//! limit and slows for curves, stops at red and yellow lights, comes to a
//! full stop at stop signs and crosses their junction one at a time, keeps
//! its distance to vehicles and walkers on its way, and waits before a
//! junction it could not leave. One step turns one frame into one control
//! per vehicle; the same frames and calls give the same controls.

use std::collections::{BTreeMap, HashMap};

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use shared_types::roads::{Pose2, SPEED_LIMIT_KMH};
use shared_types::{ActorKind, ActorState, LightState};

use super::lanes::{wrap, LaneRef, Lanes};
use super::parameters::{Parameters, Turn, VehicleParameters};
use way::{extend, follow, junction_clear, on_way, sample};

/// How hard vehicles slow down when they can choose, m/s².
const COMFORT_DECELERATION: f64 = 3.0;
/// The most a vehicle can slow down, m/s² (full brake).
const FULL_DECELERATION: f64 = 8.0;
/// The acceleration of full throttle, m/s² (about every simbus car's).
const FULL_ACCELERATION: f64 = 3.5;
/// Sideways acceleration allowed in curves, m/s².
const LATERAL_ACCELERATION: f64 = 2.0;
/// A stop sign's wait at rest before the junction, seconds (CARLA's
/// `MINIMUM_STOP_TIME`).
const STOP_SIGN_WAIT: f64 = 2.0;
/// Below this a vehicle is at rest, m/s.
const AT_REST: f64 = 0.2;
/// How far before a stop line a vehicle aims to stop, metres.
const STOP_MARGIN: f64 = 1.0;
/// The largest front-wheel angle, radians (every simbus car's).
const MAX_STEER: f64 = 0.5;
/// Path samples are this far apart, metres.
const SAMPLE_STEP: f64 = 1.0;
/// A vehicle this far from every lane's centre is found again.
const LOST: f64 = 3.0;
/// Half the width of the band a walker occupies, metres.
const WALKER_HALF_WIDTH: f64 = 0.4;
/// Room kept beside a vehicle's path, metres.
const SIDE_MARGIN: f64 = 0.4;
/// The most throttle from rest, and how much more each m/s allows.
const LAUNCH_THROTTLE: f64 = 0.4;
const LAUNCH_GAIN: f64 = 0.15;
/// The nose-up pitch (its sine, about 6°) past which no throttle is given.
const MAX_NOSE_UP: f64 = 0.1;
/// Time kept to the vehicle ahead on top of the distance, seconds.
const HEADWAY: f64 = 0.5;
/// How close to a path point (`set_path`) counts as reaching it, metres.
const PATH_REACHED: f64 = 6.0;

/// CARLA's `VehicleLightState` bits the traffic manager sets.
const BRAKE_LIGHT: u32 = 8;
const RIGHT_BLINKER: u32 = 16;
const LEFT_BLINKER: u32 = 32;

/// One vehicle's control for the next step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Control {
    /// The vehicle's actor id.
    pub vehicle: u32,
    /// 0..=1.
    pub throttle: f32,
    /// simbus's: positive to the left.
    pub steer: f32,
    /// 0..=1.
    pub brake: f32,
    /// CARLA's light flags, for a vehicle whose lights it sets.
    pub lights: Option<u32>,
}

impl Control {
    /// The control as the command that applies it (simbus's steer, no
    /// hand brake).
    pub fn command(&self) -> shared_types::Command {
        shared_types::Command::vehicle_control(
            u64::from(self.vehicle),
            self.throttle,
            self.steer,
            self.brake,
            false,
        )
    }
}

/// One driven vehicle's own state.
#[derive(Debug)]
struct Driven {
    rng: ChaCha8Rng,
    /// The lane it is on, then those it will take.
    lanes: Vec<LaneRef>,
    progress: f64,
    /// The speed error's integral, m.
    integral: f64,
    /// The km/h of the last speed-limit sign passed.
    limit: f64,
    /// The stop sign it stopped at and since when (seconds), or served.
    stop: Option<StopSign>,
    path: Vec<(f64, f64)>,
    route: Vec<Turn>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct StopSign {
    signal: u32,
    junction: u32,
    since: f64,
    served: bool,
}

/// A vehicle's pose and motion in OpenDRIVE's axes.
#[derive(Debug, Clone, Copy)]
struct Body {
    x: f64,
    y: f64,
    hdg: f64,
    /// Velocity, m/s.
    vx: f64,
    vy: f64,
    half_length: f64,
    half_width: f64,
    walker: bool,
    /// The sine of its nose-up pitch.
    nose_up: f64,
}

impl Body {
    fn of(actor: &ActorState) -> Self {
        let forward = simbus_pose::rotate(actor.rotation, [1.0, 0.0, 0.0]);
        let [vx, _, vz] = actor.linear_velocity;
        let walker = actor.actor_kind() == Some(ActorKind::Walker);
        let [ex, _, ez] = actor.extent;
        Self {
            x: f64::from(actor.position[0]),
            y: -f64::from(actor.position[2]),
            hdg: f64::from(-forward[2]).atan2(f64::from(forward[0])),
            vx: f64::from(vx),
            vy: -f64::from(vz),
            half_length: if walker {
                WALKER_HALF_WIDTH
            } else {
                f64::from(ex)
            },
            half_width: if walker {
                WALKER_HALF_WIDTH
            } else {
                f64::from(ez)
            },
            walker,
            nose_up: f64::from(forward[1]),
        }
    }

    /// Speed along its heading, m/s.
    fn speed(&self) -> f64 {
        self.vx * self.hdg.cos() + self.vy * self.hdg.sin()
    }
}

/// A point of a vehicle's way ahead.
#[derive(Debug, Clone, Copy)]
struct Sample {
    pose: Pose2,
    /// Metres ahead of the vehicle.
    along: f64,
}

/// The native traffic manager's driving: its vehicles, in id order.
#[derive(Debug, Default)]
pub struct Planner {
    vehicles: BTreeMap<u32, Driven>,
    /// Per junction with stop signs, the vehicles waiting at them, in
    /// the order they came to rest.
    queues: HashMap<u32, Vec<u32>>,
    /// Kept between steps: the frame's bodies, one vehicle's way, ids.
    bodies: Vec<(u32, Body)>,
    samples: Vec<Sample>,
    ids: Vec<u32>,
}

impl Planner {
    /// Whether any vehicle is driven.
    pub fn is_empty(&self) -> bool {
        self.vehicles.is_empty()
    }

    /// The vehicles driven, in id order.
    pub fn vehicles(&self) -> impl Iterator<Item = u32> + '_ {
        self.vehicles.keys().copied()
    }

    /// Starts driving `id` with randomness from `seed`.
    pub fn register(&mut self, id: u32, seed: u64) {
        self.vehicles.entry(id).or_insert_with(|| Driven {
            rng: ChaCha8Rng::seed_from_u64(
                seed ^ u64::from(id).wrapping_mul(0x9e37_79b9_7f4a_7c15),
            ),
            lanes: Vec::new(),
            progress: 0.0,
            integral: 0.0,
            limit: SPEED_LIMIT_KMH,
            stop: None,
            path: Vec::new(),
            route: Vec::new(),
        });
    }

    /// Stops driving `id`.
    pub fn unregister(&mut self, id: u32) {
        self.vehicles.remove(&id);
        for queue in self.queues.values_mut() {
            queue.retain(|&v| v != id);
        }
    }

    /// Every vehicle's randomness starts again from `seed`.
    pub fn reseed(&mut self, seed: u64) {
        for (&id, driven) in &mut self.vehicles {
            driven.rng =
                ChaCha8Rng::seed_from_u64(seed ^ u64::from(id).wrapping_mul(0x9e37_79b9_7f4a_7c15));
        }
    }

    /// Gives vehicle `id` points to drive through (CARLA's axes).
    pub fn set_path(&mut self, id: u32, points: &[[f32; 3]]) {
        if let Some(driven) = self.vehicles.get_mut(&id) {
            driven.path = points
                .iter()
                .map(|p| (f64::from(p[0]), -f64::from(p[1])))
                .collect();
            driven.lanes.truncate(1);
        }
    }

    /// Gives vehicle `id` the turns to take at the next junctions.
    pub fn set_route(&mut self, id: u32, turns: &[Turn]) {
        if let Some(driven) = self.vehicles.get_mut(&id) {
            driven.route = turns.to_vec();
            driven.lanes.truncate(1);
        }
    }

    /// The controls for the step after a frame of `actors` at `time`
    /// seconds, its lights showing `lights` (by signal id), on `lanes`.
    /// Vehicles not in the frame are no longer driven.
    pub fn step(
        &mut self,
        lanes: &Lanes,
        actors: &[ActorState],
        lights: &HashMap<u32, LightState>,
        (time, delta): (f64, f64),
        parameters: &Parameters,
        out: &mut Vec<Control>,
    ) {
        out.clear();
        self.bodies.clear();
        self.bodies.extend(
            actors
                .iter()
                .filter(|a| matches!(a.actor_kind(), Some(ActorKind::Vehicle | ActorKind::Walker)))
                .map(|a| (u32::try_from(a.id).unwrap_or(u32::MAX), Body::of(a))),
        );
        // Kept lists, not allocated per frame: the vehicles gone, then
        // those driven.
        let mut ids = std::mem::take(&mut self.ids);
        ids.clear();
        ids.extend(
            self.vehicles
                .keys()
                .filter(|id| !self.bodies.iter().any(|(b, body)| b == *id && !body.walker)),
        );
        for &id in &ids {
            self.unregister(id);
        }
        ids.clear();
        ids.extend(self.vehicles.keys());
        for &id in &ids {
            let Some(&(_, body)) = self.bodies.iter().find(|(b, _)| *b == id) else {
                continue;
            };
            let params = parameters.vehicles.get(&id);
            let control = self.drive(lanes, id, body, lights, (time, delta), parameters, params);
            out.push(control);
        }
        self.ids = ids;
    }

    /// One vehicle's control.
    #[allow(clippy::too_many_arguments)]
    fn drive(
        &mut self,
        lanes: &Lanes,
        id: u32,
        body: Body,
        lights: &HashMap<u32, LightState>,
        (time, delta): (f64, f64),
        parameters: &Parameters,
        params: Option<&VehicleParameters>,
    ) -> Control {
        let defaults = VehicleParameters::default();
        let p = params.unwrap_or(&defaults);
        let globals = &parameters.globals;
        let hold = Control {
            vehicle: id,
            throttle: 0.0,
            steer: 0.0,
            brake: 1.0,
            lights: p.update_lights.then_some(BRAKE_LIGHT),
        };
        let Some(driven) = self.vehicles.get_mut(&id) else {
            return hold;
        };
        if !follow(lanes, driven, &body) {
            return hold;
        }
        let speed = body.speed();
        let horizon = (12.0 + speed.max(0.0) * 3.5).min(60.0);
        extend(lanes, driven, horizon + 20.0);
        let offset = -f64::from(p.lane_offset.unwrap_or(globals.lane_offset));
        sample(lanes, driven, offset, horizon + 20.0, &mut self.samples);
        let samples = &self.samples;
        // Speed limit signs passed.
        let lane = driven.lanes[0];
        for &(at, kmh) in lanes.limits(lane) {
            if driven.progress >= at && driven.progress < at + 5.0 {
                driven.limit = kmh;
            }
        }
        let base = match p.desired_speed {
            Some(kmh) => f64::from(kmh),
            None => {
                let pct = f64::from(p.speed_difference.unwrap_or(globals.speed_difference));
                driven.limit * (1.0 - pct / 100.0)
            }
        }
        .max(0.0)
            / 3.6;
        let mut target = base;
        // Curves: slow enough to take each, braking comfortably before it.
        for (i, s) in samples.iter().enumerate() {
            let Some(next) = samples.get(i + 3) else {
                break;
            };
            let curvature = wrap(next.pose.hdg - s.pose.hdg).abs() / (next.along - s.along);
            if curvature > 1e-3 {
                let allowed = (LATERAL_ACCELERATION / curvature).sqrt();
                let reach =
                    (allowed * allowed + 2.0 * COMFORT_DECELERATION * s.along.max(0.0)).sqrt();
                target = target.min(reach);
            }
        }
        // Where it must stop: the nearest of these, metres ahead.
        let mut stop_at = f64::INFINITY;
        let roll = |rng: &mut ChaCha8Rng, pct: f32| pct > 0.0 && rng.random_range(0.0..100.0) < pct;
        // Signals on the lanes ahead.
        let mut ahead = -driven.progress;
        let mut junction_entry: Option<(f64, f64)> = None;
        let mut blinker = 0;
        for (k, &l) in driven.lanes.iter().enumerate() {
            if ahead > horizon {
                break;
            }
            if k > 0 && junction_entry.is_none() && lanes.junction(l).is_some() {
                junction_entry = Some((ahead, ahead + lanes.length(l)));
                let turn = lanes.turn(l);
                if ahead < 30.0 && turn.abs() > 0.5 {
                    blinker = if turn > 0.0 {
                        LEFT_BLINKER
                    } else {
                        RIGHT_BLINKER
                    };
                }
            }
            for line in lanes.stops(l) {
                // To the front bumper: it stops before the line.
                let d = ahead + line.progress - body.half_length;
                if d < -0.5 {
                    continue;
                }
                if line.light {
                    let state = lights
                        .get(&line.signal)
                        .copied()
                        .unwrap_or(LightState::Green);
                    let must = match state {
                        LightState::Red => true,
                        // Stop if it can, comfortably or nearly so.
                        LightState::Yellow => speed * speed / (2.0 * d.max(0.1)) < 6.0,
                        LightState::Green | LightState::Off => false,
                    };
                    if must && !roll(&mut driven.rng, p.running_light) {
                        stop_at = stop_at.min(d);
                    }
                } else if let Some(junction) = line.junction {
                    let served = driven
                        .stop
                        .is_some_and(|s| s.signal == line.signal && s.served);
                    if served || roll(&mut driven.rng, p.running_sign) {
                        continue;
                    }
                    if d < STOP_MARGIN + 2.0 && speed.abs() < AT_REST {
                        let queue = self.queues.entry(junction).or_default();
                        if !queue.contains(&id) {
                            queue.push(id);
                        }
                        let since = match driven.stop {
                            Some(s) if s.signal == line.signal => s.since,
                            _ => time,
                        };
                        driven.stop = Some(StopSign {
                            signal: line.signal,
                            junction,
                            since,
                            served: false,
                        });
                        let first = queue.first() == Some(&id);
                        let clear = junction_clear(lanes, junction, id, &self.bodies);
                        if first && clear && time - since >= STOP_SIGN_WAIT {
                            driven.stop = Some(StopSign {
                                served: true,
                                ..driven.stop.unwrap_or(StopSign {
                                    signal: line.signal,
                                    junction,
                                    since,
                                    served: true,
                                })
                            });
                            continue;
                        }
                    }
                    stop_at = stop_at.min(d);
                }
            }
            ahead += lanes.length(l);
        }
        // A served stop sign's junction is left: out of its queue.
        if let Some(s) = driven.stop {
            let inside = lanes.junction(lane) == Some(s.junction);
            let waiting = lanes.stops(lane).iter().any(|l| l.signal == s.signal);
            if s.served && !inside && !waiting {
                driven.stop = None;
                if let Some(queue) = self.queues.get_mut(&s.junction) {
                    queue.retain(|&v| v != id);
                }
            }
        }
        // Vehicles and walkers on the way.
        let distance = f64::from(p.distance.unwrap_or(globals.distance)).max(0.0);
        let ignore_vehicles = roll(&mut driven.rng, p.ignore_vehicles);
        let ignore_walkers = roll(&mut driven.rng, p.ignore_walkers);
        let mut blocked_after_junction = false;
        for &(other_id, other) in &self.bodies {
            if other_id == id
                || p.ignored.contains(&other_id)
                || (other.walker && ignore_walkers)
                || (!other.walker && ignore_vehicles)
            {
                continue;
            }
            let reach = horizon + body.half_length + other.half_length.max(other.half_width) + 2.0;
            if (other.x - body.x).hypot(other.y - body.y) > reach {
                continue;
            }
            let Some((along, dir)) = on_way(samples, &other, body.half_width) else {
                continue;
            };
            let gap = along - body.half_length - other.half_length;
            if gap < -body.half_length {
                continue;
            }
            let other_speed = (other.vx * dir.cos() + other.vy * dir.sin()).max(0.0);
            // The distance kept, and half a second more at speed.
            let room = gap - distance - HEADWAY * speed.max(0.0);
            let allowed = if room >= 0.0 {
                (other_speed * other_speed + 2.0 * COMFORT_DECELERATION * room).sqrt()
            } else {
                (other_speed + room).max(0.0)
            };
            target = target.min(allowed);
            if gap - distance < 0.5 && other_speed < 0.5 {
                stop_at = stop_at.min(gap - distance + STOP_MARGIN);
            }
            if let Some((entry, exit)) = junction_entry {
                let after = along - exit;
                if entry > 0.5
                    && after > 0.0
                    && after < 2.0 * body.half_length + distance + 2.0
                    && other_speed < 2.0
                {
                    blocked_after_junction = true;
                }
            }
        }
        if blocked_after_junction {
            if let Some((entry, _)) = junction_entry {
                stop_at = stop_at.min(entry);
            }
        }
        if stop_at.is_finite() {
            let room = (stop_at - STOP_MARGIN).max(0.0);
            target = target.min((2.0 * COMFORT_DECELERATION * room).sqrt());
        }
        // Steering: pure pursuit of a point ahead on the way.
        let look = (2.0 + 0.45 * speed.abs()).clamp(3.5, 9.0);
        let aim = samples
            .iter()
            .find(|s| s.along >= look)
            .or(samples.last())
            .map_or(Pose2::new(body.x, body.y, body.hdg), |s| s.pose);
        let alpha = wrap((aim.y - body.y).atan2(aim.x - body.x) - body.hdg);
        let distance_to_aim = (aim.x - body.x).hypot(aim.y - body.y).max(1.0);
        let wheelbase = 1.2 * body.half_length;
        let angle = (2.0 * wheelbase * alpha.sin() / distance_to_aim).atan();
        let steer = (angle / MAX_STEER).clamp(-1.0, 1.0);
        // Speed: an acceleration towards the target, braking at once for
        // a stop that needs more than comfort.
        let error = target - speed;
        let mut acceleration = (1.2 * error).clamp(-FULL_DECELERATION, FULL_ACCELERATION);
        if stop_at.is_finite() && speed > 0.0 {
            let room = (stop_at - STOP_MARGIN).max(0.05);
            let needed = speed * speed / (2.0 * room);
            if needed > COMFORT_DECELERATION {
                acceleration = acceleration.min(-needed);
            }
        }
        let (throttle, brake) = if target < 0.05 && speed < 0.5 {
            driven.integral = 0.0;
            (0.0, 1.0)
        } else if acceleration >= -0.3 {
            driven.integral = (driven.integral + error * delta).clamp(-5.0, 20.0);
            let throttle = acceleration / FULL_ACCELERATION + 0.05 + 0.03 * driven.integral;
            // Pulling away gently, and never lifting the nose: a light car
            // at full throttle from rest would rear up (traction control).
            let gentle = LAUNCH_THROTTLE + LAUNCH_GAIN * speed.max(0.0);
            let throttle = if body.nose_up > MAX_NOSE_UP {
                0.0
            } else {
                throttle.min(gentle)
            };
            (throttle.clamp(0.0, 1.0), 0.0)
        } else {
            driven.integral = 0.0;
            (0.0, (-acceleration / FULL_DECELERATION).clamp(0.0, 1.0))
        };
        tracing::trace!(
            id,
            lane = ?driven.lanes.first(),
            progress = driven.progress,
            speed,
            target,
            stop_at,
            throttle,
            brake,
            "drives"
        );
        let mut flags = blinker;
        if brake > 0.1 {
            flags |= BRAKE_LIGHT;
        }
        Control {
            vehicle: id,
            throttle: throttle as f32,
            steer: steer as f32,
            brake: brake as f32,
            lights: p.update_lights.then_some(flags),
        }
    }
}

mod way;

#[cfg(test)]
mod tests;
