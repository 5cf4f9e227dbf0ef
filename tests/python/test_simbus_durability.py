"""Snapshots and restarts from Python: a restored snapshot gives the digests
of the run after its save, a client reads on through a server killed with
SIGKILL and resumed from its journal (`next_event` hands out a
`simbus.Reconnected`), and a ticker that follows restarts claims the
resumed world itself (`simbus.Restarted`); the status names the journal
and the run the resumed server continues."""

import pytest

import simbus

from simbus_support import frame_at, server  # noqa: F401 (a fixture)


def run(client, ticker, frames):
    """(source frame, digest) of `frames` ticks, a push every 10th."""
    out = []
    for i in range(frames):
        if i % 10 == 0:
            client.apply_batch_sync([simbus.ApplyImpulse(BOX, (0.5, 2.0, 0.0))])
        frame = frame_at(client, ticker.tick())
        out.append((frame.frame, frame.digest))
    return out


BOX = None


def test_a_restored_snapshot_digests_as_the_run_after_its_save(server):
    global BOX
    client = server("--sync", "--fps", "20").client()
    with client.ticker(delta_seconds=0.05) as ticker:
        with client.wait_for_frame(timeout=10) as first:
            BOX = int(first.actors[first.actors["kind"] == 2]["id"][0])
        for _ in range(30):
            ticker.tick()
        snapshot = client.save_snapshot()
        [info] = client.snapshots()
        assert (info.id, info.frame) == (snapshot, 30)
        after_save = run(client, ticker, 40)
        frame = client.restore_snapshot(snapshot)
        assert frame == after_save[-1][0] + 1, "frame ids go on"
        assert frame_at(client, frame).frame == frame
        after_restore = run(client, ticker, 40)
        assert [d for _, d in after_restore] == [d for _, d in after_save]
        with pytest.raises(KeyError):
            client.restore_snapshot(999)
        client.drop_snapshot(snapshot)
        assert client.snapshots() == []


def test_clients_ride_through_a_killed_and_resumed_server(server, tmp_path):
    journal = str(tmp_path / "journal")
    first = server("--sync", "--fps", "20", "--journal", journal)
    client = first.client()
    status = client.status()
    assert status.run_pid == status.server_pid == first.proc.pid
    # (The status has room for the directory's first 64 bytes.)
    assert status.journal.writing and journal.startswith(status.journal.dir)
    assert status.snapshots == 0
    with client.ticker(delta_seconds=0.05) as ticker:
        ticker.follow_restarts(30.0)
        for _ in range(25):
            ticker.tick()
        while client.next_event(timeout=1).frame < 25:
            pass
        first.proc.kill()
        first.proc.wait()
        second = server("--resume", journal, world=first.world)
        with pytest.raises(simbus.Restarted) as restarted:
            ticker.tick()
        assert restarted.value.resumed_at == 25
        assert restarted.value.server_pid == second.proc.pid
        event = client.next_event(timeout=30)
        assert isinstance(event, simbus.Reconnected)
        assert (event.resumed_at, event.server_pid) == (25, second.proc.pid)
        with client.next_event(timeout=10) as resumed:
            assert resumed.frame == 25
        assert ticker.tick() == 26
        with client.next_event(timeout=10) as frame:
            assert frame.frame == 26
        resumed = client.status()
        assert (resumed.server_pid, resumed.run_pid) == (second.proc.pid, first.proc.pid)
        assert resumed.journal.durable_frame == 26
