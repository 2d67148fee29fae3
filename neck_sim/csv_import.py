"""Turn the CSV files a prototype produces into a contract log (``neck-sim import``).

Files (comma-separated, one header row naming the columns, any column order, extra columns
ignored, blank lines and lines starting with ``#`` skipped, SI units, one row per sample, time
strictly increasing):

=============== ====================================================================== ==========
file            columns (N X-joints, m cables of the parameter file's routing)         topic
=============== ====================================================================== ==========
motors CSV      ``t`` (s), ``theta1`` .. ``theta{m}`` (rad, motor shaft, 0 at the      /neck/motors
                straight rest pose, > 0 winds the cable up), ``force1`` ..
                ``force{m}`` (commanded cable force, N); index i is the routing's
                cable i (m = N + 1 on the paper's routing, N + 1 the long left cable)
camera CSV      ``t`` (s), ``alpha1`` .. ``alpha{N}`` (rad, joint angles from video)    /neck/camera
reference CSV   ``t``, ``alpha_d1`` .. ``alpha_d{N}`` (rad), optional                  /neck/reference
estimate CSV    ``t``, ``alpha_hat1`` .. ``alpha_hat{N}`` (rad), optional              /neck/estimate
=============== ====================================================================== ==========

Times are seconds since the start of the run (>= 0); ``shift_time=True`` subtracts the earliest
time found in the files instead (for clocks that do not start at zero).  Column names are
matched without regard to case and surrounding spaces.  The nominal constants of the ``neck``
record come from the parameter file (defaults of a 3-joint neck without one).
"""

from __future__ import annotations

import csv
import math
import re
import os
from dataclasses import dataclass

import numpy as np

from neck_sim.logs import LogWriter
from neck_sim.logs.contract import TOPIC_BY_NAME, LogError, check_plausible
from neck_sim.params import NeckParams, default_params

__all__ = ["csv_columns", "read_csv_table", "import_csv", "ImportResult"]


def csv_columns(kind: str, n_joints: int, n_cables: int) -> list[str]:
    """Required columns of a ``motors`` (m = ``n_cables`` motors), ``camera``, ``reference`` or
    ``estimate`` (N = ``n_joints`` joints) CSV."""
    if kind == "motors":
        return (["t"] + [f"theta{j}" for j in range(1, n_cables + 1)]
                + [f"force{j}" for j in range(1, n_cables + 1)])
    prefix = {"camera": "alpha", "reference": "alpha_d", "estimate": "alpha_hat"}.get(kind)
    if prefix is None:
        raise ValueError(f"unknown CSV kind {kind!r} (motors, camera, reference, estimate)")
    return ["t"] + [f"{prefix}{i}" for i in range(1, n_joints + 1)]


def read_csv_table(path: str | os.PathLike[str], columns: list[str],
                   why: str = "") -> tuple[dict[str, np.ndarray], list[str]]:
    """Read the named columns of a CSV file as float arrays; returns (columns, ignored names).

    ``why`` (e.g. "the routing's 4 cables") is named with the needed columns when some are missing.
    Raises ValueError naming the file, line and column of the first problem: missing or duplicate
    column, wrong number of cells, a cell that is not a finite number, time not increasing.
    """
    path = os.fspath(path)
    try:
        fh = open(path, newline="", encoding="utf-8-sig")
    except OSError as exc:
        raise ValueError(f"{path}: cannot read CSV file ({exc.strerror})") from None
    with fh:
        reader = csv.reader(fh)
        try:
            rows = [(i + 1, row) for i, row in enumerate(reader)
                    if row and any(c.strip() for c in row) and not row[0].lstrip().startswith("#")]
        except UnicodeDecodeError as exc:
            raise ValueError(f"{path}: not UTF-8 text (byte {exc.object[exc.start]:#04x} near line "
                             f"{reader.line_num + 1}); save the CSV as UTF-8") from None
        except csv.Error as exc:
            raise ValueError(f"{path}:{reader.line_num}: not a readable CSV file ({exc})") from None
    if not rows:
        raise ValueError(f"{path}: empty CSV file (expected a header row: {', '.join(columns)})")
    header_line, header = rows[0]
    names = [h.strip().lower() for h in header]
    dup = sorted({h for h in names if names.count(h) > 1})
    if dup:
        raise ValueError(f"{path}:{header_line}: duplicate column(s) {', '.join(dup)}")
    missing = [c for c in columns if c.lower() not in names]
    if missing:
        raise ValueError(f"{path}: missing column(s) {', '.join(missing)} (needed{' for ' + why if why else ''}: "
                         f"{', '.join(columns)}; "
                         f"found: {', '.join(h.strip() for h in header)})")
    index = [names.index(c.lower()) for c in columns]
    ignored = [h.strip() for h, low in zip(header, names) if low not in {c.lower() for c in columns}]
    if len(rows) < 2:
        raise ValueError(f"{path}: no data rows after the header")
    data = np.empty((len(rows) - 1, len(columns)))
    for r, (line, row) in enumerate(rows[1:]):
        if len(row) != len(header):
            raise ValueError(f"{path}:{line}: expected {len(header)} cells (as in the header), got {len(row)}")
        for c, i in enumerate(index):
            cell = row[i].strip()
            try:
                v = float(cell)
            except ValueError:
                raise ValueError(f"{path}:{line}: column {columns[c]}: {cell!r} is not a number") from None
            if not math.isfinite(v):
                raise ValueError(f"{path}:{line}: column {columns[c]}: {cell!r} is not a finite number")
            data[r, c] = v
    t = data[:, 0]
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        r = int(back[0]) + 1
        raise ValueError(f"{path}:{rows[r + 1][0]}: time not increasing: t = {float(t[r])!r} s after {float(t[r - 1])!r} s")
    return {c: data[:, k] for k, c in enumerate(columns)}, ignored


def _refuse_extra_channels(path, kind: str, ignored: list[str], columns: list[str], why: str) -> None:
    """Refuse channel columns beyond the routing's (``theta5`` for 4 cables, ``alpha11`` for 10
    joints): a file for another neck, not an extra column to ignore."""
    prefixes = sorted({m.group() for c in columns[1:] if (m := re.match(r"[a-z_]+", c))}, key=len, reverse=True)
    extra = [c for c in ignored if any(re.fullmatch(rf"{p}\d+", c.lower()) for p in prefixes)]
    if extra:
        width = len(columns) - 1 if kind != "motors" else (len(columns) - 1) // 2
        found = max(int(m.group()) for c in extra if (m := re.search(r"\d+$", c)))
        raise ValueError(f"{os.fspath(path)}: column(s) {', '.join(extra)} beyond {why}: expected {width} per "
                         f"channel ({', '.join(columns[1:])}), found {found}; is "
                         f"--params the neck these data come from?")


@dataclass(frozen=True)
class ImportResult:
    """What ``import_csv`` wrote: samples per topic, time shift applied (s), ignored columns."""

    path: str
    counts: dict[str, int]
    duration: float
    time_shift: float
    ignored_columns: dict[str, list[str]]


def import_csv(motors: str | os.PathLike[str], output: str | os.PathLike[str], *,
               camera: str | os.PathLike[str] | None = None, reference: str | os.PathLike[str] | None = None,
               estimate: str | os.PathLike[str] | None = None, params: NeckParams | None = None,
               shift_time: bool = False, run_info: dict | None = None,
               accept_out_of_range_forces: bool = False) -> ImportResult:
    """Write a contract log at ``output`` from prototype CSV files (columns: module docstring).

    ``params`` are the nominal constants for the ``neck`` record (default: 3-joint defaults).  The
    data are checked against them before anything is written (sample rates, joint range, forces
    in [0, f_max]: :func:`neck_sim.logs.contract.check_plausible`); ValueError names the file.
    """
    params = default_params(3) if params is None else params
    n, m = params.n_joints, params.n_cables
    files = {"motors": motors, "camera": camera, "reference": reference, "estimate": estimate}
    tables, ignored = {}, {}
    for kind, path in files.items():
        if path is not None:
            why = (f"the routing's {m} cables" if kind == "motors" else f"the neck's {n} joints")
            tables[kind], ignored[kind] = read_csv_table(path, csv_columns(kind, n, m), why)
            _refuse_extra_channels(path, kind, ignored[kind], csv_columns(kind, n, m), why)
    t0 = min(tab["t"][0] for tab in tables.values())
    shift = float(t0) if shift_time else 0.0
    if not shift_time and t0 < 0:
        kind = min(tables, key=lambda k: tables[k]["t"][0])
        raise ValueError(f"{files[kind]}: negative time t = {float(t0)!r} s (times are s since the start of the run; "
                         "use --shift-time to start at the earliest sample)")
    t_last = max(float(tab["t"][-1]) for tab in tables.values()) - shift
    if t_last >= 9.2e9:
        raise ValueError(f"{files[max(tables, key=lambda k: tables[k]['t'][-1])]}: time t = {t_last:.6g} s is beyond "
                         "MCAP's nanosecond timestamps (t < 9.2e9 s); times are seconds since the start of the run"
                         + ("" if shift_time else " (--shift-time subtracts the earliest time)"))
    events = []
    for kind, tab in tables.items():
        cols = csv_columns(kind, n, m)[1:]
        arrays: tuple[np.ndarray, ...]
        if kind == "motors":
            arrays = (np.stack([tab[c] for c in cols[:m]], 1), np.stack([tab[c] for c in cols[m:]], 1))
        else:
            arrays = (np.stack([tab[c] for c in cols], 1),)
        t = tab["t"] - shift
        spec = TOPIC_BY_NAME[kind]
        try:
            check_plausible(spec, {"t": t, **dict(zip(spec.field_names, arrays))}, params,
                            accept_out_of_range_forces=accept_out_of_range_forces)
        except LogError as exc:
            raise LogError(f"{files[kind]}: {exc}") from None
        events += [(t[i], kind, i, arrays) for i in range(len(t))]
    events.sort(key=lambda e: (e[0], e[1]))
    info = {"source": "csv import", **{f"{k}_csv": os.path.abspath(v) for k, v in files.items() if v is not None},
            "time_shift_s": shift, **(run_info or {})}
    with LogWriter(output, params, run_info=info) as w:
        for t, kind, i, arrays in events:
            getattr(w, kind)(t, *(a[i] for a in arrays))
    end = max(tab["t"][-1] for tab in tables.values()) - shift
    return ImportResult(os.fspath(output), {k: len(v["t"]) for k, v in tables.items()}, float(end), shift, ignored)
