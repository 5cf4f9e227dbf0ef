//! `sim-client config`: change the time settings, like CARLA's `config.py`.

use std::time::Duration;

use anyhow::anyhow;
use clap::Args;
use shared_types::{WorldName, WorldSettings};
use sim_client::{ApplySettingsError, Client};
use simbus_input as input;

use crate::Failure;

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

    /// Print the settings (after any change).
    #[arg(long)]
    inspect: bool,

    /// Print one JSON object.
    #[arg(long)]
    json: bool,
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
    let mut client = Client::connect(world.as_str(), timeout)?;
    client.set_request_timeout(timeout);
    let current = client.get_settings()?;
    let mut effective_frame = None;
    let mut settings = current;
    if args.changes_anything() {
        settings = args.apply_to(current).map_err(super::refused_or_runtime)?;
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
                .map_err(super::refused_or_runtime)?;
        }
        let left_first = args.no_sync && current.synchronous_mode && settings != only_leaving;
        effective_frame =
            Some(client.apply_settings(settings).map_err(|e| {
                let failure = super::refused_or_runtime(e);
                if !left_first {
                    return failure;
                }
                // Two requests: the first one (leaving synchronous mode) holds.
                let (Failure::Refused(e) | Failure::Runtime(e)) = failure;
                Failure::Runtime(e.context(
                    "the world left synchronous mode, but the other changes were not applied",
                ))
            })?);
    }
    if args.json {
        let mut json = super::settings_json(&settings);
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
        for (name, value) in super::settings_lines(&settings) {
            println!("{name:<9} {value}");
        }
    }
    Ok(())
}
