"""CARLA's fixed time-step, with simbus: every frame advances exactly
0.05 s of simulation time (20 frames per simulated second), however long
the server takes to compute it.

    python fixed_step.py --world W [--delta-seconds 0.05] [--frames N]
"""

import argparse

import simbus


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default="default")
    parser.add_argument("--delta-seconds", type=float, default=0.05)
    parser.add_argument("--frames", type=int, default=10)
    args = parser.parse_args()

    client = simbus.connect(args.world)
    # settings.fixed_delta_seconds = 0.05; world.apply_settings(settings)
    client.apply_settings(fixed_delta_seconds=args.delta_seconds)
    print(f"fixed_delta_seconds = {client.settings().fixed_delta_seconds}")
    seen = 0
    for frame in client.frames():
        with frame:
            if frame.delta_seconds != args.delta_seconds:
                continue  # a frame computed before the settings took hold
            # Asynchronous: a reader slower than the server skips frames
            # (`missed`); each still advanced exactly dt.
            print(f"frame {frame.frame} t = {frame.elapsed_ns} ns dt = {frame.delta_seconds} s"
                  f" missed {frame.missed}")
        seen += 1
        if seen == args.frames:
            break
    client.apply_settings(fixed_delta_seconds=0)


if __name__ == "__main__":
    main()
