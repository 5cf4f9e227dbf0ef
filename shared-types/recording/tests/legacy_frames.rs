//! Recordings made before frame headers carried `recorded_frame` (schema
//! `simbus::FrameHeader/2`, a 96-byte header) and before sensor specs
//! carried 16 parameters (`simbus::RecordedSensor/1`, 104 bytes) still
//! read: every frame with its actors and every sensor's spawn, the new
//! fields zero.

use std::io::BufWriter;

use mcap::records::MessageHeader;
use shared_types::{ActorState, FrameHeader, Gnss, SensorSpec, WorldSettings, PROTOCOL_VERSION};
use simbus_recording::{
    Entry, RecordedSensor, RecordingHeader, RecordingReader, FRAMES_TOPIC, HEADER_SCHEMA,
    HEADER_TOPIC, LEGACY_FRAME_HEADER_BYTES, LEGACY_FRAME_SCHEMA, LEGACY_SENSOR_SPAWN_BYTES,
    LEGACY_SENSOR_SPAWN_SCHEMA, PROFILE, RECORDING_VERSION, SENSORS_TOPIC, WIRE_ENCODING,
};

#[test]
fn a_recording_of_older_frame_headers_and_sensor_specs_reads_with_the_new_fields_zero() {
    let dir = std::env::temp_dir().join(format!("simbus-legacy-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("legacy.mcap");
    let header = RecordingHeader {
        recording_version: RECORDING_VERSION,
        simbus_version: "0.1.0".to_string(),
        protocol_version: 2,
        world: "old".to_string(),
        scene: "default".to_string(),
        seed: 1,
        settings: WorldSettings::default().into(),
        start_frame: 7,
        start_elapsed_ns: 350_000_000,
        episode: 0,
        start_platform_timestamp: 1.0,
        sensors: false,
        keyframe_seconds: 10.0,
        journal_sync_frames: 0,
        run_pid: 0,
    };
    let frames: Vec<(FrameHeader, Vec<ActorState>)> = (0..3u64)
        .map(|i| {
            let header = FrameHeader {
                protocol_version: 2,
                actor_count: 2,
                timestamp: shared_types::Timestamp {
                    frame: 7 + i,
                    elapsed_ns: 350_000_000 + i * 50_000_000,
                    delta_ns: 50_000_000,
                    platform_timestamp: 1.0,
                },
                first_actor_id: 1,
                // What a version 2 writer cannot have written: must read as zero.
                recorded_frame: 99,
                recorded_elapsed_ns: 99,
                ..FrameHeader::default()
            };
            let actors = (1..=2)
                .map(|id| ActorState {
                    id,
                    kind: 2,
                    position: [i as f32, id as f32, 0.0],
                    rotation: [0.0, 0.0, 0.0, 1.0],
                    ..ActorState::default()
                })
                .collect();
            (header, actors)
        })
        .collect();
    let gnss = Gnss {
        lat_stddev: 1e-6,
        seed: 42,
        ..Gnss::default()
    };
    let sensor = RecordedSensor {
        frame: 7,
        id: 3,
        spec: SensorSpec::with_params([0.0, 2.0, 0.0], gnss).attached_to(2),
    };
    // What a protocol 3 writer cannot have written: must read as zero.
    let mut written_sensor = sensor;
    written_sensor.spec.params[8..].fill(99.0);
    {
        let file = std::fs::File::create(&path).unwrap();
        let mut mcap = mcap::WriteOptions::new()
            .profile(PROFILE)
            .create(BufWriter::new(file))
            .unwrap();
        let schema = mcap.add_schema(HEADER_SCHEMA, "jsonschema", b"{}").unwrap();
        let header_channel = mcap
            .add_channel(schema, HEADER_TOPIC, "json", &Default::default())
            .unwrap();
        let schema = mcap
            .add_schema(LEGACY_FRAME_SCHEMA, WIRE_ENCODING, b"96 bytes")
            .unwrap();
        let frame_channel = mcap
            .add_channel(schema, FRAMES_TOPIC, WIRE_ENCODING, &Default::default())
            .unwrap();
        let message = |channel_id, sequence, log_time| MessageHeader {
            channel_id,
            sequence,
            log_time,
            publish_time: log_time,
        };
        mcap.write_to_known_channel(
            &message(header_channel, 0, 0),
            &serde_json::to_vec(&header).unwrap(),
        )
        .unwrap();
        let schema = mcap
            .add_schema(LEGACY_SENSOR_SPAWN_SCHEMA, WIRE_ENCODING, b"104 bytes")
            .unwrap();
        let sensor_channel = mcap
            .add_channel(schema, SENSORS_TOPIC, WIRE_ENCODING, &Default::default())
            .unwrap();
        mcap.write_to_known_channel(
            &message(sensor_channel, 0, 0),
            &bytemuck::bytes_of(&written_sensor)[..LEGACY_SENSOR_SPAWN_BYTES],
        )
        .unwrap();
        for (i, (header, actors)) in frames.iter().enumerate() {
            let mut bytes = bytemuck::bytes_of(header)[..LEGACY_FRAME_HEADER_BYTES].to_vec();
            bytes.extend_from_slice(bytemuck::cast_slice(actors));
            mcap.write_to_known_channel(
                &message(frame_channel, i as u32, i as u64 * 50_000_000),
                &bytes,
            )
            .unwrap();
        }
        mcap.finish().unwrap();
    }

    let mut reader =
        RecordingReader::open(path.to_str().unwrap()).expect("a version 2 recording opens");
    let (mut read, mut sensors) = (Vec::new(), Vec::new());
    while let Some(entry) = reader.next() {
        match entry.expect("every message reads") {
            Entry::Frame { header, actors, .. } => read.push((header, actors)),
            Entry::Sensor(sensor) => sensors.push(sensor),
            _ => {}
        }
    }
    assert_eq!(sensors, [sensor]);
    assert_eq!(sensors[0].spec.gnss_params(), Some(gnss));
    assert_eq!(read.len(), frames.len());
    for ((header, actors), (written, written_actors)) in read.iter().zip(&frames) {
        assert_eq!(header.timestamp, written.timestamp);
        assert_eq!((header.recorded_frame, header.recorded_elapsed_ns), (0, 0));
        assert_eq!(actors, written_actors);
    }
    const { assert!(PROTOCOL_VERSION > 3, "this build writes newer layouts") };
    std::fs::remove_dir_all(&dir).unwrap();
}
