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
    poses = []
    for points, pose, _ in shinevdb.read_sequence(small_sequence):
        nmap.integrate(points, pose)
        poses.append(pose)
    # What the CLI does at the end of the sequence, the kept scans' poses refined with it.
    done = nmap.consolidate(progress=False)
    nmap.write_products(tmp_path / "py")
    assert_same_products(tmp_path / "cli", tmp_path / "py", scans)
    corrections = done["pose_corrections"]
    assert corrections.shape == (len(poses), 4, 4)
    assert len(done["refinement"]) == 4
    cli_refined = np.loadtxt(tmp_path / "cli" / "poses_refined.txt").reshape(-1, 3, 4)
    for k, pose in enumerate(poses):
        np.testing.assert_allclose((corrections[k] @ pose)[:3], cli_refined[k], atol=1e-6)
    # Refinement off: no corrections, as `shine map --no-refine`.
    plain = shinevdb.NeuralMap(config={"run": FAST_CONFIG["run"],
                                       "refine": {"in_consolidation": False}}, threads=THREADS)
    for points, pose, _ in shinevdb.read_sequence(small_sequence):
        plain.integrate(points, pose)
    assert plain.consolidate(steps=10, progress=False)["pose_corrections"].shape == (0, 4, 4)
