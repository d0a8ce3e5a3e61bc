#!/usr/bin/python3
"""Map a scan sequence as spatial tiles on a Dask distributed cluster, then merge the tiles.

    scripts/shine_dask_tiles.py DATA -o OUT [--scheduler tcp://host:8786 | --local-workers 4]
        [--tile-size-m 40] [--overlap-m 10] [--shine build/shine] [-c extra.yaml]
        [--threads-per-tile 1] [--ref gt_mesh.ply] [--min-scan-fraction 0.1] [--force]

1. Reads DATA's poses (KITTI layout: velodyne/NNNNNN.bin, poses.txt, optional calib.txt) and the
   effective configuration (`shine map --print-config -c extra.yaml`: max range, origin).
2. Lays a grid of square tiles (--tile-size-m, anchored at the common map origin, which is the
   first pose rounded to whole km as `shine map` chooses it, or the config's map.origin_world_m)
   over the trajectory's bounds grown by the max range. A tile's core is its grid square; its crop
   box is the core grown by --overlap-m (z unbounded). Every scan is read once (numpy) to find
   the tiles its points fall into: a tile maps the scans that have points in its crop box (all of
   them within max range + overlap of the core), except those that put fewer than
   --min-scan-fraction of the best scan's points there (far views that incremental mode would
   over-train, see drop_weak_scans); tiles that receive no point are dropped.
3. Writes, per tile, OUT/tiles/<tile>/seq (symlinks velodyne/NNNNNN.bin -> the original scans,
   the matching poses.txt lines, calib.txt) and config.yaml (the extra config plus
   map.origin_world_m = the common origin, preprocess.crop_world_m = the crop box, run.threads).
4. Submits one task per tile to the Dask cluster; each runs
   `shine map seq -o map --mode incremental -c config.yaml --no-eval` in a subprocess, its output
   in OUT/tiles/<tile>/shine.log. Incremental mode's decoder is pretrained and frozen, so all
   tiles share it and can be merged corner by corner. The scheduler, the workers and this script
   must see DATA, OUT and the shine binary at the same absolute paths (a shared filesystem).
5. Runs `shine merge --manifest OUT/manifest.json -o OUT [--ref ...]` and prints the merged
   metrics: OUT/map.vdb, surface.vdb, mesh.ply, stats.json; OUT/tiles_run.json has the plan and
   the per-tile timings.

Reruns are idempotent: every file is rewritten from the inputs, a tile whose inputs (scans, poses,
config, binary) did not change since its last successful run is not mapped again (--force maps it
anyway), and tile directories of an earlier, different grid are removed.

Run with Debian's python3 (packages python3-distributed, python3-numpy). See docs/tiles.md.
"""

import argparse
import hashlib
import json
import logging
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time

LOG = logging.getLogger("shine-tiles")
REPO_DIR = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
Z_UNBOUNDED_M = 1e4  # the crop box's half-height around the origin: z is not cropped


class TilesError(Exception):
    """A problem the user can fix; main() prints it and exits with status 1."""


def import_or_fail(name, package):
    try:
        return __import__(name)
    except ImportError as e:
        raise TilesError(
            "python module '%s' is missing (%s); install the Debian package %s "
            "(apt-get install %s) and run this script with /usr/bin/python3"
            % (name, e, package, package))


def write_atomically(path, text):
    """Writes `text` to `path` through a temporary file and a rename."""
    directory = os.path.dirname(path) or "."
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", dir=directory)
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


# --- input -----------------------------------------------------------------------------------

def read_sequence(data_dir):
    """Scan paths, pose lines (text, as in poses.txt) and T_world_lidar (numpy, n x 4 x 4)."""
    np = import_or_fail("numpy", "python3-numpy")
    velodyne = os.path.join(data_dir, "velodyne")
    poses_path = os.path.join(data_dir, "poses.txt")
    if not os.path.isdir(data_dir):
        raise TilesError("data directory '%s' does not exist" % data_dir)
    if not os.path.isdir(velodyne) or not os.path.isfile(poses_path):
        raise TilesError(
            "'%s' is not a KITTI-layout sequence: this script needs velodyne/NNNNNN.bin and "
            "poses.txt (12 numbers a line) there" % data_dir)
    names = [n for n in os.listdir(velodyne) if n.endswith(".bin")]
    if not names:
        raise TilesError("'%s' holds no .bin scans" % velodyne)

    def order(n):
        stem = n[:-4]
        return (0, int(stem), n) if stem.isdigit() else (1, 0, n)

    scans = [os.path.join(velodyne, n) for n in sorted(names, key=order)]
    with open(poses_path) as f:
        lines = [l.strip() for l in f if l.strip()]
    if len(lines) < len(scans):
        raise TilesError("'%s' has %d poses but '%s' has %d scans: every scan needs a pose"
                         % (poses_path, len(lines), velodyne, len(scans)))
    lines = lines[:len(scans)]
    poses = np.zeros((len(lines), 4, 4))
    for i, line in enumerate(lines):
        try:
            values = [float(v) for v in line.split()]
        except ValueError:
            values = []
        if len(values) != 12 or not all(math.isfinite(v) for v in values):
            raise TilesError("'%s' line %d: expected 12 finite numbers" % (poses_path, i + 1))
        poses[i, :3, :] = np.array(values).reshape(3, 4)
        poses[i, 3, 3] = 1.0
    calib = os.path.join(data_dir, "calib.txt")
    if os.path.isfile(calib):  # KITTI camera poses: T_world_lidar = Tr^-1 * P * Tr
        tr = None
        with open(calib) as f:
            for line in f:
                key, _, rest = line.partition(":")
                if key.strip() in ("Tr", "Tr_velo_to_cam"):
                    tr = np.eye(4)
                    tr[:3, :] = np.array([float(v) for v in rest.split()]).reshape(3, 4)
        if tr is not None:
            poses = np.linalg.inv(tr) @ poses @ tr
    return scans, lines, poses


def effective_config(shine, extra_config):
    """The configuration `shine map` would use with -c extra_config (YAML, parsed)."""
    yaml = import_or_fail("yaml", "python3-yaml")
    command = [shine, "map", "--print-config"]
    if extra_config:
        command += ["-c", extra_config]
    run = subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if run.returncode != 0:
        raise TilesError("'%s' rejected the configuration: %s" % (" ".join(command),
                                                                  run.stdout.strip()))
    return yaml.safe_load(run.stdout)


# --- the plan --------------------------------------------------------------------------------

class Tile:
    def __init__(self, ix, iy, core, crop):
        self.ix, self.iy = ix, iy
        self.name = "tile_%+04d_%+04d" % (ix, iy)
        self.core = core  # [xmin, ymin, xmax, ymax] world m, half-open
        self.crop = crop  # [xmin, ymin, zmin, xmax, ymax, zmax] world m, half-open
        self.scans = []   # indices into the sequence
        self.scan_counts = []  # points each of them puts into the crop box
        self.scan_points_each = []  # points of each of them, in range
        self.dropped = 0  # scans that see the tile too little (drop_weak_scans)
        self.points = 0   # points (of every point_stride-th) in the crop box
        self.scan_points = 0  # points (ditto) of its scans, in range, wherever they fall

    def share(self):
        """The tile's share of its scans' points: what its crop box keeps of them."""
        return self.points / self.scan_points if self.scan_points else 0.0


def plan_tiles(scans, poses, origin, tile_size_m, overlap_m, min_range_m, max_range_m,
               point_stride):
    """Tiles that receive points, each with the scans that put points into its crop box."""
    np = import_or_fail("numpy", "python3-numpy")
    ox, oy = origin[0], origin[1]
    xy = poses[:, :2, 3]
    lo = xy.min(axis=0) - max_range_m
    hi = xy.max(axis=0) + max_range_m
    ix_range = range(int(math.floor((lo[0] - ox) / tile_size_m)),
                     int(math.floor((hi[0] - ox) / tile_size_m)) + 1)
    iy_range = range(int(math.floor((lo[1] - oy) / tile_size_m)),
                     int(math.floor((hi[1] - oy) / tile_size_m)) + 1)
    tiles = {}
    for ix in ix_range:
        for iy in iy_range:
            core = [ox + ix * tile_size_m, oy + iy * tile_size_m,
                    ox + (ix + 1) * tile_size_m, oy + (iy + 1) * tile_size_m]
            crop = [core[0] - overlap_m, core[1] - overlap_m, origin[2] - Z_UNBOUNDED_M,
                    core[2] + overlap_m, core[3] + overlap_m, origin[2] + Z_UNBOUNDED_M]
            tiles[(ix, iy)] = Tile(ix, iy, core, crop)
    reach_m = max_range_m + overlap_m
    for i, path in enumerate(scans):
        sensor = poses[i, :3, 3]
        # Only tiles whose core is within max range + overlap of the sensor can get points.
        near = [t for t in tiles.values()
                if math.hypot(max(t.core[0] - sensor[0], 0.0, sensor[0] - t.core[2]),
                              max(t.core[1] - sensor[1], 0.0, sensor[1] - t.core[3])) <= reach_m]
        if not near:
            continue
        raw = np.fromfile(path, dtype=np.float32)
        if raw.size % 4 != 0:
            raise TilesError("scan '%s' has %d bytes, not a multiple of 16 (x y z i float32)"
                             % (path, raw.size * 4))
        p = raw.reshape(-1, 4)[::point_stride, :3].astype(np.float64)
        p = p[np.isfinite(p).all(axis=1)]
        r = np.linalg.norm(p, axis=1)
        p = p[(r >= min_range_m) & (r <= max_range_m)]
        world = p @ poses[i, :3, :3].T + poses[i, :3, 3]
        # Tile indices whose crop box [i*s - ov, (i+1)*s + ov) contains each point, per axis.
        gx0 = np.floor((world[:, 0] - ox - overlap_m) / tile_size_m).astype(np.int64)
        gx1 = np.floor((world[:, 0] - ox + overlap_m) / tile_size_m).astype(np.int64)
        gy0 = np.floor((world[:, 1] - oy - overlap_m) / tile_size_m).astype(np.int64)
        gy1 = np.floor((world[:, 1] - oy + overlap_m) / tile_size_m).astype(np.int64)
        # Count points per tile with one bincount over flat tile keys (a point can lie in the
        # crop boxes of up to (1 + ceil(2 overlap / size))^2 tiles).
        counts = np.zeros(len(ix_range) * len(iy_range), dtype=np.int64)
        for dx in range(int((gx1 - gx0).max(initial=0)) + 1):
            for dy in range(int((gy1 - gy0).max(initial=0)) + 1):
                kx, ky = gx0 + dx, gy0 + dy
                keep = ((kx <= gx1) & (ky <= gy1) & (kx >= ix_range.start) &
                        (kx < ix_range.stop) & (ky >= iy_range.start) & (ky < iy_range.stop))
                keys = (kx[keep] - ix_range.start) * len(iy_range) + (ky[keep] - iy_range.start)
                counts += np.bincount(keys, minlength=counts.size)
        for t in near:
            c = int(counts[(t.ix - ix_range.start) * len(iy_range) + (t.iy - iy_range.start)])
            if c > 0:
                t.scans.append(i)
                t.scan_counts.append(c)
                t.points += c
                t.scan_points += len(world)
                t.scan_points_each.append(len(world))
    return [t for t in sorted(tiles.values(), key=lambda t: (t.ix, t.iy)) if t.scans]


def drop_weak_scans(tiles, min_fraction):
    """Keeps, per tile, the scans that put at least `min_fraction` of the best scan's points into
    its crop box. Incremental mode spends each scan's whole training budget on the scan's points
    in the crop; a scan that sees the tile only from afar (a few sparse, grazing points) would
    then train them for as many steps as a close scan trains a dense one and wear down what the
    close scans mapped (measured in docs/tiles.md)."""
    for t in tiles:
        best = max(t.scan_counts)
        keep = [k for k, c in enumerate(t.scan_counts) if c >= min_fraction * best]
        t.dropped = len(t.scans) - len(keep)
        t.scan_points = int(round(sum(t.scan_points_each[k] for k in keep)))
        t.scans = [t.scans[k] for k in keep]
        t.scan_counts = [t.scan_counts[k] for k in keep]
        t.points = sum(t.scan_counts)


def tile_config(base_config, tile, origin, threads):
    """The tile's YAML config: the extra config plus origin, crop box and thread count."""
    config = json.loads(json.dumps(base_config))  # deep copy
    config.setdefault("map", {})["origin_world_m"] = [float(v) for v in origin]
    config.setdefault("preprocess", {})["crop_world_m"] = [float(v) for v in tile.crop]
    config.setdefault("run", {})["threads"] = threads
    return config


def write_tile_inputs(tile, tile_dir, scans, pose_lines, data_dir, config):
    """OUT/tiles/<tile>/seq (symlinks, poses.txt, calib.txt) and config.yaml, rewritten."""
    yaml = import_or_fail("yaml", "python3-yaml")
    seq = os.path.join(tile_dir, "seq")
    if os.path.isdir(seq):
        shutil.rmtree(seq)
    os.makedirs(os.path.join(seq, "velodyne"))
    for k, i in enumerate(tile.scans):
        os.symlink(os.path.abspath(scans[i]), os.path.join(seq, "velodyne", "%06d.bin" % k))
    write_atomically(os.path.join(seq, "poses.txt"),
                     "".join(pose_lines[i] + "\n" for i in tile.scans))
    calib = os.path.join(data_dir, "calib.txt")
    if os.path.isfile(calib):
        shutil.copyfile(calib, os.path.join(seq, "calib.txt"))
    text = ("# written by scripts/shine_dask_tiles.py for %s: core %s, crop %s\n"
            % (tile.name, tile.core, tile.crop)) + yaml.safe_dump(config, sort_keys=True)
    write_atomically(os.path.join(tile_dir, "config.yaml"), text)


def input_digest(tile, scans, pose_lines, config_text, shine):
    """What decides a tile's result: scan files (path, size, mtime), poses, config, binary."""
    h = hashlib.sha256()
    for i in tile.scans:
        st = os.stat(scans[i])
        h.update(("%s %d %d %s\n" % (os.path.abspath(scans[i]), st.st_size, st.st_mtime_ns,
                                     pose_lines[i])).encode())
    h.update(config_text.encode())
    st = os.stat(shine)
    h.update(("%s %d %d\n" % (shine, st.st_size, st.st_mtime_ns)).encode())
    return h.hexdigest()


# --- the Dask task ---------------------------------------------------------------------------

def map_tile(name, shine, seq_dir, config_path, out_dir, log_path, threads):
    """Runs on a Dask worker: `shine map` of one tile, its output in log_path. Returns a dict
    with the exit code, seconds, host and the log's last lines (never raises for a failed run,
    so that the client reports the tile by name)."""
    import os
    import socket
    import subprocess
    import time
    start = time.time()
    result = {"tile": name, "host": socket.gethostname(), "log": log_path}
    if not os.access(shine, os.X_OK):
        result.update(returncode=-1, seconds=0.0,
                      tail="shine binary '%s' is not executable on worker host %s (the cluster "
                           "needs a filesystem shared at the same paths)"
                           % (shine, result["host"]))
        return result
    command = [shine, "map", seq_dir, "-o", out_dir, "--mode", "incremental", "-c", config_path,
               "--threads", str(threads), "--no-eval", "-q"]
    with open(log_path, "w") as log:
        log.write("$ %s\n" % " ".join(command))
        log.flush()
        code = subprocess.call(command, stdout=log, stderr=subprocess.STDOUT)
    with open(log_path) as log:
        lines = log.read().splitlines()
    result.update(returncode=code, seconds=time.time() - start, tail="\n".join(lines[-15:]))
    return result


# --- main ------------------------------------------------------------------------------------

def connect(args):
    """A dask.distributed Client: to --scheduler, or to a new local cluster."""
    distributed = import_or_fail("distributed", "python3-distributed")
    if args.scheduler:
        try:
            client = distributed.Client(args.scheduler, timeout=args.connect_timeout_s)
        except (OSError, TimeoutError) as e:
            raise TilesError(
                "cannot reach the Dask scheduler at %s (%s); start one with `dask-scheduler` "
                "and workers with `dask-worker %s` on machines that share this filesystem, or "
                "use --local-workers N" % (args.scheduler, e, args.scheduler))
        workers = len(client.scheduler_info().get("workers", {}))
        LOG.info("connected to %s (%d workers); dashboard %s", args.scheduler, workers,
                 client.dashboard_link)
        if workers == 0:
            LOG.warning("the scheduler has no workers yet: tasks wait until one connects")
        return client, None
    cluster = distributed.LocalCluster(n_workers=args.local_workers, threads_per_worker=1,
                                       processes=True, dashboard_address=":0",
                                       silence_logs=logging.ERROR)
    client = distributed.Client(cluster)
    LOG.info("local Dask cluster: %d worker processes; dashboard %s", args.local_workers,
             client.dashboard_link)
    return client, cluster


def parse_args(argv):
    p = argparse.ArgumentParser(
        description="Map a KITTI-layout sequence as spatial tiles on a Dask cluster (one "
                    "`shine map --mode incremental` per tile) and merge them with `shine "
                    "merge` (docs/tiles.md).")
    p.add_argument("data", help="sequence directory (velodyne/NNNNNN.bin, poses.txt)")
    p.add_argument("-o", "--output", required=True, help="output directory")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--scheduler", help="address of a running Dask scheduler, "
                                           "e.g. tcp://host:8786")
    where.add_argument("--local-workers", type=int, default=4,
                       help="worker processes of a local cluster (default 4)")
    p.add_argument("--tile-size-m", type=float, default=40.0, help="tile edge (default 40 m)")
    p.add_argument("--overlap-m", type=float, default=10.0,
                   help="each tile also maps this far beyond its core (default 10 m)")
    p.add_argument("--shine", default=os.path.join(REPO_DIR, "build", "shine"),
                   help="the shine binary (default: build/shine of this checkout)")
    p.add_argument("-c", "--config", help="extra YAML configuration for every tile (and merge)")
    p.add_argument("--threads-per-tile", type=int, default=1,
                   help="threads of each tile's shine run (default 1)")
    p.add_argument("--ref", help="reference mesh for the merged map (default DATA/gt_mesh.ply "
                                 "when it exists)")
    p.add_argument("--no-eval", action="store_true", help="do not evaluate the merged mesh")
    p.add_argument("--point-stride", type=int, default=1,
                   help="plan with every n-th point of each scan (default 1: all)")
    p.add_argument("--force", action="store_true", help="map every tile, even up-to-date ones")
    p.add_argument("--min-scan-fraction", type=float, default=0.1,
                   help="a tile maps the scans that put at least this fraction of the best "
                        "scan's points into its crop box (default 0.1; 0: every scan that sees "
                        "it)")
    p.add_argument("--connect-timeout-s", type=float, default=20.0,
                   help="how long to try reaching --scheduler (default 20 s)")
    args = p.parse_args(argv)
    if not args.tile_size_m > 0:
        p.error("--tile-size-m must be > 0")
    if not 0 <= args.overlap_m <= args.tile_size_m:
        p.error("--overlap-m must be between 0 and --tile-size-m")
    if not 0 <= args.min_scan_fraction <= 1:
        p.error("--min-scan-fraction must be between 0 and 1")
    if args.local_workers < 1 or args.threads_per_tile < 1 or args.point_stride < 1:
        p.error("--local-workers, --threads-per-tile and --point-stride must be >= 1")
    return args


def run(args):
    start = time.time()
    yaml = import_or_fail("yaml", "python3-yaml")
    import_or_fail("distributed", "python3-distributed")
    shine = os.path.abspath(args.shine)
    if not (os.path.isfile(shine) and os.access(shine, os.X_OK)):
        raise TilesError("shine binary '%s' not found or not executable; build it (cmake "
                         "--build build) or pass --shine PATH" % shine)
    probe = subprocess.run([shine, "--help"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           text=True)
    if not any(line.split()[:1] == ["merge"] for line in probe.stdout.splitlines()):
        raise TilesError("'%s' has no `merge` command; rebuild it from this checkout" % shine)
    data = os.path.abspath(args.data)
    out = os.path.abspath(args.output)
    extra = {}
    if args.config:
        if not os.path.isfile(args.config):
            raise TilesError("config file '%s' does not exist" % args.config)
        with open(args.config) as f:
            extra = yaml.safe_load(f) or {}
        if not isinstance(extra, dict):
            raise TilesError("config file '%s' is not a YAML mapping" % args.config)
        if (extra.get("preprocess") or {}).get("crop_world_m"):
            raise TilesError("'%s' sets preprocess.crop_world_m; the tiles' crop boxes are "
                             "set by this script" % args.config)
        weights = (extra.get("incremental") or {}).get("decoder_weights", "builtin")
        if weights == "none":
            raise TilesError("'%s' sets incremental.decoder_weights: none; tiles can only be "
                             "merged when they share a frozen decoder (builtin or a file)"
                             % args.config)
        if weights != "builtin":  # a file: the same absolute path on every worker
            extra["incremental"]["decoder_weights"] = os.path.abspath(weights)
    config = effective_config(shine, args.config)
    pre = config["preprocess"]
    min_range_m, max_range_m = float(pre["min_range_m"]), float(pre["max_range_m"])

    scans, pose_lines, poses = read_sequence(data)
    if config["map"].get("origin_world_m"):
        origin = [float(v) for v in config["map"]["origin_world_m"]]
    else:  # as `shine map` chooses it: the first pose rounded to whole km
        origin = [math.copysign(math.floor(abs(v) / 1000.0 + 0.5) * 1000.0, v)
                  for v in poses[0, :3, 3].tolist()]  # std::round: halves away from zero
    t0 = time.time()
    tiles = plan_tiles(scans, poses, origin, args.tile_size_m, args.overlap_m, min_range_m,
                       max_range_m, args.point_stride)
    drop_weak_scans(tiles, args.min_scan_fraction)
    LOG.info("%d scans; %d tiles of %g m (overlap %g m) receive points; origin %s; planned "
             "in %.1f s", len(scans), len(tiles), args.tile_size_m, args.overlap_m, origin,
             time.time() - t0)
    if not tiles:
        raise TilesError("no scan point lies within %g m of its sensor: nothing to map"
                         % max_range_m)

    tiles_dir = os.path.join(out, "tiles")
    os.makedirs(tiles_dir, exist_ok=True)
    names = {t.name for t in tiles}
    for stale in os.listdir(tiles_dir):  # tiles of an earlier, different grid
        if stale.startswith("tile_") and stale not in names:
            shutil.rmtree(os.path.join(tiles_dir, stale))
    jobs = []
    for t in tiles:
        tile_dir = os.path.join(tiles_dir, t.name)
        os.makedirs(tile_dir, exist_ok=True)
        cfg = tile_config(extra, t, origin, args.threads_per_tile)
        write_tile_inputs(t, tile_dir, scans, pose_lines, data, cfg)
        with open(os.path.join(tile_dir, "config.yaml")) as f:
            digest = input_digest(t, scans, pose_lines, f.read(), shine)
        done_path = os.path.join(tile_dir, "done.json")
        up_to_date = False
        if not args.force and os.path.isfile(done_path):
            try:
                with open(done_path) as f:
                    up_to_date = json.load(f).get("inputs") == digest
            except ValueError:
                up_to_date = False
            up_to_date = up_to_date and os.path.isfile(os.path.join(tile_dir, "map", "map.vdb"))
        if not up_to_date:  # mapped from scratch: no result or checkpoint of an earlier run
            for stale in (done_path, os.path.join(tile_dir, "map", "checkpoint.bin")):
                if os.path.exists(stale):
                    os.unlink(stale)
        jobs.append({"tile": t, "dir": tile_dir, "digest": digest, "skip": up_to_date})
        LOG.info("%s: core %s, %d scans (%d seeing it less dropped), %d points (%.0f %% of "
                 "theirs)%s", t.name, t.core, len(t.scans), t.dropped, t.points,
                 100.0 * t.share(), " (up to date)" if up_to_date else "")

    results = {}
    todo = [j for j in jobs if not j["skip"]]
    map_seconds = 0.0
    if todo:
        distributed = import_or_fail("distributed", "python3-distributed")
        client, cluster = connect(args)
        try:
            t0 = time.time()
            futures = {}
            for j in todo:
                d = j["dir"]
                future = client.submit(map_tile, j["tile"].name, shine, os.path.join(d, "seq"),
                                       os.path.join(d, "config.yaml"), os.path.join(d, "map"),
                                       os.path.join(d, "shine.log"), args.threads_per_tile,
                                       key="shine-map-" + j["tile"].name, pure=False)
                futures[future] = j
            failed = []
            for k, future in enumerate(distributed.as_completed(futures), 1):
                j = futures[future]
                name = j["tile"].name
                try:
                    r = future.result()
                except Exception as e:  # the worker died or the task could not run
                    r = {"tile": name, "returncode": -1, "seconds": 0.0, "host": "?",
                         "log": os.path.join(j["dir"], "shine.log"),
                         "tail": "Dask task failed: %r" % (e,)}
                results[name] = r
                if r["returncode"] == 0:
                    write_atomically(os.path.join(j["dir"], "done.json"),
                                     json.dumps({"inputs": j["digest"], "seconds": r["seconds"],
                                                 "host": r["host"]}) + "\n")
                    LOG.info("[%d/%d] %s mapped in %.1f s on %s", k, len(futures), name,
                             r["seconds"], r["host"])
                else:
                    failed.append(r)
                    LOG.error("[%d/%d] %s FAILED (exit %s) on %s; log %s", k, len(futures), name,
                              r["returncode"], r["host"], r["log"])
            map_seconds = time.time() - t0
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
        if failed:
            raise TilesError("%d of %d tiles failed:\n%s" % (
                len(failed), len(todo), "\n".join(
                    "  %s (log %s):\n    %s" % (r["tile"], r["log"],
                                                r["tail"].replace("\n", "\n    "))
                    for r in failed)))
    else:
        LOG.info("every tile is up to date")

    manifest = {"tiles": [{"map": os.path.join("tiles", j["tile"].name, "map", "map.vdb"),
                           "core_world_m": j["tile"].core} for j in jobs]}
    manifest_path = os.path.join(out, "manifest.json")
    write_atomically(manifest_path, json.dumps(manifest, indent=2) + "\n")
    ref = args.ref or os.path.join(data, "gt_mesh.ply")
    command = [shine, "merge", "--manifest", manifest_path, "-o", out]
    if not args.no_eval and os.path.isfile(ref):
        command += ["--ref", ref]
    LOG.info("merging: %s", " ".join(command))
    t0 = time.time()
    merge = subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    sys.stdout.write(merge.stdout)
    if merge.returncode != 0:
        raise TilesError("shine merge failed (exit %d)" % merge.returncode)
    merge_seconds = time.time() - t0

    summary = {
        "data": data, "tile_size_m": args.tile_size_m, "overlap_m": args.overlap_m,
        "origin_world_m": origin, "scheduler": args.scheduler or "local",
        "local_workers": None if args.scheduler else args.local_workers,
        "threads_per_tile": args.threads_per_tile, "min_scan_fraction": args.min_scan_fraction,
        "seconds": {"map_tiles": map_seconds, "merge": merge_seconds,
                    "total": time.time() - start},
        "tiles": [{"name": j["tile"].name, "core_world_m": j["tile"].core,
                   "crop_world_m": j["tile"].crop, "scans": len(j["tile"].scans),
                   "scans_dropped": j["tile"].dropped,
                   "points": j["tile"].points, "share_of_scan_points": j["tile"].share(),
                   "up_to_date": j["skip"],
                   "seconds": results.get(j["tile"].name, {}).get("seconds"),
                   "host": results.get(j["tile"].name, {}).get("host")} for j in jobs]}
    write_atomically(os.path.join(out, "tiles_run.json"), json.dumps(summary, indent=2) + "\n")
    with open(os.path.join(out, "stats.json")) as f:
        stats = json.load(f)
    line = "tiled map: %d tiles, mapped in %.1f s, merged in %.1f s, total %.1f s" % (
        len(jobs), map_seconds, merge_seconds, time.time() - start)
    if "eval" in stats:
        e = stats["eval"]
        line += "; F-score %.2f %%, Chamfer-L1 %.2f cm" % (100 * e["fscore"],
                                                           100 * e["chamfer_l1_m"])
    print(line)
    return 0


def main(argv=None):
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(asctime)s shine-tiles: %(message)s", "%H:%M:%S"))
    LOG.addHandler(handler)
    LOG.setLevel(logging.INFO)
    LOG.propagate = False
    logging.getLogger("distributed").setLevel(logging.WARNING)  # progress comes from LOG
    args = parse_args(sys.argv[1:] if argv is None else argv)
    try:
        return run(args)
    except TilesError as e:
        sys.stderr.write("shine-tiles: error: %s\n" % e)
        return 1
    except KeyboardInterrupt:
        sys.stderr.write("shine-tiles: interrupted\n")
        return 130


if __name__ == "__main__":
    sys.exit(main())
