"""The Python side of `simbus-bench python`: simbus's own package (the PyO3
extension, a release build) against a world. Every wait blocks, as the Rust
client's do by default. Prints one JSON object on its last line.

    python_bench.py tick WORLD N [MODE]
                                      ticker.tick() round trips (this client ticks,
                                      waiting as MODE says: block, the default, or hybrid)
    python_bench.py wait WORLD N      wait_for_frame: publish -> returned (another ticks)
    python_bench.py capture WORLD N W H
                                      a W x H depth camera: tick returned -> the
                                      capture's numpy array in hand
    python_bench.py depth WORLD N     640x480 depth frames per second: tick, read,
                                      array each frame
"""

import json
import sys
import time

import simbus


def tick(client, n):
    """Ticker.tick() round trips, n after n // 10 to warm up."""
    samples = []
    with client.ticker(delta_seconds=0.01) as ticker:
        for i in range(n + n // 10):
            start = time.perf_counter_ns()
            ticker.tick()
            elapsed = time.perf_counter_ns() - start
            if i >= n // 10:
                samples.append(elapsed)
    return {"ns": samples}


def wait(client, n):
    """Frame published (its platform timestamp) -> wait_for_frame returned."""
    client.wait_for_frame(30.0).release()
    print("ready", flush=True)
    samples = []
    while len(samples) < n:
        with client.wait_for_frame(30.0) as frame:
            received = time.time_ns()
            samples.append(received - int(frame.timestamp * 1e9))
    return {"ns": samples}


def capture(client, n, width, height):
    """Tick returned -> the W x H capture's numpy array in hand (its first
    and last element read), n after n // 10 to warm up."""
    samples = []
    with client.ticker(delta_seconds=0.01) as ticker:
        sensor = client.spawn_sensor("depth", at=(0.0, 2.0, 0.0), width=width, height=height)
        for i in range(n + n // 10):
            frame = ticker.tick()
            start = time.perf_counter_ns()
            captured = sensor.read(30.0)
            array = captured.array
            array[0, 0], array[-1, -1]
            elapsed = time.perf_counter_ns() - start
            assert captured.frame == frame and array.shape == (height, width)
            del array
            captured.release()
            if i >= n // 10:
                samples.append(elapsed)
        sensor.destroy()
    return {"ns": samples}


def depth(client, n):
    """640x480 depth frames per second: tick, then the capture as a numpy
    array, each frame."""
    with client.ticker(delta_seconds=0.01) as ticker:
        sensor = client.spawn_sensor("depth", at=(0.0, 2.0, 0.0), width=640, height=480)
        for _ in range(5):
            ticker.tick()
            with sensor.read(30.0) as captured:
                captured.array.shape
        start = time.perf_counter()
        for _ in range(n):
            frame = ticker.tick()
            captured = sensor.read(30.0)
            array = captured.array
            assert captured.frame == frame and array.shape == (480, 640)
            del array
            captured.release()
        elapsed = time.perf_counter() - start
        sensor.destroy()
    return {"fps": n / elapsed}


def main():
    mode, world, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
    mode_arg = sys.argv[4] if mode == "tick" and len(sys.argv) > 4 else "block"
    client = simbus.connect(world, timeout=30.0, wait_mode=mode_arg)
    if mode == "tick":
        answer = tick(client, n)
    elif mode == "wait":
        answer = wait(client, n)
    elif mode == "capture":
        answer = capture(client, n, int(sys.argv[4]), int(sys.argv[5]))
    elif mode == "depth":
        answer = depth(client, n)
    else:
        raise SystemExit(f"unknown mode {mode}")
    print(json.dumps(answer))


if __name__ == "__main__":
    main()
