"""Figures of the control tests (paper Figs. 11-16) from :class:`controllers.closed_loop.RunResult`.

* :func:`joint_angles_figure`: alpha_d, alpha_hat, true alpha and camera frames per joint (Figs. 11-13);
* :func:`forces_figure`: commanded forces of one or several runs side by side (Fig. 14);
* :func:`errors_figure`: e_alpha = alpha_hat - alpha_camera (Fig. 15) or e = alpha_hat - alpha_d
  (Fig. 16), one column per run.

Figures are built with matplotlib's object API on the Agg canvas (no pyplot state, no display
needed) and written as PNG atomically by :func:`save_figure`.
"""

from __future__ import annotations

import io
import os
import re
from typing import Mapping

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from controllers.closed_loop import RunResult
from neck_sim.atomic import atomic_write_bytes

__all__ = ["SUMMARY_FILES", "joint_angles_figure", "forces_figure", "errors_figure", "save_figure", "save_run_plots"]

_CABLE_COLOURS = ("tab:blue", "gold", "tab:red", "tab:green")   # the paper's c1..c3 right, c4 left


def _cable_colour(j: int, n_cables: int) -> str:
    if j == n_cables - 1:
        return _CABLE_COLOURS[3]
    return _CABLE_COLOURS[j] if j < 3 else f"C{j + 3}"


def joint_angles_figure(result: RunResult, title: str = "") -> Figure:
    """Joint angles (deg) against time, one panel per joint (Figs. 11-13)."""
    n = result.alpha_hat.shape[1]
    fig = Figure(figsize=(9, 2.2 * n + 0.6), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(n, 1, sharex=True, squeeze=False)[:, 0]
    deg = np.degrees
    for i, ax in enumerate(axes):
        ax.plot(result.t, deg(result.alpha_d[:, i]), "k--", lw=1.2, label=r"$\alpha^d$ desired")
        ax.plot(result.t, deg(result.alpha[:, i]), color="tab:orange", lw=1.0, label=r"$\alpha$ true")
        ax.plot(result.t, deg(result.alpha_hat[:, i]), color="tab:blue", lw=1.0, label=r"$\hat\alpha$ estimated")
        if len(result.camera_t):
            ax.plot(result.camera_t, deg(result.camera_alpha[:, i]), ".", color="0.4", ms=2.5,
                    label=r"$\alpha_{IP}$ camera")
        ax.set_ylabel(f"joint {i + 1} (deg)")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8, ncol=4)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle(title or f"joint angles: {result.info.get('trajectory', '')}, law {result.info.get('law', '?')}")
    return fig


def forces_figure(results: Mapping[str, RunResult], title: str = "commanded forces") -> Figure:
    """Commanded forces (N), one column per run (Fig. 14); f_max clipping is marked."""
    fig = Figure(figsize=(4.2 * len(results) + 0.8, 3.4), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(results), sharey=True, squeeze=False)[0]
    for ax, (label, res) in zip(axes, results.items()):
        n1 = res.force.shape[1]
        for j in range(n1):
            ax.plot(res.t, res.force[:, j], lw=0.9, color=_cable_colour(j, n1), label=f"f{j + 1}")
        sat = res.saturated.any(axis=1)
        if sat.any():
            ax.plot(res.t[sat], res.force[sat].max(axis=1), "kx", ms=3, label="clipped at f_max")
        ax.set_title(label)
        ax.set_xlabel("time (s)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("force (N)")
    axes[0].legend(fontsize=8)
    fig.suptitle(title)
    return fig


def errors_figure(results: Mapping[str, RunResult], kind: str = "estimation") -> Figure:
    """Errors (deg) per joint, one column per run.

    ``kind="estimation"``: e_alpha = alpha_hat - alpha_camera at the frames (Fig. 15), with
    alpha_hat - alpha (truth) as a line; ``kind="tracking"``: e = alpha_hat - alpha_d (Fig. 16).
    """
    if kind not in ("estimation", "tracking"):
        raise ValueError(f"kind: expected 'estimation' or 'tracking', got {kind!r}")
    fig = Figure(figsize=(4.2 * len(results) + 0.8, 3.4), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(results), sharey=True, squeeze=False)[0]
    for ax, (label, res) in zip(axes, results.items()):
        n = res.alpha_hat.shape[1]
        m = res.metrics
        for i in range(n):
            colour = f"C{i}"
            if kind == "tracking":
                ax.plot(res.t, np.degrees(res.alpha_hat[:, i] - res.alpha_d[:, i]), color=colour, lw=0.9,
                        label=f"joint {i + 1}")
            else:
                if len(res.camera_t):
                    hat = np.interp(res.camera_t, res.t, res.alpha_hat[:, i])
                    ax.plot(res.camera_t, np.degrees(hat - res.camera_alpha[:, i]), ".", color=colour, ms=2.5)
                ax.plot(res.t, np.degrees(res.alpha_hat[:, i] - res.alpha[:, i]), color=colour, lw=0.9,
                        label=f"joint {i + 1}")
        mean = m.tracking_error if kind == "tracking" else m.estimation_error_camera
        ax.set_title(f"{label}: mean |e| = {mean:.2f} deg")
        ax.set_xlabel("time (s)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(r"$\hat\alpha - \alpha^d$ (deg)" if kind == "tracking"
                       else r"$\hat\alpha - \alpha_{IP}$ (dots), $\hat\alpha - \alpha$ (lines) (deg)")
    axes[0].legend(fontsize=8)
    fig.suptitle("tracking error e" if kind == "tracking" else r"estimation error $e_\alpha$")
    return fig


def save_figure(fig: Figure, path: str | os.PathLike[str]) -> str:
    """Write ``fig`` as PNG to ``path`` atomically; returns the path."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=120)
    atomic_write_bytes(path, buf.getvalue())
    return os.fspath(path)


def _slug(label: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "_", label).strip("_").lower() or "run"


#: The files :func:`save_run_plots` writes whatever the runs (besides one ``angles_<label>.png`` each).
SUMMARY_FILES = ("forces.png", "estimation_error.png", "tracking_error.png")


def save_run_plots(results: Mapping[str, RunResult], directory: str | os.PathLike[str]) -> list[str]:
    """Figures 11-16 for one or several labelled runs into ``directory``; returns the PNG paths.

    One ``angles_<label>.png`` per run, then ``forces.png``, ``estimation_error.png`` and
    ``tracking_error.png`` with one column per run.
    """
    if not results:
        raise ValueError("results: nothing to plot")
    directory = os.fspath(directory)
    paths = [save_figure(joint_angles_figure(res, f"joint angles: {label}"),
                         os.path.join(directory, f"angles_{_slug(label)}.png")) for label, res in results.items()]
    forces, estimation, tracking = (os.path.join(directory, name) for name in SUMMARY_FILES)
    paths.append(save_figure(forces_figure(results), forces))
    paths.append(save_figure(errors_figure(results, "estimation"), estimation))
    paths.append(save_figure(errors_figure(results, "tracking"), tracking))
    return paths
