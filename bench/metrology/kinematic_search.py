"""A global check of a kinematic identification: several starts drawn from the prior, the best kept, and a refusal
when distinct solutions explain the data about equally well.

Why: the forward model is nonlinear (a least-squares FK per pose), and a local solver started at the documented
geometry can stop in a wrong basin whose residuals look honest (reduced chi^2 ~ 1): on the ideal simulator, true
geometry seed 14 stopped with ``pd_5_x_mm`` 10 standard uncertainties from its truth at a MAP objective 5.6 above
the one the same fit reaches from the truth (docs/calibration.md, "Multi-start"). The chi^2 check cannot see
that; only comparing solutions can.

Method (a multi-start search, Nocedal & Wright 2006 §2.1 on local vs global minimisers; Ugray et al. 2007, "Scatter
search and local NLP solvers"): solve from the documented geometry, then from ``starts - 1`` draws of the prior
``theta_j ~ N(0, sigma_j^2)`` (the registration, which has no prior, starts at the first solution's); keep the
solution of lowest MAP objective

.. math:: \\Phi(\\theta) = \\sum_i |(m_i - f_i(\\theta)) / u_i|^2 + \\sum_j (\\theta_j / \\sigma_j)^2 ,

the negative log posterior up to a constant (Tarantola 2005 §3.2). Refused (:class:`AmbiguousFit`, one line naming
the parameters) when another solution's objective lies within :data:`AMBIGUITY_DELTA` of the best (posterior density
ratio above ``exp(-2)``: both are plausible) yet some parameter differs from the best by more than
:data:`AMBIGUITY_Z` of the best's standard uncertainties: the data then cannot tell the two geometries apart, and the
stated uncertainty would not cover the other. A start whose solve fails (FK failures on the way or at its
solution, no convergence) is left out; when every start fails, the documented start's failure is the fit's. Pure
computation, arrays in and out.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from bench.errors import InsufficientData
from bench.metrology.kinematic_calibration import Identification, UnidentifiableParameters, identify
from bench.metrology.kinematic_uncertainty import profile_ratios

__all__ = [
    "AMBIGUITY_DELTA",
    "AMBIGUITY_Z",
    "COVERAGE_K",
    "DEFAULT_STARTS",
    "AmbiguousFit",
    "SearchResult",
    "covering_rival",
    "identify_global",
    "map_objective",
    "rival_apart",
]

#: Starts of the search: the documented geometry and seven prior draws (measured: on the ideal simulator's seeds
#: 0-99 every stuck fit found its better basin within the first four draws, docs/calibration.md).
DEFAULT_STARTS = 8
#: Two solutions whose MAP objectives differ by less than this (a posterior density ratio above exp(-2)) are both
#: plausible.
AMBIGUITY_DELTA = 4.0
#: ... and are distinct when a parameter differs by more than this many of the best solution's standard uncertainties.
AMBIGUITY_Z = 5.0
#: Coverage factor of the prediction uncertainty within which two ambiguous solutions command alike (k = 2, 95 %).
COVERAGE_K = 2.0


class AmbiguousFit(UnidentifiableParameters):
    """Distinct geometries explain the data about equally well (module docstring): the fit is not stored.
    ``separation`` is how far apart their predictions lie, ``sum |(f_rival - f_best) / u|^2`` over the readings:
    measured, it stays ~1 as the cycles per pose grow (each solution refits the better data), so only poses that
    see the difference resolve it (docs/calibration.md). ``search`` is the search (its best kept) and ``rival`` the
    other solution, so a caller can see where the two differ (:func:`covering_rival`)."""

    def __init__(
        self,
        message: str,
        separation: float = float("nan"),
        search: SearchResult | None = None,
        rival: Identification | None = None,
    ) -> None:
        super().__init__(message)
        self.separation = separation
        self.search, self.rival = search, rival


@dataclass(frozen=True)
class SearchResult:
    """The kept identification and what the search saw: each start's objective (NaN: its solve failed) and the
    largest parameter distance (in the kept fit's standard uncertainties) of any converged start from it."""

    best: Identification
    objectives: np.ndarray
    spread_z: np.ndarray
    kept_start: int
    profile_ratio: np.ndarray | None = None  # per parameter u' / u (kinematic_uncertainty; NaN: undetermined, the
    # linear u kept); None: not profiled

    def as_dict(self) -> dict[str, Any]:
        widened = (
            {}
            if self.profile_ratio is None
            else {name: round(float(r), 4) for name, r in zip(self.best.names, self.profile_ratio) if r > 1.0}
        )
        return {
            "starts": len(self.objectives),
            "kept_start": self.kept_start,
            "objectives": [None if not np.isfinite(o) else round(float(o), 4) for o in self.objectives],
            "spread_z": [None if not np.isfinite(z) else round(float(z), 3) for z in self.spread_z],
            "profile_widened": widened,
            "profile_undetermined": []
            if self.profile_ratio is None
            else [name for name, r in zip(self.best.names, self.profile_ratio) if np.isnan(r)],
        }


def map_objective(result: Identification, uncertainty: ArrayLike) -> float:
    """``Phi`` of the module docstring at ``result``'s solution: weighted data residuals squared plus the prior's
    rows squared (the prior's only where ``result.prior_sigma`` is finite)."""
    data = float(np.sum((np.asarray(result.residuals) / np.broadcast_to(uncertainty, result.residuals.shape)) ** 2))
    if result.prior_sigma is None:
        return data
    finite = np.isfinite(result.prior_sigma)
    return data + float(np.sum((result.values[finite] / result.prior_sigma[finite]) ** 2))


def identify_global(
    model: Any,
    measured: ArrayLike,
    uncertainty: ArrayLike,
    *,
    prior_sigma: ArrayLike,
    starts: int = DEFAULT_STARTS,
    seed: int = 0,
    profile: bool = True,
    **options: Any,
) -> SearchResult:
    """Maximum a posteriori identification (:func:`identify`) from ``starts`` starting points (module docstring);
    ``seed`` seeds the prior draws, so a search is reproducible. Raises what :func:`identify` raises at the
    documented start, and :class:`AmbiguousFit` when two solutions are both plausible and distinct. With ``profile``
    the kept fit's standard uncertainties are widened where its profile-likelihood interval is wider than the
    linearised one (:func:`bench.metrology.kinematic_uncertainty.profile_uncertainty`; the ambiguity is judged by the
    linearised ones, as before)."""
    sigma = np.broadcast_to(np.asarray(prior_sigma, dtype=float), (len(model.free),))
    failure = None
    try:  # the documented start; its pose-set refusal (UnidentifiableParameters) is the fit's at once
        first = identify(model, measured, uncertainty, prior_sigma=sigma, **options)
    except InsufficientData as exc:  # its solve stopped where the model fails: the other starts may not
        failure, first = exc, None
    fits: list[Identification | None] = [first]
    rng = np.random.default_rng([int(seed), 35])
    finite = np.isfinite(sigma)
    for _ in range(int(starts) - 1):
        registration = np.zeros(len(sigma)) if first is None else first.values
        theta0 = np.where(finite, rng.normal(0.0, 1.0, len(sigma)) * np.where(finite, sigma, 0.0), registration)
        try:
            fits.append(
                identify(model, measured, uncertainty, prior_sigma=sigma, theta0=theta0, check_start=False, **options)
            )
        except (InsufficientData, UnidentifiableParameters):  # a start that left the model's domain
            fits.append(None)
    if all(f is None for f in fits):
        raise failure or InsufficientData("kinematic calibration refused: no start of the search converged")
    objectives = np.array([np.nan if f is None else map_objective(f, uncertainty) for f in fits])
    kept = int(np.nanargmin(objectives))
    best = fits[kept]
    assert best is not None  # the least objective is a finite one: a fit
    spread = np.array(
        [np.nan if f is None else float(np.max(np.abs(f.values - best.values) / best.uncertainty)) for f in fits]
    )
    rivals = [
        i
        for i, f in enumerate(fits)
        if f is not None
        and i != kept
        and objectives[i] - objectives[kept] < AMBIGUITY_DELTA
        and spread[i] > AMBIGUITY_Z
    ]
    ratio, linear_u = None, best.uncertainty
    if profile:  # after the ambiguity test, which keeps the linearised u it was measured with
        ratio = profile_ratios(model, measured, uncertainty, best)
        best = dataclasses.replace(best, uncertainty=best.uncertainty * np.nan_to_num(ratio, nan=1.0))
    if rivals:
        rival = fits[rivals[0]]
        assert rival is not None
        z = np.abs(rival.values - best.values) / linear_u
        named = ", ".join(f"{best.names[j]} ({z[j]:.1f} u)" for j in np.argsort(-z)[:3] if z[j] > AMBIGUITY_Z)
        separation = float(
            np.sum(((rival.residuals - best.residuals) / np.broadcast_to(uncertainty, best.residuals.shape)) ** 2)
        )
        raise AmbiguousFit(
            f"kinematic calibration refused: two geometries explain the {len(np.asarray(measured))} readings about "
            f"equally well (MAP objectives {objectives[kept]:.1f} and {objectives[rivals[0]]:.1f}, within "
            f"{AMBIGUITY_DELTA:g}) yet differ by more than {AMBIGUITY_Z:g} standard uncertainties in {named}; "
            f"nothing stored. Their predictions differ by chi^2 {separation:.3g} over the readings",
            separation,
            SearchResult(best, objectives, spread, kept, ratio),
            rival,
        )
    return SearchResult(best, objectives, spread, kept, ratio)


def rival_apart(best: Identification, rival: Identification, model: Any) -> tuple[np.ndarray, np.ndarray]:
    """Where two solutions differ, at the poses of ``model`` (a forward model of the same free parameters, e.g. a
    sample of the workspace): per pose the distance of their predictions ``d_i = |f_i(rival) - f_i(best)|`` (inf
    where one cannot be evaluated) and its ratio to the best's own stated uncertainty of prediction there at
    coverage :data:`COVERAGE_K`,

    .. math:: r_i = d_i / (k \\sqrt{\\operatorname{tr}(J_i C J_i^T)}),

    ``C`` the best's (posterior) covariance, ``J_i`` its Jacobian at the pose. Every ``r_i <= 1``: commanding by the
    best is as good as it states whichever solution is true."""
    apart = np.linalg.norm(model.predict(best.values) - model.predict(rival.values), axis=1)
    apart = np.where(np.isfinite(apart), apart, np.inf)
    jac = model.jacobian(best.values)
    covariance = best.correlation * np.outer(best.uncertainty, best.uncertainty)
    stated = np.sqrt(np.einsum("nak,kl,nal->n", jac, covariance, jac))
    return apart, apart / (COVERAGE_K * stated)


def covering_rival(best: Identification, rival: Identification) -> Identification:
    """``best`` with each standard uncertainty widened to cover the rival solution's value,

    .. math:: u'_j = \\sqrt{u_j^2 + (\\theta^{rival}_j - \\theta^{best}_j)^2},

    so that the truth, near either of two equally plausible solutions, lies within about one u' of the stored value
    (a conservative bound on the spread of the two-mode posterior; the correlations stay the best mode's). For
    ambiguities the data cannot resolve but that change no predicted position (the caller checks that)."""
    widened = np.sqrt(best.uncertainty**2 + (rival.values - best.values) ** 2)
    return dataclasses.replace(best, uncertainty=widened)
