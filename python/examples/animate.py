"""Renders a run as an animation: a GIF, or an MP4 when imageio's ffmpeg plugin is installed.

    python python/examples/animate.py examples/stack.toml --time 2 --out stack.gif

Each frame draws every body's points, a colour per body. Needs matplotlib and
imageio (`pip install "./python[examples]"`; MP4 also `pip install imageio-ffmpeg`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

import jello


def frames(sim: jello.Simulation, seconds: float, fps: int) -> list[npt.NDArray[np.float64]]:
    """Positions at ``fps`` frames per simulated second for ``seconds``, the first at the start."""
    per_frame = max(1, round(1.0 / (fps * sim.dt)))
    count = max(1, round(seconds * fps))
    out = [sim.positions]
    for _ in range(count):
        sim.step(per_frame)
        out.append(sim.positions)
    return out


def render(
    positions: list[npt.NDArray[np.float64]], bodies: list[tuple[str, slice]], title: str
) -> list[npt.NDArray[np.uint8]]:
    """Each frame drawn with matplotlib (off screen) as an RGB image."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    everything = np.concatenate(positions)
    lo, hi = everything.min(axis=0), everything.max(axis=0)
    centre, half = (lo + hi) / 2, float((hi - lo).max()) / 2 + 0.1
    fig = plt.figure(figsize=(5, 5), dpi=80)
    ax: Any = fig.add_subplot(projection="3d")
    images = []
    for i, p in enumerate(positions):
        ax.cla()
        for b, (name, points) in enumerate(bodies):
            q = p[points]
            ax.scatter(q[:, 0], q[:, 1], q[:, 2], color=f"C{b % 10}", s=6, label=name)
        for axis, set_lim in enumerate((ax.set_xlim, ax.set_ylim, ax.set_zlim)):
            set_lim(centre[axis] - half, centre[axis] + half)
        ax.set_title(f"{title}   frame {i}")
        fig.canvas.draw()
        rgba = np.asarray(fig.canvas.buffer_rgba())  # type: ignore[attr-defined]
        images.append(np.ascontiguousarray(rgba[:, :, :3]))
    plt.close(fig)
    return images


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("world", nargs="?", default="examples/stack.toml", help="a .w world or .toml scene")
    parser.add_argument("--time", type=float, default=2.0, help="simulated seconds (default 2)")
    parser.add_argument("--fps", type=int, default=25, help="frames per simulated second (default 25)")
    parser.add_argument("--out", type=Path, default=Path("jello.gif"), help="a .gif or .mp4 (default jello.gif)")
    args = parser.parse_args(argv)
    if args.out.suffix.lower() not in (".gif", ".mp4"):
        print(f"animate: {args.out}: expected a .gif or .mp4 file name", file=sys.stderr)
        return 2
    try:
        import imageio.v3 as iio
        import matplotlib  # noqa: F401
    except ImportError:
        print('animate: needs matplotlib and imageio: pip install "./python[examples]"', file=sys.stderr)
        return 1

    sim = jello.load(args.world)
    try:
        positions = frames(sim, args.time, args.fps)
    except jello.BlowUp as e:
        print(f"animate: {e}", file=sys.stderr)
        return 3
    images = render(positions, sim.bodies, Path(args.world).name)
    if args.out.suffix.lower() == ".gif":
        iio.imwrite(args.out, np.stack(images), duration=1000 / args.fps, loop=0)
    else:
        try:
            iio.imwrite(args.out, np.stack(images), fps=args.fps, codec="libx264")
        except Exception as e:  # imageio names the missing plugin
            print(f"animate: {args.out}: cannot write MP4 ({e}); pip install imageio-ffmpeg", file=sys.stderr)
            return 1
    print(f"wrote {args.out}: {len(images)} frames")
    return 0


if __name__ == "__main__":
    sys.exit(main())
