//! A driven vehicle's way: where it is on its lanes, the lanes it will
//! take, points along them, what stands on them, and whether a junction
//! is clear to cross.

use rand::RngExt;

use super::super::lanes::{LaneRef, Lanes, OnLane};
use super::super::parameters::Turn;
use super::{Body, Driven, Sample, LOST, PATH_REACHED, SAMPLE_STEP, SIDE_MARGIN};

/// Moves `driven` along its lanes to where `body` is; finds its lane
/// anew when it left them. Whether it is on a lane.
pub(super) fn follow(lanes: &Lanes, driven: &mut Driven, body: &Body) -> bool {
    while let Some(&lane) = driven.lanes.first() {
        match lanes.project_on(lane, body.x, body.y) {
            Some(on) if on.left.abs() <= LOST => {
                if on.progress > lanes.length(lane) && driven.lanes.len() > 1 {
                    driven.lanes.remove(0);
                    continue;
                }
                driven.progress = on.progress;
                return true;
            }
            _ => break,
        }
    }
    match lanes.locate(body.x, body.y, body.hdg) {
        Some(OnLane { lane, progress, .. }) => {
            driven.lanes.clear();
            driven.lanes.push(lane);
            driven.progress = progress;
            true
        }
        None => false,
    }
}

/// Adds lanes to `driven`'s way until it reaches `horizon` metres ahead:
/// at each fork the route's turn, the way to the next path point, or a
/// seeded random pick.
pub(super) fn extend(lanes: &Lanes, driven: &mut Driven, horizon: f64) {
    // Path points reached are done.
    while let Some(&(px, py)) = driven.path.first() {
        let Some(&lane) = driven.lanes.first() else {
            break;
        };
        let here = lanes.point(lane, driven.progress, 0.0);
        if (here.x - px).hypot(here.y - py) < PATH_REACHED {
            driven.path.remove(0);
            driven.lanes.truncate(1);
        } else {
            break;
        }
    }
    let mut ahead: f64 =
        driven.lanes.iter().map(|&l| lanes.length(l)).sum::<f64>() - driven.progress;
    while ahead < horizon {
        let Some(&last) = driven.lanes.last() else {
            return;
        };
        let options = lanes.next(last);
        let chosen = match options {
            [] => return,
            [only] => *only,
            _ => {
                let by_route = driven.route.first().copied().and_then(|turn| {
                    options.iter().copied().find(|&o| {
                        let t = lanes.turn(o);
                        match turn {
                            Turn::Left => t > 0.5,
                            Turn::Right => t < -0.5,
                            Turn::Straight => t.abs() <= 0.5,
                        }
                    })
                });
                if by_route.is_some() {
                    driven.route.remove(0);
                }
                let by_path = driven.path.first().and_then(|&(px, py)| {
                    options.iter().copied().min_by(|&a, &b| {
                        let end = |l: LaneRef| {
                            let e = lanes.point(l, lanes.length(l), 0.0);
                            (e.x - px).hypot(e.y - py)
                        };
                        end(a).total_cmp(&end(b))
                    })
                });
                by_route
                    .or(by_path)
                    .unwrap_or_else(|| options[driven.rng.random_range(0..options.len())])
            }
        };
        driven.lanes.push(chosen);
        ahead += lanes.length(chosen);
    }
}

/// Samples `driven`'s way every [`SAMPLE_STEP`] from where it is, `left`
/// metres left of the lanes' centres, `horizon` metres ahead.
pub(super) fn sample(
    lanes: &Lanes,
    driven: &Driven,
    left: f64,
    horizon: f64,
    out: &mut Vec<Sample>,
) {
    out.clear();
    let mut start = driven.progress.max(0.0);
    let mut along = start - driven.progress;
    for &lane in &driven.lanes {
        let length = lanes.length(lane);
        let mut progress = start;
        while progress < length {
            if along > horizon {
                return;
            }
            out.push(Sample {
                pose: lanes.point(lane, progress, left),
                along,
            });
            progress += SAMPLE_STEP;
            along += SAMPLE_STEP;
        }
        start = progress - length;
    }
}

/// Where `other` is on the way `samples`: how far ahead, and the way's
/// heading there; `None` if it is beside it (a vehicle `half_width` wide
/// passes).
pub(super) fn on_way(samples: &[Sample], other: &Body, half_width: f64) -> Option<(f64, f64)> {
    let nearest = samples.iter().min_by(|a, b| {
        let d = |s: &Sample| (other.x - s.pose.x).powi(2) + (other.y - s.pose.y).powi(2);
        d(a).total_cmp(&d(b))
    })?;
    let (dx, dy) = (other.x - nearest.pose.x, other.y - nearest.pose.y);
    let (sin, cos) = nearest.pose.hdg.sin_cos();
    let across = -dx * sin + dy * cos;
    let forward = dx * cos + dy * sin;
    let band = half_width + other.half_width + SIDE_MARGIN;
    if across.abs() > band || forward.abs() > SAMPLE_STEP + other.half_length.max(other.half_width)
    {
        return None;
    }
    Some((nearest.along + forward, nearest.pose.hdg))
}

/// Whether junction `junction` is clear for vehicle `id` to cross from a
/// stop sign: no other vehicle in it, nor coming at it fast.
pub(super) fn junction_clear(
    lanes: &Lanes,
    junction: u32,
    id: u32,
    bodies: &[(u32, Body)],
) -> bool {
    let Some((cx, cy, radius)) = lanes.junction_area(junction) else {
        return true;
    };
    bodies.iter().all(|&(other_id, b)| {
        if other_id == id || b.walker {
            return true;
        }
        let (dx, dy) = (cx - b.x, cy - b.y);
        let d = dx.hypot(dy);
        if d < radius + b.half_length {
            return false;
        }
        let closing = (b.vx * dx + b.vy * dy) / d.max(1e-6);
        !(d < radius + 25.0 && closing > 1.0)
    })
}
