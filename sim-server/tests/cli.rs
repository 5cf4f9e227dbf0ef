//! The `sim-server` command line: help that explains, and bad start settings
//! refused with the rule named (exit 2) before anything is created — huge,
//! negative and non-finite numbers included, never a panic.

use std::process::Command;

fn sim_server(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_sim-server"))
        .args(args)
        .output()
        .expect("run sim-server")
}

#[test]
fn help_names_every_time_setting() {
    let out = sim_server(&["--help"]);
    assert!(out.status.success());
    let help = String::from_utf8_lossy(&out.stdout);
    for flag in [
        "--world",
        "--scene",
        "--fixed-delta-seconds",
        "--fps",
        "--no-substepping",
        "--max-substep-delta-time",
        "--max-substeps",
        "--max-frames",
        "--realtime",
        "SIMBUS_WORLD",
    ] {
        assert!(help.contains(flag), "--help mentions {flag}");
    }
}

#[test]
fn bad_start_settings_are_refused_with_the_rule() {
    let cases: &[(&[&str], &str)] = &[
        (&["--fixed-delta-seconds", "0.5"], "substep rule violated"),
        (
            &["--max-substeps", "17"],
            "must be a whole number in 1..=16, got 17",
        ),
        (
            &["--max-substeps=-1"],
            "must be a whole number in 1..=16, got -1",
        ),
        (&["--fps=-1"], "fps = -1 is negative"),
        (
            &["--delta-seconds", "-1"],
            "fixed_delta_seconds = -1 is negative; it must be >= 0 (0 means variable step)",
        ),
        (
            &["--max-substep-delta-time", "-0.01"],
            "max_substep_delta_time = -0.01 is negative; it must be positive",
        ),
        (&["--lockstep-timeout", "1e30"], "at most 1e9 seconds"),
        (&["--lockstep-timeout", "nan"], "positive, finite number"),
        (&["--max-fps", "1e-30"], "one tick every 1e30 s"),
        (&["--sync"], "--sync needs a fixed step"),
        (&["--scene", "boxes:0"], "invalid box count"),
        (&["--scene", "town10"], "unknown scene 'town10'"),
        (&["--world", "a/b"], "contains '/'"),
    ];
    for (args, message) in cases {
        let out = sim_server(args);
        // Refused input exits 2, like every sim-client refusal.
        assert_eq!(out.status.code(), Some(2), "{args:?} is refused");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains(message), "{args:?}: {stderr}");
    }
}
