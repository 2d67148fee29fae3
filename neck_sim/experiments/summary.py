"""The one-table summary of a reproduction: neck-sim against the paper, from ``results.json``.

``neck-sim reproduce`` puts it at the top of ``report.md``; the README's results table is this
function's output on ``docs/results.json`` (a test holds them equal).  Print it for any run with::

    python -m neck_sim.experiments.summary reproduce/results.json
"""

from __future__ import annotations

import json
import sys

__all__ = ["summary_table"]


def _join(values, fmt: str) -> str:
    return " / ".join(format(v, fmt) for v in values)


def summary_table(results: dict) -> str:
    """A Markdown table (rows: result and paper section; columns: neck-sim, paper) of the main
    numbers of a ``results.json`` written by :func:`neck_sim.experiments.reproduce`."""
    pul, ct, ctp = results["pulleys"], results["control_tests"], results["control_tests_paper"]
    t3, t3p = results["table3"], results["table3_paper"]
    ident = results["identification"]
    paper = ident["paper"]
    elastic, variable = ident["models"]["elastic"]["parameters"], ident["models"]["variable"]["parameters"]
    laws = ("1", "2", "3")
    cases = ("rigid, with pulleys", "identified, with pulleys", "rigid, without pulleys", "identified, without pulleys")
    cables = range(1, len(paper["table1"]["f_s_elastic"]) + 1)
    diag = [f["effect"].replace("_", " ") for f in results["diagnosis"]["findings"]]
    rows = [
        ("pulleys: joint torques with vs without, mean difference (5.6)",
         f"{100 * pul['torque_rel_diff']:.1f} %", f"{100 * pul['paper']['torque_rel_diff']:.0f} %"),
        ("pulleys: eq (35) joint increments, mean change (5.6)",
         f"{100 * pul['increment_rel_diff']:.1f} %", f"{100 * pul['paper']['increment_rel_diff']:.0f} %"),
        ("tracking e, laws 1 / 2 / 3 (7, deg)",
         _join([ct[f"law {k}"]["tracking_error"] for k in laws], ".2f"), _join([ctp[k]["tracking"] for k in laws], ".2f")),
        ("estimation e_alpha vs camera, laws 1 / 2 / 3 (7, deg)",
         _join([ct[f"law {k}"]["estimation_error_camera"] for k in laws], ".2f"),
         _join([ctp[k]["estimation"] for k in laws], ".2f")),
        ("Table 3 e_alpha: pulleys + rigid / + identified; no pulleys + rigid / + identified (deg)",
         _join([t3[c]["estimation_error_true"] for c in cases], ".2f"), _join([t3p[c]["estimation"] for c in cases], ".2f")),
        ("dry friction f_s, cables 1-4, eqs (44)-(45) (Table 1, N)",
         _join([elastic[f"f_s({i})"]["value"] for i in cables], ".2f"), _join(paper["table1"]["f_s_elastic"], ".2f")),
        ("stiffness k, variable model, cables 1-4 (Table 2, N/m)",
         _join([variable[f"k({i})"]["value"] for i in cables], ".0f"), _join(paper["table2"]["k"], ".0f")),
        ("joint torque reconstruction, with / without friction (N m)",
         _join([ident["torque_error_Nm"][k] for k in ("with_friction", "without_friction")], ".3f"),
         _join([paper["torque_error"][k] for k in ("with_friction", "without_friction")], ".2f")),
        ("alpha_hat by eq (35): inextensible / model 1 / model 2 (deg)",
         _join([ident["alpha_error_deg"]["eq35"][k] for k in ("inextensible", "constant", "variable")], ".2f"),
         _join([paper["alpha_error_deg"]["eq35"][k] for k in ("inextensible", "constant", "variable")], ".2f")),
        ("diagnosis from a rigid, frictionless model: effects found in order",
         ", ".join(diag) or "none", "dry friction, cable elasticity, tension stiffening"),
    ]
    lines = ["| result (paper section) | neck-sim | paper |", "|---|---|---|"]
    lines += [f"| {a} | {b} | {c} |" for a, b, c in rows]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        print("usage: python -m neck_sim.experiments.summary RESULTS.json", file=sys.stderr)
        return 2
    try:
        with open(args[0], encoding="utf-8") as fh:
            results = json.load(fh)
        sys.stdout.write(summary_table(results))
    except (OSError, ValueError, KeyError) as e:
        print(f"{args[0]}: not a results.json of neck-sim reproduce ({type(e).__name__}: {e})", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
