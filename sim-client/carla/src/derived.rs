//! CARLA's cameras the gateway computes from a simbus camera's captures:
//! `sensor.camera.normals` and `sensor.camera.optical_flow` from a depth
//! camera, `sensor.camera.dvs` from an RGB camera, and
//! `sensor.camera.cosmos_visualization` from a semantic camera. Each
//! forwarder of such a sensor keeps what its camera needs from frame to
//! frame (a DVS camera's last brightness, the last capture's time).

use std::collections::HashMap;

use rmpv::Value;
use shared_types::{ActorKind, SemanticTag, SensorKind, SensorSpec};
use sim_client::Capture;

use crate::stream::ActorInfo;
use crate::wire as carla;

/// The sensor type ids of 0.9.16's registry.
const NORMALS_SENSOR_TYPE: u64 = 2;
const DVS_SENSOR_TYPE: u64 = 3;
const OPTICAL_FLOW_SENSOR_TYPE: u64 = 8;
const COSMOS_SENSOR_TYPE: u64 = 16;

/// The time a first capture's motion spans, seconds (no previous one).
const FIRST_FRAME_SECONDS: f64 = 0.05;

/// A CARLA camera computed from another.
#[derive(Debug)]
pub(crate) enum Derived {
    /// Surface normals from a depth image.
    Normals,
    /// Each pixel's motion over the last frame from a depth image, the
    /// camera's motion and the actors' velocities.
    OpticalFlow { last_ns: Option<u64> },
    /// Brightness-change events from an RGB image.
    Dvs(Dvs),
    /// Cosmos's control colours from a semantic image.
    Cosmos,
}

/// A DVS camera's settings (CARLA's attributes) and last brightness.
#[derive(Debug)]
pub(crate) struct Dvs {
    positive: f32,
    negative: f32,
    use_log: bool,
    log_eps: f32,
    refractory_ns: u64,
    /// Each pixel's reference brightness and its last event's time.
    reference: Vec<f32>,
    last_event: Vec<i64>,
    last_ns: Option<u64>,
}

impl Derived {
    /// The derived camera of blueprint `id` (with `attribute` reading its
    /// attributes), if it is one.
    pub(crate) fn of(id: &str, attribute: impl Fn(&str) -> Option<f32>) -> Option<Self> {
        Some(match id {
            "sensor.camera.normals" => Self::Normals,
            "sensor.camera.optical_flow" => Self::OpticalFlow { last_ns: None },
            "sensor.camera.cosmos_visualization" => Self::Cosmos,
            "sensor.camera.dvs" => Self::Dvs(Dvs {
                positive: attribute("positive_threshold").unwrap_or(0.3),
                negative: attribute("negative_threshold").unwrap_or(0.3),
                use_log: attribute("use_log").is_none_or(|v| v != 0.0),
                log_eps: attribute("log_eps").unwrap_or(0.001),
                refractory_ns: attribute("refractory_period_ns").unwrap_or(0.0).max(0.0) as u64,
                reference: Vec::new(),
                last_event: Vec::new(),
                last_ns: None,
            }),
            _ => return None,
        })
    }

    /// The simbus camera blueprint `id` is computed from.
    pub(crate) fn source(id: &str) -> Option<SensorKind> {
        match id {
            "sensor.camera.normals" | "sensor.camera.optical_flow" => Some(SensorKind::Depth),
            "sensor.camera.dvs" => Some(SensorKind::Rgb),
            "sensor.camera.cosmos_visualization" => Some(SensorKind::Semantic),
            _ => None,
        }
    }

    /// CARLA's stream message for `capture` (of a camera built from
    /// `spec`, riding on `parent`), `actors` the world's last.
    pub(crate) fn message(
        &mut self,
        capture: &Capture,
        spec: &SensorSpec,
        parent: Option<&ActorInfo>,
        actors: &HashMap<u32, ActorInfo>,
    ) -> Option<Vec<u8>> {
        let h = capture.header();
        let [w, hgt] = h.size;
        let fov = spec.camera()?.fov;
        let sensor_type = match self {
            Self::Normals => NORMALS_SENSOR_TYPE,
            Self::OpticalFlow { .. } => OPTICAL_FLOW_SENSOR_TYPE,
            Self::Dvs(_) => DVS_SENSOR_TYPE,
            Self::Cosmos => COSMOS_SENSOR_TYPE,
        };
        let pixels = (w as usize) * (hgt as usize);
        let mut out =
            Vec::with_capacity(carla::SENSOR_HEADER_LEN + carla::IMAGE_HEADER_LEN + pixels * 8);
        let transform = crate::convert::transform(h.position, h.rotation);
        let elapsed = shared_types::nanos_to_seconds(h.elapsed_ns);
        carla::sensor_header(&mut out, sensor_type, h.frame, elapsed, transform);
        carla::image_header(&mut out, w, hgt, fov);
        let camera = Intrinsics::new(w, hgt, fov);
        match self {
            Self::Normals => normals(&mut out, capture.depth()?, &camera),
            Self::Cosmos => cosmos(&mut out, capture.bytes()),
            Self::OpticalFlow { last_ns } => {
                let dt = last_ns.map_or(FIRST_FRAME_SECONDS, |t| {
                    h.elapsed_ns.saturating_sub(t) as f64 / 1e9
                });
                *last_ns = Some(h.elapsed_ns);
                let pose = (h.position, h.rotation);
                flow(
                    &mut out,
                    capture.depth()?,
                    &camera,
                    pose,
                    (parent, actors),
                    dt as f32,
                );
            }
            Self::Dvs(dvs) => dvs.events(&mut out, capture.bytes(), (w, hgt), h.elapsed_ns),
        }
        Some(out)
    }
}

/// A camera's image size and focal length: pixel (u, v) looks along
/// (focal, h/2 − v − ½, u + ½ − w/2) in the camera's frame (x forward, y
/// up, z right), as simbus casts it.
struct Intrinsics {
    width: usize,
    height: usize,
    focal: f32,
}

impl Intrinsics {
    fn new(width: u32, height: u32, fov: f32) -> Self {
        Self {
            width: width as usize,
            height: height as usize,
            focal: (width as f32 / 2.0) / (fov.to_radians() / 2.0).tan(),
        }
    }

    /// The camera-frame point at planar depth `d` seen by pixel (u, v).
    fn point(&self, u: usize, v: usize, d: f32) -> [f32; 3] {
        let up = self.height as f32 / 2.0 - v as f32 - 0.5;
        let right = u as f32 + 0.5 - self.width as f32 / 2.0;
        [d, d * up / self.focal, d * right / self.focal]
    }

    /// Where camera-frame point `p` falls: (u, v), continuous, if in front.
    fn project(&self, p: [f32; 3]) -> Option<[f32; 2]> {
        if p[0] <= 1e-4 {
            return None;
        }
        let u = p[2] / p[0] * self.focal + self.width as f32 / 2.0 - 0.5;
        let v = self.height as f32 / 2.0 - 0.5 - p[1] / p[0] * self.focal;
        Some([u, v])
    }
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn conjugate(q: [f32; 4]) -> [f32; 4] {
    [-q[0], -q[1], -q[2], q[3]]
}

/// Surface normals from the neighbours' points, facing the camera, as
/// BGRA: CARLA's camera axes (x forward, y right, z up) mapped from
/// [-1, 1] to [0, 255] in R, G, B. Where nothing was met: facing back.
fn normals(out: &mut Vec<u8>, depth: &[f32], camera: &Intrinsics) {
    let (w, h) = (camera.width, camera.height);
    let at = |u: usize, v: usize| camera.point(u, v, depth[v * w + u]);
    let far = depth.iter().copied().fold(0.0, f32::max);
    for v in 0..h {
        for u in 0..w {
            let d = depth[v * w + u];
            let mut n = [-1.0, 0.0, 0.0];
            if d < far && w > 1 && h > 1 {
                let (l, r) = (u.saturating_sub(1), (u + 1).min(w - 1));
                let (t, b) = (v.saturating_sub(1), (v + 1).min(h - 1));
                let across = sub(at(r, v), at(l, v));
                let down = sub(at(u, b), at(u, t));
                let c = cross(across, down);
                let length = dot(c, c).sqrt();
                if length > 1e-9 {
                    n = c.map(|x| x / length);
                    if dot(n, at(u, v)) > 0.0 {
                        n = n.map(|x| -x);
                    }
                }
            }
            // simbus camera (x forward, y up, z right) → CARLA's.
            let [x, y, z] = [n[0], n[2], n[1]];
            let byte = |c: f32| ((c + 1.0) * 0.5 * 255.0).round().clamp(0.0, 255.0) as u8;
            out.extend_from_slice(&[byte(z), byte(y), byte(x), 255]);
        }
    }
}

/// Cosmos's control colours (`ACosmosControlSensor::CosmosColors`) for
/// a semantic image's tags (in each pixel's red byte); black elsewhere.
fn cosmos(out: &mut Vec<u8>, semantic: &[u8]) {
    use SemanticTag as T;
    let colours: [(&[T], [u8; 3]); 7] = [
        (&[T::Roads], [56, 103, 221]),
        (&[T::RoadLines], [98, 183, 249]),
        (&[T::Poles], [66, 40, 144]),
        (&[T::TrafficSigns], [131, 175, 155]),
        (&[T::TrafficLight], [252, 157, 155]),
        (
            &[T::Car, T::Truck, T::Bus, T::Motorcycle, T::Bicycle],
            [255, 0, 0],
        ),
        (&[T::Pedestrians, T::Rider], [0, 255, 0]),
    ];
    for pixel in semantic.chunks_exact(4) {
        let tag = pixel[2];
        let [r, g, b] = colours
            .iter()
            .find(|(tags, _)| tags.iter().any(|&t| t as u8 == tag))
            .map_or([0, 0, 0], |(_, colour)| *colour);
        out.extend_from_slice(&[b, g, r, 255]);
    }
}

/// Each pixel's motion over the last `dt` seconds, as Unreal's velocity
/// buffer gives CARLA's camera: two floats, the screen-space displacement
/// (x right, y up) with the screen 2 wide and 2 high. The point a pixel
/// sees moves with the actor whose box holds it (its linear and angular
/// velocity), the rest of the world stands; the camera moves with its
/// parent.
fn flow(
    out: &mut Vec<u8>,
    depth: &[f32],
    camera: &Intrinsics,
    (position, rotation): ([f32; 3], [f32; 4]),
    (parent, actors): (Option<&ActorInfo>, &HashMap<u32, ActorInfo>),
    dt: f32,
) {
    let (w, h) = (camera.width, camera.height);
    let far = depth.iter().copied().fold(0.0, f32::max);
    let rotate = simbus_pose::rotate;
    // The camera's own velocity, and its turn rate.
    let (camera_velocity, camera_spin) = parent.map_or(([0.0; 3], [0.0; 3]), |p| {
        let arm = sub(position, p.position);
        let v = cross(p.angular, arm);
        (
            [p.linear[0] + v[0], p.linear[1] + v[1], p.linear[2] + v[2]],
            p.angular,
        )
    });
    // The moving actors, each with its box (simbus's half extents).
    let moving: Vec<&ActorInfo> = actors
        .values()
        .filter(|a| {
            ActorKind::from_u32(a.kind).is_some_and(|k| k.moves())
                && (dot(a.linear, a.linear) > 1e-8 || dot(a.angular, a.angular) > 1e-8)
        })
        .collect();
    let to_world = |p: [f32; 3]| {
        let r = rotate(rotation, p);
        [r[0] + position[0], r[1] + position[1], r[2] + position[2]]
    };
    for v in 0..h {
        for u in 0..w {
            let d = depth[v * w + u];
            let (mut x, mut y) = (0.0f32, 0.0f32);
            if d < far {
                let here = camera.point(u, v, d);
                let world = to_world(here);
                // The point's velocity: that of the actor whose box holds it.
                let velocity = moving
                    .iter()
                    .find(|a| {
                        let local = rotate(conjugate(a.rotation), sub(world, a.position));
                        let half = crate::convert::vector(a.extent);
                        (0..3).all(|i| local[i].abs() <= half[i] + 0.05)
                    })
                    .map_or([0.0; 3], |a| {
                        let spin = cross(a.angular, sub(world, a.position));
                        [
                            a.linear[0] + spin[0],
                            a.linear[1] + spin[1],
                            a.linear[2] + spin[2],
                        ]
                    });
                // Where it was a frame ago, seen from where the camera was.
                let before = [0, 1, 2].map(|i| world[i] - velocity[i] * dt);
                let camera_before = [0, 1, 2].map(|i| position[i] - camera_velocity[i] * dt);
                let turn = [0, 1, 2].map(|i| -camera_spin[i] * dt);
                let angle = dot(turn, turn).sqrt();
                let back = if angle > 1e-9 {
                    let s = (angle / 2.0).sin() / angle;
                    simbus_pose::compose(
                        (
                            [0.0; 3],
                            [turn[0] * s, turn[1] * s, turn[2] * s, (angle / 2.0).cos()],
                        ),
                        ([0.0; 3], rotation),
                    )
                    .1
                } else {
                    rotation
                };
                let seen_before = rotate(conjugate(back), sub(before, camera_before));
                if let (Some(now), Some(then)) = (camera.project(here), camera.project(seen_before))
                {
                    x = 2.0 * (now[0] - then[0]) / w as f32;
                    y = -2.0 * (now[1] - then[1]) / h as f32;
                }
            }
            out.extend_from_slice(&x.to_le_bytes());
            out.extend_from_slice(&y.to_le_bytes());
        }
    }
}

impl Dvs {
    /// The events since the last image, as CARLA's `DVSEventArray`
    /// payload: per pixel, each threshold the brightness crossed since its
    /// reference is an event, at a time between the two images in
    /// proportion (CARLA's simulator, after ESIM), sorted by time.
    fn events(&mut self, out: &mut Vec<u8>, bgra: &[u8], (w, h): (u32, u32), now_ns: u64) {
        let pixels = (w as usize) * (h as usize);
        let brightness = |p: &[u8]| {
            let luma = 0.299 * f32::from(p[2]) + 0.587 * f32::from(p[1]) + 0.114 * f32::from(p[0]);
            if self.use_log {
                (self.log_eps + luma).ln()
            } else {
                luma
            }
        };
        let values: Vec<f32> = bgra.chunks_exact(4).map(brightness).collect();
        let (Some(last_ns), true) = (self.last_ns, self.reference.len() == pixels) else {
            self.reference = values;
            self.last_event = vec![i64::MIN; pixels];
            self.last_ns = Some(now_ns);
            return;
        };
        self.last_ns = Some(now_ns);
        let span = now_ns.saturating_sub(last_ns) as f64;
        let mut events: Vec<(i64, u16, u16, bool)> = Vec::new();
        for (i, &value) in values.iter().enumerate().take(pixels) {
            let start = self.reference[i];
            let change = value - start;
            let (step, polarity) = if change >= 0.0 {
                (self.positive, true)
            } else {
                (-self.negative, false)
            };
            if step == 0.0 {
                continue;
            }
            let mut level = start;
            while (value - level) / step >= 1.0 {
                level += step;
                // Same sign as the change: a fraction of the way.
                let fraction = f64::from((level - start) / change);
                let t = last_ns as i64 + (span * fraction.clamp(0.0, 1.0)) as i64;
                if t.saturating_sub(self.last_event[i]) >= self.refractory_ns as i64 {
                    self.last_event[i] = t;
                    let (x, y) = (i % w as usize, i / w as usize);
                    events.push((t, x as u16, y as u16, polarity));
                }
            }
            self.reference[i] = level;
        }
        events.sort_by_key(|e| e.0);
        for (t, x, y, polarity) in events {
            out.extend_from_slice(&x.to_le_bytes());
            out.extend_from_slice(&y.to_le_bytes());
            out.extend_from_slice(&t.to_le_bytes());
            out.push(u8::from(polarity));
        }
    }
}

/// Reads a number out of a CARLA blueprint record's attribute list
/// (`[uid, id, [[id, type, value], ...]]`).
pub(crate) fn attribute(description: &Value, name: &str) -> Option<f32> {
    let attributes = description.as_array()?.get(2)?.as_array()?;
    let value = attributes.iter().find_map(|a| {
        let a = a.as_array()?;
        (a.first()?.as_str()? == name).then(|| a.get(2)?.as_str().map(str::to_owned))?
    })?;
    match value.to_ascii_lowercase().as_str() {
        "true" => Some(1.0),
        "false" => Some(0.0),
        v => v.parse().ok(),
    }
}
