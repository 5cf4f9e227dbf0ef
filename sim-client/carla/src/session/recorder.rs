//! CARLA's recorder calls on simbus's recorder. The `show_*` calls read
//! the file here and answer JSON text (CARLA's answer preformatted text).

use rmpv::Value;

use super::{arg_f64, arg_flag, arg_str, Session};
use crate::error::CallError;
use crate::rpc::Answer;

/// `value` as the JSON text a `show_*` call answers.
fn json(value: &impl serde::Serialize) -> Result<Answer, CallError> {
    let text = serde_json::to_string_pretty(value).unwrap_or_default();
    Ok(Answer::Value(Value::from(text)))
}

/// `n` frames, as people write it: `1 frame`, `2 frames`.
fn frames(n: u64) -> String {
    let s = if n == 1 { "" } else { "s" };
    format!("{n} frame{s}")
}

impl Session {
    pub(super) fn on_start_recorder(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        let name = arg_str(args, 0, "start_recorder")?;
        let sensors = arg_flag(args, 1);
        let path = self
            .client()?
            .start_recorder(&name, sensors)
            .map_err(CallError::simbus)?;
        Ok(Answer::Value(Value::from(
            path.to_string_lossy().into_owned(),
        )))
    }

    pub(super) fn on_stop_recorder(&mut self, _: &[Value]) -> Result<Answer, CallError> {
        self.client()?.stop_recorder().map_err(CallError::simbus)?;
        Ok(Answer::Done)
    }

    pub(super) fn on_replay_file(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        const METHOD: &str = "replay_file";
        let name = arg_str(args, 0, METHOD)?;
        let (start, duration) = (arg_f64(args, 1, METHOD)?, arg_f64(args, 2, METHOD)?);
        let follow = args.get(3).and_then(Value::as_u64).unwrap_or(0);
        let sensors = arg_flag(args, 4);
        let status = self
            .client()?
            .replay_file(&name, start, duration, follow, sensors)
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
        let factor = arg_f64(args, 0, "set_replayer_time_factor")?;
        self.client()?
            .set_replayer_time_factor(factor)
            .map_err(CallError::simbus)?;
        Ok(Answer::Done)
    }

    pub(super) fn on_show_recorder_file_info(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        let name = arg_str(args, 0, "show_recorder_file_info")?;
        let all = arg_flag(args, 1);
        let info =
            simbus_recording::inspect::file_info(&name, all).map_err(CallError::recording)?;
        json(&info)
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
        let list = simbus_recording::inspect::collisions(&name, kind(1), kind(2))
            .map_err(CallError::recording)?;
        json(&list)
    }

    pub(super) fn on_show_recorder_actors_blocked(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        const METHOD: &str = "show_recorder_actors_blocked";
        let name = arg_str(args, 0, METHOD)?;
        let (min_time, min_distance) = (arg_f64(args, 1, METHOD)?, arg_f64(args, 2, METHOD)?);
        let list = simbus_recording::inspect::actors_blocked(&name, min_time, min_distance)
            .map_err(CallError::recording)?;
        json(&list)
    }
}
