//! Every subcommand's `--help` lists its own options first and the global
//! ones (--world, --timeout, -v) after them, under their own heading.

use std::process::Command;

fn help(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_sim-client"))
        .args(args)
        .arg("--help")
        .output()
        .expect("run sim-client");
    assert!(out.status.success(), "{args:?} --help: {out:?}");
    String::from_utf8(out.stdout).expect("UTF-8 help")
}

/// The lines of `help` under the heading `heading` (up to the next one).
fn section<'a>(help: &'a str, heading: &str) -> Vec<&'a str> {
    help.lines()
        .skip_while(|l| *l != heading)
        .skip(1)
        .take_while(|l| l.is_empty() || l.starts_with(' '))
        .collect()
}

#[test]
fn watch_help_lists_its_own_options_before_the_global_ones() {
    let help = help(&["watch"]);
    let own = section(&help, "Options:");
    let global = section(&help, "Global options:");
    let has = |lines: &[&str], flag: &str| lines.iter().any(|l| l.trim_start().contains(flag));
    assert!(has(&own, "--frames <N>"), "{help}");
    assert!(has(&own, "--digest"), "{help}");
    for flag in ["--world <WORLD>", "--timeout <S>", "--verbose"] {
        assert!(has(&global, flag), "{flag} under Global options: {help}");
        assert!(!has(&own, flag), "{flag} not among watch's own: {help}");
    }
    let own_at = help.find("Options:").expect("an Options heading");
    let global_at = help
        .find("Global options:")
        .expect("a Global options heading");
    assert!(own_at < global_at, "own options first: {help}");
}

#[test]
fn every_subcommand_puts_the_global_options_under_their_heading() {
    for command in [
        &["status"][..],
        &["top"],
        &["tick"],
        &["config"],
        &["spawn"],
        &["sensor", "watch"],
        &["recorder", "info"],
        &["replay"],
        &["demo"],
    ] {
        let help = help(command);
        let global = section(&help, "Global options:");
        assert!(
            global.iter().any(|l| l.contains("--world <WORLD>")),
            "{command:?}: {help}"
        );
        assert!(
            !section(&help, "Options:")
                .iter()
                .any(|l| l.contains("--world <WORLD>")),
            "{command:?}: {help}"
        );
    }
}
