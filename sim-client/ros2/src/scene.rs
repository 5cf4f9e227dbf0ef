//! A frame's actors for ROS: every pose on `/tf`, vehicles' odometry, and
//! the scene as rviz2 markers (boxes, vehicles, walkers, traffic lights
//! coloured by state).

use shared_types::{ActorKind, ActorState, LightState};

use crate::axes;
use crate::msg::{
    ColorRgba, Covariance, Header, Marker, MarkerArray, Odometry, Pose, PoseWithCovariance,
    TfMessage, Transform, TransformStamped, Twist, TwistWithCovariance, Vector3,
};

/// The fixed frame every pose is given in.
pub(crate) const MAP: &str = "map";

/// `actor`'s pose in `map`.
pub(crate) fn pose(actor: &ActorState) -> Pose {
    Pose {
        position: axes::point(actor.position),
        orientation: axes::quaternion(actor.rotation),
    }
}

/// `/tf` for one frame: each actor's pose in `map`, named by `frame_of`
/// (actors it names `None` are left out: the static ground).
pub(crate) fn transforms<'a>(
    actors: &'a [ActorState],
    elapsed_ns: u64,
    frame_of: impl Fn(&ActorState) -> Option<String> + 'a,
) -> TfMessage {
    TfMessage {
        transforms: actors
            .iter()
            .filter_map(|actor| {
                let child_frame_id = frame_of(actor)?;
                let Pose {
                    position,
                    orientation,
                } = pose(actor);
                Some(TransformStamped {
                    header: Header::new(elapsed_ns, MAP),
                    child_frame_id,
                    transform: Transform {
                        translation: Vector3 {
                            x: position.x,
                            y: position.y,
                            z: position.z,
                        },
                        rotation: orientation,
                    },
                })
            })
            .collect(),
    }
}

/// `v` (world axes) in the body axes of an actor turned by `q`.
fn in_body(q: [f32; 4], v: [f32; 3]) -> [f32; 3] {
    if q == [0.0; 4] {
        return v;
    }
    simbus_pose::rotate([-q[0], -q[1], -q[2], q[3]], v)
}

/// A vehicle's odometry: its pose in `map`, its velocity in its own frame
/// (`child_frame_id`), as REP 105 and `nav_msgs/Odometry` say.
pub(crate) fn odometry(actor: &ActorState, elapsed_ns: u64, child_frame_id: &str) -> Odometry {
    Odometry {
        header: Header::new(elapsed_ns, MAP),
        child_frame_id: child_frame_id.to_owned(),
        pose: PoseWithCovariance {
            pose: pose(actor),
            covariance: Covariance::default(),
        },
        twist: TwistWithCovariance {
            twist: Twist {
                linear: axes::vector3(in_body(actor.rotation, actor.linear_velocity)),
                angular: axes::vector3(in_body(actor.rotation, actor.angular_velocity)),
            },
            covariance: Covariance::default(),
        },
    }
}

/// The colour of a traffic light in `state`.
fn light_colour(state: Option<LightState>) -> ColorRgba {
    let (r, g, b) = match state {
        Some(LightState::Red) => (1.0, 0.0, 0.0),
        Some(LightState::Yellow) => (1.0, 0.8, 0.0),
        Some(LightState::Green) => (0.0, 1.0, 0.0),
        Some(LightState::Off) | None => (0.2, 0.2, 0.2),
    };
    ColorRgba { r, g, b, a: 1.0 }
}

/// One marker per actor (namespace = its kind, id = its id), replacing the
/// last frame's (a `DELETEALL` first, so destroyed actors go).
pub(crate) fn markers(actors: &[ActorState], elapsed_ns: u64) -> MarkerArray {
    let mut markers = vec![Marker {
        header: Header::new(elapsed_ns, MAP),
        action: Marker::DELETEALL,
        ..Marker::default()
    }];
    for actor in actors {
        let Some(kind) = actor.actor_kind() else {
            continue;
        };
        let e = actor.extent;
        // Full sizes in ROS's axes (X forward, Y left, Z up).
        let (shape, scale, color) = match kind {
            ActorKind::Static | ActorKind::Box => (
                Marker::CUBE,
                [2.0 * e[0], 2.0 * e[2], 2.0 * e[1]],
                (0.6, 0.6, 0.6),
            ),
            ActorKind::Vehicle => (
                Marker::CUBE,
                [2.0 * e[0], 2.0 * e[2], 2.0 * e[1]],
                (0.1, 0.4, 0.9),
            ),
            ActorKind::Sphere => (Marker::SPHERE, [2.0 * e[0]; 3], (0.8, 0.5, 0.2)),
            ActorKind::Capsule | ActorKind::Walker => (
                Marker::CYLINDER,
                [2.0 * e[0], 2.0 * e[0], 2.0 * e[1]],
                (0.9, 0.7, 0.3),
            ),
            ActorKind::TrafficLight => {
                let c = light_colour(actor.light().map(|l| l.state));
                (
                    Marker::CUBE,
                    [2.0 * e[0], 2.0 * e[2], 2.0 * e[1]],
                    (c.r, c.g, c.b),
                )
            }
            ActorKind::TrafficSign => (
                Marker::CUBE,
                [2.0 * e[0], 2.0 * e[2], 2.0 * e[1]],
                (0.9, 0.9, 0.9),
            ),
        };
        markers.push(Marker {
            header: Header::new(elapsed_ns, MAP),
            ns: kind.name().to_owned(),
            id: i32::try_from(actor.id).unwrap_or(i32::MAX),
            r#type: shape,
            action: Marker::ADD,
            pose: pose(actor),
            scale: Vector3 {
                x: f64::from(scale[0]),
                y: f64::from(scale[1]),
                z: f64::from(scale[2]),
            },
            color: ColorRgba {
                r: color.0,
                g: color.1,
                b: color.2,
                a: 1.0,
            },
            ..Marker::default()
        });
    }
    MarkerArray { markers }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_vehicle_going_forward_has_a_forward_twist_whichever_way_it_faces() {
        let h = std::f32::consts::FRAC_1_SQRT_2;
        // Facing -Z (left) in simbus, moving that way at 3 m/s.
        let car = ActorState {
            id: 5,
            kind: ActorKind::Vehicle as u32,
            rotation: [0.0, h, 0.0, h],
            linear_velocity: [0.0, 0.0, -3.0],
            ..ActorState::default()
        };
        let odometry = odometry(&car, 1_500_000_000, "vehicle_5");
        let v = odometry.twist.twist.linear;
        assert!(
            (v.x - 3.0).abs() < 1e-6 && v.y.abs() < 1e-6 && v.z.abs() < 1e-6,
            "{v:?}"
        );
        assert_eq!(odometry.header.stamp.sec, 1);
        assert_eq!(odometry.header.stamp.nanosec, 500_000_000);
    }
}
