"""The joint speeds of a neck with fewer cables than joints, from the encoders and the camera together.

With C < N cables, eq (35) (Z^T alpha_dot = (r_d/R) theta_dot - x_dot, the elongation rates x_dot
of eq 27) gives C equations for N joint speeds; the camera gives all N, with its 1 deg angle noise
differentiated (0.064-0.075 rad/s rms at a 2.75 Hz common cutoff and 30 frames/s).  This module
combines the two by weighted least squares, on the slow grid of the observations:

    alpha_dot = argmin |Z^T a - b|^2_{sigma_x} + |a - alpha_dot_camera|^2_{sigma_c}
    b = (r_d/R) theta_dot - d/dt x(t),    x = x(tension) of eq (54) at rest (k, lambda nominal)

``x`` is each cable's elastic elongation from its measured tension (``MeasuredData.tension0``:
the forces less the motor's inertia and a first dry-friction estimate) through the nominal k,
lambda (``dynamics.static_elongation``).  The encoder equations are sharp where Z^T is (on the
10-joint, 4-cable neck, two of its singular values are about 0.09 m, two 0.0008-0.0017 m: a plain
pseudo-inverse multiplies 1 mm/s of elongation-rate error by 400-1000 rad/m); the weights let the
camera set the directions Z^T barely sees.  Weights: ``sigma_c`` the camera's speed noise
predicted from ``sensors.camera_noise`` (:func:`camera_speed_noise`), ``sigma_x`` per cable the
rms of its elongation rate (the correction is trusted to its own size: nominal k, lambda).  On the
blind 59.3 s hinge logs of the 10x4 neck (seeds 1 and 3, the plant's speed from ``/neck/truth``)
the estimated rates correlate 0.98-0.998 with the plant's; a tighter sigma_x (a half or a quarter
of the rms) helps the low joints a little and makes joints 6, 9 and 10 worse than the camera.

    >>> from identification.diagnosis.joint_speed import fused_joint_speed
    >>> speed = fused_joint_speed(data)        # (S, N) rad/s          # doctest: +SKIP

Measured for the hinge-friction column of a neck with C < N (``columns.joint_friction``, which
takes the camera's speed there) and not adopted: on the blind 59.3 s logs of the 10x4 neck it reads
the hinge joints' speed 6-15 % closer to the plant's than the camera, but sizes the three hidden
hinges -10.0 %, +1.4 %, +22.6 % against the camera's -8.6 %, +0.1 %, +26 %
(docs/your-own-neck.md section 7).  C >= N necks take eq (35) at the control rate.
"""

from __future__ import annotations

import math

import numpy as np

from neck_sim.analytic.dynamics import static_elongation

__all__ = ["camera_speed_noise", "elongation_rate", "fused_joint_speed"]


def camera_speed_noise(sigma_rad: float, camera_rate_hz: float, cutoff_hz: float) -> float:
    """rms (rad/s) of the camera's white angle noise ``sigma_rad`` per frame at ``camera_rate_hz``,
    differentiated after an ideal low-pass at ``cutoff_hz``: sqrt((2 pi)^2 2 sigma^2 f_c^3 /
    (3 f_cam)) (the one-sided noise density 2 sigma^2 / f_cam times (2 pi f)^2 integrated to f_c)."""
    fc = min(cutoff_hz, 0.5 * camera_rate_hz)
    return math.sqrt((2.0 * math.pi) ** 2 * 2.0 * sigma_rad ** 2 * fc ** 3 / (3.0 * camera_rate_hz))


def elongation_rate(data) -> np.ndarray:
    """d/dt of each cable's elastic elongation (S, C) m/s: eq (54) at rest inverted at the
    measured tension (``data.tension0``, N) with the nominal k, lambda, differentiated on the slow
    grid (``numpy.gradient``)."""
    cab = data.params.cables
    x = static_elongation(data.tension0, np.asarray(cab.k, dtype=float), np.asarray(cab.lam, dtype=float))
    return np.gradient(x, data.t, axis=0)


def fused_joint_speed(data, *, elongation: bool = True) -> np.ndarray:
    """alpha_dot (S, N) rad/s: the weighted least-squares joint speed of the encoders' eq (35)
    (elongation-rate corrected, :func:`elongation_rate`; ``elongation=False`` drops the
    correction, for comparison) and the camera's speed (module docstring).  ``data`` is a
    ``ColumnData`` (its Z, camera speed, encoders, tension estimate and pre-processing)."""
    p = data.params
    act, sens = p.actuation, p.sensors
    theta_dot = data.cached("slow theta_dot", lambda: data.to_slow(data.theta_dot_fast))
    x_dot = elongation_rate(data)
    b = (act.r_d / act.R) * theta_dot - (x_dot if elongation else 0.0)
    # the floor (1 um/s, against 0.9-2.3 mm/s on the 10x4 logs) keeps the solve conditioned on a
    # log whose tensions never change
    sigma_x = np.maximum(np.sqrt(np.mean(x_dot ** 2, axis=0)), 1e-6)      # (C,)
    sigma_c = camera_speed_noise(float(sens.camera_noise), float(sens.camera_rate_hz), data.prep.cutoffs["common"].hz)
    if not sigma_c > 0:                     # a noise-free camera reads the speeds itself
        return np.array(data.alpha_dot, dtype=float)
    Zw = data.Z / sigma_x                                                          # (S, N, C)
    A = np.einsum("snc,smc->snm", Zw, Zw) + np.eye(data.n) / sigma_c ** 2
    rhs = np.einsum("snc,sc->sn", Zw, b / sigma_x) + data.alpha_dot / sigma_c ** 2
    return np.linalg.solve(A, rhs[..., None])[..., 0]
