//! Per-frame timings for benchmarks: how long rapier's own pipeline step
//! took in each frame, and how long the whole frame took (step, snapshot,
//! publishing and the loop's bookkeeping until the next frame begins).
//!
//! Off unless `Server::time_frames` turns it on: a server that was
//! not asked reads no clock and records nothing (one branch per frame and
//! per substep). Nothing of it goes on the wire.

use std::time::{Duration, Instant};

/// The frames a server timed, in order (see `Server::time_frames`).
#[derive(Debug, Clone)]
pub struct FrameTimings {
    origin: Instant,
    /// When each frame began, in nanoseconds after `origin`.
    starts_ns: Vec<u64>,
    /// rapier's step time in each frame, all substeps, in nanoseconds.
    physics_ns: Vec<u64>,
}

/// One timed frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameTime {
    /// When the server began the frame.
    pub started: Instant,
    /// Time spent inside rapier's pipeline step (every substep), nothing else.
    pub physics: Duration,
    /// From the frame's beginning to the next frame's: the step, the
    /// snapshot, publishing, and the loop's bookkeeping in between.
    pub whole: Duration,
}

impl FrameTimings {
    /// Room for `capacity` frames, reserved now: recording allocates
    /// nothing, and frames beyond `capacity` are not recorded.
    pub(crate) fn new(capacity: usize) -> Self {
        Self {
            origin: Instant::now(),
            starts_ns: Vec::with_capacity(capacity),
            physics_ns: Vec::with_capacity(capacity),
        }
    }

    /// Records a frame that began at `started` and spent `physics` in rapier.
    pub(crate) fn record(&mut self, started: Instant, physics: Duration) {
        if self.starts_ns.len() == self.starts_ns.capacity() {
            return;
        }
        let since = started.saturating_duration_since(self.origin).as_nanos();
        self.starts_ns.push(since as u64);
        self.physics_ns.push(physics.as_nanos() as u64);
    }

    /// Every recorded frame that a later frame followed (the last one has
    /// no end yet), in order.
    pub fn frames(&self) -> impl Iterator<Item = FrameTime> + '_ {
        self.starts_ns
            .windows(2)
            .zip(&self.physics_ns)
            .map(|(starts, &physics)| FrameTime {
                started: self.origin + Duration::from_nanos(starts[0]),
                physics: Duration::from_nanos(physics),
                whole: Duration::from_nanos(starts[1] - starts[0]),
            })
    }
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::AtomicBool;

    use shared_types::{WorldName, WorldSettings};

    use super::*;
    use crate::{Scene, Server, ServerConfig};

    #[test]
    fn a_server_asked_times_each_frame_with_rapier_inside_it() {
        let world = WorldName::new(&format!("timing-unit-{}", std::process::id())).unwrap();
        let config = ServerConfig {
            scene: Scene::Boxes(20),
            settings: WorldSettings {
                fixed_delta_seconds: Some(0.01),
                ..Default::default()
            },
            max_fps: 0.0,
            max_frames: Some(10),
            ..ServerConfig::new(world)
        };
        let mut server = Server::start(config).unwrap();
        assert!(server.frame_timings().is_none(), "off unless asked");
        server.time_frames(64);
        server.run(&AtomicBool::new(false)).unwrap();
        let frames: Vec<FrameTime> = server.frame_timings().unwrap().frames().collect();
        // Ten frames computed; the last has no next beginning yet.
        assert_eq!(frames.len(), 9);
        for pair in frames.windows(2) {
            assert_eq!(pair[0].started + pair[0].whole, pair[1].started);
        }
        assert!(frames
            .iter()
            .all(|f| f.physics > Duration::ZERO && f.physics <= f.whole));
    }

    #[test]
    fn a_frame_lasts_until_the_next_begins_and_the_last_is_left_open() {
        let mut timings = FrameTimings::new(3);
        let t0 = timings.origin;
        for (i, physics) in [5u64, 7, 9, 11].into_iter().enumerate() {
            let started = t0 + Duration::from_micros(100 * i as u64 * i as u64);
            timings.record(started, Duration::from_micros(physics));
        }
        let frames: Vec<FrameTime> = timings.frames().collect();
        // Three recorded (the capacity), the fourth dropped; two closed.
        assert_eq!(frames.len(), 2);
        assert_eq!(frames[0].physics, Duration::from_micros(5));
        assert_eq!(frames[0].whole, Duration::from_micros(100));
        assert_eq!(frames[1].started, t0 + Duration::from_micros(100));
        assert_eq!(frames[1].whole, Duration::from_micros(300));
    }
}
