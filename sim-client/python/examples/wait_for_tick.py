"""CARLA's `world.wait_for_tick()` and `on_tick`, with simbus: a client that
does not tick waits for the frames another client (or the server, in
asynchronous mode) computes.

    python wait_for_tick.py --world W [--frames N]
"""

import argparse

import simbus


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default="default")
    parser.add_argument("--frames", type=int, default=5)
    args = parser.parse_args()

    client = simbus.connect(args.world)
    # world_snapshot = world.wait_for_tick()
    with client.wait_for_frame(timeout=10) as snapshot:
        print(f"frame {snapshot.frame} at {snapshot.elapsed_seconds:.3f} s, "
              f"{len(snapshot.actors)} actors")
    # world.on_tick(lambda world_snapshot: do_something(world_snapshot))
    for n, snapshot in enumerate(client.frames(timeout=10)):
        with snapshot:
            moving = (abs(snapshot.actors["linear_velocity"]).sum(axis=1) > 0).sum()
            print(f"frame {snapshot.frame}: {moving} actors moving")
        if n + 1 == args.frames:
            break


if __name__ == "__main__":
    main()
