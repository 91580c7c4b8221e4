"""Intent estimation: DTW matches to model likelihoods and posterior category probabilities.

Implements docs/controller-design.md, "Probabilities" (paper, "Estimating model probabilities"):

- accepted match: `P(obs | model_j) = chi2.sf(D_j, df = 2 L_j)`, rejected: 0;
- `P(obs | other) = prod_j (1 - P(obs | model_j))`;
- posteriors by Bayes' rule over (squat, stoop_left, stoop_right, other).

The chi-square survival function with even degrees of freedom `2L` is the Poisson
tail `exp(-x) sum_{k<L} x^k / k!` with `x = D/2`. All its terms are positive, so the
sum is accumulated directly (no cancellation) and rescaled when it grows large; the
factor `exp(-x)` is applied in log space at the end. This keeps full relative accuracy
for `L` in the hundreds and `D` in the thousands, where `exp(-x)` alone underflows.

Degenerate evidence: Bayes' rule is 0/0 when every category has zero
evidence-times-prior. With strictly positive priors this cannot happen (if every
`P(obs | model_j)` is 0 then `P(obs | other)` is 1, and if one is 1 its own term is
positive), so it only arises with zero priors. Then the posterior is all on `other`:
nothing was recognised, and `other` is the category whose utilities are built to be
safe for any motion.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numba import njit

FloatArray = npt.NDArray[np.float64]

#: Number of motion models and of categories (models + other).
N_MODELS = 3
N_CATEGORIES = 4
#: Equal priors, the paper's choice.
EQUAL_PRIORS: tuple[float, float, float, float] = (0.25, 0.25, 0.25, 0.25)

_RESCALE = 1e200
_LOG_RESCALE = math.log(_RESCALE)


@njit(cache=True, nogil=True)
def likelihood_nb(D: float, L: int) -> float:
    """Compiled `likelihood` for the hot loop: NaN for NaN `D` or `L < 1`."""
    dist = D
    if math.isnan(dist) or L < 1:
        return np.nan
    if dist <= 0.0:
        return 1.0
    if math.isinf(dist):
        return 0.0
    x = 0.5 * dist
    term = 1.0
    total = 1.0
    log_scale = 0.0
    for k in range(1, L):
        term *= x / k
        total += term
        if total > _RESCALE:
            total /= _RESCALE
            term /= _RESCALE
            log_scale += _LOG_RESCALE
    p = math.exp(math.log(total) + log_scale - x)
    return 1.0 if p > 1.0 else p


def likelihood(D: float, L: int) -> float:
    """`P(obs | model) = chi2.sf(D, df=2L)` for a path of `L` cells and DTW distance `D`.

    Args:
        D: DTW distance, >= 0 (inf gives 0).
        L: Number of cells on the warping path, >= 1.

    Raises:
        ValueError: for NaN or negative `D`, or `L < 1`.
    """
    if isinstance(L, bool) or int(L) != L or L < 1:
        raise ValueError(f"L must be an integer >= 1, got {L!r}")
    if math.isnan(D) or D < 0:
        raise ValueError(f"D must be >= 0, got {D!r}")
    return float(likelihood_nb(float(D), int(L)))


def p_other(p_obs: npt.ArrayLike) -> float:
    """`P(obs | other) = prod_j (1 - P(obs | model_j))` (paper, independence rule of thumb)."""
    p = _as_probs(p_obs, "p_obs")
    return float(np.prod(1.0 - p))


def check_priors(priors: npt.ArrayLike) -> FloatArray:
    """Validate priors over (squat, stoop_left, stoop_right, other) and return them.

    They must be 4 finite, non-negative numbers that sum to 1 (within 1e-9).
    """
    pr = np.asarray(priors, dtype=np.float64)
    if pr.shape != (N_CATEGORIES,):
        raise ValueError(f"priors must have shape ({N_CATEGORIES},), got {pr.shape}")
    if not np.all(np.isfinite(pr)) or np.any(pr < 0):
        raise ValueError(f"priors must be finite and >= 0, got {pr.tolist()}")
    if abs(float(pr.sum()) - 1.0) > 1e-9:
        raise ValueError(f"priors must sum to 1, got sum {float(pr.sum())!r}")
    return pr


def _as_probs(p: npt.ArrayLike, name: str) -> FloatArray:
    a = np.asarray(p, dtype=np.float64)
    if a.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional, got shape {a.shape}")
    if not np.all((a >= 0) & (a <= 1)):  # also rejects NaN
        raise ValueError(f"{name} must lie in [0, 1], got {a.tolist()}")
    return a


@njit(cache=True, nogil=True)
def _posteriors_into(p_obs: FloatArray, priors: FloatArray, post: FloatArray) -> None:
    """Bayes over the models plus `other`; `post` has one more entry than `p_obs`."""
    k = p_obs.shape[0]
    other = 1.0
    for j in range(k):
        other *= 1.0 - float(p_obs[j])
    total = 0.0
    for j in range(k):
        w = float(p_obs[j] * priors[j])
        post[j] = w
        total += w
    w = other * float(priors[k])
    post[k] = w
    total += w
    if total > 0.0:
        for j in range(k + 1):
            post[j] /= total
    else:
        for j in range(k):
            post[j] = 0.0
        post[k] = 1.0


@njit(cache=True, nogil=True)
def intent_kernel(
    D: FloatArray,
    L: npt.NDArray[np.int64],
    accepted: npt.NDArray[np.bool_],
    priors: FloatArray,
    p_obs: FloatArray,
    post: FloatArray,
) -> None:
    """Posteriors into `post` from the bank's distances and lengths (`D`, `L`): the
    estimator's own step, public so the UMC's compiled tick runs the same code."""
    for j in range(D.shape[0]):
        p_obs[j] = likelihood_nb(D[j], L[j]) if accepted[j] else 0.0
    _posteriors_into(p_obs, priors, post)


def posteriors(p_obs: npt.ArrayLike, priors: npt.ArrayLike = EQUAL_PRIORS) -> FloatArray:
    """`P(category | obs)` for (squat, stoop_left, stoop_right, other) by Bayes' rule.

    Args:
        p_obs: (3,) `P(obs | model_j)`, each in [0, 1].
        priors: (4,) priors, see `check_priors`.

    Returns:
        (4,) posteriors summing to 1; all on `other` in the degenerate case described
        in the module docstring.
    """
    p = _as_probs(p_obs, "p_obs")
    if p.shape != (N_MODELS,):
        raise ValueError(f"p_obs must have shape ({N_MODELS},), got {p.shape}")
    pr = check_priors(priors)
    out = np.empty(N_CATEGORIES)
    _posteriors_into(np.ascontiguousarray(p), np.ascontiguousarray(pr), out)
    return out


class IntentEstimator:
    """Hot-path likelihoods and posteriors for one tick, into preallocated arrays.

    After `update`, `p_obs` (3,) holds `P(obs | model_j)` (0 for rejected matches) and
    `post` (4,) the posteriors. Both arrays are reused on every call.
    """

    def __init__(self, priors: npt.ArrayLike = EQUAL_PRIORS, n_models: int = N_MODELS) -> None:
        """Args: priors over the models then `other` (length n_models + 1, sum 1)."""
        pr = np.asarray(priors, dtype=np.float64)
        if n_models == N_MODELS:
            pr = check_priors(pr)
        elif pr.shape != (n_models + 1,) or not np.all(pr >= 0) or abs(pr.sum() - 1) > 1e-9:
            raise ValueError(f"priors must be {n_models + 1} values >= 0 summing to 1")
        self.priors = np.ascontiguousarray(pr)
        self.p_obs = np.zeros(n_models)
        self.post = np.zeros(n_models + 1)

    def warm_up(self) -> None:
        """Compile now, never inside a tick."""
        k = self.p_obs.shape[0]
        self.update(np.full(k, 7.5), np.full(k, 3, dtype=np.int64), np.ones(k, dtype=np.bool_))

    def update(
        self,
        D: FloatArray,
        L: npt.NDArray[np.int64],
        accepted: npt.NDArray[np.bool_],
    ) -> FloatArray:
        """Likelihoods of the accepted matches, then posteriors; returns `post`.

        Arguments are the `ModelBank` output arrays (float64, int64, bool).
        """
        intent_kernel(D, L, accepted, self.priors, self.p_obs, self.post)
        return self.post
