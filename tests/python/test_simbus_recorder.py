"""The recorder from Python against real servers: ticked frames recorded to
a file, read back without a server (`simbus.recording.info`), and replayed
exactly in a fresh server with the recorded digests, frame for frame; a
file that is no recording, and bad arguments, raise and change nothing."""

import math
import os

import pytest

import simbus

from simbus_support import frame_at, server  # noqa: F401 (a fixture)
TICKS = 20


def record(client, path):
    """Records the frame now and TICKS ticked frames (a spawn and an
    impulse among them) into `path`; returns their (frame, digest)."""
    with client.ticker(delta_seconds=0.05) as ticker:
        first = frame_at(client, ticker.tick())
        written = client.start_recorder(path)
        assert written == str(path)
        assert client.recorder_status().recording
        seen = [(first.frame, first.digest)]
        for n in range(TICKS):
            if n == 3:
                box = client.spawn("box", at=(20.0, 4.0, 20.0))
            if n == 6:
                client.apply_batch_sync([simbus.ApplyImpulse(box, (3.0, 2.0, 0.0))])
            frame = frame_at(client, ticker.tick())
            seen.append((frame.frame, frame.digest))
        status = client.stop_recorder()
    assert (status.recording, status.path, status.frames) == (False, str(path), TICKS + 1)
    assert status.bytes == os.path.getsize(path)
    return seen


def test_recorded_frames_read_back_and_replay_with_their_digests(server, tmp_path):
    path = tmp_path / "run.mcap"
    world = server("--seed", "7").world
    recorded = record(simbus.connect(world, timeout=10.0), path)
    first, last = recorded[0][0], recorded[-1][0]

    info = simbus.recording.info(path)
    assert (info.frames, info.first_frame, info.last_frame) == (TICKS + 1, first, last)
    assert info.duration_seconds == pytest.approx(TICKS * 0.05)
    assert (info.commands, info.actors_spawned, info.episodes) == (2, 1, 0)
    assert (info.truncated, info.bytes) == (False, os.path.getsize(path))
    header = info.header
    assert (header.world, header.scene, header.seed, header.start_frame) == (
        world, "default", 7, first)
    assert header.settings.synchronous_mode and header.settings.fixed_delta_seconds == 0.05
    assert [e.frames for e in info.episode_list] == [TICKS + 1]
    listed = simbus.recording.info(str(path), show_all=True).frame_list
    assert [line[0] for line in listed] == [f for f, _ in recorded]

    # Exact replay in a fresh server: one recorded frame per tick.
    client = server().client()
    with client.ticker(delta_seconds=0.05) as ticker:
        status = client.replay(path, mode="exact")
        assert (status.replay.mode, status.replay.total) == ("exact", TICKS + 1)
        replayed = []
        for _ in range(TICKS + 5):
            frame = frame_at(client, ticker.tick())
            replayed.append(frame.digest)
            status = client.recorder_status()
            if status.replay.state != "running":
                break
    assert status.replay.state == "finished", status
    assert status.replay.frames == TICKS + 1
    assert replayed == [digest for _, digest in recorded]


def test_a_file_that_is_no_recording_raises_and_changes_nothing(server, tmp_path):
    garbage = tmp_path / "garbage.mcap"
    garbage.write_bytes(b"\x89MCAP0\r\n" + bytes(range(256)) * 16)
    text = tmp_path / "notes.txt"
    text.write_text("not a recording\n")
    with pytest.raises(simbus.Error, match="damaged|not an MCAP|not closed|not a simbus"):
        simbus.recording.info(garbage)
    with pytest.raises(simbus.Error, match="is not an MCAP file"):
        simbus.recording.info(text)
    with pytest.raises(simbus.Error, match="cannot read"):
        simbus.recording.info(tmp_path / "missing.mcap")
    with pytest.raises(simbus.Error, match="is a directory"):
        simbus.recording.info(tmp_path)
    with pytest.raises(TypeError):
        simbus.recording.info(42)

    client = server().client()
    before = client.recorder_status()
    with pytest.raises(simbus.Error, match="MCAP"):
        client.replay(text)
    with pytest.raises(ValueError, match="unknown replay mode"):
        client.replay(text, mode="backwards")
    with pytest.raises(ValueError, match="start"):
        client.replay(text, start=math.nan)
    with pytest.raises(ValueError, match="longer than"):
        client.start_recorder(tmp_path / ("x" * 2000))
    with pytest.raises(simbus.Error, match="no recording|not recording|No recording"):
        client.stop_recorder()
    with pytest.raises(simbus.Error):
        client.stop_replayer()
    after = client.recorder_status()
    assert (after.recording, after.replay.state) == (before.recording, before.replay.state)
    assert after.replay.state == "idle"


def test_a_recording_cut_short_reads_as_far_as_it_goes(server, tmp_path):
    path = tmp_path / "run.mcap"
    record(server().client(), path)
    assert simbus.recording.info(path).truncated is False
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:1000])
    with pytest.raises(simbus.Error, match="cut.mcap is still being recorded, or was not closed"):
        simbus.recording.info(cut)
    cut.write_bytes(data[: len(data) * 9 // 10])
    partial = simbus.recording.info(cut)
    assert partial.truncated is True
    assert partial.frames <= TICKS + 1
