"""ShineVDB from Python: neural SDF maps (SHINE-Mapping) and the TSDF baseline, on numpy arrays.

    import shinevdb
    nmap = shinevdb.NeuralMap(leaf_size_m=0.2)
    for points, pose, _ in shinevdb.read_sequence("examples/street"):
        nmap.add_scan(points, pose)
    nmap.train()
    vertices, triangles = nmap.extract_triangle_mesh()
    print(shinevdb.evaluate((vertices, triangles), "examples/street/gt_mesh.ply"))

    mesh = shinevdb.read_mesh("out")      # a `shine map` output: mesh.colors, mesh.intensity

See docs/python.md.
"""

from ._shinevdb import (  # noqa: F401
    Mesh,
    NeuralMap,
    ScanSequenceReader,
    TSDFVolume,
    evaluate,
    extract_mesh,
    read_mesh,
    read_sequence,
    read_surface_grids,
)

__all__ = ["NeuralMap", "TSDFVolume", "ScanSequenceReader", "read_sequence", "evaluate", "Mesh",
           "read_mesh", "extract_mesh", "read_surface_grids"]
