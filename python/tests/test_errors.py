"""Wrong shapes, dtypes, poses and settings raise ValueError naming the argument."""

import numpy as np
import pytest

import shinevdb

POINTS = np.random.default_rng(1).uniform(-10, 10, (100, 3)).astype(np.float32)
POSE = np.eye(4)


@pytest.mark.parametrize("points, message", [
    (np.zeros((10, 2), np.float32), r"points must have shape \(N, 3\), got \(10, 2\)"),
    (np.zeros(30, np.float32), r"points must have shape \(N, 3\), got \(30,\)"),
    (np.zeros((10, 3), np.int64), "points must be float32 or float64, got int64"),
    (np.zeros((10, 3), np.float16), "points must be float32 or float64, got float16"),
    (None, "points must be a numpy array"),
])
def test_bad_points(points, message):
    nmap = shinevdb.NeuralMap()
    with pytest.raises(ValueError, match=message):
        nmap.add_scan(points, POSE)
    with pytest.raises(ValueError, match=message):
        nmap.integrate(points, POSE)


@pytest.mark.parametrize("pose, message", [
    (np.eye(3), r"pose must be a \(4, 4\) or \(3, 4\) rigid transform"),
    (np.full((4, 4), np.nan), r"pose must be finite, but entry \[0, 0\] is nan"),
    (np.diag([1.0, 1.0, 1.0, 2.0]), r"pose's last row must be \[0, 0, 0, 1\]"),
    (np.diag([2.0, 1.0, 1.0, 1.0]), "pose's upper-left 3x3 block must be a rotation"),
    (np.eye(4, dtype=np.int32), "pose must be float32 or float64, got int32"),
])
def test_bad_pose(pose, message):
    with pytest.raises(ValueError, match=message):
        shinevdb.NeuralMap().add_scan(POINTS, pose)


def test_inf_in_pose_translation():
    pose = np.eye(4)
    pose[1, 3] = np.inf
    with pytest.raises(ValueError, match=r"pose must be finite, but entry \[1, 3\] is inf"):
        shinevdb.NeuralMap().integrate(POINTS, pose)


def test_bad_times():
    with pytest.raises(ValueError, match=r"times must have shape \(100,\)"):
        shinevdb.NeuralMap().integrate(POINTS, POSE, times=np.zeros(99))


def test_bad_settings(tmp_path):
    with pytest.raises(ValueError, match="leaf_size_m must be a positive"):
        shinevdb.NeuralMap(leaf_size_m=-0.1)
    with pytest.raises(ValueError, match="threads must be >= 0"):
        shinevdb.NeuralMap(threads=-1)
    with pytest.raises(ValueError, match="no_such_key"):
        shinevdb.NeuralMap(config={"map": {"no_such_key": 1}})
    with pytest.raises(ValueError, match="leaf_size_m"):
        shinevdb.NeuralMap(config={"map": {"leaf_size_m": -1}})
    with pytest.raises(ValueError, match="cannot open config file .*missing.yaml"):
        shinevdb.NeuralMap(config=str(tmp_path / "missing.yaml"))
    with pytest.raises(ValueError, match="config must be None, a dict or the path"):
        shinevdb.NeuralMap(config=3)


def test_config_dict_and_file_agree(tmp_path):
    (tmp_path / "c.yaml").write_text("map:\n  leaf_size_m: 0.4\nrun:\n  seed: 3\n")
    from_file = shinevdb.NeuralMap(config=tmp_path / "c.yaml")
    from_dict = shinevdb.NeuralMap(config={"map": {"leaf_size_m": 0.4}, "run": {"seed": 3}})
    assert from_file.config_yaml == from_dict.config_yaml
    assert "leaf_size_m: 0.4" in from_dict.config_yaml
    # leaf_size_m given explicitly wins over the configuration's
    assert "leaf_size_m: 0.1" in shinevdb.NeuralMap(0.1, config=tmp_path / "c.yaml").config_yaml


def test_empty_map_and_mode_errors():
    nmap = shinevdb.NeuralMap()
    with pytest.raises(RuntimeError, match="the map is empty"):
        nmap.extract_triangle_mesh()
    with pytest.raises(RuntimeError, match="needs scans"):
        nmap.train()
    with pytest.raises(RuntimeError, match="consolidate\\(\\) needs scans"):
        nmap.consolidate()
    nmap.integrate(POINTS, POSE)
    with pytest.raises(ValueError, match="steps must be"):
        nmap.consolidate(steps=-1)
    batch = shinevdb.NeuralMap()
    batch.add_scan(POINTS, POSE)
    with pytest.raises(RuntimeError, match="consolidate\\(\\) is for incremental mode"):
        batch.consolidate()
    with pytest.raises(ValueError, match="voxel_size_m must be a positive"):
        nmap.extract_triangle_mesh(voxel_size_m=0.0)


def test_tsdf_errors():
    with pytest.raises(ValueError, match="voxel_size must be a positive"):
        shinevdb.TSDFVolume(0.0, 0.3)
    with pytest.raises(ValueError, match="sdf_trunc must be a positive"):
        shinevdb.TSDFVolume(0.1, -1.0)
    volume = shinevdb.TSDFVolume(0.1, 0.3)
    with pytest.raises(ValueError, match=r"extrinsic must be a \(4, 4\) pose or a \(3,\) sensor origin"):
        volume.integrate(POINTS, np.zeros(2))
    with pytest.raises(ValueError, match="extrinsic must be finite"):
        volume.integrate(POINTS, np.full((4, 4), np.nan))
    with pytest.raises(ValueError, match=r"points must have shape \(N, 3\)"):
        volume.integrate(POINTS[:, :2], np.zeros(3))
    with pytest.raises(ValueError, match="min_weight must be >= 0"):
        volume.extract_triangle_mesh(min_weight=-1.0)


def test_evaluate_errors(tmp_path):
    with pytest.raises(ValueError, match="pred_mesh must be a PLY path, a shinevdb.Mesh or a"):
        shinevdb.evaluate(3, "x.ply")
    tri = (np.zeros((3, 3)), np.array([[0, 1, 5]]))
    with pytest.raises(ValueError, match=r"pred_mesh\[1\] \(triangles\): triangle 0 refers to vertex 5"):
        shinevdb.evaluate(tri, tri)
    with pytest.raises(OSError, match="absent.ply"):
        shinevdb.evaluate(str(tmp_path / "absent.ply"), str(tmp_path / "absent.ply"))
