//! The `sim-server` command line: help that explains, and bad start settings
//! refused with the rule named before anything is created.

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
            "max_substeps = 17 is outside the allowed range 1..=16",
        ),
        (&["--fps=-1"], "fps = -1 is negative"),
        (&["--scene", "boxes:0"], "invalid box count"),
        (&["--scene", "town10"], "unknown scene 'town10'"),
        (&["--world", "a/b"], "contains '/'"),
    ];
    for (args, message) in cases {
        let out = sim_server(args);
        assert!(!out.status.success(), "{args:?} is refused");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains(message), "{args:?}: {stderr}");
    }
}
