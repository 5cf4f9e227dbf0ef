"""CARLA's synchronous mode with a camera queue, with simbus: the client is
the ticker, a depth camera's captures go into a queue, and every tick is
followed by the capture of that very frame.

    python synchronous_mode.py --world W [--frames N]
"""

import argparse
import queue

import simbus


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default="default")
    parser.add_argument("--frames", type=int, default=10)
    args = parser.parse_args()

    client = simbus.connect(args.world)
    # settings.synchronous_mode = True; settings.fixed_delta_seconds = 0.05
    with client.ticker(delta_seconds=0.05) as ticker:
        camera = client.spawn_sensor("depth", at=(-4.0, 3.0, 0.0), width=320, height=240)
        image_queue = queue.Queue()
        # camera.listen(image_queue.put): captures arrive on a thread of
        # their own; copy() keeps one after its shared memory goes back.
        listening = camera.listen(lambda capture: image_queue.put(capture.copy()))
        try:
            for _ in range(args.frames):
                frame = ticker.tick()  # world.tick()
                image = image_queue.get(timeout=5)  # image_queue.get()
                while image.frame < frame:  # captures from before this tick
                    image = image_queue.get(timeout=5)
                depth = image.array
                print(f"frame {frame}: image of frame {image.frame}, {depth.shape[1]}x"
                      f"{depth.shape[0]}, nearest {depth.min():.2f} m")
        finally:
            listening.stop()
            camera.destroy()


if __name__ == "__main__":
    main()
