"""CARLA's physics substepping, with simbus: each frame's physics runs in
substeps of at most `max_substep_delta_time`, at most `max_substeps` of
them, and a fixed step must fit:
fixed_delta_seconds <= max_substep_delta_time * max_substeps.

    python substepping.py --world W
"""

import argparse

import simbus


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default="default")
    args = parser.parse_args()

    client = simbus.connect(args.world)
    # settings.substepping = True; max_substep_delta_time = 0.01; max_substeps = 10
    client.apply_settings(substepping=True, max_substep_delta_time=0.01, max_substeps=10)
    settings = client.settings()
    print(f"substepping = {settings.substepping}, max_substep_delta_time = "
          f"{settings.max_substep_delta_time}, max_substeps = {settings.max_substeps}")
    # 0.1 s fits in 10 substeps of 0.01 s; 0.2 s does not, and is refused.
    client.apply_settings(fixed_delta_seconds=0.1)
    print(f"fixed_delta_seconds = {client.settings().fixed_delta_seconds}: accepted")
    try:
        client.apply_settings(fixed_delta_seconds=0.2)
    except simbus.SettingsError as error:
        print(f"fixed_delta_seconds = 0.2: refused ({error})")
    print(f"still {client.settings().fixed_delta_seconds}")
    client.apply_settings(fixed_delta_seconds=0)


if __name__ == "__main__":
    main()
