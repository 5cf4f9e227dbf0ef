//! The substep rule: a fixed step longer than `max_substeps ×
//! max_substep_delta_time` (CARLA's examples: 0.2 s frames with the default
//! 0.01 s × 10) is refused natively, naming the rule; under `clamp` (CARLA's
//! behaviour) a free-falling sphere falls bit for bit as it does in 0.1 s
//! frames while each frame's timestamp advances 0.2 s, and every such frame
//! says so; under `stretch` it falls as with 10 substeps of 0.02 s.

use std::time::Duration;

use shared_types::{Command, SubstepRule, WorldSettings};
use sim_client::Client;
use simbus_tests::TestWorld;

const T: Duration = Duration::from_secs(20);

/// Frames each run ticks.
const TICKS: u64 = 8;

/// What a frame showed of the falling sphere.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Fallen {
    /// The sphere's height, bit for bit.
    height_bits: u32,
    /// The frame's delta, nanoseconds.
    delta_ns: u64,
    /// Physics substeps the frame ran.
    substeps: u32,
    /// The frame says physics was clamped.
    clamped: bool,
    /// The seconds physics advanced, as the frame says.
    physics_seconds: f64,
}

/// In an `empty` world whose settings `configure` set through
/// `sim-client config`, the ticker enters synchronous mode with those
/// settings (and `rule_for_ticker`, when given), spawns a sphere 100 m up
/// and ticks [`TICKS`] frames: what each frame showed of the sphere.
fn fall(tag: &str, configure: &[&str], rule_for_ticker: Option<SubstepRule>) -> Vec<Fallen> {
    let world = TestWorld::start(tag, &["--scene", "empty"]);
    let mut all = vec!["config"];
    all.extend_from_slice(configure);
    world.cli(&all).assert_success();
    let mut client: Client = world.connect();
    let configured = client.get_settings().unwrap();
    let mut ticker = client.claim_ticker().expect("claim");
    let settings = WorldSettings {
        synchronous_mode: true,
        substep_rule: rule_for_ticker.unwrap_or(configured.substep_rule),
        ..configured
    };
    ticker.apply_settings(settings).expect("enter sync");
    let sphere = client
        .spawn_actor(Command::spawn_sphere([0.0, 100.0, 0.0], 0.5))
        .expect("spawn");
    (0..TICKS)
        .map(|_| {
            let frame = ticker.tick(T).expect("tick");
            let snapshot = loop {
                let s = client.wait_for_tick(T).expect("the ticked frame");
                if s.frame() >= frame {
                    break s;
                }
            };
            assert_eq!(snapshot.frame(), frame);
            assert_eq!(snapshot.settings(), settings, "frame {frame}");
            let actor = snapshot
                .actors
                .iter()
                .find(|a| a.id == sphere)
                .unwrap_or_else(|| panic!("the sphere in frame {frame}"));
            Fallen {
                height_bits: actor.position[1].to_bits(),
                delta_ns: snapshot.timestamp().delta_ns,
                substeps: snapshot.header.physics_substeps,
                clamped: snapshot.is_physics_clamped(),
                physics_seconds: snapshot.physics_seconds(),
            }
        })
        .collect()
}

fn heights(run: &[Fallen]) -> Vec<u32> {
    run.iter().map(|f| f.height_bits).collect()
}

#[test]
fn a_step_longer_than_substepping_allows_is_refused_naming_the_rule() {
    let world = TestWorld::start("substep-refuse", &["--scene", "empty"]);
    for args in [
        &["config", "--delta-seconds", "0.2"][..],
        &["tick", "--delta-seconds", "0.2", "--count", "1"][..],
        &[
            "tick",
            "--delta-seconds",
            "0.2",
            "--count",
            "1",
            "--substep-rule",
            "refuse",
        ][..],
    ] {
        let out = world.cli(args);
        out.assert_code(2);
        for needle in [
            "substep rule violated: fixed_delta_seconds (0.2 s)",
            "substep rule 'refuse'",
            "'clamp' runs CARLA's way: physics advances 0.1 s per 0.2 s frame",
            "'stretch' lengthens the substeps to 0.02 s",
        ] {
            assert!(out.stderr.contains(needle), "{needle:?} in:\n{out}");
        }
    }
    // Nothing changed; the world says which rule holds.
    let out = world.cli(&["config", "--json"]);
    let json = &out.assert_success().json()[0];
    assert_eq!(json["fixed_delta_seconds"], serde_json::Value::Null);
    assert_eq!(json["substep_rule"], "refuse");
    let out = world.cli(&["config"]);
    assert!(
        out.line_starting("rule")
            .contains("refuse (a fixed step over 0.1 s is refused)"),
        "{out}"
    );
}

#[test]
fn clamp_falls_as_ten_substeps_of_a_hundredth_per_frame_of_a_fifth() {
    let clamp = fall(
        "substep-clamp",
        &["--delta-seconds", "0.2", "--substep-rule", "clamp"],
        None,
    );
    let tenth = fall("substep-tenth", &["--delta-seconds", "0.1"], None);
    // The same fall, bit for bit, frame by frame...
    assert_eq!(heights(&clamp), heights(&tenth));
    assert!(
        f32::from_bits(clamp[TICKS as usize - 1].height_bits) < 99.0,
        "the sphere fell: {clamp:?}"
    );
    for (c, t) in clamp.iter().zip(&tenth) {
        // ...while each clamped frame's time advanced twice as far.
        assert_eq!((c.delta_ns, t.delta_ns), (200_000_000, 100_000_000));
        assert_eq!((c.substeps, t.substeps), (10, 10));
        // Only the clamped frames say so, with the physics time they ran.
        assert!(c.clamped && !t.clamped, "{c:?} {t:?}");
        assert_eq!((c.physics_seconds, t.physics_seconds), (0.1, 0.1));
    }
}

#[test]
fn stretch_falls_as_ten_substeps_of_two_hundredths() {
    // `tick --substep-rule` sets the rule for the ticker's run; here the
    // library's ticker does, from a world configured to allow 0.2 s frames.
    let stretch = fall(
        "substep-stretch",
        &["--delta-seconds", "0.2", "--substep-rule", "stretch"],
        None,
    );
    let coarse = fall(
        "substep-coarse",
        &["--delta-seconds", "0.2", "--max-substep-delta-time", "0.02"],
        Some(SubstepRule::Refuse),
    );
    assert_eq!(heights(&stretch), heights(&coarse));
    for (s, c) in stretch.iter().zip(&coarse) {
        assert_eq!((s.delta_ns, c.delta_ns), (200_000_000, 200_000_000));
        assert_eq!((s.substeps, c.substeps), (10, 10));
        assert!(!s.clamped && !c.clamped, "{s:?} {c:?}");
        assert_eq!(s.physics_seconds, 0.2);
    }
    // And it is not the clamped fall: physics kept pace with time.
    let clamp = fall(
        "substep-not-clamp",
        &["--delta-seconds", "0.2", "--substep-rule", "clamp"],
        None,
    );
    assert_ne!(heights(&stretch), heights(&clamp));
}

#[test]
fn tick_takes_the_rule_for_its_run_and_watch_shows_the_clamped_frame() {
    let world = TestWorld::start("substep-tick", &["--scene", "empty"]);
    // --leave-sync: the world then waits for the next ticker, so its latest
    // frame stays the last one ticked.
    let out = world.cli(&[
        "tick",
        "--delta-seconds",
        "0.2",
        "--substep-rule",
        "clamp",
        "--count",
        "3",
        "--leave-sync",
    ]);
    out.assert_success();
    assert!(
        out.stderr
            .contains("substep rule 'clamp': physics advances 0.100 s per 0.200 s frame"),
        "{out}"
    );
    let watched = world.cli(&["watch", "--frames", "1", "--json"]);
    let frame = &watched.assert_success().json()[0];
    assert_eq!(frame["delta_ns"], 200_000_000, "{frame}");
    assert_eq!(frame["physics_clamped"], true, "{frame}");
    assert_eq!(frame["physics_seconds"], 0.1, "{frame}");
    assert_eq!(frame["substep_rule"], "clamp", "{frame}");
    let line = world.cli(&["watch", "--frames", "1"]);
    assert!(
        line.assert_success().stdout[0].contains("(physics clamped to 0.1 s)"),
        "{line}"
    );
    // The tick gave the world back with its own rule.
    let json = &world.cli(&["config", "--json"]).json()[0];
    assert_eq!(json["substep_rule"], "refuse");
}

#[test]
fn a_substep_rule_the_server_does_not_know_is_refused_by_value() {
    use shared_types::{ControlRequest, ResponseStatus, SettingsError, WireSettings};
    let world = TestWorld::start("substep-unknown", &["--scene", "empty"]);
    let mut wire = WireSettings::from(WorldSettings::default());
    wire.substep_rule = 9;
    let request = ControlRequest {
        settings: wire,
        ..ControlRequest::apply_settings(WorldSettings::default())
    };
    let response = simbus_tests::raw::RawPorts::open(world.name()).control(request);
    assert_eq!(response.status, ResponseStatus::InvalidSettings as u32);
    assert_eq!(
        response.settings_error(),
        Some(SettingsError::UnknownSubstepRule { value: 9 })
    );
    // The server is still there, its rule unchanged.
    let json = &world.cli(&["config", "--json"]).json()[0];
    assert_eq!(json["substep_rule"], "refuse");
}
