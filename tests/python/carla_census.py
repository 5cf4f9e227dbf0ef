"""The CARLA census: every script of CARLA 0.9.16's `PythonAPI/examples`
and `PythonAPI/util` run against a fresh simbus server and CARLA gateway
of its own, headless, and the table the CARLA chapter shows written from
what happened.

    python tests/python/carla_census.py --python-api ~/carla/PythonAPI \\
        --bin-dir target/release --out census.md [--json census.json]

For each script: a `sim-server --scene town` on a world of its own and a
`sim-client carla-gateway` on `--port` (CARLA's 2000 by default, which
the scripts use), then the script itself, with `SDL_VIDEODRIVER=dummy`, its
own folder as the working directory and `PythonAPI/carla` on the path (for
`agents`), given `--port` when it takes one, and the arguments
`SCRIPT_ARGS` lists. A script still running after `--seconds` gets Ctrl-C
(SIGINT), and is killed 10 s later; every process is reaped.

A result is one of:
- `runs`: it exited 0 (or, stopped with Ctrl-C, ended on
  `KeyboardInterrupt` or cleanly: a script that loops until stopped);
- `fails`: it exited otherwise; the why is the last line of its traceback
  (or of its output);
- `not run`: `NOT_RUN` says why (it needs what only CARLA has).
"""

import argparse
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time

# Scripts that need more than a server to start: the arguments they get.
# `{recording}`: the file `start_recording.py` (run first) records, by
# its absolute path (each script runs in its own folder, each pair anew).
SCRIPT_ARGS = {
    "start_recording.py": ["-f", "{recording}"],
    "start_replaying.py": ["-f", "{recording}"],
    "show_recorder_file_info.py": ["-f", "{recording}"],
    "show_recorder_collisions.py": ["-f", "{recording}", "-t", "va"],
    "show_recorder_actors_blocked.py": ["-f", "{recording}"],
    "environment.py": ["--sun", "sunset", "--weather", "rain"],
    "extract_spawn_points.py": ["-o", "{scratch}"],
}

# Scripts run before the others, in this order (what they make, the
# others read).
FIRST = ["start_recording.py"]

# Scripts not run, and why (what only CARLA has).
NOT_RUN = {
    "V2XDemo.py": "CARLA's V2X sensors (`sensor.other.v2x`, `v2x_custom`) simulate radio links between Unreal actors",
    "test_addsecondvx.py": "CARLA's V2X sensors (`sensor.other.v2x`)",
    "get_component_test.py": "Unreal's actor components (`get_actor_component_world_transform` of a mesh's parts)",
    "tutorial_gbuffer.py": "Unreal's render G-buffer textures (`enable_gbuffers`)",
    "apply_texture.py": "Unreal's materials and textures (`apply_color_texture_to_object`)",
    "invertedai_traffic.py": "Inverted AI's cloud service (the `invertedai` package and an API key)",
    "manual_control_fisheye.py": "not a 0.9.16 script: its wide-angle lens cameras are not in 0.9.16's client",
}

# What a result owes to the script or the machine, not to simbus.
NOTES = {
    "check_lidar_bb.py": "it spawns its cars at Town10HD's coordinates: a building of simbus's town stands at one",
    "vehicle_physics_tester.py": "it spawns its cars at Town10HD's coordinates: a building of simbus's town stands at one",
    "start_replaying.py": "this PythonAPI's script passes `replay_file` an `offset` the 0.9.16 client does not take",
    "open3d_lidar.py": "Open3D needs `libusb-1.0` on the machine",
    "manual_control_steeringwheel.py": "it needs a steering wheel (joystick 0) on the machine",
    "draw_skeleton.py": "it ends its loop and cleans up on Ctrl-C; then its multiprocessing helper, interrupted by the same Ctrl-C, keeps the process from exiting: the script's own matter",
    "performance_benchmark.py": "it needs `tr`, `cpuinfo`, `psutil` and `GPUtil` in the Python it runs with",
}

# How long a script may take to start before its run counts (seconds).
GRACE = 10


def takes_port(path):
    """Whether the script reads `--port` (CARLA's scripts that connect)."""
    with open(path, errors="replace") as f:
        return "--port" in f.read()


def why(output):
    """The exception a traceback in `output` ends on (not the warnings
    printed after it), else its last line."""
    lines = [l.strip() for l in output.splitlines() if l.strip()]
    if "Traceback (most recent call last):" in output:
        tail = output.split("Traceback (most recent call last):")[-1]
        tail_lines = [l.strip() for l in tail.splitlines() if l.strip()]
        raised = [l for l in tail_lines
                  if re.match(r"^[A-Za-z_.]*(Error|Exception|Interrupt|Exit|\.error)\b", l)]
        if raised:
            return raised[-1]
        if tail_lines:
            return tail_lines[-1]
    return lines[-1] if lines else "no output"


def ctrl_c_reaches():
    """In the script's process: Ctrl-C interrupts Python (a runner started
    in the background of a shell inherits SIGINT ignored, and so would the
    scripts, which then never stop)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start_pair(bin_dir, world, port, log):
    """A server on `world` (the town) and a gateway on `port`; both
    processes, once the gateway says it listens."""
    server = subprocess.Popen(
        [os.path.join(bin_dir, "sim-server"), "--world", world, "--scene", "town"],
        stdout=subprocess.DEVNULL, stderr=log, start_new_session=True)
    gateway = subprocess.Popen(
        [os.path.join(bin_dir, "sim-client"), "--world", world, "--timeout", "10",
         # Any free streaming port: the scripts connect to the RPC port
         # only (port + 1 may be another process's).
         "carla-gateway", "--port", str(port), "--streaming-port", "0", "--json"],
        stdout=subprocess.PIPE, stderr=log, text=True, start_new_session=True)
    deadline = time.time() + 60
    while time.time() < deadline:
        line = gateway.stdout.readline()
        if '"streaming_port"' in line:
            return [server, gateway]
        if not line and gateway.poll() is not None:
            break
    stop([server, gateway])
    raise RuntimeError(f"the gateway on port {port} did not start")


def stop(procs):
    """Kills and reaps every process (and its group)."""
    for proc in reversed(procs):
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait(timeout=10)


def run_script(path, python_api, port, seconds, recording="census_recording.log", scratch="."):
    """Runs one script (`{recording}` in its arguments: `recording`;
    `{scratch}`: a folder for what it writes); its result, why, and its
    output's tail."""
    args = [sys.executable, path]
    if takes_port(path):
        args += ["--port", str(port)]
    args += [a.replace("{recording}", recording).replace("{scratch}", scratch)
             for a in SCRIPT_ARGS.get(os.path.basename(path), [])]
    env = {**os.environ, "SDL_VIDEODRIVER": "dummy",
           "PYTHONPATH": os.pathsep.join(
               [os.path.join(python_api, "carla"), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen(args, cwd=os.path.dirname(path), env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, start_new_session=True,
                            preexec_fn=ctrl_c_reaches)
    interrupted = False
    try:
        output, _ = proc.communicate(timeout=seconds)
    except subprocess.TimeoutExpired:
        interrupted = True
        os.killpg(proc.pid, signal.SIGINT)
        try:
            output, _ = proc.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            output, _ = proc.communicate()
            return "fails", f"did not stop within 10 s of Ctrl-C after {seconds} s", output
    stopped_by_us = interrupted and (
        "Traceback" not in output or why(output).startswith("KeyboardInterrupt"))
    if proc.returncode == 0 or stopped_by_us:
        note = f"looped until Ctrl-C after {seconds} s" if interrupted else "exited 0"
        return "runs", note, output
    return "fails", why(output), output


def scripts(python_api):
    """Every script of `examples/` and `util/`, in order."""
    found = []
    for folder in ("examples", "util"):
        directory = os.path.join(python_api, folder)
        if os.path.isdir(directory):
            found += [os.path.join(directory, n) for n in sorted(os.listdir(directory))
                      if n.endswith(".py")]
    first = [p for name in FIRST for p in found if os.path.basename(p) == name]
    return first + [p for p in found if p not in first]


def census(python_api, bin_dir, port, seconds, log):
    """One row per script: (folder/name, result, why)."""
    rows = []
    scratch = tempfile.mkdtemp(prefix="carla-census-")
    recording = os.path.join(scratch, "census_recording.log")
    every = scripts(python_api)
    for i, path in enumerate(every):
        name = os.path.relpath(path, python_api)
        reason = NOT_RUN.get(os.path.basename(path))
        if reason:
            rows.append((name, "not run", reason))
        else:
            procs = start_pair(bin_dir, f"census-{os.getpid()}-{i}", port, log)
            try:
                result, note, _ = run_script(path, python_api, port, seconds, recording, scratch)
            finally:
                stop(procs)
            extra = NOTES.get(os.path.basename(path))
            if extra and result != "runs":
                note = f"{note} ({extra})"
            rows.append((name, result, note))
        # Progress, for the person waiting.
        print(f"[{i + 1}/{len(every)}] {name}: {rows[-1][1]}", file=sys.stderr, flush=True)
    return rows


def table(rows):
    """The census as the CARLA chapter's markdown table."""
    out = ["| script | result | why |", "|---|---|---|"]
    for name, result, note in rows:
        note = re.sub(r"\|", "\\|", note)
        out.append(f"| {name} | {result} | {note} |")
    return "\n".join(out) + "\n"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--python-api", required=True, help="CARLA 0.9.16's PythonAPI folder")
    parser.add_argument("--bin-dir", default=os.environ.get("SIMBUS_BIN_DIR", "target/release"),
                        help="where sim-server and sim-client are")
    parser.add_argument("--port", type=int, default=2000, help="the gateway's port")
    parser.add_argument("--seconds", type=float, default=30.0,
                        help="Ctrl-C a script still running after this long")
    parser.add_argument("--out", help="write the markdown table here (default: stdout)")
    parser.add_argument("--json", help="also write the rows as JSON here")
    args = parser.parse_args()
    with tempfile.TemporaryFile("w+") as log:
        rows = census(os.path.abspath(args.python_api), os.path.abspath(args.bin_dir),
                      args.port, args.seconds, log)
    text = table(rows)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text)
    else:
        sys.stdout.write(text)
    if args.json:
        with open(args.json, "w") as f:
            json.dump([{"script": n, "result": r, "why": w} for n, r, w in rows], f, indent=1)


if __name__ == "__main__":
    main()
