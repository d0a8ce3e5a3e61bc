#!/usr/bin/python3
"""Wall-clock cost of mapping a sequence through the Python module against the CLI.

    /usr/bin/python3 scripts/python_overhead.py [examples/street] [--runs 3] [--threads 2]

Alternates `build/shine map DATA -o OUT --threads N -q` and a Python process doing the same work
through shinevdb (read_sequence -> NeuralMap.add_scan -> train -> write_products -> evaluate
against gt_mesh.ply, as `shine map` evaluates), each in a fresh process (interpreter start-up and
import included), and prints every run's wall-clock and CPU seconds (user + system of the child
process), their medians and the overheads. On a machine shared with other jobs the wall-clock
time mostly measures the others' load; the CPU time is the work each process did. It also checks
that both wrote the same mesh.ply, byte for byte.
"""

import argparse
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

REPO = pathlib.Path(__file__).resolve().parents[1]

PYTHON_RUN = """
import sys
import shinevdb
data, out, threads = sys.argv[1], sys.argv[2], int(sys.argv[3])
nmap = shinevdb.NeuralMap(threads=threads)
for points, pose, _ in shinevdb.read_sequence(data):
    nmap.add_scan(points, pose)
nmap.train(progress=False)
products = nmap.write_products(out)
metrics = shinevdb.evaluate(products["mesh"], data + "/gt_mesh.ply")
print(f"F-score {100 * metrics['fscore']:.2f} %")
"""


def timed(cmd):
    """(wall-clock seconds, CPU seconds) of running `cmd`."""
    start = time.monotonic()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.monotonic() - start
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise subprocess.CalledProcessError(proc.returncode, cmd)
    return wall, usage.ru_utime + usage.ru_stime


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("data", nargs="?", type=pathlib.Path, default=REPO / "examples" / "street")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--shine", type=pathlib.Path, default=REPO / "build" / "shine")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out_cli, out_py = pathlib.Path(tmp, "cli"), pathlib.Path(tmp, "py")
        cli_cmd = [str(args.shine), "map", str(args.data), "-o", str(out_cli), "--threads",
                   str(args.threads), "-q"]
        py_cmd = [sys.executable, "-c", PYTHON_RUN, str(args.data), str(out_py),
                  str(args.threads)]
        cli_s, py_s = [], []
        for run in range(args.runs):
            # Alternate which goes first, so that a drift in the machine's load hits both.
            order = [("cli", cli_cmd, cli_s), ("python", py_cmd, py_s)]
            for name, cmd, times in order if run % 2 == 0 else order[::-1]:
                times.append(timed(cmd))
                print(f"run {run + 1} {name:6s} wall {times[-1][0]:7.2f} s  "
                      f"cpu {times[-1][1]:7.2f} s", flush=True)
        same = (out_cli / "mesh.ply").read_bytes() == (out_py / "mesh.ply").read_bytes()
    for i, what in enumerate(("wall", "cpu")):
        cli_med = statistics.median(t[i] for t in cli_s)
        py_med = statistics.median(t[i] for t in py_s)
        print(f"median {what}: cli {cli_med:.2f} s, python {py_med:.2f} s, "
              f"overhead {100 * (py_med / cli_med - 1):+.1f} % ({args.runs} runs each)")
    # Each run's two processes ran back to back, under about the same load: their ratio.
    paired = statistics.median(p[0] / c[0] for c, p in zip(cli_s, py_s))
    print(f"median of the runs' python/cli wall-clock ratios: {100 * (paired - 1):+.1f} %")
    print(f"mesh.ply identical: {same}")


if __name__ == "__main__":
    main()
