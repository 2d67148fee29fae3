"""`neck-sim render`: the neck at the four configurations of the paper's Fig. 10, rendered offscreen."""

from __future__ import annotations

HELP = ("render the neck at the four main configurations of the control test (paper Fig. 10) with MuJoCo "
        "offscreen (EGL or OSMesa) into one PNG")


def add_arguments(parser) -> None:
    parser.add_argument("-o", "--output", default="neck_fig10.png", metavar="PNG",
                        help="output picture (default neck_fig10.png)")
    parser.add_argument("--width", type=int, default=2000, metavar="W",
                        help="width of the whole picture in pixels, four panels (default 2000)")
    parser.add_argument("--n-joints", type=int, default=3, help="number of X-joints N (default 3)")
    parser.add_argument("--params", metavar="PATH", help="parameter file (.json/.toml); default: the paper's neck")
    parser.add_argument("--backend", choices=("auto", "egl", "osmesa", "glfw"), default="auto",
                        help="OpenGL backend (default auto: MUJOCO_GL if set, else EGL, then OSMesa)")


def run(args) -> int:
    from neck_sim import params as P
    from neck_sim.render import render_figure10

    if args.params:
        params = P.load(args.params)
        if args.n_joints != 3 and args.n_joints != params.n_joints:
            raise ValueError(f"--n-joints {args.n_joints} contradicts {args.params} (n_joints = {params.n_joints})")
    else:
        if args.n_joints < 1:
            raise ValueError(f"--n-joints: must be >= 1, got {args.n_joints}")
        params = P.default_params(args.n_joints)
    res = render_figure10(args.output, params, width=args.width, backend=args.backend)
    print(f"wrote {res.path} (MUJOCO_GL={res.backend})")
    return 0
