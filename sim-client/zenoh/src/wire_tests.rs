//! The bridge's wire: every message round-trips and garbage is refused.

use super::*;
use std::mem::offset_of;

#[test]
fn the_frame_header_layout_is_the_documented_one() {
    // The book's table (docs/src/wire.md): a Zenoh client decodes frames
    // with these offsets.
    assert_eq!(offset_of!(FrameHeader, protocol_version), 0);
    assert_eq!(offset_of!(FrameHeader, actor_count), 4);
    assert_eq!(offset_of!(FrameHeader, episode), 8);
    assert_eq!(offset_of!(FrameHeader, timestamp), 16);
    assert_eq!(offset_of!(shared_types::Timestamp, frame), 0);
    assert_eq!(offset_of!(shared_types::Timestamp, elapsed_ns), 8);
    assert_eq!(offset_of!(shared_types::Timestamp, delta_ns), 16);
    assert_eq!(offset_of!(shared_types::Timestamp, platform_timestamp), 24);
    assert_eq!(offset_of!(FrameHeader, settings), 48);
    let after_settings = 48 + std::mem::size_of::<shared_types::WireSettings>();
    assert_eq!(offset_of!(FrameHeader, physics_substeps), after_settings);
    assert_eq!(offset_of!(FrameHeader, flags), after_settings + 4);
    assert_eq!(offset_of!(FrameHeader, first_actor_id), after_settings + 8);
    assert_eq!(offset_of!(FrameHeader, server_pid), after_settings + 16);
    assert_eq!(offset_of!(FrameHeader, recorded_frame), after_settings + 24);
    assert_eq!(
        offset_of!(FrameHeader, recorded_elapsed_ns),
        after_settings + 32
    );
    assert_eq!(FRAME_HEADER_BYTES, after_settings + 40);
    assert_eq!((after_settings, FRAME_HEADER_BYTES), (72, 112));
    let settings = offset_of!(FrameHeader, settings);
    assert_eq!(
        settings + offset_of!(shared_types::WireSettings, fixed_delta_seconds),
        48
    );
    assert_eq!(
        settings + offset_of!(shared_types::WireSettings, max_substep_delta_time),
        56
    );
    assert_eq!(
        settings + offset_of!(shared_types::WireSettings, max_substeps),
        64
    );
    assert_eq!(
        settings + offset_of!(shared_types::WireSettings, synchronous_mode),
        68
    );
    assert_eq!(
        settings + offset_of!(shared_types::WireSettings, substepping),
        69
    );
    assert_eq!(std::mem::size_of::<ActorState>(), 96);
    assert_eq!(std::mem::size_of::<SensorHeader>(), 104);
    assert_eq!(
        [
            offset_of!(ActorState, kind),
            offset_of!(ActorState, flags),
            offset_of!(ActorState, position),
            offset_of!(ActorState, rotation),
            offset_of!(ActorState, linear_velocity),
            offset_of!(ActorState, angular_velocity),
            offset_of!(ActorState, acceleration),
            offset_of!(ActorState, extent),
        ],
        [8, 12, 16, 28, 44, 56, 68, 80]
    );
}

#[test]
fn a_frame_survives_the_trip_and_a_bad_one_is_named() {
    let header = FrameHeader {
        protocol_version: PROTOCOL_VERSION,
        actor_count: 2,
        ..FrameHeader::default()
    };
    let actors = [ActorState {
        id: 7,
        ..ActorState::default()
    }; 2];
    let mut bytes = vec![0xAA]; // unaligned on purpose
    encode_frame(&header, &actors, &mut bytes);
    let (h, a) = decode_frame(&bytes[1..]).unwrap();
    assert_eq!((h, a.as_slice()), (header, &actors[..]));
    assert!(matches!(
        decode_frame(&bytes[1..bytes.len() - 1]),
        Err(PayloadError::WrongLength { .. })
    ));
    assert!(matches!(
        decode_frame(&bytes[1..20]),
        Err(PayloadError::TooShort { .. })
    ));
    let mut old = bytes[1..].to_vec();
    old[0] = 1;
    assert_eq!(
        decode_frame(&old).unwrap_err(),
        PayloadError::ProtocolMismatch {
            peer: 1,
            ours: PROTOCOL_VERSION
        }
    );
    let mut huge = bytes[1..].to_vec();
    huge[4..8].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(decode_frame(&huge).is_err());
}

#[test]
fn a_frame_in_pieces_reads_as_the_whole() {
    // A Zenoh payload may arrive in several slices; the mirror reads
    // the frame from them as they are.
    let header = FrameHeader {
        protocol_version: PROTOCOL_VERSION,
        actor_count: 3,
        ..FrameHeader::default()
    };
    let actors: Vec<ActorState> = (1..=3)
        .map(|id| ActorState {
            id,
            ..ActorState::default()
        })
        .collect();
    let mut bytes = Vec::new();
    encode_frame(&header, &actors, &mut bytes);
    assert_eq!(bytes.len(), frame_len(actors.len()));
    for cuts in [vec![1], vec![50, 111, 112, 113], vec![200, 201, 300]] {
        let mut pieces = Vec::new();
        let mut from = 0;
        for cut in cuts.into_iter().chain([bytes.len()]) {
            pieces.push(&bytes[from..cut]);
            from = cut;
        }
        let mut reader = Slices::new(pieces.iter().copied());
        let read = frame_header(&mut reader, bytes.len()).unwrap();
        let read_actors: Vec<ActorState> = (0..read.actor_count)
            .map(|_| reader.read().unwrap())
            .collect();
        assert_eq!((read, read_actors), (header, actors.clone()));
        assert!(reader.read::<u8>().is_none(), "nothing after the frame");
    }
    let mut short = Slices::new([&bytes[..40], &bytes[40..100]]);
    assert!(matches!(
        frame_header(&mut short, 100),
        Err(PayloadError::TooShort { .. })
    ));
}

#[test]
fn the_clock_is_cdr_of_seconds_and_nanoseconds() {
    assert_eq!(
        ros2_clock_cdr(3_250_000_001),
        [0, 1, 0, 0, 3, 0, 0, 0, 0x81, 0xB2, 0xE6, 0x0E] // 250_000_001 = 0x0EE6B281
    );
    assert_eq!(&ros2_clock_cdr(u64::MAX)[4..8], &i32::MAX.to_le_bytes());
}

#[test]
fn slices_are_bounded_and_versioned() {
    let header = shared_types::BatchHeader::zeroed();
    let mut bytes = Vec::new();
    encode_slice(&header, &[shared_types::Command::zeroed(); 3], &mut bytes);
    // A zeroed header carries version 0: refused.
    assert!(matches!(
        decode_slice::<shared_types::BatchHeader, shared_types::Command>(&bytes, "batch", 10),
        Err(PayloadError::ProtocolMismatch { peer: 0, .. })
    ));
    bytes[..4].copy_from_slice(&PROTOCOL_VERSION.to_le_bytes());
    let (_, commands) =
        decode_slice::<shared_types::BatchHeader, shared_types::Command>(&bytes, "batch", 10)
            .unwrap();
    assert_eq!(commands.len(), 3);
    assert!(
        decode_slice::<shared_types::BatchHeader, shared_types::Command>(&bytes, "batch", 2)
            .is_err()
    );
    bytes.push(0);
    assert!(
        decode_slice::<shared_types::BatchHeader, shared_types::Command>(&bytes, "batch", 10)
            .is_err()
    );
}
