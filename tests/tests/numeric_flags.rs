//! Every numeric flag of `sim-server` and `sim-client` states its range and
//! holds to it (issue #24): NaN, inf, -inf, 0, -1 and 1e300 are each either
//! inside the flag's documented range, and accepted, or refused with exit
//! 2 and the flag named, before anything starts or changes.
//!
//! The table (`numeric_flags/table.rs`) lists them all; a second test
//! reads every `--help` and fails on an option or argument that takes a
//! value and is in neither the table nor the list of non-numeric ones, so a
//! new flag cannot skip it.

use std::collections::BTreeSet;
use std::process::Command;
use std::time::Duration;

use simbus_tests::{bin, unique_world, Proc, Scratch};

#[path = "numeric_flags/table.rs"]
mod table;

use table::{Bin, Flag, FLAGS, NOT_NUMERIC, VALUES};

fn run(program: &str, args: &[String]) -> simbus_tests::Finished {
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    Proc::spawn(program, &args).finish(Duration::from_secs(60))
}

/// Aliases, and the name clap reports them by.
const ALIASES: &[(&str, &str)] = &[("--fixed-delta-seconds", "--delta-seconds")];

/// The name a refusal of `flag` says.
fn reported(flag: &str) -> &str {
    ALIASES
        .iter()
        .find(|(alias, _)| *alias == flag)
        .map_or(flag, |(_, name)| name)
}

/// Asserts a refusal: exit 2, the flag and the value named.
fn assert_refused(flag: &Flag, value: &str, out: &simbus_tests::Finished) {
    assert_eq!(out.status.code(), Some(2), "{} {value}: {out}", flag.flag);
    assert!(
        out.stderr.contains(reported(flag.flag)),
        "{} {value}: the flag is named: {out}",
        flag.flag
    );
    // A real flag of that command (a renamed one fails here), refused as
    // such, never a panic.
    for wrong in ["unexpected argument", "unrecognized subcommand", "panicked"] {
        assert!(!out.stderr.contains(wrong), "{} {value}: {out}", flag.flag);
    }
}

/// Asserts the parser took the value: whatever happened next (no server
/// here), it was not refused as the flag's value.
fn assert_accepted(flag: &Flag, value: &str, stderr: &str) {
    assert!(
        !stderr.contains(&format!("for '{}", reported(flag.flag)))
            && !stderr.contains("invalid value"),
        "{} {value} is in the documented range: {stderr}",
        flag.flag
    );
}

#[test]
fn every_numeric_flag_refuses_what_is_out_of_range_and_changes_nothing() {
    // Client refusals run against a live world waiting in synchronous mode
    // for a ticker: nothing may tick it, change it, spawn or record.
    let live = simbus_tests::TestWorld::start("numeric", &["--sync", "--delta-seconds", "0.02"]);
    let before = live.status();
    let scratch = Scratch::new("numeric-flags");
    let out_dir = scratch.file("never-created");
    let out_dir = out_dir.to_string_lossy().into_owned();
    // Server refusals name a world no server may start on.
    let refused_world = unique_world("numeric-refused");
    let nowhere = unique_world("numeric-nowhere");
    let mut checked = 0;
    for flag in FLAGS {
        for value in VALUES {
            let args = flag.args(value, &out_dir);
            let valid = flag.valid.contains(&value);
            match (flag.bin, valid) {
                (Bin::Server, false) => {
                    let mut all = vec!["--world".to_string(), refused_world.clone()];
                    all.extend(args);
                    assert_refused(flag, value, &run("sim-server", &all));
                }
                (Bin::Client, false) => {
                    let mut all = vec!["--world".to_string(), live.name().to_string()];
                    all.extend(args);
                    assert_refused(flag, value, &run("sim-client", &all));
                }
                (Bin::Server, true) => {
                    // Accepted: a server starts, computes two frames, exits 0.
                    let world = unique_world("numeric-ok");
                    let mut all = vec!["--world".to_string(), world, "--max-frames=2".into()];
                    all.extend(args);
                    let out = run("sim-server", &all);
                    out.assert_success();
                    assert_accepted(flag, value, &out.stderr);
                }
                (Bin::Client, true) => {
                    // Accepted: no server answers there, so it fails later,
                    // or (a gateway) serves until it is stopped.
                    let mut all = vec![
                        "--world".to_string(),
                        nowhere.clone(),
                        "--timeout=0.3".into(),
                    ];
                    all.extend(args);
                    let all: Vec<&str> = all.iter().map(String::as_str).collect();
                    let proc = Proc::spawn(flag.program(), &all);
                    if flag.before.first() == Some(&"carla-gateway") {
                        let line = proc.line(Duration::from_secs(30));
                        assert!(
                            line.as_deref()
                                .is_some_and(|l| l.contains("served to CARLA clients")),
                            "{} {value}: {line:?} {}",
                            flag.flag,
                            proc.stderr()
                        );
                        assert_accepted(flag, value, &proc.stderr());
                    } else {
                        let out = proc.finish(Duration::from_secs(60));
                        assert_accepted(flag, value, &out.stderr);
                    }
                }
            }
            checked += 1;
        }
        // An option's negative value typed after a space (as people do)
        // is its value too, refused or taken as the range says.
        if !flag.flag.starts_with('<') && !flag.valid.contains(&"-1") {
            let mut all = vec![
                "--world".to_string(),
                match flag.bin {
                    Bin::Server => refused_world.clone(),
                    Bin::Client => live.name().to_string(),
                },
            ];
            let args = flag.args("-1", &out_dir);
            for arg in args {
                match arg.strip_prefix(&format!("{}=", flag.flag)) {
                    Some(value) => all.extend([flag.flag.to_string(), value.to_string()]),
                    None => all.push(arg),
                }
            }
            assert_refused(flag, "-1", &run(flag.program(), &all));
        }
    }
    assert_eq!(checked, FLAGS.len() * VALUES.len());

    // Nothing started on the refused servers' world ...
    assert!(
        sim_client::Client::connect(&refused_world, Duration::from_millis(300)).is_err(),
        "no server started on {refused_world}"
    );
    // ... and the live world is as it was: same frame (nobody ticked), same
    // settings, actors, episode, no ticker, no participant, no sensor.
    let after = live.status();
    for key in [
        "frame",
        "episode",
        "actors",
        "synchronous_mode",
        "fixed_delta_seconds",
        "substepping",
        "max_substep_delta_time",
        "max_substeps",
        "ticker",
        "participants",
        "scene",
    ] {
        assert_eq!(before[key], after[key], "{key} unchanged");
    }
    let sensors = live.cli(&["sensor", "list", "--json"]);
    sensors.assert_success();
    assert!(sensors.stdout.is_empty(), "no sensor spawned: {sensors}");
    assert!(
        !std::path::Path::new(&out_dir).exists(),
        "sensor save wrote nothing"
    );
}

/// `--help` of `program` with `path` (e.g. `["sensor", "spawn"]`).
fn help(program: &str, path: &[&str]) -> String {
    let out = Command::new(bin(program))
        .args(path)
        .arg("--help")
        .output()
        .expect("run --help");
    assert!(out.status.success(), "{program} {path:?} --help");
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The subcommands a help text lists (`Commands:` section, without `help`).
fn subcommands(help: &str) -> Vec<String> {
    help.lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter(|l| !l.starts_with("   "))
        .filter_map(|l| l.split_whitespace().next())
        .filter(|name| *name != "help")
        .map(str::to_owned)
        .collect()
}

/// Every option taking a value (`--flag <X>`) and every positional
/// argument (`<NAME>`) a help text lists.
fn valued(help: &str) -> BTreeSet<String> {
    let mut found = BTreeSet::new();
    let mut section = "";
    for line in help.lines() {
        if line.trim().is_empty() {
            continue;
        }
        if !line.starts_with(' ') {
            section = line;
            continue;
        }
        let first = line.trim_start();
        if section.starts_with("Arguments:") && first.starts_with('<') {
            if let Some(end) = first.find('>') {
                found.insert(first[..=end].to_string());
            }
        }
        if section.to_lowercase().contains("options") && first.starts_with('-') {
            let spec = first.split("  ").next().unwrap_or("");
            if let Some(long) = spec.split([' ', ',']).find(|w| w.starts_with("--")) {
                if spec.contains('<') {
                    found.insert(long.trim_end_matches('=').to_string());
                }
            }
        }
    }
    found
}

#[test]
fn the_table_lists_every_flag_that_takes_a_number() {
    let in_table = |bin: Bin, name: &str| FLAGS.iter().any(|f| f.bin == bin && f.flag == name);
    let mut missing = Vec::new();
    let mut seen = BTreeSet::new();
    for (bin, program) in [(Bin::Server, "sim-server"), (Bin::Client, "sim-client")] {
        let mut pending: Vec<Vec<String>> = vec![Vec::new()];
        while let Some(path) = pending.pop() {
            let path_ref: Vec<&str> = path.iter().map(String::as_str).collect();
            let text = help(program, &path_ref);
            for sub in subcommands(&text) {
                let mut next = path.clone();
                next.push(sub);
                pending.push(next);
            }
            for name in valued(&text) {
                seen.insert((program, name.clone()));
                if !in_table(bin, &name) && !NOT_NUMERIC.contains(&name.as_str()) {
                    missing.push(format!("{program} {} {name}", path.join(" ")));
                }
            }
        }
    }
    assert!(
        missing.is_empty(),
        "flags neither in the numeric table nor known to be non-numeric: {missing:#?}"
    );
    // And every row of the table is a flag some `--help` lists (aliases
    // are listed with their flag).
    for flag in FLAGS {
        let listed = seen.contains(&(flag.program(), flag.flag.to_string()))
            || ALIASES.iter().any(|(alias, _)| *alias == flag.flag);
        assert!(
            listed,
            "{} {} is not a flag of it",
            flag.program(),
            flag.flag
        );
    }
}

/// Issue #24's low items: each refusal states the rule, and settings read
/// back readably.
#[test]
fn scene_position_and_fps_refusals_state_the_rule_and_status_reads_readably() {
    let nowhere = unique_world("numeric-rules");
    let cases: &[(&[&str], &str)] = &[
        (&["load", "boxes:0"], "boxes:N needs N in 1..=100000"),
        (
            &["sensor", "spawn", "depth", "--at", "1e9,0,0"],
            "within +-100000 m of the origin",
        ),
        (
            &["config", "--fps", "1e-300"],
            "fps = 1e-300 is out of range: it must be 0 (variable step) or in 0.000277778..=1e6",
        ),
        (
            &["config", "--delta-seconds", "-1e300"],
            "fixed_delta_seconds = -1e300 is negative",
        ),
    ];
    for (args, rule) in cases {
        let out = simbus_tests::client(&nowhere, args);
        out.assert_code(2);
        assert!(out.stderr.contains(rule), "{args:?}: {out}");
        assert!(out.stderr.len() < 400, "no 300-digit numbers: {out}");
    }
    let out = Proc::spawn("sim-server", &["--world", &nowhere, "--scene", "boxes:0"])
        .finish(Duration::from_secs(30));
    out.assert_code(2);
    assert!(
        out.stderr.contains("boxes:N needs N in 1..=100000"),
        "{out}"
    );

    let world = simbus_tests::TestWorld::start("numeric-status", &["--fps", "30"]);
    let out = world.cli(&["status"]);
    out.assert_success();
    let step = out.line_starting("step");
    assert!(step.contains("fixed 0.0333333 s (30 FPS)"), "{step}");
    let out = world.cli(&["config", "--inspect"]);
    out.assert_success();
    assert!(
        out.stdout
            .iter()
            .any(|l| l.contains("fixed 0.0333333 s (30 FPS)")),
        "{out}"
    );
    // JSON keeps the exact value.
    assert_eq!(
        world.status()["fixed_delta_seconds"].as_f64(),
        Some(1.0 / 30.0)
    );
}
