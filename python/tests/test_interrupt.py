"""Ctrl-C during a long call stops it after the current step with KeyboardInterrupt."""

import signal
import subprocess
import sys
import textwrap
import time

SCRIPT = textwrap.dedent("""
    import sys, time
    import shinevdb
    nmap = shinevdb.NeuralMap(threads=2)
    for points, pose, _ in shinevdb.read_sequence(sys.argv[1]):
        nmap.add_scan(points, pose)
    print("training", flush=True)
    start = time.monotonic()
    try:
        nmap.train(progress=False)
        print("finished", nmap.iterations_done, flush=True)
    except KeyboardInterrupt:
        print("interrupted", nmap.iterations_done, nmap.iterations_planned,
              f"{time.monotonic() - start:.2f}", flush=True)
        nmap.train(steps=1, progress=False)  # the map is still usable: training continues
        print("continued", nmap.iterations_done, flush=True)
""")


def test_ctrl_c_raises_keyboard_interrupt(small_sequence, tmp_path):
    script = tmp_path / "train.py"
    script.write_text(SCRIPT)
    proc = subprocess.Popen([sys.executable, str(script), str(small_sequence)],
                            stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "training"
    time.sleep(1.0)
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    out, _ = proc.communicate(timeout=60)
    stopped_after = time.monotonic() - sent
    lines = out.split("\n")
    assert lines[0].startswith("interrupted"), out
    _, done, planned, _ = lines[0].split()
    assert 0 < int(done) < int(planned)
    assert lines[1] == f"continued {int(done) + 1}"
    assert proc.returncode == 0
    # One 32768-sample step takes ~0.1-0.3 s on 2 cores; the stop comes within a few steps.
    assert stopped_after < 5.0
