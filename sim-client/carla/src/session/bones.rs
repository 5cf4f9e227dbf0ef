//! A walker's bones, approximated: simbus's walker is a capsule with no
//! skeleton, so `get_bones()` answers CARLA's bone names (its pedestrians'
//! skeleton, `crl_*`) in a standing rest pose scaled to the walker's
//! height, placed on the walker as it stands now; `set_bones`,
//! `blend_pose`, `show_pose`, `hide_pose` and `get_pose_from_animation`
//! are accepted and change nothing (the CARLA chapter says so).

use rmpv::Value;
use shared_types::ActorKind;

use super::Session;
use crate::convert;
use crate::error::CallError;
use crate::locks::lock;
use crate::rpc::Answer;

/// The height the rest pose is drawn for, metres.
const REST_HEIGHT: f32 = 1.8;

/// One finger of the rest pose: its name and its knuckle's offset from
/// the hand (forward, right away from the body, down), metres.
const FINGERS: [(&str, f32, f32); 5] = [
    ("Thumb", 0.03, -0.02),
    ("Index", 0.02, 0.0),
    ("Middle", 0.005, 0.0),
    ("Ring", -0.01, 0.0),
    ("Pinky", -0.025, 0.0),
];

/// CARLA's bones of one side (`side` `L` or `R`) in the rest pose: name,
/// parent, and where it is (forward, out to its side, up) from the feet,
/// metres, for a walker [`REST_HEIGHT`] tall.
fn side(side: &str, out: &mut Vec<(String, String, [f32; 3])>) {
    let b = |name: &str| format!("crl_{name}__{side}");
    let mut push = |name: String, parent: String, at: [f32; 3]| out.push((name, parent, at));
    push(b("shoulder"), "crl_spine01__C".into(), [0.0, 0.06, 1.42]);
    push(b("arm"), b("shoulder"), [0.0, 0.19, 1.42]);
    push(b("foreArm"), b("arm"), [0.0, 0.22, 1.14]);
    push(b("hand"), b("foreArm"), [0.0, 0.24, 0.88]);
    for (finger, forward, aside) in FINGERS {
        let mut parent = b("hand");
        for (i, joint) in ["", "01", "02", "End"].into_iter().enumerate() {
            let name = b(&format!("hand{finger}{joint}"));
            let down = 0.04 + 0.025 * i as f32;
            push(name.clone(), parent, [forward, 0.24 + aside, 0.88 - down]);
            parent = name;
        }
    }
    push(b("thigh"), "crl_hips__C".into(), [0.0, 0.09, 0.92]);
    push(b("leg"), b("thigh"), [0.0, 0.10, 0.50]);
    push(b("foot"), b("leg"), [0.0, 0.10, 0.08]);
    push(b("toe"), b("foot"), [0.12, 0.10, 0.02]);
    push(b("toeEnd"), b("toe"), [0.18, 0.10, 0.02]);
    push(b("eye"), "crl_Head__C".into(), [0.09, 0.03, 1.70]);
}

/// The rest pose: every bone with its parent and its place from the
/// feet (forward, right, up), root first, parents before children.
fn rest_pose() -> Vec<(String, String, [f32; 3])> {
    let centre = [
        ("crl_root", "", 0.0),
        ("crl_hips__C", "crl_root", 0.95),
        ("crl_spine__C", "crl_hips__C", 1.05),
        ("crl_spine01__C", "crl_spine__C", 1.30),
        ("crl_neck__C", "crl_spine01__C", 1.50),
        ("crl_Head__C", "crl_neck__C", 1.62),
    ];
    let mut bones: Vec<(String, String, [f32; 3])> = centre
        .iter()
        .map(|&(name, parent, up)| (name.to_owned(), parent.to_owned(), [0.0, 0.0, up]))
        .collect();
    let (mut left, mut right) = (Vec::new(), Vec::new());
    side("L", &mut left);
    side("R", &mut right);
    // CARLA's left is the walker's -y (its y points right).
    bones.extend(left.into_iter().map(|(n, p, [x, y, z])| (n, p, [x, -y, z])));
    bones.extend(right);
    bones
}

/// `[[x, y, z], [pitch, yaw, roll]]`.
fn transform(location: [f32; 3], rotation: [f32; 3]) -> Value {
    let floats = |v: [f32; 3]| Value::Array(v.iter().map(|&x| Value::F32(x)).collect());
    Value::Array(vec![floats(location), floats(rotation)])
}

impl Session {
    /// The walker a bone call names.
    fn walker_arg(&self, args: &[Value], method: &'static str) -> Result<u32, CallError> {
        self.actor_of_kind(args, method, ActorKind::Walker, CallError::NotAWalker)
    }

    /// CARLA's `walker.get_bones()`: every bone's name and its world,
    /// component (from the feet, in the walker's axes) and relative (from
    /// its parent) transforms, in the rest pose on the walker as it stands.
    pub(super) fn on_get_bones_transform(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        let id = self.walker_arg(args, "get_bones_transform")?;
        let walker = lock(&self.hub.actors)
            .get(&id)
            .copied()
            .ok_or(CallError::UnknownActor(id))?;
        let t = convert::transform(walker.position, walker.rotation);
        let half_height = walker.extent[2];
        let scale = 2.0 * half_height / REST_HEIGHT;
        let (sin, cos) = t.rotation[1].to_radians().sin_cos();
        let bones = rest_pose();
        let place = |name: &str| {
            bones
                .iter()
                .find(|b| b.0 == name)
                .map_or([0.0; 3], |b| b.2.map(|v| v * scale))
        };
        let out = bones
            .iter()
            .map(|(name, parent, _)| {
                let [forward, right, up] = place(name);
                let world = [
                    t.location[0] + forward * cos - right * sin,
                    t.location[1] + forward * sin + right * cos,
                    t.location[2] - half_height + up,
                ];
                let from = place(parent);
                let relative = [forward - from[0], right - from[1], up - from[2]];
                Value::Array(vec![
                    Value::from(name.as_str()),
                    transform(world, [0.0, t.rotation[1], 0.0]),
                    transform([forward, right, up], [0.0; 3]),
                    transform(relative, [0.0; 3]),
                ])
            })
            .collect();
        Ok(Answer::Value(Value::Array(vec![Value::Array(out)])))
    }

    /// CARLA's `set_bones`, `blend_pose` (also what `show_pose` and
    /// `hide_pose` send) and `get_pose_from_animation`: accepted on a
    /// walker; simbus's has no skeleton to pose.
    pub(super) fn on_pose(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        self.walker_arg(args, "set_bones_transform / blend_pose")?;
        Ok(Answer::Done)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rest_pose_has_carlas_bones_each_after_its_parent() {
        let bones = rest_pose();
        for (i, (name, parent, _)) in bones.iter().enumerate() {
            assert!(name.starts_with("crl_"), "{name}");
            if i > 0 {
                assert!(
                    bones[..i].iter().any(|b| &b.0 == parent),
                    "{name} before {parent}"
                );
            }
        }
        let names: Vec<&str> = bones.iter().map(|b| b.0.as_str()).collect();
        for name in [
            "crl_hips__C",
            "crl_Head__C",
            "crl_handPinkyEnd__L",
            "crl_toeEnd__R",
            "crl_eye__L",
        ] {
            assert!(names.contains(&name), "{name}");
        }
        // The left hand on the walker's left (CARLA's -y), the head on top.
        let at = |n: &str| bones.iter().find(|b| b.0 == n).unwrap().2;
        assert!(at("crl_hand__L")[1] < 0.0 && at("crl_hand__R")[1] > 0.0);
        assert!(bones.iter().all(|b| b.2[2] <= at("crl_eye__L")[2]));
    }
}
