#!/usr/bin/python3
"""Maps the bundled street with shinevdb.NeuralMap and shinevdb.TSDFVolume, scores both against
the street's ground-truth mesh and plots memory and accuracy side by side (matplotlib, PNG).

    /usr/bin/python3 examples/python/map_street.py [-o out/python_street.png] [--leaf-size-m 0.2]

The street (examples/street) is simulated with `build/shine simulate` on first use, as
`shine map` does. The TSDF integrates every point of every scan (VDBFusion's way, no
downsampling); `shine tsdf` instead feeds it the mapper's preprocessed scans (docs/tsdf.md).
"""

import argparse
import pathlib
import subprocess
import sys
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import shinevdb  # noqa: E402

REPO = pathlib.Path(__file__).resolve().parents[2]


def ensure_street(data: pathlib.Path, shine: pathlib.Path) -> None:
    if (data / "poses.txt").exists():
        return
    if not shine.exists():
        sys.exit(f"{data} is missing and {shine} is not built: run ./scripts/setup.sh first")
    print(f"simulating the street into {data} ...", flush=True)
    subprocess.run([str(shine), "simulate", "-o", str(data)], check=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=pathlib.Path, default=REPO / "examples" / "street")
    parser.add_argument("-o", "--output", type=pathlib.Path,
                        default=REPO / "out" / "python_street.png")
    parser.add_argument("--leaf-size-m", type=float, default=0.2)
    parser.add_argument("--tsdf-voxel-m", type=float, default=0.1)
    parser.add_argument("--tsdf-trunc-m", type=float, default=0.3)
    parser.add_argument("--threads", type=int, default=0, help="0: all cores")
    parser.add_argument("--shine", type=pathlib.Path, default=REPO / "build" / "shine")
    args = parser.parse_args()
    ensure_street(args.data, args.shine)

    neural = shinevdb.NeuralMap(leaf_size_m=args.leaf_size_m, threads=args.threads)
    tsdf = shinevdb.TSDFVolume(args.tsdf_voxel_m, args.tsdf_trunc_m, space_carving=False)
    t0 = time.monotonic()
    tsdf_seconds = 0.0
    for points, pose, _ in shinevdb.read_sequence(args.data):
        neural.add_scan(points, pose)
        t1 = time.monotonic()
        points_world = points.astype(np.float64) @ pose[:3, :3].T + pose[:3, 3]
        tsdf.integrate(points_world, pose)
        tsdf_seconds += time.monotonic() - t1
    neural.train()
    neural_seconds = time.monotonic() - t0 - tsdf_seconds

    reference = args.data / "gt_mesh.ply"
    results = {}
    for name, mesh, memory, seconds in (
            ("ShineVDB neural map", neural.extract_triangle_mesh(), neural.memory_bytes,
             neural_seconds),
            ("TSDF (VDBFusion)", tsdf.extract_triangle_mesh(fill_holes=False, min_weight=0.5),
             tsdf.memory_bytes, tsdf_seconds)):
        metrics = shinevdb.evaluate(mesh, reference)
        results[name] = dict(metrics, memory_mb=memory / 1e6, seconds=seconds,
                             triangles=len(mesh[1]))
        print(f"{name:20s} {memory / 1e6:7.2f} MB  {seconds:6.1f} s  "
              f"accuracy {100 * metrics['accuracy_m']:.2f} cm  "
              f"completion {100 * metrics['completion_m']:.2f} cm  "
              f"Chamfer-L1 {100 * metrics['chamfer_l1_m']:.2f} cm  "
              f"F-score {100 * metrics['fscore']:.1f} %")

    names = list(results)
    colors = ["tab:blue", "tab:orange"]
    fig, axes = plt.subplots(1, 3, figsize=(12, 4))
    panels = (("memory (MB)", "memory_mb", 1.0),
              ("Chamfer-L1 (cm)", "chamfer_l1_m", 100.0),
              ("F-score at 10 cm (%)", "fscore", 100.0))
    for ax, (title, key, scale) in zip(axes, panels):
        values = [results[n][key] * scale for n in names]
        bars = ax.bar(range(len(names)), values, color=colors)
        ax.bar_label(bars, fmt="%.2f" if key != "fscore" else "%.1f")
        ax.set_ylim(0, 1.15 * max(values))
        ax.set_xticks(range(len(names)), [n.replace(" ", "\n", 1) for n in names])
        ax.set_title(title)
    fig.suptitle(f"{args.data.name}: neural map (leaf {args.leaf_size_m} m) vs TSDF "
                 f"(voxel {args.tsdf_voxel_m} m, trunc {args.tsdf_trunc_m} m)")
    fig.tight_layout()
    args.output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.output, dpi=100)
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
