//! `sim-client config`: change the time settings, like CARLA's `config.py`.

use std::time::Duration;

use anyhow::anyhow;
use clap::{Args, ValueEnum};
use shared_types::{SubstepRule, WorldName, WorldSettings};
use sim_client::ApplySettingsError;
use simbus_input as input;

use crate::cli::failure::Failure;

/// Options of `sim-client config` (described on the command).
#[derive(Debug, Args)]
pub(crate) struct ConfigArgs {
    /// Fixed time-step in seconds: 1e-6..=3600 (0 = variable step).
    #[arg(long, value_name = "S", conflicts_with = "fps", allow_negative_numbers = true, value_parser = input::fixed_delta_seconds)]
    delta_seconds: Option<f64>,

    /// Fixed time-step as frames per simulated second: 0.000277778..=1e6,
    /// a step of 1e-6..=3600 s (0 = variable step).
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = input::fps)]
    fps: Option<f64>,

    /// Leave synchronous mode: the server stops waiting for ticks. Anyone
    /// may; it ends the ticker's ownership, and the ticker's next tick fails
    /// naming this client. (Other changes are the ticker's while it ticks;
    /// given with --no-sync, they are applied once it has left.)
    #[arg(long)]
    no_sync: bool,

    /// Refused: synchronous mode is entered by the tick owner.
    #[arg(long, hide = true, conflicts_with = "no_sync")]
    sync: bool,

    /// One physics step per frame, however long.
    #[arg(long, conflicts_with = "substepping")]
    no_substepping: bool,

    /// Split frames into physics substeps (the default).
    #[arg(long)]
    substepping: bool,

    /// Longest physics substep in seconds (1e-6..=3600).
    #[arg(long, value_name = "S", allow_negative_numbers = true, value_parser = input::max_substep_delta_time)]
    max_substep_delta_time: Option<f64>,

    /// Most physics substeps per frame (1..=16).
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = input::max_substeps)]
    max_substeps: Option<u32>,

    /// What a fixed step longer than max_substeps x max_substep_delta_time
    /// does (with substepping on).
    #[arg(long, value_name = "RULE")]
    substep_rule: Option<SubstepRuleArg>,

    /// Print the settings (after any change).
    #[arg(long)]
    inspect: bool,

    /// Print one JSON object.
    #[arg(long)]
    json: bool,
}

/// `--substep-rule` of `config` and `tick`: the values and their help.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum SubstepRuleArg {
    /// Refuse such a step (simbus's rule; the default).
    Refuse,
    /// CARLA's way: physics advances only max_substeps x
    /// max_substep_delta_time per frame while the frame's time advances the
    /// full step; each such frame is flagged clamped.
    Clamp,
    /// Lengthen the substeps to step / max_substeps, so physics keeps pace
    /// with time (substeps longer than max_substep_delta_time).
    Stretch,
}

impl From<SubstepRuleArg> for SubstepRule {
    fn from(rule: SubstepRuleArg) -> Self {
        match rule {
            SubstepRuleArg::Refuse => Self::Refuse,
            SubstepRuleArg::Clamp => Self::Clamp,
            SubstepRuleArg::Stretch => Self::Stretch,
        }
    }
}

impl ConfigArgs {
    fn changes_anything(&self) -> bool {
        self.delta_seconds.is_some()
            || self.fps.is_some()
            || self.no_sync
            || self.no_substepping
            || self.substepping
            || self.max_substep_delta_time.is_some()
            || self.max_substeps.is_some()
            || self.substep_rule.is_some()
    }

    /// `current` with this command's changes applied.
    fn apply_to(&self, current: WorldSettings) -> Result<WorldSettings, ApplySettingsError> {
        let mut settings = current;
        if let Some(dt) = self.delta_seconds {
            settings.fixed_delta_seconds = Some(dt);
        }
        if let Some(fps) = self.fps {
            settings.fixed_delta_seconds = WorldSettings::delta_from_fps(fps)?;
        }
        if self.no_sync {
            settings.synchronous_mode = false;
        }
        if self.no_substepping {
            settings.substepping = false;
        }
        if self.substepping {
            settings.substepping = true;
        }
        if let Some(dt) = self.max_substep_delta_time {
            settings.max_substep_delta_time = dt;
        }
        if let Some(n) = self.max_substeps {
            settings.max_substeps = n;
        }
        if let Some(rule) = self.substep_rule {
            settings.substep_rule = rule.into();
        }
        settings.validate()?;
        Ok(settings.normalized())
    }
}

pub(crate) fn run(world: &WorldName, timeout: Duration, args: ConfigArgs) -> Result<(), Failure> {
    if args.sync {
        return Err(Failure::Refused(anyhow!(
            "{}",
            ApplySettingsError::SyncNeedsTicker
        )));
    }
    let mut client = super::session::connect(world.as_str(), timeout)?;
    client.set_request_timeout(timeout);
    let current = client.get_settings()?;
    let mut effective_frame = None;
    let mut settings = current;
    if args.changes_anything() {
        settings = args
            .apply_to(current)
            .map_err(super::session::refused_or_runtime)?;
        // Like CARLA's config.py, `--no-sync` with other changes applies
        // them all. While a ticker holds the world only it changes
        // settings, but anyone may leave synchronous mode (which ends its
        // ownership): so leave it first, then change the rest.
        let only_leaving = WorldSettings {
            synchronous_mode: false,
            ..current
        }
        .normalized();
        if args.no_sync && current.synchronous_mode && settings != only_leaving {
            client
                .apply_settings(only_leaving)
                .map_err(super::session::refused_or_runtime)?;
        }
        let left_first = args.no_sync && current.synchronous_mode && settings != only_leaving;
        effective_frame =
            Some(client.apply_settings(settings).map_err(|e| {
                let failure = super::session::refused_or_runtime(e);
                if !left_first {
                    return failure;
                }
                // Two requests: the first one (leaving synchronous mode) holds.
                let (Failure::Refused(e) | Failure::Runtime(e) | Failure::Interrupted(e)) = failure;
                Failure::Runtime(e.context(
                    "the world left synchronous mode, but the other changes were not applied",
                ))
            })?);
    }
    if args.json {
        let mut json = super::describe::settings_json(&settings);
        if let Some(object) = json.as_object_mut() {
            object.insert("world".into(), world.as_str().into());
            object.insert("effective_frame".into(), effective_frame.into());
        }
        println!("{json}");
        return Ok(());
    }
    if let Some(frame) = effective_frame {
        println!("settings applied; they hold from frame {frame}");
        for warning in settings.warnings() {
            println!("warning: {warning}");
        }
    }
    if args.inspect || effective_frame.is_none() {
        for (name, value) in super::describe::settings_lines(&settings) {
            println!("{name:<9} {value}");
        }
    }
    Ok(())
}
