"""Strength envelopes of rock from triaxial peaks: the principal stress at failure sigma_1 against
the confining pressure sigma_3 (both compression positive, Pa).

Mohr-Coulomb: sigma_1 = UCS + q sigma_3, q = (1 + sin phi) / (1 - sin phi), c = UCS / (2 sqrt q),
a straight line fitted by least squares. Hoek-Brown for intact rock (Hoek and Brown 1980, 1997):
sigma_1 = sigma_3 + sigma_ci (m_i sigma_3 / sigma_ci + 1)^0.5, fitted as Hoek and Brown do it:
(sigma_1 - sigma_3)^2 = m_i sigma_ci sigma_3 + sigma_ci^2 is a straight line in sigma_3."""

from __future__ import annotations

import math

import numpy as np


def _line(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float]:
    """Least-squares y = a + b x: (a, b, coefficient of determination)."""
    b, a = np.polyfit(x, y, 1)
    residual = y - (a + b * x)
    spread = float(np.sum((y - y.mean()) ** 2))
    return float(a), float(b), 1.0 - float(np.sum(residual**2)) / spread if spread > 0 else 1.0


def mohr_coulomb(sigma_3, sigma_1) -> dict | None:
    """The Mohr-Coulomb envelope through the peaks: ucs (Pa), slope q, friction_angle (deg),
    cohesion (Pa), r2; None under two distinct confinements or for a slope q <= 1 (no friction)."""
    s3, s1 = np.asarray(sigma_3, float), np.asarray(sigma_1, float)
    if len(np.unique(s3)) < 2:
        return None
    ucs, q, r2 = _line(s3, s1)
    if q <= 1.0:
        return None
    phi = math.asin((q - 1.0) / (q + 1.0))
    return {"ucs": ucs, "slope": q, "friction_angle": math.degrees(phi), "cohesion": ucs / (2.0 * math.sqrt(q)),
            "r2": r2}


def hoek_brown(sigma_3, sigma_1) -> dict | None:
    """The Hoek-Brown envelope for intact rock through the peaks: sigma_ci (Pa), m_i, r2 (of the
    linearised fit); None under two distinct confinements or without a positive sigma_ci^2."""
    s3, s1 = np.asarray(sigma_3, float), np.asarray(sigma_1, float)
    if len(np.unique(s3)) < 2:
        return None
    intercept, slope, r2 = _line(s3, (s1 - s3) ** 2)
    if intercept <= 0.0:
        return None
    sigma_ci = math.sqrt(intercept)
    return {"sigma_ci": sigma_ci, "m_i": slope / sigma_ci, "r2": r2}


def mohr_coulomb_sigma_1(fit: dict, sigma_3):
    return fit["ucs"] + fit["slope"] * np.asarray(sigma_3, float)


def hoek_brown_sigma_1(fit: dict, sigma_3):
    s3 = np.asarray(sigma_3, float)
    return s3 + fit["sigma_ci"] * np.sqrt(np.maximum(fit["m_i"] * s3 / fit["sigma_ci"] + 1.0, 0.0))
