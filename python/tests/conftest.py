"""Shared fixtures: a small simulated sequence (5 scans of the street) and the CLI binary.

ctest runs this suite with the built module on PYTHONPATH and SHINE_CLI naming build/shine
(python/CMakeLists.txt); run by hand: PYTHONPATH=build/python /usr/bin/python3 -m pytest python/tests
"""

import os
import pathlib
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
# Few optimisation steps keep the suite fast; a set step count uses the paper's 4096-sample steps.
FAST_CONFIG = {"training": {"iterations": 20}, "run": {"seed": 7}}
THREADS = 2


def cli_path() -> pathlib.Path:
    path = pathlib.Path(os.environ.get("SHINE_CLI", REPO / "build" / "shine"))
    if not path.exists():
        pytest.fail(f"the shine CLI is not at {path}: build it (cmake --build build --target shine) "
                    "or set SHINE_CLI")
    return path


@pytest.fixture(scope="session")
def shine_cli() -> pathlib.Path:
    return cli_path()


@pytest.fixture(scope="session")
def small_sequence(tmp_path_factory) -> pathlib.Path:
    """5 scans of the simulated street (KITTI layout) with its gt_mesh.ply."""
    out = tmp_path_factory.mktemp("street5")
    subprocess.run([str(cli_path()), "simulate", "-o", str(out), "--frames", "5", "--threads",
                    str(THREADS)], check=True, stdout=subprocess.DEVNULL)
    return out


@pytest.fixture(scope="session")
def scans(small_sequence):
    """The small sequence in memory: a list of (points float32 sensor frame, 4x4 pose)."""
    import shinevdb
    return [(points, pose) for points, pose, _ in shinevdb.read_sequence(small_sequence)]


@pytest.fixture(scope="session")
def batch_map(scans):
    """A batch-mode map of the small sequence with FAST_CONFIG."""
    import shinevdb
    nmap = shinevdb.NeuralMap(config=FAST_CONFIG, threads=THREADS)
    for points, pose in scans:
        nmap.add_scan(points, pose)
    assert nmap.train(progress=False)
    return nmap
