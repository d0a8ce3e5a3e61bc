"""Type hints of the shinevdb package (the compiled _shinevdb module it re-exports)."""

import os
from typing import Any, Dict, Iterator, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

FloatArray = Union[npt.NDArray[np.float32], npt.NDArray[np.float64]]
"""float32 or float64; any strides (read in place)."""
PathLike = Union[str, os.PathLike]
MeshArrays = Tuple[npt.NDArray[np.float64], npt.NDArray[np.int32]]
"""(vertices (V, 3) float64 world frame, triangles (T, 3) int32)."""
class Mesh:
    """A triangle mesh with its per-vertex colour and reflectance, when it has them."""

    @property
    def vertices(self) -> npt.NDArray[np.float64]:
        """(V, 3) world frame, metres."""
    @property
    def triangles(self) -> npt.NDArray[np.int32]:
        """(T, 3) vertex indices."""
    @property
    def colors(self) -> Optional[npt.NDArray[np.uint8]]:
        """(V, 3) 8-bit sRGB; (0, 0, 0) where no camera saw; None without colour."""
    @property
    def intensity(self) -> Optional[npt.NDArray[np.float32]]:
        """(V,) reflectance as the scans give it; NaN where unknown; None without it."""

MeshInput = Union[
    PathLike,
    Mesh,
    Tuple[FloatArray, npt.NDArray[np.integer]],
    Tuple[FloatArray, npt.NDArray[np.integer], npt.NDArray[Any]],
]
"""A PLY path, (vertices, triangles) or (vertices, triangles, face_observed)."""

class NeuralMap:
    """A SHINE-Mapping neural SDF map (batch: add_scan + train; incremental: integrate)."""

    def __init__(
        self,
        leaf_size_m: Optional[float] = None,
        config: Union[None, Dict[str, Any], PathLike] = None,
        threads: Optional[int] = None,
    ) -> None:
        """leaf_size_m None: the config's (0.2 m); config: dict or YAML path in the form of
        examples/config.yaml; threads 0: all cores, None: the config's (0)."""
    @staticmethod
    def load(path: PathLike) -> "NeuralMap":
        """Reads map.vdb (from save() or `shine map`); queryable, not trainable."""
    def integrate(
        self, points: FloatArray, pose: FloatArray, times: Optional[FloatArray] = None
    ) -> None:
        """Incremental mode: one scan ((N, 3) sensor frame, 4x4 T_world_sensor), trained at once."""
    def consolidate(
        self, steps: Optional[int] = None, progress: bool = True
    ) -> Dict[str, Any]:
        """Incremental mode: trains the kept scans together, as `shine map` does at the end."""
    def add_scan(self, points: FloatArray, pose: FloatArray) -> None:
        """Batch mode: adds a scan ((N, 3) sensor frame, 4x4 T_world_sensor); train() learns."""
    def train(self, steps: Optional[int] = None, progress: bool = True) -> bool:
        """Batch mode: runs up to `steps` more steps (None: all); True when the schedule is done."""
    def sdf(self, points: FloatArray) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
        """(values (N,), gradients (N, 3)) at world-frame points; NaN outside the map."""
    def extract_triangle_mesh(self, voxel_size_m: Optional[float] = None) -> MeshArrays:
        """Bake and mesh (vertices float64 world frame, triangles int32); no colours."""
    def extract_mesh(
        self, voxel_size_m: Optional[float] = None, colors_from: Optional[PathLike] = None
    ) -> Mesh:
        """Bake and mesh; colors / intensity None (a neural map holds none) unless colors_from
        names a surface.vdb (or `shine map` output folder) with "color" / "intensity" grids."""
    def bake(self, path: PathLike, voxel_size_m: Optional[float] = None) -> Dict[str, Any]:
        """Writes the surface level set .vdb; returns voxel_size_m, active_voxels, bytes."""
    def save(self, path: PathLike) -> None:
        """Writes the neural map (map.vdb format)."""
    def write_products(self, out_dir: PathLike) -> Dict[str, Any]:
        """map.vdb, surface.vdb and mesh.ply into out_dir, as `shine map` writes them."""
    @property
    def memory_bytes(self) -> int:
        """Features + OpenVDB structure + decoder, in bytes."""
    @property
    def stats(self) -> Dict[str, Any]:
        """stats.json's figures: frames, rays, seconds, map bytes, loss."""
    @property
    def config_yaml(self) -> str: ...
    @property
    def mode(self) -> str:
        """'empty', 'batch', 'incremental' or 'loaded'."""
    @property
    def num_scans(self) -> int: ...
    @property
    def iterations_done(self) -> int: ...
    @property
    def iterations_planned(self) -> int: ...

class TSDFVolume:
    """TSDF fusion with VDBFusion's algorithm and names (VDBVolume)."""

    def __init__(self, voxel_size: float, sdf_trunc: float, space_carving: bool = False) -> None: ...
    def integrate(self, points: FloatArray, extrinsic: FloatArray) -> None:
        """World-frame points (N, 3); extrinsic a 4x4 pose or a (3,) sensor origin."""
    def extract_triangle_mesh(
        self, fill_holes: bool = True, min_weight: float = 0.0
    ) -> MeshArrays: ...
    def extract_vdb_grids(self, out_file: PathLike) -> None: ...
    @property
    def voxel_size(self) -> float: ...
    @property
    def sdf_trunc(self) -> float: ...
    @property
    def space_carving(self) -> bool: ...
    @property
    def memory_bytes(self) -> int: ...
    @property
    def active_voxels(self) -> int: ...

class ScanSequenceReader(Iterator[Tuple[npt.NDArray[np.float32], npt.NDArray[np.float64], None]]):
    def __iter__(self) -> "ScanSequenceReader": ...
    def __next__(self) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.float64], None]: ...
    def __len__(self) -> int: ...
    def pose(self, index: int) -> npt.NDArray[np.float64]: ...
    def scan_path(self, index: int) -> str: ...

def read_sequence(
    path: PathLike,
    first_frame: int = 0,
    last_frame: int = -1,
    frame_step: int = 1,
    poses: Optional[PathLike] = None,
) -> ScanSequenceReader:
    """(points (N, 3) float32 sensor frame, pose 4x4 T_world_sensor, times None) per scan."""

def evaluate(pred_mesh: MeshInput, ref_mesh: MeshInput, threshold_m: float = 0.1,
             tile_m: Optional[float] = None) -> Dict[str, float]:
    """accuracy_m, completion_m, chamfer_l1_m, precision, completion_ratio, fscore, ...
    (tile by tile with tile_m, as `shine eval --tile-m`)"""

def read_mesh(path: PathLike) -> Mesh:
    """A PLY (or a `shine map` output folder's mesh.ply) with its red/green/blue and intensity."""

def extract_mesh(surface: PathLike, adaptivity: float = 0.0) -> Mesh:
    """Meshes a surface.vdb (or output folder) and samples its "color" / "intensity" grids at
    the vertices (nearest active voxel among the 27 around each vertex)."""

def read_surface_grids(path: PathLike) -> Dict[str, Any]:
    """voxel_size_m, origin_world_m, color_voxels / color (uint8), intensity_voxels / intensity
    of a surface.vdb's grids (None for a missing grid)."""
