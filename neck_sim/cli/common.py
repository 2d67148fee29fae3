"""Arguments shared by several commands: the neck's parameters, checked option values, and the
input/output path checks every command runs before it does any work."""

from __future__ import annotations

import math
import os

from neck_sim import params as P


def add_params_arguments(parser, default_n_joints: int = 3) -> None:
    """``--params PATH`` and ``--n-joints N``: which neck a command works on (without either, the
    paper's neck with ``default_n_joints`` X-joints, which the command sets when it is not 3)."""
    neck = "the paper's neck" if default_n_joints == 3 else f"the paper's design with {default_n_joints} X-joints"
    parser.add_argument("--params", metavar="PATH",
                        help=f"parameter file (.json/.toml, see `neck-sim params -o`); default: {neck}")
    parser.add_argument("--n-joints", type=int, default=None,
                        help=f"number of X-joints N (default {default_n_joints}, or the parameter file's)")


def load_params_file(path, option: str = "--params") -> P.NeckParams:
    """``params.load(path)`` with every error naming the option and the file."""
    try:
        return P.load(path)
    except (ValueError, OSError) as exc:
        text = str(exc)
        raise ValueError(text if os.fspath(path) in text else f"{option} {os.fspath(path)}: {text}") from None


def params_from_args(args) -> P.NeckParams:
    """The parameters chosen by :func:`add_params_arguments`' options."""
    if args.n_joints is not None and args.n_joints < 1:
        raise ValueError(f"--n-joints: must be >= 1, got {args.n_joints}")
    if args.params:
        params = load_params_file(args.params)
        if args.n_joints is not None and args.n_joints != params.n_joints:
            raise ValueError(f"--n-joints {args.n_joints} contradicts {args.params} (n_joints = {params.n_joints})")
        return params
    return P.default_params(3 if args.n_joints is None else args.n_joints)


def check_params_fit_log(params: P.NeckParams, log, path) -> None:
    """Refuse ``--params`` whose neck is not the log's: joints, cables and routing (one line
    naming the field, the file's and the log's value)."""
    log_p = log.params
    for field, mine, theirs in (("n_joints", params.n_joints, log_p.n_joints),
                                ("n_cables", params.n_cables, log_p.n_cables)):
        if mine != theirs:
            raise ValueError(f"--params {path}: {field} = {mine}, the log's neck record has {theirs}")
    if params.routing.segment_cases(params.n_joints).tolist() != log_p.routing.segment_cases(log_p.n_joints).tolist():
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


def check_paths(inputs: dict | None = None, files: dict | None = None, dirs: dict | None = None) -> None:
    """Refuse, before any work, output paths that would destroy an input or cannot be written.

    ``inputs``, ``files`` (output files) and ``dirs`` (output directories, created when missing)
    map the option that names a path (``"--json"``, ``"LOG"``) to the path; None values are
    skipped.  An output file must not be an input (same file after resolving links, or the same
    name), another output, or a directory, and its directory must exist and be writable.
    Raises ValueError naming the option and the user's path.
    """
    inputs = {k: os.fspath(v) for k, v in (inputs or {}).items() if v is not None}
    files = {k: os.fspath(v) for k, v in (files or {}).items() if v is not None}
    dirs = {k: os.fspath(v) for k, v in (dirs or {}).items() if v is not None}
    seen: dict[str, str] = {}
    for opt, path in files.items():
        for in_opt, in_path in inputs.items():
            if _same_file(path, in_path):
                raise ValueError(f"{opt} {path}: is the input {in_opt} {in_path}; refusing to write over an "
                                 "input (choose another output path)")
        for other, other_path in seen.items():
            if _same_file(path, other_path):
                raise ValueError(f"{opt} {path}: is also the output of {other}; give each output its own path")
        seen[opt] = path
        if os.path.isdir(path):
            raise ValueError(f"{opt} {path}: is a directory; give a file name")
        parent = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(parent):
            what = "is not a directory" if os.path.exists(parent) else "does not exist"
            raise ValueError(f"{opt} {path}: the folder {parent} {what}")
        if not os.access(parent, os.W_OK | os.X_OK):
            raise ValueError(f"{opt} {path}: the folder {parent} is not writable")
        if os.path.exists(path) and not os.access(path, os.W_OK):
            raise ValueError(f"{opt} {path}: the file is read-only")
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

def add_force_range_argument(parser) -> None:
    """``--accept-out-of-range-forces``: analyse a log whose commanded forces leave [0, f_max]."""
    parser.add_argument("--accept-out-of-range-forces", action="store_true",
                        help="accept logged forces outside [0, f_max] (refused by default); the output says so")


def report_input_warnings(log_warnings) -> dict:
    """Print what was accepted on request (``Log.warnings``); returns the entry for a JSON output
    (``{"input_warnings": [...]}``, empty without warnings)."""
    for text in log_warnings:
        print(f"warning: {text}")
    return {"input_warnings": list(log_warnings)} if log_warnings else {}
