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
