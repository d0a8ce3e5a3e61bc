"""ShineVDB from Python: neural SDF maps (SHINE-Mapping) and the TSDF baseline, on numpy arrays.

    import shinevdb
    nmap = shinevdb.NeuralMap(leaf_size_m=0.2)
    for points, pose, _ in shinevdb.read_sequence("examples/street"):
        nmap.add_scan(points, pose)
    nmap.train()
    vertices, triangles = nmap.extract_triangle_mesh()
    print(shinevdb.evaluate((vertices, triangles), "examples/street/gt_mesh.ply"))

See docs/python.md.
"""

from ._shinevdb import (  # noqa: F401
    NeuralMap,
    ScanSequenceReader,
    TSDFVolume,
    evaluate,
    read_sequence,
)

__all__ = ["NeuralMap", "TSDFVolume", "ScanSequenceReader", "read_sequence", "evaluate"]
