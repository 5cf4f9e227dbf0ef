//! The first pass over a recording: checks every message (a damaged file
//! is refused before anything changes) and works out which frames a replay
//! covers and which keyframe it starts from.

use std::collections::HashSet;

use shared_types::NANOS_PER_SECOND;
use simbus_recording::{Entry, RecordingReader};

use super::{ReplayError, ReplayRefused};

/// The frames a replay covers.
#[derive(Debug, Clone)]
pub(crate) struct Selection {
    /// Frames to replay.
    pub(crate) frames: u64,
    /// Index (in file order, from 0) of the first replayed frame.
    pub(crate) first_index: u64,
    /// Its frame id.
    pub(crate) first_frame: u64,
    /// Its recording time.
    pub(crate) start_log_ns: u64,
    /// The recording time of the last frame to replay.
    pub(crate) end_log_ns: u64,
    /// Which keyframe (in file order, from 0) to restore.
    pub(crate) keyframe: u64,
    /// The index of the frame that keyframe follows.
    pub(crate) keyframe_index: u64,
    /// That frame's id.
    pub(crate) keyframe_frame: u64,
    /// Every actor id in the recording.
    pub(crate) actor_ids: HashSet<u64>,
    /// Whether some frame was computed with a variable step.
    pub(crate) variable_step: bool,
    /// The recording's seed.
    pub(crate) seed: u64,
}

impl Selection {
    /// Reads `path` through and selects `duration_seconds` (0: to the end)
    /// from `start_seconds` (negative: from the end).
    pub(crate) fn scan(
        path: &str,
        start_seconds: f64,
        duration_seconds: f64,
    ) -> Result<Self, ReplayRefused> {
        let mut reader = RecordingReader::open(path).map_err(ReplayError::from)?;
        let seed = reader.header().seed;
        // (recording time, frame id) of every frame; (keyframe, index of its frame).
        let mut frames: Vec<(u64, u64)> = Vec::new();
        let mut keyframes: Vec<u64> = Vec::new();
        let mut actor_ids = HashSet::new();
        let mut variable_step = false;
        while let Some(entry) = reader.next() {
            match entry.map_err(ReplayError::from)? {
                Entry::Frame {
                    log_ns,
                    header,
                    actors,
                } => {
                    if header.timestamp.delta_ns > 0 && header.settings.fixed_delta_seconds == 0.0 {
                        variable_step = true;
                    }
                    actor_ids.extend(actors.iter().map(|a| a.id));
                    frames.push((log_ns, header.timestamp.frame));
                }
                Entry::Keyframe { .. } => match frames.len().checked_sub(1) {
                    Some(index) => keyframes.push(index as u64),
                    None => return Err(ReplayRefused::KeyframeFirst(path.to_string())),
                },
                _ => {}
            }
        }
        let (Some(&(end_ns, _)), Some(&first_keyframe)) = (frames.last(), keyframes.first()) else {
            return Err(ReplayRefused::NothingToReplay(path.to_string()));
        };
        let seconds = |ns: u64| ns as f64 / NANOS_PER_SECOND as f64;
        let to_ns = |s: f64| (s * NANOS_PER_SECOND as f64).round() as u64;
        let start_ns = if start_seconds < 0.0 {
            end_ns.saturating_sub(to_ns(-start_seconds))
        } else {
            to_ns(start_seconds)
        };
        if start_ns > end_ns {
            return Err(ReplayRefused::StartPastEnd {
                start: start_seconds,
                length: seconds(end_ns),
            });
        }
        let end_log_ns = if duration_seconds == 0.0 {
            end_ns
        } else {
            start_ns.saturating_add(to_ns(duration_seconds)).min(end_ns)
        };
        // Frames are in recording-time order (the log time never goes back).
        let first_index = frames.partition_point(|&(log, _)| log < start_ns) as u64;
        let past_end = frames.partition_point(|&(log, _)| log <= end_log_ns) as u64;
        let keyframe = keyframes
            .partition_point(|&index| index <= first_index)
            .max(1)
            - 1;
        let keyframe_index = keyframes.get(keyframe).copied().unwrap_or(first_keyframe);
        Ok(Self {
            frames: past_end.saturating_sub(first_index),
            first_index,
            first_frame: frames[first_index as usize].1,
            start_log_ns: frames[first_index as usize].0,
            end_log_ns,
            keyframe: keyframe as u64,
            keyframe_index,
            keyframe_frame: frames[keyframe_index as usize].1,
            actor_ids,
            variable_step,
            seed,
        })
    }
}
