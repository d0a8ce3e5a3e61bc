"""Meshes with colour and reflectance: read_mesh (PLY properties), extract_mesh (surface.vdb's
"color" / "intensity" grids) and NeuralMap.extract_mesh(colors_from=...).

Fixtures independent of the module's writers: PLY files packed here with struct, and a surface.vdb
with both grids made by the CLI (`shine simulate --cameras`, scans given a reflectance here, then
`shine map`); python3-openvdb, which could write a grid independently, is not among the packages
scripts/setup.sh installs.
"""

import math
import struct
import subprocess

import numpy as np
import pytest

import shinevdb
from conftest import THREADS


# --- PLY written by hand ---------------------------------------------------------------------

VERTICES = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.5], [0.0, 1.0, 0.25]])
TRIANGLES = np.array([[0, 1, 2], [0, 2, 3]])
COLORS = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255], [17, 128, 254]], dtype=np.uint8)
INTENSITY = np.array([0.125, 1e-3, math.nan, 87.5], dtype=np.float32)


def write_ply(path, colors=None, intensity=None):
    """A binary little-endian PLY: float x y z, an unknown float `quality` (to be skipped),
    optionally float intensity and uchar red green blue (intensity first: order must not matter),
    and uchar-int faces."""
    header = ["ply", "format binary_little_endian 1.0", f"element vertex {len(VERTICES)}",
              "property float x", "property float y", "property float z", "property float quality"]
    if intensity is not None:
        header.append("property float intensity")
    if colors is not None:
        header += ["property uchar red", "property uchar green", "property uchar blue"]
    header += [f"element face {len(TRIANGLES)}", "property list uchar int vertex_indices",
               "end_header"]
    body = b""
    for i, v in enumerate(VERTICES):
        body += struct.pack("<4f", *v, 0.5 * i)
        if intensity is not None:
            body += struct.pack("<f", intensity[i])
        if colors is not None:
            body += struct.pack("<3B", *colors[i])
    for t in TRIANGLES:
        body += struct.pack("<B3i", 3, *t)
    path.write_bytes(("\n".join(header) + "\n").encode("ascii") + body)
    return path


def test_read_mesh_gives_the_ply_colours_and_intensity_exactly(tmp_path):
    mesh = shinevdb.read_mesh(write_ply(tmp_path / "coloured.ply", COLORS, INTENSITY))
    assert isinstance(mesh, shinevdb.Mesh)
    assert mesh.vertices.dtype == np.float64 and mesh.triangles.dtype == np.int32
    np.testing.assert_array_equal(mesh.vertices, VERTICES)
    np.testing.assert_array_equal(mesh.triangles, TRIANGLES)
    assert mesh.colors.dtype == np.uint8 and mesh.colors.shape == (4, 3)
    np.testing.assert_array_equal(mesh.colors, COLORS)
    assert mesh.intensity.dtype == np.float32 and mesh.intensity.shape == (4,)
    np.testing.assert_array_equal(mesh.intensity, INTENSITY)  # NaN where NaN, bit for bit else
    assert "colors (V, 3) uint8" in repr(mesh)


def test_read_mesh_without_attributes_gives_none(tmp_path):
    plain = shinevdb.read_mesh(write_ply(tmp_path / "plain.ply"))
    assert plain.colors is None and plain.intensity is None
    np.testing.assert_array_equal(plain.triangles, TRIANGLES)
    only_intensity = shinevdb.read_mesh(write_ply(tmp_path / "i.ply", intensity=INTENSITY))
    assert only_intensity.colors is None
    np.testing.assert_array_equal(only_intensity.intensity, INTENSITY)


def test_read_mesh_reads_an_output_folder_and_names_a_missing_file(tmp_path):
    write_ply(tmp_path / "mesh.ply", COLORS)
    np.testing.assert_array_equal(shinevdb.read_mesh(tmp_path).colors, COLORS)
    with pytest.raises(OSError, match="nowhere.ply"):
        shinevdb.read_mesh(tmp_path / "nowhere.ply")


def test_evaluate_takes_a_mesh(tmp_path):
    mesh = shinevdb.read_mesh(write_ply(tmp_path / "m.ply", COLORS))
    result = shinevdb.evaluate(mesh, (mesh.vertices, mesh.triangles))
    assert result["chamfer_l1_m"] < 1e-3


# --- surface.vdb with colour and reflectance, made by `shine map` ------------------------------

def reflectance(points_sensor):
    """The intensity given to every simulated point: smooth in space (so the fused values vary
    little across a voxel) and never 0 (all-zero intensity reads as none)."""
    return (0.2 + 0.1 * np.sin(points_sensor[:, 0]) + 0.05 * points_sensor[:, 2]).clip(0.01, 1.0)


@pytest.fixture(scope="module")
def coloured_output(tmp_path_factory, shine_cli):
    """A `shine map` output folder with mesh.ply colours and intensity and surface.vdb's "color"
    and "intensity" grids: 3 simulated scans with the front camera, reflectance set here."""
    root = tmp_path_factory.mktemp("coloured")
    seq, out = root / "seq", root / "out"
    subprocess.run([str(shine_cli), "simulate", "-o", str(seq), "--frames", "3", "--cameras",
                    "--threads", str(THREADS)], check=True, stdout=subprocess.DEVNULL)
    for scan in sorted((seq / "velodyne").glob("*.bin")):
        points = np.fromfile(scan, dtype=np.float32).reshape(-1, 4)
        points[:, 3] = reflectance(points[:, :3])
        points.tofile(scan)
    subprocess.run([str(shine_cli), "map", str(seq), "-o", str(out), "--threads", str(THREADS),
                    "--iterations", "20", "--seed", "7", "--no-refine", "--no-eval", "-q"],
                   check=True, stdout=subprocess.DEVNULL)
    return out


def nearest_active_reference(vertices_world, grids, name):
    """Brute-force numpy twin of the binding's rule: the value of the nearest active voxel centre
    among the 27 around round(index); ties to the first in (dx, dy, dz) order; None if none."""
    voxels, values = grids[f"{name}_voxels"], grids[name]
    index = (vertices_world - grids["origin_world_m"]) * (1.0 / grids["voxel_size_m"])
    centre = np.floor(index + 0.5).astype(np.int64)

    def keys(ijk):
        shifted = ijk + (1 << 20)  # 21 bits an axis
        return (shifted[:, 0] << 42) | (shifted[:, 1] << 21) | shifted[:, 2]

    grid_keys = keys(voxels.astype(np.int64))
    order = np.argsort(grid_keys)
    sorted_keys = grid_keys[order]
    best_sq = np.full(len(index), np.inf)
    best = np.full(len(index), -1)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                q = centre + np.array([dx, dy, dz])
                k = keys(q)
                pos = np.searchsorted(sorted_keys, k).clip(0, len(sorted_keys) - 1)
                active = sorted_keys[pos] == k
                d = index - q
                d_sq = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]
                better = active & (d_sq < best_sq)
                best_sq[better] = d_sq[better]
                best[better] = order[pos[better]]
    return best


def test_extract_mesh_samples_the_grids_at_the_vertices(coloured_output):
    mesh = shinevdb.extract_mesh(coloured_output)  # the folder: its surface.vdb
    grids = shinevdb.read_surface_grids(coloured_output / "surface.vdb")
    assert grids["voxel_size_m"] == pytest.approx(0.1)
    assert grids["color"].dtype == np.uint8
    assert grids["color"].shape == (len(grids["color_voxels"]), 3)
    assert grids["intensity"].dtype == np.float32
    assert len(grids["color_voxels"]) > 10000 and len(grids["intensity_voxels"]) > 10000

    assert mesh.colors.dtype == np.uint8 and mesh.colors.shape == (len(mesh.vertices), 3)
    assert mesh.intensity.dtype == np.float32 and mesh.intensity.shape == (len(mesh.vertices),)
    # Colours: exactly the nearest active voxel's bytes, (0, 0, 0) where there is none.
    nearest = nearest_active_reference(mesh.vertices, grids, "color")
    found = nearest >= 0
    assert 0.2 < found.mean() < 1.0  # one front camera, three frames: part of the street
    np.testing.assert_array_equal(mesh.colors[found], grids["color"][nearest[found]])
    assert not mesh.colors[~found].any()
    # Intensity: the same rule, NaN where there is none.
    nearest = nearest_active_reference(mesh.vertices, grids, "intensity")
    found = nearest >= 0
    assert found.mean() > 0.9
    np.testing.assert_array_equal(mesh.intensity[found], grids["intensity"][nearest[found]])
    assert np.isnan(mesh.intensity[~found]).all()


def test_grid_colours_agree_with_mesh_ply(coloured_output):
    """mesh.ply's colours are fused at its own vertices (another path through the images): at the
    same vertices the grid's colours are mostly the same bytes, and the reflectance the same."""
    from_grid = shinevdb.extract_mesh(coloured_output)
    from_ply = shinevdb.read_mesh(coloured_output)
    assert from_ply.colors is not None and from_ply.intensity is not None
    # The same level set meshed whole here and column by column by `shine map`: the vertices
    # coincide (the columns weld their seams, so a few whole-grid vertices have no twin).
    key_um = lambda v: [tuple(r) for r in np.round(v * 1e4).astype(np.int64)]  # 0.1 mm
    ply_index = {k: i for i, k in enumerate(key_um(from_ply.vertices))}
    pairs = np.array([(ply_index.get(k, -1), j)
                      for j, k in enumerate(key_um(from_grid.vertices))])
    pairs = pairs[pairs[:, 0] >= 0]
    assert len(pairs) > 0.97 * len(from_grid.vertices)  # measured 98.9 % and 99.5 %
    ply_rgb = from_ply.colors[pairs[:, 0]].astype(int)
    grid_rgb = from_grid.colors[pairs[:, 1]].astype(int)
    seen = grid_rgb.any(axis=1)
    worst_channel = np.abs(ply_rgb - grid_rgb)[seen].max(axis=1)
    # Measured: median 0, 75th percentile 5-7 levels, 84 % within 16; edges of objects and of
    # the camera's view differ more (a voxel's surface point is not the vertex).
    kMedianLevels = 2
    kWithin16LevelsFraction = 0.7
    assert np.median(worst_channel) <= kMedianLevels
    assert (worst_channel <= 16).mean() >= kWithin16LevelsFraction
    ply_intensity = from_ply.intensity[pairs[:, 0]]
    grid_intensity = from_grid.intensity[pairs[:, 1]]
    both = np.isfinite(ply_intensity) & np.isfinite(grid_intensity)
    # Measured: 72 % of mesh.ply's vertices have a reflectance, 97 % of the sampled ones (the
    # nearest active voxel reaches a voxel further); median difference 0.002.
    assert both.mean() > 0.6
    kIntensityMedian = 0.01  # reflectance() varies by ~0.01 over a voxel
    assert np.median(np.abs(ply_intensity - grid_intensity)[both]) < kIntensityMedian


def test_neural_map_colours_come_from_the_surface_only(coloured_output):
    nmap = shinevdb.NeuralMap.load(coloured_output / "map.vdb")
    plain = nmap.extract_mesh()
    assert plain.colors is None and plain.intensity is None
    coloured = nmap.extract_mesh(colors_from=coloured_output)
    # map.vdb baked at the stored voxel size is surface.vdb: the same mesh and the same samples.
    reference = shinevdb.extract_mesh(coloured_output / "surface.vdb")
    np.testing.assert_array_equal(coloured.vertices, plain.vertices)
    np.testing.assert_array_equal(coloured.vertices, reference.vertices)
    np.testing.assert_array_equal(coloured.triangles, reference.triangles)
    np.testing.assert_array_equal(coloured.colors, reference.colors)
    np.testing.assert_array_equal(coloured.intensity, reference.intensity)


def test_a_map_trained_here_takes_colours_from_another_run(batch_map, coloured_output):
    """The 5-scan street of conftest and the 3-scan one share the world frame (same simulated
    street): the grids are sampled where the two surfaces overlap, world frame to world frame."""
    mesh = batch_map.extract_mesh(colors_from=coloured_output / "surface.vdb")
    grids = shinevdb.read_surface_grids(coloured_output)
    nearest = nearest_active_reference(mesh.vertices, grids, "color")
    found = nearest >= 0
    assert found.mean() > 0.1
    np.testing.assert_array_equal(mesh.colors[found], grids["color"][nearest[found]])
    assert not mesh.colors[~found].any()


def test_surfaces_without_grids(tmp_path, batch_map):
    surface = tmp_path / "surface.vdb"
    batch_map.bake(surface)
    plain = shinevdb.extract_mesh(surface)
    assert plain.colors is None and plain.intensity is None
    assert len(plain.triangles) > 1000
    with pytest.raises(ValueError, match="surface.vdb.*no 'color' or 'intensity' grid"):
        batch_map.extract_mesh(colors_from=surface)
    with pytest.raises(ValueError, match="no 'color' or 'intensity' grid"):
        shinevdb.read_surface_grids(surface)
    with pytest.raises(OSError, match="missing.vdb"):
        batch_map.extract_mesh(colors_from=tmp_path / "missing.vdb")
    with pytest.raises(OSError, match="missing.vdb"):
        shinevdb.extract_mesh(tmp_path / "missing.vdb")
    with pytest.raises(ValueError, match="adaptivity"):
        shinevdb.extract_mesh(surface, adaptivity=2.0)
