#!/usr/bin/env python3
"""How bodies touch, measured from the OBJ frames of a run (`jello run SCENE --frames DIR
--format obj`), as a user sees them: each body's skin is its object (`o NAME`) in the frame.

For the last frame (or the one given), for every pair of bodies whose skins come within NEAR
metres of each other: how deep a vertex of one skin is inside the other (the overlap), or, when
none is, how far apart the skins are (the gap). For each body, how its skin passes through
itself: the pairs of its triangles that share no vertex and cross (a triangle–triangle test on
the pairs whose boxes overlap in a uniform grid), the length of the curve they cross along, the
longest one pair's segment of it, and the deepest pair (of each triangle, the deepest of its
points over the other that lies behind it; the lesser of the two); 0 pairs when no face is
through another. Faces pressed together by a penalty contact cross a little (as deep as the
contact gives); faces gone through each other cross as deep as a triangle is wide. With
--apart M, the same again of only the pairs whose triangles were more than M apart in the first
frame (a run's start): parts of the skin that came together, not a crease where neighbours fold
into each other (which self-contact, acting only between places more than half a cell apart at
rest, leaves alone). With --all-frames, also each measure's largest over all frames, the frame
with the most pairs and how many frames have any. With --drift, how far each body's centre (the
mean of its skin's vertices) moved horizontally from the first frame, as a fraction of its size.

    scripts/contact_report.py DIR [--near M] [--frame N] [--apart M] [--all-frames] [--drift] [--json]

Needs numpy. Prints a table, or with --json one object: {"frame", "pairs": [{"bodies", "overlap",
"gap"}], "deepest_overlap", "largest_gap", "self": {name: {"pairs", "length", "longest",
"deepest", "apart": {the same four}}}, "self_crossing_pairs", "self_worst": {name: {"frame",
"pairs", "length", "longest", "deepest", "apart", "frames_crossed"}}, "drift": {name:
fraction}}.
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


def weld(vertices, faces):
    """The faces renumbered so that vertices at exactly the same place are one (a skin written
    with its seams split would otherwise have neighbours that share no vertex)."""
    _, first, inverse = np.unique(vertices, axis=0, return_index=True, return_inverse=True)
    return first[inverse.reshape(-1)][faces]


def candidate_pairs(tri):
    """Pairs (i < j) of triangles of `tri` (t, 3, 3) whose boxes overlap: a uniform grid of cells
    about as large as the median triangle's box, each triangle in every cell its box meets."""
    lo, hi = tri.min(axis=1), tri.max(axis=1)
    extent = (hi - lo).max(axis=1)
    origin = lo.min(axis=0)
    # At most 128 cells along the box's longest side, so that a few huge triangles stay cheap.
    size = max(float(np.median(extent)), float((hi.max(axis=0) - origin).max()) / 128, 1e-12)
    c0 = np.floor((lo - origin) / size).astype(np.int64)
    c1 = np.floor((hi - origin) / size).astype(np.int64)
    span = c1 - c0 + 1
    count = span.prod(axis=1)
    owner = np.repeat(np.arange(len(tri)), count)
    k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    sx, sy = span[owner, 0], span[owner, 1]
    cell = c0[owner] + np.stack([k % sx, k // sx % sy, k // (sx * sy)], axis=1)
    dims = c1.max(axis=0) + 1
    key = (cell[:, 2] * dims[1] + cell[:, 1]) * dims[0] + cell[:, 0]
    order = np.argsort(key, kind="stable")
    key, owner = key[order], owner[order]
    # Each entry with every later one in its cell.
    end = np.searchsorted(key, key, side="right")
    later = end - np.arange(len(key)) - 1
    a = np.repeat(np.arange(len(key)), later)
    b = a + 1 + np.arange(later.sum()) - np.repeat(np.cumsum(later) - later, later)
    i, j = owner[a], owner[b]
    i, j = np.minimum(i, j), np.maximum(i, j)
    pairs = np.unique(np.stack([i, j], axis=1), axis=0)
    i, j = pairs[:, 0], pairs[:, 1]
    keep = (i != j) & np.all(lo[i] <= hi[j], axis=1) & np.all(lo[j] <= hi[i], axis=1)
    return i[keep], j[keep]


def behind_over(tri, other):
    """For each k, how far the deepest point of triangle tri[k] that lies over other[k] (its foot
    on other[k]'s plane inside other[k]) is behind other[k] (against its outward normal); 0 where
    none is. Exact: that part of tri[k] is a convex polygon, whose deepest point is one of its
    corners: a corner of tri[k], a point where an edge of tri[k] meets one of the four planes that
    bound the region behind and over other[k] (its own plane and the three through its edges,
    square to it), or a point where two of those planes meet tri[k]'s plane."""
    a, b, c = other[:, 0], other[:, 1], other[:, 2]
    n = np.cross(b - a, c - a)
    n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    # The region's four bounding planes, (normal, point), inside where (p − point)·normal ≥ 0.
    planes = [(-n, a)] + [(np.cross(n, v - u), u) for u, v in ((a, b), (b, c), (c, a))]
    normals = np.stack([p[0] for p in planes], axis=1)            # (m, 4, 3)
    points = np.stack([p[1] for p in planes], axis=1)             # (m, 4, 3)
    normals = normals / np.maximum(np.linalg.norm(normals, axis=2, keepdims=True), 1e-300)
    offsets = np.einsum("mkj,mkj->mk", normals, points)           # (m, 4)
    candidates = [tri[:, 0], tri[:, 1], tri[:, 2]]
    for e in range(3):
        p, q = tri[:, e], tri[:, (e + 1) % 3]
        for k in range(4):
            sp = np.einsum("mj,mj->m", p, normals[:, k]) - offsets[:, k]
            sq = np.einsum("mj,mj->m", q, normals[:, k]) - offsets[:, k]
            t = np.clip(sp / np.where(sp != sq, sp - sq, 1.0), 0.0, 1.0)
            candidates.append(p + t[:, None] * (q - p))
    ta, tb, tc = tri[:, 0], tri[:, 1], tri[:, 2]
    own = np.cross(tb - ta, tc - ta)
    own = own / np.maximum(np.linalg.norm(own, axis=1, keepdims=True), 1e-300)
    for i in range(4):
        for j in range(i + 1, 4):
            m = np.stack([own, normals[:, i], normals[:, j]], axis=1)
            rhs = np.stack([np.einsum("mj,mj->m", own, ta), offsets[:, i], offsets[:, j]], axis=1)
            det = np.linalg.det(m)
            ok = np.abs(det) > 1e-12
            p = np.full_like(ta, np.nan)
            if ok.any():
                p[ok] = np.linalg.solve(m[ok], rhs[ok][..., None])[..., 0]
            candidates.append(p)
    cand = np.stack(candidates, axis=1)                           # (m, 21, 3)
    # Rounding allowed on the tests below: a billionth of the pair's size.
    size = (np.linalg.norm(tri - tri[:, :1], axis=2).max(axis=1)
            + np.linalg.norm(other - other[:, :1], axis=2).max(axis=1))[:, None]
    # Candidates on tri[k] (the plane-pair points may lie off it) and in the region.
    keep = ~np.isnan(cand[..., 0])
    for u, v in ((ta, tb), (tb, tc), (tc, ta)):
        side = np.einsum("mkj,mj->mk", np.cross((v - u)[:, None, :], cand - u[:, None, :]), own)
        keep &= side >= -1e-9 * size * size
    into = np.einsum("mkj,mlj->mkl", np.nan_to_num(cand), normals) - offsets[:, None, :]
    keep &= (into >= -1e-9 * size[..., None]).all(axis=2)
    return np.maximum(np.where(keep, into[:, :, 0], 0.0).max(axis=1), 0.0)


def crossings(ta, tb):
    """Where triangles ta[k] and tb[k] (each (m, 3, 3), outward: counter-clockwise seen from
    outside) cross: whether they do, the length of the segment they cross along, and how deep:
    the lesser of the two triangles' depths, each the deepest of its points over the other
    behind it (`behind_over`; a corner behind the other's plane but beside the other is not
    through it: faces pressed together at a slant cross along a short segment, and their
    corners lie far behind each other's planes). The segment's ends are where an edge of one
    passes through the other (strictly: an edge that only touches the other's plane, and
    coplanar triangles, do not cross)."""
    points = []
    for tri, other in ((ta, tb), (tb, ta)):
        a, b, c = other[:, 0], other[:, 1], other[:, 2]
        n = np.cross(b - a, c - a)
        for e in range(3):
            p, q = tri[:, e], tri[:, (e + 1) % 3]
            dp = np.einsum("ij,ij->i", p - a, n)
            dq = np.einsum("ij,ij->i", q - a, n)
            through = dp * dq < 0
            x = p + (dp / np.where(through, dp - dq, 1.0))[:, None] * (q - p)
            # x inside the triangle: on the inner side of its three edges.
            for u, v in ((a, b), (b, c), (c, a)):
                through &= np.einsum("ij,ij->i", np.cross(v - u, x - u), n) >= 0
            points.append(np.where(through[:, None], x, np.nan))
    points = np.stack(points, axis=1)  # (m, 6, 3)
    crossed = ~np.isnan(points[:, :, 0])
    hit = crossed.any(axis=1)
    # The longest distance between two of a pair's ends (a missing end stands in as its first).
    first = points[np.arange(len(points)), crossed.argmax(axis=1)]
    ends = np.where(crossed[..., None], points, first[:, None, :])[hit]
    length = np.zeros(len(hit))
    length[hit] = np.linalg.norm(ends[:, :, None, :] - ends[:, None, :, :], axis=3).max(axis=(1, 2))
    depth = np.zeros(len(hit))
    depth[hit] = np.minimum(behind_over(ta[hit], tb[hit]), behind_over(tb[hit], ta[hit]))
    return hit, length, depth


def self_crossings(vertices, faces, rest=None, apart=0.0):
    """How a closed skin passes through itself: the pairs of its triangles that cross while sharing
    no vertex, the length of the curve they cross along (the sum of their segments), the longest
    segment, and the deepest pair (see crossings). With `rest` (the same vertices elsewhere, as in
    the first frame), also the same of only the pairs whose triangles' centres were more than
    `apart` from each other there, under "apart"."""
    welded = weld(vertices, faces)
    tri = vertices[welded]
    i, j = candidate_pairs(tri)
    share = (welded[i][:, :, None] == welded[j][:, None, :]).any(axis=(1, 2))
    i, j = i[~share], j[~share]
    found = []
    for k in range(0, len(i), 65536):
        hit, segment, depth = crossings(tri[i[k:k + 65536]], tri[j[k:k + 65536]])
        found.append((i[k:k + 65536][hit], j[k:k + 65536][hit], segment[hit], depth[hit]))
    i, j, segment, depth = (np.concatenate(x) for x in zip(*found)) if found else (np.zeros(0, int),) * 4

    def summary(keep):
        return {"pairs": int(keep.sum()), "length": float(segment[keep].sum()),
                "longest": float(segment[keep].max(initial=0.0)),
                "deepest": float(depth[keep].max(initial=0.0))}

    out = summary(np.ones(len(i), dtype=bool))
    if rest is not None:
        centre = rest[faces].mean(axis=1)
        out["apart"] = summary(np.linalg.norm(centre[i] - centre[j], axis=1) > apart)
    return out


def touch(skin_a, tri_b):
    """How deep the deepest vertex of skin A is inside the mesh B (0 if none is), and the least
    distance from a vertex of A outside B to B's surface."""
    d = distance(skin_a, tri_b)
    inside = winding(skin_a, tri_b) > 0.5
    overlap = d[inside].max() if inside.any() else 0.0
    gap = d[~inside].min() if (~inside).any() else 0.0
    return float(overlap), float(gap)


def self_report(frame, rest=None, apart=0.0):
    """Each body's self_crossings in the frame, by name (with `rest`, the first frame's vertices,
    also those of triangles more than `apart` from each other there)."""
    v, objects = read_obj(frame)
    if rest is not None and len(rest) != len(v):
        sys.exit(f"{frame}: {len(v)} vertices, the first frame {len(rest)}: not the same skins")
    return {name: self_crossings(v, faces, rest, apart) for name, faces in objects}


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


def largest(a, b):
    """Each number of b, or of a where larger (a new dict: neither is changed)."""
    return {k: largest(a[k], v) if isinstance(v, dict) else max(a[k], v) for k, v in b.items()}


def crossed(s, apart=None):
    if not s["pairs"]:
        return "no faces cross"
    text = (f"{s['pairs']} pair(s) of faces cross, along {s['length']:.3e} m "
            f"(longest {s['longest']:.3e} m), {s['deepest']:.3e} m deep")
    if "apart" in s:
        a = s["apart"]
        text += f"; of them {a['pairs']} more than {apart} m apart at first"
        if a["pairs"]:
            text += f", {a['deepest']:.3e} m deep"
    return text


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("frames", type=Path, help="folder of frame_*.obj")
    parser.add_argument("--near", type=float, default=0.05,
                        help="pairs of skins closer than this are reported (m; default 0.05)")
    parser.add_argument("--frame", type=int, help="the frame to judge (default: the last)")
    parser.add_argument("--apart", type=float, metavar="M",
                        help="also count self-crossings only between triangles more than M apart in "
                             "the first frame (a run's first frame is its start)")
    parser.add_argument("--all-frames", action="store_true",
                        help="also the largest of each self-crossing measure over all frames")
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
    rest = read_obj(frames[0])[0] if args.apart is not None else None
    selves = self_report(frame, rest, args.apart or 0.0)
    result = {
        "frame": frame.name,
        "pairs": pairs,
        "deepest_overlap": max((p["overlap"] for p in pairs), default=0.0),
        "largest_gap": max((p["gap"] for p in pairs), default=0.0),
        "self": selves,
        "self_crossing_pairs": sum(s["pairs"] for s in selves.values()),
    }
    if args.all_frames:
        worst = {}
        for f in frames:
            for name, s in (selves if f == frame else self_report(f, rest, args.apart or 0.0)).items():
                w = worst.setdefault(name, {"frame": f.name, **s, "frames_crossed": 0})
                w["frames_crossed"] += s["pairs"] > 0
                if s["pairs"] > w["pairs"]:
                    w["frame"] = f.name
                w.update(largest(w, s))
        result["self_worst"] = worst
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
    for name, s in selves.items():
        print(f"  {name} through itself: {crossed(s, args.apart)}")
    for name, w in result.get("self_worst", {}).items():
        print(f"  {name} through itself at worst (most pairs in {w['frame']}, {w['frames_crossed']} "
              f"of {len(frames)} frames crossed): {crossed(w, args.apart)}")
    for name, d in result.get("drift", {}).items():
        print(f"  {name} drifted {100 * d:.2f} % of its size horizontally")


if __name__ == "__main__":
    main()
