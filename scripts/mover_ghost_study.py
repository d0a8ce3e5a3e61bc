#!/usr/bin/env python3
"""Where the ghosts of a simulated street with movers come from (docs/movers.md).

    python3 scripts/mover_ghost_study.py SIM_DIR MESH.ply [--cache votes.npz]

SIM_DIR is a `shine simulate --movers N` directory, MESH.ply a map of it (`shine map`). The script
recomputes every scan point's votes as range_image.cpp and free_space_votes.cpp do (3 x 3 window,
margin 0.2 m + 2 bins at the point's distance), for each of the other scans, labels each point with
the mover it lies on (inside the mover's box grown by 5 cm at the ray's time), samples the mesh's
ghost surface (400 samples per m^2, at least 10 cm from the static reference, inside a mover's
swept box) and prints where it lies and why the votes kept the mover points under it, by group.
The near rule it applies is the one before the far votes (10 scans per side, 2 votes, 30 % free).

Needs Debian's python3-numpy and python3-scipy; takes a few minutes and about 2 GB of memory for
the 50-scan street.
"""
import argparse
import json

import numpy as np
from scipy.spatial import cKDTree

TWO_PI = 2.0 * np.pi


class RangeImage:
    """The nearest return per square (elevation, azimuth) bin, and its 3 x 3 window minimum."""

    def __init__(self, p):
        r = np.linalg.norm(p, axis=1)
        p, r = p[r >= 1e-6], r[r >= 1e-6]
        el = np.arctan2(p[:, 2], np.hypot(p[:, 0], p[:, 1]))
        az = np.arctan2(p[:, 1], p[:, 0])
        n, el_min, el_max = len(r), el.min(), el.max()
        b = np.sqrt(max(el_max - el_min, TWO_PI / n) * TWO_PI / n)
        cols = int(np.ceil(TWO_PI / b))
        b = TWO_PI / cols
        rows = int(np.floor((el_max - el_min) / b)) + 1
        self.bin_rad, self.el_min, self.rows, self.cols = b, el_min, rows, cols
        row = np.clip(((el - el_min) / b).astype(int), 0, rows - 1)
        col = np.clip(((az + np.pi) / b).astype(int), 0, cols - 1)
        img = np.full(rows * cols, np.inf)
        np.minimum.at(img, row * cols + col, r)
        self.centre = img.reshape(rows, cols)
        # Window minimum and count, azimuth wrapping; rows -1 and `rows` see the edge rows.
        pad = np.full((rows + 2, cols), np.inf)
        pad[1:-1] = self.centre
        self.min = np.full((rows + 2, cols), np.inf)
        self.count = np.zeros((rows + 2, cols), int)
        for dr in (-1, 0, 1):
            shifted = np.roll(pad, -dr, axis=0)
            if dr == 1:
                shifted[-1] = np.inf
            if dr == -1:
                shifted[0] = np.inf
            for dc in (-1, 0, 1):
                s = np.roll(shifted, -dc, axis=1)
                self.min = np.minimum(self.min, s)
                self.count += np.isfinite(s)

    def vote(self, q):
        """-1 no return in the window, 0 hidden, 1 hit, 2 free; and the centre bin's outcome."""
        d = np.linalg.norm(q, axis=1)
        el = (np.arctan2(q[:, 2], np.hypot(q[:, 0], q[:, 1])) - self.el_min) / self.bin_rad
        inside = (el >= -1) & (el < self.rows + 1)
        row = np.clip(np.floor(el).astype(int) + 1, 0, self.rows + 1)
        col = (((np.arctan2(q[:, 1], q[:, 0]) + np.pi) / self.bin_rad).astype(int)) % self.cols
        nearest = np.where(inside, self.min[row, col], np.inf)
        count = np.where(inside, self.count[row, col], 0)
        margin = 0.2 + 2.0 * self.bin_rad * d

        def outcome(r, has):
            return np.where(~has, -1, np.where(r > d + margin, 2, np.where(r >= d - margin, 1, 0)))

        crow = row - 1
        ok = (crow >= 0) & (crow < self.rows)
        centre = np.full(len(q), np.inf)
        centre[ok] = self.centre[crow[ok], col[ok]]
        return outcome(nearest, count > 0), outcome(centre, np.isfinite(centre))


def mover_pose(mover, t):
    w = mover["waypoints"]
    ts = np.array([x["t_s"] for x in w])
    pos = np.array([x["position_m"] for x in w])
    yaw = np.array([x["yaw_rad"] for x in w])
    t = np.clip(t, ts[0], ts[-1])
    return np.stack([np.interp(t, ts, pos[:, i]) for i in range(3)], 1), np.interp(t, ts, yaw)


def scan_votes(sim_dir):
    sim = json.load(open(f"{sim_dir}/simulation.json"))
    movers = sim["movers"]["list"]
    steps = sim["lidar"]["azimuth_steps"]
    period, sweep = sim["movers"]["frame_period_s"], sim["movers"]["sweep_s"]
    poses = np.loadtxt(f"{sim_dir}/poses.txt").reshape(-1, 3, 4)
    n = len(poses)
    T = [np.vstack([poses[k], [0, 0, 0, 1]]) for k in range(n)]
    scans = [np.fromfile(f"{sim_dir}/velodyne/{k:06d}.bin", np.float32).reshape(-1, 4)[:, :3]
             .astype(np.float64) for k in range(n)]
    images = [RangeImage(p) for p in scans]
    pts, scan, label, window, centre = [], [], [], [], []
    for k in range(n):
        p = scans[k]
        r = np.linalg.norm(p, axis=1)
        p = p[(r >= 1.5) & (r <= 60.0)]
        az = np.mod(np.arctan2(p[:, 1], p[:, 0]), TWO_PI)
        t = k * period + sweep * (np.round(az / TWO_PI * steps) % steps) / steps
        pw = p @ T[k][:3, :3].T + T[k][:3, 3]
        lab = np.full(len(p), -1)
        for i, m in enumerate(movers):
            pos, yaw = mover_pose(m, t)
            L, W, H = m["size_m"]
            dx = pw - pos
            bx = np.cos(yaw) * dx[:, 0] + np.sin(yaw) * dx[:, 1]
            by = -np.sin(yaw) * dx[:, 0] + np.cos(yaw) * dx[:, 1]
            on = ((np.abs(bx) <= L / 2 + 0.05) & (np.abs(by) <= W / 2 + 0.05) &
                  (dx[:, 2] >= -0.05) & (dx[:, 2] <= H + 0.05))
            lab[on & (lab < 0)] = i
        win = np.full((len(p), n), -3, np.int8)
        ctr = np.full((len(p), n), -3, np.int8)
        for j in range(n):
            if j == k:
                continue
            inv = np.linalg.inv(T[j])
            win[:, j], ctr[:, j] = images[j].vote(pw @ inv[:3, :3].T + inv[:3, 3])
        pts.append(pw), scan.append(np.full(len(p), k)), label.append(lab)
        window.append(win), centre.append(ctr)
    return dict(pts=np.concatenate(pts), scan=np.concatenate(scan),
                mover=np.concatenate(label), window=np.concatenate(window),
                centre=np.concatenate(centre), kinds=np.array([m["kind"] for m in movers]))


def read_ply(path):
    with open(path, "rb") as f:
        header = b""
        while not header.endswith(b"end_header\n"):
            header += f.readline()
        lines = header.decode().split("\n")
        nv = int([l for l in lines if l.startswith("element vertex")][0].split()[-1])
        nf = int([l for l in lines if l.startswith("element face")][0].split()[-1])
        extra = [("o", "u1")] if "property uchar observed" in lines else []
        v = np.frombuffer(f.read(nv * 12), np.float32).reshape(nv, 3).astype(np.float64)
        face = np.dtype([("n", "u1"), ("i", "<i4", 3)] + extra)
        return v, np.frombuffer(f.read(nf * face.itemsize), face)["i"]


def sample_mesh(v, f, per_m2, rng):
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    t = np.repeat(np.arange(len(f)),
                  rng.poisson(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1) * per_m2))
    u, w = rng.random(len(t)), rng.random(len(t))
    flip = u + w > 1
    u[flip], w[flip] = 1 - u[flip], 1 - w[flip]
    return a[t] + u[:, None] * (b[t] - a[t]) + w[:, None] * (c[t] - a[t])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("sim_dir")
    ap.add_argument("mesh")
    ap.add_argument("--cache", help="votes file to write, or to read if it exists")
    args = ap.parse_args()
    try:
        z = dict(np.load(args.cache))
    except (TypeError, FileNotFoundError):
        z = scan_votes(args.sim_dir)
        if args.cache:
            np.savez(args.cache, **z)
    P, S, M, O, C = z["pts"], z["scan"], z["mover"], z["window"], z["centre"]
    n = O.shape[1]
    frames = np.arange(n)
    near = np.abs(frames[None, :] - S[:, None]) <= 10
    f, h = ((O == 2) & near).sum(1), ((O == 1) & near).sum(1)
    kept_movers = ~((f >= 2) & (f >= 0.3 * (f + h))) & (M >= 0) & (P[:, 2] > 0.08)

    rng = np.random.default_rng(0)
    per_m2 = 400.0
    samples = sample_mesh(*read_ply(args.mesh), per_m2, rng)
    ref = sample_mesh(*read_ply(f"{args.sim_dir}/gt_mesh.ply"), 2500.0, rng)
    off = cKDTree(ref).query(samples, distance_upper_bound=0.2, workers=2)[0] >= 0.1
    sim = json.load(open(f"{args.sim_dir}/simulation.json"))
    swept = np.zeros(len(samples), bool)
    for m in sim["movers"]["list"]:
        L, W, H = m["size_m"]
        w = m["waypoints"]
        for s in range(len(w) - 1):
            p0, p1 = np.array(w[s]["position_m"]), np.array(w[s + 1]["position_m"])
            lo = np.minimum(p0, p1) - [L / 2 + 0.1, W / 2 + 0.1, 0.1]
            hi = np.maximum(p0, p1) + [L / 2 + 0.1, W / 2 + 0.1, H + 0.1]
            swept |= np.all((samples >= lo) & (samples <= hi), axis=1)
    ghosts = samples[off & swept]
    print(f"ghost area {len(ghosts) / per_m2:.1f} m^2")
    for name, col, edges in (("along x", 0, [-70, 0, 50, 125]),
                             ("across y", 1, [-8, -5.5, -2.85, 0, 2.85, 5.5, 8]),
                             ("height z", 2, [-1, 0.1, 0.5, 1.0, 1.6, 2.0])):
        hist = np.histogram(ghosts[:, col], edges)[0] / per_m2
        print(f"  {name} {edges}: " + " ".join(f"{a:.1f}" for a in hist))

    kept = np.where(kept_movers)[0]
    dist, nearest = cKDTree(P[kept]).query(ghosts)
    under = np.unique(kept[nearest[dist < 0.3]])
    rng_m = np.linalg.norm(P[under, :2] - np.stack([S[under], 0 * S[under]], 1), axis=1)
    print(f"kept mover points within 0.3 m of a ghost sample: {len(under)}; "
          f"behind their sensor {np.mean(P[under, 0] < S[under]):.2f}; "
          f"median range {np.median(rng_m):.1f} m")
    kinds = z["kinds"]
    ys = np.array([m["waypoints"][0]["position_m"][1] for m in sim["movers"]["list"]])
    parked = np.array([len(m["waypoints"]) > 2 for m in sim["movers"]["list"]])
    groups = {
        "parked car that leaves": parked[M[under]],
        "right lane behind the sensor": (~parked[M[under]]) & (kinds[M[under]] == "car") &
                                        (ys[M[under]] < 0) & (P[under, 0] < S[under]),
        "oncoming cars": (kinds[M[under]] == "car") & (ys[M[under]] > 0),
        "cyclists": kinds[M[under]] == "cyclist",
        "pedestrians": kinds[M[under]] == "pedestrian",
    }
    everyone = np.ones((len(under), n), bool)
    for name, sel in groups.items():
        ids = under[sel]
        if len(ids) == 0:
            continue
        line = f"  {name:30s} {len(ids):6d} points"
        for label, votes, w in (("window, +-10", O[ids], near[ids]),
                                ("window, all", O[ids], everyone[: len(ids)]),
                                ("centre, all", C[ids], everyone[: len(ids)])):
            ff = ((votes == 2) & w).sum(1)
            hh = ((votes == 1) & w).sum(1)
            hid = ((votes == 0) & w).sum(1)
            dyn = ((ff >= 2) & (ff >= 0.3 * (ff + hh))).mean()
            line += (f" | {label}: free {ff.mean():.1f} hit {hh.mean():.1f} hidden {hid.mean():.1f}"
                     f" -> dynamic {dyn * 100:.0f} %")
        print(line)


if __name__ == "__main__":
    main()
