//! The table of every numeric flag of `sim-server` and `sim-client`, with
//! the values each one's documented range holds, and the options that take
//! a value but not a number (see `numeric_flags.rs`).

/// The values every numeric flag is fed.
pub(crate) const VALUES: [&str; 6] = ["NaN", "inf", "-inf", "0", "-1", "1e300"];

#[derive(Clone, Copy, PartialEq)]
pub(crate) enum Bin {
    Server,
    Client,
}

/// One numeric flag (or positional argument, spelled `<NAME>`).
pub(crate) struct Flag {
    pub(crate) bin: Bin,
    /// The subcommand and what it needs before the flag.
    pub(crate) before: &'static [&'static str],
    /// `--flag`, or `<NAME>` for a positional argument.
    pub(crate) flag: &'static str,
    /// The value as typed, `{}` standing for the value under test.
    pub(crate) template: &'static str,
    /// What it needs after the flag.
    pub(crate) after: &'static [&'static str],
    /// Which of [`VALUES`] the documented range holds.
    pub(crate) valid: &'static [&'static str],
}

const fn server_flag(flag: &'static str, valid: &'static [&'static str]) -> Flag {
    Flag {
        bin: Bin::Server,
        before: &[],
        flag,
        template: "{}",
        after: &[],
        valid,
    }
}

const fn client_flag(
    before: &'static [&'static str],
    flag: &'static str,
    template: &'static str,
    after: &'static [&'static str],
    valid: &'static [&'static str],
) -> Flag {
    Flag {
        bin: Bin::Client,
        before,
        flag,
        template,
        after,
        valid,
    }
}

const NONE: &[&str] = &[];
const ZERO: &[&str] = &["0"];
const ZERO_AND_MINUS_ONE: &[&str] = &["0", "-1"];
const LISTEN: &[&str] = &["bridge", "zenoh", "--listen", "tcp/127.0.0.1:1"];
/// A recording path no test creates (the flags are refused before it is read).
const NO_FILE: &str = "/nonexistent-simbus-numeric-flags/x.mcap";

/// Every numeric flag, read off the clap `Args` structs of
/// `sim-server/src/cli.rs`, `sim-client/src/main.rs` and `sim-client/src/cli/**`.
pub(crate) const FLAGS: &[Flag] = &[
    // sim-server
    server_flag("--delta-seconds", ZERO),
    server_flag("--fixed-delta-seconds", ZERO),
    server_flag("--fps", ZERO),
    server_flag("--max-substep-delta-time", NONE),
    server_flag("--max-substeps", NONE),
    server_flag("--max-fps", ZERO),
    server_flag("--seed", ZERO),
    server_flag("--hybrid-window-us", ZERO),
    server_flag("--lockstep-timeout", NONE),
    server_flag("--keyframe-seconds", NONE),
    server_flag("--max-clients", NONE),
    server_flag("--max-sensor-readers", NONE),
    server_flag("--render-threads", NONE),
    server_flag("--max-frames", NONE),
    Flag {
        template: "boxes:{}",
        ..server_flag("--scene", NONE)
    },
    Flag {
        template: "frames:{}",
        before: &["--journal", "/nonexistent-simbus-numeric-flags/journal"],
        ..server_flag("--journal-sync", NONE)
    },
    Flag {
        before: &["--resume", "/nonexistent-simbus-numeric-flags/journal"],
        ..server_flag("--at", NONE)
    },
    // sim-client, global
    client_flag(&[], "--timeout", "{}", &["status"], NONE),
    // watch, top, foxglove, bridge
    client_flag(&["watch"], "--frames", "{}", &[], NONE),
    client_flag(&["watch", "--lockstep"], "--window", "{}", &[], ZERO),
    client_flag(&["top"], "--interval", "{}", &[], NONE),
    client_flag(&["foxglove"], "--port", "{}", &[], ZERO),
    client_flag(&["foxglove"], "--max-hz", "{}", &[], ZERO),
    client_flag(LISTEN, "--lease-ms", "{}", &[], NONE),
    client_flag(LISTEN, "--request-timeout", "{}", &[], NONE),
    client_flag(LISTEN, "--poll-us", "{}", &[], ZERO),
    // config
    client_flag(&["config"], "--delta-seconds", "{}", &[], ZERO),
    client_flag(&["config"], "--fps", "{}", &[], ZERO),
    client_flag(&["config"], "--max-substep-delta-time", "{}", &[], NONE),
    client_flag(&["config"], "--max-substeps", "{}", &[], NONE),
    // tick
    client_flag(&["tick"], "--count", "{}", &[], ZERO),
    client_flag(&["tick"], "--rate", "{}", &[], NONE),
    client_flag(&["tick"], "--until-sim-time", "{}", &[], ZERO),
    client_flag(&["tick"], "--delta-seconds", "{}", &[], ZERO),
    client_flag(&["tick"], "--fps", "{}", &[], ZERO),
    client_flag(&["tick"], "--participants", "{}", &[], ZERO),
    client_flag(&["tick", "--standby"], "--standby-timeout", "{}", &[], NONE),
    client_flag(&["tick"], "--restart-timeout", "{}", &[], NONE),
    // actors and worlds
    client_flag(&["spawn", "box"], "--at", "{},0,0", &[], ZERO_AND_MINUS_ONE),
    client_flag(&["destroy"], "<ID>", "{}", &[], ZERO),
    client_flag(&["load"], "<SCENE>", "boxes:{}", &[], NONE),
    client_flag(&["autopilot"], "--seed", "{}", &[], ZERO),
    client_flag(&["autopilot"], "--every", "{}", &[], NONE),
    client_flag(&["autopilot"], "--frames", "{}", &[], NONE),
    // sensors
    client_flag(&["sensor", "spawn", "imu"], "--attach", "{}", &[], ZERO),
    client_flag(
        &["sensor", "spawn", "imu"],
        "--at",
        "{},0,0",
        &[],
        ZERO_AND_MINUS_ONE,
    ),
    client_flag(
        &["sensor", "spawn", "imu"],
        "--rotation",
        "{},0,0",
        &[],
        ZERO_AND_MINUS_ONE,
    ),
    client_flag(
        &["sensor", "spawn", "imu"],
        "--sensor-tick",
        "{}",
        &[],
        ZERO,
    ),
    client_flag(&["sensor", "spawn", "depth"], "--size", "{},480", &[], NONE),
    client_flag(&["sensor", "spawn", "depth"], "--fov", "{}", &[], NONE),
    client_flag(&["sensor", "spawn", "depth"], "--range", "{}", &[], NONE),
    client_flag(&["sensor", "spawn", "lidar"], "--channels", "{}", &[], NONE),
    client_flag(
        &["sensor", "spawn", "radar"],
        "--vertical-fov",
        "{}",
        &[],
        NONE,
    ),
    client_flag(
        &["sensor", "spawn", "radar"],
        "--points-per-second",
        "{}",
        &[],
        NONE,
    ),
    client_flag(
        &["sensor", "spawn", "obstacle"],
        "--hit-radius",
        "{}",
        &[],
        NONE,
    ),
    client_flag(
        &["sensor", "spawn", "lidar"],
        "--dropoff",
        "{},0,0",
        &[],
        ZERO,
    ),
    client_flag(
        &["sensor", "spawn", "lidar"],
        "--attenuation",
        "{}",
        &[],
        ZERO,
    ),
    client_flag(&["sensor", "spawn", "lidar"], "--points", "{}", &[], NONE),
    client_flag(
        &["sensor", "spawn", "lidar"],
        "--fov-range",
        "10,{}",
        &[],
        ZERO_AND_MINUS_ONE,
    ),
    client_flag(
        &["sensor", "spawn", "lidar"],
        "--rotation-frequency",
        "{}",
        &[],
        ZERO,
    ),
    client_flag(
        &["sensor", "spawn", "gnss"],
        "--noise-stddev",
        "{},0,0",
        &[],
        ZERO,
    ),
    client_flag(
        &["sensor", "spawn", "gnss"],
        "--noise-bias",
        "{},0,0",
        &[],
        ZERO_AND_MINUS_ONE,
    ),
    client_flag(
        &["sensor", "spawn", "gnss"],
        "--noise-seed",
        "{}",
        &[],
        ZERO,
    ),
    client_flag(&["sensor", "watch"], "<ID>", "{}", &[], ZERO),
    client_flag(&["sensor", "watch", "1"], "--captures", "{}", &[], NONE),
    client_flag(&["sensor", "save"], "<ID>", "{}", &["--out", "OUT"], ZERO),
    client_flag(
        &["sensor", "save", "1", "--out", "OUT"],
        "--captures",
        "{}",
        &[],
        NONE,
    ),
    client_flag(
        &["sensor", "save", "1", "--out", "OUT"],
        "--range",
        "{}",
        &[],
        NONE,
    ),
    client_flag(&["sensor", "destroy"], "<ID>", "{}", &[], ZERO),
    // demo (it would start a server: no value here is valid)
    client_flag(&["demo"], "--frames", "{}", &[], NONE),
    client_flag(&["demo"], "--delta-seconds", "{}", &[], NONE),
    client_flag(&["demo"], "--scene", "boxes:{}", &[], NONE),
    // recorder and replay
    client_flag(&["recorder", "time-factor"], "<FACTOR>", "{}", &[], NONE),
    client_flag(
        &["recorder", "blocked", NO_FILE],
        "--min-time",
        "{}",
        &[],
        ZERO,
    ),
    client_flag(
        &["recorder", "blocked", NO_FILE],
        "--min-distance",
        "{}",
        &[],
        NONE,
    ),
    client_flag(
        &["replay", NO_FILE],
        "--start",
        "{}",
        &[],
        ZERO_AND_MINUS_ONE,
    ),
    client_flag(&["replay", NO_FILE], "--duration", "{}", &[], ZERO),
    client_flag(&["replay", NO_FILE], "--follow", "{}", &[], ZERO),
    client_flag(&["replay", NO_FILE], "--time-factor", "{}", &[], NONE),
    // the CARLA gateway (0: any free port; it then serves until killed)
    client_flag(&["carla-gateway"], "--port", "{}", &[], ZERO),
    client_flag(
        &["carla-gateway", "--port", "0"],
        "--streaming-port",
        "{}",
        &[],
        ZERO,
    ),
    client_flag(
        &["carla-gateway", "--port", "0"],
        "--ros-domain-id",
        "{}",
        &[],
        ZERO,
    ),
    // ROS 2 (a domain 0..=232; ids of sensors and vehicles)
    client_flag(&["ros2"], "--domain-id", "{}", &[], ZERO),
    client_flag(&["ros2"], "--sensors", "{}", &[], ZERO),
    client_flag(&["ros2"], "--vehicles", "{}", &[], ZERO),
    client_flag(
        &["ros2", "--tick-from-ros"],
        "--delta-seconds",
        "{}",
        &[],
        NONE,
    ),
];

/// Options and arguments that take a value but not a number.
pub(crate) const NOT_NUMERIC: &[&str] = &[
    "--world",
    "--journal",
    "--resume",
    "--wait-mode",
    "--substep-rule",
    "--on-ticker-loss",
    "--host",
    "--listen",
    "--connect",
    "--zenoh-config",
    "--out",
    "--server",
    "--kind1",
    "--kind2",
    "--mode",
    "--namespace",
    "<FILE>",
    "<KIND>",
    "<COMMAND>",
];

impl Flag {
    /// The command line for `value` (`OUT` replaced by `out`), the value
    /// glued to an option with `=` so that `-inf` is a value, and after `--`
    /// (and the options) for a positional that starts with `-`.
    pub(crate) fn args(&self, value: &str, out: &str) -> Vec<String> {
        let typed = self.template.replace("{}", value);
        let fix = |a: &&str| {
            if *a == "OUT" {
                out.to_owned()
            } else {
                a.to_string()
            }
        };
        let mut args: Vec<String> = self.before.iter().map(fix).collect();
        if self.flag.starts_with('<') {
            // Options first: after `--` everything is positional.
            args.extend(self.after.iter().map(fix));
            if typed.starts_with('-') {
                args.push("--".into());
            }
            args.push(typed);
        } else {
            args.push(format!("{}={typed}", self.flag));
            args.extend(self.after.iter().map(fix));
        }
        args
    }

    pub(crate) fn program(&self) -> &'static str {
        match self.bin {
            Bin::Server => "sim-server",
            Bin::Client => "sim-client",
        }
    }
}
