"""Figures, report.md and results.json of ``neck-sim design`` (matplotlib, atomic writes)."""

from __future__ import annotations

import io
import os

import numpy as np

from neck_sim.analytic.geometry import forward_kinematics
from neck_sim.atomic import atomic_write_bytes, atomic_write_json
from neck_sim.design import StrategyResult

__all__ = ["write_report", "OUTPUT_FILES"]

FIGURES = ("workspace.png", "joint_maps.png", "shapes.png", "forces.png", "stiffness.png")
OUTPUT_FILES = ("report.md", "results.json") + FIGURES


def _save(fig, path) -> None:
    import matplotlib.pyplot as plt
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())


def _grid(k):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, k, figsize=(4.2 * k, 4.4), squeeze=False, layout="constrained")
    return fig, axes[0]


def _backbone(ax, pose, params, **kw):
    kin = forward_kinematics(pose, params)
    ax.plot(kin.frame_origin[:, 0], kin.frame_origin[:, 1], **kw)


HEAD_ANGLE_LABEL = "head bar orientation, sum of alpha (deg)"
"""The head angle is the sum of the joint angles, not wrapped: past +-180 deg the neck curls over
itself (the model has no contact between bars, so such a pose may collide on a real neck)."""


def _workspace_figure(results, path):
    fig, axes = _grid(len(results))
    angles = [np.degrees(r.workspace.head[r.workspace.feasible, 2]) for r in results]
    vmax = max([float(np.max(np.abs(a))) for a in angles if a.size] or [1.0])
    sc = None
    for ax, r, ang in zip(axes, results, angles):
        ws, p = r.workspace, r.strategy.params
        f = ws.feasible
        sc = ax.scatter(ws.head[f, 0], ws.head[f, 1], c=ang, s=6, cmap="coolwarm", vmin=-vmax, vmax=vmax)
        _backbone(ax, np.zeros(p.n_joints), p, color="k", lw=1)
        ax.set_aspect("equal")
        ax.set_title(f"{r.strategy.name}: {100 * f.mean():.1f} % of samples")
        ax.set_xlabel("head x (m)")
        ax.set_ylabel("head y (m)")
    fig.colorbar(sc, ax=list(axes), shrink=0.8, label=HEAD_ANGLE_LABEL)  # one scale for every routing
    fig.suptitle("Static-feasible workspace: head positions of stable equilibria, tensions in [f_min, f_max]")
    _save(fig, path)


def _joint_map_figure(results, path):
    fig, axes = _grid(len(results))
    for ax, r in zip(axes, results):
        ws = r.workspace
        f = ws.feasible
        if f.any():
            order = np.argsort(ws.head[f, 2])
            im = ax.imshow(np.degrees(ws.alpha[f][order]), aspect="auto", cmap="coolwarm", vmin=-90, vmax=90,
                           interpolation="nearest")
            fig.colorbar(im, ax=ax, shrink=0.7, label="alpha (deg)")
        ax.set_title(r.strategy.name)
        ax.set_xlabel("joint (number)")
        ax.set_xticks(range(r.strategy.params.n_joints), [str(i + 1) for i in range(r.strategy.params.n_joints)])
        ax.set_ylabel("feasible samples, sorted by head orientation (count)")
    fig.suptitle("Joint-angle maps of the workspace")
    _save(fig, path)


def _shapes_figure(results, path):
    fig, axes = _grid(len(results))
    colors = {"C": "tab:blue", "S": "tab:green", "reach": "tab:red"}
    for ax, r in zip(axes, results):
        p = r.strategy.params
        for name, (target, sol, band) in r.shapes.items():
            c = colors.get(name, "k")
            for a in band:
                _backbone(ax, a, p, color=c, lw=0.5, alpha=0.25)
            if "alpha_target" in target:
                _backbone(ax, target["alpha_target"], p, color=c, lw=1, ls="--")
            else:
                ax.plot(*target["head_target"][:2], "x", color=c, ms=9)
            if sol is not None:
                _backbone(ax, sol.equilibrium.alpha, p, color=c, lw=2, label=name)
        ax.set_aspect("equal")
        ax.set_title(r.strategy.name)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.legend(loc="lower left", fontsize=8)
    fig.suptitle("Typical shapes: target (dashed / x), nearest reachable equilibrium (thick), friction band (thin)")
    _save(fig, path)


def _forces_figure(results, path):
    fig, axes = _grid(len(results))
    for ax, r in zip(axes, results):
        names = list(r.summary["shapes"])
        m = r.strategy.params.n_cables
        width = 0.8 / max(len(names), 1)
        for k, name in enumerate(names):
            info = r.summary["shapes"][name]
            if info.get("reachable"):
                ax.bar(np.arange(m) + k * width, info["forces"], width, label=name)
        straight = next(iter(r.summary["straight"].values()))
        ax.bar(np.arange(m) + len(names) * width, straight["forces"], width, label="straight", color="0.6")
        ax.set_xticks(np.arange(m) + 0.4, [str(j + 1) for j in range(m)])
        ax.set_xlabel("cable (number)")
        ax.set_title(r.strategy.name)
        ax.set_ylabel("holding tension (N)")
        ax.legend(fontsize=8)
    fig.suptitle("Tensions that hold the typical shapes")
    _save(fig, path)


def _stiffness_figure(results, path):
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4), layout="constrained")
    for r in results:
        k = r.workspace.lateral_stiffness[r.workspace.feasible]
        if k.size:
            ax.hist(k, bins=30, histtype="step", lw=1.5, label=r.strategy.name)
    ax.set_xlabel("head lateral stiffness with held motors (N/m)")
    ax.set_ylabel("workspace samples (count)")
    ax.set_title("Head lateral stiffness over the workspace")
    ax.legend()
    _save(fig, path)


def _fmt(x, spec=".3g"):
    return "-" if x is None else format(x, spec)


def _markdown(results, samples: int, seed: int, source: str) -> str:
    p0 = results[0].strategy.params
    lines = [f"# Routing comparison: {p0.n_joints}-X neck ({source})", "",
             f"{samples} tension samples per routing, uniform in [{p0.actuation.f_min:g}, {p0.actuation.f_max:g}] N "
             f"(seed {seed}); equilibria kept when inside |alpha| < {np.degrees(p0.geometry.alpha_max):.0f} deg "
             "and stable with the motors held (elastic cables).", "",
             "## Routings", ""]
    for r in results:
        lines.append(f"- **{r.strategy.name}** ({r.strategy.params.n_cables} cables): {r.strategy.description}")
        for j, c in enumerate(r.summary["routing"] or []):
            passes = ", ".join(c["passes"]) if c["passes"] else "-"
            lines.append(f"  - cable {j + 1}: {c['side']}, passes [{passes}], ends at joint {c['ends_at']}")
    lines += ["", "## Workspace and stiffness", "",
              "| routing | feasible | force-control stable | head area (cm^2) | head orientation, sum of alpha (deg) | "
              "workspace head stiffness median / 5 % (N/m) |", "|---|---|---|---|---|---|"]
    for r in results:
        w = r.summary["workspace"]
        ang = w["head_angle_range_deg"]
        lines.append(
            f"| {r.strategy.name} | {100 * w['feasible_fraction']:.1f} % | {100 * w['force_control_stable_fraction']:.1f} % "
            f"| {w['head_area_cm2']:.0f} | {'-' if ang is None else f'{ang[0]:.0f} .. {ang[1]:.0f}'} "
            f"| {_fmt(w['lateral_stiffness_median'])} / {_fmt(w['lateral_stiffness_p5'])} |")
    lines += ["", "Head orientation: the sum of the joint angles, not wrapped to +-180 deg; beyond +-180 deg the "
              "neck curls past a half turn (the model has no contact between bars: such poses may collide on "
              "a real neck).", "",
              "Straight pose held with the least tensions above a pretension: smallest eigenvalue of K_f "
              "(force control) and K_theta (held motors, elastic cables), N m/rad, and the head's lateral "
              "stiffness with held motors (N/m; negative: unstable).", "",
              "| routing | pretension (N) | tensions (N) | min eig K_f | min eig K_theta | uncontrolled modes | "
              "head stiffness (N/m) |", "|---|---|---|---|---|---|---|"]
    for r in results:
        for level, s in r.summary["straight"].items():
            tensions = ", ".join(f"{f:.1f}" for f in s["forces"])
            lines.append(f"| {r.strategy.name} | {level} | {tensions} | {s['min_eig_force']:.2f} "
                         f"| {s['min_eig_motor']:.2f} | {_fmt(s['min_eig_uncontrolled'], '.2f')} "
                         f"| {s['head_lateral_stiffness_motor']:.1f} |")
    lines += ["", "A negative smallest eigenvalue of K_f means the pose cannot be held by force control alone "
              "(gravity wins); K_theta adds the elastic cables of held motors. *Uncontrolled modes*: the smallest "
              "stiffness of the joint motions no cable reaches (null space of Z^T): springs, gravity and the "
              "cables' curvature (pretension) alone hold them, and no motor can damp them.", "",
              "## Holding forces and friction spread", "",
              "| routing | shape | max tension (N) | error | friction: joint spread (deg) | head spread (mm) | "
              "corners in range |", "|---|---|---|---|---|---|---|"]
    for r in results:
        for name, info in r.summary["shapes"].items():
            if not info.get("reachable"):
                lines.append(f"| {r.strategy.name} | {name} | unreachable | - | - | - | - |")
                continue
            err = (f"{info['pose_error_rms_deg']:.2f} deg rms" if "pose_error_rms_deg" in info
                   else f"{info['head_error_mm']:.1f} mm")
            lines.append(f"| {r.strategy.name} | {name} | {info['max_force']:.1f} | {err} "
                         f"| {_fmt(info.get('friction_joint_spread_deg'), '.1f')} "
                         f"| {_fmt(info.get('friction_head_spread_mm'), '.0f')} "
                         f"| {info['friction_corners_in_range']}/{info['friction_corners']} |")
    lines += ["", "Friction band: the equilibria with each motor's dry friction (f_s) adding to or subtracting from "
              "its tension, kept where they are stable with the motors held (a stopped motor is held by its "
              "friction); the other corners have no stable rest pose nearby.", "",
              "## Figures", ""]
    lines += [f"![{f[:-4]}]({f})" for f in FIGURES]
    return "\n".join(lines) + "\n"


def write_report(results: list[StrategyResult], out_dir: str | os.PathLike[str], *, samples: int, seed: int,
                 source: str) -> None:
    """DIR/report.md, DIR/results.json and the figures, each written atomically."""
    os.makedirs(out_dir, exist_ok=True)
    for fig, path in ((_workspace_figure, "workspace.png"), (_joint_map_figure, "joint_maps.png"),
                      (_shapes_figure, "shapes.png"), (_forces_figure, "forces.png"),
                      (_stiffness_figure, "stiffness.png")):
        fig(results, os.path.join(out_dir, path))
    atomic_write_json(os.path.join(out_dir, "results.json"),
                      {"source": source, "samples": samples, "seed": seed,
                       "strategies": [r.summary for r in results]})
    atomic_write_bytes(os.path.join(out_dir, "report.md"), _markdown(results, samples, seed, source).encode())
