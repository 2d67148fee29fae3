"""Output-error identification: re-simulate the logged forces through the MuJoCo plant and fit
f_s, k, lambda, c_a per cable (and an extended model's effect magnitudes) to the encoders and the
camera, weighted by their noise, from the paper's least-squares estimate (eqs 44-57).

Several logs share one parameter set.  The integrator is fixed once per fit; a candidate whose
re-simulation diverges is a rejected step.  Intervals come from the Jacobian at the optimum;
the cost per signal against its noise floor says whether the model explains the logs.

Example::

    from neck_sim.logs import read_log
    from identification.output_error import identify_output_error, format_output_error

    logs = [read_log(p, topics=("motors", "camera", "reference")) for p in ("a.mcap", "b.mcap")]
    result, least_squares = identify_output_error(logs, progress=True)
    print(format_output_error(result, logs[0].params))
    result.group("k"), result.group("k", "ci95")      # N/m, per cable

Modules: ``problem`` (logs, parameter vector, weighted residuals), ``rollouts`` (the parallel
re-simulation engine), ``solver`` (Levenberg-Marquardt with Broyden updates), ``fit`` (one solve
over the whole logs), ``intervals`` (Newey-West sandwich), ``misfit``,
``identify`` (start point, extended models, the entry point), ``report`` (text).
"""

__all__ = ["OutputErrorResult", "OutputErrorSettings", "fit", "identify_output_error", "load_extended_model",
           "format_output_error"]

_WHERE = {"OutputErrorResult": "fit", "fit": "fit", "identify_output_error": "identify",
          "load_extended_model": "identify", "format_output_error": "report", "OutputErrorSettings": "settings"}


def __getattr__(name: str):
    # lazy: the command line reads the settings without importing MuJoCo
    if name in _WHERE:
        import importlib

        return getattr(importlib.import_module(f"identification.output_error.{_WHERE[name]}"), name)
    raise AttributeError(f"module 'identification.output_error' has no attribute {name!r}")
