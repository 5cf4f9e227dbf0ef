//! The signals of a network: traffic lights on the approaches of its
//! four-way junctions (one group per junction, cycling), stop signs on
//! the stems of its T junctions and speed-limit signs, each where CARLA's
//! towns put theirs: beside the lane it speaks to, at its stop line.
//!
//! The same list places the server's light and sign actors and writes
//! the OpenDRIVE `<signal>` records CARLA's client reads as landmarks,
//! so both name the same signals.

use std::f64::consts::PI;

use super::{Contact, Link, Pose2, RoadNetwork, CROSSWALK_WIDTH, LANE_WIDTH};

/// How far past its lane's outer edge a light or sign stands, metres:
/// over the sidewalk's middle, clear of the widest vehicles (a bus's
/// side reaches 3.7 m from the road's centre line) and high enough for
/// walkers to pass under.
pub const KERB_OFFSET: f64 = 1.0;
/// A light head's centre above the road, metres: walkers pass under it.
pub const LIGHT_HEIGHT: f64 = 3.0;
/// A light head's half extents: along the traffic, up, across, metres.
pub const LIGHT_HALF_EXTENTS: [f64; 3] = [0.2, 0.5, 0.2];
/// A sign plate's centre above the road, metres.
pub const SIGN_HEIGHT: f64 = 2.4;
/// A sign plate's half extents: along the traffic, up, across, metres.
pub const SIGN_HALF_EXTENTS: [f64; 3] = [0.03, 0.35, 0.35];
/// How far before its stop line a vehicle is at a light or stop sign,
/// metres: the length of the trigger volume along the lane.
pub const TRIGGER_LENGTH: f64 = 6.0;
/// How far a speed-limit sign stands from the junction its road leaves,
/// metres.
const SPEED_SIGN_DISTANCE: f64 = 8.0;

/// What a signal is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SignalKind {
    /// A traffic light (OpenDRIVE type 1000001, CARLA's
    /// `traffic.traffic_light`).
    TrafficLight,
    /// A stop sign (type 206, `traffic.stop`).
    Stop,
    /// A speed limit in km/h (type 274, `traffic.speed_limit.<km/h>`).
    SpeedLimit(u32),
}

/// One signal, on the side of the lane whose traffic it speaks to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Signal {
    /// Its id: the OpenDRIVE `<signal>`'s, 1 and up in list order.
    pub id: u32,
    /// What it is.
    pub kind: SignalKind,
    /// The road it stands on.
    pub road: u32,
    /// The lane it faces (`-1`: traffic along the road; `1`: against).
    pub lane: i32,
    /// Its station on the road: for a light or a stop sign the stop line.
    pub s: f64,
    /// Its lateral offset from the road's reference line (left positive).
    pub t: f64,
    /// The junction a light or stop sign guards.
    pub junction: Option<u32>,
    /// A light's place in its junction's group, 0 and up (CARLA's pole
    /// index): the order in which the group turns them green.
    pub pole: u32,
    /// Where it stands on the ground, heading as the traffic it faces
    /// drives (OpenDRIVE's axes).
    pub pose: Pose2,
    /// The centre of its lane at the stop line, heading as the traffic.
    pub stop: Pose2,
}

impl Signal {
    /// OpenDRIVE's orientation: `+` for traffic along the road, `-`
    /// against it.
    pub fn orientation(&self) -> &'static str {
        if self.lane < 0 {
            "+"
        } else {
            "-"
        }
    }

    /// Its head's or plate's centre height above the road, metres.
    pub fn height(&self) -> f64 {
        match self.kind {
            SignalKind::TrafficLight => LIGHT_HEIGHT,
            _ => SIGN_HEIGHT,
        }
    }

    /// Its head's or plate's half extents: along the traffic, up, across.
    pub fn half_extents(&self) -> [f64; 3] {
        match self.kind {
            SignalKind::TrafficLight => LIGHT_HALF_EXTENTS,
            _ => SIGN_HALF_EXTENTS,
        }
    }

    /// Whether point `(x, y)` (OpenDRIVE's axes) is in its trigger volume:
    /// on its lane, within [`TRIGGER_LENGTH`] before the stop line.
    pub fn triggers(&self, x: f64, y: f64) -> bool {
        let (sin, cos) = self.stop.hdg.sin_cos();
        let (dx, dy) = (x - self.stop.x, y - self.stop.y);
        let along = dx * cos + dy * sin;
        let across = -dx * sin + dy * cos;
        (-TRIGGER_LENGTH..=0.0).contains(&along) && across.abs() <= LANE_WIDTH / 2.0
    }

    /// The centre of its trigger volume and its half extents (along the
    /// lane, across it, metres).
    pub fn trigger(&self) -> (Pose2, [f64; 2]) {
        let (sin, cos) = self.stop.hdg.sin_cos();
        let back = TRIGGER_LENGTH / 2.0;
        let centre = Pose2::new(
            self.stop.x - back * cos,
            self.stop.y - back * sin,
            self.stop.hdg,
        );
        (centre, [back, LANE_WIDTH / 2.0])
    }
}

/// One approach to a junction: the lane that enters it and where.
#[derive(Debug, Clone, Copy)]
struct Approach {
    road: u32,
    lane: i32,
    /// The road's station at the junction.
    s: f64,
    /// The road's reference pose there, heading out of the junction.
    out: Pose2,
}

impl RoadNetwork {
    /// The approaches of junction `id`, counter-clockwise round it from
    /// east.
    fn approaches(&self, id: u32) -> Vec<Approach> {
        let mut approaches: Vec<Approach> = self
            .roads
            .iter()
            .filter(|r| r.junction.is_none())
            .flat_map(|road| {
                let ends = [
                    (road.predecessor, Contact::Start),
                    (road.successor, Contact::End),
                ];
                ends.into_iter()
                    .filter(move |(link, _)| *link == Some(Link::Junction(id)))
                    .map(move |(_, contact)| match contact {
                        Contact::Start => Approach {
                            road: road.id,
                            lane: 1,
                            s: 0.0,
                            out: road.start,
                        },
                        Contact::End => {
                            let end = road.pose_at(road.length());
                            Approach {
                                road: road.id,
                                lane: -1,
                                s: road.length(),
                                out: Pose2::new(end.x, end.y, end.hdg + PI),
                            }
                        }
                    })
            })
            .collect();
        approaches.sort_by(|a, b| {
            let angle = |p: &Approach| (p.out.hdg - PI).rem_euclid(2.0 * PI);
            angle(a).total_cmp(&angle(b))
        });
        approaches
    }

    /// Adds a signal of `kind` for `lane` of `road` at station `s`.
    fn add_signal(
        &mut self,
        kind: SignalKind,
        road: u32,
        lane: i32,
        s: f64,
        junction: Option<u32>,
    ) {
        let r = &self.roads[road as usize];
        let reference = r.pose_at(s);
        let side = f64::from(lane.signum());
        let t = side * (LANE_WIDTH + KERB_OFFSET);
        let heading = if lane < 0 {
            reference.hdg
        } else {
            reference.hdg + PI
        };
        let ground = reference.lateral(t);
        let centre = reference.lateral(side * LANE_WIDTH / 2.0);
        let pole = match kind {
            SignalKind::TrafficLight => self
                .signals
                .iter()
                .filter(|g| g.junction == junction && g.kind == SignalKind::TrafficLight)
                .count() as u32,
            _ => 0,
        };
        self.signals.push(Signal {
            id: self.signals.len() as u32 + 1,
            kind,
            road,
            lane,
            s,
            t,
            junction,
            pole,
            pose: Pose2::new(ground.x, ground.y, heading),
            stop: Pose2::new(centre.x, centre.y, heading),
        });
    }

    /// The stop line of an approach: before the crosswalk.
    fn stop_station(approach: &Approach) -> f64 {
        if approach.lane < 0 {
            approach.s - CROSSWALK_WIDTH
        } else {
            approach.s + CROSSWALK_WIDTH
        }
    }

    /// A traffic light on every approach of junction `id`, one group.
    pub(super) fn add_lights(&mut self, id: u32) {
        for approach in self.approaches(id) {
            let s = Self::stop_station(&approach);
            self.add_signal(
                SignalKind::TrafficLight,
                approach.road,
                approach.lane,
                s,
                Some(id),
            );
        }
    }

    /// A stop sign on the approach of junction `id` that meets no other
    /// head on (a T junction's stem).
    pub(super) fn add_stop_on_stem(&mut self, id: u32) {
        let approaches = self.approaches(id);
        let opposite = |a: &Approach| {
            approaches.iter().any(|b| {
                let turn = (a.out.hdg - b.out.hdg).rem_euclid(2.0 * PI);
                (turn - PI).abs() < 1e-6
            })
        };
        for approach in approaches.iter().filter(|a| !opposite(a)) {
            let s = Self::stop_station(approach);
            self.add_signal(SignalKind::Stop, approach.road, approach.lane, s, Some(id));
        }
    }

    /// A speed-limit sign of `kmh` on each lane of `road`, a little after
    /// the junction each lane leaves.
    pub(super) fn add_speed_limits(&mut self, road: u32, kmh: u32) {
        let length = self.roads[road as usize].length();
        if length < 2.0 * SPEED_SIGN_DISTANCE {
            return;
        }
        self.add_signal(
            SignalKind::SpeedLimit(kmh),
            road,
            -1,
            SPEED_SIGN_DISTANCE,
            None,
        );
        self.add_signal(
            SignalKind::SpeedLimit(kmh),
            road,
            1,
            length - SPEED_SIGN_DISTANCE,
            None,
        );
    }

    /// The traffic lights of junction `id`, in pole order.
    pub fn lights_of(&self, id: u32) -> impl Iterator<Item = &Signal> {
        self.signals
            .iter()
            .filter(move |s| s.kind == SignalKind::TrafficLight && s.junction == Some(id))
    }

    /// The light or stop sign whose trigger volume holds point `(x, y)`
    /// (OpenDRIVE's axes) for traffic heading `hdg` (radians): a vehicle
    /// there is at it.
    pub fn signal_at(&self, x: f64, y: f64, hdg: f64) -> Option<&Signal> {
        self.signals.iter().find(|s| {
            !matches!(s.kind, SignalKind::SpeedLimit(_))
                && s.triggers(x, y)
                && (hdg - s.stop.hdg).cos() > 0.0
        })
    }
}
