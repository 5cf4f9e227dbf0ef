//! A junction's lights take turns, green then yellow then red all round,
//! to the nanosecond of simulation time; a frozen group holds, a reset
//! starts again, and a state shown by a script holds until the cycle
//! reaches that light.

use super::*;

const S: u64 = NANOS_PER_SECOND;

/// A junction (7) of three lights, actors 10, 11, 12 (added out of pole
/// order), and another junction (8) of one light, actor 13.
fn lights() -> TrafficLights {
    let mut lights = TrafficLights::default();
    lights.add(10, 7, 0);
    lights.add(11, 7, 2);
    lights.add(12, 7, 1);
    lights.add(13, 8, 0);
    lights
}

fn states(lights: &TrafficLights) -> Vec<LightState> {
    (10..=13)
        .map(|a| lights.reading(a).expect("a light").state)
        .collect()
}

use LightState::{Green as G, Red as R, Yellow as Y};

#[test]
fn a_groups_lights_take_turns_in_pole_order() {
    let mut l = lights();
    assert_eq!(states(&l), [G, R, R, G]);
    // 10 s green, 3 s yellow, 2 s all red, then the next pole (12).
    let steps = [
        (10 * S - 1, [G, R, R, G]),
        (1, [Y, R, R, Y]),
        (3 * S, [R, R, R, R]),
        (2 * S, [R, R, G, G]),
        (15 * S, [R, G, R, G]),
        (15 * S, [G, R, R, G]),
    ];
    for (delta, expected) in steps {
        l.advance(delta);
        assert_eq!(states(&l), expected, "after {delta} ns more");
    }
    // Elapsed counts the current light's phase; a waiting light's is 0.
    assert_eq!(l.reading(10).unwrap().elapsed_seconds, 0.0);
    l.advance(S / 2);
    assert_eq!(l.reading(10).unwrap().elapsed_seconds, 0.5);
    assert_eq!(l.reading(12).unwrap().elapsed_seconds, 0.0);
    l.advance(10 * S);
    assert_eq!(l.reading(10).unwrap().elapsed_seconds, 0.5);
}

#[test]
fn a_frozen_group_holds_and_a_reset_starts_it_again() {
    let mut l = lights();
    l.advance(11 * S);
    assert!(l.freeze(10, true));
    l.advance(100 * S);
    assert_eq!(states(&l), [Y, R, R, G]);
    assert!(l.reading(11).unwrap().frozen && !l.reading(13).unwrap().frozen);
    assert!(l.reset(0));
    assert_eq!(states(&l), [G, R, R, G]);
    // Still frozen after the reset; unfreezing goes on from there.
    l.advance(20 * S);
    assert_eq!(states(&l)[..3], [G, R, R]);
    assert!(l.freeze(0, false));
    l.advance(10 * S);
    assert_eq!(states(&l)[..3], [Y, R, R]);
    assert!(!l.freeze(99, true) && !l.reset(99));
}

#[test]
fn a_state_shown_by_a_script_holds_until_the_cycle_reaches_the_light() {
    let mut l = lights();
    assert!(l.set_state(11, G));
    assert!(!l.set_state(99, G));
    l.advance(15 * S);
    // 12's turn came; 11 was not touched by it.
    assert_eq!(states(&l)[..3], [R, G, G]);
    l.advance(15 * S);
    // 11's own turn: green, then yellow.
    l.advance(10 * S);
    assert_eq!(states(&l)[..3], [R, Y, R]);
}

#[test]
fn times_change_the_next_phase_and_zero_times_never_hang() {
    let mut l = lights();
    assert!(l.set_times(10, [Some(1.0), None, Some(0.0)]));
    assert_eq!(l.times(10), Some([1.0, 3.0, 0.0]));
    l.advance(S);
    assert_eq!(states(&l)[0], Y);
    l.advance(3 * S);
    // No all-red time: the next pole is green at once.
    assert_eq!(states(&l)[..3], [R, R, G]);
    for actor in 10..=12 {
        l.set_times(actor, [Some(0.0); 3]);
    }
    l.advance(S);
    assert!(l.times(99).is_none() && !l.set_times(99, [None; 3]));
}
