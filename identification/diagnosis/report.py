"""The diagnosis report: a Markdown file with figures (matplotlib, Agg backend).

``write_report(diagnosis, directory)`` writes

* ``report.md`` -- verdict, findings with parameters and uncertainties, the gain of each finding
  (cross-validated residual RMS per type, alpha_hat against the camera, re-simulation), every
  candidate of every step with its evidence, the split and the method;
* ``residuals_torque.png``, ``residuals_cable.png`` -- the cross-validated residuals of the
  baseline and of the final model against time, motor speed, tension and joint angle (the
  variables an effect shows in: a friction against speed, a stiffness error against tension, a
  payload or spring error against the angle, a delay or pretension against time);
* ``candidates.png`` -- the cross-validated improvement of every candidate, per step;
* ``unexplained.png`` -- when structure is left (verdict ``unexplained``): the strongest leftover
  residual against the feature it follows and against time;
* ``alpha_hat.png``, ``resimulation.png`` -- alpha_hat and the open-loop re-simulation against
  the camera and the encoders, baseline vs final;
* ``model.json`` -- the final model (terms, plant parameters, effects; ``--model`` reads it).
"""

from __future__ import annotations

import math
import os

import numpy as np

from identification.diagnosis.materiality import undecided_lines
from identification.diagnosis.result import method_text
from identification.diagnosis.parameters import note_label
from neck_sim.effects import INSUFFICIENT_EXCITATION, UNEXPLAINED

__all__ = ["write_report", "format_summary"]


def _fmt(v, unit: str = "", digits: int = 4) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return f"{v:.{digits}g}" + (f" {unit}" if unit else "")


def _param_text(params: dict) -> str:
    parts = []
    for name, p in params.items():
        unit = "" if p.unit in ("-", "") else f" {p.unit}"
        parts.append(f"{name} = {_fmt(p.value)}" + (f" ± {_fmt(p.sigma, digits=2)}" if p.sigma is not None else "")
                     + unit + note_label(p.note))
    return "; ".join(parts)


def _where(f) -> str:
    if f.joints:
        return "joints " + ", ".join(map(str, f.joints))
    if f.cables:
        return "cables " + ", ".join(map(str, f.cables))
    return ""


#: Residual types in reports: attribute of ResidualRMS, label, scale to the unit shown, unit.
_RESIDUALS = (("torque_Nm", "joint torque", 1.0, "N m"), ("tension_N", "cable tension", 1.0, "N"),
              ("elongation_m", "cable elongation", 1e3, "mm"))


def look_alike_lines(diag) -> list[str]:
    """Per step whose verdict lists look-alikes (``selection.decide``): alternatives, and what would separate them."""
    return [f"step {i + 1}: {' or '.join(st.verdict)}: fitted together{getattr(st, 'look_alike_where', '')} neither "
            f"adds to the other, so this log supports one of them and cannot tell which; {st.verdict[0]} has the larger "
            f"cross-validated improvement{getattr(getattr(st, 'separation', None), 'separating_text', str)()}"
            for i, st in enumerate(diag.steps) if st.chosen is not None and isinstance(st.verdict, list)]


def format_summary(diag) -> str:
    """A few lines for the terminal: verdict, findings and their gains."""
    model = diag.baseline.description if diag.baseline is not None else diag.model.describe()
    lines = [f"diagnosis of {diag.source or 'data'} from the model: {model}",
             f"verdict: {diag.verdict}" + (f" ({'borderline' if diag.borderline else 'margins'}: {margin_text(diag)})"
                                            if margin_text(diag) else "")] + [f"  {x}" for x in look_alike_lines(diag)]
    if diag.gaps:
        lines.append("  what this log cannot separate" + (" (no verdict):" if diag.insufficient else
                                                       " (a gain it cannot attribute):"
                                                       if diag.verdict == INSUFFICIENT_EXCITATION else ":"))
        lines += [f"      {g.describe()}" for g in diag.gaps]
    for f in diag.findings:
        ev = f.evidence
        where = f" on {_where(f)}" if _where(f) else ""
        lines.append(f"  step {f.step}: {f.effect}{where}: held-out (cross-validated) score "
                     f"-{100 * ev.improvement:.1f} % (p = {ev.p_holdout:.2g}, F-test p = {ev.p_train:.2g}; margin "
                     f"{ev.margin:+.2f} bands" + (", borderline)" if ev.borderline else ")"))
        lines.append(f"      {_param_text(f.parameters)}")
        before, after = f.gain.before.residual_rms_crossvalidated, f.gain.after.residual_rms_crossvalidated
        for key, label, scale, unit in _RESIDUALS:
            b, a = getattr(before, key), getattr(after, key)
            if b is None and a is None:
                continue
            bs = "-" if b is None else ", ".join(f"{scale * x:.3g}" for x in b)
            as_ = "-" if a is None else ", ".join(f"{scale * x:.3g}" for x in a)
            lines.append(f"      {label} RMS ({unit}): [{bs}] -> [{as_}]")
    if diag.baseline is None:          # nothing was fitted: the gaps above say why
        return "\n".join(lines + [f"  note: {n}" for n in diag.notes])
    b, a = diag.baseline.alpha_hat_vs_camera, diag.final.alpha_hat_vs_camera
    if b and a:
        lines.append(f"  alpha_hat vs camera, held out, mean |error|: {b.holdout.mean_abs_deg:.2f} deg"   # one model: no arrow
                     + (" (the baseline; no model was extended)" if a is b else f" -> {a.holdout.mean_abs_deg:.2f} deg"))
    b, a = diag.baseline.resimulation, diag.final.resimulation
    if b and a:
        lines.append(resimulation_line(b, a))
    if diag.leftover is not None and diag.leftover.significant:
        lines.append("  unexplained structure left (strongest first):")
        lines += [f"      {x.describe()}" for x in diag.leftover.found[:3]]
    lines += undecided_lines(diag) + [f"  note: {n}" for n in diag.notes]
    lines.append("  time: " + ", ".join(f"{k} {v:.1f} s" for k, v in diag.timings.items()))
    return "\n".join(lines)


def resimulation_line(before, after) -> str:
    """The summary's line on the held-out re-simulation of the baseline ``before`` and the final model ``after``
    (:class:`~identification.diagnosis.resimulation.Resimulation`): their errors; no comparison when every block of
    both diverged (the errors cover only each block's run-up) or when no finding made ``after`` ``before`` itself."""
    if before.diverged_everywhere and after.diverged_everywhere:
        who = "the baseline (no model was extended) out of its" if after is before else "both models out of their"
        return (f"  re-simulation, held out: no comparison: open loop, the logged forces drive {who} valid range in "
                f"every block ({before.n_diverged} of {before.n_blocks}); the verdict rests on the fitted residuals alone")
    status = before.status if before.status == after.status else f"{before.status} / {after.status}"
    (b, bd), (a, ad) = ((_vec(x.holdout.theta_rms_rad), _fmt(x.holdout.alpha_mean_abs_deg, digits=3)) for x in (before, after))
    if after is before:                    # no model was extended: nothing to compare the baseline with
        return (f"  re-simulation, held out, of the baseline alone (no model was extended, no comparison): theta RMS "
                f"{b} rad; alpha mean |error| {bd} deg ({status})")
    return f"  re-simulation, held out: theta RMS {b} -> {a} rad; alpha mean |error| {bd} -> {ad} deg ({status})"


def margin_text(diag) -> str:
    """The verdict's decisions nearest their thresholds, in borderline bands (see
    :meth:`~identification.diagnosis.Diagnosis.margins`)."""
    out = []
    for key, m in diag.margins().items():
        v = m.get("margin_in_bands")
        if v is None or not np.isfinite(v):
            continue
        what = m.get("candidate") or f"{m.get('channel')} vs {m.get('feature')}"
        out.append(f"{key.replace('_', ' ')}: {what} {v:+.2f} bands")
    return "; ".join(out)


def _vec(v) -> str:
    return "-" if v is None else "[" + ", ".join(f"{x:.3g}" for x in v) + "]"


# ----------------------------------------------------------------------------------------- figures

def _shade(ax, split, t):
    for a, b, fold in split.blocks:
        if fold == 1:
            ax.axvspan(a, b, color="0.92", zorder=0)


def _residual_figure(diag, path: str, kind: str) -> str:
    import matplotlib.pyplot as plt

    data = diag.data
    n, C = data.n, data.C
    base, final = diag.baseline.cv_residuals, diag.final.cv_residuals
    extended = len(diag.summaries) > 1
    t_hat = diag.steps[0].base.fit.tension_hat if diag.steps[0].base.fit.model.elastic else \
        diag.steps[-1].base.fit.tension_hat
    if kind == "torque":
        chans = list(range(n))
        scale, unit, title = 1.0, "N m", "joint torque residual (eq 51)"
        # the cable that drives joint i most (the paper's routing: right cable i)
        lever = np.abs(data.Z).mean(axis=0)                     # (N, C) m
        cable_of = lambda i: int(np.argmax(lever[i]))
        joint_of = lambda i: i
        name_of = lambda i: f"joint {i + 1}"
    else:
        chans = list(range(n, n + C))
        scale, unit, title = 1e3, "mm", "elongation residual (eq 42/54)"
        cable_of = lambda i: i - n
        joint_of = lambda i: min(i - n, n - 1)
        name_of = lambda i: f"cable {i - n + 1}"
    fig, axes = plt.subplots(len(chans), 4, figsize=(15, 2.3 * len(chans) + 0.8), squeeze=False)
    xs = [("time (s)", lambda i: data.t), ("motor speed (rad/s)", lambda i: data.theta_dot[:, cable_of(i)]),
          ("tension (N)", lambda i: t_hat[:, cable_of(i)]), ("joint angle (deg)", lambda i: np.degrees(data.alpha[:, joint_of(i)]))]
    for r, ch in enumerate(chans):
        for c, (xlabel, xf) in enumerate(xs):
            ax = axes[r, c]
            x = xf(ch)
            if c == 0:
                _shade(ax, diag.split, data.t)
                ax.plot(x, scale * base[:, ch], color="0.5", lw=0.7, label=f"baseline: {diag.baseline.description}")
                if extended:
                    ax.plot(x, scale * final[:, ch], color="C3", lw=0.7, label=f"final: {diag.final.description}")
            else:
                ax.plot(x, scale * base[:, ch], ".", color="0.6", ms=1.5)
                if extended:
                    ax.plot(x, scale * final[:, ch], ".", color="C3", ms=1.5)
            ax.axhline(0, color="k", lw=0.5)
            if r == len(chans) - 1:
                ax.set_xlabel(xlabel)
            if c == 0:
                ax.set_ylabel(f"{name_of(ch)} ({unit})")
    handles, names = axes[0, 0].get_legend_handles_labels()
    fig.suptitle(f"{title}, cross-validated (grey bands: primary held-out blocks)")
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    fig.legend(handles, names, loc="lower center", ncol=2, fontsize=8, frameon=False)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _candidates_figure(diag, path: str) -> str:
    import matplotlib.pyplot as plt

    steps = diag.steps
    fig, axes = plt.subplots(1, len(steps), figsize=(4.5 * len(steps), 3.2), squeeze=False)
    for i, st in enumerate(steps):
        ax = axes[0, i]
        cands = sorted(st.candidates, key=lambda c: c.improvement)
        vals = [100 * max(c.improvement, -20) if math.isfinite(c.improvement) else 0 for c in cands]
        colors = ["C2" if c.significant else ("C1" if not c.valid else "0.6") for c in cands]
        ax.barh([c.term.name for c in cands], vals, color=colors)
        ax.axvline(100 * diag.settings.min_improvement, color="k", ls="--", lw=0.8)
        ax.set_title(f"step {i + 1}: {st.verdict}", fontsize=9)
        ax.set_xlabel("held-out improvement (%)")
        ax.set_ylabel("candidate effect")
        ax.tick_params(labelsize=7)
    fig.suptitle("candidates (green: significant; orange: unphysical sign; dashed: minimum improvement)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _compared(diag, attr: str) -> list:
    """[(label, colour, result)] of the baseline and the final model where they have ``attr``."""
    out = [("baseline: " + diag.baseline.description, "0.5", getattr(diag.baseline, attr))]
    if len(diag.summaries) > 1:
        out.append(("final: " + diag.final.description, "C3", getattr(diag.final, attr)))
    return [(label, colour, r) for label, colour, r in out if r is not None]


def _alpha_figure(diag, path: str) -> str | None:
    import matplotlib.pyplot as plt

    curves = _compared(diag, "alpha_hat_vs_camera")
    if not curves:
        return None
    n = diag.data.n
    fig, axes = plt.subplots(n, 1, figsize=(12, 2.2 * n + 0.6), sharex=True, squeeze=False)
    for j in range(n):
        ax = axes[j, 0]
        _shade(ax, diag.split, None)
        for label, colour, r in curves:
            ax.plot(r.t, r.error_deg[:, j], color=colour, lw=0.7, label=label)
        ax.set_ylabel(f"joint {j + 1} (deg)")
        ax.axhline(0, color="k", lw=0.5)
    axes[0, 0].legend(fontsize=7)
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle("alpha_hat (eq 35 with the model's elongation) minus camera angle")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _resim_scale(data, key: str, curves) -> tuple[float, list[bool]]:
    """Half-height of a re-simulation panel and which curves leave it.

    The scale holds the last model compared (the final one) whole, but never more than
    the measured signal's own range (motor angles in rad, camera angles in deg): an error larger
    than the signal it is the error of says only that the model diverged, which the legend says.
    """
    measured = data.prep.fast.theta if key == "theta_error" else np.degrees(data.alpha)
    measured = np.abs(np.asarray(measured, dtype=float))
    span = float(np.nanmax(measured)) if np.isfinite(measured).any() else np.inf
    ref = np.abs(getattr(curves[-1][2], key))
    ref = ref[np.isfinite(ref)]
    lim = 1.1 * float(ref.max()) if ref.size else span
    lim = max(min(lim, span), 1e-9)
    off = [bool(np.nanmax(np.abs(getattr(r, key)), initial=0.0) > lim) for _, _, r in curves]
    return lim, off


def _resim_figure(diag, path: str) -> str | None:
    import matplotlib.pyplot as plt

    curves = _compared(diag, "resimulation")
    if not curves:
        return None
    data = diag.data
    fig, axes = plt.subplots(2, 1, figsize=(12, 6), sharex=True)
    scales = {key: _resim_scale(data, key, curves) for key in ("theta_error", "alpha_error_deg")}
    units = {"theta_error": "rad", "alpha_error_deg": "deg"}
    for ax, key in zip(axes, ("theta_error", "alpha_error_deg")):
        lim, off = scales[key]
        for (label, colour, r), out in zip(curves, off):
            err = getattr(r, key)
            t = r.t if key == "theta_error" else r.t_camera
            if out:  # diverged: dotted, behind, its size in the legend
                label = f"{label} -- diverged, off scale (max |error| {np.nanmax(np.abs(err)):.3g} {units[key]})"
            for j in range(err.shape[1]):
                ax.plot(t, err[:, j], color=colour, lw=0.6, ls=":" if out else "-", zorder=1 if out else 2,
                        alpha=0.5 if out else 0.4 + 0.15 * j, label=label if j == 0 else None)
        _shade(ax, diag.split, None)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_ylim(-lim, lim)
        ax.legend(fontsize=7, loc="upper left")
    axes[0].set_ylabel("motor angle error (rad)")
    axes[1].set_ylabel("alpha - camera (deg)")
    axes[1].set_xlabel("time (s)")
    fig.suptitle("open-loop re-simulation driven by the logged forces (scale: the final model's error)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


# ----------------------------------------------------------------------------------------- markdown

def _rms_rows(before, after) -> list[str]:
    """Table rows of two ResidualRMS, channel by channel."""
    rows = []
    for key, label, scale, unit in _RESIDUALS:
        b, a = getattr(before, key), getattr(after, key)
        if b is None and a is None:
            continue
        for i in range(len(b if b is not None else a)):
            who = f"joint {i + 1}" if key == "torque_Nm" else f"cable {i + 1}"
            bv = "-" if b is None else f"{scale * b[i]:.4g}"
            av = "-" if a is None else f"{scale * a[i]:.4g}"
            ratio = "" if (b is None or a is None or b[i] == 0) else f"{a[i] / b[i]:.2f}"
            rows.append(f"| {label} ({unit}) | {who} | {bv} | {av} | {ratio} |")
    return rows


def _alpha_row(label: str, where: str, b, a) -> str:
    """A table row of two AngleErrors (mean |error|)."""
    return (f"| {label} | {where} | {b.mean_abs_deg:.3f} | {a.mean_abs_deg:.3f} | "
            f"{a.mean_abs_deg / b.mean_abs_deg:.2f} |")


def _unexplained_figure(diag, path: str) -> str | None:
    import matplotlib.pyplot as plt

    lo = diag.leftover
    if lo is None or lo.plot is None:
        return None
    top, t, res, feat = lo.plot
    ok = np.isfinite(res)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4))
    a1.plot(feat[ok], res[ok], ".", ms=2, alpha=0.5)
    order = np.argsort(feat[ok])
    bins = np.array_split(order, 20)
    a1.plot([feat[ok][b].mean() for b in bins if b.size], [res[ok][b].mean() for b in bins if b.size], "r-", lw=2,
            label="binned mean")
    from identification.diagnosis.structure import feature_unit
    a1.set_xlabel(f"{top.feature} ({feature_unit(top.feature)})")
    a1.set_ylabel(f"{top.channel} residual ({top.unit})")
    a1.legend(fontsize=7)
    a2.plot(t, res, lw=0.7)
    a2.set_xlabel("time (s)")
    a2.set_ylabel(f"{top.channel} residual ({top.unit})")
    fig.suptitle(f"unexplained: {top.describe()}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _unexplained_lines(diag) -> list[str]:
    lo = diag.leftover
    if lo is None:
        return []
    if not lo.significant:
        return ["No structure beyond noise is left in the final model's cross-validated residuals "
                f"({lo.n_tests} tests against state features and whiteness, |z| < {lo.z_threshold:.1f}).", ""]
    L = ["## Unexplained: structure left in the residuals", "",
         "The final model leaves structure beyond noise that no effect of the vocabulary removes"
         + (" (the findings above are therefore no clean explanation)" if diag.findings else "") + ":", "",
         "| channel | follows | rho | z (threshold " + f"{lo.z_threshold:.1f}) | structure / rest | residual RMS |",
         "|---|---|---|---|---|---|"]
    for x in lo.found[:10]:
        L.append(f"| {x.channel} | {x.feature} | {x.rho:+.2f} | {x.z:.1f} | {x.size:.2f} | {_fmt(x.rms, x.unit, 3)} |")
    return L + [""]


def _markdown(diag, figures: dict) -> str:
    L = [f"# Diagnosis of `{os.path.basename(diag.source) or 'data'}`", "",
         f"Baseline model: **{diag.baseline.description}**.", "",
         f"## Verdict: `{diag.verdict}`", ""]
    L += [("**Borderline**: " if diag.borderline else "Margins to the decision thresholds: ")
          + (margin_text(diag) or "-") + " (in borderline bands of "
          f"{diag.settings.borderline:g} relative / {diag.settings.borderline_decades:g} decades of p; within 1 band "
          "is borderline).", ""]
    L += [f"* {line}\n" for line in look_alike_lines(diag)]
    if diag.gaps:
        L += ["### What this log cannot separate" + (" (no verdict)" if diag.insufficient else ""), ""]
        L += [f"* {g.describe()}" for g in diag.gaps] + [""]
    if diag.findings:
        L += ["| step | effect | where | parameters | held-out improvement | p (Wilcoxon, held out) | p (F, train) | "
              "margin (bands) |", "|---|---|---|---|---|---|---|---|"]
        for f in diag.findings:
            ev = f.evidence
            L.append(f"| {f.step} | {f.effect} | {_where(f) or 'all'} | {_param_text(f.parameters)} | "
                     f"{100 * ev.improvement:.1f} % | {ev.p_holdout:.2g} | {ev.p_train:.2g} | {ev.margin:+.2f} |")
        L.append("")
    else:
        L += ["No candidate effect improves the held-out prediction significantly: the model explains the data "
              "to within its noise.", ""]
    if diag.notes:
        L += ["## Notes", ""] + [f"* {n}" for n in diag.notes] + [""]
    L += _unexplained_lines(diag)
    for f in diag.findings:
        L += [f"### Gain of step {f.step} ({f.effect}), cross-validated residual RMS", "",
              "| residual | channel | before | after | after/before |", "|---|---|---|---|---|"]
        g = f.gain
        L += _rms_rows(g.before.residual_rms_crossvalidated, g.after.residual_rms_crossvalidated)
        if g.before.alpha_hat_vs_camera and g.after.alpha_hat_vs_camera:
            L.append(_alpha_row("alpha_hat - camera, held out (deg, mean abs)", "all",
                                g.before.alpha_hat_vs_camera.holdout, g.after.alpha_hat_vs_camera.holdout))
        L.append("")
    b, a = diag.baseline, diag.final
    L += ["## Baseline vs final model (held-out data)", "", f"Final model: **{a.description}**.", "",
          "| residual | channel | baseline | final | final/baseline |", "|---|---|---|---|---|"]
    L += _rms_rows(b.residual_rms_crossvalidated, a.residual_rms_crossvalidated)
    if b.alpha_hat_vs_camera and a.alpha_hat_vs_camera:
        L.append(_alpha_row("alpha_hat - camera (deg, mean abs)", "held out", b.alpha_hat_vs_camera.holdout,
                            a.alpha_hat_vs_camera.holdout))
    if b.resimulation and a.resimulation:
        bb, aa = b.resimulation.holdout, a.resimulation.holdout
        for j in range(len(bb.theta_rms_rad or aa.theta_rms_rad or [])):
            bv = bb.theta_rms_rad[j] if bb.theta_rms_rad else None
            av = aa.theta_rms_rad[j] if aa.theta_rms_rad else None
            L.append(f"| re-simulation theta (rad RMS) | motor {j + 1} | {_fmt(bv)} | {_fmt(av)} | "
                     f"{_fmt(av / bv, digits=2) if bv and av else ''} |")
        L.append(f"| re-simulation alpha - camera (deg, mean abs) | held out | {_fmt(bb.alpha_mean_abs_deg)} | "
                 f"{_fmt(aa.alpha_mean_abs_deg)} | |")
        L += ["", f"Re-simulation status: baseline {b.resimulation.status}; final {a.resimulation.status}."]
    L.append("")
    for key, title in (("torque", "Joint-torque residuals"), ("cable", "Cable residuals"),
                       ("candidates", "Candidates"), (UNEXPLAINED, "Unexplained structure"),
                       ("alpha", "alpha_hat against the camera"), ("resim", "Re-simulation")):
        if figures.get(key):
            L += [f"### {title}", "", f"![{title}]({os.path.basename(figures[key])})", ""]
    L += ["## Candidates per step", ""]
    for i, st in enumerate(diag.steps):
        L += [f"### Step {i + 1}: from {st.base.fit.model.describe()} -> `{st.verdict}`", "",
              "| candidate | shape | held-out improvement | torque ratio | cable ratio | p (held out) | p (F) | "
              "added params | sign | significant |", "|---|---|---|---|---|---|---|---|---|---|"]
        for c in sorted(st.candidates, key=lambda c: -c.improvement):
            shape = ", ".join(f"{k}={_fmt(v)}" for k, v in c.term.shape)
            br = c.block_ratio or {}
            L.append(f"| {c.term.name} | {shape} | {100 * (c.improvement or 0):.1f} % | "
                     f"{_fmt(br.get('torque'), digits=3)} | {_fmt(br.get('cable'), digits=3)} | "
                     f"{_fmt(c.p_holdout, digits=2)} | {_fmt(c.p_train, digits=2)} | "
                     f"{c.added_params} | {'ok' if c.valid else 'wrong'} | "
                     f"{'**yes**' if c.significant else 'no'} |")
        for t in st.pairwise:
            if t.error:
                continue
            L.append(f"\nEncompassing test {t.a} vs {t.b}{'' if t.cable is None else f' (on cable {t.cable})'}: "
                     f"{t.b} adds to {t.a}: {t.b_adds_to_a.improvement * 100:.1f} % (p {t.b_adds_to_a.p_holdout:.2g}), "
                     f"{t.a} adds to {t.b}: {t.a_adds_to_b.improvement * 100:.1f} % "
                     f"(p {t.a_adds_to_b.p_holdout:.2g}).")
        L.append("")
    sp = diag.split
    L += ["## Method", "", f"Split: {sp.method}; {sp.n_chunks} chunks for the paired test.", ""]
    L += [f"- **{k}**: {v}" for k, v in method_text(diag.settings).items()]
    L += ["", "Time (s): " + ", ".join(f"{k} {v:.2f}" for k, v in diag.timings.items()), ""]
    return "\n".join(L)


# the files write_report puts into its directory (the CLI checks them against the other outputs)
REPORT_FILES = ("report.md", "model.json", "residuals_torque.png", "residuals_cable.png", "candidates.png",
                f"{UNEXPLAINED}.png", "alpha_hat.png", "resimulation.png")


def write_report(diag, directory) -> list[str]:
    """Write ``report.md``, the figures and ``model.json`` into ``directory``; returns the paths."""
    import matplotlib

    matplotlib.use("Agg")
    from neck_sim.atomic import atomic_write_bytes

    directory = os.fspath(directory)
    os.makedirs(directory, exist_ok=True)
    if diag.baseline is None:          # nothing fitted (too short or too still): the verdict and its reasons
        md = os.path.join(directory, "report.md")
        text = [f"# Diagnosis of `{os.path.basename(diag.source) or 'data'}`", "", f"## Verdict: `{diag.verdict}`", "",
                "### What this log cannot separate (no verdict)", ""] + [f"* {g.describe()}" for g in diag.gaps]
        atomic_write_bytes(md, ("\n".join(text + [""] + [f"Note: {n}" for n in diag.notes]) + "\n").encode())
        return [md]
    figs = {"torque": _residual_figure(diag, os.path.join(directory, "residuals_torque.png"), "torque"),
            "cable": _residual_figure(diag, os.path.join(directory, "residuals_cable.png"), "cable"),
            "candidates": _candidates_figure(diag, os.path.join(directory, "candidates.png")),
            UNEXPLAINED: _unexplained_figure(diag, os.path.join(directory, f"{UNEXPLAINED}.png")),
            "alpha": _alpha_figure(diag, os.path.join(directory, "alpha_hat.png")),
            "resim": _resim_figure(diag, os.path.join(directory, "resimulation.png"))}
    md = os.path.join(directory, "report.md")
    atomic_write_bytes(md, _markdown(diag, figs).encode())
    model = os.path.join(directory, "model.json")
    diag.write_model(model)
    return [md, model] + [p for p in figs.values() if p]
