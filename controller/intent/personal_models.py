"""Personal motion models: the population models adapted to one wearer, or fitted from
the wearer alone.

MAP adaptation (the GMM-UBM pattern of Reynolds, Quatieri and Dunn, Digital Signal
Processing 10:19-41, 2000, with the population model as the prior). For each motion,
with the wearer's `n` time-normalised demonstrations `x_i` (101 x 2 each) and the
population mean `mu`, the adapted mean is

    mu_hat = (tau mu + sum_i x_i) / (tau + n) = mu + sum_i (x_i - mu) / (tau + n),

with relevance factor `tau` (in demonstrations; default 5, a stated choice: five of
the wearer's own demonstrations weigh as much as the whole population, so the first
few move the model halfway and it follows the wearer as demonstrations accumulate).
The second form is used: with `n = 0` it returns the population mean bit for bit.

The covariance (the PPCA loading `W` and `sigma^2`) is kept from the population, for
three reasons: a handful of demonstrations cannot estimate a 202-dimensional
covariance; Reynolds et al. found adapting the means alone as good as adapting
variances too; and the population covariance, which includes the spread between
people, keeps the onset detector tolerant of the wearer's own variation.

Fitted from the wearer alone: the population-independent PPCA fit
(`fit_model_set`), refused with a clear error below a minimum number of
demonstrations per motion (default 3: two give a rank-one sample, no latent
dimension at all).
"""

from __future__ import annotations

from collections.abc import Sequence
from datetime import UTC, datetime
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.intent.motion_model import ModelSet, MotionModel, fit_model_set, time_normalise
from controller.tick_record import MODEL_NAMES

FloatArray = NDArray[np.float64]

DEFAULT_TAU = 5.0
MIN_PARTICIPANT_DEMOS = 3


class TooFewDemonstrationsError(ValueError):
    """A participant-only fit was asked for with too few demonstrations of some motion."""


def _ids(name: str, n: int, demo_ids: dict[str, list[str]] | None) -> list[str]:
    ids = list(demo_ids[name]) if demo_ids and name in demo_ids else [
        f"{name}-{i}" for i in range(n)]
    if len(ids) != n:
        raise ValueError(f"model {name}: {len(ids)} ids for {n} demonstrations")
    return [str(i) for i in ids]


def adapt_model(model: MotionModel, demos: Sequence[FloatArray], tau: float) -> MotionModel:
    """One motion model with its mean MAP-adapted to `demos` (segments `(K, 2)`)."""
    if not (np.isfinite(tau) and tau > 0):
        raise ValueError(f"tau must be a positive number, got {tau!r}")
    rows = []
    for i, seg in enumerate(demos):
        try:
            rows.append(time_normalise(seg))
        except ValueError as exc:
            raise ValueError(f"model {model.name}, demonstration {i}: {exc}") from exc
    shift = np.zeros_like(model.mean)
    for x in rows:
        shift += x - model.mean
    mean = model.mean + shift / (tau + len(rows))
    return MotionModel(name=model.name, mean=mean, cov=model.cov, q=model.q,
                       sigma2=model.sigma2, explained_variance=model.explained_variance,
                       n_demonstrations=model.n_demonstrations, online_n=model.online_n,
                       w=model.w)


def adapt_model_set(
    population: ModelSet,
    demos: dict[str, list[FloatArray]],
    *,
    tau: float = DEFAULT_TAU,
    demo_ids: dict[str, list[str]] | None = None,
    participant: str = "",
    version: str | None = None,
) -> ModelSet:
    """The population set with each motion's mean adapted to the wearer's demonstrations.

    A motion without demonstrations keeps its population model. Provenance: the
    population set's version and demonstrations, the wearer's demonstration ids, `tau`.
    """
    unknown = set(demos) - set(MODEL_NAMES)
    if unknown:
        raise ValueError(f"unknown model names {sorted(unknown)}; expected {MODEL_NAMES}")
    models: dict[str, MotionModel] = {}
    own: dict[str, list[str]] = {}
    for name in MODEL_NAMES:
        segs = demos.get(name, [])
        models[name] = adapt_model(population[name], segs, tau)
        own[name] = _ids(name, len(segs), demo_ids)
    return ModelSet(
        models=models,
        version=version or f"{population.version}+map-{participant or 'participant'}",
        demonstrations={n: [*population.demonstrations.get(n, []), *own[n]]
                        for n in MODEL_NAMES},
        fit_params={**population.fit_params, "adaptation": "map-mean", "tau": tau},
        created=datetime.now(UTC).isoformat(timespec="seconds"),
        meta={"personal": {"method": "map-mean", "tau": tau, "participant": participant,
                           "population_version": population.version,
                           "population_created": population.created,
                           "participant_demonstrations": own,
                           "n_participant": {n: len(own[n]) for n in MODEL_NAMES}}},
    )


def fit_participant_model_set(
    demos: dict[str, list[FloatArray]],
    *,
    min_per_motion: int = MIN_PARTICIPANT_DEMOS,
    demo_ids: dict[str, list[str]] | None = None,
    participant: str = "",
    version: str | None = None,
    q: int | None = None,
) -> ModelSet:
    """A model set fitted from one wearer's demonstrations alone.

    Raises:
        TooFewDemonstrationsError: naming every motion with fewer than `min_per_motion`.
    """
    if min_per_motion < 2:
        raise ValueError(f"min_per_motion must be at least 2 (PPCA needs two), got "
                         f"{min_per_motion}")
    short = {n: len(demos.get(n, [])) for n in MODEL_NAMES
             if len(demos.get(n, [])) < min_per_motion}
    if short:
        raise TooFewDemonstrationsError(
            "a participant-only model set needs at least "
            f"{min_per_motion} demonstrations of each motion; have "
            + ", ".join(f"{n}: {k}" for n, k in short.items()))
    meta: dict[str, Any] = {"personal": {"method": "participant-only",
                                         "participant": participant}}
    return fit_model_set(demos, q=q, demo_ids=demo_ids, meta=meta,
                         version=version or f"participant-{participant or 'unnamed'}")
