"""simbus.gym on a Ray cluster of two nodes, each node a network namespace
of this machine (root only; the fault suite runs it, bench/run-fault-suite):

1. two namespaces joined by a veth pair, a Ray head in the first and a Ray
   node in the second, each with 4 CPUs;
2. a driver in the first runs `simbus.gym.RayVectorEnv` with 4 worlds, one
   per Ray actor, spread over both nodes (their servers start on the node
   that owns them);
3. at step `--kill-at` every process of the second node is SIGKILLed (its
   raylet, its actors, their servers): the driver notices, starts the lost
   worlds again on the first node and replays their episodes;
4. the lost worlds are reported in `info["restarted"]` on the step of the
   kill and run on the first node after it, and no step is lost or
   repeated: every world's steps since its episode began go up by one each
   step, across the recovery;
5. every batch equals the batch of the same seeds and actions run without
   Ray in one process, bit for bit.

    sudo target/simbus-venv/bin/python tests/python/ray_two_nodes.py --bin-dir target/debug

Exit status 0 when all holds; everything it started is killed and removed
at the end, whatever happens."""

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile

DRIVER = r'''
import hashlib, json, os, sys, time
import numpy as np
import ray
import simbus.gym as sg
from simbus.gym.distributed import RayVectorEnv

address, kill_at, steps, worlds, node_b = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
task = dict(vehicles=3, walkers=2, max_episode_steps=25)
rng = np.random.default_rng(5)
actions = rng.uniform(-1, 1, size=(steps, worlds, 2)).astype(np.float32)
actions[:, :, 0] *= 0.3
actions[:, :, 1] = np.abs(actions[:, :, 1]) * 0.8

def digest(obs, reward, term, trunc):
    """One digest per world of a batch."""
    out = []
    for i in range(len(reward)):
        h = hashlib.sha256()
        for k in sorted(obs):
            h.update(np.ascontiguousarray(obs[k][i]).tobytes())
        for a in (reward, term, trunc):
            h.update(np.ascontiguousarray(a[i]).tobytes())
        out.append(h.hexdigest()[:16])
    return out

# The reference: the same seeds and actions without Ray, in this process.
def local_run():
    local = sg.VectorEnv("driving", num_envs=worlds, **task)
    obs, _ = local.reset(seed=9)
    out = [digest(obs, np.zeros(worlds), np.zeros(worlds, bool), np.zeros(worlds, bool))]
    for t in range(steps):
        obs, r, te, tr, _ = local.step(actions[t])
        out.append(digest(obs, r, te, tr))
    local.close()
    return out
reference = local_run()

ray.init(address=address, log_to_driver=False)
envs = RayVectorEnv(worlds, worlds_per_actor=1, seed=9, step_timeout=90, **task)
nodes = sorted(set(envs.nodes))
print(json.dumps({"nodes_at_start": envs.nodes}), flush=True)
assert len(nodes) == 2, f"the worlds did not spread over both nodes: {envs.nodes}"
obs, info = envs.reset()
got = [digest(obs, np.zeros(worlds), np.zeros(worlds, bool), np.zeros(worlds, bool))]
restarted = []
# No step lost or repeated: each world's steps since its episode began
# go up by one a step (or start again from 0 at its reset).
counts, miscounted = info["episode_steps"].copy(), []
ended = np.zeros(worlds, bool)
for t in range(steps):
    if t == kill_at:
        print(json.dumps({"kill": node_b, "step": t}), flush=True)
        input()  # the parent kills the node, then says go on
    started = time.monotonic()
    obs, r, te, tr, info = envs.step(actions[t])
    if "restarted" in info:
        restarted.append({"step": t, "worlds": np.flatnonzero(info["_restarted"]).tolist(),
                          "noticed_in_s": round(time.monotonic() - started, 2),
                          "why": [x for x in info["restarted"] if x][0]})
    expected = np.where(ended, 0, counts + 1)
    if not np.array_equal(info["episode_steps"], expected):
        miscounted.append({"step": t, "expected": expected.tolist(), "got": info["episode_steps"].tolist()})
    counts, ended = info["episode_steps"].copy(), te | tr
    got.append(digest(obs, r, te, tr))
print(json.dumps({"restarted": restarted, "nodes_at_end": envs.nodes, "miscounted": miscounted,
                  "equal": got == reference,
                  "first_difference": next(([i, [w for w in range(worlds) if a[w] != b[w]]]
                                            for i, (a, b) in enumerate(zip(got, reference)) if a != b), None)}),
      flush=True)
envs.close()
ray.shutdown()
recovered = bool(restarted) and restarted[0]["step"] == kill_at and all(n != node_b for n in envs.nodes)
sys.exit(0 if recovered and not miscounted and got == reference else 1)
'''


def sh(*args, check=True, **kw):
    """Runs a command; a failure raises with what it printed."""
    done = subprocess.run(list(args), capture_output=True, text=True, **kw)
    if check and done.returncode != 0:
        raise RuntimeError(f"{' '.join(args)} failed ({done.returncode}): {done.stderr.strip()[-2000:]}")
    return done


def netns_pids(ns):
    out = sh("ip", "netns", "pids", ns, check=False).stdout.split()
    return [int(p) for p in out if p.isdigit()]


def kill_netns(ns):
    for pid in netns_pids(ns):
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--bin-dir", default="target/debug")
    p.add_argument("--steps", type=int, default=60)
    p.add_argument("--kill-at", type=int, default=30)
    p.add_argument("--worlds", type=int, default=4)
    args = p.parse_args()
    if os.geteuid() != 0:
        sys.exit("needs root: it makes network namespaces")
    python = sys.executable
    ray_bin = os.path.join(os.path.dirname(python), "ray")
    tag = f"{os.getpid() % 100000}"
    a, b = f"sbray-a{tag}", f"sbray-b{tag}"
    octet = 100 + os.getpid() % 100
    ip_a, ip_b = f"10.{octet}.77.1", f"10.{octet}.77.2"
    temp = tempfile.mkdtemp(prefix="simbus-ray-")
    env = {**os.environ, "SIMBUS_BIN_DIR": os.path.abspath(args.bin_dir),
           "RAY_health_check_period_ms": "1000", "RAY_health_check_failure_threshold": "3",
           "RAY_USAGE_STATS_ENABLED": "0"}
    driver = None
    try:
        for ns in (a, b):
            sh("ip", "netns", "add", ns)
            sh("ip", "netns", "exec", ns, "ip", "link", "set", "lo", "up")
        sh("ip", "link", "add", f"va{tag}", "type", "veth", "peer", "name", f"vb{tag}")
        sh("ip", "link", "set", f"va{tag}", "netns", a)
        sh("ip", "link", "set", f"vb{tag}", "netns", b)
        sh("ip", "netns", "exec", a, "ip", "addr", "add", f"{ip_a}/24", "dev", f"va{tag}")
        sh("ip", "netns", "exec", b, "ip", "addr", "add", f"{ip_b}/24", "dev", f"vb{tag}")
        sh("ip", "netns", "exec", a, "ip", "link", "set", f"va{tag}", "up")
        sh("ip", "netns", "exec", b, "ip", "link", "set", f"vb{tag}", "up")
        port = "6390"
        system = '{"health_check_period_ms":1000,"health_check_failure_threshold":3}'
        sh("ip", "netns", "exec", a, ray_bin, "start", "--head", "--node-ip-address", ip_a, "--port", port,
           "--num-cpus", "4", "--include-dashboard=false", "--disable-usage-stats",
           "--temp-dir", os.path.join(temp, "a"), f"--system-config={system}", env=env, timeout=180)
        sh("ip", "netns", "exec", b, ray_bin, "start", "--address", f"{ip_a}:{port}", "--node-ip-address", ip_b,
           "--num-cpus", "4", "--disable-usage-stats", "--temp-dir", os.path.join(temp, "b"),
           env=env, timeout=180)
        print(f"ray cluster: head {ip_a} ({a}), node {ip_b} ({b})", flush=True)
        driver = subprocess.Popen(
            ["ip", "netns", "exec", a, python, "-c", DRIVER, f"{ip_a}:{port}", str(args.kill_at),
             str(args.steps), str(args.worlds), ip_b],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)
        for line in driver.stdout:
            print(line, end="", flush=True)
            if '"kill"' in line:
                kill_netns(b)
                print(f"killed every process of {b} ({ip_b})", flush=True)
                driver.stdin.write("\n")
                driver.stdin.flush()
        status = driver.wait(timeout=900)
        print("PASS" if status == 0 else "FAIL", flush=True)
        return status
    finally:
        if driver is not None and driver.poll() is None:
            driver.kill()
            driver.wait()
        for ns in (b, a):
            kill_netns(ns)
        for ns in (a, b):
            sh("ip", "netns", "del", ns, check=False)
        shutil.rmtree(temp, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
