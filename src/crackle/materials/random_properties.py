"""Random material properties per fracture site: an FDEM face, a DEM bond, a meshfree particle,
a shell edge.

A property's values come from its marginal distribution (Weibull, normal truncated at a floor,
lognormal) through a standard normal variable per site: drawn independently per site (numpy, in
the order of the sites, which every method numbers from its mesh or packing alone), or read from
a Gaussian random field at the site's reference position (GSTools' randomisation method: a sum of
Fourier modes fixed by the seed, so the field at a point does not depend on which other points
are evaluated: two meshes of the same specimen see the same field). Everything is drawn once, at
set-up, from `run.seed`, the material's name and the property's name: the same scenario gives
the same values on any thread count and after `--resume` (the checkpoint keeps them), and two
properties or two materials draw apart.
"""

from __future__ import annotations

import math
import zlib
from typing import Literal

import numpy as np
from pydantic import model_validator
from scipy import special, stats

from ..schema import Positive, Strict

COVARIANCES = ("exponential", "gaussian", "spherical", "matern")
# The empirical variogram behind the summary's realised correlation length: the sites it samples
# (its cost grows as their square) and its lag bins out to this many correlation lengths.
_VARIOGRAM_SITES = 3000
# Fourier modes of a field: one realisation's covariance is a mean over its modes, so more modes
# follow the model closer (2,000: within a few % at the correlation length, measured in
# tests/core/test_random_properties.py) at a cost linear in modes x sites (about 2 s per 20,000 sites).
FIELD_MODES = 2000
_VARIOGRAM_REACH = 3.0


class RandomProperty(Strict):
    """[material.random.NAME]: the distribution of one property over the fracture sites (the value
    given in the material, or its law, is the mean)."""

    distribution: Literal["weibull", "normal", "lognormal"]
    """"weibull" (give `modulus`), "normal" (give `cv`; truncated below at `floor`) or "lognormal" (give `cv`)"""
    modulus: Positive | None = None
    """weibull: m, the Weibull modulus (rock 5-20, concrete 8-12; lower: more scatter, CV ~ 1.2 / m)"""
    scale: Positive | None = None
    """Pa (the property's unit), weibull: the scale sigma_0 instead of the mean (the mean is then
    sigma_0 Gamma(1 + 1/m); the material's own value stays the reference the set-up's checks use)"""
    cv: Positive | None = None
    """normal, lognormal: the coefficient of variation, standard deviation over the mean"""
    floor: float | None = None
    """normal: values are drawn from the normal truncated below at this floor (the property's unit;
    default 0: no negative strength)"""
    correlation_length: Positive | None = None
    """m: the length of the Gaussian random field the values follow (GSTools' len_scale: the integral
    scale of the exponential and gaussian models, the range of the spherical); unset: every site drawn
    on its own"""
    covariance: Literal["exponential", "gaussian", "spherical", "matern"] = "exponential"
    """the field's covariance model (with correlation_length)"""

    @model_validator(mode="after")
    def _parameters(self):
        weibull = self.distribution == "weibull"
        if weibull and self.modulus is None:
            raise ValueError("distribution = \"weibull\" needs `modulus` (m; e.g. 6)")
        if not weibull and self.cv is None:
            raise ValueError(f"distribution = \"{self.distribution}\" needs `cv` (standard deviation over mean; e.g. 0.2)")
        wrong = [key for key, given in (("modulus", self.modulus), ("scale", self.scale), ("cv", self.cv),
                                         ("floor", self.floor))
                 if given is not None and key not in _KEYS_OF[self.distribution]]
        if wrong:
            raise ValueError(f"{', '.join(wrong)} do(es) not apply to distribution = \"{self.distribution}\" "
                             f"(it takes {', '.join(_KEYS_OF[self.distribution])}); remove it")
        if self.covariance != "exponential" and self.correlation_length is None:
            raise ValueError("covariance needs correlation_length (m); without it every site is drawn on its own")
        return self

    def marginal(self, mean: float):
        """The frozen scipy distribution of the values, for a property whose given value is `mean`."""
        if self.distribution == "weibull":
            m = self.modulus
            scale = self.scale if self.scale is not None else mean / math.gamma(1.0 + 1.0 / m)
            return stats.weibull_min(m, scale=scale)
        if self.distribution == "normal":
            sd = self.cv * mean
            floor = 0.0 if self.floor is None else self.floor
            if floor >= mean:
                raise ValueError(f"floor = {floor:g} is not below the mean {mean:g}: lower the floor")
            return stats.truncnorm((floor - mean) / sd, np.inf, loc=mean, scale=sd)
        s = math.sqrt(math.log1p(self.cv**2))
        return stats.lognorm(s, scale=mean / math.sqrt(1.0 + self.cv**2))

    def covariance_model(self):
        """The GSTools model of the field (unit variance), None for independent sites."""
        if self.correlation_length is None:
            return None
        import gstools

        model = {"exponential": gstools.Exponential, "gaussian": gstools.Gaussian,
                 "spherical": gstools.Spherical, "matern": gstools.Matern}[self.covariance]
        return model(dim=3, var=1.0, len_scale=self.correlation_length)


_KEYS_OF = {"weibull": ("modulus", "scale"), "normal": ("cv", "floor"), "lognormal": ("cv",)}


def check_names(random: dict, allowed: tuple[str, ...], where: str) -> None:
    """ValueError naming a property that cannot be random here, and those that can."""
    unknown = [name for name in random if name not in allowed]
    if unknown:
        raise ValueError(f"{where}.random.{unknown[0]}: not a property drawn per fracture site here; "
                         f"random properties of this method: {', '.join(allowed)}")


def stream_seed(seed: int, material: str, prop: str) -> int:
    """The seed of one property of one material: the run's seed with the two names, so that
    properties and materials draw apart and the same names draw alike whatever else is random."""
    key = zlib.crc32(f"{material}/{prop}".encode())
    return int(np.random.SeedSequence([int(seed), key]).generate_state(1)[0])


def standard_normal(spec: RandomProperty, positions: np.ndarray, seed: int) -> np.ndarray:
    """One standard normal value per site: independent ones in the sites' order, or the random
    field at the sites' positions (m, (n, 3))."""
    positions = np.asarray(positions, float).reshape(-1, 3)
    field = random_field(spec, seed)
    if field is None:
        return np.random.default_rng(seed).standard_normal(len(positions))
    return np.asarray(field(positions.T, mesh_type="unstructured"), float)


def random_field(spec: RandomProperty, seed: int):
    """The GSTools field (unit variance, FIELD_MODES modes) of a correlated property, a function
    of position for its seed; None for independent sites."""
    model = spec.covariance_model()
    if model is None:
        return None
    import gstools

    return gstools.SRF(model, mean=0.0, seed=seed, mode_no=FIELD_MODES)


_GOLDEN = np.uint64(0x9E3779B97F4A7C15)


def _mix(h: np.ndarray) -> np.ndarray:
    """splitmix64's finaliser on uint64 values (wrapping arithmetic)."""
    h = (h ^ (h >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    h = (h ^ (h >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return h ^ (h >> np.uint64(31))


def hashed_normal(points: np.ndarray, seed: int) -> np.ndarray:
    """Independent standard normal values, one per point (m, (k, 3)), each a function of the
    point's coordinates (their bits; -0.0 counted as 0.0) and the seed alone: independent sites
    whose numbering changes during a run (the shell's edges, which cracks cut and renumber)."""
    bits = (np.ascontiguousarray(points, dtype=float).reshape(-1, 3) + 0.0).view(np.uint64)
    h = np.full(len(bits), np.uint64(seed), dtype=np.uint64)
    for c in range(3):
        h = _mix((h + _GOLDEN) ^ bits[:, c])
    h = _mix(h + _GOLDEN)
    return special.ndtri(((h >> np.uint64(11)).astype(float) + 0.5) * 2.0**-53)



def to_marginal(spec: RandomProperty, mean: float, z: np.ndarray) -> np.ndarray:
    """The standard normal values z mapped through the property's marginal (equal quantiles)."""
    # Both tails from their own side, so a far tail does not round to a probability of 0 or 1.
    upper = z > 0.0
    dist = spec.marginal(mean)
    values = np.empty_like(z)
    values[upper] = dist.isf(special.ndtr(-z[upper]))
    values[~upper] = dist.ppf(special.ndtr(z[~upper]))
    return values


def draw(spec: RandomProperty, mean: float, positions: np.ndarray, seed: int, material: str, prop: str) -> np.ndarray:
    """The values of property `prop` of `material` at the sites (their reference positions, m)."""
    z = standard_normal(spec, positions, stream_seed(seed, material, prop))
    return to_marginal(spec, mean, z)


def realised_correlation_length(spec: RandomProperty, positions: np.ndarray, values: np.ndarray) -> float | None:
    """The correlation length of the covariance model fitted to the values' empirical variogram
    (in their normal scores, on a fixed sample of the sites); None for independent sites."""
    model = spec.covariance_model()
    if model is None or len(values) < 10:
        return None
    import gstools

    positions = np.asarray(positions, float).reshape(-1, 3)
    rank = stats.rankdata(values) / (len(values) + 1.0)
    scores = special.ndtri(rank)
    pick = np.random.default_rng(0).permutation(len(values))[:_VARIOGRAM_SITES]
    bins = np.linspace(0.0, _VARIOGRAM_REACH * spec.correlation_length, 16)
    centres, gamma = gstools.vario_estimate(positions[pick].T, scores[pick], bins)
    fitted = type(model)(dim=3)
    fitted.fit_variogram(centres, gamma, nugget=False)
    return float(fitted.len_scale)


def statistics(spec: RandomProperty, positions: np.ndarray, values: np.ndarray) -> dict:
    """What summary.json reports of a drawn property."""
    values = np.asarray(values, float)
    return {
        "distribution": spec.distribution,
        "sites": int(len(values)),
        "mean": float(values.mean()) if len(values) else None,
        "sd": float(values.std(ddof=1)) if len(values) > 1 else None,
        "min": float(values.min()) if len(values) else None,
        "max": float(values.max()) if len(values) else None,
        "correlation_length": spec.correlation_length,
        "correlation_length_realised": realised_correlation_length(spec, positions, values),
    }


__all__ = ["COVARIANCES", "RandomProperty", "check_names", "draw", "hashed_normal", "random_field",
           "realised_correlation_length", "standard_normal", "statistics", "stream_seed", "to_marginal"]
