//! The driving task of `simbus.gym`, frame in, numbers out: where each ego
//! vehicle is on its route, what it sees around it, and how its step is
//! rewarded. Pure computation over a frame's actors, the same for the same
//! frames (no clock, no randomness but the seeded route).

use std::f64::consts::PI;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use shared_types::roads::{Pose2, LANE_WIDTH};
use shared_types::{ActorKind, ActorState, LightState};
use simbus_traffic::{wrap, LaneRef, Lanes};

/// Values of the `ego` observation, in order.
pub(crate) const EGO_VALUES: usize = 8;
/// Values per nearby actor: forward, left, forward speed, left speed,
/// walker, present.
pub(crate) const ACTOR_VALUES: usize = 6;
/// Reward terms, in order: progress, collision, lane, off-road, red light.
pub(crate) const REWARD_TERMS: usize = 5;
/// Metres between route points kept.
const ROUTE_STEP: f64 = 1.0;
/// How far ahead of its last point the route search looks, points.
const ROUTE_WINDOW: usize = 40;
/// How far apart the route points the ego observes are, metres.
const ROUTE_LOOK_STEP: f64 = 4.0;
/// Actors farther than this are not observed, metres.
const SEEN_WITHIN: f64 = 50.0;
/// Stop lines farther than this read as this, metres.
const STOP_HORIZON: f64 = 50.0;
/// Off the route's centre by more than this, the ego has left the road.
pub(crate) const OFF_ROAD: f64 = 4.0;
/// An acceleration above this, m/s², is a crash into something (a wall, a
/// kerb at speed) whatever the shapes say.
const CRASH_ACCELERATION: f32 = 60.0;
/// Room added around shapes when testing them for contact, metres.
const CONTACT_MARGIN: f64 = 0.05;

/// What the task is asked to be: sizes and reward weights.
#[derive(Debug, Clone)]
pub(crate) struct TaskSpec {
    /// Nearby actors observed per ego.
    pub(crate) actors: usize,
    /// Route points observed per ego.
    pub(crate) route_points: usize,
    /// Route length, metres.
    pub(crate) route_length: f64,
    /// Weights of the reward terms.
    pub(crate) weights: [f32; REWARD_TERMS],
    /// Whether a collision ends the episode.
    pub(crate) end_on_collision: bool,
}

impl TaskSpec {
    /// Floats of one ego's observation row.
    pub(crate) fn row(&self) -> usize {
        EGO_VALUES + self.actors * ACTOR_VALUES + self.route_points * 2
    }
}

/// A body in OpenDRIVE's axes.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Flat {
    pub(crate) x: f64,
    pub(crate) y: f64,
    pub(crate) hdg: f64,
    pub(crate) vx: f64,
    pub(crate) vy: f64,
    half: [f64; 2],
}

impl Flat {
    /// `actor` seen from above (OpenDRIVE's x east, y north).
    pub(crate) fn of(actor: &ActorState) -> Self {
        let forward = simbus_pose::rotate(actor.rotation, [1.0, 0.0, 0.0]);
        let [ex, _, ez] = actor.extent;
        let half = match actor.actor_kind() {
            Some(ActorKind::Sphere | ActorKind::Capsule | ActorKind::Walker) => {
                [f64::from(ex), f64::from(ex)]
            }
            _ => [f64::from(ex), f64::from(ez)],
        };
        Self {
            x: f64::from(actor.position[0]),
            y: -f64::from(actor.position[2]),
            hdg: f64::from(-forward[2]).atan2(f64::from(forward[0])),
            vx: f64::from(actor.linear_velocity[0]),
            vy: -f64::from(actor.linear_velocity[2]),
            half,
        }
    }

    /// Speed along its heading, m/s.
    pub(crate) fn speed(&self) -> f64 {
        self.vx * self.hdg.cos() + self.vy * self.hdg.sin()
    }

    /// `(x, y)` in this body's frame: (forward, left).
    fn local(&self, x: f64, y: f64) -> (f64, f64) {
        let (dx, dy) = (x - self.x, y - self.y);
        let (s, c) = self.hdg.sin_cos();
        (dx * c + dy * s, -dx * s + dy * c)
    }

    /// Whether the footprints of `self` and `other` overlap (separating
    /// axes of two rectangles).
    fn touches(&self, other: &Flat) -> bool {
        let axes = [
            self.hdg,
            self.hdg + PI / 2.0,
            other.hdg,
            other.hdg + PI / 2.0,
        ];
        axes.iter().all(|&a| {
            let (s, c) = a.sin_cos();
            let reach = |b: &Flat| {
                let (bs, bc) = (b.hdg - a).sin_cos();
                (b.half[0] * bc).abs() + (b.half[1] * bs).abs() + CONTACT_MARGIN
            };
            let gap = ((other.x - self.x) * c + (other.y - self.y) * s).abs();
            gap <= reach(self) + reach(other)
        })
    }
}

/// One ego's way: points every metre along the lanes it will drive, and
/// the stop lines on it.
#[derive(Debug, Default)]
pub(crate) struct Route {
    points: Vec<Pose2>,
    /// (route index of the line, signal id, is a light).
    stops: Vec<(usize, u32, bool)>,
    /// The point the ego was last nearest.
    at: usize,
}

impl Route {
    /// `length` metres of lanes from where `start` is, a seeded way at
    /// each junction.
    pub(crate) fn plan(lanes: &Lanes, start: Pose2, length: f64, rng: &mut ChaCha8Rng) -> Self {
        let mut route = Route::default();
        let Some(on) = lanes.locate(start.x, start.y, start.hdg) else {
            return route;
        };
        let (mut lane, mut progress) = (on.lane, on.progress.max(0.0));
        let mut travelled = 0.0;
        while travelled < length {
            let lane_length = lanes.length(lane);
            for stop in lanes.stops(lane) {
                if stop.progress >= progress {
                    let index = route.points.len()
                        + ((stop.progress - progress) / ROUTE_STEP).round() as usize;
                    route.stops.push((index, stop.signal, stop.light));
                }
            }
            while progress <= lane_length && travelled < length {
                route.points.push(lanes.point(lane, progress, 0.0));
                progress += ROUTE_STEP;
                travelled += ROUTE_STEP;
            }
            let next = lanes.next(lane);
            if next.is_empty() {
                break;
            }
            lane = next[rng.random_range(0..next.len())];
            progress -= lane_length;
        }
        route
    }

    /// Moves the ego's place on the route to the nearest point ahead
    /// (searched from the last); returns metres advanced, the signed
    /// distance left of the route and the heading error.
    fn advance(&mut self, ego: &Flat) -> (f64, f64, f64) {
        let end = (self.at + ROUTE_WINDOW).min(self.points.len());
        let start = self.at.saturating_sub(2);
        let mut best = self.at.min(self.points.len().saturating_sub(1));
        let mut best_d = f64::INFINITY;
        for (i, p) in self.points.iter().enumerate().take(end).skip(start) {
            let d = (p.x - ego.x).powi(2) + (p.y - ego.y).powi(2);
            if d < best_d {
                best_d = d;
                best = i;
            }
        }
        let advanced = (best as f64 - self.at as f64) * ROUTE_STEP;
        self.at = best;
        let Some(p) = self.points.get(best) else {
            return (0.0, 0.0, 0.0);
        };
        let (s, c) = p.hdg.sin_cos();
        let left = -(ego.x - p.x) * s + (ego.y - p.y) * c;
        (advanced, left, wrap(ego.hdg - p.hdg))
    }

    /// Whether the ego is at the route's end.
    fn done(&self) -> bool {
        self.at + 2 >= self.points.len()
    }
}

/// One ego's state between steps.
#[derive(Debug, Default)]
pub(crate) struct Ego {
    pub(crate) id: u64,
    pub(crate) route: Route,
    /// Its last action: steer, throttle minus brake.
    pub(crate) last: [f32; 2],
    /// The actors near it in the last frame (distance, body, walker).
    pub(crate) near: Vec<(f64, Flat, bool)>,
}

/// One ego's step: its reward terms and how the episode goes on.
#[derive(Debug, Default, Clone, Copy)]
pub(crate) struct Outcome {
    pub(crate) terms: [f32; REWARD_TERMS],
    pub(crate) terminated: bool,
    pub(crate) collided: bool,
}

/// A seeded generator for an episode (the route's way, the traffic's).
pub(crate) fn episode_rng(seed: u64, salt: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed ^ salt.wrapping_mul(0x9e37_79b9_7f4a_7c15))
}

/// Writes `ego`'s observation of `actors` into `row` (`spec.row()` floats)
/// and returns its step's outcome. `lights` says what each signal shows.
pub(crate) fn observe(
    spec: &TaskSpec,
    ego: &mut Ego,
    actors: &[ActorState],
    lights: &std::collections::HashMap<u32, LightState>,
    row: &mut [f32],
) -> Outcome {
    row.fill(0.0);
    let mut outcome = Outcome::default();
    let Some(me) = actors.iter().find(|a| a.id == ego.id) else {
        outcome.terminated = true;
        return outcome;
    };
    let body = Flat::of(me);
    let before = ego.route.at;
    let (advanced, left, heading) = ego.route.advance(&body);
    // The next stop line ahead on the route and whether it was crossed on red.
    let mut stop_distance = STOP_HORIZON;
    let mut stop_red = 0.0;
    for &(index, signal, light) in &ego.route.stops {
        let state = lights.get(&signal).copied();
        let red = !light || matches!(state, Some(LightState::Red));
        if light && index > before && index <= ego.route.at && red {
            outcome.terms[4] = -1.0;
        }
        if index > ego.route.at {
            let distance = (index - ego.route.at) as f64 * ROUTE_STEP;
            if distance < STOP_HORIZON {
                stop_distance = distance;
                stop_red = if red { 1.0 } else { 0.0 };
            }
            break;
        }
    }
    let ego_values = [
        body.speed() as f32,
        left as f32,
        heading as f32,
        ego.last[0],
        ego.last[1],
        stop_distance as f32,
        stop_red,
        (simbus_speed_limit() / 3.6) as f32,
    ];
    row[..EGO_VALUES].copy_from_slice(&ego_values);
    // The nearest actors that move (vehicles, walkers, dynamic bodies).
    // Kept in the ego between steps: the hot path allocates nothing.
    let mut near = std::mem::take(&mut ego.near);
    near.clear();
    near.extend(
        actors
            .iter()
            .filter(|a| a.id != ego.id && moves(a))
            .map(|a| {
                let f = Flat::of(a);
                let d = ((f.x - body.x).powi(2) + (f.y - body.y).powi(2)).sqrt();
                (d, f, a.actor_kind() == Some(ActorKind::Walker))
            })
            .filter(|(d, _, _)| *d <= SEEN_WITHIN),
    );
    near.sort_by(|a, b| a.0.total_cmp(&b.0));
    outcome.collided = me.acceleration.iter().map(|a| a * a).sum::<f32>().sqrt()
        > CRASH_ACCELERATION
        || near.iter().any(|(_, f, _)| body.touches(f));
    let slots =
        row[EGO_VALUES..EGO_VALUES + spec.actors * ACTOR_VALUES].chunks_exact_mut(ACTOR_VALUES);
    for (slot, (_, f, walker)) in slots.zip(&near) {
        let (fwd, lft) = body.local(f.x, f.y);
        let (s, c) = body.hdg.sin_cos();
        let (dvx, dvy) = (f.vx - body.vx, f.vy - body.vy);
        slot.copy_from_slice(&[
            fwd as f32,
            lft as f32,
            (dvx * c + dvy * s) as f32,
            (-dvx * s + dvy * c) as f32,
            if *walker { 1.0 } else { 0.0 },
            1.0,
        ]);
    }
    let route_row = &mut row[EGO_VALUES + spec.actors * ACTOR_VALUES..];
    let step = (ROUTE_LOOK_STEP / ROUTE_STEP) as usize;
    for (k, slot) in route_row.chunks_exact_mut(2).enumerate() {
        let index = ego.route.at + (k + 1) * step;
        let Some(p) = ego
            .route
            .points
            .get(index.min(ego.route.points.len().saturating_sub(1)))
        else {
            break;
        };
        let (fwd, lft) = body.local(p.x, p.y);
        slot.copy_from_slice(&[fwd as f32, lft as f32]);
    }
    ego.near = near;
    outcome.terms[0] = advanced as f32;
    outcome.terms[1] = if outcome.collided { -1.0 } else { 0.0 };
    outcome.terms[2] = -((left.abs() - LANE_WIDTH / 2.0).max(0.0) as f32);
    let off_road = left.abs() > OFF_ROAD;
    outcome.terms[3] = if off_road { -1.0 } else { 0.0 };
    outcome.terminated =
        off_road || ego.route.done() || (spec.end_on_collision && outcome.collided);
    outcome
}

/// The speed limit every simbus road has, km/h.
fn simbus_speed_limit() -> f64 {
    shared_types::roads::SPEED_LIMIT_KMH
}

/// Whether an actor moves (and so is worth observing).
fn moves(actor: &ActorState) -> bool {
    actor.actor_kind().is_some_and(|k| k.moves())
}

/// The reward of `terms` under `weights`.
pub(crate) fn reward(terms: &[f32; REWARD_TERMS], weights: &[f32; REWARD_TERMS]) -> f32 {
    terms.iter().zip(weights).map(|(t, w)| t * w).sum()
}

/// A pose on a lane as a simbus position and rotation, `up` metres above
/// the road.
pub(crate) fn placed(pose: Pose2, up: f32) -> ([f32; 3], [f32; 4]) {
    let half = pose.hdg / 2.0;
    (
        [pose.x as f32, up, -pose.y as f32],
        [0.0, half.sin() as f32, 0.0, half.cos() as f32],
    )
}

/// The places egos and traffic may start: every lane's points every
/// `spacing` metres, away from junctions.
pub(crate) fn start_places(lanes: &Lanes, spacing: f64) -> Vec<(LaneRef, f64)> {
    let mut places = Vec::new();
    for lane in lanes.lanes() {
        if lanes.junction(lane).is_some() {
            continue;
        }
        let length = lanes.length(lane);
        let mut p = spacing / 2.0;
        while p + spacing / 2.0 <= length {
            places.push((lane, p));
            p += spacing;
        }
    }
    places
}
