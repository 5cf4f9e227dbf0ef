//! The networks hold what CARLA's client needs: spawn points on lane
//! centres facing the way the lane drives, roads that meet where their
//! links say, and OpenDRIVE text that is a well-formed document.

use super::*;
use crate::scene::SceneName;

const SCENES: [SceneName; 6] = [
    SceneName::Default,
    SceneName::Empty,
    SceneName::Town,
    SceneName::Flat,
    SceneName::Boxes(1),
    SceneName::Boxes(100_000),
];

/// The distance from CARLA point `(x, y)` to the nearest driving lane
/// centre of a road outside the junctions, and that lane's heading there
/// in CARLA's yaw (degrees).
fn nearest_lane(network: &RoadNetwork, x: f64, y: f64) -> (f64, f64) {
    let mut best = (f64::MAX, 0.0);
    for road in network.roads.iter().filter(|r| r.junction.is_none()) {
        let length = road.length();
        for i in 0..=(length * 20.0) as usize {
            let pose = road.pose_at(i as f64 / 20.0);
            for lane in &road.lanes {
                let centre = pose.lateral(f64::from(lane.id) * LANE_WIDTH / 2.0);
                let d = (centre.x - x).hypot(-centre.y - y);
                if d < best.0 {
                    let hdg = if lane.id < 0 { pose.hdg } else { pose.hdg + PI };
                    best = (d, -hdg.to_degrees());
                }
            }
        }
    }
    best
}

#[test]
fn the_town_has_more_than_a_hundred_spawn_points_on_lane_centres_facing_the_traffic() {
    let town = network(SceneName::Town);
    let points = town.spawn_points();
    assert!(points.len() >= 100, "{}", points.len());
    for p in &points {
        let (d, yaw) = nearest_lane(&town, p.location[0], p.location[1]);
        assert!(d < 0.05, "{p:?} is {d} m off a lane centre");
        let turn = wrap((p.rotation[1] - yaw).to_radians()).abs();
        assert!(turn < 1e-3, "{p:?} faces {yaw}");
        assert_eq!(p.location[2], SPAWN_HEIGHT);
    }
    // No two share a place.
    for (i, a) in points.iter().enumerate() {
        for b in &points[i + 1..] {
            let d = (a.location[0] - b.location[0]).hypot(a.location[1] - b.location[1]);
            assert!(d > 3.0, "{a:?} and {b:?}");
        }
    }
}

#[test]
fn the_town_has_four_way_junctions_and_every_lane_end_leads_on() {
    let town = network(SceneName::Town);
    let four_way = town
        .junctions
        .iter()
        .filter(|j| j.connections.len() == 12)
        .count();
    assert_eq!(four_way, 4);
    // Junction ids are no road's (CARLA's client tells them apart by id).
    for junction in &town.junctions {
        assert!(junction.id as usize >= town.roads.len(), "{}", junction.id);
    }
    // No dead end: every two-way road's ends are linked.
    for road in town.roads.iter().filter(|r| r.junction.is_none()) {
        assert!(
            road.predecessor.is_some() && road.successor.is_some(),
            "{}",
            road.id
        );
    }
}

#[test]
fn linked_roads_meet_where_their_links_say() {
    for scene in SCENES {
        let net = network(scene);
        let end_of = |id: u32, contact: Contact| {
            let road = &net.roads[id as usize];
            match contact {
                Contact::Start => road.start,
                Contact::End => road.pose_at(road.length()),
            }
        };
        for road in &net.roads {
            let ends = [
                (road.predecessor, road.start),
                (road.successor, road.pose_at(road.length())),
            ];
            for (link, here) in ends {
                if let Some(Link::Road { id, contact }) = link {
                    let there = end_of(id, contact);
                    let gap = (there.x - here.x).hypot(there.y - here.y);
                    assert!(gap < 1e-6, "{scene}: road {} to {id}: {gap} m", road.id);
                }
            }
        }
    }
}

#[test]
fn every_scene_has_roads_and_a_well_formed_opendrive_with_a_geo_reference() {
    for scene in SCENES {
        let net = network(scene);
        assert!(!net.spawn_points().is_empty(), "{scene}");
        let text = net.to_opendrive();
        assert_eq!(check_opendrive(&text), Ok(()), "{scene}");
        assert!(text.contains("<geoReference><![CDATA[+proj=tmerc +lat_0=0 +lon_0=0"));
        assert!(text.contains("<speed max=\"30\" unit=\"km/h\"/>"));
        let roads = text.matches("<road ").count();
        assert_eq!(roads, net.roads.len());
        assert_eq!(text.matches("</road>").count(), roads);
    }
    // The same every time.
    assert_eq!(
        network(SceneName::Town).to_opendrive(),
        network(SceneName::Town).to_opendrive()
    );
}

#[test]
fn the_default_ring_stays_on_the_ground_and_away_from_the_action() {
    let ring = network(SceneName::Default);
    for p in ring.spawn_points() {
        let [x, y, _] = p.location;
        assert!(x.abs() < 45.0 && y.abs() < 45.0, "{p:?}");
        assert!(x.abs() > 25.0 || y.abs() > 25.0, "{p:?}");
    }
}

#[test]
fn texts_that_are_not_opendrive_are_refused_with_the_reason() {
    let cases = [
        ("", OpenDriveError::Missing("OpenDRIVE")),
        ("garbage", OpenDriveError::OutsideRoot(0)),
        (
            "<OpenDRIVE><header/><road>",
            OpenDriveError::Unterminated("road".into()),
        ),
        (
            "<OpenDRIVE><header/></road></OpenDRIVE>",
            OpenDriveError::Mismatched {
                expected: "OpenDRIVE".into(),
                found: "road".into(),
                at: 20,
            },
        ),
        (
            "<html><header/><road/></html>",
            OpenDriveError::Root("html".into()),
        ),
        (
            "<OpenDRIVE><header/></OpenDRIVE>",
            OpenDriveError::Missing("road"),
        ),
        (
            "<OpenDRIVE><road/></OpenDRIVE>",
            OpenDriveError::Missing("header"),
        ),
        (
            "<OpenDRIVE><header a=\"1",
            OpenDriveError::Unclosed {
                what: "a tag",
                at: 11,
            },
        ),
        (
            "<OpenDRIVE><header/><road/></OpenDRIVE><x/>",
            OpenDriveError::OutsideRoot(39),
        ),
    ];
    for (text, want) in cases {
        assert_eq!(check_opendrive(text), Err(want.clone()), "{text:?}");
        assert!(want.to_string().contains("OpenDRIVE") || want.to_string().contains("XML"));
    }
    let fine = "<?xml version=\"1.0\"?>\n<!-- a map -->\n<OpenDRIVE>\
                <header a=\"x > y\"><geoReference><![CDATA[<&>]]></geoReference></header>\
                <road id=\"0\"/></OpenDRIVE>\n";
    assert_eq!(check_opendrive(fine), Ok(()));
}

#[test]
fn the_towns_four_way_junctions_have_a_light_on_every_approach_and_its_tees_a_stop() {
    let town = network(SceneName::Town);
    let lights: Vec<&Signal> = town
        .signals
        .iter()
        .filter(|s| s.kind == SignalKind::TrafficLight)
        .collect();
    assert_eq!(lights.len(), 16);
    let stops = town.signals.iter().filter(|s| s.kind == SignalKind::Stop);
    assert_eq!(stops.count(), 8);
    let limits = town
        .signals
        .iter()
        .filter(|s| s.kind == SignalKind::SpeedLimit(30));
    assert_eq!(limits.count(), 8);
    for (i, signal) in town.signals.iter().enumerate() {
        assert_eq!(signal.id as usize, i + 1);
        // Beside its lane, off the road.
        assert!(signal.t.abs() > LANE_WIDTH, "{signal:?}");
        assert_eq!(signal.t.signum(), f64::from(signal.lane.signum()));
        // Its stop point on its lane's centre, heading as the lane drives:
        // it is in its own trigger volume, and a car heading the other
        // way is not.
        let (x, y) = (signal.stop.x, signal.stop.y);
        let (d, yaw) = nearest_lane(&town, x, -y);
        assert!(d < 0.05, "{signal:?} is {d} m off a lane centre");
        assert!(wrap((-yaw).to_radians() - signal.stop.hdg).abs() < 1e-6);
        if !matches!(signal.kind, SignalKind::SpeedLimit(_)) {
            assert_eq!(
                town.signal_at(
                    x - signal.stop.hdg.cos(),
                    y - signal.stop.hdg.sin(),
                    signal.stop.hdg
                )
                .map(|s| s.id),
                Some(signal.id)
            );
            assert!(town.signal_at(x, y, signal.stop.hdg + PI).is_none());
        }
    }
    // Per junction: four lights, poles 0 to 3.
    for junction in town.junctions.iter().filter(|j| j.connections.len() == 12) {
        let poles: Vec<u32> = town.lights_of(junction.id).map(|l| l.pole).collect();
        assert_eq!(poles, [0, 1, 2, 3]);
    }
    // A point on the lane past the stop line is at no light.
    let light = lights[0];
    let (sin, cos) = light.stop.hdg.sin_cos();
    assert!(town
        .signal_at(light.stop.x + cos, light.stop.y + sin, light.stop.hdg)
        .is_none());
}

#[test]
fn the_towns_opendrive_names_every_signal_and_the_controllers_of_its_lights() {
    let town = network(SceneName::Town);
    let text = town.to_opendrive();
    check_opendrive(&text).expect("well formed");
    assert_eq!(text.matches("<signal ").count(), town.signals.len());
    assert_eq!(text.matches("type=\"1000001\"").count(), 16);
    assert_eq!(text.matches("type=\"206\"").count(), 8);
    assert_eq!(
        text.matches("type=\"274\" subtype=\"30\" value=\"30\"")
            .count(),
        8
    );
    // Every light's controller, declared and listed by its junction.
    assert_eq!(text.matches("<control signalId=").count(), 16);
    assert_eq!(text.matches("<controller id=").count(), 32);
    // No scene but the town has signals.
    for scene in SCENES.into_iter().filter(|s| *s != SceneName::Town) {
        assert!(network(scene).signals.is_empty(), "{scene}");
    }
}
