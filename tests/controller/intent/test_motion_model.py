"""Tests of time normalisation, the PPCA fit and the model-set format."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller.intent.motion_model import (
    FORMAT_NAME,
    ModelSet,
    MotionModel,
    PPCAFit,
    fit_model_set,
    fit_ppca,
    time_normalise,
)


def log_likelihood(x: np.ndarray, mean: np.ndarray, c: np.ndarray) -> float:
    """Gaussian log-likelihood of the rows of x under N(mean, c)."""
    n_obs, d = x.shape
    xc = x - mean
    s = xc.T @ xc / n_obs
    _, logdet = np.linalg.slogdet(c)
    return float(-0.5 * n_obs * (d * np.log(2 * np.pi) + logdet + np.trace(np.linalg.solve(c, s))))


def reference_fit(x: np.ndarray, q: int) -> tuple[np.ndarray, float]:
    """Tipping & Bishop from an eigendecomposition of the full d x d covariance."""
    s = np.cov(x, rowvar=False, bias=True)
    lam, u = np.linalg.eigh(s)
    lam, u = lam[::-1], u[:, ::-1]
    lam = np.clip(lam, 0.0, None)  # round-off below zero
    sigma2 = lam[q:].mean()
    w = u[:, :q] * np.sqrt(lam[:q] - sigma2)
    return w @ w.T + sigma2 * np.eye(x.shape[1]), float(sigma2)


def lift(k: int, peak_l: float, peak_r: float, shape: float = 1.0) -> np.ndarray:
    s = np.linspace(0.0, 1.0, k)
    base = np.sin(np.pi * s) ** (2 * shape)
    return np.column_stack([peak_l * base, peak_r * base])


def demos(rng: np.random.Generator, count: int, pl: float, pr: float) -> list[np.ndarray]:
    return [
        lift(int(rng.integers(150, 300)), pl + rng.normal(0, 0.1), pr + rng.normal(0, 0.1),
             shape=1.0 + rng.normal(0, 0.1)) + rng.normal(0, 0.005, (1, 2))
        for _ in range(count)
    ]


def test_time_normalise() -> None:
    k = 257
    t = np.linspace(0.0, 2.56, k)
    q = np.column_stack([3.0 * t, 1.0 - t])
    out = time_normalise(q)
    assert out.shape == (101, 2)
    s = np.linspace(0.0, 1.0, 101)
    np.testing.assert_allclose(out[:, 0], 3.0 * 2.56 * s, atol=1e-12)
    np.testing.assert_allclose(out[:, 1], 1.0 - 2.56 * s, atol=1e-12)
    np.testing.assert_array_equal(out[[0, -1]], q[[0, -1]])
    np.testing.assert_array_equal(time_normalise(out), out)  # already 101 samples
    with pytest.raises(ValueError, match=r"\(K, 2\)"):
        time_normalise(np.zeros((10, 3)))
    with pytest.raises(ValueError, match="at least 2"):
        time_normalise(np.zeros((1, 2)))
    bad = q.copy()
    bad[40, 1] = np.nan
    with pytest.raises(ValueError, match="sample 40"):
        time_normalise(bad)


@settings(max_examples=40, deadline=None)
@given(n_obs=st.integers(2, 14), d=st.integers(2, 9), seed=st.integers(0, 2**32 - 1),
       ev=st.floats(0.3, 1.0))
def test_ppca_matches_eigendecomposition_route(n_obs: int, d: int, seed: int, ev: float) -> None:
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n_obs, 3)) @ rng.normal(size=(3, d)) + 0.1 * rng.normal(size=(n_obs, d))
    fit = fit_ppca(x, explained_variance=ev)
    c_ref, sigma2_ref = reference_fit(x, fit.q)
    assert fit.sigma2 == pytest.approx(sigma2_ref, rel=1e-8, abs=1e-12)
    assert fit.sigma2 > 0.0
    np.testing.assert_allclose(fit.covariance(), c_ref, rtol=1e-7, atol=1e-10)
    # q is the smallest reaching the target, unless capped to keep sigma^2 > 0.
    frac = np.cumsum(fit.eigenvalues) / fit.eigenvalues.sum()
    rank = min(n_obs - 1, d)
    target_q = int(np.argmax(frac >= ev - 1e-12)) + 1  # smallest q reaching the target
    assert fit.q == min(target_q, rank - 1, d - 1)
    assert fit.explained_variance == pytest.approx(frac[fit.q - 1] if fit.q else 0.0)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), q=st.integers(0, 4))
def test_ppca_is_the_maximum_likelihood(seed: int, q: int) -> None:
    rng = np.random.default_rng(seed)
    d, n_obs = 6, 40
    x = rng.normal(size=(n_obs, d)) * np.array([3.0, 2.0, 1.5, 1.0, 0.5, 0.3])
    fit = fit_ppca(x, q=q)
    best = log_likelihood(x, fit.mean, fit.covariance())
    for _ in range(10):
        w = fit.w + 0.05 * rng.normal(size=fit.w.shape)
        s2 = fit.sigma2 * float(np.exp(rng.normal(0, 0.1)))
        assert log_likelihood(x, fit.mean, w @ w.T + s2 * np.eye(d)) < best
        shifted = fit.mean + 0.05 * rng.normal(size=d)
        assert log_likelihood(x, shifted, fit.covariance()) < best


def test_full_rank_q_gives_sample_covariance() -> None:
    rng = np.random.default_rng(3)
    x = rng.normal(size=(50, 5)) @ rng.normal(size=(5, 5))
    fit = fit_ppca(x, q=4)
    np.testing.assert_allclose(fit.covariance(), np.cov(x, rowvar=False, bias=True), rtol=1e-10)


def test_fewer_demonstrations_than_dimensions() -> None:
    rng = np.random.default_rng(4)
    segs = demos(rng, 6, 1.6, 1.5)
    x = np.vstack([time_normalise(s).reshape(-1) for s in segs])
    assert x.shape == (6, 202)
    fit = fit_ppca(x)
    lam = np.sort(np.linalg.eigvalsh(np.cov(x, rowvar=False, bias=True)))[::-1]
    assert fit.q <= 4  # at most rank - 1 = 4
    # sigma^2 averages over all 202 - q discarded directions, the ~197 zeros included.
    assert fit.sigma2 == pytest.approx(lam[fit.q :].clip(0).sum() / (202 - fit.q), rel=1e-8)
    c_ref, _ = reference_fit(x, fit.q)
    np.testing.assert_allclose(fit.covariance(), c_ref, rtol=1e-7, atol=1e-12)
    with pytest.raises(ValueError, match="rank"):
        fit_ppca(x, q=5)


def test_ppca_validation() -> None:
    with pytest.raises(ValueError, match="at least 2"):
        fit_ppca(np.zeros((1, 4)))
    with pytest.raises(ValueError, match="no variance"):
        fit_ppca(np.ones((3, 4)))
    x = np.random.default_rng(0).normal(size=(5, 4))
    x[2, 1] = np.nan
    with pytest.raises(ValueError, match="row 2"):
        fit_ppca(x)


def make_set() -> ModelSet:
    rng = np.random.default_rng(11)
    data = {
        "squat": demos(rng, 8, 1.7, 1.7),
        "stoop_left": demos(rng, 5, 1.6, 1.2),
        "stoop_right": demos(rng, 4, 1.2, 1.6),
    }
    ids = {"squat": [f"rec1:{i}" for i in range(8)]}
    return fit_model_set(data, version="p07-v2", demo_ids=ids, meta={"participant": "P07"})


def test_fit_model_set_blocks_and_provenance() -> None:
    mset = make_set()
    sq = mset["squat"]
    assert sq.mean.shape == (101, 2) and sq.cov.shape == (101, 2, 2)
    assert sq.online_mean.shape == (51, 2) and sq.online_cov.shape == (51, 2, 2)
    assert sq.n_demonstrations == 8
    assert mset.demonstrations["squat"][3] == "rec1:3"
    assert mset.demonstrations["stoop_right"] == [f"stoop_right-{i}" for i in range(4)]
    assert mset.fit_params["explained_variance"] == 0.95
    assert mset.created.endswith("+00:00")
    # Blocks are the diagonal 2x2 blocks of the full C in sample-major order.
    assert sq.w is not None
    c = sq.w @ sq.w.T + sq.sigma2 * np.eye(202)
    for n in (0, 37, 100):
        np.testing.assert_allclose(sq.cov[n], c[2 * n : 2 * n + 2, 2 * n : 2 * n + 2])
    # Mean lift: peak flexion near s = 0.5 and the stoops' asymmetry in the right hip.
    assert mset["squat"].mean[50] == pytest.approx([1.7, 1.7], abs=0.1)
    assert mset["stoop_left"].mean[50, 0] > mset["stoop_left"].mean[50, 1] + 0.2
    assert [m.name for m in mset.ordered()] == ["squat", "stoop_left", "stoop_right"]


def test_model_set_json_round_trip(tmp_path: Path) -> None:
    mset = make_set()
    path = tmp_path / "models.json"
    mset.save(path)
    doc = json.loads(path.read_text())
    assert doc["format"] == FORMAT_NAME and doc["format_version"] == 1
    back = ModelSet.load(path)
    for name in ("squat", "stoop_left", "stoop_right"):
        a, b = mset[name], back[name]
        np.testing.assert_array_equal(a.mean, b.mean)
        np.testing.assert_array_equal(a.cov, b.cov)
        facts = ("q", "sigma2", "explained_variance", "n_demonstrations", "online_n")
        assert [getattr(a, f) for f in facts] == [getattr(b, f) for f in facts]
        assert a.w is not None and b.w is not None
        np.testing.assert_array_equal(a.w, b.w)
    assert (back.version, back.created, back.demonstrations, back.meta) == (
        mset.version, mset.created, mset.demonstrations, mset.meta)


def test_model_set_rejects_bad_input() -> None:
    rng = np.random.default_rng(5)
    ok = {"squat": demos(rng, 3, 1.7, 1.7), "stoop_left": demos(rng, 3, 1.6, 1.2),
          "stoop_right": demos(rng, 3, 1.2, 1.6)}
    with pytest.raises(ValueError, match="unknown model names"):
        fit_model_set({**ok, "jump": demos(rng, 3, 1, 1)})
    with pytest.raises(ValueError, match="stoop_left: needs at least 2"):
        fit_model_set({**ok, "stoop_left": ok["stoop_left"][:1]})
    with pytest.raises(ValueError, match="no demonstrations for model stoop_right"):
        fit_model_set({k: v for k, v in ok.items() if k != "stoop_right"})
    bad = [s.copy() for s in ok["squat"]]
    bad[1][5, 0] = np.nan
    with pytest.raises(ValueError, match="squat, demonstration 1"):
        fit_model_set({**ok, "squat": bad})
    with pytest.raises(ValueError, match="demonstration 2"):
        fit_model_set({**ok, "squat": [*ok["squat"][:2], np.zeros(10)]})
    with pytest.raises(ValueError, match="ids"):
        fit_model_set(ok, demo_ids={"squat": ["a"]})


def test_from_json_names_model_and_sample_of_bad_block() -> None:
    doc = make_set().to_json()
    doc["models"]["stoop_left"]["cov_rad2"][17] = [[0.01, 0.02], [0.02, 0.01]]
    with pytest.raises(ValueError, match=r"stoop_left.*sample 17.*positive definite"):
        ModelSet.from_json(doc)
    doc = make_set().to_json()
    doc["models"]["squat"]["cov_rad2"][4] = [[0.01, 0.001], [0.002, 0.01]]
    with pytest.raises(ValueError, match=r"squat.*sample 4.*not symmetric"):
        ModelSet.from_json(doc)
    doc = make_set().to_json()
    doc["models"]["squat"]["mean_rad"] = doc["models"]["squat"]["mean_rad"][:50]
    with pytest.raises(ValueError, match=r"squat: mean must be \(101, 2\)"):
        ModelSet.from_json(doc)
    doc = make_set().to_json()
    doc["models"]["walk"] = doc["models"].pop("squat")
    with pytest.raises(ValueError, match="unknown model"):
        ModelSet.from_json(doc)
    with pytest.raises(ValueError, match="format_version"):
        ModelSet.from_json({**make_set().to_json(), "format_version": 2})


def test_motion_model_rejects_nan() -> None:
    m = make_set()["squat"]
    mean = m.mean.copy()
    mean[12, 1] = np.nan
    with pytest.raises(ValueError, match="sample 12"):
        MotionModel(name="squat", mean=mean, cov=m.cov, q=m.q, sigma2=m.sigma2,
                    explained_variance=m.explained_variance, n_demonstrations=3)


def test_ppcafit_properties() -> None:
    fit = fit_ppca(np.random.default_rng(2).normal(size=(10, 4)), q=2)
    assert isinstance(fit, PPCAFit)
    assert (fit.q, fit.d) == (2, 4)


def test_segmented_recording_to_model_set() -> None:
    """Pipeline: continuous recording -> segment_lifts -> fit_model_set."""
    from controller.intent.segmentation import segment_lifts

    rng = np.random.default_rng(8)
    peaks = {"squat": (1.7, 1.7), "stoop_left": (1.6, 1.1), "stoop_right": (1.1, 1.6)}
    parts, labels = [np.zeros((200, 2))], []
    for name, (pl, pr) in peaks.items():
        for seg in demos(rng, 3, pl, pr):
            parts += [seg - seg[0], np.zeros((150, 2))]
            labels.append(name)
    q = np.vstack(parts) + rng.normal(0.0, np.radians(0.06), (sum(map(len, parts)), 2))
    t = np.arange(len(q)) / 100.0
    found = segment_lifts(t, q)
    assert len(found) == 9
    by_model: dict[str, list[np.ndarray]] = {}
    for label, lift_seg in zip(labels, found, strict=True):
        by_model.setdefault(label, []).append(q[lift_seg.as_slice()])
    mset = fit_model_set(by_model)
    for name, (pl, pr) in peaks.items():
        np.testing.assert_allclose(mset[name].mean[50], [pl, pr], atol=0.15)
        assert np.abs(mset[name].mean[0]).max() < 0.05


def test_start_posture_is_the_mean_of_the_models_first_samples() -> None:
    mset = make_set()
    first = np.array([m.mean[0] for m in mset.ordered()])
    assert first.shape == (3, 2)
    np.testing.assert_allclose(mset.start_posture(), first.sum(axis=0) / 3, atol=1e-12)
    assert mset.start_posture().dtype == np.float64
