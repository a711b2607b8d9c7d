#!/usr/bin/env python3
"""How bodies touch, measured from the OBJ frames of a run (`jello run SCENE --frames DIR
--format obj`), as a user sees them: each body's skin is its object (`o NAME`) in the frame.

For the last frame (or the one given), for every pair of bodies whose skins come within NEAR
metres of each other: how deep a vertex of one skin is inside the other (the overlap), or, when
none is, how far apart the skins are (the gap). With --drift, how far each body's centre (the
mean of its skin's vertices) moved horizontally from the first frame, as a fraction of its size.

    scripts/contact_report.py DIR [--near M] [--frame N] [--drift] [--json]

Needs numpy. Prints a table, or with --json one object: {"frame", "pairs": [{"bodies", "overlap",
"gap"}], "deepest_overlap", "largest_gap", "drift": {name: fraction}}.
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np


def read_obj(path):
    """The frame's vertices and, per object in order, its name and triangles (0-based)."""
    vertices, objects = [], []
    with open(path, encoding="utf-8") as f:
        for number, line in enumerate(f, 1):
            parts = line.split()
            if not parts or parts[0].startswith("#"):
                continue
            if parts[0] == "v":
                vertices.append([float(x) for x in parts[1:4]])
            elif parts[0] == "o":
                objects.append((" ".join(parts[1:]), []))
            elif parts[0] == "f":
                if not objects:
                    sys.exit(f"{path}:{number}: a face before any `o NAME` line: frames of an older jello?")
                objects[-1][1].append([int(p.split("/")[0]) - 1 for p in parts[1:4]])
    v = np.array(vertices, dtype=float)
    return v, [(name, np.array(faces, dtype=int).reshape(-1, 3)) for name, faces in objects]


def winding(points, tri):
    """Generalised winding number of the closed triangle mesh `tri` (t, 3, 3) at each point: 1
    inside, 0 outside (Van Oosterom and Strackee's solid angle)."""
    a = tri[None, :, 0, :] - points[:, None, :]
    b = tri[None, :, 1, :] - points[:, None, :]
    c = tri[None, :, 2, :] - points[:, None, :]
    la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
    det = np.einsum("ijk,ijk->ij", a, np.cross(b, c))
    div = (la * lb * lc + np.einsum("ijk,ijk->ij", a, b) * lc
           + np.einsum("ijk,ijk->ij", a, c) * lb + np.einsum("ijk,ijk->ij", b, c) * la)
    return np.arctan2(det, div).sum(axis=1) / (2 * np.pi)


def distance(points, tri):
    """Distance from each point to the nearest triangle of `tri` (t, 3, 3)."""
    p = points[:, None, :]
    a, b, c = tri[None, :, 0, :], tri[None, :, 1, :], tri[None, :, 2, :]
    n = np.cross(b - a, c - a)
    n = n / np.maximum(np.linalg.norm(n, axis=2, keepdims=True), 1e-300)
    height = np.einsum("ijk,ijk->ij", p - a, n)
    q = p - height[..., None] * n
    inside = np.ones(height.shape, dtype=bool)
    for u, v in ((a, b), (b, c), (c, a)):
        inside &= np.einsum("ijk,ijk->ij", np.cross(v - u, q - u), n) >= 0
    best = np.where(inside, np.abs(height), np.inf)
    for u, v in ((a, b), (b, c), (c, a)):
        e = v - u
        t = np.clip(np.einsum("ijk,ijk->ij", p - u, e) / np.maximum(np.einsum("ijk,ijk->ij", e, e), 1e-300), 0, 1)
        best = np.minimum(best, np.linalg.norm(p - (u + t[..., None] * e), axis=2))
    return best.min(axis=1)


def touch(skin_a, tri_b):
    """How deep the deepest vertex of skin A is inside the mesh B (0 if none is), and the least
    distance from a vertex of A outside B to B's surface."""
    d = distance(skin_a, tri_b)
    inside = winding(skin_a, tri_b) > 0.5
    overlap = d[inside].max() if inside.any() else 0.0
    gap = d[~inside].min() if (~inside).any() else 0.0
    return float(overlap), float(gap)


def report(frame, near):
    v, objects = read_obj(frame)
    bodies = []
    for name, faces in objects:
        skin = v[np.unique(faces)]
        bodies.append((name, skin, v[faces], skin.min(axis=0), skin.max(axis=0)))
    pairs = []
    for i in range(len(bodies)):
        for j in range(i + 1, len(bodies)):
            (na, sa, ta, loa, hia), (nb, sb, tb, lob, hib) = bodies[i], bodies[j]
            if np.any(loa > hib + near) or np.any(lob > hia + near):
                continue
            (oa, ga), (ob, gb) = touch(sa, tb), touch(sb, ta)
            overlap = max(oa, ob)
            gap = 0.0 if overlap > 0 else min(ga, gb)
            if overlap > 0 or gap <= near:
                pairs.append({"bodies": [na, nb], "overlap": overlap, "gap": gap})
    return pairs


def centres(frame):
    v, objects = read_obj(frame)
    out = {}
    for name, faces in objects:
        skin = v[np.unique(faces)]
        out[name] = (skin.mean(axis=0), float((skin.max(axis=0) - skin.min(axis=0)).max()))
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("frames", type=Path, help="folder of frame_*.obj")
    parser.add_argument("--near", type=float, default=0.05,
                        help="pairs of skins closer than this are reported (m; default 0.05)")
    parser.add_argument("--frame", type=int, help="the frame to judge (default: the last)")
    parser.add_argument("--drift", action="store_true",
                        help="also each body's horizontal drift from the first frame, over its size")
    parser.add_argument("--json", action="store_true", help="print JSON")
    args = parser.parse_args()
    frames = sorted(args.frames.glob("frame_*.obj"))
    if not frames:
        sys.exit(f"{args.frames}: no frame_*.obj (run with --frames {args.frames} --format obj)")
    if args.frame is not None and not 0 <= args.frame < len(frames):
        sys.exit(f"--frame {args.frame}: {args.frames} has frames 0 to {len(frames) - 1}")
    frame = frames[-1 if args.frame is None else args.frame]
    pairs = report(frame, args.near)
    result = {
        "frame": frame.name,
        "pairs": pairs,
        "deepest_overlap": max((p["overlap"] for p in pairs), default=0.0),
        "largest_gap": max((p["gap"] for p in pairs), default=0.0),
    }
    if args.drift:
        first, last = centres(frames[0]), centres(frame)
        result["drift"] = {
            name: float(np.linalg.norm((last[name][0] - c)[:2]) / size)
            for name, (c, size) in first.items() if name in last
        }
    if args.json:
        print(json.dumps(result, indent=1))
        return
    print(f"{frame.name}: {len(pairs)} pair(s) of skins within {args.near} m")
    for p in pairs:
        a, b = p["bodies"]
        what = f"overlap {p['overlap']:.3e} m" if p["overlap"] > 0 else f"gap {p['gap']:.3e} m"
        print(f"  {a} and {b}: {what}")
    print(f"deepest overlap {result['deepest_overlap']:.3e} m, largest gap {result['largest_gap']:.3e} m")
    for name, d in result.get("drift", {}).items():
        print(f"  {name} drifted {100 * d:.2f} % of its size horizontally")


if __name__ == "__main__":
    main()
