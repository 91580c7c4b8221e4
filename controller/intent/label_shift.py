"""Priors from unconfirmed use: the EM estimate under label shift and its test
(Saerens, Latinne and Decaestecker, Neural Computation 14(1):21-41, 2002).

The controller's posteriors were computed with the priors it ran with (`p_train`).
If the wearer's motions come in other proportions, but each motion still looks the same
(label shift: `p(x | k)` unchanged), the new priors are the fixed point of

    w_ik = post_ik p_new(k) / p_train(k),  normalised over k;   p_new(k) = mean_i w_ik,

started at `p_train`. Each step is an EM step, so the likelihood of the unlabelled
data never falls. The iteration stops when no prior moves by more than `tol` or after
`max_iter` steps (then `converged` is False).

Test of whether the priors changed (their likelihood-ratio test): the log-likelihood
of the data under the new priors, relative to the old, is
`sum_i log sum_k post_ik p_new(k) / p_train(k)`; twice it is asymptotically chi-square
with `K - 1` degrees of freedom when the priors did not change.

Caveats, stated: the method assumes calibrated posteriors (Alexandari, Kundaje and
Shrikumar, ICML 2020, show how much that matters), and the test assumes independent
samples. UMC evaluations 0.1 s apart are neither: feed one posterior per motion (for
instance each segmented motion's posterior at its peak), not every tick.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from controller.intent.learned_priors import LearnedPriors
from controller.intent.prior_safety import PriorBounds

FloatArray = npt.NDArray[np.float64]

DEFAULT_TOL = 1e-8
DEFAULT_MAX_ITER = 1000


@dataclass(frozen=True)
class LabelShiftEstimate:
    """The EM estimate and the likelihood-ratio test against the training priors."""

    priors: FloatArray
    iterations: int
    converged: bool
    log_likelihood_ratio: float
    statistic: float
    dof: int
    p_value: float


def em_priors(posteriors: npt.ArrayLike, train_priors: npt.ArrayLike,
              tol: float = DEFAULT_TOL, max_iter: int = DEFAULT_MAX_ITER) -> LabelShiftEstimate:
    """Saerens et al.'s EM estimate of new priors from `(n, K)` posteriors.

    Raises:
        ValueError: posteriors not `(n, K)` rows in [0, 1] summing to 1, no rows,
            training priors not positive and summing to 1, or a bad `tol`/`max_iter`.
    """
    post = np.asarray(posteriors, dtype=np.float64)
    p0 = np.asarray(train_priors, dtype=np.float64)
    if post.ndim != 2 or post.shape[0] == 0:
        raise ValueError(f"posteriors must be (n, K) with n >= 1, got shape {post.shape}")
    k = post.shape[1]
    if p0.shape != (k,) or not np.isfinite(p0).all() or (p0 <= 0).any() \
            or abs(float(p0.sum()) - 1.0) > 1e-9:
        raise ValueError(f"train_priors must be {k} positive values summing to 1, got {p0}")
    if not np.isfinite(post).all() or (post < 0).any() or (post > 1).any():
        raise ValueError("posteriors must lie in [0, 1]")
    bad = np.flatnonzero(np.abs(post.sum(axis=1) - 1.0) > 1e-6)
    if bad.size:
        raise ValueError(f"posterior row {int(bad[0])} sums to {float(post[bad[0]].sum())!r}")
    if not tol > 0 or max_iter < 1:
        raise ValueError(f"need tol > 0 and max_iter >= 1, got {tol!r}, {max_iter!r}")
    p = p0.copy()
    converged = False
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 - the count is reported
        w = post * (p / p0)
        w /= np.maximum(w.sum(axis=1, keepdims=True), np.finfo(float).tiny)
        new = w.mean(axis=0)
        step = float(np.abs(new - p).max())
        p = new
        if step < tol:
            converged = True
            break
    llr = float(np.log(post @ (p / p0)).sum())
    stat = max(2.0 * llr, 0.0)
    # SciPy on first use, not at import: it costs every server start ~0.7 s of CPU.
    from scipy.stats import chi2

    return LabelShiftEstimate(priors=p, iterations=it, converged=converged,
                              log_likelihood_ratio=llr, statistic=stat, dof=k - 1,
                              p_value=float(chi2.sf(stat, k - 1)))


def learn_from_unconfirmed(posteriors: npt.ArrayLike, train_priors: npt.ArrayLike,
                           bounds: PriorBounds, *, sources: tuple[str, ...] = (),
                           version: str = "1", tol: float = DEFAULT_TOL,
                           max_iter: int = DEFAULT_MAX_ITER) -> LearnedPriors:
    """The EM estimate as a priors record, projected onto `bounds`; the iterations and
    the test go in `meta` (so a reader can see whether the change was significant)."""
    from datetime import UTC, datetime

    est = em_priors(posteriors, train_priors, tol, max_iter)
    return LearnedPriors(
        version=version, values=tuple(bounds.project(est.priors)),
        estimate=tuple(float(x) for x in est.priors), method="label-shift-em",
        floors=bounds.floors, roles=tuple(r.value for r in bounds.roles), sources=sources,
        created=datetime.now(UTC).isoformat(timespec="seconds"),
        meta={"train_priors": [float(x) for x in np.asarray(train_priors)],
              "n_samples": int(np.asarray(posteriors).shape[0]),
              "iterations": est.iterations, "converged": est.converged, "tol": tol,
              "max_iter": max_iter, "lr_statistic": est.statistic, "lr_dof": est.dof,
              "lr_p_value": est.p_value})
