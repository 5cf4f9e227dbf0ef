//! Settings and lockstep participants as people and scripts read them.

use shared_types::{SubstepRule, WorldSettings};
use simbus_input::Readable;

/// A lockstep participant as `status` and `top` print it: its window,
/// how far behind the world it is, and how long it made its last frame
/// wait.
pub(crate) fn participant_line(p: &sim_client::ParticipantStatus) -> String {
    let behind = match p.lag {
        None => "no report in this episode yet".to_owned(),
        Some(0) => format!("done with frame {}, the latest", p.done_frame),
        Some(lag) => format!(
            "done with frame {}, {} behind",
            p.done_frame,
            super::words::count(lag, "frame")
        ),
    };
    let wait = p.done_after.map_or_else(String::new, |d| {
        format!(" ({:.0} µs after it was published)", d.as_secs_f64() * 1e6)
    });
    format!(
        "{} (pid {}): window {}, {behind}{wait}",
        p.name, p.pid, p.window
    )
}

/// A lockstep participant as `status --json` and `top --json` print it.
pub(crate) fn participant_json(p: &sim_client::ParticipantStatus) -> serde_json::Value {
    serde_json::json!({
        "name": p.name,
        "pid": p.pid,
        "window": p.window,
        "done_frame": p.done_frame,
        // Frames the world is ahead of its last "done" (null: none yet).
        "lag": p.lag,
        // How long after that frame's publication its "done" came (µs):
        // how long it made that step wait at most.
        "done_after_us": p.done_after.map(|d| d.as_secs_f64() * 1e6),
    })
}

/// The settings as the JSON object `status` and `config --json` print.
pub(crate) fn settings_json(settings: &WorldSettings) -> serde_json::Value {
    serde_json::json!({
        "synchronous_mode": settings.synchronous_mode,
        "fixed_delta_seconds": settings.fixed_delta_seconds,
        "substepping": settings.substepping,
        "max_substep_delta_time": settings.max_substep_delta_time,
        "max_substeps": settings.max_substeps,
        "substep_rule": settings.substep_rule.name(),
    })
}

/// The settings as readable lines (seconds to six significant digits;
/// `--json` has them exact).
pub(crate) fn settings_lines(settings: &WorldSettings) -> Vec<(&'static str, String)> {
    vec![
        (
            "mode",
            if settings.synchronous_mode {
                "synchronous (the ticker rules time)".to_owned()
            } else {
                "asynchronous".to_owned()
            },
        ),
        (
            "step",
            match settings.fixed_delta_seconds {
                // Readably: 0.0333333 s (30 FPS), not 0.03333333333333333.
                Some(dt) => format!("fixed {} s ({} FPS)", Readable(dt), Readable(1.0 / dt)),
                None => "variable (follows wall time)".to_owned(),
            },
        ),
        (
            "substeps",
            if settings.substepping {
                format!(
                    "on: at most {} of {} s",
                    settings.max_substeps,
                    Readable(settings.max_substep_delta_time)
                )
            } else {
                "off: one physics step per frame".to_owned()
            },
        ),
        ("rule", substep_rule_line(settings)),
    ]
}

/// The `rule` line of the printed settings: the substep rule and what it
/// does with these settings.
pub(crate) fn substep_rule_line(settings: &WorldSettings) -> String {
    let limit = settings.max_substep_delta_time * f64::from(settings.max_substeps);
    let what = match settings.substep_rule {
        SubstepRule::Refuse => format!("a fixed step over {} s is refused", Readable(limit)),
        SubstepRule::Clamp => format!(
            "CARLA's: physics advances at most {} s per frame",
            Readable(limit)
        ),
        SubstepRule::Stretch => format!(
            "a fixed step over {} s lengthens the substeps",
            Readable(limit)
        ),
    };
    match (settings.substepping, settings.clamps_physics()) {
        (false, _) => format!("{} (no substepping: no effect)", settings.substep_rule),
        (true, false) => format!("{} ({what})", settings.substep_rule),
        (true, true) => format!(
            "{} ({what}: {} s of each {} s frame)",
            settings.substep_rule,
            Readable(limit),
            Readable(settings.fixed_delta_seconds.unwrap_or(0.0))
        ),
    }
}
