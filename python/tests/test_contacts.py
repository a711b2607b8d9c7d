"""Contacts between bodies from Python and as a user measures them: self-contact in a scene made
in Python, and `scripts/contact_report.py` on the OBJ frames of two cubes resting on each other."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import jello

from conftest import REPO


def test_self_contact_is_asked_for_by_name() -> None:
    on = jello.create([jello.cube(4, size=0.5)], self_contact=True)
    off = jello.create([jello.cube(4, size=0.5)])
    assert "self_contact = true" in on.dumps()
    assert "self_contact" not in off.dumps()


def test_the_report_finds_cubes_resting_skin_to_skin(cli: Path, tmp_path: Path) -> None:
    """Two 0.5 m cubes of 5³ points dropped on each other: at rest their skins are neither apart
    nor inside each other by more than 2 % of a cell (0.125 m), and they stay one above the
    other."""
    scene = tmp_path / "pair.toml"
    subprocess.run(
        [cli, "create", scene, "--cube", "5", "--size", "0.5", "--centre", "0,0,-1.75",
         "--total-mass", "1", "--cube", "5", "--size", "0.5", "--centre", "0,0,-1.2",
         "--total-mass", "1", "--collision-stiffness", "2000"],
        check=True, capture_output=True,
    )
    frames = tmp_path / "frames"
    subprocess.run(
        [cli, "run", scene, "--time", "3", "--frames", frames, "--format", "obj", "--every", "1000", "-q"],
        check=True, capture_output=True,
    )
    out = subprocess.run(
        [sys.executable, REPO / "scripts" / "contact_report.py", frames, "--json", "--drift"],
        check=True, capture_output=True, text=True,
    )
    report = json.loads(out.stdout)
    assert [p["bodies"] for p in report["pairs"]] == [["cube1", "cube2"]]
    cell = 0.125
    assert report["deepest_overlap"] < 0.02 * cell, report
    assert report["largest_gap"] < 0.02 * cell, report
    assert all(d < 0.01 for d in report["drift"].values()), report


def cube_skin(corner: tuple[float, float, float]) -> tuple[list[list[float]], list[list[int]]]:
    """A unit cube's twelve outward triangles, its corner at `corner`."""
    v = [[corner[0] + x, corner[1] + y, corner[2] + z] for z in (0, 1) for y in (0, 1) for x in (0, 1)]
    f = [[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
         [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]]
    return v, f


def torus_skin(squash: float) -> tuple[list[list[float]], list[list[int]]]:
    """A ring standing on its edge (radius 0.3, tube 0.1, 24 × 12 quads, welded), its upper half
    moved down by `squash` (m): by more than 0.4 its top passes through its bottom."""
    import math

    big, small, n, m = 0.3, 0.1, 24, 12
    v, f = [], []
    for i in range(n):
        for j in range(m):
            u, w = 2 * math.pi * i / n, 2 * math.pi * j / m
            r = big + small * math.cos(w)
            z = r * math.sin(u)
            v.append([r * math.cos(u), small * math.sin(w), z - squash if z > 0 else z])
            a, b = i * m + j, i * m + (j + 1) % m
            c, d = (i + 1) % n * m + j, (i + 1) % n * m + (j + 1) % m
            f += [[a, c, d], [a, d, b]]
    return v, f


def write_frame(path: Path, bodies: dict[str, tuple[list[list[float]], list[list[int]]]]) -> None:
    """An OBJ frame as `jello run --format obj` writes one: every vertex, then each body's faces
    under `o NAME`."""
    lines, base, faces = [], 0, []
    for name, (v, f) in bodies.items():
        lines += [f"v {x} {y} {z}" for x, y, z in v]
        faces += [f"o {name}"] + [f"f {a + base + 1} {b + base + 1} {c + base + 1}" for a, b, c in f]
        base += len(v)
    path.write_text("\n".join(lines + faces) + "\n", encoding="utf-8")


def report_on(frames: Path, *flags: str) -> dict:
    out = subprocess.run(
        [sys.executable, REPO / "scripts" / "contact_report.py", frames, "--json", *flags],
        check=True, capture_output=True, text=True,
    )
    return json.loads(out.stdout)


def test_the_report_finds_a_skin_through_itself(tmp_path: Path) -> None:
    """Hand-made skins: two unit cubes as one body, the second's corner at (0.5, 0.4, 0.3), cross
    along six segments 3.6 m long in all (12 pairs of triangles), a corner of each pair up to
    0.6 m behind the other's face; the same cubes apart, and a ring, do not cross themselves,
    however close their neighbouring triangles; the ring with its top pushed through its bottom
    (in the second frame) does, between triangles that were 0.3 m apart and more in the first."""
    a, faces = cube_skin((0, 0, 0))
    b, _ = cube_skin((0.5, 0.4, 0.3))
    c, _ = cube_skin((1.5, 0.4, 0.3))
    two = faces + [[i + 8 for i in t] for t in faces]
    for n, squash in enumerate((0.0, 0.45)):
        ring, ring_faces = torus_skin(squash)
        write_frame(tmp_path / f"frame_00000{n}.obj", {
            "through": (a + b, two),
            "apart": ([[x + 5, y, z] for x, y, z in a + c], two),
            "ring": ([[x - 5, y, z] for x, y, z in ring], ring_faces),
        })
    first = report_on(tmp_path, "--frame", "0")
    through = first["self"]["through"]
    assert through["pairs"] == 12, first
    assert abs(through["length"] - 3.6) < 1e-9, first
    assert abs(through["deepest"] - 0.6) < 1e-9, first
    assert first["self"]["apart"]["pairs"] == 0, first
    assert first["self"]["ring"]["pairs"] == 0, first
    assert first["self_crossing_pairs"] == 12
    last = report_on(tmp_path, "--apart", "0.3", "--all-frames")
    assert last["frame"] == "frame_000001.obj"
    ring = last["self"]["ring"]
    assert 0 < ring["apart"]["pairs"] <= ring["pairs"], last
    worst = last["self_worst"]
    assert worst["ring"]["frame"] == "frame_000001.obj" and worst["ring"]["frames_crossed"] == 1, last
    assert worst["through"]["frames_crossed"] == 2, last
    nothing = {"pairs": 0, "length": 0.0, "longest": 0.0, "deepest": 0.0}
    assert worst["apart"] == {"frame": "frame_000000.obj", **nothing, "apart": nothing, "frames_crossed": 0}
    # No two of the ring's triangles were a metre apart.
    assert report_on(tmp_path, "--apart", "1")["self"]["ring"]["apart"] == nothing


def test_faces_pressed_together_at_a_slant_are_as_deep_as_they_press(tmp_path: Path) -> None:
    """Two triangles face to face, crossing along y = x: B on z = 0 facing up (x, y ≥ 0,
    x + y ≤ 1), A on z = 0.2 (x − y) facing down (x, y ≤ 0.8, x + y ≥ 0.6). They cross along
    (0.3, 0.3, 0)–(0.5, 0.5, 0). A's points over B lie at most 0.16 behind it (at (0, 0.8)); B's
    over A at most 0.16·√1.08/1.04 behind it (its point (0, 0.8·1.08/1.04), whose foot on A is
    on A's edge y = 0.8), the lesser. Corners lie further behind the other's plane (A's
    (−0.2, 0.8) 0.2 behind B's, B's (0, 1) 0.2/√1.08 behind A's) but beside the other
    triangle: not through it."""
    b = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    a = [[x, y, 0.2 * (x - y)] for x, y in ((0.8, 0.8), (0.8, -0.2), (-0.2, 0.8))]
    write_frame(tmp_path / "frame_000000.obj", {"pressed": (b + a, [[0, 1, 2], [3, 4, 5]])})
    pressed = report_on(tmp_path)["self"]["pressed"]
    assert pressed["pairs"] == 1, pressed
    assert abs(pressed["length"] - 0.2 * 2**0.5) < 1e-12, pressed
    assert abs(pressed["deepest"] - 0.16 * 1.08**0.5 / 1.04) < 1e-12, pressed


def test_the_time_spent_on_contacts_is_counted_where_bodies_may_touch() -> None:
    """Two cubes stacked on the floor spend some of their steps' time and work on contacts
    between them, and a cube alone none; changing the model starts the count again."""
    lower = jello.cube(4, 0.5, centre=(0, 0, -1.7), total_mass=1)
    upper = jello.cube(4, 0.5, centre=(0, 0, -1.15), total_mass=1)
    pair = jello.create([lower, upper])
    assert pair.contact_seconds == 0.0
    pair.run(200)
    assert pair.contact_seconds > 0.0
    work = pair.contact_work
    assert work.passes == 4 * 200 and work.sorts >= 1, work  # RK4: four passes a step
    assert work.listed > 0 and work.placed >= work.touches, work
    pair.dt = pair.dt / 2
    assert pair.contact_seconds == 0.0 and pair.contact_work.passes == 0
    alone = jello.create([jello.cube(4, 0.5, centre=(0, 0, -1.7), total_mass=1)])
    alone.run(200)
    assert alone.contact_seconds == 0.0 and alone.contact_work.passes == 0
