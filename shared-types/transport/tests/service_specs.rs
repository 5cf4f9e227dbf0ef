//! Every service of a world, created from its description as the server
//! does (under non-default limits), opens from a client's side with the
//! same configuration.

use iceoryx2::prelude::*;
use shared_types::limits::WorldLimits;
use shared_types::{Doorbell, ImuMeasurement, LidarPoint, ServiceNames, WorldName};
use simbus_transport::spec::{Limit, WorldServices};
use simbus_transport::Bus;

fn node(name: &str) -> Node<Bus> {
    simbus_transport::environment::prepare().expect("iceoryx2 environment");
    simbus_transport::node(name).expect("node")
}

macro_rules! round_trip {
    ($server:expr, $client:expr, $spec:expr, $limits:expr) => {{
        let created = $spec.create(&$server, $limits).expect("create");
        let opened = $spec.open(&$client).expect("open");
        assert_eq!(
            created.static_config(),
            opened.static_config(),
            "{}",
            $spec.name.as_str()
        );
        (created, opened)
    }};
}

#[test]
fn every_service_created_from_its_spec_opens_with_the_same_config() {
    let world = WorldName::new(&format!("spec-{}", std::process::id())).unwrap();
    let specs = WorldServices::new(&ServiceNames::new(&world)).unwrap();
    let limits = WorldLimits {
        max_clients: 7,
        max_sensor_readers: 3,
    };
    let (server, client) = (node("spec-server"), node("spec-client"));

    let (frames, _) = round_trip!(server, client, specs.frames, &limits);
    assert_eq!(frames.static_config().max_subscribers(), 7);
    assert_eq!(frames.static_config().history_size(), 1);
    assert_eq!(frames.static_config().max_nodes(), limits.nodes());
    let (ready, _) = round_trip!(server, client, specs.frame_ready, &limits);
    assert_eq!(ready.static_config().max_listeners(), 14);
    assert_eq!(ready.static_config().max_notifiers(), 4);
    let (wake, _) = round_trip!(server, client, specs.control_wake, &limits);
    assert_eq!(wake.static_config().max_notifiers(), 7);
    // Every request service rings its own doorbell, and the wake-up event
    // carries every doorbell's id (a frame-ready ring carries only 0).
    assert_eq!(wake.static_config().event_id_max_value(), Doorbell::MAX_ID);
    assert_eq!(ready.static_config().event_id_max_value(), 0);
    let bells = [
        specs.control.doorbell,
        specs.tick.doorbell,
        specs.batch.doorbell,
        specs.lockstep.doorbell,
        specs.sensors.doorbell,
        specs.recorder.doorbell,
    ];
    let mut sorted = bells.map(Doorbell::event_id);
    sorted.sort_unstable();
    assert_eq!(sorted, [1, 2, 3, 4, 5, 6], "{bells:?}");
    let (control, _) = round_trip!(server, client, specs.control, &limits);
    assert_eq!(control.static_config().max_clients(), 7);
    assert_eq!(control.static_config().max_servers(), 1);
    let (tick, _) = round_trip!(server, client, specs.tick, &limits);
    // The ticker, a dead ticker's port until cleanup, and two standbys.
    assert_eq!(tick.static_config().max_clients(), 4);
    let (batch, _) = round_trip!(server, client, specs.batch, &limits);
    assert!(!batch.static_config().has_safe_overflow_for_requests());
    round_trip!(server, client, specs.lockstep, &limits);
    round_trip!(server, client, specs.sensors, &limits);
    round_trip!(server, client, specs.recorder, &limits);

    let depth = specs.sensor::<f32>(1).unwrap();
    let (created, _) = round_trip!(server, client, depth, &limits);
    assert_eq!(created.static_config().max_subscribers(), 3);
    assert_eq!(
        created
            .static_config()
            .message_type_details()
            .payload
            .alignment(),
        16
    );
    round_trip!(
        server,
        client,
        specs.sensor::<LidarPoint>(2).unwrap(),
        &limits
    );
    round_trip!(
        server,
        client,
        specs.sensor::<ImuMeasurement>(3).unwrap(),
        &limits
    );

    // The ports the server's domains and the mirror make from the specs.
    specs.batch.server(&batch).expect("batch server");
    specs.batch.client(&batch).expect("batch client");
    specs.frames.publisher(&frames, 0).expect("frame publisher");
    specs.frames.subscriber(&frames).expect("frame subscriber");

    // A second creator (another server or mirror) is refused.
    assert!(specs.control.create(&server, &limits).is_err());
    assert_eq!(Limit::SensorNodes.of(&limits), 3 + 16);
}
