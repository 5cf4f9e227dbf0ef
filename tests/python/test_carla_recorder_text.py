"""CARLA 0.9.16's own client gets CARLA's text from the recorder queries
through the gateway, so scripts that print or parse it (CARLA's
show_recorder_file_info.py prints it; users grep "Frames:", "Duration:" and
" Create" lines) work: `show_recorder_file_info` has CARLA's heading
(Version, Map, Date), a `Frame N at T seconds` line per frame with events
(every frame and its positions with show_all), ` Create ID: type_id (type)
at (x, y, z)` in CARLA's axes and centimetres, ` Destroy ID`, and the
`Frames:` / `Duration:` footer; `show_recorder_collisions` and
`show_recorder_actors_blocked` have CARLA's tables between the same heading
and footer."""

import json
import re

import carla

from conftest import synced

DATE = re.compile(r"^Date: \d\d/\d\d/\d\d \d\d:\d\d:\d\d$", re.M)


def frames_and_duration(text):
    """The footer as CARLA users read it."""
    frames = int(re.search(r"^Frames: (\d+)$", text, re.M).group(1))
    duration = float(re.search(r"^Duration: ([\d.]+) seconds$", text, re.M).group(1))
    return frames, duration


def created_at(text, actor_id, type_pattern):
    """The location of actor `actor_id`'s ` Create` line (its type id
    matching `type_pattern`), in centimetres."""
    number = r"(-?[\d.e+-]+)"
    line = re.search(
        rf"^ Create {actor_id}: {type_pattern} at \({number}, {number}, {number}\)$",
        text,
        re.M,
    )
    assert line, text
    return [float(line.group(i)) for i in (1, 2, 3)]


def test_file_info_is_carlas_text(gateway, tmp_path):
    client, world = synced(gateway)
    library = world.get_blueprint_library()
    path = str(tmp_path / "run.mcap")
    assert client.start_recorder(path, False) == path
    world.tick()
    box = world.spawn_actor(
        library.find("static.prop.box"), carla.Transform(carla.Location(x=20, y=-20, z=5))
    )
    car = world.spawn_actor(
        library.filter("vehicle.*")[0], carla.Transform(carla.Location(x=-30, y=30, z=1))
    )
    world.tick()
    world.tick()
    box.destroy()
    world.tick()
    client.stop_recorder()

    text = client.show_recorder_file_info(path, False)
    lines = text.splitlines()
    assert lines[0] == "Version: 1", text
    assert lines[1].startswith("Map: ") and lines[1] != "Map: ", text
    assert DATE.search(text), text
    # Five frames (the one published when recording started, four ticks),
    # 0.05 s apart.
    frames, duration = frames_and_duration(text)
    assert frames == 5
    assert abs(duration - 0.2) < 1e-9
    info = json.loads(gateway.sim_client("recorder", "info", path, "--json").stdout)
    assert info["frames"] == frames
    # Every actor there at the start is created in frame 1, as CARLA's
    # recorder adds the actors that exist when it starts.
    assert "\nFrame 1 at 0 seconds\n Create " in text, text
    # Spawned actors are created where they are, in CARLA's axes and
    # centimetres; the box falls, the car stands on the ground.
    x, y, z = created_at(text, box.id, r"static\.prop\.box \(0\)")
    assert (abs(x - 2000) < 1, abs(y + 2000) < 1, z <= 500) == (True, True, True), text
    x, y, _ = created_at(text, car.id, r"vehicle\.[\w.]+ \(1\)")
    assert abs(x + 3000) < 20 and abs(y - 3000) < 20, text
    assert re.search(rf"^ Destroy {box.id}$", text, re.M), text
    # Without show_all a frame is listed only for its events.
    for i, line in enumerate(lines):
        if line.startswith("Frame "):
            assert lines[i + 1].startswith(" "), text

    everything = client.show_recorder_file_info(path, True)
    titles = re.findall(r"^Frame (\d+) at ([\d.e+-]+) seconds$", everything, re.M)
    assert [int(n) for n, _ in titles] == [1, 2, 3, 4, 5], everything
    assert [round(float(t), 9) for _, t in titles] == [0, 0.05, 0.1, 0.15, 0.2]
    assert len(re.findall(r"^ Positions: \d+$", everything, re.M)) == 5
    assert re.search(rf"^  Id: {car.id} Location: \(.*\) Rotation: \(.*\)$", everything, re.M)
    assert frames_and_duration(everything) == (frames, duration)


def test_collisions_and_blocked_actors_are_carlas_tables(gateway, tmp_path):
    client, world = synced(gateway)
    # The default scene: boxes fall onto the ground; its vehicles stand.
    # From its start: a loaded machine may have run the young world past
    # the fall before this test's first call.
    world = client.reload_world(False)
    path = str(tmp_path / "scene.mcap")
    assert client.start_recorder(path, False) == path
    for _ in range(40):
        world.tick()
    client.stop_recorder()

    collisions = client.show_recorder_collisions(path, "a", "a")
    assert collisions.startswith("Version: 1\nMap: "), collisions
    assert DATE.search(collisions), collisions
    assert re.search(r"^\s+Time\s+Types\s+Id\s+Actor 1\s+Id\s+Actor 2\s*$", collisions, re.M)
    rows = re.findall(
        r"^\s*(\d+)\s+([ov]) ([ov])\s+(\d+) (\S+)\s+(\d+) (\S+)\s*$", collisions, re.M
    )
    assert any("static.prop.fixed" in (r[4], r[6]) for r in rows), collisions
    # CARLA's stream writes the duration in whole seconds after a row.
    assert frames_and_duration(collisions) == (41, 2.0)
    assert collisions.endswith("\nFrames: 41\nDuration: 2 seconds\n")

    # Still for 0.5 s within 10 cm: the standing vehicles, all along.
    blocked = client.show_recorder_actors_blocked(path, 0.5, 10.0)
    assert DATE.search(blocked), blocked
    assert re.search(r"^\s+Time\s+Id\s+Actor\s+Duration$", blocked, re.M), blocked
    rows = re.findall(r"^\s*(\d+)\s+(\d+)\s+(\S+)\s+(\d+)$", blocked, re.M)
    vehicles = [r for r in rows if r[2].startswith("vehicle.")]
    assert len(vehicles) >= 1, blocked
    assert all(r[3] == "2" for r in vehicles), blocked
    durations = [int(r[3]) for r in rows]
    assert durations == sorted(durations, reverse=True), blocked
    assert not any(r[2] == "static.prop.fixed" for r in rows), blocked
    assert frames_and_duration(blocked) == (41, 2.0)
