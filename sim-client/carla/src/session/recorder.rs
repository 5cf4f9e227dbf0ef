//! CARLA's recorder calls on simbus's recorder. The `show_*` calls read
//! the file here and answer CARLA's preformatted text
//! ([`crate::recorder_text`]).

use rmpv::Value;
use shared_types::{ActorKind, RecorderRefusal};
use sim_client::{RecorderError, ReplayOptions};
use simbus_recording::inspect;

use super::{arg_f64, arg_flag, arg_str, Session};
use crate::error::CallError;
use crate::locks::lock;
use crate::recorder_text;
use crate::rpc::Answer;

/// `text` as a `show_*` call answers it.
fn text(text: String) -> Result<Answer, CallError> {
    Ok(Answer::Value(Value::from(text)))
}

/// `n` frames, as people write it: `1 frame`, `2 frames`.
fn frames(n: u64) -> String {
    let s = if n == 1 { "" } else { "s" };
    format!("{n} frame{s}")
}

/// Whether an actor of kind `kind` (its name in a recording) is in CARLA's
/// collision category `category`: `a` any, `v` vehicle, `w` walker, `o`
/// other (anything not a vehicle, walker or traffic light: simbus's boxes,
/// spheres, capsules and static bodies such as the ground), `t` traffic
/// light (simbus has none), `h` hero, and simbus's own letters (see
/// [`inspect::kind_matches`]); any other letter matches nothing.
fn in_category(category: char, kind: &str) -> bool {
    let vehicle = kind == ActorKind::Vehicle.name();
    let walker = kind == ActorKind::Walker.name();
    match category {
        'a' => true,
        'v' => vehicle,
        'w' => walker,
        'o' => !vehicle && !walker,
        // CARLA's hero is the actor whose role_name is "hero". A simbus
        // recording keeps no role_name, so no recorded actor is the hero:
        // 'h' matches nothing.
        'h' | 't' => false,
        _ => ActorKind::from_name(kind).is_some_and(|k| inspect::kind_matches(category, k as u32)),
    }
}

impl Session {
    pub(super) fn on_start_recorder(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        let name = arg_str(args, 0, "start_recorder")?;
        let sensors = arg_flag(args, 1);
        let path = self
            .client()?
            .start_recorder(&name, sensors)
            .map_err(CallError::simbus)?;
        *lock(&self.hub.recording) = Some(path.clone());
        Ok(Answer::Value(Value::from(
            path.to_string_lossy().into_owned(),
        )))
    }

    pub(super) fn on_stop_recorder(&mut self, _: &[Value]) -> Result<Answer, CallError> {
        self.client()?.stop_recorder().map_err(CallError::simbus)?;
        // The type ids of the actors spawned through the gateway go beside
        // the file (a recording keeps kinds only), for whoever reads it
        // later through another gateway.
        if let Some(path) = lock(&self.hub.recording).take() {
            let names = self.type_ids(None);
            if let Err(e) = recorder_text::write_names(&path, &names) {
                tracing::warn!("the recording's type ids were not written beside it: {e}");
            }
        }
        Ok(Answer::Done)
    }

    pub(super) fn on_replay_file(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        const METHOD: &str = "replay_file";
        let name = arg_str(args, 0, METHOD)?;
        let (start, duration) = (arg_f64(args, 1, METHOD)?, arg_f64(args, 2, METHOD)?);
        let options = ReplayOptions {
            start,
            duration,
            follow_id: args.get(3).and_then(Value::as_u64).unwrap_or(0),
            replay_sensors: arg_flag(args, 4),
            // The factor of the session's last set_replayer_time_factor,
            // as CARLA's replayer keeps it for the replays that follow.
            time_factor: self.replay_time_factor,
            ..ReplayOptions::default()
        };
        let status = self
            .client()?
            .replay(&name, &options)
            .map_err(CallError::simbus)?;
        Ok(Answer::Value(Value::from(format!(
            "Replaying {name}: {} ({})",
            frames(status.replay.total),
            status.replay.mode
        ))))
    }

    pub(super) fn on_stop_replayer(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        let keep = arg_flag(args, 0);
        self.client()?
            .stop_replayer(keep)
            .map_err(CallError::simbus)?;
        Ok(Answer::Done)
    }

    pub(super) fn on_set_replayer_time_factor(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        const METHOD: &str = "set_replayer_time_factor";
        let factor = arg_f64(args, 0, METHOD)?;
        if !(factor.is_finite() && factor > 0.0) {
            return Err(CallError::Shape {
                method: METHOD,
                what: "the time factor must be a positive number",
            });
        }
        // Kept for the next replay_file (CARLA's replayer keeps it too).
        self.replay_time_factor = factor;
        match self.client()?.set_replayer_time_factor(factor) {
            Ok(_) => Ok(Answer::Done),
            Err(RecorderError::Refused {
                refusal: RecorderRefusal::NotReplaying,
                ..
            }) => Ok(Answer::Done),
            Err(e) => Err(CallError::simbus(e)),
        }
    }

    pub(super) fn on_show_recorder_file_info(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        let name = arg_str(args, 0, "show_recorder_file_info")?;
        let all = arg_flag(args, 1);
        let names = self.type_ids(Some(&name));
        text(recorder_text::file_info_named(&name, all, &names).map_err(CallError::recording)?)
    }

    pub(super) fn on_show_recorder_collisions(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        let name = arg_str(args, 0, "show_recorder_collisions")?;
        let kind = |i: usize| {
            args.get(i)
                .and_then(Value::as_u64)
                .and_then(|c| char::from_u32(c as u32))
                .unwrap_or('a')
        };
        let (kind1, kind2) = (kind(1), kind(2));
        let keep = |a: &str, b: &str| {
            (in_category(kind1, a) && in_category(kind2, b))
                || (in_category(kind1, b) && in_category(kind2, a))
        };
        let names = self.type_ids(Some(&name));
        text(recorder_text::collisions(&name, keep, &names).map_err(CallError::recording)?)
    }

    /// The type ids of the actors CARLA clients spawned through the
    /// gateway (the recording knows only their kinds), and those written
    /// beside recording `path` when it stopped.
    fn type_ids(&self, path: Option<&str>) -> recorder_text::Names {
        let mut names: recorder_text::Names = lock(&self.hub.registry)
            .descriptions
            .iter()
            .filter_map(|(&id, d)| Some((id, d.as_array()?.get(1)?.as_str()?.to_string())))
            .collect();
        if let Some(path) = path {
            names.extend(recorder_text::read_names(std::path::Path::new(path)));
        }
        names
    }

    pub(super) fn on_show_recorder_actors_blocked(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        const METHOD: &str = "show_recorder_actors_blocked";
        let name = arg_str(args, 0, METHOD)?;
        let (min_time, min_distance) = (arg_f64(args, 1, METHOD)?, arg_f64(args, 2, METHOD)?);
        // CARLA's min_distance is in centimetres; simbus's in metres.
        if !(min_distance.is_finite() && min_distance > 0.0) {
            return Err(CallError::Shape {
                method: METHOD,
                what: "min_distance must be a positive, finite number of centimetres",
            });
        }
        let list = inspect::actors_blocked(&name, min_time, min_distance / 100.0)
            .map_err(CallError::recording)?;
        text(recorder_text::actors_blocked(&name, &list).map_err(CallError::recording)?)
    }
}
