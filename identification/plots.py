"""Figures 4-9 of the paper from an identification result (matplotlib, Agg backend, PNG).

Colours follow the paper: figure 4 Gamma_m blue, Gamma_rf green, Gamma_r red; figure 8 inextensible
green, model 1 blue, model 2 red, camera black.  Files are written atomically.
"""

from __future__ import annotations

import io
import os
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from matplotlib.figure import Figure  # noqa: E402

from neck_sim.atomic import atomic_write_bytes  # noqa: E402

if TYPE_CHECKING:
    from identification.paper import IdentificationResult

__all__ = ["FIGURE_FILES", "save_figure", "figure_torques", "figure_tensions", "figure_tension_error", "figure_alpha",
           "figure_simulator", "save_identification_figures"]


def save_figure(fig: Figure, path: str | os.PathLike[str]) -> str:
    """Write ``fig`` as PNG to ``path`` atomically and close it; returns the path."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())
    return os.fspath(path)


def figure_torques(result: IdentificationResult) -> Figure:
    """Figure 4: Gamma_m = Z f, Gamma_rf (with friction) and Gamma_r (without), per joint."""
    s = result.series
    t = s["t"]
    n = s["gamma_m"].shape[1]
    fig, axes = plt.subplots(n, 1, figsize=(10, 2.2 * n), sharex=True)
    for j, ax in enumerate(np.atleast_1d(axes)):
        # the measured torque is a wide pale band under the models' thin dashed lines: where the
        # friction model is right its line runs inside the band, and both stay visible
        ax.plot(t, s["gamma_m"][:, j], color="tab:blue", lw=3.0, alpha=0.45, zorder=1,
                label=r"$\Gamma_m = Zf$ (measured)")
        ax.plot(t, s["gamma_rf"][:, j], color="tab:green", lw=1.0, ls="--", zorder=3,
                label=r"$\Gamma_{rf}$ (model, friction)")
        ax.plot(t, s["gamma_r"][:, j], color="tab:red", lw=1.0, ls=":", zorder=2,
                label=r"$\Gamma_r$ (model, no friction)")
        ax.set_ylabel(f"joint {j + 1} (N m)")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", ncol=3, fontsize=8)
    axes[-1].set_xlabel("time (s)")
    te = result.torque_error
    fig.suptitle(f"Fig. 4: torque reconstruction, mean error {te['with_friction']:.3f} N m with friction, "
                 f"{te['without_friction']:.3f} N m without")
    return fig


def _masked(x, mask):
    return np.where(mask, x, np.nan)


def figure_tensions(result: IdentificationResult, model: str = "constant") -> Figure:
    """Figures 5 (constant stiffness) and 7 (variable): tension from forces vs from the cable model."""
    s = result.series
    t, taut = s["t"], s["taut"]
    n1 = s["tension_rhs"].shape[1]
    fig, axes = plt.subplots(n1, 1, figsize=(10, 2.0 * n1), sharex=True)
    for i, ax in enumerate(np.atleast_1d(axes)):
        ax.plot(t, _masked(s["tension_rhs"][:, i], taut[:, i]), color="tab:blue", lw=1.0, label="from forces (eq 41)")
        ax.plot(t, _masked(s[f"tension_{model}"][:, i], taut[:, i]), color="tab:orange", lw=1.0,
                label=f"from elongation ({'eq 40' if model == 'constant' else 'eq 54'})")
        ax.set_ylabel(f"cable {i + 1} (N)")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", ncol=2, fontsize=8)
    axes[-1].set_xlabel("time (s)")
    num = 5 if model == "constant" else 7
    fig.suptitle(f"Fig. {num}: cable tension, {model} stiffness, mean error "
                 f"{result.tension_error[model]:.2f} N (taut samples)")
    return fig


def figure_tension_error(result: IdentificationResult) -> Figure:
    """Figure 6: |tension from forces - from the cable model| against the tension from forces."""
    s = result.series
    taut = s["taut"]
    n1 = s["tension_rhs"].shape[1]
    fig, axes = plt.subplots(1, n1, figsize=(3.2 * n1, 3.2), sharey=True)
    for i, ax in enumerate(np.atleast_1d(axes)):
        m = taut[:, i]
        x = s["tension_rhs"][m, i]
        for model, colour in (("constant", "tab:blue"), ("variable", "tab:red")):
            if f"tension_{model}" in s:
                ax.scatter(x, np.abs(x - s[f"tension_{model}"][m, i]), s=3, color=colour, alpha=0.5,
                           label=f"{model} stiffness")
        ax.set_xlabel(f"tension c{i + 1} from forces (N)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("reconstruction error (N)")
    axes[0].legend(fontsize=8)
    fig.suptitle("Fig. 6: tension reconstruction error against tension")
    return fig


def figure_alpha(result: IdentificationResult) -> Figure:
    """Figure 8: alpha_hat by eq (33) (left) and eq (35) (right) for the three cable models vs camera."""
    s = result.series
    colours = {"inextensible": "tab:green", "constant": "tab:blue", "variable": "tab:red"}
    n = s["camera_alpha"].shape[1]
    fig, axes = plt.subplots(n, 2, figsize=(13, 2.4 * n), sharex=True)
    for col, eq in enumerate(("eq33", "eq35")):
        for j in range(n):
            ax = axes[j, col]
            ax.plot(s["camera_t"], np.degrees(s["camera_alpha"][:, j]), color="k", lw=0.8, label="camera")
            for name, colour in colours.items():
                key = f"alpha_{eq}_{name}"
                if key in s:
                    err = result.alpha_error_deg[eq][name]
                    ax.plot(s["t_fast"], np.degrees(s[key][:, j]), color=colour, lw=0.9,
                            label=f"{name} ({err:.2f} deg)")
            ax.set_ylabel(f"alpha_{j + 1} (deg)")
            ax.grid(alpha=0.3)
        axes[0, col].set_title(f"eq ({eq[2:]})")
        axes[0, col].legend(fontsize=7, ncol=2)
        axes[-1, col].set_xlabel("time (s)")
    fig.suptitle("Fig. 8: alpha_hat reconstruction against the camera")
    return fig


def figure_simulator(runs: dict, measured_key: str = "measured") -> Figure:
    """Figure 9: applied forces of the measured run and of simulators, ``runs`` name -> (t, force)."""
    n1 = next(iter(runs.values()))[1].shape[1]
    fig, axes = plt.subplots(n1, 1, figsize=(10, 2.0 * n1), sharex=True)
    styles = {measured_key: dict(color="0.15", lw=2.6, alpha=0.45)}     # wide and pale: simulators on top stay visible
    palette = iter(["tab:red", "tab:green", "tab:blue", "tab:orange"])
    for name, (t, f) in runs.items():
        st = styles.get(name) or dict(color=next(palette), lw=0.9)
        for i, ax in enumerate(np.atleast_1d(axes)):
            ax.plot(t, f[:, i], label=name, **st)
    for i, ax in enumerate(np.atleast_1d(axes)):
        ax.set_ylabel(f"f{i + 1} (N)")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, ncol=len(runs))
    axes[-1].set_xlabel("time (s)")
    fig.suptitle("Fig. 9: applied forces, measured run and simulators")
    return fig


#: The files :func:`save_identification_figures` and ``neck-sim identify --plots`` may write (figures 4-9).
FIGURE_FILES = ("fig4_torques.png", "fig5_tension_constant.png", "fig6_tension_error.png",
                "fig7_tension_variable.png", "fig8_alpha.png", "fig9_simulators.png")


def save_identification_figures(result: IdentificationResult, directory: str | os.PathLike[str]) -> list[str]:
    """Figures 4-8 as PNG files in ``directory`` (created); returns the paths written."""
    os.makedirs(directory, exist_ok=True)
    paths = [save_figure(figure_torques(result), os.path.join(directory, FIGURE_FILES[0]))]
    if "tension_constant" in result.series:
        paths.append(save_figure(figure_tensions(result, "constant"), os.path.join(directory, FIGURE_FILES[1])))
        paths.append(save_figure(figure_tension_error(result), os.path.join(directory, FIGURE_FILES[2])))
    if "tension_variable" in result.series:
        paths.append(save_figure(figure_tensions(result, "variable"), os.path.join(directory, FIGURE_FILES[3])))
    if "camera_alpha" in result.series:
        paths.append(save_figure(figure_alpha(result), os.path.join(directory, FIGURE_FILES[4])))
    return paths
