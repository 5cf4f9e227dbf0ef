"""Spawn-then-destroy in asynchronous mode. CARLA 0.9.16's client drops
`actor.destroy()` for an actor its latest world state does not hold (it
reads the actor's state from that snapshot and warns "attempting to destroy
an actor that is already dead"), so the gateway writes a world state holding
a new actor to every world-stream reader before it answers the spawn.

The client reads the world stream and the answer on two threads, so on a
busy machine its main thread can still act on the answer before its
streaming thread has read the world state (CARLA's own server leaves the
same race, wider); a test through the `carla` module could only sample that
race. What the gateway guarantees is the order on the wire, and that is what
this test checks with raw sockets: when the spawn's answer arrives, the
world state holding the new actor is already in the reader's socket. The
world runs paced at 20 frames/s, so a world state that merely came with the
next frame would come up to 50 ms late."""

import select
import socket
import struct
import time

import pytest

from test_carla_actors_sensors import Raw

SENSOR_HEADER_LEN, EPISODE_HEADER_LEN, ACTOR_STATE_LEN = 48, 36, 119
BOX = [1, "static.prop.box", []]


def value_of(result):
    """The value of CARLA's `Response<T>` `[[1, value]]`."""
    assert result[0][0] == 1, result
    return result[0][1]


def world_stream(gateway, raw):
    """A raw reader of the world stream, subscribed by the token
    `get_episode_info` hands out."""
    _episode, [token] = value_of(raw.call("get_episode_info"))
    stream_id = struct.unpack_from("<I", token)[0]
    reader = socket.create_connection(("127.0.0.1", gateway.streaming_port))
    reader.sendall(struct.pack("<I", stream_id))
    return reader


class Messages:
    """The `[u32 length][message]` frames a stream reader has received."""

    def __init__(self, reader):
        self.reader, self.buffer = reader, b""

    def pending(self, wait=0.0):
        """The whole messages already in the socket; with `wait`, waiting
        up to that many seconds for at least one."""
        deadline = time.monotonic() + wait
        out = []
        while True:
            remaining = max(0.0, deadline - time.monotonic())
            ready, _, _ = select.select([self.reader], [], [], remaining if not out else 0)
            while ready:
                data = self.reader.recv(1 << 20)
                assert data, "the gateway closed the world stream"
                self.buffer += data
                ready, _, _ = select.select([self.reader], [], [], 0)
            while len(self.buffer) >= 4:
                (length,) = struct.unpack_from("<I", self.buffer)
                if len(self.buffer) < 4 + length:
                    break
                out.append(self.buffer[4:4 + length])
                self.buffer = self.buffer[4 + length:]
            if out or time.monotonic() >= deadline:
                return out


def actor_ids(world_state):
    start = SENSOR_HEADER_LEN + EPISODE_HEADER_LEN
    return {
        struct.unpack_from("<I", world_state, offset)[0]
        for offset in range(start, len(world_state), ACTOR_STATE_LEN)
    }


@pytest.mark.parametrize("gateway", [["--realtime", "--delta-seconds", "0.05"]], indirect=True)
def test_the_world_state_holding_a_new_actor_is_sent_before_the_spawns_answer(gateway):
    raw = Raw(gateway.port)
    messages = Messages(world_stream(gateway, raw))
    assert messages.pending(wait=10.0), "the world stream delivers"
    for i in range(5):
        messages.pending()  # what came before the spawn
        record = value_of(raw.call("spawn_actor", BOX, [[20.0 + 2 * i, 20.0, 1.0], [0.0, 0.0, 0.0]]))
        actor = record[0]
        # Already in the socket: no wait for the next frame.
        held = [m for m in messages.pending() if actor in actor_ids(m)]
        assert held, f"spawn {i}: no world state holding actor {actor} before its answer"
        assert value_of(raw.call("destroy_actor", actor)) is True
