//! The lanes of a road network as the traffic manager drives them: each
//! driving lane in its direction of travel, the lanes it leads into, and
//! where a point is on it (OpenDRIVE's axes throughout).

use std::collections::HashMap;
use std::f64::consts::PI;

use shared_types::roads::{Contact, Link, Pose2, RoadNetwork, Segment, SignalKind, LANE_WIDTH};

/// One driving lane of one road, travelled one way: lane -1 along the
/// road's reference line (s growing), lane 1 against it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct LaneRef {
    /// The road's id (its index in the network).
    pub road: u32,
    /// -1 along the road's reference line, 1 against it.
    pub lane: i32,
}

/// A stop line on a lane: a light's or a stop sign's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StopLine {
    /// The signal's OpenDRIVE id.
    pub signal: u32,
    /// Whether it is a light (else a stop sign).
    pub light: bool,
    /// How far along the lane (in its direction of travel) the line is.
    pub progress: f64,
    /// The junction it guards.
    pub junction: Option<u32>,
}

/// Where a point is on a lane: how far along it (its direction of
/// travel), and how far left of its centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OnLane {
    /// The lane.
    pub lane: LaneRef,
    /// Metres along it, in its direction of travel.
    pub progress: f64,
    /// Metres left of its centre (negative: right).
    pub left: f64,
}

/// A network's lanes, with what the traffic manager looks up per step
/// computed once.
#[derive(Debug)]
pub struct Lanes {
    network: RoadNetwork,
    lengths: Vec<f64>,
    /// Each segment's start (s, pose), per road.
    starts: Vec<Vec<(f64, Pose2)>>,
    next: HashMap<LaneRef, Vec<LaneRef>>,
    stops: HashMap<LaneRef, Vec<StopLine>>,
    /// Speed-limit signs on each lane: (progress, km/h).
    limits: HashMap<LaneRef, Vec<(f64, f64)>>,
    /// Each junction's middle and radius (x, y, metres).
    areas: HashMap<u32, (f64, f64, f64)>,
}

/// `a` wrapped into (-π, π].
pub fn wrap(a: f64) -> f64 {
    let a = a.rem_euclid(2.0 * PI);
    if a > PI {
        a - 2.0 * PI
    } else {
        a
    }
}

impl Lanes {
    /// The lanes of `network`.
    pub fn new(network: RoadNetwork) -> Self {
        let lengths = network.roads.iter().map(|r| r.length()).collect();
        let starts = network.roads.iter().map(|r| r.segment_starts()).collect();
        let mut lanes = Self {
            network,
            lengths,
            starts,
            next: HashMap::new(),
            stops: HashMap::new(),
            limits: HashMap::new(),
            areas: HashMap::new(),
        };
        for junction in &lanes.network.junctions {
            if let Some(area) = area_of(&lanes.network, junction.id) {
                lanes.areas.insert(junction.id, area);
            }
        }
        let all: Vec<LaneRef> = lanes.all().collect();
        for lane in all {
            let next = lanes.successors(lane);
            lanes.next.insert(lane, next);
        }
        for signal in &lanes.network.signals {
            let lane = LaneRef {
                road: signal.road,
                lane: signal.lane,
            };
            let Some(on) = lanes.project_on(lane, signal.stop.x, signal.stop.y) else {
                continue;
            };
            match signal.kind {
                SignalKind::SpeedLimit(kmh) => {
                    let at = lanes.project_on(lane, signal.pose.x, signal.pose.y);
                    let progress = at.map_or(on.progress, |at| at.progress);
                    lanes
                        .limits
                        .entry(lane)
                        .or_default()
                        .push((progress, f64::from(kmh)));
                }
                kind => lanes.stops.entry(lane).or_default().push(StopLine {
                    signal: signal.id,
                    light: kind == SignalKind::TrafficLight,
                    progress: on.progress,
                    junction: signal.junction,
                }),
            }
        }
        lanes
    }

    /// Every driving lane.
    fn all(&self) -> impl Iterator<Item = LaneRef> + '_ {
        self.network.roads.iter().flat_map(|road| {
            road.lanes.iter().map(move |lane| LaneRef {
                road: road.id,
                lane: lane.id,
            })
        })
    }

    /// The road network the lanes are of.
    pub fn network(&self) -> &RoadNetwork {
        &self.network
    }

    /// Every driving lane, in the network's order.
    pub fn lanes(&self) -> impl Iterator<Item = LaneRef> + '_ {
        self.all()
    }

    /// Lane `lane`'s length, metres (its road's reference line).
    pub fn length(&self, lane: LaneRef) -> f64 {
        self.lengths.get(lane.road as usize).copied().unwrap_or(0.0)
    }

    /// The junction lane `lane` crosses, if it is a connecting road's.
    pub fn junction(&self, lane: LaneRef) -> Option<u32> {
        self.network.roads.get(lane.road as usize)?.junction
    }

    /// The lanes lane `lane` leads into, in the network's order.
    pub fn next(&self, lane: LaneRef) -> &[LaneRef] {
        self.next.get(&lane).map_or(&[], Vec::as_slice)
    }

    /// The stop lines on lane `lane`, in the network's order.
    pub fn stops(&self, lane: LaneRef) -> &[StopLine] {
        self.stops.get(&lane).map_or(&[], Vec::as_slice)
    }

    /// The speed-limit signs on lane `lane`: (progress, km/h).
    pub fn limits(&self, lane: LaneRef) -> &[(f64, f64)] {
        self.limits.get(&lane).map_or(&[], Vec::as_slice)
    }

    /// The centre of lane `lane` `progress` metres along it, heading its
    /// way, moved `left` metres to the left.
    pub fn point(&self, lane: LaneRef, progress: f64, left: f64) -> Pose2 {
        let Some(road) = self.network.roads.get(lane.road as usize) else {
            return Pose2::new(0.0, 0.0, 0.0);
        };
        let length = self.length(lane);
        let forward = lane.lane < 0;
        let s = if forward { progress } else { length - progress };
        let reference = road.pose_at(s.clamp(0.0, length));
        let centre = reference.lateral(f64::from(lane.lane.signum()) * LANE_WIDTH / 2.0);
        if forward {
            centre.lateral(left)
        } else {
            Pose2::new(centre.x, centre.y, wrap(centre.hdg + PI)).lateral(left)
        }
    }

    /// Where `(x, y)` is on lane `lane`: `None` past either end by more
    /// than a lane's width.
    pub fn project_on(&self, lane: LaneRef, x: f64, y: f64) -> Option<OnLane> {
        let road = self.network.roads.get(lane.road as usize)?;
        let starts = self.starts.get(lane.road as usize)?;
        let length = self.length(lane);
        let last = road.segments.len().saturating_sub(1);
        let mut best: Option<(f64, f64, f64)> = None;
        for (i, (segment, &(s0, start))) in road.segments.iter().zip(starts).enumerate() {
            let (s, t, off) = project_segment(segment, start, x, y);
            // Before the road's start or past its end, the distance along
            // is kept (a vehicle leaving the lane reads past its end).
            let along = match (i, i == last) {
                (0, true) => s,
                (0, false) => s.min(segment.length()),
                (_, true) => s.max(0.0),
                _ => s.clamp(0.0, segment.length()),
            };
            let error = off + t.abs() * 1e-3;
            if best.is_none_or(|b| error < b.2) {
                best = Some((s0 + along, t, error));
            }
        }
        let (s, t, _) = best?;
        if s < -LANE_WIDTH || s > length + LANE_WIDTH {
            return None;
        }
        let centre = f64::from(lane.lane.signum()) * LANE_WIDTH / 2.0;
        let (progress, left) = if lane.lane < 0 {
            (s, t - centre)
        } else {
            (length - s, centre - t)
        };
        Some(OnLane {
            lane,
            progress,
            left,
        })
    }

    /// The lane a vehicle at `(x, y)` heading `hdg` drives on: the nearest
    /// lane centre within a lane's width whose way is the vehicle's (to
    /// within 60°).
    pub fn locate(&self, x: f64, y: f64, hdg: f64) -> Option<OnLane> {
        let mut best: Option<OnLane> = None;
        for lane in self.all() {
            let Some(on) = self.project_on(lane, x, y) else {
                continue;
            };
            let length = self.length(lane);
            if on.left.abs() > LANE_WIDTH || on.progress < -1.0 || on.progress > length + 1.0 {
                continue;
            }
            let way = self.point(lane, on.progress.clamp(0.0, length), 0.0).hdg;
            if wrap(way - hdg).cos() < 0.5 {
                continue;
            }
            if best.is_none_or(|b| on.left.abs() < b.left.abs()) {
                best = Some(on);
            }
        }
        best
    }

    /// The lanes lane `lane` leads into at its far end.
    fn successors(&self, lane: LaneRef) -> Vec<LaneRef> {
        let Some(road) = self.network.roads.get(lane.road as usize) else {
            return Vec::new();
        };
        let Some(spec) = road.lanes.iter().find(|l| l.id == lane.lane) else {
            return Vec::new();
        };
        let (link, next_lane) = if lane.lane < 0 {
            (road.successor, spec.successor)
        } else {
            (road.predecessor, spec.predecessor)
        };
        match link {
            Some(Link::Road { id, contact }) => {
                let entering = next_lane.unwrap_or(match contact {
                    Contact::Start => -1,
                    Contact::End => 1,
                });
                vec![LaneRef {
                    road: id,
                    lane: entering,
                }]
            }
            Some(Link::Junction(junction)) => self
                .network
                .junctions
                .iter()
                .filter(|j| j.id == junction)
                .flat_map(|j| &j.connections)
                .filter(|c| c.incoming == lane.road && c.from_lane == lane.lane)
                .map(|c| LaneRef {
                    road: c.connecting,
                    lane: -1,
                })
                .collect(),
            None => Vec::new(),
        }
    }

    /// The middle of junction `junction` and how far from it its
    /// connecting roads reach, metres.
    pub fn junction_area(&self, junction: u32) -> Option<(f64, f64, f64)> {
        self.areas.get(&junction).copied()
    }

    /// How much lane `lane` turns from its start to its end, radians
    /// (positive: left).
    pub fn turn(&self, lane: LaneRef) -> f64 {
        let length = self.length(lane);
        wrap(self.point(lane, length, 0.0).hdg - self.point(lane, 0.0, 0.0).hdg)
    }
}

/// The middle of junction `junction` and how far from it its connecting
/// roads reach.
fn area_of(network: &RoadNetwork, junction: u32) -> Option<(f64, f64, f64)> {
    let ends: Vec<Pose2> = network
        .roads
        .iter()
        .filter(|r| r.junction == Some(junction))
        .flat_map(|r| [r.pose_at(0.0), r.pose_at(r.length())])
        .collect();
    if ends.is_empty() {
        return None;
    }
    let n = ends.len() as f64;
    let cx = ends.iter().map(|p| p.x).sum::<f64>() / n;
    let cy = ends.iter().map(|p| p.y).sum::<f64>() / n;
    let radius = ends
        .iter()
        .map(|p| (p.x - cx).hypot(p.y - cy))
        .fold(0.0, f64::max);
    Some((cx, cy, radius))
}

/// Where `(x, y)` is along `segment` starting at `start`: (s, not
/// clamped to the segment; t to the left; the distance from the segment's
/// nearest point).
fn project_segment(segment: &Segment, start: Pose2, x: f64, y: f64) -> (f64, f64, f64) {
    match *segment {
        Segment::Line { length } => {
            let (sin, cos) = start.hdg.sin_cos();
            let (dx, dy) = (x - start.x, y - start.y);
            let s = dx * cos + dy * sin;
            let t = -dx * sin + dy * cos;
            let clamped = s.clamp(0.0, length);
            (s, t, (s - clamped).hypot(t))
        }
        Segment::Arc { length, curvature } => {
            let radius = 1.0 / curvature.abs();
            let centre = start.lateral(1.0 / curvature);
            let (vx, vy) = (x - centre.x, y - centre.y);
            let r = vx.hypot(vy);
            let a0 = (start.y - centre.y).atan2(start.x - centre.x);
            let a = vy.atan2(vx);
            // Swept angle, centred on the arc's middle so a point just
            // before its start reads negative.
            let middle = length / radius / 2.0;
            let swept = wrap((a - a0) * curvature.signum() - middle) + middle;
            let s = swept * radius;
            let t = if curvature > 0.0 {
                radius - r
            } else {
                r - radius
            };
            let clamped = s.clamp(0.0, length);
            (s, t, (s - clamped).abs() + (r - radius).abs())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared_types::scene::SceneName;

    fn town() -> Lanes {
        Lanes::new(shared_types::roads::network(SceneName::Town))
    }

    #[test]
    fn every_point_of_a_lane_projects_back_onto_it() {
        let lanes = town();
        for lane in lanes.all() {
            let length = lanes.length(lane);
            for k in 0..=4 {
                let progress = length * f64::from(k) / 4.0;
                let p = lanes.point(lane, progress, 0.5);
                let on = lanes.project_on(lane, p.x, p.y).unwrap();
                assert!(
                    (on.progress - progress).abs() < 1e-6,
                    "{lane:?} {on:?} {progress}"
                );
                assert!((on.left - 0.5).abs() < 1e-6, "{lane:?} {on:?}");
                let found = lanes.locate(p.x, p.y, p.hdg).unwrap();
                assert!(found.left.abs() <= 0.5 + 1e-6, "{lane:?} {found:?}");
            }
        }
    }

    #[test]
    fn every_lane_leads_somewhere_and_joins_where_it_ends() {
        let lanes = town();
        for lane in lanes.all() {
            let next = lanes.next(lane);
            assert!(!next.is_empty(), "{lane:?} is a dead end");
            let end = lanes.point(lane, lanes.length(lane), 0.0);
            for &n in next {
                let start = lanes.point(n, 0.0, 0.0);
                let gap = (end.x - start.x).hypot(end.y - start.y);
                assert!(gap < 1e-6, "{lane:?} -> {n:?}: {gap} m apart");
                assert!(wrap(end.hdg - start.hdg).abs() < 1e-6, "{lane:?} -> {n:?}");
            }
        }
    }

    #[test]
    fn lights_and_stop_signs_stand_on_the_lanes_entering_junctions() {
        let lanes = town();
        let stops: usize = lanes.stops.values().map(Vec::len).sum();
        assert_eq!(stops, 16 + 8);
        for (lane, lines) in &lanes.stops {
            for line in lines {
                let gap = lanes.length(*lane) - line.progress;
                assert!((0.0..6.0).contains(&gap), "{lane:?} {line:?}");
                assert!(lanes
                    .next(*lane)
                    .iter()
                    .all(|n| lanes.junction(*n).is_some()));
            }
        }
    }
}
