"""The `tsrl` command line: `tsrl demo` renders the reach scene to PNG files."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import mujoco
import numpy as np

from .assets import SCENES, load_model
from .assets.ur5e import HOME_Q, JOINT_LIMITS
from .exceptions import TsrlError
from .kinematics import forward_kinematics


def demo(out_dir: Path, scene: str = "reach", n_random: int = 3, seed: int = 0) -> list[Path]:
    """Renders `scene` at the home pose and at `n_random` seeded random poses; returns the PNG paths."""
    from PIL import Image

    from .rendering import SceneRenderer

    model = load_model(scene)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(seed)
    # Random poses near home (+-0.6 rad per joint) so that the arm stays in view above the table.
    poses = [("home", HOME_Q)] + [
        (f"random_{i}", np.clip(HOME_Q + rng.uniform(-0.6, 0.6, 6), *JOINT_LIMITS.T)) for i in range(n_random)
    ]
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    with SceneRenderer(model) as renderer:
        for name, q in poses:
            forward_kinematics(model, data, q)
            path = out_dir / f"{scene}_{name}.png"
            Image.fromarray(renderer.render(data)).save(path)
            paths.append(path)
    return paths


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="tsrl", description=__doc__)
    commands = parser.add_subparsers(dest="command", required=True)
    p_demo = commands.add_parser("demo", help="render a scene at home and a few poses to PNG files")
    p_demo.add_argument("--out-dir", type=Path, default=Path("results/demo"), help="folder for the PNG files")
    p_demo.add_argument("--scene", default="reach", help=f"built-in scene: {', '.join(SCENES)}")
    p_demo.add_argument("--poses", type=int, default=3, help="number of random poses besides home")
    p_demo.add_argument("--seed", type=int, default=0, help="seed of the random poses")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    try:
        if args.command == "demo":
            if args.poses < 0:
                parser.error(f"--poses must be >= 0; got {args.poses}")
            for path in demo(args.out_dir, args.scene, args.poses, args.seed):
                print(f"wrote {path}")
    except TsrlError as err:
        print(f"tsrl: error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
