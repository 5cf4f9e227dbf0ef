"""CARLA's variable time-step, with simbus: each frame advances by the wall
time the server took (the default; the simulation is not repeatable).

    python variable_step.py --world W [--frames N]
"""

import argparse

import simbus


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default="default")
    parser.add_argument("--frames", type=int, default=10)
    args = parser.parse_args()

    client = simbus.connect(args.world)
    # settings.fixed_delta_seconds = None: a fixed step of 0 asks for the variable step.
    client.apply_settings(fixed_delta_seconds=0)
    print(f"fixed_delta_seconds = {client.settings().fixed_delta_seconds}")
    for frame in client.frames():
        with frame:
            print(f"frame {frame.frame} dt = {frame.delta_seconds:.6f} s")
        args.frames -= 1
        if args.frames == 0:
            break


if __name__ == "__main__":
    main()
