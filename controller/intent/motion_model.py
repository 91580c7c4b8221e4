"""PPCA motion models of the lifting motions (paper, "Learning motion models").

Each demonstration (one segmented lift, `(K, 2)` hip flexion in rad, left then right)
is time-normalised to `N = 101` samples and stacked as one vector of length `2N`. The
stacking order is **sample-major**: `[theta_L(s_0), theta_R(s_0), theta_L(s_1),
theta_R(s_1), ...]`, i.e. `q.reshape(-1)` of an `(N, 2)` array. With this order the 2x2
block of `C` for sample `n` is `C[2n:2n+2, 2n:2n+2]`, which is all the onset detector
needs (the paper fixes the latent variables at zero, eq. 1).

The fit is the closed-form maximum-likelihood PPCA of Tipping & Bishop (1999):
`sigma^2` is the mean of the `d - q` discarded eigenvalues of the sample covariance
(zero eigenvalues included) and `W = U_q (Lambda_q - sigma^2 I)^(1/2)`. The
eigenvalues come from the SVD of the centred data, so it works with fewer
demonstrations than dimensions (the usual case: tens of lifts, 202 dimensions).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from controller.tick_record import MODEL_NAMES

FloatArray = NDArray[np.float64]

N_PROGRESS = 101
ONLINE_N = 51
FORMAT_NAME = "exostudy.motion_model_set"
FORMAT_VERSION = 1
STACKING = "sample-major: [theta_L(s_0), theta_R(s_0), theta_L(s_1), theta_R(s_1), ...]"
DEFAULT_EXPLAINED_VARIANCE = 0.95


def time_normalise(q_segment: FloatArray, n: int = N_PROGRESS) -> FloatArray:
    """Resample one demonstration to `n` samples over its own duration.

    Progress `s` runs linearly from 0 at the first sample to 1 at the last, so both
    ends are kept exactly and the result is independent of the lift's speed.

    Args:
        q_segment: `(K, 2)` hip flexion (rad), `K >= 2`.
        n: number of output samples.

    Returns:
        `(n, 2)` array.

    >>> time_normalise(np.array([[0.0, 0.0], [1.0, 2.0]]), n=3)[1].tolist()
    [0.5, 1.0]
    """
    q = np.asarray(q_segment, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != 2:
        raise ValueError(f"demonstration must have shape (K, 2), got {q.shape}")
    if q.shape[0] < 2:
        raise ValueError(f"demonstration needs at least 2 samples, got {q.shape[0]}")
    if n < 2:
        raise ValueError(f"n must be at least 2, got {n}")
    if not np.isfinite(q).all():
        raise ValueError(f"demonstration contains NaN or inf at sample {_first_bad(q)}")
    src = np.linspace(0.0, 1.0, q.shape[0])
    dst = np.linspace(0.0, 1.0, n)
    out = np.empty((n, 2))
    for col in range(2):
        out[:, col] = np.interp(dst, src, q[:, col])
    return out


def _first_bad(a: FloatArray) -> int:
    return int(np.argwhere(~np.isfinite(a))[0][0])


@dataclass(frozen=True)
class PPCAFit:
    """Closed-form ML PPCA of data vectors of dimension `d`.

    Attributes:
        mean: `(d,)` sample mean.
        w: `(d, q)` loading matrix `U_q (Lambda_q - sigma^2 I)^(1/2)`.
        sigma2: isotropic noise variance.
        eigenvalues: `(d,)` eigenvalues of the ML sample covariance (divisor `D`),
            descending, zeros included.
        explained_variance: fraction of the total variance in the `q` kept components.
    """

    mean: FloatArray
    w: FloatArray
    sigma2: float
    eigenvalues: FloatArray
    explained_variance: float

    @property
    def q(self) -> int:
        """Latent dimension."""
        return int(self.w.shape[1])

    @property
    def d(self) -> int:
        """Data dimension."""
        return int(self.mean.shape[0])

    def covariance(self) -> FloatArray:
        """The model covariance `C = W W^T + sigma^2 I` (`(d, d)`)."""
        return np.asarray(self.w @ self.w.T + self.sigma2 * np.eye(self.d), dtype=np.float64)


def fit_ppca(
    x: FloatArray,
    q: int | None = None,
    explained_variance: float = DEFAULT_EXPLAINED_VARIANCE,
) -> PPCAFit:
    """Fit PPCA by the Tipping & Bishop closed form.

    Args:
        x: `(D, d)` data, one vector per row, `D >= 2`.
        q: latent dimension; `None` picks the smallest `q` whose components explain at
            least `explained_variance` of the total variance.
        explained_variance: target fraction in (0, 1] when `q` is None.

    Returns:
        The fit. When the explained-variance rule would keep every non-zero
        eigenvalue (so that `sigma^2 = 0` and `C` is singular), `q` is lowered by one
        so that `sigma^2 > 0`; the stored `explained_variance` is the achieved one.

    Raises:
        ValueError: bad shape, NaN, fewer than 2 rows, an explicit `q` outside
            `0 <= q < rank`, or data with no variance at all.
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 2:
        raise ValueError(f"data must be 2-D (D, d), got shape {x.shape}")
    n_obs, d = x.shape
    if n_obs < 2:
        raise ValueError(f"PPCA needs at least 2 data vectors, got {n_obs}")
    if not np.isfinite(x).all():
        raise ValueError(f"data contain NaN or inf in row {_first_bad(x)}")
    if not 0.0 < explained_variance <= 1.0:
        raise ValueError(f"explained_variance must be in (0, 1], got {explained_variance}")
    mean = x.mean(axis=0)
    xc = x - mean
    # Thin SVD: eigenvalues of S = Xc^T Xc / D are s^2 / D, eigenvectors the rows of Vt.
    # Cost is O(D^2 d) instead of the O(d^3) of an eigendecomposition of S.
    _, s, vt = np.linalg.svd(xc, full_matrices=False)
    lam_nz = s * s / n_obs
    lam = np.zeros(d)
    lam[: lam_nz.shape[0]] = lam_nz
    total = float(lam.sum())
    if total <= 0.0:
        raise ValueError("data have no variance: every demonstration is identical")
    tol = lam[0] * max(n_obs, d) * np.finfo(float).eps
    rank = int(np.count_nonzero(lam > tol))
    if q is None:
        frac = np.cumsum(lam) / total
        q = int(np.searchsorted(frac, explained_variance - 1e-12) + 1)
        q = min(q, rank - 1, d - 1)
    elif not 0 <= q < rank:
        raise ValueError(
            f"latent dimension q={q} must satisfy 0 <= q < rank of the data ({rank}); "
            "otherwise sigma^2 is zero and the covariance is singular"
        )
    # Mean of the d - q discarded eigenvalues, the zeros beyond the rank included.
    sigma2 = float(lam[q:].sum() / (d - q))
    w = vt[:q].T * np.sqrt(np.maximum(lam[:q] - sigma2, 0.0))
    return PPCAFit(
        mean=mean,
        w=np.asarray(w, dtype=np.float64),
        sigma2=sigma2,
        eigenvalues=lam,
        explained_variance=float(lam[:q].sum() / total),
    )


def _check_spd_blocks(name: str, cov: FloatArray) -> None:
    """Raise naming the model and sample if a 2x2 block is not symmetric positive definite."""
    for n in range(cov.shape[0]):
        b = cov[n]
        scale = max(abs(b[0, 0]), abs(b[1, 1]), 1e-300)
        if abs(b[0, 1] - b[1, 0]) > 1e-9 * scale:
            raise ValueError(f"model {name}: covariance block at sample {n} is not symmetric")
        det = b[0, 0] * b[1, 1] - b[0, 1] * b[1, 0]
        if not (b[0, 0] > 0.0 and det > 0.0):
            raise ValueError(
                f"model {name}: covariance block at sample {n} is not positive definite"
            )


@dataclass(frozen=True)
class MotionModel:
    """One motion's distribution of hip flexion over progress, `N(mu(s_n), Sigma(s_n))`.

    Attributes:
        name: one of `MODEL_NAMES`.
        mean: `(101, 2)` mean (rad), columns left and right hip.
        cov: `(101, 2, 2)` per-sample blocks of `C = W W^T + sigma^2 I` (rad^2).
        online_n: samples `0..online_n-1` are the hip-flexion half used online.
        q, sigma2, explained_variance, n_demonstrations: facts of the PPCA fit.
        w: `(202, q)` loading matrix in sample-major order, kept so the full model
            can be rebuilt; `None` if unknown (e.g. a hand-made model).
    """

    name: str
    mean: FloatArray
    cov: FloatArray
    q: int
    sigma2: float
    explained_variance: float
    n_demonstrations: int
    online_n: int = ONLINE_N
    w: FloatArray | None = None

    def __post_init__(self) -> None:
        if self.name not in MODEL_NAMES:
            raise ValueError(f"unknown model name {self.name!r}; expected one of {MODEL_NAMES}")
        mean = np.asarray(self.mean, dtype=np.float64)
        cov = np.asarray(self.cov, dtype=np.float64)
        if mean.shape != (N_PROGRESS, 2):
            raise ValueError(f"model {self.name}: mean must be (101, 2), got {mean.shape}")
        if cov.shape != (N_PROGRESS, 2, 2):
            raise ValueError(f"model {self.name}: cov must be (101, 2, 2), got {cov.shape}")
        for label, arr in (("mean", mean), ("cov", cov)):
            if not np.isfinite(arr).all():
                raise ValueError(
                    f"model {self.name}: {label} has NaN or inf at sample {_first_bad(arr)}"
                )
        _check_spd_blocks(self.name, cov)
        if not 2 <= self.online_n <= N_PROGRESS:
            raise ValueError(f"model {self.name}: online_n must be in 2..101")
        if self.n_demonstrations < 2:
            raise ValueError(f"model {self.name}: needs at least 2 demonstrations")
        if not (self.sigma2 > 0.0 and math.isfinite(self.sigma2)):
            raise ValueError(f"model {self.name}: sigma2 must be positive, got {self.sigma2}")
        object.__setattr__(self, "mean", mean)
        object.__setattr__(self, "cov", cov)
        if self.w is not None:
            w = np.asarray(self.w, dtype=np.float64).reshape(2 * N_PROGRESS, -1)
            if w.shape[1] != self.q:
                raise ValueError(f"model {self.name}: w has {w.shape[1]} columns, q={self.q}")
            object.__setattr__(self, "w", w)

    @property
    def online_mean(self) -> FloatArray:
        """`(online_n, 2)` mean of the hip-flexion half."""
        return self.mean[: self.online_n]

    @property
    def online_cov(self) -> FloatArray:
        """`(online_n, 2, 2)` covariance blocks of the hip-flexion half."""
        return self.cov[: self.online_n]

    @classmethod
    def from_ppca(cls, name: str, fit: PPCAFit, n_demonstrations: int) -> MotionModel:
        """Keep the mean and the per-sample 2x2 blocks of a fit on stacked vectors."""
        if fit.d != 2 * N_PROGRESS:
            raise ValueError(f"fit has dimension {fit.d}, expected {2 * N_PROGRESS}")
        mean = fit.mean.reshape(N_PROGRESS, 2)
        wb = fit.w.reshape(N_PROGRESS, 2, fit.q)
        cov = np.einsum("nik,njk->nij", wb, wb) + fit.sigma2 * np.eye(2)
        return cls(
            name=name,
            mean=mean,
            cov=cov,
            q=fit.q,
            sigma2=fit.sigma2,
            explained_variance=fit.explained_variance,
            n_demonstrations=n_demonstrations,
            w=fit.w,
        )

    def to_json(self) -> dict[str, Any]:
        """JSON-able dictionary (part of a model-set document)."""
        return {
            "mean_rad": self.mean.tolist(),
            "cov_rad2": self.cov.tolist(),
            "online_n": self.online_n,
            "q": self.q,
            "sigma2": self.sigma2,
            "explained_variance": self.explained_variance,
            "n_demonstrations": self.n_demonstrations,
            "w": None if self.w is None else self.w.tolist(),
        }

    @classmethod
    def from_json(cls, name: str, data: dict[str, Any]) -> MotionModel:
        """Inverse of `to_json`."""
        try:
            w = data.get("w")
            return cls(
                name=name,
                mean=np.asarray(data["mean_rad"], dtype=np.float64),
                cov=np.asarray(data["cov_rad2"], dtype=np.float64),
                online_n=int(data.get("online_n", ONLINE_N)),
                q=int(data["q"]),
                sigma2=float(data["sigma2"]),
                explained_variance=float(data["explained_variance"]),
                n_demonstrations=int(data["n_demonstrations"]),
                w=None if w is None else np.asarray(w, dtype=np.float64),
            )
        except KeyError as exc:
            raise ValueError(f"model {name}: missing field {exc}") from exc


@dataclass(frozen=True)
class ModelSet:
    """The three lifting-motion models loaded by the controller, with provenance.

    Attributes:
        models: one `MotionModel` per name in `MODEL_NAMES`.
        version: free-form version label chosen by the experimenter.
        demonstrations: per model, the ids/labels of the demonstrations it was fitted
            from (in fit order).
        fit_params: how the fit was run (`q`, `explained_variance`, `n_progress`).
        created: ISO 8601 UTC time of the fit.
        meta: anything else worth keeping (participant, session, notes).
    """

    models: dict[str, MotionModel]
    version: str = "1"
    demonstrations: dict[str, list[str]] = field(default_factory=dict)
    fit_params: dict[str, Any] = field(default_factory=dict)
    created: str = ""
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        unknown = set(self.models) - set(MODEL_NAMES)
        if unknown:
            raise ValueError(f"unknown model names {sorted(unknown)}; expected {MODEL_NAMES}")
        missing = [m for m in MODEL_NAMES if m not in self.models]
        if missing:
            raise ValueError(f"model set lacks models {missing}")
        for key, model in self.models.items():
            if model.name != key:
                raise ValueError(f"model stored under {key!r} is named {model.name!r}")

    def __getitem__(self, name: str) -> MotionModel:
        return self.models[name]

    def ordered(self) -> tuple[MotionModel, MotionModel, MotionModel]:
        """Models in `MODEL_NAMES` order (the order of every per-model array)."""
        m = self.models
        return (m[MODEL_NAMES[0]], m[MODEL_NAMES[1]], m[MODEL_NAMES[2]])

    def start_posture(self) -> NDArray[np.float64]:
        """(q_left, q_right): the mean of the models' first samples, the posture a
        wearer stands in before a lift. The E-UMC's calibration measures the encoder
        offsets against it."""
        return np.asarray(np.mean([m.mean[0] for m in self.ordered()], axis=0),
                          dtype=np.float64)

    def to_json(self) -> dict[str, Any]:
        """Versioned JSON document."""
        return {
            "format": FORMAT_NAME,
            "format_version": FORMAT_VERSION,
            "version": self.version,
            "created": self.created,
            "n_progress": N_PROGRESS,
            "stacking": STACKING,
            "fit_params": self.fit_params,
            "demonstrations": self.demonstrations,
            "meta": self.meta,
            "models": {name: self.models[name].to_json() for name in MODEL_NAMES},
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> ModelSet:
        """Inverse of `to_json`; refuses other formats and versions."""
        if data.get("format") != FORMAT_NAME:
            raise ValueError(f"not an {FORMAT_NAME} document (format={data.get('format')!r})")
        if data.get("format_version") != FORMAT_VERSION:
            raise ValueError(f"unsupported format_version {data.get('format_version')!r}")
        if data.get("n_progress", N_PROGRESS) != N_PROGRESS:
            raise ValueError(f"n_progress must be {N_PROGRESS}")
        raw = data.get("models")
        if not isinstance(raw, dict):
            raise ValueError("model set document has no 'models' object")
        models = {name: MotionModel.from_json(name, m) for name, m in raw.items()}
        return cls(
            models=models,
            version=str(data.get("version", "1")),
            demonstrations={
                k: [str(i) for i in v] for k, v in data.get("demonstrations", {}).items()
            },
            fit_params=dict(data.get("fit_params", {})),
            created=str(data.get("created", "")),
            meta=dict(data.get("meta", {})),
        )

    def save(self, path: Path) -> None:
        """Write as JSON."""
        path.write_text(json.dumps(self.to_json()))

    @classmethod
    def load(cls, path: Path) -> ModelSet:
        """Read a file written by `save`."""
        return cls.from_json(json.loads(path.read_text()))


def fit_model_set(
    demos: dict[str, list[FloatArray]],
    *,
    q: int | None = None,
    explained_variance: float = DEFAULT_EXPLAINED_VARIANCE,
    version: str = "1",
    demo_ids: dict[str, list[str]] | None = None,
    meta: dict[str, Any] | None = None,
) -> ModelSet:
    """Time-normalise the segmented demonstrations and fit one PPCA model per motion.

    Args:
        demos: per model name, a list of `(K, 2)` segments (onset to return to rest).
        q: latent dimension for every model, or `None` for the explained-variance rule.
        explained_variance: target fraction when `q` is None.
        version: label stored in the set.
        demo_ids: per model, ids/labels of the demonstrations (default `"<name>-<i>"`).
        meta: extra provenance.

    Raises:
        ValueError: unknown or missing model names, fewer than 2 demonstrations for a
            model, a bad demonstration (shape, NaN), mismatched id lists.
    """
    unknown = set(demos) - set(MODEL_NAMES)
    if unknown:
        raise ValueError(f"unknown model names {sorted(unknown)}; expected {MODEL_NAMES}")
    models: dict[str, MotionModel] = {}
    ids: dict[str, list[str]] = {}
    for name in MODEL_NAMES:
        segs = demos.get(name)
        if segs is None:
            raise ValueError(f"no demonstrations for model {name}")
        if len(segs) < 2:
            raise ValueError(f"model {name}: needs at least 2 demonstrations, got {len(segs)}")
        rows = []
        for i, seg in enumerate(segs):
            try:
                rows.append(time_normalise(seg).reshape(-1))
            except ValueError as exc:
                raise ValueError(f"model {name}, demonstration {i}: {exc}") from exc
        these = list(demo_ids[name]) if demo_ids and name in demo_ids else None
        if these is None:
            these = [f"{name}-{i}" for i in range(len(segs))]
        elif len(these) != len(segs):
            raise ValueError(f"model {name}: {len(these)} ids for {len(segs)} demonstrations")
        try:
            fit = fit_ppca(np.vstack(rows), q=q, explained_variance=explained_variance)
        except ValueError as exc:
            raise ValueError(f"model {name}: {exc}") from exc
        models[name] = MotionModel.from_ppca(name, fit, n_demonstrations=len(segs))
        ids[name] = [str(i) for i in these]
    return ModelSet(
        models=models,
        version=version,
        demonstrations=ids,
        fit_params={"q": q, "explained_variance": explained_variance, "n_progress": N_PROGRESS},
        created=datetime.now(UTC).isoformat(timespec="seconds"),
        meta=dict(meta or {}),
    )
