"""Helpers shared by the log tests: synthetic logs, hand-made (possibly malformed) MCAP files and
a short simulated run of the analytic elastic model (no MuJoCo plant needed)."""

from __future__ import annotations

import json

import numpy as np
from mcap.writer import CompressionType, Writer

from neck_sim.analytic import cable_lengths, elastic_derivative, simulate_elastic
from neck_sim.logs import LogWriter, neck_metadata


def synthetic_arrays(params, seconds: float = 2.0, seed: int = 0) -> dict:
    """Full-precision random signals (with tiny, negative and integer-valued numbers) per topic."""
    n, m = params.n_joints, params.n_cables
    rate = params.control.rate_hz
    steps = int(round(seconds * rate))
    rng = np.random.default_rng(seed)
    t = np.arange(steps) / rate

    def sig(width, scale=1.0):
        x = rng.normal(size=(steps, width)) * scale
        x[::7, 0] *= 1e-9                  # exponent notation in JSON
        x[::11, -1] = np.round(x[::11, -1])  # integer-valued floats
        return x

    cam_idx = np.arange(0, steps, int(round(rate / params.sensors.camera_rate_hz)))
    # measured topics stay plausible (neck_sim.logs.contract.check_plausible): forces in [0, f_max],
    # joint angles within the joint range
    angle = params.geometry.alpha_max
    return {
        "motors": {"t": t, "theta": sig(m, 10.0),
                   "force": np.minimum(np.abs(sig(m, 30.0)), params.actuation.f_max)},
        "camera": {"t": t[cam_idx], "alpha": np.clip(sig(n, 0.4), -angle, angle)[cam_idx]},
        "reference": {"t": t, "alpha_d": np.clip(sig(n, 0.4), -angle, angle)},
        "estimate": {"t": t, "alpha_hat": sig(n, 0.4)},
        "truth": {"t": t, "alpha": sig(n, 0.4), "alpha_dot": sig(n), "tension": sig(m, 20.0),
                  "elongation": sig(m, 1e-3)},
    }


def write_arrays(path, params, arrays: dict, **writer_kw) -> None:
    """Write per-topic arrays with LogWriter, interleaved in time order as a run would."""
    events = []
    for topic, fields in arrays.items():
        names = [k for k in fields if k != "t"]
        for i, t in enumerate(fields["t"]):
            events.append((t, topic, [fields[k][i] for k in names]))
    events.sort(key=lambda e: e[0])
    with LogWriter(path, params, **writer_kw) as w:
        for t, topic, values in events:
            getattr(w, topic)(t, *values)


def write_raw(path, params, topics: dict, *, neck: dict | None = None, chunk_size: int = 1 << 20,
              compression=CompressionType.ZSTD) -> None:
    """An MCAP written directly with the mcap library: ``topics`` maps a topic to a list of
    (log_time ns, payload bytes or dict); ``neck`` overrides the metadata record."""
    with open(path, "wb") as fh:
        w = Writer(fh, chunk_size=chunk_size, compression=compression)
        w.start()
        w.add_metadata("neck", neck_metadata(params) if neck is None else neck)
        sid = w.register_schema("x", "jsonschema", b"{}")
        for topic, msgs in topics.items():
            ch = w.register_channel(topic, "json", sid)
            for ns, payload in msgs:
                data = payload if isinstance(payload, bytes) else json.dumps(payload).encode()
                w.add_message(ch, ns, data, ns)
        w.finish()


def motors_messages(n_cables: int, times, theta=None, force=None, extra=None) -> list:
    out = []
    for i, t in enumerate(times):
        msg = {"t": float(t), "theta": [0.1 * i] * n_cables if theta is None else theta[i],
               "force": [1.0] * n_cables if force is None else force[i]}
        if extra:
            msg.update(extra)
        out.append((int(round(t * 1e9)), msg))
    return out


def simulated_run(params, duration: float = 0.6, seed: int = 0) -> dict:
    """A short run of the analytic elastic model (eqs 29-30) sampled at the control rate.

    Forces are smooth and keep every cable taut; theta is quantised like the encoders.  Returns
    the per-topic arrays (motors, camera, truth) in the layout of ``synthetic_arrays``.
    """
    n = params.n_joints
    rate = params.control.rate_hz
    rng = np.random.default_rng(seed)
    amp = rng.uniform(3.0, 6.0, n + 1)
    freq = rng.uniform(1.0, 3.0, n + 1)

    def forces(t):
        return 20.0 + amp * np.sin(2 * np.pi * freq * t)

    # Pre-stretch every cable so it carries about 20 N (eq 54: x = t / (k + lambda t)).
    k, lam = np.asarray(params.cables.k), np.asarray(params.cables.lam)
    theta0 = (params.actuation.R / params.actuation.r_d) * (20.0 / (k + 20.0 * lam))
    t, st = simulate_elastic(np.zeros(n), theta0, forces, duration, params, sample_dt=1.0 / rate)
    res = params.sensors.encoder_resolution
    theta_q = np.round(st.theta / res) * res
    x = cable_lengths(st.alpha, params) + (params.actuation.r_d / params.actuation.R) * st.theta
    f = np.array([forces(ti) for ti in t])
    _, _, tension = elastic_derivative(st, f, params)
    cam = np.arange(0, len(t), int(round(rate / params.sensors.camera_rate_hz)))
    return {
        "motors": {"t": t, "theta": theta_q, "force": f},
        "camera": {"t": t[cam], "alpha": st.alpha[cam]},
        "truth": {"t": t, "alpha": st.alpha, "alpha_dot": st.alpha_dot, "tension": tension, "elongation": x},
        "_theta_true": st.theta,
    }


def plant_run(path, seconds: float = 1.0, *, params=None, effects=None, seed: int = 0, alpha0=(0.05, -0.03, 0.02)):
    """An open-loop run of the MuJoCo plant with smooth antagonistic forces, logged with the
    plant's run info (what replay needs).  Returns the plant."""
    from neck_sim.plant import Plant
    from neck_sim.replay import plant_run_info

    plant = Plant(params, effects, seed=seed)
    n = plant.n_joints
    plant.reset(alpha0=np.asarray(alpha0[:n], dtype=float))
    rng = np.random.default_rng(seed + 1)
    amp, freq, phase = rng.uniform(6, 12, n + 1), rng.uniform(0.8, 1.6, n + 1), rng.uniform(0, 2 * np.pi, n + 1)
    steps = int(round(seconds * plant.params.control.rate_hz))
    with LogWriter(path, plant.params, mjcf_xml=plant.xml, run_info=plant_run_info(plant)) as w:
        for _ in range(steps):
            t = plant.time
            force = 28.0 + amp * np.sin(2 * np.pi * freq * t + phase)
            theta, truth = plant.encoders(), plant.truth()
            plant.step(force)
            w.motors(t, theta, force)
            w.truth(t, truth.alpha, truth.alpha_dot, truth.tension, truth.elongation)
            frame = plant.camera_frame()
            if frame is not None:
                w.camera(*frame)
    return plant


def log_arrays(log) -> dict:
    """Per-topic arrays of a Log in the layout of ``synthetic_arrays`` (topics present only)."""
    out = {}
    for topic in ("motors", "camera", "reference", "estimate", "truth"):
        samples = getattr(log, topic)
        if samples is not None:
            out[topic] = {k: np.array(v) for k, v in vars(samples).items()}
    return out
