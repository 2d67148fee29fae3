"""Every figure the commands write has a title and axis labels with units.

The commands that write figures run in-process on short inputs (`identify --plots --simulators`,
`diagnose --report`, `simulate --plots`, `design`, `render`) while a hook on matplotlib's
``Figure.savefig`` inspects each figure as it is saved: a title (the figure's or an axes'), and on
every drawn axes an x and a y label ending in a unit in parentheses, ``"time (s)"`` (a label may
be said once for the axes sharing that axis, or for a grid's column (x) or row (y); colour bars
need their own label).  Axes drawn
without axis lines (pictures) need no labels.  The report of `neck-sim reproduce` lists its figures
in the paper's order with a caption each.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from matplotlib.category import UnitData
from matplotlib.figure import Figure

from neck_sim.cli import main
from neck_sim.params import default_params

UNIT = re.compile(r"\([^()]+\)\s*\$?$")


def _has_unit(label: str) -> bool:
    return bool(UNIT.search(label.strip()))


def figure_problems(fig: Figure) -> list[str]:
    """What a reader misses in ``fig``: no title, an axis without a label, a label without a unit."""
    problems = []
    titles = [fig._suptitle.get_text() if fig._suptitle is not None else ""]
    titles += [ax.get_title(loc) for ax in fig.axes for loc in ("center", "left", "right")]
    if not any(t.strip() for t in titles):
        problems.append("no title")
    for k, ax in enumerate(fig.axes):
        if not ax.axison:
            continue
        where = f"axes {k} ({ax.get_title() or 'untitled'})"
        if getattr(ax, "_colorbar", None) is not None:
            label = ax.get_ylabel() or ax.get_xlabel()
            if not _has_unit(label):
                problems.append(f"{where}: colour bar label {label!r} has no unit")
            continue
        for axis, get, shared in (("x", _xlabel, ax.get_shared_x_axes()),
                                  ("y", _ylabel, ax.get_shared_y_axes())):
            label = get(ax)
            if not label:  # said once for the axes sharing this axis, or for the grid's column / row
                peers = list(shared.get_siblings(ax)) + _grid_peers(fig, ax, "col" if axis == "x" else "row")
                label = next((get(o) for o in peers if get(o)), "")
            categorical = isinstance((ax.xaxis if axis == "x" else ax.yaxis).get_units(), UnitData)
            if not label:
                problems.append(f"{where}: no {axis} label")
            elif not _has_unit(label) and not categorical:  # names along an axis have no unit
                problems.append(f"{where}: {axis} label {label!r} has no unit in parentheses")
    return problems


def _grid_peers(fig: Figure, ax, along: str) -> list:
    """Axes of ``fig`` in the same subplot-grid column (``"col"``) or row (``"row"``) as ``ax``."""
    spec = ax.get_subplotspec()
    if spec is None:
        return []
    span = spec.colspan if along == "col" else spec.rowspan
    out = []
    for other in fig.axes:
        o = other.get_subplotspec()
        if other is not ax and o is not None and o.get_gridspec() is spec.get_gridspec():
            if (o.colspan if along == "col" else o.rowspan) == span:
                out.append(other)
    return out


def _xlabel(ax) -> str:
    return ax.get_xlabel().strip()


def _ylabel(ax) -> str:
    return ax.get_ylabel().strip()


@pytest.fixture
def saved_figures(monkeypatch):
    """[(title, problems)] of every matplotlib figure saved while the test runs."""
    seen = []
    original = Figure.savefig

    def savefig(self, *args, **kwargs):
        title = self._suptitle.get_text() if self._suptitle is not None else (
            next((ax.get_title() for ax in self.axes if ax.get_title()), "?"))
        seen.append((title, figure_problems(self)))
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", savefig)
    return seen


@pytest.fixture(scope="module")
def short_log(tmp_path_factory):
    """A 17 s identification-style log of the paper's neck under law 1 (one of tests/test_identify.py's
    sequences): `identify` and `diagnose` draw on it the same figures, with the same axes, as on
    two sequences (33 s), in 29 instead of 40 CPU s."""
    from controllers.closed_loop import run_closed_loop
    from controllers.computed_torque import ComputedTorqueController
    from identification.excitation import sequences_trajectory
    from neck_sim.plant import Plant

    p = default_params(3)
    traj = sequences_trajectory(np.radians([[42.0, 26.0, 32.0]]), move_time=2.5, hold_time=0.3)
    path = tmp_path_factory.mktemp("figs") / "identification.mcap"
    run_closed_loop(Plant(p, seed=0), ComputedTorqueController(p, law=1), traj, log_path=path, progress=False)
    return path


def _check(seen, out_dir, expected_png: int):
    pngs = sorted(out_dir.rglob("*.png"))
    assert len(pngs) == expected_png and len(seen) >= expected_png, (pngs, [t for t, _ in seen])
    bad = [f"{title}: {p}" for title, problems in seen for p in problems]
    assert not bad, "\n".join(bad)


def test_identify_figures(short_log, tmp_path, saved_figures):
    out = tmp_path / "plots"
    assert main(["identify", str(short_log), "--plots", str(out), "--simulators"]) == 0
    _check(saved_figures, out, 6)          # figures 4-9


def test_diagnose_report_figures(short_log, tmp_path, saved_figures):
    out = tmp_path / "report"
    assert main(["diagnose", str(short_log), "--model", "rigid", "--steps", "1", "--report", str(out),
                 "--json", str(tmp_path / "d.json"), "--quiet"]) == 0
    _check(saved_figures, out, len(list(out.glob("*.png"))))
    assert (out / "resimulation.png").exists()


def test_simulate_figures(tmp_path, saved_figures):
    out = tmp_path / "figs"
    assert main(["simulate", "--law", "1", "2", "--duration-scale", "0.2", "--plots", str(out), "--no-log",
                 "--no-progress"]) == 0
    _check(saved_figures, out, 5)          # two angle figures, forces, both errors


def test_design_figures(tmp_path, saved_figures):
    out = tmp_path / "design"
    assert main(["design", "--n-joints", "3", "--samples", "20", "-o", str(out)]) == 0   # four routings side by side
    _check(saved_figures, out, 5)


def test_render_figure_has_a_title(tmp_path, saved_figures):
    """The offscreen render runs in a worker process; its figure is composed by compose_figure,
    run here on blank pictures of the same layout."""
    from neck_sim.render import Framing, cable_colours, compose_figure

    sides = default_params(10).routing.sides
    legend = [(f"cable {j + 1} ({s})", c) for j, (s, c) in enumerate(zip(sides, cable_colours(sides)))]
    images = [np.ones((200, 150, 3)) for _ in range(4)]
    compose_figure(images, ["straight", "a", "b", "c"], tmp_path / "fig10.png",
                   view=Framing(np.zeros(2), 0.4, 0.3), suptitle="10-X neck", legend=legend)
    _check(saved_figures, tmp_path, 1)


def test_the_checker_finds_missing_titles_labels_and_units():
    fig = Figure()
    ax = fig.add_subplot()
    ax.plot([0, 1], [0, 1])
    assert set(figure_problems(fig)) == {"no title", "axes 0 (untitled): no x label", "axes 0 (untitled): no y label"}
    ax.set_xlabel("time (s)")
    ax.set_ylabel("head angle")
    ax.set_title("t")
    assert figure_problems(fig) == ["axes 0 (t): y label 'head angle' has no unit in parentheses"]
    ax.set_ylabel("head angle (deg)")
    assert figure_problems(fig) == []
    sc = ax.scatter([0], [0], c=[1.0])
    fig.colorbar(sc, ax=ax)
    assert figure_problems(fig) == ["axes 1 (untitled): colour bar label '' has no unit"]


def test_cable_colours_are_all_different():
    from neck_sim.render import cable_colours

    for sides in (default_params(3).routing.sides, default_params(10).routing.sides,
                  default_params(31).routing.sides, ("left",) * 3 + ("right",), ("right", "left") * 16):
        colours = cable_colours(sides)
        assert len(colours) == len(sides) == len(set(colours)), sides
        assert min(np.abs(np.subtract(a, b)).max() for i, a in enumerate(colours) for b in colours[i + 1:]) > 0.05
    paper = cable_colours(default_params(3).routing.sides)
    assert paper[3][1] > paper[3][0] and paper[3][1] > paper[3][2]    # the long left cable is green, as in the paper


def test_reproduce_report_orders_and_captions_figures_as_the_paper():
    from neck_sim.experiments.reproduce import FIGURE_CAPTIONS, ordered_figures

    names = sorted(FIGURE_CAPTIONS) + ["extra.png"]
    order = ordered_figures({n: n for n in names})
    assert order[-1] == "extra.png"
    numbers = [FIGURE_CAPTIONS[n][0] for n in order[:-1]]
    assert numbers == list(range(4, 17))
    assert all(caption.strip() for _, caption in FIGURE_CAPTIONS.values())


def test_resimulation_scale_follows_the_final_model_and_marks_a_diverged_baseline():
    from types import SimpleNamespace

    from identification.diagnosis.report import _resim_scale

    t = np.linspace(0, 10, 101)
    data = SimpleNamespace(prep=SimpleNamespace(fast=SimpleNamespace(theta=np.outer(np.sin(t), [20.0, 10.0]))),
                           alpha=np.radians(np.outer(np.sin(t), [30.0])))
    diverged = SimpleNamespace(theta_error=np.outer(t, [15.0, 1.0]), alpha_error_deg=np.outer(t, [40.0]))
    final = SimpleNamespace(theta_error=np.outer(np.cos(t), [0.5, 0.2]), alpha_error_deg=np.outer(np.cos(t), [2.0]))
    curves = [("baseline", "0.5", diverged), ("final", "C3", final)]
    lim, off = _resim_scale(data, "theta_error", curves)
    assert lim == pytest.approx(1.1 * 0.5) and off == [True, False]
    lim, off = _resim_scale(data, "alpha_error_deg", curves)
    assert lim == pytest.approx(1.1 * 2.0) and off == [True, False]
    # a final model whose error exceeds the measured signal's own range is capped there, and marked
    wild = SimpleNamespace(theta_error=np.outer(t, [9.0, 9.0]), alpha_error_deg=np.outer(t, [9.0]))
    lim, off = _resim_scale(data, "theta_error", [("final", "C3", wild)])
    assert lim == pytest.approx(20.0, rel=1e-3) and off == [True]
