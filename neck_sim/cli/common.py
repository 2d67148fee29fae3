"""Arguments shared by several commands: the neck's parameters, checked option values, and the
input/output path checks every command runs before it does any work."""

from __future__ import annotations

import argparse
import math
import os
from typing import TYPE_CHECKING, Sequence

from neck_sim import params as P

if TYPE_CHECKING:
    from neck_sim.logs import Log


def add_params_arguments(parser: argparse.ArgumentParser, default_n_joints: int = 3) -> None:
    """``--params PATH`` and ``--n-joints N``: which neck a command works on (without either, the
    paper's neck with ``default_n_joints`` X-joints, which the command sets when it is not 3)."""
    neck = "the paper's neck" if default_n_joints == 3 else f"the paper's design with {default_n_joints} X-joints"
    parser.add_argument("--params", metavar="PATH",
                        help=f"parameter file (.json/.toml, see `neck-sim params -o`); default: {neck}")
    parser.add_argument("--n-joints", type=int, default=None,
                        help=f"number of X-joints N (default {default_n_joints}, or the parameter file's)")
    add_implausible_params_argument(parser)


def add_implausible_params_argument(parser: argparse.ArgumentParser) -> None:
    """``--accept-implausible-params``: load a parameter file whose values look like a unit mistake."""
    parser.add_argument("--accept-implausible-params", action="store_true",
                        help="accept parameter values that look like a unit mistake (lengths over 5 m, masses "
                             "over 10 kg, gravity over 25 m/s^2; refused by default); a warning names them")


def load_params_file(path: str | os.PathLike[str], option: str = "--params",
                     accept_implausible: bool = False) -> P.NeckParams:
    """``params.load(path)`` with every error naming the option and the file; implausible values
    accepted on request are printed as warnings."""
    try:
        params = P.load(path, accept_implausible=accept_implausible)
    except (ValueError, OSError) as exc:
        text = str(exc)
        raise ValueError(text if os.fspath(path) in text else f"{option} {os.fspath(path)}: {text}") from None
    for text in P.implausible_values(params):
        print(f"warning: {option} {os.fspath(path)}: {text} (accepted: --accept-implausible-params)")
    return params


def params_from_args(args: argparse.Namespace) -> P.NeckParams:
    """The parameters chosen by :func:`add_params_arguments`' options."""
    if args.n_joints is not None and args.n_joints < 1:
        raise ValueError(f"--n-joints: must be >= 1, got {args.n_joints}")
    if args.params:
        params = load_params_file(args.params, accept_implausible=args.accept_implausible_params)
        if args.n_joints is not None and args.n_joints != params.n_joints:
            raise ValueError(f"--n-joints {args.n_joints} contradicts {args.params} (n_joints = {params.n_joints})")
        return params
    return P.default_params(3 if args.n_joints is None else args.n_joints)


def check_params_fit_log(params: P.NeckParams, log: Log, path: str | os.PathLike[str]) -> None:
    """Refuse ``--params`` whose neck is not the log's: joints, cables and routing (one line
    naming the field, the file's and the log's value)."""
    log_p = log.params
    for field, mine, theirs in (("n_joints", params.n_joints, log_p.n_joints),
                                ("n_cables", params.n_cables, log_p.n_cables)):
        if mine != theirs:
            raise ValueError(f"--params {path}: {field} = {mine}, the log's neck record has {theirs}")
    mine_cases = params.routing.segment_cases(params.n_joints)
    if mine_cases.tolist() != log_p.routing.segment_cases(log_p.n_joints).tolist():
        raise ValueError(f"--params {path}: routing.cables routes the cables differently from the log's neck record "
                         f"(its 'routing' key); use the parameter file the log was recorded with")


# -- option values: argparse names the option in its error ------------------------------------

def _number(kind, text: str, test, wanted: str):
    import argparse
    try:
        value = kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {wanted}, got {text!r}") from None
    if not test(value):
        raise argparse.ArgumentTypeError(f"must be {wanted}, got {text}")
    return value


def nonnegative_int(text: str) -> int:
    """argparse type: an integer >= 0 (seeds, counts)."""
    return _number(int, text, lambda v: v >= 0, "an integer >= 0")


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    return _number(int, text, lambda v: v >= 1, "an integer >= 1")


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    return _number(float, text, lambda v: math.isfinite(v) and v > 0, "a finite number > 0")


def nonnegative_float(text: str) -> float:
    """argparse type: a finite number >= 0 (times in s, tolerances)."""
    return _number(float, text, lambda v: math.isfinite(v) and v >= 0, "a finite number >= 0")


def probability(text: str) -> float:
    """argparse type: a number strictly between 0 and 1 (significance levels)."""
    return _number(float, text, lambda v: 0 < v < 1, "a number between 0 and 1 (exclusive)")


# -- standard output ----------------------------------------------------------------------------

def closed_stdout_error(command: str) -> str | None:
    """The one-line error for a run whose standard output is closed (``>&-``: Python then sets
    ``sys.stdout`` to None and every print vanishes, so results would be lost with status 0);
    None when it is open."""
    import sys
    if sys.stdout is not None:
        return None
    return (f"{command}: error: standard output is closed (started with >&-?); results would be lost: "
            "redirect it to a file or /dev/null instead")


# -- input and output paths, checked before any work ------------------------------------------

def _same_file(a: str, b: str) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:                     # one does not exist: compare the resolved names
        return os.path.realpath(a) == os.path.realpath(b)


def _nearest_existing(path: str) -> str:
    path = os.path.abspath(path)
    while not os.path.exists(path):
        parent = os.path.dirname(path)
        if parent == path:
            break
        path = parent
    return path


def _input_refusal(opt: str, path: str) -> None:
    """Refuse an input that is a FIFO, socket or device (opening a FIFO blocks until a writer comes)."""
    from neck_sim.atomic import path_kind
    kind = path_kind(path)
    if kind is not None and kind != "a directory":
        raise ValueError(f"{opt} {path}: is {kind}, not a regular file; give a file (copy the data into one)")


def check_paths(inputs: dict | None = None, files: dict | None = None, dirs: dict | None = None,
                contents: dict | None = None) -> None:
    """Refuse, before any work, input and output paths that would block, destroy an input or
    cannot be written.

    ``inputs``, ``files`` (output files) and ``dirs`` (output directories, created when missing)
    map the option that names a path (``"--json"``, ``"LOG"``) to the path; None values are
    skipped.  ``contents`` maps an option of ``dirs`` to the names of the files the command
    writes inside that directory (``report.md``): those are output files too.

    An input must not be a FIFO, socket or device node.  An output file must not be an input (same
    file after resolving links, or the same name), another output (a file written inside an output
    directory included), or anything :func:`neck_sim.atomic.output_refusal` refuses (a directory,
    a device node, FIFO or socket or a symlink to one, a read-only file, a name over NAME_MAX), and
    its directory must exist and be writable.  An output directory may hold inputs.
    Raises ValueError naming the option and the user's path.
    """
    from neck_sim.atomic import output_refusal
    inputs = {k: os.fspath(v) for k, v in (inputs or {}).items() if v is not None}
    files = {k: os.fspath(v) for k, v in (files or {}).items() if v is not None}
    dirs = {k: os.fspath(v) for k, v in (dirs or {}).items() if v is not None}
    for opt, path in inputs.items():
        _input_refusal(opt, path)
    # (option, path, inside a directory the command creates)
    outputs = [(opt, path, False) for opt, path in files.items()]
    outputs += [(opt, os.path.join(dirs[opt], name), True) for opt, names in (contents or {}).items()
                if opt in dirs for name in names]
    seen: list[tuple[str, str]] = []
    for opt, path, inside in outputs:
        for in_opt, in_path in inputs.items():
            if _same_file(path, in_path):
                raise ValueError(f"{opt} {path}: is the input {in_opt} {in_path}; refusing to write over an "
                                 "input (choose another output path)")
        for other, other_path in seen:
            if _same_file(path, other_path):
                raise ValueError(f"{opt} {path}: is also the output of {other} {other_path}; give each output "
                                 "its own path")
        seen.append((opt, path))
        reason = output_refusal(path)
        if reason is not None:
            raise ValueError(f"{opt} {path}: {reason.removeprefix('it ')}")
        if inside:
            continue
        parent = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(parent):
            what = "is not a directory" if os.path.exists(parent) else "does not exist"
            raise ValueError(f"{opt} {path}: the folder {parent} {what}")
        if not os.access(parent, os.W_OK | os.X_OK):
            raise ValueError(f"{opt} {path}: the folder {parent} is not writable")
    for opt, path in dirs.items():
        for in_opt, in_path in inputs.items():
            if _same_file(path, in_path):
                raise ValueError(f"{opt} {path}: is the input {in_opt}; refusing to write over an input")
        base = _nearest_existing(path)
        if not os.path.isdir(base):
            raise ValueError(f"{opt} {path}: {base} is a file, not a directory")
        if not os.access(base, os.W_OK | os.X_OK):
            raise ValueError(f"{opt} {path}: the folder {base} is not writable")


# -- measured data outside the record's ranges --------------------------------------------------

def add_force_range_argument(parser: argparse.ArgumentParser) -> None:
    """``--accept-out-of-range-forces``: analyse a log whose commanded forces leave [0, f_max]."""
    parser.add_argument("--accept-out-of-range-forces", action="store_true",
                        help="accept logged forces outside [0, f_max] (refused by default); the output says so")


def report_input_warnings(log_warnings: Sequence[str]) -> dict:
    """Print what was accepted on request (``Log.warnings``); returns the entry for a JSON output
    (``{"input_warnings": [...]}``, empty without warnings)."""
    for text in log_warnings:
        print(f"warning: {text}")
    return {"input_warnings": list(log_warnings)} if log_warnings else {}
