"""Actors, batches and lockstep from Python against real servers: a spawn
and a destroy show in the next frame, a batch answers one result per
command (an unknown actor refused, the others applied), bad input raises
the right exception and changes nothing, and a lockstep participant holds
the tick until it is done and is dropped when it never is."""

import math
import threading

import numpy as np
import pytest

import simbus

from simbus_support import SimbusServer as Server, frame_at, server  # noqa: F401 (a fixture)
UNKNOWN = 987654321


def actor(frame, actor_id):
    rows = frame.actors[frame.actors["id"] == actor_id]
    assert len(rows) == 1, f"actor {actor_id} in frame {frame.frame}: {len(rows)} rows"
    return rows[0]


def test_a_spawn_and_a_destroy_show_in_the_next_frame(server):
    client = server().client()
    with client.ticker(delta_seconds=0.05) as ticker:
        before = frame_at(client, ticker.tick())
        sphere = client.spawn("sphere", at=(20.0, 6.0, 20.0), radius=0.25)
        assert sphere not in before.actors["id"]
        after = frame_at(client, ticker.tick())
        row = actor(after, sphere)
        assert row["kind"] == 3  # ActorKind::Sphere
        assert row["extent"][0] == np.float32(0.25)
        assert row["position"][0] == np.float32(20.0)
        assert len(after.actors) == len(before.actors) + 1
        assert client.status().actor_count == len(after.actors)

        client.destroy(sphere)
        gone = frame_at(client, ticker.tick())
        assert sphere not in gone.actors["id"]
        assert sorted(gone.actors["id"]) == sorted(before.actors["id"])
        with pytest.raises(simbus.CommandError, match=f"actor {sphere}: unknown actor"):
            client.destroy(sphere)


def test_a_batch_answers_each_command_and_refuses_only_the_bad_ones(server):
    client = server().client()
    with client.ticker(delta_seconds=0.05) as ticker:
        frame_at(client, ticker.tick())
        box = client.spawn("box", at=(20.0, 5.0, 20.0), half_extents=(0.3, 0.3, 0.3))
        results = client.apply_batch_sync([
            simbus.SetTargetVelocity(box, (2.0, 0.0, 0.0)),
            simbus.SetTargetVelocity(UNKNOWN, (1.0, 0.0, 0.0)),
            simbus.SpawnActor("sphere", (25.0, 5.0, 20.0), radius=0.5),
            simbus.SpawnActor("box", (25.0, 5.0, 25.0), half_extents=(0.0, 1.0, 1.0)),
            simbus.ApplyVehicleControl(box, throttle=1.0),
            simbus.SetEnableGravity(box, False),
        ])
        assert [r.status for r in results] == [
            "ok", "unknown_actor", "ok", "invalid_argument", "not_a_vehicle", "ok",
        ]
        assert [r.ok for r in results] == [True, False, True, False, False, True]
        assert results[0].actor_id == box and results[0].error is None
        assert results[1].actor_id == UNKNOWN
        assert results[1].error == f"actor {UNKNOWN}: unknown actor"
        sphere = results[2].actor_id
        assert sphere not in (0, box)
        assert results[3].actor_id == 0

        stepped = ticker.tick()
        assert {r.frame for r in results} == {stepped}, "the first frame to show the batch"
        frame = frame_at(client, stepped)
        assert actor(frame, sphere)["kind"] == 3
        # Gravity off, velocity set: it flies along x at 2 m/s, level.
        assert tuple(actor(frame, box)["linear_velocity"]) == (2.0, 0.0, 0.0)
        assert len(frame.actors) == client.status().actor_count


def test_bad_input_raises_before_sending_and_changes_nothing(server):
    client = server().client()
    with client.ticker(delta_seconds=0.05) as ticker:
        frame_at(client, ticker.tick())
        box = client.spawn("box", at=(20.0, 5.0, 20.0))
        client.apply_batch_sync([simbus.SetEnableGravity(box, False)])
        start = frame_at(client, ticker.tick())
        status = client.status()

        with pytest.raises(ValueError, match="finite"):
            simbus.SetTargetVelocity(box, (math.nan, 0.0, 0.0))
        with pytest.raises(ValueError, match="finite"):
            simbus.ApplyImpulse(box, (0.0, math.inf, 0.0))
        with pytest.raises(ValueError, match="finite"):
            simbus.ApplyForce(box, (1e39, 0.0, 0.0))  # beyond f32
        with pytest.raises(ValueError, match="3 values"):
            simbus.SetTargetVelocity(box, (1.0, 0.0))
        with pytest.raises(TypeError, match="sequence of 3 numbers"):
            simbus.SetTargetVelocity(box, "abc")
        with pytest.raises(TypeError, match="actor_id must be an int"):
            simbus.SetTargetVelocity(str(box), (1.0, 0.0, 0.0))
        with pytest.raises(ValueError, match="actor_id"):
            simbus.DestroyActor(-1)
        with pytest.raises(TypeError):
            simbus.Command()
        # A batch with one bad item sends nothing, not even the good ones.
        with pytest.raises(TypeError, match=r"commands\[1\]"):
            client.apply_batch_sync([simbus.SetTargetVelocity(box, (5.0, 0.0, 0.0)), 42])
        with pytest.raises(TypeError, match=r"commands\[0\]"):
            client.apply_batch([(box, 1.0)])
        with pytest.raises(TypeError):
            client.apply_batch_sync(5)
        with pytest.raises(ValueError, match="unknown actor kind 'teapot'"):
            client.spawn("teapot")
        with pytest.raises(ValueError, match="finite"):
            client.spawn("box", at=(math.nan, 1.0, 0.0))
        with pytest.raises(ValueError, match="radius"):
            client.spawn("box", radius=1.0)
        with pytest.raises(ValueError, match="actor_id"):
            client.destroy(-5)
        # The server's own checks: an unknown actor, a place out of range.
        with pytest.raises(simbus.CommandError, match=f"actor {UNKNOWN}: unknown actor"):
            client.destroy(UNKNOWN)
        with pytest.raises(simbus.CommandError, match="invalid argument"):
            client.spawn("box", at=(1e6, 1.0, 0.0))
        # Only the ticker's process may tick with a batch.
        other = Server()
        try:
            with pytest.raises(simbus.NotTickerError):
                other.client().apply_batch_sync([], tick=True)
        finally:
            other.stop()

        after = client.status()
        assert (after.frame, after.actor_count) == (status.frame, status.actor_count)
        frame = frame_at(client, ticker.tick())
        assert sorted(frame.actors["id"]) == sorted(start.actors["id"])
        assert tuple(actor(frame, box)["linear_velocity"]) == (0.0, 0.0, 0.0)


def test_the_ticker_process_steps_a_frame_with_its_batch(server):
    client = server().client()
    with client.ticker(delta_seconds=0.05) as ticker:
        last = ticker.tick()
        box = client.spawn("box", at=(20.0, 5.0, 20.0))
        results = client.apply_batch_sync([simbus.SetTransform(box, (21.0, 7.0, 20.0))], tick=True)
        assert [(r.ok, r.frame) for r in results] == [(True, last + 1)]
        frame = frame_at(client, last + 1)
        assert actor(frame, box)["position"][0] == np.float32(21.0)


def test_commands_read_back_what_they_send():
    spawn = simbus.SpawnActor("capsule", (1, 2, 3), radius=0.2, half_height=0.7)
    assert (spawn.kind, spawn.at, spawn.actor_id) == ("capsule", (1.0, 2.0, 3.0), None)
    velocity = simbus.SetTargetVelocity(7, np.array([1.0, 2.0, 3.0]), angular_velocity=[0, 0, 1])
    assert (velocity.actor_id, velocity.velocity, velocity.angular_velocity) == (
        7, (1.0, 2.0, 3.0), (0.0, 0.0, 1.0))
    assert repr(velocity) == (
        "SetTargetVelocity(7, velocity=(1.0, 2.0, 3.0), angular_velocity=(0.0, 0.0, 1.0))")
    drive = simbus.ApplyVehicleControl(4, throttle=0.5, steer=-0.25, hand_brake=True)
    assert (drive.throttle, drive.steer, drive.brake, drive.hand_brake) == (0.5, -0.25, 0.0, True)
    assert simbus.ApplyForce(3, (0, 1, 0)) == simbus.ApplyForce(3, [0.0, 1.0, 0.0])
    assert simbus.ApplyForce(3, (0, 1, 0)) != simbus.ApplyImpulse(3, (0, 1, 0))
    assert all(isinstance(c, simbus.Command) for c in (spawn, velocity, drive))


def wait_for_participants(client, count):
    """Until the world has `count` lockstep participants (joins and leaves
    have no event of their own; each status is a round trip)."""
    for _ in range(100_000):
        if client.status().participants == count:
            return
    raise AssertionError(f"never {count} participants: {client.status()}")


def test_a_participant_holds_the_tick_until_it_is_done(server):
    s = server("--lockstep-timeout", "60")
    client = s.client()
    ticked, claimed, failed = [], threading.Event(), []

    def tick_once():
        try:
            own = s.client()  # a client per thread: its ports are bound to it
            with own.ticker(delta_seconds=0.05) as ticker:
                claimed.set()
                ticked.append(ticker.tick(timeout=60))
        except BaseException as e:
            failed.append(e)
            claimed.set()

    with client.participant("py-traffic") as participant:
        assert participant.name == "py-traffic" and participant.active
        wait_for_participants(client, 1)
        thread = threading.Thread(target=tick_once)
        thread.start()
        try:
            claimed.wait(30)
            line = s.wait_line("a tick waits for a lockstep participant")
            assert "py-traffic" in line
            held = client.status().frame
            assert ticked == [] and not failed, "the tick went through without the participant"
            participant.done(held)
        finally:
            thread.join(60)
        assert not failed, failed
        assert ticked == [held + 1]
    wait_for_participants(client, 0)
    with pytest.raises(simbus.Error, match="left the lockstep"):
        participant.done(held + 1)
    assert not participant.active


def test_a_participant_with_a_window_lets_the_world_run_that_far_ahead(server):
    # Synchronous from the start: no frame before the ticker's first tick.
    s = server("--sync", "--delta-seconds", "0.05", "--lockstep-timeout", "60")
    client = s.client()
    with pytest.raises(ValueError, match="more than the 1000"):
        client.participant("py-greedy", window=1001)
    assert client.status().participants == 0
    with client.participant("py-windowed", window=2) as participant:
        wait_for_participants(client, 1)
        joined = client.status().frame
        with client.ticker(delta_seconds=0.05) as ticker:
            # Silent since it joined: two steps need nothing of it; the one
            # past joined + 2 needs its done with `joined`.
            assert ticker.tick(timeout=30) == joined + 1
            assert ticker.tick(timeout=30) == joined + 2
            (windowed,) = client.status().lockstep
            assert (windowed.name, windowed.window, windowed.lag) == ("py-windowed", 2, None)
            participant.done(joined)
            assert ticker.tick(timeout=30) == joined + 3
            assert client.status().lockstep[0].lag == 3  # done with `joined`
        assert not any("a tick waits" in line for line in s.lines), "".join(s.lines)


def test_a_participant_that_is_never_done_is_dropped_and_told(server):
    s = server("--lockstep-timeout", "1")
    client = s.client()
    participant = client.participant("py-idle")
    wait_for_participants(client, 1)
    with client.ticker(delta_seconds=0.05) as ticker:
        # Held until the server drops the participant (1 s), then stepped.
        frame = ticker.tick(timeout=30)
        # Read while the world is held: released, it runs on asynchronously
        # and a busy machine's client queue can move past this frame.
        seen = frame_at(client, frame)
    s.wait_line("lockstep participant did not report done in time")
    assert client.status().participants == 0
    with pytest.raises(TypeError, match="simbus.Frame"):
        participant.done("latest")
    with pytest.raises(simbus.Error, match="dropped from the lockstep") as raised:
        for _ in range(1000):
            participant.done(seen)  # a Frame: its own episode and id
            client.status()  # a round trip: the server answers the done meanwhile
    assert not isinstance(raised.value, simbus.TimeoutError)
    participant.leave()
