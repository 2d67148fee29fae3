"""`neck-sim render`: the neck at the four configurations of the paper's Fig. 10, rendered offscreen."""

from __future__ import annotations

import argparse

from neck_sim.cli.common import add_params_arguments, check_paths, params_from_args, positive_int

HELP = ("render the neck at the four main configurations of the control test (paper Fig. 10) with MuJoCo "
        "offscreen (EGL or OSMesa) into one PNG")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("-o", "--output", default="neck_fig10.png", metavar="PNG",
                        help="output picture (default neck_fig10.png)")
    parser.add_argument("--width", type=positive_int, default=2000, metavar="W",
                        help="width of the whole picture in pixels, four panels (default 2000)")
    add_params_arguments(parser)
    parser.add_argument("--backend", choices=("auto", "egl", "osmesa", "glfw"), default="auto",
                        help="OpenGL backend (default auto: MUJOCO_GL if set, else EGL, then OSMesa)")


def run(args: argparse.Namespace) -> int:
    from neck_sim.render import render_figure10

    check_paths(inputs={"--params": args.params}, files={"-o": args.output})
    params = params_from_args(args)
    res = render_figure10(args.output, params, width=args.width, backend=args.backend)
    print(f"wrote {res.path} (MUJOCO_GL={res.backend})")
    return 0
