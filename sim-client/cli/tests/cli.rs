//! The `sim-client` command line: help that explains, and input refused
//! before any server is asked.

use std::process::Command;

fn sim_client(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_sim-client"))
        .args(args)
        .output()
        .expect("run sim-client")
}

#[test]
fn help_lists_the_commands() {
    let out = sim_client(&["--help"]);
    assert!(out.status.success());
    let help = String::from_utf8_lossy(&out.stdout);
    for command in ["watch", "status", "config", "demo", "--world", "--timeout"] {
        assert!(help.contains(command), "--help mentions {command}");
    }
}

#[test]
fn config_cannot_enter_synchronous_mode_and_says_why() {
    let out = sim_client(&["--world", "no-such-world", "config", "--sync"]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("entered by the tick owner"), "{stderr}");
}

#[test]
fn bad_world_names_and_timeouts_are_refused() {
    let out = sim_client(&["--world", "", "status"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("world name is empty"));
    let out = sim_client(&["--timeout=-1", "status"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn huge_negative_and_odd_numbers_are_refused_with_exit_2_not_a_panic() {
    let cases: &[(&[&str], &str)] = &[
        (&["--timeout", "1e20", "status"], "at most 1e9 seconds"),
        (&["--timeout", "inf", "status"], "positive, finite number"),
        (&["tick", "--rate", "1e-30"], "one tick every 1e30 s"),
        (&["tick", "--rate", "0"], "positive, finite number of Hz"),
        (
            &["tick", "--until-sim-time", "inf"],
            "must be a finite number of seconds",
        ),
        (
            &["config", "--max-substeps=-1"],
            "must be a whole number in 1..=16",
        ),
        (
            &["sensor", "spawn", "imu", "--sensor-tick", "1e300"],
            "18446744073",
        ),
        (
            &["sensor", "spawn", "imu", "--size", "4,4"],
            "--size applies to depth, rgb, semantic or instance sensors, not to imu",
        ),
        (
            &["sensor", "spawn", "depth", "--size", "8192,8192"],
            "at most 8388608 pixels",
        ),
        (&["spawn", "box", "--at", "1e9,0,0"], "within +-100000 m"),
    ];
    for (args, message) in cases {
        let out = sim_client(&[&["--world", "no-such-world"], *args].concat());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(message), "{args:?}: {stderr}");
    }
}
