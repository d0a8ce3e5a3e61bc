"""The Python mappers and `shine map` give the same map for the same scans, seed and threads."""

import subprocess

import numpy as np

import shinevdb
from conftest import FAST_CONFIG, THREADS


def cli_map(shine_cli, data, out, *extra):
    subprocess.run([str(shine_cli), "map", str(data), "-o", str(out), "--threads", str(THREADS),
                    "--seed", str(FAST_CONFIG["run"]["seed"]), "--no-eval", "-q", *extra],
                   check=True, stdout=subprocess.DEVNULL)


def assert_same_products(cli_out, py_out, scans):
    # mesh.ply is written the same way by both: identical bytes.
    assert (cli_out / "mesh.ply").read_bytes() == (py_out / "mesh.ply").read_bytes()
    # map.vdb files hold per-file UUIDs; compare the maps they hold instead.
    cli_map_ = shinevdb.NeuralMap.load(cli_out / "map.vdb")
    py_map = shinevdb.NeuralMap.load(py_out / "map.vdb")
    points, pose = scans[1]
    query = points.astype(np.float64) @ pose[:3, :3].T + pose[:3, 3]
    for a, b in zip(cli_map_.sdf(query), py_map.sdf(query)):
        np.testing.assert_array_equal(a, b)
    assert cli_map_.memory_bytes == py_map.memory_bytes


def test_batch_parity(shine_cli, small_sequence, scans, batch_map, tmp_path):
    # The Python batch map trains at the poses it is given; `shine map` refines them first unless
    # told not to (docs/field.md).
    cli_map(shine_cli, small_sequence, tmp_path / "cli",
            "--iterations", str(FAST_CONFIG["training"]["iterations"]), "--no-refine")
    batch_map.write_products(tmp_path / "py")
    assert_same_products(tmp_path / "cli", tmp_path / "py", scans)


def test_incremental_parity(shine_cli, small_sequence, scans, tmp_path):
    cli_map(shine_cli, small_sequence, tmp_path / "cli", "--mode", "incremental")
    nmap = shinevdb.NeuralMap(config={"run": FAST_CONFIG["run"]}, threads=THREADS)
    for points, pose, _ in shinevdb.read_sequence(small_sequence):
        nmap.integrate(points, pose)
    nmap.consolidate(progress=False)  # what the CLI does at the end of the sequence
    nmap.write_products(tmp_path / "py")
    assert_same_products(tmp_path / "cli", tmp_path / "py", scans)
