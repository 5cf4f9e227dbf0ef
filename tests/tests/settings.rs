//! Settings: a change holds from exactly the frame `config` reports; every
//! invalid setting is refused with its rule named and changes nothing — by
//! the CLI, by the client library, and by the server itself for senders that
//! skip the client's checks; a wrong protocol version is refused.

use std::time::Duration;

use serde_json::Value;
use shared_types::{
    ControlRequest, ControlResponse, ResponseStatus, SettingsError, WireSettings, WorldSettings,
    PROTOCOL_VERSION,
};
use sim_client::{ApplySettingsError, Client};
use simbus_tests::{client, status, Proc, TestWorld};

#[test]
fn config_change_holds_from_the_reported_frame() {
    let world = TestWorld::start("config", &["--realtime", "--fixed-delta-seconds", "0.01"]);
    let watcher = Proc::spawn(
        "sim-client",
        &["--world", &world, "watch", "--frames", "150", "--json"],
    );
    // The watcher is watching once it printed a frame.
    let first = watcher
        .line(Duration::from_secs(30))
        .unwrap_or_else(|| panic!("the watcher started: {}", watcher.stderr()));
    let out = client(&world, &["config", "--delta-seconds", "0.05", "--json"]);
    out.assert_success();
    let applied = &out.json()[0];
    let from = applied["effective_frame"]
        .as_u64()
        .expect("effective_frame");
    assert_eq!(applied["fixed_delta_seconds"].as_f64(), Some(0.05));

    let mut frames = vec![serde_json::from_str::<Value>(&first).expect("a JSON frame")];
    frames.extend(watcher.finish(Duration::from_secs(60)).json());
    let (before, after): (Vec<&Value>, Vec<&Value>) = frames
        .iter()
        .partition(|f| f["frame"].as_u64().unwrap() < from);
    assert!(
        !before.is_empty() && !after.is_empty(),
        "watched across the change"
    );
    // Frame 0 (current when a quick watcher connects) is the initial state,
    // stepped by nothing.
    for f in before.into_iter().filter(|f| f["frame"] != 0) {
        assert_eq!(f["delta_ns"].as_u64(), Some(10_000_000), "{f}");
        assert_eq!(f["physics_substeps"].as_u64(), Some(1), "{f}");
    }
    for f in after {
        assert_eq!(f["delta_ns"].as_u64(), Some(50_000_000), "{f}");
        // ceil(0.05 / 0.01) = 5 substeps of 0.01 s.
        assert_eq!(f["physics_substeps"].as_u64(), Some(5), "{f}");
    }
    assert_eq!(status(&world)["fixed_delta_seconds"].as_f64(), Some(0.05));
}

#[test]
fn every_invalid_setting_is_refused_with_its_rule_and_changes_nothing() {
    let world = TestWorld::start("invalid", &["--fixed-delta-seconds", "0.05", "--realtime"]);
    let settings_of = |s: &Value| {
        [
            "synchronous_mode",
            "fixed_delta_seconds",
            "substepping",
            "max_substep_delta_time",
            "max_substeps",
        ]
        .map(|k| s[k].clone())
    };
    let before = settings_of(&status(&world));
    let cases: &[(&[&str], &str)] = &[
        (&["--delta-seconds=-0.1"], "negative"),
        (&["--delta-seconds", "NaN"], "not a finite number"),
        (&["--delta-seconds", "inf"], "not a finite number"),
        (&["--fps=-20"], "fps = -20 is negative"),
        (
            &["--max-substeps", "0"],
            "must be a whole number in 1..=16, got 0",
        ),
        (
            &["--max-substeps=-1"],
            "must be a whole number in 1..=16, got -1",
        ),
        (
            &["--delta-seconds", "-1"],
            "fixed_delta_seconds = -1 is negative; it must be >= 0 (0 means variable step)",
        ),
        (
            &["--max-substep-delta-time=-0.01"],
            "max_substep_delta_time = -0.01 is negative",
        ),
        (
            &["--delta-seconds", "0.5"],
            "substep rule violated: fixed_delta_seconds (0.5 s)",
        ),
        (
            &["--max-substeps", "2"],
            "max_substep_delta_time (0.01 s) * max_substeps (2) = 0.02 s",
        ),
        (&["--sync"], "entered by the tick owner"),
    ];
    for (args, rule) in cases {
        let mut all = vec!["config"];
        all.extend_from_slice(args);
        let out = client(&world, &all);
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?} exits 2: {}",
            out.stderr
        );
        assert!(
            out.stderr.contains(rule),
            "{args:?} names the rule '{rule}': {}",
            out.stderr
        );
        assert_eq!(
            settings_of(&status(&world)),
            before,
            "{args:?} changed nothing"
        );
    }
}

/// Sends `request` to `world`'s control service as a raw client would.
fn raw_request(world: &str, request: ControlRequest) -> ControlResponse {
    simbus_tests::raw::RawPorts::open(world).control(request)
}

#[test]
fn the_server_checks_settings_itself_and_refuses_other_protocol_versions() {
    let world = TestWorld::start(
        "server-checks",
        &["--fixed-delta-seconds", "0.05", "--realtime"],
    );
    let before = status(&world);

    let mut wire = WireSettings::from(WorldSettings::default());
    wire.fixed_delta_seconds = 0.5; // breaks the substep rule
    let request = ControlRequest {
        settings: wire,
        ..ControlRequest::apply_settings(WorldSettings::default())
    };
    let response = raw_request(&world, request);
    assert_eq!(response.status, ResponseStatus::InvalidSettings as u32);
    assert_eq!(
        response.settings_error(),
        Some(SettingsError::SubstepRule {
            fixed: 0.5,
            max_dt: 0.01,
            max_substeps: 10
        })
    );

    let mut nan = WireSettings::from(WorldSettings::default());
    nan.max_substep_delta_time = f64::NAN;
    let response = raw_request(
        &world,
        ControlRequest {
            settings: nan,
            ..ControlRequest::apply_settings(WorldSettings::default())
        },
    );
    assert_eq!(response.status, ResponseStatus::InvalidSettings as u32);

    let response = raw_request(
        &world,
        ControlRequest {
            protocol_version: PROTOCOL_VERSION + 1,
            ..ControlRequest::apply_settings(WorldSettings::default())
        },
    );
    assert_eq!(response.status, ResponseStatus::ProtocolMismatch as u32);

    let response = raw_request(
        &world,
        ControlRequest {
            kind: 999,
            ..ControlRequest::apply_settings(WorldSettings::default())
        },
    );
    assert_eq!(response.status, ResponseStatus::UnknownRequest as u32);

    let after = status(&world);
    for key in [
        "fixed_delta_seconds",
        "max_substep_delta_time",
        "max_substeps",
        "substepping",
    ] {
        assert_eq!(before[key], after[key], "{key} unchanged");
    }
}

#[test]
fn the_client_library_returns_typed_errors_and_the_effective_frame() {
    let world = TestWorld::start("typed", &["--fixed-delta-seconds", "0.01", "--realtime"]);
    let mut client = Client::connect(&world, Duration::from_secs(10)).unwrap();
    let current = client.get_settings().unwrap();
    assert_eq!(current.fixed_delta_seconds, Some(0.01));

    let bad = WorldSettings {
        max_substeps: 40,
        ..current
    };
    assert!(matches!(
        client.apply_settings(bad),
        Err(ApplySettingsError::Invalid(
            SettingsError::MaxSubstepsOutOfRange { value: 40, max: 16 }
        ))
    ));
    let sync = WorldSettings {
        synchronous_mode: true,
        ..current
    };
    assert!(matches!(
        client.apply_settings(sync),
        Err(ApplySettingsError::SyncNeedsTicker)
    ));
    assert_eq!(client.get_settings().unwrap(), current);

    let faster = WorldSettings {
        fixed_delta_seconds: Some(0.02),
        ..current
    };
    let from = client.apply_settings(faster).unwrap();
    loop {
        let snapshot = client.wait_for_tick(Duration::from_secs(10)).unwrap();
        let expected = if snapshot.frame() >= from {
            20_000_000
        } else {
            10_000_000
        };
        assert_eq!(
            snapshot.timestamp().delta_ns,
            expected,
            "frame {}",
            snapshot.frame()
        );
        if snapshot.frame() > from + 3 {
            break;
        }
    }
}
