//! The second pass over a recording: restores the chosen keyframe, rolls
//! forward to the first replayed frame, then hands out frames one by one,
//! applying the recorded commands and episodes before each.

use std::collections::VecDeque;

use shared_types::{ActorState, FrameHeader, ReplayMode, SensorSpec};
use simbus_recording::{Entry, RecordedEvent, RecordingReader};

use super::selection::Selection;
use super::{episode_of, episode_world, recorded_plan, restore, ReplayError};
use crate::clock::Clock;
use crate::scene::Scene;
use crate::world::World;

/// A recorded frame.
#[derive(Debug, Clone)]
struct Recorded {
    log_ns: u64,
    header: FrameHeader,
    actors: Vec<ActorState>,
    /// The world already holds this frame's state (the keyframe's own frame).
    applied: bool,
}

/// A frame the cursor produced.
#[derive(Debug)]
pub(crate) struct Interpolated {
    pub(crate) log_ns: u64,
    pub(crate) header: FrameHeader,
    pub(crate) actors: Vec<ActorState>,
    /// Resimulate: the first (frame, actor) that differs from the recording.
    pub(crate) mismatch: Option<(u64, u64)>,
}

/// A recorded sensor that appeared or ended (by its recorded id).
#[derive(Debug, Clone, Copy)]
pub(crate) enum SensorChange {
    Spawned(u64, SensorSpec),
    Ended(u64),
}

/// Reads a recording forward.
#[derive(Debug)]
pub(crate) struct Cursor {
    reader: RecordingReader,
    seed: u64,
    /// Entries read ahead: commands and events, then (last) the next frame.
    buffer: VecDeque<Entry>,
    /// The next frame, when it is the keyframe's own (already in the world).
    first: Option<Recorded>,
    /// Interpolate: the latest frame at or before the replay time.
    previous: Option<Recorded>,
    /// Interpolate: frames handed out and the last elapsed time.
    produced: u64,
    last_elapsed_ns: u64,
    first_frame: u64,
    done: bool,
    /// Recorded sensors that appeared or ended since last taken.
    pub(crate) sensor_changes: Vec<SensorChange>,
    /// Recorded frames passed since the replay began (not counting the
    /// roll forward to its start).
    pub(crate) passed: u64,
}

/// A recording read up to its chosen keyframe.
struct AtKeyframe {
    /// The keyframe's world and clock.
    world: World,
    clock: Clock,
    /// The scene the keyframe names.
    scene: String,
    /// The recorded sensors alive at the keyframe.
    alive: Vec<(u64, SensorSpec)>,
    /// The frame before the keyframe (its own: the world holds it).
    last_frame: Option<Recorded>,
}

/// Reads `reader` up to keyframe number `keyframe` and restores it.
fn seek_keyframe(reader: &mut RecordingReader, keyframe: u64) -> Result<AtKeyframe, ReplayError> {
    let mut keyframes = 0;
    let mut alive: Vec<(u64, SensorSpec)> = Vec::new();
    let mut last_frame: Option<Recorded> = None;
    loop {
        match reader.next() {
            None => return Err(ReplayError::NoKeyframe),
            Some(Err(e)) => return Err(e.into()),
            Some(Ok(Entry::Frame {
                log_ns,
                header,
                actors,
            })) => {
                last_frame = Some(Recorded {
                    log_ns,
                    header,
                    actors,
                    applied: true,
                })
            }
            Some(Ok(Entry::Sensor(sensor))) => alive.push((sensor.id, sensor.spec)),
            Some(Ok(Entry::Event(RecordedEvent::SensorEnded { id, .. }))) => {
                alive.retain(|(alive, _)| *alive != id)
            }
            Some(Ok(Entry::Keyframe { data, .. })) => {
                if keyframes == keyframe {
                    let (world, clock, scene) = restore(&data).map_err(ReplayError::Keyframe)?;
                    return Ok(AtKeyframe {
                        world,
                        clock,
                        scene,
                        alive,
                        last_frame,
                    });
                }
                keyframes += 1;
            }
            Some(Ok(_)) => {}
        }
    }
}

impl Cursor {
    /// Restores `selection`'s keyframe from `reader` and rolls forward to
    /// its first frame; returns the cursor and the world, clock and scene
    /// the replay starts from.
    pub(crate) fn start(
        mut reader: RecordingReader,
        selection: &Selection,
        mode: ReplayMode,
    ) -> Result<(Self, World, Clock, Scene), ReplayError> {
        let AtKeyframe {
            mut world,
            clock,
            scene,
            alive,
            last_frame,
        } = seek_keyframe(&mut reader, selection.keyframe)?;
        let scene: Scene = scene.parse().map_err(ReplayError::KeyframeScene)?;
        let mut cursor = Self {
            reader,
            seed: selection.seed,
            buffer: VecDeque::new(),
            first: None,
            previous: None,
            produced: 0,
            last_elapsed_ns: 0,
            first_frame: selection.first_frame,
            done: false,
            sensor_changes: Vec::new(),
            passed: 0,
        };
        if selection.keyframe_index == selection.first_index {
            cursor.first = last_frame;
        }
        let clock = cursor.roll_forward(&mut world, clock, selection, mode)?;
        cursor.sensors_alive_at_start(alive);
        cursor.passed = 0;
        Ok((cursor, world, clock, scene))
    }

    /// Rolls the world (not published) forward from the keyframe to just
    /// before the first replayed frame; returns the clock there.
    fn roll_forward(
        &mut self,
        world: &mut World,
        mut clock: Clock,
        selection: &Selection,
        mode: ReplayMode,
    ) -> Result<Clock, ReplayError> {
        // The index of the last frame the world holds.
        let mut index = selection.keyframe_index;
        while index + 1 < selection.first_index && self.first.is_none() {
            self.fill()?;
            let Some(frame) = self.take(world)? else {
                return Err(ReplayError::EndedBeforeStart);
            };
            if mode == ReplayMode::Resimulate {
                step(world, &frame)?;
            }
            clock = Clock::at_timestamp(&frame.header.timestamp, std::time::Instant::now());
            index += 1;
        }
        Ok(clock)
    }

    /// The sensors alive at the first replayed frame (`alive` at the
    /// keyframe, and what changed while rolling forward) appear with it.
    fn sensors_alive_at_start(&mut self, mut alive: Vec<(u64, SensorSpec)>) {
        for change in std::mem::take(&mut self.sensor_changes) {
            match change {
                SensorChange::Spawned(id, spec) => alive.push((id, spec)),
                SensorChange::Ended(id) => alive.retain(|(alive, _)| *alive != id),
            }
        }
        self.sensor_changes = alive
            .into_iter()
            .map(|(id, spec)| SensorChange::Spawned(id, spec))
            .collect();
    }

    /// Reads until the buffer ends with a frame (or the file ends).
    fn fill(&mut self) -> Result<(), ReplayError> {
        if self.first.is_some() || matches!(self.buffer.back(), Some(Entry::Frame { .. })) {
            return Ok(());
        }
        while !self.done {
            match self.reader.next() {
                None => self.done = true,
                Some(Err(e)) => return Err(e.into()),
                Some(Ok(entry)) => {
                    let frame = matches!(entry, Entry::Frame { .. });
                    if matches!(
                        entry,
                        Entry::Command(_)
                            | Entry::Event(_)
                            | Entry::Sensor(_)
                            | Entry::Frame { .. }
                    ) {
                        self.buffer.push_back(entry);
                    }
                    if frame {
                        break;
                    }
                }
            }
        }
        Ok(())
    }

    /// The recording time of the next frame, if there is one.
    pub(crate) fn next_log_ns(&mut self) -> Option<u64> {
        if let Some(first) = &self.first {
            return Some(first.log_ns);
        }
        self.fill().ok()?;
        match self.buffer.back() {
            Some(Entry::Frame { log_ns, .. }) => Some(*log_ns),
            _ => None,
        }
    }

    /// Whether the file has no frame left.
    pub(crate) fn exhausted(&mut self) -> bool {
        self.next_log_ns().is_none()
    }

    /// Applies the buffered commands and episodes to `world` and takes the
    /// frame that follows them.
    fn take(&mut self, world: &mut World) -> Result<Option<Recorded>, ReplayError> {
        if let Some(first) = self.first.take() {
            self.passed += 1;
            return Ok(Some(first));
        }
        self.fill()?;
        while let Some(entry) = self.buffer.pop_front() {
            if let Some((scene, first_id)) = episode_of(&entry) {
                *world = episode_world(scene, self.seed, first_id)?.0;
                continue;
            }
            match entry {
                Entry::Command(recorded) => {
                    world.apply(&recorded.command);
                }
                Entry::Sensor(sensor) => self
                    .sensor_changes
                    .push(SensorChange::Spawned(sensor.id, sensor.spec)),
                Entry::Event(RecordedEvent::SensorEnded { id, .. }) => {
                    self.sensor_changes.push(SensorChange::Ended(id))
                }
                Entry::Frame {
                    log_ns,
                    header,
                    actors,
                } => {
                    self.passed += 1;
                    return Ok(Some(Recorded {
                        log_ns,
                        header,
                        actors,
                        applied: false,
                    }));
                }
                _ => {}
            }
        }
        Ok(None)
    }

    /// The next recorded frame: exact sets the world to it; resimulate
    /// steps the world and compares.
    pub(crate) fn next_recorded(
        &mut self,
        world: &mut World,
        mode: ReplayMode,
    ) -> Result<Option<Interpolated>, ReplayError> {
        let Some(frame) = self.take(world)? else {
            return Ok(None);
        };
        let mut mismatch = None;
        let actors = if mode == ReplayMode::Resimulate {
            if !frame.applied {
                step(world, &frame)?;
            }
            let actors = world.states();
            if bytemuck::cast_slice::<ActorState, u8>(&actors)
                != bytemuck::cast_slice::<ActorState, u8>(&frame.actors)
            {
                let actor = actors
                    .iter()
                    .zip(&frame.actors)
                    .find(|(a, b)| a != b)
                    .map_or(0, |(a, _)| a.id);
                let actor = if actors.len() == frame.actors.len() {
                    actor
                } else {
                    0
                };
                mismatch = Some((frame.header.timestamp.frame, actor));
            }
            actors
        } else {
            world.set_states(&frame.actors);
            frame.actors
        };
        Ok(Some(Interpolated {
            log_ns: frame.log_ns,
            header: frame.header,
            actors,
            mismatch,
        }))
    }

    /// The recorded states interpolated at recording time `at` (position
    /// linear, rotation slerp, velocities linear), set into `world`.
    pub(crate) fn interpolated(
        &mut self,
        world: &mut World,
        at: u64,
    ) -> Result<Option<Interpolated>, ReplayError> {
        loop {
            match self.next_log_ns() {
                Some(log_ns) if log_ns <= at || self.previous.is_none() => {
                    let frame = self.take(world)?;
                    self.previous = frame.or(self.previous.take());
                }
                _ => break,
            }
        }
        let more = self.next_log_ns().is_some();
        let Some(previous) = &self.previous else {
            return Ok(None);
        };
        if self.produced > 0 && !more && at > previous.log_ns {
            return Ok(None);
        }
        let next = match self.buffer.back() {
            Some(Entry::Frame {
                log_ns,
                header,
                actors,
            }) if header.episode == previous.header.episode && *log_ns > previous.log_ns => {
                Some((*log_ns, actors.as_slice()))
            }
            _ => None,
        };
        let at = at.max(previous.log_ns);
        let actors: Vec<ActorState> = match next {
            Some((next_ns, next_actors)) => {
                let alpha = ((at - previous.log_ns) as f64 / (next_ns - previous.log_ns) as f64)
                    .min(1.0) as f32;
                previous
                    .actors
                    .iter()
                    .map(
                        |a| match next_actors.binary_search_by_key(&a.id, |b| b.id) {
                            Ok(i) => interpolate(a, &next_actors[i], alpha),
                            Err(_) => *a,
                        },
                    )
                    .collect()
            }
            None => previous.actors.clone(),
        };
        let elapsed_ns = previous
            .header
            .timestamp
            .elapsed_ns
            .saturating_add(at - previous.log_ns);
        let mut header = previous.header;
        header.timestamp.frame = self.first_frame.saturating_add(self.produced);
        header.timestamp.delta_ns = if self.produced == 0 {
            0
        } else {
            elapsed_ns.saturating_sub(self.last_elapsed_ns)
        };
        header.timestamp.elapsed_ns = elapsed_ns;
        header.physics_substeps = 0;
        header.actor_count = actors.len() as u32;
        self.produced += 1;
        self.last_elapsed_ns = elapsed_ns;
        world.set_states(&actors);
        Ok(Some(Interpolated {
            log_ns: at,
            header,
            actors,
            mismatch: None,
        }))
    }
}

/// Steps `world` through a recorded frame as the recording's server did.
/// The world came from a file: should rapier panic on it anyway, the
/// replay fails instead of the server.
fn step(world: &mut World, frame: &Recorded) -> Result<(), ReplayError> {
    if frame.header.physics_substeps == 0 {
        return Ok(());
    }
    let plan = recorded_plan(&frame.header);
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| world.step(&plan))).map_err(|_| {
        ReplayError::Physics {
            frame: frame.header.timestamp.frame,
        }
    })
}

/// `a` moved `alpha` of the way to `b`.
fn interpolate(a: &ActorState, b: &ActorState, alpha: f32) -> ActorState {
    use rapier3d::prelude::{Rotation, Vector};
    let lerp = |x: [f32; 3], y: [f32; 3]| {
        Vector::from_array(x)
            .lerp(Vector::from_array(y), alpha)
            .to_array()
    };
    let [ax, ay, az, aw] = a.rotation;
    let [bx, by, bz, bw] = b.rotation;
    let rotation =
        Rotation::from_xyzw(ax, ay, az, aw).slerp(Rotation::from_xyzw(bx, by, bz, bw), alpha);
    ActorState {
        position: lerp(a.position, b.position),
        rotation: rotation.to_array(),
        linear_velocity: lerp(a.linear_velocity, b.linear_velocity),
        angular_velocity: lerp(a.angular_velocity, b.angular_velocity),
        ..*a
    }
}
